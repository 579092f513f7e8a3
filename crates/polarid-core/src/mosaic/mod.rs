//! Division-of-focal-plane (DoFP) polarization cameras: a 2×2 super-pixel of polarizers
//! at 0°, 45°, 90° and 135° in any arrangement, repeated over the sensor.
//!
//! The pattern is written row by row, top-left first (CONVENTIONS): Sony IMX250MZR /
//! IMX253MZR sensors are `90,45,135,0` ([`Pattern::IMX250MZR`]). With the four angles
//! `S0 = ½ (I0 + I45 + I90 + I135)`, `S1 = I0 − I90`, `S2 = I45 − I135` — the least-squares
//! solution of [`crate::stokes`] for this angle set.
//!
//! Two reconstructions:
//!
//! * **Super-pixel** ([`superpixel_stokes`], [`DofpMethod::Superpixel`]): one Stokes
//!   vector per 2×2 cell, a `(w/2) × (h/2)` image; every output pixel uses its own four raw pixels, so output
//!   pixels are statistically independent.
//! * **Bilinear** ([`bilinear_stokes`], [`demosaic_bilinear`], [`DofpMethod::Bilinear`]):
//!   a full-resolution image
//!   of each of the four channels, then Stokes per pixel. This is exactly what
//!   polanalyser 3.0.0's `demosaicing(raw, COLOR_PolarMono)` computes (it runs OpenCV's
//!   bilinear Bayer demosaicing, `COLOR_BayerBG2BGR` / `COLOR_BayerGR2BGR`, once per
//!   pair of diagonal channels). For a channel whose polarizer sits at `(pr, pc)` of the
//!   cell, the value at pixel `(y, x)` with `dy = (y − pr) mod 2`, `dx = (x − pc) mod 2`
//!   is
//!   - `dy = 0, dx = 0`: the raw value itself;
//!   - `dy = 0, dx = 1`: the mean of the left and right neighbours;
//!   - `dy = 1, dx = 0`: the mean of the upper and lower neighbours;
//!   - `dy = 1, dx = 1`: the mean of the four diagonal neighbours;
//!
//!   for interior pixels (`1 <= y <= h−2`, `1 <= x <= w−2`). Border rows and columns
//!   copy the adjacent interior row or column (the corners copy the diagonal interior
//!   pixel), as OpenCV does. With `round = true` each interpolated value is rounded to the
//!   nearest integer, halves up (`⌊v + ½⌋`), which is OpenCV's integer arithmetic for
//!   8- and 16-bit input: the output is then identical to polanalyser's. Without
//!   rounding the interpolation is exact in `f32`.
//!
//!   Every output pixel depends on the raw pixels of its 3×3 neighbourhood (the four
//!   channels together use all nine), so a pixel is rejected as saturated or invalid
//!   when any raw pixel of its (border-replicated) 3×3 neighbourhood is. Neighbouring
//!   output pixels share raw pixels: see [`crate::region::Sampling::BilinearDofp`] for the
//!   consequence on standard errors.
//!
//! The dark level is subtracted after interpolation (the interpolation is linear, so
//! this only matters for the rounding, which then acts on raw DN as in OpenCV).
//!
//! # Fused reconstruction
//! [`dofp_polar`] goes from the raw mosaic straight to any of `S0`, `S1`, `S2`, the
//! mask, DoLP and AoLP, for both reconstructions, in one pass: the image is cut into
//! strips of rows processed in parallel (rayon), and every output row is made from the
//! raw rows around it in blocks of columns whose intermediate values (the neighbourhood
//! flags, and the Stokes values and mask of outputs not asked for) stay in the L1
//! cache; the four interpolated channels live only in vector registers. No full-size
//! intermediate image is made: asking for DoLP and AoLP only reads the mosaic and
//! writes those two images. [`bilinear_stokes`] and [`superpixel_stokes`] are
//! [`dofp_polar`] with the Stokes images and the mask; [`demosaic_bilinear`],
//! [`demosaic_bilinear_dark`] and [`demosaic_bilinear_int`] write the four channel
//! images with the same strips and blocks.
//!
//! Every value is computed with the operations, in the order, of the two-step path
//! (Stokes images, then [`crate::stokes::dolp_aolp`] with the mask; the row-by-row
//! implementation that preceded the fused one is kept as the tests' oracle), so the
//! results are bit-identical to it. DoLP and AoLP are [`crate::stokes::dolp_aolp_pixel`]:
//! one square root and one division for DoLP, a branch-free polynomial `atan2` (one
//! division, error below 4·10⁻⁸ rad, under `f32` resolution of the result) for AoLP.
//!
//! # Instruction sets
//! The kernels (`kernel.rs`) are portable, branch-free loops; `isa.rs` compiles them
//! for AVX2 + FMA and for AVX-512F behind the tokens of `crate::cpu` (the widest the
//! CPU has is used). Rust does not contract `a·b + c` into a fused multiply-add, so all
//! give the same bits. The pixel loops carry no bounds checks and the last block of a
//! row is extended backwards to a whole number of vectors, so no pixel is left to a
//! scalar remainder loop.
//!
//! # Files
//! | file         | contents                                                                 |
//! |--------------|--------------------------------------------------------------------------|
//! | `pattern.rs` | [`Pattern`], the size checks                                             |
//! | `kernel.rs`  | the portable strip kernels (components, pixels, borders), [`IntSample`]  |
//! | `isa.rs`     | the token-gated entry points, instantiated in `avx2.rs` and `avx512.rs`  |
//! | `reference.rs`, `tests.rs` | the previous implementation (test oracle) and the tests    |
//! | `colour*.rs` | colour polarization mosaics ([`colour`]): pattern, kernels, oracle, tests   |

