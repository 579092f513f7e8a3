//! Colour polarization mosaics (Sony IMX250MYR and kin): a 2×2 polarizer block under
//! each colour of a 2×2 colour pattern of blocks, a 4×4 period ([`ColourPattern`]).
//! Each band (colour) is reconstructed on its own, from its own samples only, into
//! `S0`, `S1`, `S2`, the mask, DoLP and AoLP per band ([`colour_polar`]), in one fused
//! pass over the mosaic (rayon strips of rows, column blocks in the L1 cache, the same
//! bits on every instruction set), with the formulas of [`crate::mosaic`]:
//! `S0 = ½ ((I0 + I90) + (I45 + I135)) − 2·dark`, `S1 = I0 − I90`, `S2 = I45 − I135`.
//!
//! # Lattices
//! The raw pixels with `y ≡ ρ`, `x ≡ χ (mod 4)` form a lattice of period 4 in both
//! directions; each of the 16 lattices carries one band and one polarizer angle. A band
//! with `n` blocks in the period (`G` of `RGGB`: 2) has `n` lattices per angle.
//!
//! # Super-pixel ([`ColourMethod::Superpixel`])
//! One output per 4×4 period (`w/4 × h/4`): `I_k = (Σ raw)/n − dark` over the band's
//! `n` samples of polarizer `k` in the period. Outputs are independent. Its samples sit
//! at different places: on a brightness ramp of slope `(gx, gy)` DN/pixel (unpolarized)
//! the IMX pattern (`90,45,135,0`, the 0° pixel one down and one right of the 90° one)
//! reads `S1 = gx + gy`, `S2 = gx − gy`, a false DoLP of `√2·|g|/S0` (tested).
//!
//! # Bilinear ([`ColourMethod::Bilinear`])
//! Full resolution: each lattice is interpolated at every pixel, separably (vertically,
//! then horizontally). Along an axis, at position `p`, for the lattice at residue `r`,
//! with `e = (p − r) mod 4`: `v = raw(p)` when `e = 0`, else
//! `(1 − e/4)·raw(p − e) + (e/4)·raw(p − e + 4)`, a sample beyond the image being
//! replaced by the lattice's first or last sample (constant extrapolation within 3
//! pixels of the border). A channel is the mean of its band's `n` lattices (summed in
//! lattice order, times `1/n`). A pixel of a band is saturated when a raw value with a
//! non-zero weight in one of its band's interpolations is, invalid when a Stokes value
//! is not finite, dark when `S0 <= min_s0`.
//!
//! **Bias on brightness gradients.** The interpolation reproduces any brightness that is
//! linear in `x` and `y` (indeed bilinear) exactly, at the pixel itself: on a linear
//! ramp every channel equals the ramp, `S1 = S2 = 0` and the DoLP is 0 (exactly for
//! integer ramps: the weights are multiples of ¼), except within 3 pixels of the
//! image border where the extrapolation is constant. A step edge is not linear: the
//! four angles' lattices are offset by one pixel, so their interpolants cross the edge
//! at different places. For an unpolarized vertical step from `a` to `b > a` (DN,
//! dark-subtracted) whose first column at `b` is `x_e`, each lattice's interpolant
//! ramps from `a` to `b` over the 4 pixels between its last sample before the edge and
//! its first after it; the lattices of two angles start their ramps `s` = 1, 2 or 3
//! pixels apart (depending on `x_e mod 4`), so their values differ by up to `s/4` of
//! the step. The false DoLP is confined to the 6 columns `x_e − 3 ..= x_e + 2`
//! (elsewhere it is exactly 0); with the IMX polarizer pattern (0° and 45° in one
//! column of the cell, 90° and 135° in the other) it is at most
//! `3√2·(b − a)/(8a + 3(b − a))`, reached for one of the four positions of the edge
//! in the period: 0.051 for a 10 % step, 0.39 for a 2:1 step, 1 for a 10:1 step (the
//! same holds for horizontal steps; tested). The 2-pixel lattices of a monochrome
//! sensor give at most `√2·(b − a)/(4a + (b − a))` (0.28 for 2:1). A region's DoLP
//! should therefore keep 3 pixels from strong edges;
//! the super-pixel method confines the same error to the period containing the edge.

use rayon::prelude::*;

use super::colour_kernel::{self as ck, BandStrip, ColourJob, ColourScratch, MAX_BANDS};
use super::colour_pattern::check_colour_mosaic;
use super::{DofpOutputs, ROWS_PER_TASK, split_strips};
use crate::cpu::{Isa, cpu_features};
use crate::error::{CoreError, Result, check_len};
use crate::stokes::{PixelCounts, PixelRules, Sample};

pub use super::colour_pattern::ColourPattern;

/// How a colour polarization mosaic is turned into per-band images.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColourMethod {
    /// One value per 4×4 period: outputs are `(width/4) × (height/4)`.
    Superpixel,
    /// Bilinear interpolation of each band's lattices at full resolution.
    Bilinear,
}

