//! Stage 1 of the map: the (binned) DoLP image of one capture per band and its signal
//! flags.

use std::path::Path;

use polarid_core::map::noise::NoiseAnalyzer;
use polarid_core::map::{self, NoiseOut};
use polarid_core::mosaic::{self, ColourMethod};
use polarid_core::stokes::{PixelRules, StokesSolver};
use polarid_io::IoError;
use polarid_io::bands::colour_stokes;
use polarid_io::image::{self, Frame};
use polarid_io::manifest::{Capture, CaptureSource};
use polarid_io::measure::rules_for;

use super::MapConfig;
use super::rules::min_s0_for;
use crate::error::{PipelineError, Result};

/// The map's geometry: frame size, binned size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Dims {
    pub width: usize,
    pub height: usize,
    pub out_w: usize,
    pub out_h: usize,
}

/// The error of a core computation on the data of `path`.
pub(super) fn core_err(path: &Path) -> impl FnOnce(polarid_core::CoreError) -> IoError + '_ {
    move |e| IoError::core(path, e)
}

/// Check that a capture's frame has the map's size (set by the first capture).
pub(crate) fn check_dims(dims: &mut Option<Dims>, f: &Frame, bin: usize) -> Result<Dims> {
    if let Some(d) = dims {
        if (d.width, d.height) != (f.width, f.height) {
            return Err(IoError::Image {
                path: f.path.clone(),
                reason: format!(
                    "is {}x{} pixels but the first capture's frames are {}x{}: every capture of a map must have the same size",
                    f.width, f.height, d.width, d.height
                ),
            }
            .into());
        }
        return Ok(*d);
    }
    let (out_w, out_h) = map::binned_size(f.width, f.height, bin).map_err(|e| {
        let (w, h, file) = (f.width, f.height, f.path.display());
        let why = format!("does not fit the {w}x{h} frames of {file}: {e}");
        PipelineError::config("--bin", bin, why)
    })?;
    let (width, height) = (f.width, f.height);
    Ok(*dims.insert(Dims {
        width,
        height,
        out_w,
        out_h,
    }))
}

/// One band's binned DoLP image of a capture, its signal flags and, for weighted fits,
/// the noise terms `(A, B)` of every block (`polarid_core::map::noise`).
pub(crate) struct CaptureBand {
    /// The band's wavelength: a colour band's, or the single-band capture's own.
    pub wavelength_nm: Option<f64>,
    pub dolp: Vec<f32>,
    pub flags: Vec<u8>,
    pub noise: Option<(Vec<f32>, Vec<f32>)>,
}

impl CaptureBand {
    pub(super) fn new(wavelength_nm: Option<f64>, d: Dims, weighted: bool) -> Self {
        let n = d.out_w * d.out_h;
        Self {
            wavelength_nm,
            dolp: vec![0.0; n],
            flags: vec![0; n],
            noise: weighted.then(|| (vec![0.0; n], vec![0.0; n])),
        }
    }

    /// The outputs of a DoLP kernel; `scale` converts the capture's signal to DN.
    pub(super) fn outputs<'a>(
        &'a mut self,
        analyzer: &'a NoiseAnalyzer,
        scale: f64,
    ) -> (&'a mut [f32], &'a mut [u8], Option<NoiseOut<'a>>) {
        let nz = self.noise.as_mut().map(|(a, b)| NoiseOut {
            analyzer,
            scale,
            read: a.as_mut_slice(),
            shot: b.as_mut_slice(),
        });
        (&mut self.dolp, &mut self.flags, nz)
    }
}

/// A capture's mosaic `file`, the pixel rules of its reconstruction and the binning of
/// its Stokes images (the map's size; the dark threshold in DN, tested on the block mean
/// by `stokes_dolp`; `weighted`: with the noise terms).
fn read_mosaic(
    c: &Capture,
    file: &Path,
    cfg: &MapConfig,
    dims: &mut Option<Dims>,
    weighted: bool,
) -> Result<(Frame, PixelRules, StokesBinning)> {
    let raw = image::read_frame(file)?;
    let d = check_dims(dims, &raw, cfg.bin)?;
    let mut rules = rules_for(&raw, c.dark_level, c.saturation);
    let min_s0 = min_s0_for(&rules, raw.kind.is_integer(), cfg.min_s0);
    rules.min_s0 = f32::MIN;
    let binning = StokesBinning {
        d,
        min_s0,
        scale: 1.0,
        bin: cfg.bin,
        weighted,
    };
    Ok((raw, rules, binning))
}

/// How a capture's Stokes images are binned into DoLP: the map's size, the dark test on
/// the block mean at `min_s0`, `scale` converting the signal to DN for the noise model,
/// the binning, and whether the noise terms are kept.
#[derive(Debug, Clone, Copy)]
pub(super) struct StokesBinning {
    pub d: Dims,
    pub min_s0: f32,
    pub scale: f64,
    pub bin: usize,
    pub weighted: bool,
}

