//! The measure pipeline shared by `polarid measure`, `polarid stokes` and the Python
//! bindings: capture files → Stokes images → region statistics → [`Measurement`] rows.
//!
//! - Rotating-polarizer frames: [`StokesSolver::compute`] with the capture's
//!   [`rules_for`] (dark level, saturation; default the type's maximum).
//! - DoFP mosaics: demosaiced by [`dofp_stokes`]; [`measure_manifest`] uses the bilinear
//!   reconstruction at full resolution (so that region rectangles are in raw pixel
//!   coordinates), not rounded, whose standard errors use the bilinear variance
//!   inflation ([`Sampling::BilinearDofp`]).
//! - Stokes captures (float TIFF) are used as they are: `dark_level` and `saturation` do
//!   not apply; pixels with `S0 <= 0` or non-finite values are rejected.
//!
//! For every region and capture a row holds the DoLP of the region's mean Stokes vector,
//! its standard error from the pixel scatter (`polarid_core::region`; an SE of 0, from
//! noiseless data, is left empty), the mean S0 divided by the capture's exposure, the
//! pixels used, rejected and saturated, and `beta` from the geometry (paper eq. 5).
//!
//! **Calibrated captures** (a `source` under a `[camera]`): every pixel of a region gets
//! its own `β`, `θi`, `θr`, `φ` and plane-of-incidence angle from
//! [`ViewGeometry::fill`] (the region's plane, the capture's source), and the row comes
//! from [`region_stats_local`]: the DoLP of the mean Stokes vector taken in each pixel's
//! plane-of-incidence frame, the S0-weighted mean geometry (`theta_i_deg`,
//! `theta_r_deg`, `phi_deg`, `beta_deg`) with `beta_sd_deg`, `aolp_deg` (image frame)
//! and `aolp_poi_deg` (from the plane of incidence; 90 for a single interface), and a
//! standard error from the scatter with the trend in β removed (docs/GEOMETRY.md).
//!
//! **HDR brackets** (a capture's `brackets`, [`hdr_images`]): the exposures are merged
//! per pixel before the Stokes solve: each pixel takes its values from the longest
//! exposure in which none of its raw values is saturated (for a DoFP mosaic: none of
//! the raw pixels of its 3×3 neighbourhood, which the bilinear demosaic uses), dark
//! subtracted and scaled by the exposure ratio to the longest exposure's DN. A pixel
//! saturated in every bracket is saturated. One bracket for all the polarizer angles of
//! a pixel keeps an error in the exposure ratios out of its DoLP.
//!
//! **Colour captures** (a `dofp` with `color`, docs/BANDS.md): a manifest with colour
//! captures is measured per band ([`measure_capture_bands`]): each colour mosaic is
//! reconstructed once into per-band Stokes images at full resolution
//! ([`crate::bands::capture_band_images`]) and every band gives one row per region with
//! `wavelength_nm`; the rules above (dark level, saturation, dark threshold, HDR
//! brackets, calibrated geometry) apply to each band.
//!
//! **Partial failure.** A region that is dark in a capture (its mean dark-subtracted S0
//! below the capture's dark threshold, [`dark_threshold_dn`]), or that has no usable
//! pixel there (all saturated, dark or invalid), gives a row with a [`RowStatus`] other
//! than `ok` and a reason instead of an error; `fit` skips such rows. With `strict`
//! ([`measure_manifest_with`]) the first such row is an error naming the region's
//! `rect`, as before.
//!
//! Nothing here prints: progress goes through a callback and saturation warnings are
//! returned as text ([`saturation_warnings`]) for the caller to show.

use std::path::{Path, PathBuf};

use polarid_core::CoreError;
use polarid_core::geometry::{self, GeometryMaps, PinholeCamera, Source, ViewGeometry};
use polarid_core::mosaic::{self, Pattern};
use polarid_core::region::{Rect, RegionGeometry, Sampling, region_stats, region_stats_local};
use polarid_core::stokes::{self, PixelCounts, PixelRules, StokesSolver};

use crate::error::{IoError, Result};
use crate::image::{self, Frame, SampleKind};
use crate::manifest::{Capture, CaptureSource, Manifest, Region, SourceSpec};
use crate::table::measurements::{Measurement, RowStatus};

/// Fraction of a region's pixels above which [`saturation_warnings`] reports saturation
/// (1 %).
pub const SATURATED_WARN: f64 = 0.01;

/// Default dark threshold of integer frames, as a fraction of the range from the dark
/// level to the saturation level (1 %, the `map`'s default dark threshold too): a
/// region whose mean dark-subtracted S0 is below it is `dark` (docs/FORMATS.md, "Dark
/// regions").
pub const DARK_FRACTION: f64 = 0.01;

/// How a DoFP mosaic is turned into Stokes images.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Demosaic {
    /// Full resolution, bilinear interpolation of each channel (OpenCV's /
    /// polanalyser's); region standard errors use [`Sampling::BilinearDofp`].
    Bilinear,
    /// Half resolution: one Stokes vector per 2x2 super-pixel.
    Superpixel,
}

/// Stokes images of one capture, with their pixel mask and counts.
#[derive(Debug, Clone, PartialEq)]
pub struct StokesImages {
    /// Width of the images, pixels.
    pub width: usize,
    /// Height of the images, pixels.
    pub height: usize,
    /// S0, row-major.
    pub s0: Vec<f32>,
    /// S1, row-major.
    pub s1: Vec<f32>,
    /// S2, row-major.
    pub s2: Vec<f32>,
    /// Pixel mask (values of `polarid_core::stokes::mask`).
    pub mask: Vec<u8>,
    /// Pixel counts (valid, saturated, dark, invalid).
    pub counts: PixelCounts,
    /// How the pixels relate, for region standard errors.
    pub sampling: Sampling,
    /// Dark threshold, in the units of `s0` (DN): a region whose mean S0 over its used
    /// pixels is below it is `dark` ([`dark_threshold_dn`]; 0: no dark test).
    pub dark_signal_dn: f64,
    /// What the user should know about how these images were made (a saturation level
    /// the data contradict, [`saturation_notes`]; a colour mosaic's partial period
    /// dropped), one message each.
    pub warnings: Vec<String>,
}