impl ColourMethod {
    /// `(width, height)` of the outputs for a `width × height` mosaic.
    pub fn output_size(self, width: usize, height: usize) -> (usize, usize) {
        match self {
            ColourMethod::Superpixel => (width / 4, height / 4),
            ColourMethod::Bilinear => (width, height),
        }
    }
}

/// The whole 4×4 periods of a `width × height` colour mosaic whose width or height is
/// not a multiple of 4 (a sensor read out with a partial period at the right or bottom
/// edge): the top-left `(width − width mod 4) × (height − height mod 4)` pixels, copied
/// from `raw`, with their width and height; `None` when the mosaic is already whole
/// periods. The partial period is dropped, not interpolated: its pixels lack samples
/// of some of the period's 16 lattices. Pixel coordinates are unchanged (the origin is
/// the top-left corner).
///
/// Errors: [`CoreError::InvalidDimensions`] when `raw` is not whole rows of `width`, or
/// when not one whole period is left (width or height below 4).
pub fn crop_to_whole_periods<T: Copy>(
    raw: &[T],
    width: usize,
) -> Result<Option<(Vec<T>, usize, usize)>> {
    let height = raw.len().checked_div(width).unwrap_or(0);
    if width == 0 || raw.len() != width * height {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: format!("{} pixels do not form whole rows", raw.len()),
        });
    }
    let (w, h) = (width - width % 4, height - height % 4);
    if w == 0 || h == 0 {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: "a colour polarization mosaic has a 4x4 period: it needs at least one \
                     whole period (4x4 pixels)"
                .into(),
        });
    }
    if (w, h) == (width, height) {
        return Ok(None);
    }
    let mut out = Vec::with_capacity(w * h);
    for row in raw.chunks_exact(width).take(h) {
        out.extend_from_slice(&row[..w]);
    }
    Ok(Some((out, w, h)))
}

/// The fused colour reconstruction (module documentation): from the raw mosaic `raw`
/// (`width × height`, both non-zero multiples of 4) straight to the outputs asked for in
/// `out`, one [`DofpOutputs`] per band in the order of [`ColourPattern::bands`], each of
/// the output size ([`ColourMethod::output_size`]) or absent. Returns the pixel counts
/// of each band's mask (computed whether or not the mask is asked for).
///
/// Errors: [`CoreError::InvalidDimensions`] for a mosaic that is not whole 4×4
/// periods, [`CoreError::LengthMismatch`] for a number of band outputs other than the
/// pattern's bands (`band outputs`) or an output of the wrong size, the errors of
/// [`PixelRules::validate`].
pub fn colour_polar<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &ColourPattern,
    method: ColourMethod,
    rules: &PixelRules,
    out: Vec<DofpOutputs<'_>>,
) -> Result<Vec<PixelCounts>> {
    colour_polar_isa(
        cpu_features().best(),
        raw,
        width,
        pattern,
        method,
        rules,
        out,
    )
}

/// [`colour_polar`] with the instruction set `isa`.
pub(super) fn colour_polar_isa<T: Sample>(
    isa: Isa,
    raw: &[T],
    width: usize,
    pattern: &ColourPattern,
    method: ColourMethod,
    rules: &PixelRules,
    out: Vec<DofpOutputs<'_>>,
) -> Result<Vec<PixelCounts>> {
    rules.validate()?;
    let height = check_colour_mosaic(width, raw.len())?;
    let nb = pattern.bands().len();
    if nb > MAX_BANDS {
        return Err(CoreError::InvalidName {
            what: "colour pattern",
            name: pattern.color(),
            reason: "at most four bands".into(),
        });
    }
    check_len("band outputs", out.len(), nb)?;
    let (ow, oh) = method.output_size(width, height);
    let n = ow * oh;
    for o in &out {
        for (name, len) in [
            ("s0", o.s0.as_ref().map(|b| b.len())),
            ("s1", o.s1.as_ref().map(|b| b.len())),
            ("s2", o.s2.as_ref().map(|b| b.len())),
            ("mask", o.mask.as_ref().map(|b| b.len())),
            ("dolp", o.dolp.as_ref().map(|b| b.len())),
            ("aolp", o.aolp.as_ref().map(|b| b.len())),
        ] {
            if let Some(len) = len {
                check_len(name, len, n)?;
            }
        }
    }
    let polar = out.iter().any(|o| o.dolp.is_some() || o.aolp.is_some());
    let tasks = split_bands(out, ow, oh);
    let job = ColourJob::new(raw, width, height, pattern, *rules);
    // With an infinite saturation level only infinite samples reach it, and those make
    // the pixel invalid anyway: the saturation test can be skipped.
    let sat = rules.saturation != f32::INFINITY;
    let run = match (method, sat, polar) {
        (ColourMethod::Bilinear, false, false) => bilinear_dispatch::<T, false, false>,
        (ColourMethod::Bilinear, false, true) => bilinear_dispatch::<T, false, true>,
        (ColourMethod::Bilinear, true, false) => bilinear_dispatch::<T, true, false>,
        (ColourMethod::Bilinear, true, true) => bilinear_dispatch::<T, true, true>,
        (ColourMethod::Superpixel, _, false) => superpixel_dispatch::<T, false>,
        (ColourMethod::Superpixel, _, true) => superpixel_dispatch::<T, true>,
    };
    let counts = tasks
        .into_par_iter()
        .map_init(ColourScratch::new, |sc, (y0, rows, mut st)| {
            run(isa, &job, y0, rows, &mut st, sc)
        })
        .reduce(|| [PixelCounts::default(); MAX_BANDS], add_counts);
    Ok(counts[..nb].to_vec())
}

