//! A map from frames in memory: the blocks of `polarid.dask.material_map`. Stage 1 is
//! that of `map_manifest_from` (module `capture`) on frames in memory — per capture the
//! binned DoLP of every band, its signal flags and, for weighted fits, its noise terms,
//! with the same kernels, pixel rules and dark threshold — and stages 2 and 3 are the
//! map's own ([`super::bands`]: every band fitted, every pixel decided once, module
//! `decide`). A block of a DoFP mosaic carries a halo of raw pixels (neighbours read by
//! the bilinear interpolation, not mapped). The noise model of weighted fits is the
//! map's (estimated once over the whole map), given to every block.

use std::path::Path;

use polarid_core::CoreError;
use polarid_core::classify::same_band;
use polarid_core::map as cmap;
use polarid_core::map::noise::{NoiseAnalyzer, NoiseModel};
use polarid_core::map::sets::MapErrorModel;
use polarid_core::mosaic::{self, ColourMethod, ColourPattern, DofpOutputs, Pattern};
use polarid_core::stokes::{PixelRules, Sample, StokesSolver};
use polarid_io::IoError;

use super::bands::{self, BandDolp, BandsFit, FitGeometry};
use super::capture::{CaptureBand, Dims, StokesBinning};
use super::rules::min_s0_for;
use super::{MapConfig, MapPrototypes, Weights, answer, decide};
use crate::error::{PipelineError, Result};

/// How a block's captures were taken.
#[derive(Debug, Clone, Copy)]
pub enum FramesSource<'a> {
    /// Rotating-polarizer frames (data `(captures, angles, rows, columns)`); the band's
    /// wavelength, if known.
    Polarizer(&'a StokesSolver, Option<f64>),
    /// Monochrome DoFP mosaics (data `(captures, rows, columns)`).
    Dofp(&'a Pattern, Option<f64>),
    /// Colour DoFP mosaics, the wavelength of every band of the pattern (in its order).
    Colour(&'a ColourPattern, &'a [f64]),
}

/// The frames of a block, row-major, captures first.
#[derive(Debug, Clone, Copy)]
pub struct Frames<'a, T> {
    /// The samples.
    pub data: &'a [T],
    /// Captures.
    pub captures: usize,
    /// Rows and columns of a frame (with the halo).
    pub rows: usize,
    /// Columns of a frame (with the halo).
    pub columns: usize,
    /// Rows/columns `(top, bottom, left, right)` read but not mapped (DoFP only).
    pub halo: [usize; 4],
    /// The captures' kind.
    pub source: FramesSource<'a>,
    /// The pixel rules of every capture (dark level, saturation).
    pub rules: &'a [PixelRules],
    /// Integer samples (the default dark threshold of `rules::min_s0_for`).
    pub is_integer: bool,
}

impl<T> Frames<'_, T> {
    /// The mapped size (without the halo), binned: `(columns, rows)`.
    pub fn binned_size(&self, bin: usize) -> std::result::Result<(usize, usize), CoreError> {
        let h = self.halo;
        cmap::binned_size(self.columns - h[2] - h[3], self.rows - h[0] - h[1], bin)
    }

    fn colour(&self) -> bool {
        matches!(self.source, FramesSource::Colour(..))
    }
}

/// The distinct wavelengths of `nms`, increasing (the map's band order), and the index of
/// each of `nms` among them.
pub fn band_order(nms: &[f64]) -> (Vec<f64>, Vec<usize>) {
    let mut all = nms.to_vec();
    all.sort_by(f64::total_cmp);
    all.dedup_by(|a, b| same_band(Some(*a), Some(*b)));
    let of = nms
        .iter()
        .map(|&w| {
            all.iter()
                .position(|&a| same_band(Some(a), Some(w)))
                .unwrap_or(0)
        })
        .collect();
    (all, of)
}

