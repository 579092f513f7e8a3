//! Per-band Stokes images of a capture: the entry point of per-band measurement for
//! colour polarization cameras (docs/FORMATS.md, "Colour polarization cameras").
//!
//! [`capture_band_images`] returns one [`BandImages`] per band of a capture: one for a
//! single-band capture (rotating-polarizer frames, monochrome DoFP, Stokes files — the
//! images of [`crate::measure::capture_images`], with the capture's `wavelength_nm`),
//! one per colour of a colour DoFP capture in increasing wavelength, each at full
//! resolution in raw pixel coordinates (bilinear per lattice,
//! [`polarid_core::mosaic::colour`]; region standard errors use
//! [`Sampling::BilinearColour`]), so that region rectangles apply to every band. Every
//! band gets the capture's dark threshold ([`dark_threshold_dn`]); an HDR colour
//! capture's brackets are merged on the raw mosaic before the reconstruction
//! ([`COLOUR_REACH`]). `polarid_io::measure::measure_capture_bands` turns them into
//! measurement rows with `wavelength_nm`.
//!
//! A colour mosaic whose width or height is not a whole number of 4×4 periods (a
//! sensor read out with a partial period at the right or bottom edge) is measured on
//! its whole periods: the partial period's columns and rows are dropped
//! ([`polarid_core::mosaic::crop_to_whole_periods`]; pixel coordinates are unchanged,
//! the images are the whole periods' size) and a warning in
//! [`StokesImages::warnings`] says so.

use polarid_core::mosaic::{ColourMethod, ColourPattern, DofpOutputs, colour_polar};
use polarid_core::region::Sampling;
use polarid_core::stokes::PixelRules;

use crate::error::{IoError, Result};
use crate::image::{self, Frame, SampleKind};
use crate::manifest::{Capture, CaptureSource, Manifest};
use crate::measure::{
    StokesImages, capture_images, dark_threshold_dn, rules_for, saturation_notes,
};

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
    let counts = colour_polar(&raw.data, raw.width, pattern, method, rules, outs)
        .map_err(|source| IoError::core(&raw.path, source))?;
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
        CaptureSource::ColourDofp { file, .. } if c.brackets.is_empty() => {
            colour_frame_images(c, image::read_frame(file)?)
        }
        CaptureSource::ColourDofp { pattern, .. } => {
            let (imgs, dark_signal_dn, notes) = hdr_colour_images(m, c, pattern)?;
            Ok(colour_bands(c, imgs, dark_signal_dn, notes))
        }
        _ => Ok(vec![BandImages {
            wavelength_nm: c.wavelength_nm,
            band: None,
            images: capture_images(m, c)?,
        }]),
    }
}

/// [`capture_band_images`] of a colour capture `c` (one exposure) whose raw mosaic is
/// `raw`, read or made in memory.
///
/// Errors: those of [`colour_stokes`]; [`IoError::Image`] naming the raw file when `c` is
/// not a colour capture.
pub fn colour_frame_images(c: &Capture, raw: Frame) -> Result<Vec<BandImages>> {
    let CaptureSource::ColourDofp { pattern, .. } = &c.source else {
        return Err(IoError::Image {
            path: raw.path.clone(),
            reason: format!("capture {} is not a colour capture", c.index),
        });
    };
    let rules = rules_for(&raw, c.dark_level, c.saturation);
    let mut notes = saturation_notes(c, [&raw], rules.saturation);
    let raw = whole_periods(c, raw, &mut notes)?;
    let imgs = colour_stokes(&raw, pattern, &rules, ColourMethod::Bilinear)?;
    let dark_signal_dn = dark_threshold_dn(c, &rules, raw.kind.is_integer());
    Ok(colour_bands(c, imgs, dark_signal_dn, notes))
}