/// Cut every band's outputs (each `ow × oh` or absent) into strips of
/// [`ROWS_PER_TASK`] rows: per task `(first row, rows, the band strips)`.
fn split_bands(out: Vec<DofpOutputs<'_>>, ow: usize, oh: usize) -> Vec<Tasks<'_>> {
    let mut tasks: Vec<Tasks<'_>> = (0..oh.div_ceil(ROWS_PER_TASK))
        .map(|i| {
            let y0 = i * ROWS_PER_TASK;
            (y0, ROWS_PER_TASK.min(oh - y0), Vec::new())
        })
        .collect();
    for o in out {
        for (t, s) in tasks.iter_mut().zip(split_strips(o, ow, oh)) {
            t.2.push(BandStrip {
                s: s.s,
                mask: s.mask,
                dolp: s.dolp,
                aolp: s.aolp,
            });
        }
    }
    tasks
}

/// One task: first output row, rows, the strips of every band.
type Tasks<'a> = (usize, usize, Vec<BandStrip<'a>>);

fn add_counts(
    a: [PixelCounts; MAX_BANDS],
    b: [PixelCounts; MAX_BANDS],
) -> [PixelCounts; MAX_BANDS] {
    std::array::from_fn(|i| a[i].add(b[i]))
}

/// One bilinear colour strip with the widest kernel `isa` allows.
fn bilinear_dispatch<T: Sample, const SAT: bool, const POLAR: bool>(
    isa: Isa,
    job: &ColourJob<'_, T>,
    y0: usize,
    rows: usize,
    out: &mut [BandStrip<'_>],
    sc: &mut ColourScratch,
) -> [PixelCounts; MAX_BANDS] {
    #[cfg(target_arch = "x86_64")]
    match isa {
        Isa::Avx512(t) => return ck::avx512::bilinear::<T, SAT, POLAR>(t, job, y0, rows, out, sc),
        Isa::Avx2Fma(t) => return ck::avx2::bilinear::<T, SAT, POLAR>(t, job, y0, rows, out, sc),
        Isa::Portable => {}
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    ck::bilinear_strip::<T, SAT, POLAR>(job, y0, rows, out, sc)
}

/// One super-pixel colour strip with the widest kernel `isa` allows.
fn superpixel_dispatch<T: Sample, const POLAR: bool>(
    isa: Isa,
    job: &ColourJob<'_, T>,
    y0: usize,
    rows: usize,
    out: &mut [BandStrip<'_>],
    sc: &mut ColourScratch,
) -> [PixelCounts; MAX_BANDS] {
    #[cfg(target_arch = "x86_64")]
    match isa {
        Isa::Avx512(t) => return ck::avx512::superpixel::<T, POLAR>(t, job, y0, rows, out, sc),
        Isa::Avx2Fma(t) => return ck::avx2::superpixel::<T, POLAR>(t, job, y0, rows, out, sc),
        Isa::Portable => {}
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    ck::superpixel_strip::<T, POLAR>(job, y0, rows, out, sc)
}

#[cfg(test)]
mod crop_tests {
    use super::*;

    #[test]
    fn partial_periods_are_dropped_at_the_right_and_bottom() {
        // 10 x 7: two whole periods across, one down.
        let raw: Vec<u16> = (0..70).collect();
        let (c, w, h) = crop_to_whole_periods(&raw, 10).unwrap().unwrap();
        assert_eq!((w, h), (8, 4));
        assert_eq!(c.len(), 32);
        // Coordinates are unchanged: pixel (x, y) of the crop is pixel (x, y) of raw.
        for y in 0..4 {
            for x in 0..8 {
                assert_eq!(c[y * 8 + x], raw[y * 10 + x]);
            }
        }
        assert!(crop_to_whole_periods(&raw[..64], 8).unwrap().is_none());
        assert!(crop_to_whole_periods(&raw[..30], 10).is_err());
        assert!(crop_to_whole_periods(&raw[..69], 10).is_err());
    }
}