/// Crop rows `top..h-bottom` and columns `left..w-right` of a `w`-wide image.
fn crop<U: Copy>(v: Vec<U>, w: usize, h: usize, c: [usize; 4]) -> Vec<U> {
    let [top, bottom, left, right] = c;
    if c == [0; 4] {
        return v;
    }
    let mut out = Vec::with_capacity((h - top - bottom) * (w - left - right));
    for y in top..h - bottom {
        out.extend_from_slice(&v[y * w + left..(y + 1) * w - right]);
    }
    out
}

/// Stage 1 on frames in memory: the bands of the block (one unnamed band, or one per
/// wavelength of a colour pattern) with every capture's DoLP, flags and, when
/// `weighted`, noise terms; `calibrated`: a pixel's dark or saturated captures are left
/// out of its own fit ([`BandDolp::push`]).
pub fn frames_bands<T: Sample>(
    cfg: &MapConfig,
    f: &Frames<'_, T>,
    calibrated: bool,
    weighted: bool,
) -> std::result::Result<Vec<BandDolp>, CoreError> {
    let (hh, ww, halo, bin) = (f.rows, f.columns, f.halo, cfg.bin);
    let (out_w, out_h) = f.binned_size(bin)?;
    let plane = hh * ww;
    let binning = StokesBinning {
        d: Dims {
            width: ww - halo[2] - halo[3],
            height: hh - halo[0] - halo[1],
            out_w,
            out_h,
        },
        min_s0: 0.0,
        scale: 1.0,
        bin,
        weighted,
    };
    let all: Vec<usize> = (0..f.captures).collect();
    let (mut bands, band_of) = match f.source {
        FramesSource::Colour(_, nms) => {
            let (wls, of) = band_order(nms);
            let b = wls.iter().map(|&w| BandDolp::new(w, all.clone())).collect();
            (b, of)
        }
        FramesSource::Polarizer(_, wl) | FramesSource::Dofp(_, wl) => {
            (vec![BandDolp::unnamed(wl, all.clone())], vec![0])
        }
    };
    // One band's binned DoLP from its Stokes images, the dark test on the block mean.
    let stokes = |s: [Vec<f32>; 3], m: Vec<u8>, min_s0: f32| {
        let s = s.map(|x| crop(x, ww, hh, halo));
        let m = crop(m, ww, hh, halo);
        StokesBinning { min_s0, ..binning }.band(None, [&s[0], &s[1], &s[2]], Some(&m))
    };
    for (t, r) in f.rules.iter().enumerate() {
        let mut r = *r;
        let th = min_s0_for(&r, f.is_integer, cfg.min_s0);
        let mut images = Vec::with_capacity(band_of.len());
        match f.source {
            FramesSource::Polarizer(solver, _) => {
                let a = solver.len();
                r.min_s0 = th;
                let an = NoiseAnalyzer::of_solver(solver);
                let cap = &f.data[t * a * plane..(t + 1) * a * plane];
                let views: Vec<&[T]> = cap.chunks_exact(plane).collect();
                let mut b = CaptureBand::new(None, binning.d, weighted);
                let (d, cf, out) = b.outputs(&an, 1.0);
                cmap::frames_dolp_noise(solver, &views, ww, &r, bin, d, cf, out)?;
                images.push(b);
            }
            FramesSource::Dofp(p, _) => {
                // The dark test is made on the block mean by stokes_dolp.
                r.min_s0 = f32::MIN;
                let cap = &f.data[t * plane..(t + 1) * plane];
                let z = || vec![0f32; plane];
                let (mut s0, mut s1, mut s2, mut m) = (z(), z(), z(), vec![0u8; plane]);
                mosaic::bilinear_stokes(cap, ww, p, &r, false, &mut s0, &mut s1, &mut s2, &mut m)?;
                images.push(stokes([s0, s1, s2], m, th)?);
            }
            FramesSource::Colour(cp, _) => {
                r.min_s0 = f32::MIN;
                let cap = &f.data[t * plane..(t + 1) * plane];
                let nb = band_of.len();
                let z = || vec![0f32; plane];
                let mut s: Vec<[Vec<f32>; 3]> = (0..nb).map(|_| [z(), z(), z()]).collect();
                let mut mk: Vec<Vec<u8>> = (0..nb).map(|_| vec![0u8; plane]).collect();
                let outs: Vec<DofpOutputs<'_>> = s
                    .iter_mut()
                    .zip(mk.iter_mut())
                    .map(|([a, b, c], m)| DofpOutputs {
                        s0: Some(a),
                        s1: Some(b),
                        s2: Some(c),
                        mask: Some(m),
                        ..Default::default()
                    })
                    .collect();
                mosaic::colour_polar(cap, ww, cp, ColourMethod::Bilinear, &r, outs)?;
                for (s, m) in s.into_iter().zip(mk) {
                    images.push(stokes(s, m, th)?);
                }
            }
        }
        for (im, &b) in images.into_iter().zip(&band_of) {
            bands[b].push(calibrated, im.dolp, &im.flags, im.noise);
        }
    }
    bands.iter_mut().for_each(|b| b.finish(calibrated));
    Ok(bands)
}