impl StokesImages {
    /// Zeroed images of `width × height` pixels.
    pub fn alloc(width: usize, height: usize, sampling: Sampling) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            s0: vec![0.0; n],
            s1: vec![0.0; n],
            s2: vec![0.0; n],
            mask: vec![0; n],
            counts: PixelCounts::default(),
            sampling,
            dark_signal_dn: 0.0,
            warnings: Vec::new(),
        }
    }
}

/// The dark threshold of capture `c` (DN of dark-subtracted S0) for frames whose pixel
/// rules are `rules`: the capture's `dark_signal_dn` when given; else, for integer
/// frames, [`DARK_FRACTION`] of the range from the dark level to the saturation level
/// (12-bit frames with a dark level of 64: 40.3 DN); else 0 (float frames: no dark test).
///
/// Why a level in DN and not in standard errors: a region's DoLP is that of its mean
/// Stokes vector, so the pixels' random noise averages out and its upward (Rice) bias,
/// about `dolp_se² / (2 DoLP)`, stays far below `dolp_se`; what does not average out at
/// low signal is the 1-DN quantization of each polarizer frame and the clipping of the
/// read noise at the dark level (pixels at or below it are rejected, raw values below it
/// clipped), which bias S0 up and the DoLP down by an amount that no pixel count
/// removes. At 1 % of the range each frame of a 12-bit sensor holds about 20 DN,
/// several read-noise standard deviations above the clip, and one DN is a DoLP step of
/// about 0.05 per pixel, dithered away by the noise; at 1–5 DN the DoLP is meaningless.
pub fn dark_threshold_dn(c: &Capture, rules: &PixelRules, is_integer: bool) -> f64 {
    match c.dark_signal_dn {
        Some(v) => v,
        None if is_integer && rules.saturation.is_finite() => {
            DARK_FRACTION * f64::from(rules.saturation - rules.dark_level).max(0.0)
        }
        None => 0.0,
    }
}

/// Pixel rules from a dark level and an optional saturation (default: the largest
/// value the frame's file records for its samples, [`Frame::level_max`]: `2^bits − 1`
/// from a PNG `sBIT` chunk or a TIFF `MaxSampleValue` tag, else the type's maximum);
/// `min_s0` is 0.
pub fn rules_for(frame: &Frame, dark_level: f64, saturation: Option<f64>) -> PixelRules {
    PixelRules {
        dark_level: dark_level as f32,
        saturation: saturation.map_or(frame.level_max(), |s| s as f32),
        min_s0: 0.0,
    }
}

/// Largest sample value of a 16-bit file without a recorded bit depth below which
/// [`saturation_notes`] suspects a 10-, 12- or 14-bit camera (`2^14 − 1`).
pub const FEW_BITS_MAX: f32 = 16383.0;

/// `Some(b)` when `v` is `2^b − 1` for some `b` in `10..=15`: the ceiling of `b`-bit data.
fn ceiling_bits(v: f32) -> Option<u32> {
    (10..=15).find(|&b| v == ((1u32 << b) - 1) as f32)
}

/// What the data of capture `c`'s integer frames (`frames`, read with the saturation
/// level `saturation`) say against that level, one warning each (none for float
/// frames):
///
/// - values exceed a level that is a bit depth's ceiling (`2^b − 1`, given or recorded
///   in the file): the data have more bits than the level says, and every such pixel
///   is rejected as saturated;
/// - the values stop at exactly `2^b − 1` (the ceiling of `b`-bit data) below the
///   level: a `b`-bit camera's saturated pixels would be measured as if valid;
/// - the manifest gives no `saturation` and a 16-bit file records no bit depth (no PNG
///   `sBIT`, no TIFF `MaxSampleValue`), so the level is 65535, but no value exceeds
///   [`FEW_BITS_MAX`]: the data look like a 10-, 12- or 14-bit camera's.
pub fn saturation_notes<'a>(
    c: &Capture,
    frames: impl IntoIterator<Item = &'a Frame>,
    saturation: f32,
) -> Vec<String> {
    let frames: Vec<&Frame> = frames.into_iter().collect();
    let Some(first) = frames.first() else {
        return Vec::new();
    };
    if !first.kind.is_integer() {
        return Vec::new();
    }
    let max = frames
        .iter()
        .map(|f| f.data_max())
        .fold(f32::NEG_INFINITY, f32::max);
    if !max.is_finite() {
        return Vec::new();
    }
    let file = first.path.display();
    let label = format!("capture {} (line {})", c.index, c.line);
    let source = match (c.saturation, first.recorded_max) {
        (Some(_), _) => "the manifest's `saturation`".to_string(),
        (None, Some(_)) => format!("the bit depth recorded in {file}"),
        (None, None) => format!(
            "the {}-bit samples' maximum: {file} records no bit depth",
            first.bit_depth()
        ),
    };
    let sat = saturation;
    let mut out = Vec::new();
    if max > sat {
        let level_is_depth = ceiling_bits(sat).is_some() || first.recorded_max == Some(sat);
        if level_is_depth {
            out.push(format!(
                "{label}: {file} has values up to {max}, above the saturation level {sat} \
                 ({source}): the data have more bits than that, and every such pixel is \
                 rejected as saturated; check the bit depth and `saturation`"
            ));
        }
    } else if max < sat
        && let Some(b) = ceiling_bits(max)
    {
        out.push(format!(
            "{label}: the values of {file} stop at exactly {max} = 2^{b} - 1, the ceiling \
             of {b}-bit data, below the saturation level {sat} ({source}): if the camera \
             is {b}-bit, its saturated pixels are measured as if valid; set \
             `saturation = {max}`"
        ));
    } else if c.saturation.is_none()
        && first.recorded_max.is_none()
        && first.kind == SampleKind::U16
        && max <= FEW_BITS_MAX
    {
        let b = [10u32, 12, 14]
            .into_iter()
            .find(|&b| max <= ((1u32 << b) - 1) as f32)
            .unwrap_or(14);
        out.push(format!(
            "{label}: no `saturation` is given and {file} records no bit depth (16-bit \
             samples without a PNG sBIT chunk or a TIFF MaxSampleValue tag), so the \
             saturation level is 65535, but its values reach only {max}, as a {b}-bit \
             camera's would: if the camera has fewer than 16 bits, set `saturation` \
             (e.g. {} for {b} bits) or its saturated pixels are measured as if valid",
            (1u32 << b) - 1
        ));
    }
    out
}

