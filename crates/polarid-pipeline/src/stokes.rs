//! The Stokes workflow of `polarid stokes`: frames or a DoFP mosaic in, Stokes, DoLP and
//! AoLP images per band out.
//!
//! One path for every band: rotating-polarizer frames and a monochrome DoFP mosaic give
//! one band (no letter, no wavelength); a colour polarization mosaic (`color = "RGGB"`)
//! gives one band per colour, in the pattern's band order, each with its letter and
//! wavelength (the band table of [`polarid_io::manifest::colour::band_table`]). The
//! options are checked by [`StokesConfig::validate`] before any file is read; the front
//! ends render and write the images.
//!
//! Kernels: frames through [`polarid_io::measure::frames_stokes`] and
//! [`polarid_core::stokes::dolp_aolp`]; a DoFP mosaic through the fused
//! [`polarid_core::mosaic::dofp_polar`] (Stokes, mask, DoLP and AoLP in one pass); a
//! colour mosaic through [`polarid_core::mosaic::colour_polar`] (every band in one pass).

use std::path::PathBuf;

use polarid_core::mosaic::{
    self, ColourMethod, ColourPattern, DofpMethod, DofpOutputs, Pattern, colour_polar,
};
use polarid_core::region::Sampling;
use polarid_core::stokes::{self, PixelRules, StokesSolver};
use polarid_io::IoError;
use polarid_io::image::{self, Frame};
use polarid_io::manifest::colour::{band_table, pattern_wavelengths};
use polarid_io::measure::{Demosaic, StokesImages, frames_stokes, rules_for};

use crate::error::{PipelineError, Result, ensure};
use crate::map::rules::check_levels;
use crate::progress::Warning;

/// Where the polarization images come from.
#[derive(Debug, Clone, PartialEq)]
pub enum StokesSource {
    /// Frames taken through a linear polarizer, one per angle.
    Frames {
        /// The frames (grayscale PNG/TIFF).
        files: Vec<PathBuf>,
        /// Polarizer angle of each frame, degrees.
        angles_deg: Vec<f64>,
    },
    /// A raw division-of-focal-plane mosaic.
    Dofp {
        /// The raw mosaic (grayscale PNG/TIFF).
        file: PathBuf,
        /// The 2×2 polarizer pattern, degrees, row by row from the top-left.
        pattern_deg: Vec<f64>,
        /// Full-resolution bilinear reconstruction or 2×2 super-pixels.
        demosaic: Demosaic,
        /// A colour polarization mosaic: the colour of each 2×2 polarizer block of the
        /// 4×4 period (e.g. `RGGB`), and the band table (letter, nm; empty: the default
        /// R 650, G 550, B 450 nm).
        colour: Option<(String, Vec<(String, f64)>)>,
    },
}

/// A checked-once configuration of the Stokes workflow.
#[derive(Debug, Clone, PartialEq)]
pub struct StokesConfig {
    /// The input.
    pub source: StokesSource,
    /// Dark level (DN) subtracted from every raw value.
    pub dark_level: f64,
    /// Raw values at or above it are saturated (default: the type's maximum, or the
    /// file's recorded bit depth).
    pub saturation: Option<f64>,
}

/// The images of one band.
#[derive(Debug, Clone)]
pub struct StokesBand {
    /// The colour letter of a colour mosaic's band (`None`: a single-band input).
    pub letter: Option<char>,
    /// The band's wavelength, nm (colour bands).
    pub wavelength_nm: Option<f64>,
    /// S0, S1, S2, the pixel mask and its counts.
    pub images: StokesImages,
    /// DoLP (NaN where a pixel is rejected).
    pub dolp: Vec<f32>,
    /// AoLP, radians (NaN where a pixel is rejected).
    pub aolp: Vec<f32>,
}

impl StokesBand {
    /// A band of `images` with its DoLP and AoLP images to be filled.
    fn new(letter: Option<char>, wavelength_nm: Option<f64>, images: StokesImages) -> Self {
        let n = images.width * images.height;
        Self {
            letter,
            wavelength_nm,
            images,
            dolp: vec![0f32; n],
            aolp: vec![0f32; n],
        }
    }

    /// Every image of the band as the outputs of a fused mosaic kernel.
    fn outputs(&mut self) -> DofpOutputs<'_> {
        DofpOutputs {
            s0: Some(&mut self.images.s0),
            s1: Some(&mut self.images.s1),
            s2: Some(&mut self.images.s2),
            mask: Some(&mut self.images.mask),
            dolp: Some(&mut self.dolp),
            aolp: Some(&mut self.aolp),
        }
    }
}

