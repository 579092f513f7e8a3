//! Per-band Stokes images of a capture: the entry point of per-band measurement for
//! colour polarization cameras (docs/FORMATS.md, "Colour polarization cameras").
//!
//! [`capture_band_images`] returns one [`BandImages`] per band of a capture: one for a
//! single-band capture (rotating-polarizer frames, monochrome DoFP, Stokes files — the
//! images of [`crate::measure::capture_images`], with the capture's `wavelength_nm`),
//! one per colour of a colour DoFP capture in increasing wavelength, each at full
//! resolution in raw pixel coordinates (bilinear per lattice,
//! [`polarid_core::mosaic::colour`]; region standard errors use
//! [`Sampling::BilinearColour`]), so that region rectangles apply to every band.

use polarid_core::mosaic::{ColourMethod, ColourPattern, DofpOutputs, colour_polar};
use polarid_core::region::Sampling;
use polarid_core::stokes::PixelRules;

use crate::error::{IoError, Result};
use crate::image::{self, Frame};
use crate::manifest::{Capture, CaptureSource, Manifest};
use crate::measure::{StokesImages, capture_images, rules_for};

/// The Stokes images of one band of a capture.
#[derive(Debug, Clone, PartialEq)]
pub struct BandImages {
    /// The band's wavelength, nm (`None`: a single-band capture without
    /// `wavelength_nm`).
    pub wavelength_nm: Option<f64>,
    /// The colour letter of a colour capture's band (`None` for single-band captures).
    pub band: Option<char>,
    /// S0, S1, S2, mask and counts (dark level subtracted, not divided by exposure).
    pub images: StokesImages,
}

/// Per-band Stokes images of a colour polarization mosaic `raw`, one per band of
/// `pattern` (in the order of [`ColourPattern::bands`]): bilinear at full resolution
/// ([`Sampling::BilinearColour`]) or one value per 4×4 period ([`Sampling::Independent`]).
///
/// Errors: [`IoError::Core`] naming the raw file (a size that is not whole 4×4 periods,
/// bad rules).
pub fn colour_stokes(
    raw: &Frame,
    pattern: &ColourPattern,
    rules: &PixelRules,
    method: ColourMethod,
) -> Result<Vec<StokesImages>> {
    let (w, h) = method.output_size(raw.width, raw.height);
    let sampling = match method {
        ColourMethod::Bilinear => Sampling::BilinearColour,
        ColourMethod::Superpixel => Sampling::Independent,
    };
    let mut imgs: Vec<StokesImages> = pattern
        .bands()
        .iter()
        .map(|_| StokesImages::alloc(w, h, sampling))
        .collect();
    let outs = imgs
        .iter_mut()
        .map(|o| DofpOutputs {
            s0: Some(&mut o.s0),
            s1: Some(&mut o.s1),
            s2: Some(&mut o.s2),
            mask: Some(&mut o.mask),
            ..Default::default()
        })
        .collect();
    let counts =
        colour_polar(&raw.data, raw.width, pattern, method, rules, outs).map_err(|source| {
            IoError::Core {
                path: raw.path.clone(),
                source,
            }
        })?;
    for (o, c) in imgs.iter_mut().zip(counts) {
        o.counts = c;
    }
    Ok(imgs)
}

/// Per-band Stokes images of capture `c` of `m` as `polarid measure` uses them (module
/// docs): one entry for a single-band capture, one per band, in increasing wavelength,
/// for a colour capture.
///
/// Errors: those of [`capture_images`] and [`colour_stokes`] (the image reader's naming
/// the file, [`IoError::Core`] naming the raw file whose size is not whole periods).
pub fn capture_band_images(m: &Manifest, c: &Capture) -> Result<Vec<BandImages>> {
    match &c.source {
        CaptureSource::ColourDofp {
            file,
            pattern,
            wavelengths_nm,
        } => {
            let raw = image::read_frame(file)?;
            let rules = rules_for(&raw, c.dark_level, c.saturation);
            let imgs = colour_stokes(&raw, pattern, &rules, ColourMethod::Bilinear)?;
            let mut bands: Vec<BandImages> = imgs
                .into_iter()
                .zip(pattern.bands())
                .zip(wavelengths_nm)
                .map(|((images, &band), &w)| BandImages {
                    wavelength_nm: Some(w),
                    band: Some(band),
                    images,
                })
                .collect();
            bands.sort_by(|a, b| {
                a.wavelength_nm
                    .partial_cmp(&b.wavelength_nm)
                    .unwrap_or(std::cmp::Ordering::Equal)
            });
            Ok(bands)
        }
        _ => Ok(vec![BandImages {
            wavelength_nm: c.wavelength_nm,
            band: None,
            images: capture_images(m, c)?,
        }]),
    }
}