impl StokesBinning {
    /// One band's binned DoLP from its Stokes images `s` (`mask`: the mosaic's per-pixel
    /// flags).
    pub(super) fn band(
        &self,
        wavelength_nm: Option<f64>,
        s: [&[f32]; 3],
        mask: Option<&[u8]>,
    ) -> std::result::Result<CaptureBand, polarid_core::CoreError> {
        let quad = NoiseAnalyzer::quad();
        let d = self.d;
        let mut b = CaptureBand::new(wavelength_nm, d, self.weighted);
        let (dolp, flags, nz) = b.outputs(&quad, self.scale);
        map::stokes_dolp_noise(
            d.width,
            s[0],
            s[1],
            s[2],
            mask,
            self.min_s0,
            self.bin,
            dolp,
            flags,
            nz,
        )?;
        Ok(b)
    }
}

/// The binned DoLP of one capture per band (one band for a single-band capture; a
/// colour mosaic reconstructed once into its bands, bilinear per lattice, in the order
/// of its pattern), with `weighted` the noise terms; returns the dark threshold used
/// (DN) and the bands.
pub(crate) fn capture_bands(
    c: &Capture,
    cfg: &MapConfig,
    dims: &mut Option<Dims>,
    weighted: bool,
) -> Result<(f32, Vec<CaptureBand>)> {
    let bin = cfg.bin;
    match &c.source {
        CaptureSource::Frames(frames) => {
            let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
            let solver = StokesSolver::from_degrees(&angles)?;
            let paths: Vec<&Path> = frames.iter().map(|f| f.file.as_path()).collect();
            let imgs = image::read_frames(&paths)?;
            let Some(first) = imgs.first() else {
                let path = c.source.files().first().copied();
                let source = polarid_core::CoreError::TooFew {
                    what: "frames",
                    needed: solver.len(),
                    got: 0,
                };
                return Err(IoError::core(path.unwrap_or(Path::new("<no frames>")), source).into());
            };
            let d = check_dims(dims, first, bin)?;
            let mut b = CaptureBand::new(c.wavelength_nm, d, weighted);
            let an = NoiseAnalyzer::of_solver(&solver);
            let mut rules = rules_for(first, c.dark_level, c.saturation);
            rules.min_s0 = min_s0_for(&rules, first.kind.is_integer(), cfg.min_s0);
            let views: Vec<&[f32]> = imgs.iter().map(|f| f.data.as_slice()).collect();
            let (dolp, flags, nz) = b.outputs(&an, 1.0);
            map::frames_dolp_noise(&solver, &views, d.width, &rules, bin, dolp, flags, nz)
                .map_err(core_err(&first.path))?;
            Ok((rules.min_s0, vec![b]))
        }
        CaptureSource::Dofp { file, pattern } => {
            let (raw, rules, binning) = read_mosaic(c, file, cfg, dims, weighted)?;
            let n = raw.width * raw.height;
            let (mut s0, mut s1, mut s2, mut m) =
                (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0u8; n]);
            mosaic::bilinear_stokes(
                &raw.data, raw.width, pattern, &rules, false, &mut s0, &mut s1, &mut s2, &mut m,
            )
            .map_err(core_err(file))?;
            drop(raw);
            let b = binning.band(c.wavelength_nm, [&s0[..], &s1, &s2], Some(&m));
            Ok((binning.min_s0, vec![b.map_err(core_err(file))?]))
        }
        CaptureSource::ColourDofp {
            file,
            pattern,
            wavelengths_nm,
        } => {
            let (raw, rules, binning) = read_mosaic(c, file, cfg, dims, weighted)?;
            let imgs = colour_stokes(&raw, pattern, &rules, ColourMethod::Bilinear)?;
            drop(raw);
            let out = imgs.iter().zip(wavelengths_nm).map(|(img, &w)| {
                binning.band(Some(w), [&img.s0[..], &img.s1, &img.s2], Some(&img.mask))
            });
            Ok((
                binning.min_s0,
                out.collect::<std::result::Result<_, _>>()
                    .map_err(core_err(file))?,
            ))
        }
        CaptureSource::Stokes { s0, s1, s2 } => {
            let imgs = image::read_frames(&[s0, s1, s2])?;
            let [i0, i1, i2] = &imgs[..] else {
                return Err(PipelineError::Data {
                    path: s0.display().to_string(),
                    reason: "expected three Stokes images (S0, S1, S2)".into(),
                });
            };
            let d = check_dims(dims, i0, bin)?;
            let min_s0 = (cfg.min_s0.unwrap_or(0.0) / c.exposure) as f32;
            let s = [&i0.data[..], &i1.data, &i2.data];
            // S in DN / exposure: back to DN for the noise model.
            let binning = StokesBinning {
                d,
                min_s0,
                scale: c.exposure,
                bin,
                weighted,
            };
            let b = binning.band(c.wavelength_nm, s, None);
            Ok((min_s0, vec![b.map_err(core_err(s0))?]))
        }
    }
}
