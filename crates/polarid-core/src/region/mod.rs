//! Region statistics: the DoLP of a target from the mean Stokes vector of its pixels,
//! with a standard error from the pixel scatter.
//!
//! Over the valid pixels (mask [`crate::stokes::mask::VALID`]) of a rectangle, with
//! `n` pixels, the mean Stokes vector `S̄ = (S̄0, S̄1, S̄2)` gives
//! `DoLP = √(S̄1² + S̄2²) / S̄0` (CONVENTIONS; the paper's DoLP of eq. 9 is measured this
//! way, as a ratio of mean intensities, which avoids the upward bias of averaging noisy
//! per-pixel DoLP values).
//!
//! **Standard error (delta method).** The covariance of the mean is estimated from the
//! pixel scatter, `C = F · Ĉ / n`, with `Ĉ` the sample covariance (divisor `n − 1`) of
//! the per-pixel Stokes vectors and `F` a variance inflation factor for correlated
//! pixels (below). With `L = √(S̄1² + S̄2²)` and `D = L / S̄0` the gradient is
//! `g = (−D/S̄0, S̄1/(S̄0 L), S̄2/(S̄0 L))` and `SE(D) = √(gᵀ C g)`. When `L = 0` the
//! gradient is undefined; the SE is then `√(max(C11, C22)) / S̄0` (the scale of the
//! DoLP noise floor).
//!
//! **Pixel correlation** ([`Sampling`]).
//! * [`Sampling::Independent`], `F = 1`: every pixel's Stokes vector comes from its own
//!   raw values (rotating-polarizer frames, super-pixel DoFP).
//! * [`Sampling::BilinearDofp`], `F = 64/9`: pixels of a bilinearly demosaiced DoFP frame
//!   ([`crate::mosaic::bilinear_stokes`]) share raw values. For white raw noise of
//!   variance `σ²` in one channel, the interpolated image has per-pixel variance `σ²`,
//!   `σ²/2`, `σ²/2` and `σ²/4` at the four positions of the cell (own, horizontal,
//!   vertical, diagonal), on average `9σ²/16`; but each raw pixel enters the region mean
//!   with total weight 4 (1 + 4·½ + 4·¼), so the mean of `n` pixels is in effect the mean
//!   of `n/4` raw values, variance `4σ²/n`. The ratio of the true to the naive variance
//!   of the mean is `4 / (9/16) = 64/9` for each channel, hence for every Stokes
//!   component and covariance (the channels are independent). This is exact for an even
//!   width and height away from the frame border (each parity class of the cell is then
//!   equally represented), up to edge terms of relative size `~ 1/w + 1/h`.
//! * [`Sampling::BilinearColour`], `F = 4096/121 ≈ 33.9`: a colour polarization mosaic
//!   interpolated per lattice of period 4 ([`crate::mosaic::colour`]). Along one axis the
//!   four phases weigh the two taps `(1, 0)`, `(¾, ¼)`, `(½, ½)`, `(¼, ¾)`: per-pixel
//!   variance `σ²`, `⅝σ²`, `½σ²`, `⅝σ²`, on average `11/16 σ²`, in 2-D `121/256 σ²`;
//!   each raw value enters the region mean with total weight 16, so the mean of `n`
//!   pixels has variance `16σ²/n`: `F = 16 / (121/256)`. A channel averaging two
//!   lattices (`G` of `RGGB`) has half of both variances: the same `F`.
//!
//! **Calibrated captures** ([`local`]): when every pixel has its own geometry, the
//! Stokes vectors are averaged in each pixel's plane-of-incidence frame, the region's
//! geometry is the S0-weighted mean over its pixels, and the standard error leaves out
//! the deterministic trend of the polarization in β ([`region_stats_local`],
//! docs/GEOMETRY.md).

pub mod local;

pub use local::{LocalRegionStats, RegionGeometry, region_stats_local};

use crate::error::{CoreError, Result};
use crate::stokes::mask;

/// A rectangle of pixels: `x` = column and `y` = row of the top-left corner, then width
/// and height (FORMATS.md, `rect = [x, y, w, h]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// Column of the top-left corner.
    pub x: usize,
    /// Row of the top-left corner.
    pub y: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