pub mod colour;
mod colour_kernel;
mod colour_pattern;
mod kernel;
mod pattern;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "x86_64")]
mod isa;

#[cfg(test)]
mod colour_reference;
#[cfg(test)]
mod colour_tests;
#[cfg(test)]
mod reference;
#[cfg(test)]
mod tests;

use rayon::prelude::*;

use crate::cpu::{Isa, cpu_features};
use crate::error::{Result, check_len};
use crate::stokes::{PixelCounts, PixelRules, Sample};
pub use colour::{ColourMethod, ColourPattern, colour_polar, crop_to_whole_periods};
pub use kernel::IntSample;
use kernel::{Bilinear, Scratch, StripOut, Superpixel};
pub use pattern::Pattern;
use pattern::check_mosaic;

/// Output rows per parallel task (big enough to amortise scheduling, small enough to
/// balance two to a few dozen threads).
const ROWS_PER_TASK: usize = 16;

/// How a DoFP mosaic is turned into images (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DofpMethod {
    /// One value per 2×2 cell: outputs are `(width/2) × (height/2)`.
    Superpixel,
    /// Bilinear interpolation of each channel at full resolution; `round` rounds the
    /// interpolated values to whole DN, halves up, as OpenCV does for integer data.
    Bilinear {
        /// Round interpolated values (OpenCV's / polanalyser's integer arithmetic).
        round: bool,
    },
}

impl DofpMethod {
    /// `(width, height)` of the outputs for a `width × height` mosaic.
    pub fn output_size(self, width: usize, height: usize) -> (usize, usize) {
        match self {
            DofpMethod::Superpixel => (width / 2, height / 2),
            DofpMethod::Bilinear { .. } => (width, height),
        }
    }

    /// The smallest mosaic side the method accepts.
    fn min_side(self) -> usize {
        match self {
            DofpMethod::Superpixel => 2,
            DofpMethod::Bilinear { .. } => 4,
        }
    }
}

/// Caller-owned outputs of [`dofp_polar`], each of the output size
/// ([`DofpMethod::output_size`]) or absent (`None`: not computed into any image).
#[derive(Debug, Default)]
pub struct DofpOutputs<'a> {
    /// Dark-subtracted `S0`.
    pub s0: Option<&'a mut [f32]>,
    /// `S1 = I0 − I90`.
    pub s1: Option<&'a mut [f32]>,
    /// `S2 = I45 − I135`.
    pub s2: Option<&'a mut [f32]>,
    /// The pixel mask ([`crate::stokes::mask`]).
    pub mask: Option<&'a mut [u8]>,
    /// DoLP, NaN where the mask rejects the pixel ([`crate::stokes::dolp_aolp_pixel`]).
    pub dolp: Option<&'a mut [f32]>,
    /// AoLP in degrees in `[0, 180)`, NaN where the mask rejects the pixel.
    pub aolp: Option<&'a mut [f32]>,
}