/// Stokes images from rotating-polarizer frames (one per angle of `solver`, same size:
/// [`image::read_frames`] checks it).
///
/// Errors: [`IoError::Core`] naming the first frame's file when the solver rejects the
/// frames or rules (or `<no frames>` when `frames` is empty).
pub fn frames_stokes(
    frames: &[Frame],
    solver: &StokesSolver,
    rules: &PixelRules,
) -> Result<StokesImages> {
    let Some(first) = frames.first() else {
        return Err(IoError::Core {
            path: PathBuf::from("<no frames>"),
            source: CoreError::TooFew {
                what: "frames",
                needed: solver.len(),
                got: 0,
            },
        });
    };
    let mut out = StokesImages::alloc(first.width, first.height, Sampling::Independent);
    let views: Vec<&[f32]> = frames.iter().map(|f| f.data.as_slice()).collect();
    out.counts = solver
        .compute(
            &views,
            first.width,
            rules,
            &mut out.s0,
            &mut out.s1,
            &mut out.s2,
            &mut out.mask,
        )
        .map_err(|e| IoError::Core {
            path: first.path.clone(),
            source: e,
        })?;
    Ok(out)
}

/// Stokes images from a DoFP mosaic: [`Demosaic::Bilinear`] at full resolution
/// (interpolated values rounded to whole DN when `round`, as OpenCV does for integer
/// frames), or [`Demosaic::Superpixel`] at half resolution (`round` unused).
///
/// Errors: [`IoError::Core`] naming the raw file (odd size, bad rules, ...).
pub fn dofp_stokes(
    raw: &Frame,
    pattern: &Pattern,
    rules: &PixelRules,
    demosaic: Demosaic,
    round: bool,
) -> Result<StokesImages> {
    let wrap = |e| IoError::Core {
        path: raw.path.clone(),
        source: e,
    };
    let out = match demosaic {
        Demosaic::Bilinear => {
            let mut o = StokesImages::alloc(raw.width, raw.height, Sampling::BilinearDofp);
            o.counts = mosaic::bilinear_stokes(
                &raw.data,
                raw.width,
                pattern,
                rules,
                round,
                &mut o.s0,
                &mut o.s1,
                &mut o.s2,
                &mut o.mask,
            )
            .map_err(wrap)?;
            o
        }
        Demosaic::Superpixel => {
            let mut o = StokesImages::alloc(raw.width / 2, raw.height / 2, Sampling::Independent);
            o.counts = mosaic::superpixel_stokes(
                &raw.data,
                raw.width,
                pattern,
                rules,
                &mut o.s0,
                &mut o.s1,
                &mut o.s2,
                &mut o.mask,
            )
            .map_err(wrap)?;
            o
        }
    };
    Ok(out)
}

/// Stokes images read from three float TIFFs (S0, S1, S2 of the same size), masked by
/// `polarid_core::stokes::mask_stokes` (a pixel is rejected when a component is not
/// finite or `S0 <= 0`).
///
/// Errors: the reader's (missing file, different sizes), [`IoError::Image`] naming an
/// image that is not 32-bit float, [`IoError::Core`] naming `s0`.
pub fn read_stokes(s0: &Path, s1: &Path, s2: &Path) -> Result<StokesImages> {
    let imgs = image::read_frames(&[s0, s1, s2])?;
    for f in &imgs {
        image::check_float(f, "a Stokes image")?;
    }
    let got = imgs.len();
    let [f0, f1, f2]: [Frame; 3] = imgs.try_into().map_err(|_| IoError::Core {
        path: s0.to_path_buf(),
        source: CoreError::TooFew {
            what: "Stokes images",
            needed: 3,
            got,
        },
    })?;
    let (width, height) = (f0.width, f0.height);
    let mut mask = vec![0u8; width * height];
    let counts =
        stokes::mask_stokes(width, &f0.data, &f1.data, &f2.data, 0.0, &mut mask).map_err(|e| {
            IoError::Core {
                path: s0.to_path_buf(),
                source: e,
            }
        })?;
    Ok(StokesImages {
        width,
        height,
        s0: f0.data,
        s1: f1.data,
        s2: f2.data,
        mask,
        counts,
        sampling: Sampling::Independent,
        dark_signal_dn: 0.0,
        warnings: Vec::new(),
    })
}

/// Stokes images of one capture of `m`, as `polarid measure` uses them (DoFP: bilinear,
/// full resolution, not rounded).
///
/// Errors: the image reader's (file named), [`IoError::Manifest`] naming the capture's
/// `frames` field and the angles when they cannot be inverted (the manifest loader
/// already rejects them), [`IoError::Core`] naming the file whose data the Stokes
/// kernels reject.
pub fn capture_images(m: &Manifest, c: &Capture) -> Result<StokesImages> {
    if !c.brackets.is_empty() {
        return hdr_images(m, c);
    }
    match &c.source {
        CaptureSource::Frames(frames) => {
            let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
            let solver = StokesSolver::from_degrees(&angles).map_err(|e| IoError::Manifest {
                path: m.path.clone(),
                line: c.line,
                field: format!("capture[{}].frames", c.index),
                value: format!("{angles:?}"),
                reason: e.to_string(),
            })?;
            let paths: Vec<&Path> = frames.iter().map(|f| f.file.as_path()).collect();
            let imgs = image::read_frames(&paths)?;
            let Some(first) = imgs.first() else {
                return frames_stokes(&imgs, &solver, &PixelRules::default());
            };
            let rules = rules_for(first, c.dark_level, c.saturation);
            let mut out = frames_stokes(&imgs, &solver, &rules)?;
            out.dark_signal_dn = dark_threshold_dn(c, &rules, first.kind.is_integer());
            out.warnings = saturation_notes(c, &imgs, rules.saturation);
            Ok(out)
        }
        CaptureSource::Dofp { file, pattern } => {
            let raw = image::read_frame(file)?;
            let rules = rules_for(&raw, c.dark_level, c.saturation);
            let mut out = dofp_stokes(&raw, pattern, &rules, Demosaic::Bilinear, false)?;
            out.dark_signal_dn = dark_threshold_dn(c, &rules, raw.kind.is_integer());
            out.warnings = saturation_notes(c, [&raw], rules.saturation);
            Ok(out)
        }
        CaptureSource::Stokes { s0, s1, s2 } => {
            let mut out = read_stokes(s0, s1, s2)?;
            out.dark_signal_dn = c.dark_signal_dn.unwrap_or(0.0);
            Ok(out)
        }
        CaptureSource::ColourDofp { .. } => Err(IoError::Manifest {
            path: m.path.clone(),
            line: c.line,
            field: format!("capture[{}].dofp.color", c.index),
            value: "color".into(),
            reason: "a colour capture has one set of Stokes images per band: use \
                     polarid_io::bands::capture_band_images"
                .into(),
        }),
    }
}