/// What the Stokes workflow returns.
#[derive(Debug, Clone)]
pub struct StokesResult {
    /// Width of every band's images, pixels.
    pub width: usize,
    /// Height of every band's images, pixels.
    pub height: usize,
    /// One band (frames, a monochrome mosaic) or one per colour.
    pub bands: Vec<StokesBand>,
    /// The files read.
    pub inputs: Vec<PathBuf>,
    /// Things to tell the user (poorly spread polarizer angles).
    pub warnings: Vec<Warning>,
}

impl StokesConfig {
    /// Check every option before any file is read ([`PipelineError::Config`] naming the
    /// option as the command line spells it).
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
    pub fn validate(&self) -> Result<()> {
        check_levels(self.dark_level, self.saturation)?;
        match &self.source {
            StokesSource::Frames { files, angles_deg } => {
                let why = "needs one frame per polarizer angle";
                ensure(!files.is_empty(), "--frames", "no file", why)?;
                ensure(
                    angles_deg.len() == files.len(),
                    "--angles",
                    format!("{} angle(s) for {} frame(s)", angles_deg.len(), files.len()),
                    "needs one angle per frame",
                )?;
                if let Some(a) = angles_deg.iter().find(|a| !(a.abs() <= 3600.0)) {
                    return Err(PipelineError::config(
                        "--angles",
                        format!("{a:?}"),
                        "a polarizer angle must be in [-3600, 3600] degrees",
                    ));
                }
                StokesSolver::from_degrees(angles_deg)?;
            }
            StokesSource::Dofp {
                pattern_deg,
                colour,
                ..
            } => {
                let pattern = Pattern::new(pattern_deg)?;
                if let Some((color, bands)) = colour {
                    colour_bands(pattern, color, bands)?;
                }
            }
        }
        Ok(())
    }
}

/// The colour pattern and the wavelength of each of its bands.
fn colour_bands(
    pattern: Pattern,
    color: &str,
    bands: &[(String, f64)],
) -> Result<(ColourPattern, Vec<f64>)> {
    let cp = ColourPattern::new(pattern, color)
        .map_err(|e| PipelineError::config("--color", format!("{color:?}"), e.to_string()))?;
    let table = band_table(bands.iter().map(|(k, nm)| (k.as_str(), *nm))).map_err(|e| {
        PipelineError::config("--bands", format!("{bands:?}"), format!("is refused: {e}"))
    })?;
    let nms = pattern_wavelengths(&cp, &table).map_err(|e| {
        PipelineError::config("--color", format!("{color:?}"), format!("{e} in --bands"))
    })?;
    Ok((cp, nms))
}

/// The core's error on `raw`, naming its file.
fn on_file(raw: &Frame) -> impl FnOnce(polarid_core::CoreError) -> PipelineError + '_ {
    |source| IoError::core(&raw.path, source).into()
}

/// Stokes images, mask, counts, DoLP and AoLP of a monochrome DoFP mosaic in one pass.
fn dofp_band(
    raw: &Frame,
    pattern: &Pattern,
    rules: &PixelRules,
    d: Demosaic,
) -> Result<StokesBand> {
    let (method, sampling) = match d {
        Demosaic::Bilinear => (
            DofpMethod::Bilinear {
                round: raw.kind.is_integer(),
            },
            Sampling::BilinearDofp,
        ),
        Demosaic::Superpixel => (DofpMethod::Superpixel, Sampling::Independent),
    };
    let (w, h) = method.output_size(raw.width, raw.height);
    let mut band = StokesBand::new(None, None, StokesImages::alloc(w, h, sampling));
    let out = band.outputs();
    let counts = mosaic::dofp_polar(&raw.data, raw.width, pattern, method, rules, out)
        .map_err(on_file(raw))?;
    band.images.counts = counts;
    Ok(band)
}

/// Every band of a colour polarization mosaic in one pass.
fn colour_bands_images(
    raw: &Frame,
    cp: &ColourPattern,
    nms: &[f64],
    rules: &PixelRules,
    d: Demosaic,
) -> Result<Vec<StokesBand>> {
    let (method, sampling) = match d {
        Demosaic::Bilinear => (ColourMethod::Bilinear, Sampling::BilinearColour),
        Demosaic::Superpixel => (ColourMethod::Superpixel, Sampling::Independent),
    };
    let (w, h) = method.output_size(raw.width, raw.height);
    let mut bands: Vec<StokesBand> = cp
        .bands()
        .iter()
        .zip(nms)
        .map(|(&letter, &nm)| {
            StokesBand::new(Some(letter), Some(nm), StokesImages::alloc(w, h, sampling))
        })
        .collect();
    let outs = bands.iter_mut().map(StokesBand::outputs).collect();
    let counts =
        colour_polar(&raw.data, raw.width, cp, method, rules, outs).map_err(on_file(raw))?;
    for (b, c) in bands.iter_mut().zip(counts) {
        b.images.counts = c;
    }
    Ok(bands)
}