impl Rect {
    /// Check that the rectangle is non-empty and inside a `width × height` frame.
    pub fn check(&self, width: usize, height: usize) -> Result<()> {
        let err = |reason: String| CoreError::InvalidRegion {
            x: self.x,
            y: self.y,
            width: self.width,
            height: self.height,
            reason,
        };
        if self.width == 0 || self.height == 0 {
            return Err(err("is empty".into()));
        }
        let fits = self.x.checked_add(self.width).is_some_and(|r| r <= width)
            && self.y.checked_add(self.height).is_some_and(|b| b <= height);
        if !fits {
            return Err(err(format!("leaves the {width}x{height} frame")));
        }
        Ok(())
    }
}

/// How the per-pixel Stokes vectors were obtained, for the standard error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sampling {
    /// Independent pixels (rotating-polarizer frames, super-pixel DoFP, Stokes files).
    #[default]
    Independent,
    /// Bilinearly demosaiced DoFP pixels: variance inflation `64/9` (module docs).
    BilinearDofp,
    /// Bilinearly interpolated colour polarization pixels
    /// ([`crate::mosaic::colour`]): variance inflation `4096/121` (module docs).
    BilinearColour,
}

impl Sampling {
    /// Variance inflation factor `F` of the module docs.
    pub fn variance_inflation(self) -> f64 {
        match self {
            Sampling::Independent => 1.0,
            Sampling::BilinearDofp => 64.0 / 9.0,
            Sampling::BilinearColour => 4096.0 / 121.0,
        }
    }
}

/// Statistics of one region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionStats {
    /// Mean Stokes vector `(S̄0, S̄1, S̄2)` over the valid pixels.
    pub mean: [f64; 3],
    /// Covariance of the mean Stokes vector (`F Ĉ / n`); zeros when fewer than 2 pixels.
    pub cov_mean: [[f64; 3]; 3],
    /// DoLP of the mean Stokes vector, clamped to `[0, 1]`.
    pub dolp: f64,
    /// Standard error of `dolp` (delta method); `None` with fewer than 2 valid pixels.
    pub dolp_se: Option<f64>,
    /// Valid pixels used.
    pub pixels: u64,
    /// Pixels left out (saturated, dark, invalid).
    pub rejected: u64,
    /// Pixels left out because they were saturated (part of `rejected`).
    pub saturated: u64,
}

impl RegionStats {
    /// Mean `S0`.
    pub fn s0(&self) -> f64 {
        self.mean[0]
    }
}

/// DoLP and its delta-method standard error from a mean Stokes vector and the
/// covariance of that mean (module docs). `None` for the SE when `S̄0 <= 0`.
pub fn dolp_with_se(mean: [f64; 3], cov: [[f64; 3]; 3]) -> (f64, Option<f64>) {
    let [m0, m1, m2] = mean;
    let l = m1.hypot(m2);
    let d = (l / m0).clamp(0.0, 1.0);
    if m0 <= 0.0 || !m0.is_finite() {
        return (f64::NAN, None);
    }
    let se = if l > 0.0 {
        let g = [-(l / m0) / m0, m1 / (m0 * l), m2 / (m0 * l)];
        let mut v = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                v += g[i] * cov[i][j] * g[j];
            }
        }
        v.max(0.0).sqrt()
    } else {
        cov[1][1].max(cov[2][2]).max(0.0).sqrt() / m0
    };
    (d, Some(se))
}