/// The bracket each pixel of an HDR capture takes its values from: the first (longest)
/// of `saturated_at(b, p)` false, `None` when every bracket is saturated there.
fn pick_brackets(
    n: usize,
    brackets: usize,
    saturated_at: impl Fn(usize, usize) -> bool,
) -> Vec<Option<usize>> {
    (0..n)
        .map(|p| (0..brackets).find(|&b| !saturated_at(b, p)))
        .collect()
}

/// Stokes images of an HDR capture (its [`Capture::brackets`], longest exposure first):
/// the brackets merged per pixel (module docs), in DN of the longest exposure with the
/// dark level removed, then solved as one capture (DoFP: bilinear, full resolution).
///
/// Errors: the image reader's (a missing or unreadable file, brackets of different
/// sizes, naming the file), [`IoError::Manifest`] naming `capture[i].brackets` when the
/// angles cannot be inverted, [`IoError::Core`] naming the first file.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose: NaN is not usable
pub fn hdr_images(m: &Manifest, c: &Capture) -> Result<StokesImages> {
    let nb = c.brackets.len();
    let paths: Vec<&Path> = c.files();
    let frames = image::read_frames(&paths)?;
    let (Some(first), Some(reference)) = (frames.first(), c.brackets.first()) else {
        return Err(IoError::Manifest {
            path: m.path.clone(),
            line: c.line,
            field: format!("capture[{}].brackets", c.index),
            value: String::new(),
            reason: "no frames".into(),
        });
    };
    let per = frames.len() / nb.max(1);
    let (width, height, n) = (first.width, first.height, first.data.len());
    let raw_rules = rules_for(first, c.dark_level, c.saturation);
    let (dark, sat) = (raw_rules.dark_level, raw_rules.saturation);
    // Merged values are dark-subtracted; f32::MAX marks a pixel saturated everywhere.
    let merged_rules = PixelRules {
        dark_level: 0.0,
        saturation: f32::MAX,
        min_s0: 0.0,
    };
    let scale: Vec<f32> = c
        .brackets
        .iter()
        .map(|b| (reference.exposure / b.exposure) as f32)
        .collect();
    let value = |b: usize, a: usize, p: usize| frames[b * per + a].data[p];
    let merge = |pick: &[Option<usize>], a: usize| -> Vec<f32> {
        pick.iter()
            .enumerate()
            .map(|(p, b)| match b {
                Some(b) => (value(*b, a, p) - dark) * scale[*b],
                None => f32::MAX,
            })
            .collect()
    };
    let as_frame = |data: Vec<f32>, k: usize| Frame {
        path: frames[k].path.clone(),
        width,
        height,
        kind: SampleKind::F32,
        data,
        recorded_max: None,
    };
    let mut out = match &reference.source {
        CaptureSource::Frames(refs) => {
            let angles: Vec<f64> = refs.iter().map(|f| f.angle_deg).collect();
            let solver = StokesSolver::from_degrees(&angles).map_err(|e| IoError::Manifest {
                path: m.path.clone(),
                line: c.line,
                field: format!("capture[{}].brackets", c.index),
                value: format!("{angles:?}"),
                reason: e.to_string(),
            })?;
            // Not `< sat` is saturated: NaN counts as saturated too.
            let pick = pick_brackets(n, nb, |b, p| (0..per).any(|a| !(value(b, a, p) < sat)));
            let merged: Vec<Frame> = (0..per).map(|a| as_frame(merge(&pick, a), a)).collect();
            frames_stokes(&merged, &solver, &merged_rules)?
        }
        CaptureSource::Dofp { pattern, .. } => {
            let near_saturated = |b: usize, p: usize| {
                let (x, y) = (p % width, p / width);
                (y.saturating_sub(1)..(y + 2).min(height)).any(|yy| {
                    (x.saturating_sub(1)..(x + 2).min(width))
                        .any(|xx| !(value(b, 0, yy * width + xx) < sat))
                })
            };
            let pick = pick_brackets(n, nb, near_saturated);
            dofp_stokes(
                &as_frame(merge(&pick, 0), 0),
                pattern,
                &merged_rules,
                Demosaic::Bilinear,
                false,
            )?
        }
        CaptureSource::Stokes { s0, .. } => {
            return Err(IoError::Manifest {
                path: m.path.clone(),
                line: c.line,
                field: format!("capture[{}].brackets", c.index),
                value: s0.display().to_string(),
                reason: "HDR brackets need raw data (`frames` or `dofp`), not Stokes images".into(),
            });
        }
        CaptureSource::ColourDofp { file, .. } => {
            return Err(IoError::Manifest {
                path: m.path.clone(),
                line: c.line,
                field: format!("capture[{}].brackets", c.index),
                value: file.display().to_string(),
                reason: "a colour capture has one set of Stokes images per band: use \
                         polarid_io::bands::capture_band_images"
                    .into(),
            });
        }
    };
    out.dark_signal_dn = dark_threshold_dn(c, &raw_rules, first.kind.is_integer());
    out.warnings = saturation_notes(c, &frames, raw_rules.saturation);
    Ok(out)
}

/// The capture's scattering angle `beta` in degrees (paper eq. 5) from its
/// `theta_i_deg`, `theta_r_deg` and `phi_deg`.
pub fn beta_deg(c: &Capture) -> f64 {
    geometry::beta(
        c.theta_i_deg.to_radians(),
        c.theta_r_deg.to_radians(),
        c.phi_deg.to_radians(),
    )
    .to_degrees()
}