/// The fused DoFP reconstruction (module documentation): from the raw mosaic `raw`
/// (`width × height`, both even, at least 2×2 for [`DofpMethod::Superpixel`], 4×4 for
/// [`DofpMethod::Bilinear`]) straight to the outputs asked for in `out`, without any
/// other full-size image. Returns the pixel counts of the mask (computed whether or not
/// the mask is asked for).
///
/// Bilinear: `S0 = ½ (I0 + I45 + I90 + I135) − 2·dark`, `S1 = I0 − I90`,
/// `S2 = I45 − I135` from the interpolated channels; a pixel is saturated or invalid
/// when a raw value of its 3×3 neighbourhood is. Super-pixel: the same from each cell's
/// four dark-subtracted raw values; a cell is saturated or invalid when one of them is.
/// Either: dark when `S0 <= rules.min_s0`. `DoLP = √(S1² + S2²)/S0` clamped to
/// `[0, 1]`, `AoLP = ½ atan2(S2, S1)` in degrees in `[0, 180)`, NaN where rejected.
///
/// The results are bit-identical to [`bilinear_stokes`] / [`superpixel_stokes`]
/// followed by [`crate::stokes::dolp_aolp`] with the mask.
///
/// Errors: [`crate::CoreError::InvalidDimensions`] for a bad mosaic size,
/// [`crate::CoreError::LengthMismatch`] naming an output of the wrong size, the
/// errors of [`PixelRules::validate`].
pub fn dofp_polar<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    method: DofpMethod,
    rules: &PixelRules,
    out: DofpOutputs<'_>,
) -> Result<PixelCounts> {
    dofp_polar_isa(
        cpu_features().best(),
        raw,
        width,
        pattern,
        method,
        rules,
        out,
    )
}

/// [`dofp_polar`] with the instruction set `isa`.
fn dofp_polar_isa<T: Sample>(
    isa: Isa,
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    method: DofpMethod,
    rules: &PixelRules,
    out: DofpOutputs<'_>,
) -> Result<PixelCounts> {
    rules.validate()?;
    let height = check_mosaic(width, raw.len(), method.min_side())?;
    let (ow, oh) = method.output_size(width, height);
    let n = ow * oh;
    for (name, len) in [
        ("s0", out.s0.as_ref().map(|b| b.len())),
        ("s1", out.s1.as_ref().map(|b| b.len())),
        ("s2", out.s2.as_ref().map(|b| b.len())),
        ("mask", out.mask.as_ref().map(|b| b.len())),
        ("dolp", out.dolp.as_ref().map(|b| b.len())),
        ("aolp", out.aolp.as_ref().map(|b| b.len())),
    ] {
        if let Some(len) = len {
            check_len(name, len, n)?;
        }
    }
    let polar = out.dolp.is_some() || out.aolp.is_some();
    let strips = split_strips(out, ow, oh);
    let counts = match method {
        DofpMethod::Bilinear { round } => {
            let job = Bilinear {
                raw,
                width,
                height,
                rules: *rules,
                pos: kernel::positions(pattern),
            };
            let run = match (round, polar) {
                (false, false) => bilinear_dispatch::<T, false, false>,
                (false, true) => bilinear_dispatch::<T, false, true>,
                (true, false) => bilinear_dispatch::<T, true, false>,
                (true, true) => bilinear_dispatch::<T, true, true>,
            };
            strips
                .into_par_iter()
                .map_init(Scratch::new, |sc, mut st| run(isa, &job, &mut st, sc))
                .reduce(PixelCounts::default, PixelCounts::add)
        }
        DofpMethod::Superpixel => {
            let job = Superpixel {
                raw,
                width,
                rules: *rules,
                pos: pattern.pos,
            };
            let run = if polar {
                superpixel_dispatch::<T, true>
            } else {
                superpixel_dispatch::<T, false>
            };
            strips
                .into_par_iter()
                .map_init(Scratch::new, |sc, mut st| run(isa, &job, &mut st, sc))
                .reduce(PixelCounts::default, PixelCounts::add)
        }
    };
    Ok(counts)
}

/// Cut the outputs (each `ow × oh` or absent) into strips of [`ROWS_PER_TASK`] rows.
fn split_strips(out: DofpOutputs<'_>, ow: usize, oh: usize) -> Vec<StripOut<'_>> {
    let chunk = ow * ROWS_PER_TASK;
    fn chunks<V>(b: Option<&mut [V]>, chunk: usize) -> Option<std::slice::ChunksMut<'_, V>> {
        b.map(|b| b.chunks_mut(chunk))
    }
    let (mut s0, mut s1, mut s2) = (
        chunks(out.s0, chunk),
        chunks(out.s1, chunk),
        chunks(out.s2, chunk),
    );
    let mut m = chunks(out.mask, chunk);
    let (mut d, mut a) = (chunks(out.dolp, chunk), chunks(out.aolp, chunk));
    (0..oh.div_ceil(ROWS_PER_TASK))
        .map(|i| {
            let y0 = i * ROWS_PER_TASK;
            StripOut {
                y0,
                rows: ROWS_PER_TASK.min(oh - y0),
                s: [
                    s0.as_mut().and_then(Iterator::next),
                    s1.as_mut().and_then(Iterator::next),
                    s2.as_mut().and_then(Iterator::next),
                ],
                mask: m.as_mut().and_then(Iterator::next),
                dolp: d.as_mut().and_then(Iterator::next),
                aolp: a.as_mut().and_then(Iterator::next),
            }
        })
        .collect()
}