/// The class names of a map of `colour` (or single-band) data at `wavelengths` against
/// `src` under `cfg` (class code `i` is name `i - 1`), as [`map_frames`] answers.
pub fn frames_class_names(
    cfg: &MapConfig,
    src: MapPrototypes<'_>,
    wavelengths: &[Option<f64>],
    colour: bool,
) -> Result<Vec<String>> {
    let decision = decide::decision(cfg, src, wavelengths)?;
    Ok(match answer(cfg, src, &decision, colour)? {
        Some(pc) => pc.names().to_vec(),
        None => decision.class_names,
    })
}

/// Map a block of frames in memory against `src` (module documentation): stage 1
/// ([`frames_bands`]), then every band fitted and every pixel decided as `polarid map`
/// does. `far_betas`: β of every capture (radians, far field); `beta`: β of every capture
/// and binned pixel (radians; empty: far field); `noise`: weighted fits with the map's
/// noise model of every band (in increasing wavelength; `None` for a band: unweighted),
/// or `None` (unweighted). `path` names the data in errors.
#[allow(clippy::too_many_arguments)]
pub fn map_frames<T: Sample>(
    cfg: &MapConfig,
    src: MapPrototypes<'_>,
    frames: &Frames<'_, T>,
    far_betas: &[f64],
    beta: &[Vec<f32>],
    errors: &MapErrorModel,
    noise: Option<&[Option<NoiseModel>]>,
    path: &Path,
) -> Result<BandsFit> {
    let core_err = |e| IoError::core(path, e);
    let cfg = cfg.clone().with_weights(match noise {
        Some(_) => Weights::Noise,
        None => Weights::None,
    });
    let calibrated = !beta.is_empty();
    let colour = frames.colour();
    let mut bands = frames_bands(&cfg, frames, calibrated, noise.is_some()).map_err(core_err)?;
    if let Some(models) = noise {
        if models.len() != bands.len() {
            return Err(PipelineError::Data {
                path: path.display().to_string(),
                reason: format!(
                    "{} noise model(s) given for {} band(s)",
                    models.len(),
                    bands.len()
                ),
            });
        }
        for (b, &m) in bands.iter_mut().zip(models) {
            b.set_noise_model(m);
        }
    }
    let wavelengths: Vec<Option<f64>> = bands.iter().map(|b| b.wavelength()).collect();
    let decision = decide::decision(&cfg, src, &wavelengths)?;
    let answer = answer(&cfg, src, &decision, colour)?;
    let plans = bands::fit_plans(&bands, far_betas, calibrated, path)?;
    let (ow, oh) = frames.binned_size(cfg.bin).map_err(core_err)?;
    bands::fit_bands_with(
        &cfg,
        bands,
        &plans,
        FitGeometry {
            npix: ow * oh,
            far_betas,
            beta,
            errors,
        },
        &decision,
        answer.as_ref(),
        path,
        &|_, _, _| {},
    )
}