/// One row per region of `m` (in region order) for capture `c`: far-field or, for a
/// capture with a `source` (calibrated geometry), per-pixel geometry (module docs). In
/// a manifest with colour captures, one row per region per band of `c`
/// ([`measure_capture_bands`]).
///
/// Errors: those of [`capture_images`] and [`measure_images`].
pub fn measure_capture(m: &Manifest, c: &Capture) -> Result<Vec<Measurement>> {
    if has_colour(m) {
        return measure_capture_bands(m, c, false);
    }
    let img = capture_images(m, c)?;
    measure_images(m, c, &img)
}

/// One row per region of `m` (in region order) from `img`, the Stokes images of capture
/// `c` (as [`capture_images`] makes them); a dark region or one without a usable pixel
/// gives a row with its [`RowStatus`] and reason (module docs).
///
/// Errors: [`IoError::Manifest`] naming the region's `rect` (line, value) when it leaves
/// the frame, or (calibrated geometry) has a pixel whose ray misses its plane; the
/// reason names the capture, its first file and the frame size. A source below the
/// plane's horizon at some pixel of a region names the capture's `source` field and the
/// target.
pub fn measure_images(m: &Manifest, c: &Capture, img: &StokesImages) -> Result<Vec<Measurement>> {
    measure_images_with(m, c, img, false)
}

/// [`measure_images`]; with `strict`, a row that is not `ok` is an error instead (an
/// [`IoError::Manifest`] naming the region's `rect`, the capture and the reason).
pub fn measure_images_with(
    m: &Manifest,
    c: &Capture,
    img: &StokesImages,
    strict: bool,
) -> Result<Vec<Measurement>> {
    let first_file = c
        .source
        .files()
        .first()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let rect_err = |r: &Region, reason: String| IoError::Manifest {
        path: m.path.clone(),
        line: r.line,
        field: format!("region[{}].rect", r.index),
        value: format!(
            "[{}, {}, {}, {}]",
            r.rect.x, r.rect.y, r.rect.width, r.rect.height
        ),
        reason: format!(
            "in capture {} (line {}, {first_file}, {}x{} pixels): {reason}",
            c.index, c.line, img.width, img.height
        ),
    };
    let rows = if let Some(spec) = &c.illumination {
        calibrated_rows(m, c, spec, img, &rect_err)?
    } else {
        far_field_rows(m, c, img, &rect_err)?
    };
    if strict && let Some((r, row)) = m.regions.iter().zip(&rows).find(|(_, x)| !x.status.is_ok()) {
        return Err(rect_err(r, format!("{}: {}", row.status, row.reason)));
    }
    Ok(rows)
}

/// Pixel counts of `rect` (inside the image): valid, saturated, dark, invalid.
fn rect_counts(img: &StokesImages, rect: Rect) -> [u64; 4] {
    let mut cnt = [0u64; 4];
    for y in rect.y..rect.y + rect.height {
        let o = y * img.width;
        for m in img
            .mask
            .get(o + rect.x..o + rect.x + rect.width)
            .unwrap_or(&[])
        {
            cnt[(m & 3) as usize] += 1;
        }
    }
    cnt
}

/// The label of a capture in reasons: `capture 8 "L08"` or `capture 8`.
fn capture_label(c: &Capture) -> String {
    match &c.name {
        Some(n) => format!("capture {} {n:?}", c.index),
        None => format!("capture {}", c.index),
    }
}

/// The status of a region of capture `c` with pixel counts `cnt` (valid, saturated,
/// dark, invalid) and, when it has valid pixels, mean S0 `s0_dn` (DN, before the
/// exposure): `ok`, `dark` (mean S0 below `img.dark_signal_dn`), or for a region without
/// a usable pixel the most common reason of its rejections.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
fn row_status(c: &Capture, img: &StokesImages, cnt: [u64; 4], s0_dn: f64) -> (RowStatus, String) {
    let [_, sat, dark, invalid] = cnt;
    let area: u64 = cnt.iter().sum();
    let cap = capture_label(c);
    if cnt[0] == 0 {
        let status = if sat >= dark && sat >= invalid {
            RowStatus::Saturated
        } else if dark >= invalid {
            RowStatus::Dark
        } else {
            RowStatus::Invalid
        };
        return (
            status,
            format!("{cap}: has no usable pixel ({sat} saturated, {dark} dark, {invalid} invalid)"),
        );
    }
    // `!(x >= t)`: a NaN mean is dark too.
    if img.dark_signal_dn > 0.0 && !(s0_dn >= img.dark_signal_dn) {
        return (
            RowStatus::Dark,
            format!(
                "{cap}: mean S0 {s0_dn:.3} DN is below the dark threshold {:.3} DN \
                 ({dark} of {area} pixels at or below the dark level); the DoLP of so \
                 low a signal is biased",
                img.dark_signal_dn
            ),
        );
    }
    (RowStatus::Ok, String::new())
}

/// The row of a region without a usable pixel: counts, status and reason, no values.
fn empty_row(
    r: &Region,
    c: &Capture,
    cnt: [u64; 4],
    status: (RowStatus, String),
    beta_deg: f64,
) -> Measurement {
    let far = c.illumination.is_none();
    Measurement {
        target: r.name.clone(),
        class: r.class.clone(),
        theta_i_deg: far.then_some(c.theta_i_deg),
        theta_r_deg: far.then_some(c.theta_r_deg),
        phi_deg: if far { c.phi_deg } else { f64::NAN },
        beta_deg,
        dolp: f64::NAN,
        dolp_se: None,
        s0: None,
        pixels: Some(0),
        rejected: Some(cnt[1] + cnt[2] + cnt[3]),
        exposure: Some(c.exposure),
        saturated: Some(cnt[1]),
        beta_sd_deg: None,
        aolp_deg: None,
        aolp_poi_deg: None,
        angle_sd_deg: c.angle_sd_deg,
        status: status.0,
        reason: status.1,
        wavelength_nm: c.wavelength_nm,
    }
}