/// Run the Stokes workflow ([`StokesConfig::validate`] first).
pub fn stokes(cfg: &StokesConfig) -> Result<StokesResult> {
    cfg.validate()?;
    let mut warnings = Vec::new();
    let (bands, inputs) = match &cfg.source {
        StokesSource::Frames { files, angles_deg } => {
            let solver = StokesSolver::from_degrees(angles_deg)?;
            if solver.ill_conditioned() {
                warnings.push(Warning(format!(
                    "polarizer angles {angles_deg:?} are poorly spread (condition number \
                     {:.1}, best {:.2}): S1 and S2 will be noisy",
                    solver.condition_number(),
                    std::f64::consts::SQRT_2
                )));
            }
            let frames = image::read_frames(files)?;
            // ok: validate() checked one angle per frame, and at least three angles.
            let rules = rules_for(&frames[0], cfg.dark_level, cfg.saturation);
            let images = frames_stokes(&frames, &solver, &rules)?;
            drop(frames);
            let mut band = StokesBand::new(None, None, images);
            let (im, dolp, aolp) = (&band.images, &mut band.dolp, &mut band.aolp);
            let (s0, s1, s2) = (&im.s0, &im.s1, &im.s2);
            stokes::dolp_aolp(im.width, s0, s1, s2, Some(&im.mask), dolp, aolp)?;
            (vec![band], files.clone())
        }
        StokesSource::Dofp {
            file,
            pattern_deg,
            demosaic,
            colour,
        } => {
            let pattern = Pattern::new(pattern_deg)?;
            let raw = image::read_frame(file)?;
            let rules = rules_for(&raw, cfg.dark_level, cfg.saturation);
            let bands = match colour {
                None => vec![dofp_band(&raw, &pattern, &rules, *demosaic)?],
                Some((color, table)) => {
                    let (cp, nms) = colour_bands(pattern, color, table)?;
                    colour_bands_images(&raw, &cp, &nms, &rules, *demosaic)?
                }
            };
            (bands, vec![file.clone()])
        }
    };
    // ok: every source gives at least one band.
    let (width, height) = (bands[0].images.width, bands[0].images.height);
    Ok(StokesResult {
        width,
        height,
        bands,
        inputs,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(n_files: usize, angles: &[f64]) -> StokesConfig {
        StokesConfig {
            source: StokesSource::Frames {
                files: (0..n_files)
                    .map(|i| PathBuf::from(format!("f{i}.png")))
                    .collect(),
                angles_deg: angles.to_vec(),
            },
            dark_level: 0.0,
            saturation: None,
        }
    }

    #[test]
    fn options_are_checked_before_any_file_is_read() {
        let e = frames(3, &[0.0, 45.0]).validate().expect_err("count");
        assert!(e.to_string().contains("one angle per frame"), "{e}");
        let e = frames(3, &[0.0, 45.0, 1e9]).validate().expect_err("range");
        assert!(e.to_string().contains("[-3600, 3600]"), "{e}");
        assert!(
            frames(3, &[0.0, 90.0, 180.0]).validate().is_err(),
            "singular"
        );
        let mut c = frames(3, &[0.0, 60.0, 120.0]);
        assert!(c.validate().is_ok());
        c.dark_level = -1.0;
        assert!(
            c.validate()
                .expect_err("dark")
                .to_string()
                .contains("--dark-level")
        );
        let colour = |color: &str, bands: Vec<(String, f64)>| StokesConfig {
            source: StokesSource::Dofp {
                file: "raw.tif".into(),
                pattern_deg: vec![90.0, 45.0, 135.0, 0.0],
                demosaic: Demosaic::Bilinear,
                colour: Some((color.into(), bands)),
            },
            dark_level: 0.0,
            saturation: None,
        };
        assert!(colour("RGGB", vec![]).validate().is_ok());
        let e = colour("RGBN", vec![]).validate().expect_err("N");
        assert!(e.to_string().contains("colour N has no wavelength"), "{e}");
        let e = colour("RGGB", vec![("RG".into(), 1.0)])
            .validate()
            .expect_err("key");
        assert!(e.to_string().contains("--bands"), "{e}");
    }
}
