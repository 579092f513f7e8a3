//! A capture's files → its Stokes images: rotating-polarizer frames
//! ([`frames_stokes`]), DoFP mosaics ([`dofp_stokes`]), Stokes files ([`read_stokes`]),
//! HDR brackets ([`hdr_images`]), with the capture's pixel rules ([`rules_for`]: dark
//! level, saturation, [`dark_threshold_dn`]). [`crate::bands`] builds every band of a
//! capture on these; [`crate::measure`] turns the images into region rows (the rules are
//! described there).

use std::path::Path;

use polarid_core::CoreError;
use polarid_core::mosaic::{self, Pattern};
use polarid_core::region::Sampling;
use polarid_core::stokes::{self, PixelCounts, PixelRules, StokesSolver};

use crate::error::{IoError, Result};
use crate::image::{self, Frame, SampleKind};
use crate::manifest::{Capture, CaptureSource, Manifest};

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
        return Err(IoError::core(
            "<no frames>",
            CoreError::TooFew {
                what: "frames",
                needed: solver.len(),
                got: 0,
            },
        ));
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
        .map_err(|e| IoError::core(&first.path, e))?;
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
    let wrap = |e| IoError::core(&raw.path, e);
    let (w, data) = (raw.width, &raw.data);
    let mut o = match demosaic {
        Demosaic::Bilinear => StokesImages::alloc(w, raw.height, Sampling::BilinearDofp),
        Demosaic::Superpixel => StokesImages::alloc(w / 2, raw.height / 2, Sampling::Independent),
    };
    let (s0, s1, s2, mask) = (&mut o.s0, &mut o.s1, &mut o.s2, &mut o.mask);
    o.counts = match demosaic {
        Demosaic::Bilinear => {
            mosaic::bilinear_stokes(data, w, pattern, rules, round, s0, s1, s2, mask)
        }
        Demosaic::Superpixel => {
            mosaic::superpixel_stokes(data, w, pattern, rules, s0, s1, s2, mask)
        }
    }
    .map_err(wrap)?;
    Ok(o)
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
    let [f0, f1, f2]: [Frame; 3] = imgs.try_into().map_err(|_| {
        let source = CoreError::TooFew {
            what: "Stokes images",
            needed: 3,
            got,
        };
        IoError::core(s0, source)
    })?;
    let (width, height) = (f0.width, f0.height);
    let mut mask = vec![0u8; width * height];
    let counts = stokes::mask_stokes(width, &f0.data, &f1.data, &f2.data, 0.0, &mut mask)
        .map_err(|e| IoError::core(s0, e))?;
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
            let solver = StokesSolver::from_degrees(&angles).map_err(|e| {
                c.field_error(&m.path, "frames", format!("{angles:?}"), e.to_string())
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
        CaptureSource::ColourDofp { .. } => Err(c.field_error(
            &m.path,
            "dofp.color",
            "color",
            "a colour capture has one set of Stokes images per band: use \
                     polarid_io::bands::capture_band_images",
        )),
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
        return Err(c.field_error(&m.path, "brackets", "", "no frames"));
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
            let solver = StokesSolver::from_degrees(&angles).map_err(|e| {
                c.field_error(&m.path, "brackets", format!("{angles:?}"), e.to_string())
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
            return Err(c.field_error(
                &m.path,
                "brackets",
                s0.display().to_string(),
                "HDR brackets need raw data (`frames` or `dofp`), not Stokes images",
            ));
        }
        CaptureSource::ColourDofp { file, .. } => {
            return Err(c.field_error(
                &m.path,
                "brackets",
                file.display().to_string(),
                "a colour capture has one set of Stokes images per band: use \
                         polarid_io::bands::capture_band_images",
            ));
        }
    };
    out.dark_signal_dn = dark_threshold_dn(c, &raw_rules, first.kind.is_integer());
    out.warnings = saturation_notes(c, &frames, raw_rules.saturation);
    Ok(out)
}