/// The rows of a far-field capture.
fn far_field_rows(
    m: &Manifest,
    c: &Capture,
    img: &StokesImages,
    rect_err: &dyn Fn(&Region, String) -> IoError,
) -> Result<Vec<Measurement>> {
    let beta_deg = beta_deg(c);
    let mut rows = Vec::with_capacity(m.regions.len());
    for r in &m.regions {
        r.rect
            .check(img.width, img.height)
            .map_err(|e| rect_err(r, e.to_string()))?;
        let cnt = rect_counts(img, r.rect);
        if cnt[0] == 0 {
            let st = row_status(c, img, cnt, f64::NAN);
            rows.push(empty_row(r, c, cnt, st, beta_deg));
            continue;
        }
        let st = region_stats(
            img.width,
            &img.s0,
            &img.s1,
            &img.s2,
            &img.mask,
            r.rect,
            img.sampling,
        )
        .map_err(|e| rect_err(r, e.to_string()))?;
        let (status, reason) = row_status(c, img, cnt, st.s0());
        rows.push(Measurement {
            target: r.name.clone(),
            class: r.class.clone(),
            theta_i_deg: Some(c.theta_i_deg),
            theta_r_deg: Some(c.theta_r_deg),
            phi_deg: c.phi_deg,
            beta_deg,
            dolp: st.dolp,
            // Noiseless data have no scatter; an SE of 0 is left empty (the CSV
            // contract requires dolp_se > 0 when present).
            dolp_se: st.dolp_se.filter(|se| se.is_finite() && *se > 0.0),
            s0: Some(st.s0() / c.exposure),
            pixels: Some(st.pixels),
            rejected: Some(st.rejected),
            exposure: Some(c.exposure),
            saturated: Some(st.saturated),
            beta_sd_deg: None,
            aolp_deg: None,
            aolp_poi_deg: None,
            angle_sd_deg: c.angle_sd_deg,
            status,
            reason,
            wavelength_nm: c.wavelength_nm,
        });
    }
    Ok(rows)
}

/// The source of a capture as written in the manifest (`{ position = [..] }`, ...).
fn source_text(s: &SourceSpec) -> String {
    match s {
        SourceSpec::Position(p) => format!("{{ position = {p:?} }}"),
        SourceSpec::Direction(d) => format!("{{ direction = {d:?} }}"),
        SourceSpec::Sun { time, .. } => format!("{{ sun = {time:?} }}"),
    }
}

/// The per-pixel geometry of region `r` (its plane, `camera`) lit by `source`: five
/// maps over its rectangle, `[β | θi | θr | φ | ψ]`, radians.
///
/// Errors: [`IoError::Manifest`] naming the region's `rect` (a pixel whose ray misses
/// the plane) or, for a source below the plane's horizon at some pixel, the capture's
/// `source` field and the target.
fn region_geometry(
    m: &Manifest,
    c: &Capture,
    spec: &SourceSpec,
    camera: PinholeCamera,
    source: &Source,
    r: &Region,
    rect_err: &dyn Fn(&Region, String) -> IoError,
) -> Result<Vec<f64>> {
    let plane_spec = m.planes.get(r.plane);
    let plane_name = plane_spec.map_or("", |p| p.name.as_str());
    let vg = plane_spec
        .ok_or(CoreError::InvalidRegion {
            x: r.rect.x,
            y: r.rect.y,
            width: r.rect.width,
            height: r.rect.height,
            reason: format!("has no plane (index {})", r.plane),
        })
        .and_then(|p| p.to_plane())
        .and_then(|p| ViewGeometry::new(camera, p))
        .map_err(|e| rect_err(r, format!("{e} (plane {plane_name:?})")))?;
    let area = r.rect.width * r.rect.height;
    let mut maps = vec![0.0f64; 5 * area];
    let (beta, rest) = maps.split_at_mut(area);
    let (theta_i, rest) = rest.split_at_mut(area);
    let (theta_r, rest) = rest.split_at_mut(area);
    let (phi, poi) = rest.split_at_mut(area);
    let filled = vg.fill(
        r.rect,
        source,
        GeometryMaps {
            beta,
            theta_i,
            theta_r,
            phi,
            poi_angle: Some(poi),
        },
    );
    match filled {
        Ok(()) => Ok(maps),
        Err(e @ CoreError::SourceBelowHorizon { .. }) => Err(IoError::Manifest {
            path: m.path.clone(),
            line: c.line,
            field: format!("capture[{}].source.{}", c.index, spec.key()),
            value: source_text(spec),
            reason: format!(
                "for target {:?} (region[{}], plane {plane_name:?}): {e}",
                r.name, r.index
            ),
        }),
        Err(e) => Err(rect_err(
            r,
            format!("{e} (plane {plane_name:?}, source {})", source_text(spec)),
        )),
    }
}

/// The β (eq. 5, degrees) of every pixel of a `width × height` image lit by capture `c`
/// of `m` and seen on plane `plane` (an index into [`Manifest::planes`]), row-major; NaN
/// where a pixel has no geometry (its ray misses the plane, or the source is below the
/// plane's horizon there). `None` for a far-field capture (one β: [`beta_deg`]). For
/// drawing a capture's geometry (the report's β map).
///
/// Errors: [`IoError::Manifest`] naming `capture[j].source` when the manifest has no
/// camera or `plane` is not one of its planes (or the camera is behind it).
pub fn beta_map(
    m: &Manifest,
    c: &Capture,
    plane: usize,
    width: usize,
    height: usize,
) -> Result<Option<Vec<f32>>> {
    let Some(spec) = &c.illumination else {
        return Ok(None);
    };
    let err = |reason: String| IoError::Manifest {
        path: m.path.clone(),
        line: c.line,
        field: format!("capture[{}].source", c.index),
        value: source_text(spec),
        reason,
    };
    let camera = m
        .camera
        .as_ref()
        .ok_or_else(|| err("a source needs a [camera] table".into()))?
        .to_camera();
    let source = spec
        .to_source()
        .ok_or_else(|| err("the source could not be resolved".into()))?;
    let vg = m
        .planes
        .get(plane)
        .ok_or_else(|| err(format!("no plane with index {plane}")))?
        .to_plane()
        .and_then(|p| ViewGeometry::new(camera, p))
        .map_err(|e| err(e.to_string()))?;
    let mut out = vec![f32::NAN; width * height];
    for (v, row) in out.chunks_mut(width.max(1)).enumerate() {
        for (u, px) in row.iter_mut().enumerate() {
            if let Ok(g) = vg.pixel(u as f64, v as f64, &source) {
                *px = g.beta.to_degrees() as f32;
            }
        }
    }
    Ok(Some(out))
}