/// Statistics of the region `rect` of Stokes images `s0, s1, s2` with validity `mask`
/// (all `width` pixels wide, same length). Errors: [`CoreError::InvalidRegion`] when the
/// region is empty, leaves the frame, or holds no valid pixel.
#[allow(clippy::too_many_arguments)]
pub fn region_stats(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    mask: &[u8],
    rect: Rect,
    sampling: Sampling,
) -> Result<RegionStats> {
    crate::stokes::check_image(width, s0.len())?;
    let n = s0.len();
    crate::error::check_len("s1", s1.len(), n)?;
    crate::error::check_len("s2", s2.len(), n)?;
    crate::error::check_len("mask", mask.len(), n)?;
    let height = n / width;
    rect.check(width, height)?;
    let rows = rect.y..rect.y + rect.height;
    let cols = rect.x..rect.x + rect.width;
    // Pass 1: counts and mean.
    let mut cnt = [0u64; 4];
    let mut sum = [0.0f64; 3];
    for y in rows.clone() {
        let o = y * width;
        for x in cols.clone() {
            let i = o + x;
            let m = mask[i];
            cnt[(m & 3) as usize] += 1;
            if m == mask::VALID {
                sum[0] += s0[i] as f64;
                sum[1] += s1[i] as f64;
                sum[2] += s2[i] as f64;
            }
        }
    }
    let pixels = cnt[0];
    let rejected = cnt[1] + cnt[2] + cnt[3];
    if pixels == 0 {
        return Err(CoreError::InvalidRegion {
            x: rect.x,
            y: rect.y,
            width: rect.width,
            height: rect.height,
            reason: format!(
                "has no usable pixel ({} saturated, {} dark, {} invalid)",
                cnt[1], cnt[2], cnt[3]
            ),
        });
    }
    let nf = pixels as f64;
    let mean = [sum[0] / nf, sum[1] / nf, sum[2] / nf];
    // Pass 2: sample covariance about the mean.
    let mut c = [[0.0f64; 3]; 3];
    for y in rows {
        let o = y * width;
        for x in cols.clone() {
            let i = o + x;
            if mask[i] == mask::VALID {
                let d = [
                    s0[i] as f64 - mean[0],
                    s1[i] as f64 - mean[1],
                    s2[i] as f64 - mean[2],
                ];
                for a in 0..3 {
                    for b in a..3 {
                        c[a][b] += d[a] * d[b];
                    }
                }
            }
        }
    }
    let mut cov_mean = [[0.0f64; 3]; 3];
    if pixels >= 2 {
        let f = sampling.variance_inflation() / ((nf - 1.0) * nf);
        for a in 0..3 {
            for b in a..3 {
                cov_mean[a][b] = c[a][b] * f;
                cov_mean[b][a] = cov_mean[a][b];
            }
        }
    }
    let (dolp, se) = dolp_with_se(mean, cov_mean);
    Ok(RegionStats {
        mean,
        cov_mean,
        dolp,
        dolp_se: if pixels >= 2 { se } else { None },
        pixels,
        rejected,
        saturated: cnt[1],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rect_checks() {
        let r = Rect {
            x: 2,
            y: 3,
            width: 4,
            height: 5,
        };
        assert!(r.check(6, 8).is_ok());
        assert!(matches!(
            r.check(5, 8),
            Err(CoreError::InvalidRegion { .. })
        ));
        let e = Rect { width: 0, ..r };
        assert!(e.check(100, 100).is_err());
        let huge = Rect { x: usize::MAX, ..r };
        assert!(huge.check(100, 100).is_err());
    }

    #[test]
    fn stats_of_constant_region_and_mask() {
        let w = 4;
        let s0 = vec![2.0f32; 16];
        let s1 = vec![0.6f32; 16];
        let s2 = vec![0.8f32; 16];
        let mut m = vec![0u8; 16];
        m[5] = mask::SATURATED;
        m[6] = mask::DARK;
        let r = Rect {
            x: 0,
            y: 0,
            width: 4,
            height: 4,
        };
        let st = region_stats(w, &s0, &s1, &s2, &m, r, Sampling::Independent).unwrap();
        assert_eq!((st.pixels, st.rejected, st.saturated), (14, 2, 1));
        assert!((st.dolp - 0.5).abs() < 1e-7);
        assert!(st.dolp_se.unwrap() < 1e-9);
        let all = vec![mask::SATURATED; 16];
        assert!(matches!(
            region_stats(w, &s0, &s1, &s2, &all, r, Sampling::Independent),
            Err(CoreError::InvalidRegion { .. })
        ));
    }
}