/// One bilinear strip with the widest kernel `isa` allows.
fn bilinear_dispatch<T: Sample, const ROUND: bool, const POLAR: bool>(
    isa: Isa,
    job: &Bilinear<'_, T>,
    out: &mut StripOut<'_>,
    sc: &mut Scratch,
) -> PixelCounts {
    #[cfg(target_arch = "x86_64")]
    match isa {
        Isa::Avx512(t) => return avx512::bilinear_strip::<T, ROUND, POLAR>(t, job, out, sc),
        Isa::Avx2Fma(t) => return avx2::bilinear_strip::<T, ROUND, POLAR>(t, job, out, sc),
        Isa::Portable => {}
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    kernel::bilinear_strip::<T, ROUND, POLAR>(job, out, sc)
}

/// One super-pixel strip with the widest kernel `isa` allows.
fn superpixel_dispatch<T: Sample, const POLAR: bool>(
    isa: Isa,
    job: &Superpixel<'_, T>,
    out: &mut StripOut<'_>,
    sc: &mut Scratch,
) -> PixelCounts {
    #[cfg(target_arch = "x86_64")]
    match isa {
        Isa::Avx512(t) => return avx512::superpixel_strip::<T, POLAR>(t, job, out, sc),
        Isa::Avx2Fma(t) => return avx2::superpixel_strip::<T, POLAR>(t, job, out, sc),
        Isa::Portable => {}
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    kernel::superpixel_strip::<T, POLAR>(job, out, sc)
}

/// Super-pixel Stokes: one Stokes vector per 2×2 cell of `raw` (`width × height`, both
/// even). Outputs are `(width/2) × (height/2)`. A cell is saturated / invalid when any of
/// its four raw pixels is, dark when its `S0 <= rules.min_s0`.
/// [`dofp_polar`] with the Stokes images and the mask.
#[allow(clippy::too_many_arguments)]
pub fn superpixel_stokes<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    rules: &PixelRules,
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    mask: &mut [u8],
) -> Result<PixelCounts> {
    let out = DofpOutputs {
        s0: Some(s0),
        s1: Some(s1),
        s2: Some(s2),
        mask: Some(mask),
        ..Default::default()
    };
    dofp_polar(raw, width, pattern, DofpMethod::Superpixel, rules, out)
}

/// Full-resolution Stokes images of a DoFP frame by bilinear demosaicing (module docs).
/// Outputs and `mask` are `width × height`. [`dofp_polar`] with the Stokes images and
/// the mask: no full-size channel image is stored.
///
/// At every pixel the four channels use the four components (raw, horizontal, vertical,
/// diagonal mean) once each, so `S0 = ½ (mid + hor + ver + dia)` whatever the pattern,
/// and `S1`, `S2` are differences of two components chosen by the pixel's parity.
#[allow(clippy::too_many_arguments)]
pub fn bilinear_stokes<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    rules: &PixelRules,
    round: bool,
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    mask: &mut [u8],
) -> Result<PixelCounts> {
    let out = DofpOutputs {
        s0: Some(s0),
        s1: Some(s1),
        s2: Some(s2),
        mask: Some(mask),
        ..Default::default()
    };
    dofp_polar(
        raw,
        width,
        pattern,
        DofpMethod::Bilinear { round },
        rules,
        out,
    )
}

/// Bilinear demosaicing of `raw` (`width × height`, even, at least 4×4) into four
/// full-resolution channel images `out[k]` for the polarizer at `k × 45°` (0, 45, 90,
/// 135). Exactly polanalyser's / OpenCV's interpolation when `round` (module docs).
pub fn demosaic_bilinear<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    round: bool,
    out: [&mut [f32]; 4],
) -> Result<()> {
    demosaic_bilinear_dark(raw, width, pattern, round, 0.0, out)
}

/// [`demosaic_bilinear`] with `dark_level` subtracted from every output value (after
/// the interpolation and its rounding).
pub fn demosaic_bilinear_dark<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    round: bool,
    dark_level: f32,
    out: [&mut [f32]; 4],
) -> Result<()> {
    demosaic_bilinear_isa(
        cpu_features().best(),
        raw,
        width,
        pattern,
        round,
        dark_level,
        out,
    )
}

