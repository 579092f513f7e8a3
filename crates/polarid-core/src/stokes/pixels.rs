//! Raw samples and how they become usable signal: the sample types ([`Sample`]), the
//! dark level and rejection thresholds ([`PixelRules`]), the mask of every pixel
//! ([`mask`]) with its counts ([`PixelCounts`]), and the checks of image
//! and buffer sizes shared by the image kernels.

use rayon::prelude::*;

use super::mask;
use crate::error::{CoreError, Result, check_len};

/// A raw sample type that frames may hold (8/16-bit integer or 32-bit float).
pub trait Sample: Copy + Send + Sync + 'static {
    /// True for the unsigned integer types: every value is a whole number in
    /// `0..2¹⁶`, exact in `f32` and finite, so kernels may skip the non-finite tests and
    /// round with a plain conversion.
    const INTEGER: bool = false;

    /// The value as `f32` (exact for `u8` and `u16`).
    fn to_f32(self) -> f32;
}

impl Sample for u8 {
    const INTEGER: bool = true;

    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}

impl Sample for u16 {
    const INTEGER: bool = true;

    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}

impl Sample for f32 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
}

/// How raw values are turned into usable signal: dark level and rejection thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelRules {
    /// DN subtracted from every raw value.
    pub dark_level: f32,
    /// Raw values at or above this (before dark subtraction) are saturated.
    /// `f32::INFINITY` disables the test.
    pub saturation: f32,
    /// Pixels whose dark-subtracted `S0` is at or below this are "dark" and rejected.
    pub min_s0: f32,
}

impl Default for PixelRules {
    fn default() -> Self {
        Self {
            dark_level: 0.0,
            saturation: f32::INFINITY,
            min_s0: 0.0,
        }
    }
}

impl PixelRules {
    /// Check that the rules are usable (finite dark level and threshold, saturation not
    /// NaN).
    pub fn validate(&self) -> Result<()> {
        crate::error::ensure_finite("dark_level", self.dark_level as f64)?;
        crate::error::ensure_finite("min_s0", self.min_s0 as f64)?;
        if self.saturation.is_nan() {
            return Err(CoreError::NonFinite {
                name: "saturation",
                value: self.saturation as f64,
            });
        }
        Ok(())
    }
}

/// How many pixels of an image were used and why the others were rejected.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PixelCounts {
    /// Usable pixels.
    pub valid: u64,
    /// Pixels with a saturated raw value.
    pub saturated: u64,
    /// Pixels whose `S0` is at or below the dark threshold.
    pub dark: u64,
    /// Pixels with a non-finite raw value.
    pub invalid: u64,
}

impl PixelCounts {
    /// Pixels rejected for any reason.
    pub fn rejected(&self) -> u64 {
        self.saturated + self.dark + self.invalid
    }

    /// The counts of `self` and `o` together.
    pub(crate) fn add(self, o: Self) -> Self {
        Self {
            valid: self.valid + o.valid,
            saturated: self.saturated + o.saturated,
            dark: self.dark + o.dark,
            invalid: self.invalid + o.invalid,
        }
    }

    /// Count the mask values of `mask`.
    pub fn from_mask(mask: &[u8]) -> Self {
        let mut h = [0u64; 4];
        for &m in mask {
            h[(m & 3) as usize] += 1;
        }
        Self {
            valid: h[0],
            saturated: h[1],
            dark: h[2],
            invalid: h[3],
        }
    }
}

/// `len` pixels form whole rows of `width` (both non-zero), or
/// [`CoreError::InvalidDimensions`].
pub(crate) fn check_image(width: usize, len: usize) -> Result<()> {
    if width == 0 || len == 0 || !len.is_multiple_of(width) {
        return Err(CoreError::InvalidDimensions {
            width,
            height: len.checked_div(width).unwrap_or(0),
            reason: format!("{len} pixels do not form whole rows of a non-empty image"),
        });
    }
    Ok(())
}

/// Turn the accumulated flag bits of a row into mask values and count them.
#[inline]
pub(crate) fn finish_mask_row(
    r0: &[f32],
    r1: &[f32],
    r2: &[f32],
    rm: &mut [u8],
    min_s0: f32,
) -> PixelCounts {
    let mut h = [0u32; 4];
    for (((&a0, &a1), &a2), m) in r0.iter().zip(r1).zip(r2).zip(rm.iter_mut()) {
        let nonfinite = (*m & 2 != 0) || !(a0 + a1 + a2).is_finite();
        let v = if nonfinite {
            mask::INVALID
        } else if *m & 1 != 0 {
            mask::SATURATED
        } else if a0 <= min_s0 {
            mask::DARK
        } else {
            mask::VALID
        };
        *m = v;
        h[v as usize] += 1;
    }
    PixelCounts {
        valid: h[0] as u64,
        saturated: h[1] as u64,
        dark: h[2] as u64,
        invalid: h[3] as u64,
    }
}

/// Mask and counts for Stokes images read from files (no raw frames): a pixel is
/// [`mask::INVALID`] when a component is not finite and [`mask::DARK`] when
/// `S0 <= min_s0`.
pub fn mask_stokes(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    min_s0: f32,
    mask: &mut [u8],
) -> Result<PixelCounts> {
    let n = s0.len();
    check_image(width, n)?;
    check_len("s1", s1.len(), n)?;
    check_len("s2", s2.len(), n)?;
    check_len("mask", mask.len(), n)?;
    Ok(mask
        .par_chunks_mut(width)
        .enumerate()
        .map(|(y, rm)| {
            let r = y * width..(y + 1) * width;
            rm.fill(0);
            finish_mask_row(&s0[r.clone()], &s1[r.clone()], &s2[r], rm, min_s0)
        })
        .reduce(PixelCounts::default, PixelCounts::add))
}
