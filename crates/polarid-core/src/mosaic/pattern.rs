//! The 2×2 polarizer pattern of a DoFP sensor and the size checks of a mosaic.

use crate::error::{CoreError, Result};

/// A 2×2 polarizer pattern: four angles in degrees, row by row from the top-left, a
/// permutation of 0, 45, 90, 135.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pattern {
    angles_deg: [f64; 4],
    /// Cell position (0..4, row-major) of the 0°, 45°, 90° and 135° polarizers.
    pub(super) pos: [usize; 4],
}

impl Pattern {
    /// Sony IMX250MZR / IMX253MZR: `90,45,135,0`.
    pub const IMX250MZR: [f64; 4] = [90.0, 45.0, 135.0, 0.0];

    /// Validate a pattern: exactly four angles forming a permutation of 0, 45, 90, 135
    /// (degrees, taken modulo 180).
    pub fn new(angles_deg: &[f64]) -> Result<Self> {
        let err = |reason: &str| CoreError::InvalidPattern {
            pattern_deg: angles_deg.to_vec(),
            reason: reason.to_string(),
        };
        if angles_deg.len() != 4 {
            return Err(err(
                "expected exactly four angles (a 2x2 super-pixel, row by row)",
            ));
        }
        let mut pos = [usize::MAX; 4];
        let mut canon = [0.0; 4];
        for (i, &a) in angles_deg.iter().enumerate() {
            if !a.is_finite() {
                return Err(err("angles must be finite"));
            }
            let r = a.rem_euclid(180.0);
            let k = (r / 45.0).round();
            if (r - 45.0 * k).abs() > 1e-9 {
                return Err(err("angles must be 0, 45, 90 and 135 degrees"));
            }
            let k = (k as usize) % 4;
            if pos[k] != usize::MAX {
                return Err(err("the four angles must be distinct"));
            }
            pos[k] = i;
            canon[i] = 45.0 * k as f64;
        }
        Ok(Self {
            angles_deg: canon,
            pos,
        })
    }

    /// The default pattern, [`Pattern::IMX250MZR`].
    pub fn imx250mzr() -> Self {
        Self {
            angles_deg: Self::IMX250MZR,
            pos: [3, 1, 0, 2],
        }
    }

    /// The four angles, degrees, row by row.
    pub fn angles_deg(&self) -> [f64; 4] {
        self.angles_deg
    }

    /// `(row, column)` within the cell of the polarizer at `k × 45°` (`k` in 0..4).
    pub fn position(&self, k: usize) -> (usize, usize) {
        let p = self.pos[k & 3];
        (p / 2, p % 2)
    }
}

impl Default for Pattern {
    fn default() -> Self {
        Self::imx250mzr()
    }
}

/// The height of a `width`-wide mosaic of `len` pixels: whole rows, even width and
/// height, at least `min × min`; else [`CoreError::InvalidDimensions`].
pub(super) fn check_mosaic(width: usize, len: usize, min: usize) -> Result<usize> {
    let height = len.checked_div(width).unwrap_or(0);
    if width == 0 || len != width * height {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: format!("{len} pixels do not form whole rows"),
        });
    }
    if !width.is_multiple_of(2) || !height.is_multiple_of(2) {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: "a 2x2 polarizer mosaic needs an even width and height".into(),
        });
    }
    if width < min || height < min {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: format!("a polarizer mosaic needs at least {min}x{min} pixels"),
        });
    }
    Ok(height)
}