/// The rows of a capture with calibrated geometry ([`region_stats_local`] per region).
fn calibrated_rows(
    m: &Manifest,
    c: &Capture,
    spec: &SourceSpec,
    img: &StokesImages,
    rect_err: &dyn Fn(&Region, String) -> IoError,
) -> Result<Vec<Measurement>> {
    let no_geometry = |reason: &str| IoError::Manifest {
        path: m.path.clone(),
        line: c.line,
        field: format!("capture[{}].source", c.index),
        value: source_text(spec),
        reason: reason.into(),
    };
    let camera = m
        .camera
        .as_ref()
        .ok_or_else(|| no_geometry("a source needs a [camera] table"))?
        .to_camera();
    let source = spec
        .to_source()
        .ok_or_else(|| no_geometry("the source could not be resolved"))?;
    let mut rows = Vec::with_capacity(m.regions.len());
    for r in &m.regions {
        r.rect
            .check(img.width, img.height)
            .map_err(|e| rect_err(r, e.to_string()))?;
        let maps = region_geometry(m, c, spec, camera, &source, r, rect_err)?;
        let cnt = rect_counts(img, r.rect);
        if cnt[0] == 0 {
            let st = row_status(c, img, cnt, f64::NAN);
            rows.push(empty_row(r, c, cnt, st, f64::NAN));
            continue;
        }
        let area = r.rect.width * r.rect.height;
        let geom = RegionGeometry {
            beta: &maps[..area],
            theta_i: &maps[area..2 * area],
            theta_r: &maps[2 * area..3 * area],
            phi: &maps[3 * area..4 * area],
            poi_angle: &maps[4 * area..],
        };
        let st = region_stats_local(
            img.width,
            &img.s0,
            &img.s1,
            &img.s2,
            &img.mask,
            r.rect,
            img.sampling,
            &geom,
        )
        .map_err(|e| rect_err(r, e.to_string()))?;
        let finite_deg = |x: f64| x.is_finite().then(|| x.to_degrees());
        let (status, reason) = row_status(c, img, cnt, st.stats.s0());
        rows.push(Measurement {
            target: r.name.clone(),
            class: r.class.clone(),
            theta_i_deg: Some(st.theta_i.to_degrees()),
            theta_r_deg: Some(st.theta_r.to_degrees()),
            phi_deg: st.phi.to_degrees(),
            beta_deg: st.beta.to_degrees(),
            dolp: st.stats.dolp,
            dolp_se: st.stats.dolp_se.filter(|se| se.is_finite() && *se > 0.0),
            s0: Some(st.stats.s0() / c.exposure),
            pixels: Some(st.stats.pixels),
            rejected: Some(st.stats.rejected),
            exposure: Some(c.exposure),
            saturated: Some(st.stats.saturated),
            beta_sd_deg: Some(st.beta_sd.to_degrees()),
            aolp_deg: finite_deg(st.aolp),
            aolp_poi_deg: finite_deg(st.aolp_poi),
            angle_sd_deg: c.angle_sd_deg,
            status,
            reason,
            wavelength_nm: c.wavelength_nm,
        });
    }
    Ok(rows)
}

/// Measure every region of every capture of a loaded manifest: one row per target per
/// capture, targets of capture 1 in region order, then capture 2, ... (the rows of
/// `polarid measure`). A manifest with colour captures gives one row per target per
/// capture per band ([`measure_capture_bands`]). Dark regions and regions without a
/// usable pixel give rows with a status and a reason ([`measure_manifest_with`] with
/// `strict` false).
///
/// Captures are processed one after the other (each one in parallel inside), so memory
/// holds one capture at a time; `progress` is called with the number of captures done
/// after each one.
///
/// Errors: those of [`measure_capture`], for the first capture that fails.
pub fn measure_manifest(m: &Manifest, progress: &mut dyn FnMut(usize)) -> Result<Vec<Measurement>> {
    measure_manifest_with(m, false, progress)
}