/// [`demosaic_bilinear_dark`] with the instruction set `isa`.
fn demosaic_bilinear_isa<T: Sample>(
    isa: Isa,
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    round: bool,
    dark: f32,
    out: [&mut [f32]; 4],
) -> Result<()> {
    crate::error::ensure_finite("dark_level", dark as f64)?;
    let job = demosaic_job(raw, width, pattern, &out)?;
    let run = if round {
        demosaic_dispatch::<T, true>
    } else {
        demosaic_dispatch::<T, false>
    };
    split_planes(out, width)
        .into_par_iter()
        .for_each(|(y0, planes)| run(isa, &job, dark, y0, planes));
    Ok(())
}

/// Bilinear demosaicing of unsigned integer data into four channel images of the same
/// type (0, 45, 90, 135°), rounded as OpenCV does (`round = true` of
/// [`demosaic_bilinear`], whose values these are): polanalyser's
/// `demosaicing(raw, COLOR_PolarMono)` exactly, in half the memory of `f32` images.
pub fn demosaic_bilinear_int<T: IntSample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    out: [&mut [T]; 4],
) -> Result<()> {
    demosaic_bilinear_int_isa(cpu_features().best(), raw, width, pattern, out)
}

/// [`demosaic_bilinear_int`] with the instruction set `isa`.
fn demosaic_bilinear_int_isa<T: IntSample>(
    isa: Isa,
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    out: [&mut [T]; 4],
) -> Result<()> {
    let job = demosaic_job(raw, width, pattern, &out)?;
    split_planes(out, width)
        .into_par_iter()
        .for_each(|(y0, planes)| demosaic_int_dispatch(isa, &job, y0, planes));
    Ok(())
}

/// The checked job of a demosaicing into four `width × height` planes.
fn demosaic_job<'a, T: Sample, V>(
    raw: &'a [T],
    width: usize,
    pattern: &Pattern,
    out: &[&mut [V]; 4],
) -> Result<Bilinear<'a, T>> {
    let height = check_mosaic(width, raw.len(), 4)?;
    for o in out {
        check_len("demosaiced channel", o.len(), raw.len())?;
    }
    Ok(Bilinear {
        raw,
        width,
        height,
        rules: PixelRules::default(),
        pos: kernel::positions(pattern),
    })
}

/// Cut four planes into strips of [`ROWS_PER_TASK`] rows: `(first row, the strip of
/// each plane)`.
fn split_planes<V: Send>(out: [&mut [V]; 4], width: usize) -> Vec<(usize, [&mut [V]; 4])> {
    let chunk = width * ROWS_PER_TASK;
    let [a, b, c, d] = out;
    a.chunks_mut(chunk)
        .zip(b.chunks_mut(chunk))
        .zip(c.chunks_mut(chunk))
        .zip(d.chunks_mut(chunk))
        .enumerate()
        .map(|(i, (((a, b), c), d))| (i * ROWS_PER_TASK, [a, b, c, d]))
        .collect()
}

/// One strip of [`demosaic_bilinear_dark`] with the widest kernel `isa` allows.
fn demosaic_dispatch<T: Sample, const ROUND: bool>(
    isa: Isa,
    job: &Bilinear<'_, T>,
    dark: f32,
    y0: usize,
    out: [&mut [f32]; 4],
) {
    #[cfg(target_arch = "x86_64")]
    match isa {
        Isa::Avx512(t) => return avx512::demosaic_strip::<T, ROUND>(t, job, dark, y0, out),
        Isa::Avx2Fma(t) => return avx2::demosaic_strip::<T, ROUND>(t, job, dark, y0, out),
        Isa::Portable => {}
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    kernel::demosaic_strip::<T, ROUND>(job, dark, y0, out)
}

/// One strip of [`demosaic_bilinear_int`] with the widest kernel `isa` allows.
fn demosaic_int_dispatch<T: IntSample>(
    isa: Isa,
    job: &Bilinear<'_, T>,
    y0: usize,
    out: [&mut [T]; 4],
) {
    #[cfg(target_arch = "x86_64")]
    match isa {
        Isa::Avx512(t) => return avx512::demosaic_int_strip::<T>(t, job, y0, out),
        Isa::Avx2Fma(t) => return avx2::demosaic_int_strip::<T>(t, job, y0, out),
        Isa::Portable => {}
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    kernel::demosaic_int_strip::<T>(job, y0, out)
}