/// The Stokes images `imgs` of colour capture `c` (one per band of its pattern) as
/// [`BandImages`] in increasing wavelength, each with the capture's dark threshold and
/// warnings.
fn colour_bands(
    c: &Capture,
    imgs: Vec<StokesImages>,
    dark_signal_dn: f64,
    notes: Vec<String>,
) -> Vec<BandImages> {
    let CaptureSource::ColourDofp {
        pattern,
        wavelengths_nm,
        ..
    } = &c.source
    else {
        return Vec::new();
    };
    let mut bands: Vec<BandImages> = imgs
        .into_iter()
        .zip(pattern.bands())
        .zip(wavelengths_nm)
        .map(|((mut images, &band), &w)| {
            images.dark_signal_dn = dark_signal_dn;
            images.warnings = notes.clone();
            BandImages {
                wavelength_nm: Some(w),
                band: Some(band),
                images,
            }
        })
        .collect();
    bands.sort_by(|a, b| {
        a.wavelength_nm
            .partial_cmp(&b.wavelength_nm)
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    bands
}

/// `raw` cut to its whole 4×4 periods when its width or height is not a multiple of 4
/// (module docs), with a warning naming capture `c`, the file and both sizes pushed to
/// `notes`; `raw` itself otherwise.
///
/// Errors: [`IoError::Core`] naming the file when not one whole period is left.
fn whole_periods(c: &Capture, raw: Frame, notes: &mut Vec<String>) -> Result<Frame> {
    let cropped = polarid_core::mosaic::crop_to_whole_periods(&raw.data, raw.width)
        .map_err(|source| IoError::core(&raw.path, source))?;
    let Some((data, width, height)) = cropped else {
        return Ok(raw);
    };
    notes.push(format!(
        "capture {} (line {}): {} is {}x{} pixels, not a whole number of 4x4 colour \
         periods: the partial period is dropped and the capture is measured on its \
         {width}x{height} whole periods (regions must lie inside them)",
        c.index,
        c.line,
        raw.path.display(),
        raw.width,
        raw.height
    ));
    Ok(Frame {
        data,
        width,
        height,
        ..raw
    })
}

/// How far (pixels, in x and in y) the bilinear colour reconstruction reaches for a
/// pixel's samples: a lattice of period 4 is interpolated from its samples at most 3
/// pixels away ([`polarid_core::mosaic::colour`]).
pub const COLOUR_REACH: usize = 3;

/// `true` at every pixel within [`COLOUR_REACH`] (in x and y) of a pixel where `bad` is
/// true: a separable dilation of a `width`-wide mask.
fn dilate(bad: &[bool], width: usize, reach: usize) -> Vec<bool> {
    let height = bad.len() / width.max(1);
    let mut rows = vec![false; bad.len()];
    for y in 0..height {
        let row = &bad[y * width..(y + 1) * width];
        for x in 0..width {
            let lo = x.saturating_sub(reach);
            let hi = (x + reach + 1).min(width);
            rows[y * width + x] = row[lo..hi].iter().any(|&b| b);
        }
    }
    let mut out = vec![false; bad.len()];
    for y in 0..height {
        let lo = y.saturating_sub(reach);
        let hi = (y + reach + 1).min(height);
        for x in 0..width {
            out[y * width + x] = (lo..hi).any(|yy| rows[yy * width + x]);
        }
    }
    out
}

/// Per-band Stokes images of an HDR colour capture (its [`Capture::brackets`], longest
/// exposure first) and its dark threshold (DN): the raw mosaics merged per pixel as for a
/// monochrome DoFP ([`crate::measure::hdr_images`]), each raw pixel taking its value from
/// the longest exposure in which no raw value within [`COLOUR_REACH`] pixels (the
/// neighbourhood the bilinear colour reconstruction reads) is saturated, dark subtracted
/// and scaled to the longest exposure's DN; then reconstructed per band.
///
/// Errors: the image reader's (a missing file, brackets of different sizes, naming the
/// file), [`IoError::Core`] naming the first file.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose: NaN is not usable
fn hdr_colour_images(
    m: &Manifest,
    c: &Capture,
    pattern: &ColourPattern,
) -> Result<(Vec<StokesImages>, f64, Vec<String>)> {
    let paths = c.files();
    let frames = image::read_frames(&paths)?;
    let (Some(first), Some(reference)) = (frames.first(), c.brackets.first()) else {
        return Err(c.field_error(&m.path, "brackets", "", "no frames"));
    };
    let raw_rules = rules_for(first, c.dark_level, c.saturation);
    let mut notes = saturation_notes(c, &frames, raw_rules.saturation);
    let (dark, sat) = (raw_rules.dark_level, raw_rules.saturation);
    let near: Vec<Vec<bool>> = frames
        .iter()
        .map(|f| {
            let bad: Vec<bool> = f.data.iter().map(|&v| !(v < sat)).collect();
            dilate(&bad, f.width, COLOUR_REACH)
        })
        .collect();
    let scale: Vec<f32> = c
        .brackets
        .iter()
        .map(|b| (reference.exposure / b.exposure) as f32)
        .collect();
    let data: Vec<f32> = (0..first.data.len())
        .map(|p| match (0..frames.len()).find(|&b| !near[b][p]) {
            Some(b) => (frames[b].data[p] - dark) * scale[b],
            None => f32::MAX,
        })
        .collect();
    let merged = Frame {
        path: first.path.clone(),
        width: first.width,
        height: first.height,
        kind: SampleKind::F32,
        data,
        recorded_max: None,
    };
    // Merged values are dark-subtracted; f32::MAX marks a pixel saturated everywhere.
    let merged_rules = PixelRules {
        dark_level: 0.0,
        saturation: f32::MAX,
        min_s0: 0.0,
    };
    let merged = whole_periods(c, merged, &mut notes)?;
    let imgs = colour_stokes(&merged, pattern, &merged_rules, ColourMethod::Bilinear)?;
    Ok((
        imgs,
        dark_threshold_dn(c, &raw_rules, first.kind.is_integer()),
        notes,
    ))
}