/// [`measure_manifest`]; with `strict`, the first row that is not `ok` (a dark region,
/// one without a usable pixel) stops it with an error naming the region's `rect`.
pub fn measure_manifest_with(
    m: &Manifest,
    strict: bool,
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<Measurement>> {
    measure_manifest_report(m, strict, progress).map(|(rows, _)| rows)
}

/// [`measure_manifest_with`], with the warnings of the captures' images
/// ([`StokesImages::warnings`]: a saturation level the data contradict, a colour
/// mosaic's partial period dropped), in capture order.
///
/// Every capture must have the size of the first one (the regions' rectangles are in
/// one frame's pixel coordinates): a capture of another size is an [`IoError::Image`]
/// naming its first file, both captures and both sizes.
pub fn measure_manifest_report(
    m: &Manifest,
    strict: bool,
    progress: &mut dyn FnMut(usize),
) -> Result<(Vec<Measurement>, Vec<String>)> {
    let mut rows = Vec::with_capacity(m.captures.len() * m.regions.len());
    let mut warnings = Vec::new();
    let colour = has_colour(m);
    let mut first: Option<(&Capture, usize, usize)> = None;
    for (i, c) in m.captures.iter().enumerate() {
        if colour {
            check_band_wavelength(m, c)?;
            let bands = crate::bands::capture_band_images(m, c)?;
            if let Some(b) = bands.first() {
                check_capture_size(&mut first, c, b.images.width, b.images.height)?;
                warnings.extend(b.images.warnings.iter().cloned());
            }
            rows.extend(band_rows(m, c, &bands, strict)?);
        } else {
            let img = capture_images(m, c)?;
            check_capture_size(&mut first, c, img.width, img.height)?;
            warnings.extend(img.warnings.iter().cloned());
            rows.extend(measure_images_with(m, c, &img, strict)?);
        }
        progress(i + 1);
    }
    Ok((rows, warnings))
}

/// Error unless capture `c`'s images (`width × height`) have the size of the first
/// capture's (recorded in `first` by the first call).
fn check_capture_size<'a>(
    first: &mut Option<(&'a Capture, usize, usize)>,
    c: &'a Capture,
    width: usize,
    height: usize,
) -> Result<()> {
    let file_of = |c: &Capture| {
        c.files()
            .first()
            .map(|p| p.to_path_buf())
            .unwrap_or_default()
    };
    match first {
        None => {
            *first = Some((c, width, height));
            Ok(())
        }
        Some((c0, w0, h0)) if (*w0, *h0) != (width, height) => Err(IoError::Image {
            path: file_of(c),
            reason: format!(
                "capture {} (line {}) is {width}x{height} pixels but capture {} (line {}, \
                 {}) is {w0}x{h0}: every capture of a manifest must have the same size \
                 (the regions' rectangles are in one frame's pixel coordinates)",
                c.index,
                c.line,
                c0.index,
                c0.line,
                file_of(c0).display()
            ),
        }),
        Some(_) => Ok(()),
    }
}

/// Whether some capture of `m` is a colour capture ([`CaptureSource::ColourDofp`]): its
/// measurements are then per band, every row with a `wavelength_nm`.
pub fn has_colour(m: &Manifest) -> bool {
    m.captures
        .iter()
        .any(|c| matches!(c.source, CaptureSource::ColourDofp { .. }))
}

/// The number of bands capture `c` is measured in: the distinct colours of a colour
/// capture's pattern, else 1.
pub fn band_count(c: &Capture) -> usize {
    match &c.source {
        CaptureSource::ColourDofp { pattern, .. } => pattern.bands().len(),
        _ => 1,
    }
}

/// The rows of capture `c` of a manifest with colour captures: for each band of the
/// capture in increasing wavelength ([`crate::bands::capture_band_images`], the mosaic
/// read and reconstructed once), one row per region in region order, with
/// `wavelength_nm` the band's wavelength; a single-band capture gives its rows with its
/// own `wavelength_nm` (or the manifest's). The dark level, saturation, dark threshold,
/// HDR brackets and calibrated geometry apply to every band as to a monochrome capture;
/// the reasons of rows that are not `ok` name the band (`capture 2 band 450 nm: ...`).
///
/// Errors: those of [`measure_images_with`] (with `strict`, naming the band too);
/// [`IoError::Manifest`] naming `capture[i].wavelength_nm` for a single-band capture
/// without a wavelength (its rows could not be fitted with the colour captures' bands).
pub fn measure_capture_bands(m: &Manifest, c: &Capture, strict: bool) -> Result<Vec<Measurement>> {
    check_band_wavelength(m, c)?;
    let bands = crate::bands::capture_band_images(m, c)?;
    band_rows(m, c, &bands, strict)
}

/// Error unless capture `c` of a manifest with colour captures can be measured per band:
/// a single-band capture needs a wavelength.
fn check_band_wavelength(m: &Manifest, c: &Capture) -> Result<()> {
    if !matches!(c.source, CaptureSource::ColourDofp { .. }) && c.wavelength_nm.is_none() {
        return Err(IoError::Manifest {
            path: m.path.clone(),
            line: c.line,
            field: format!("capture[{}].wavelength_nm", c.index),
            value: String::new(),
            reason: "a manifest with colour captures measures every capture per band: give \
                     this single-band capture its wavelength_nm (or the top-level one)"
                .into(),
        });
    }
    Ok(())
}

/// The rows of capture `c` from its per-band images `bands` ([`measure_capture_bands`]).
fn band_rows(
    m: &Manifest,
    c: &Capture,
    bands: &[crate::bands::BandImages],
    strict: bool,
) -> Result<Vec<Measurement>> {
    check_band_wavelength(m, c)?;
    let label = capture_label(c);
    let mut rows = Vec::with_capacity(bands.len() * m.regions.len());
    for b in bands {
        let band_rows = measure_images_with(m, c, &b.images, false)?;
        let band = b.wavelength_nm.map_or_else(String::new, |w| {
            format!(" band {} nm", crate::manifest::colour::wavelength_label(w))
        });
        for (r, mut row) in m.regions.iter().zip(band_rows) {
            row.wavelength_nm = b.wavelength_nm;
            if !row.status.is_ok() {
                row.reason = row.reason.replacen(&label, &format!("{label}{band}"), 1);
                if strict {
                    let file = c
                        .source
                        .files()
                        .first()
                        .map(|p| p.display().to_string())
                        .unwrap_or_default();
                    return Err(IoError::Manifest {
                        path: m.path.clone(),
                        line: r.line,
                        field: format!("region[{}].rect", r.index),
                        value: format!(
                            "[{}, {}, {}, {}]",
                            r.rect.x, r.rect.y, r.rect.width, r.rect.height
                        ),
                        reason: format!(
                            "in capture {} (line {}, {file},{band}, {}x{} pixels): {}: {}",
                            c.index,
                            c.line,
                            b.images.width,
                            b.images.height,
                            row.status,
                            row.reason
                        ),
                    });
                }
            }
            rows.push(row);
        }
    }
    Ok(rows)
}

/// One message per row of `rows` (as [`measure_manifest`] returned them for `m`) where
/// more than [`SATURATED_WARN`] of the region's area is saturated, naming the target,
/// the capture (index and line) and the fraction.
pub fn saturation_warnings(m: &Manifest, rows: &[Measurement]) -> Vec<String> {
    let per_band = m.regions.len().max(1);
    // The capture of every row: `regions × bands` rows per capture.
    let colour = has_colour(m);
    let capture_of: Vec<usize> = m
        .captures
        .iter()
        .enumerate()
        .flat_map(|(i, c)| {
            let bands = if colour { band_count(c) } else { 1 };
            std::iter::repeat_n(i, per_band * bands)
        })
        .collect();
    let mut out = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let (Some(sat), Some(px), Some(rej)) = (r.saturated, r.pixels, r.rejected) else {
            continue;
        };
        let area = px + rej;
        if area > 0 && sat as f64 > SATURATED_WARN * area as f64 {
            let cap = capture_of.get(i).and_then(|&j| m.captures.get(j));
            let band = r.wavelength_nm.map_or_else(String::new, |w| {
                format!(", band {} nm", crate::manifest::colour::wavelength_label(w))
            });
            out.push(format!(
                "target {:?}, capture {} (line {}){band}: {sat} of {area} pixels ({:.1}%) \
                 saturated and left out",
                r.target,
                cap.map_or(0, |c| c.index),
                cap.map_or(0, |c| c.line),
                100.0 * sat as f64 / area as f64
            ));
        }
    }
    out
}
