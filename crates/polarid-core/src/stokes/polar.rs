//! DoLP and AoLP from Stokes values (CONVENTIONS): `DoLP = √(S1² + S2²) / S0` clamped
//! to `[0, 1]`, `AoLP = atan2(S2, S1) / 2` in degrees in `[0, 180)`, with a branch-free
//! polynomial `atan2` so that the loops over pixels vectorise.

use rayon::prelude::*;

use super::mask;
use super::pixels::check_image;
use crate::error::{Result, check_len};

const ATAN_C: [f32; 8] = [
    0.999_999_34,
    -0.333_298_6,
    0.199_465_66,
    -0.139_086_28,
    0.096_421_91,
    -0.055_912_23,
    0.021_862_883,
    -0.004_054_544_5,
];

/// `atan2(y, x)` in radians by an odd minimax polynomial on `[0, 1]` (max error
/// 4e-8 rad, below `f32` resolution of the result) and octant folding; branch-free so
/// that loops over it vectorise. `atan2(0, 0) = 0`.
#[inline(always)]
pub fn atan2_fast(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let mx = ax.max(ay);
    let mn = ax.min(ay);
    let t = if mx > 0.0 { mn / mx } else { 0.0 };
    let s = t * t;
    let mut p = ATAN_C[7];
    p = p * s + ATAN_C[6];
    p = p * s + ATAN_C[5];
    p = p * s + ATAN_C[4];
    p = p * s + ATAN_C[3];
    p = p * s + ATAN_C[2];
    p = p * s + ATAN_C[1];
    p = p * s + ATAN_C[0];
    let mut r = p * t;
    r = if ay > ax {
        std::f32::consts::FRAC_PI_2 - r
    } else {
        r
    };
    r = if x < 0.0 { std::f32::consts::PI - r } else { r };
    if y < 0.0 { -r } else { r }
}

/// DoLP and AoLP of one pixel (CONVENTIONS): `DoLP = √(S1²+S2²)/S0` clamped to `[0, 1]`,
/// `AoLP = atan2(S2, S1)/2` in degrees in `[0, 180)`. NaN for both when `S0 <= 0` or
/// any component is not finite.
#[inline(always)]
pub fn dolp_aolp_pixel(s0: f32, s1: f32, s2: f32) -> (f32, f32) {
    let l = (s1 * s1 + s2 * s2).sqrt();
    let d = (l / s0).clamp(0.0, 1.0);
    let a = atan2_fast(s2, s1) * (90.0 / std::f32::consts::PI);
    let a = if a < 0.0 { a + 180.0 } else { a };
    let a = if a >= 180.0 { a - 180.0 } else { a };
    let ok = s0 > 0.0 && s0.is_finite() && s1.is_finite() && s2.is_finite();
    if ok { (d, a) } else { (f32::NAN, f32::NAN) }
}

/// DoLP and AoLP of one row; NaN where `mask` (if given) rejects the pixel.
#[inline]
pub(super) fn polar_row(
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    mask: Option<&[u8]>,
    dolp: &mut [f32],
    aolp: &mut [f32],
) {
    for ((((&a0, &a1), &a2), d), a) in s0
        .iter()
        .zip(s1)
        .zip(s2)
        .zip(dolp.iter_mut())
        .zip(aolp.iter_mut())
    {
        let (pd, pa) = dolp_aolp_pixel(a0, a1, a2);
        *d = pd;
        *a = pa;
    }
    if let Some(m) = mask {
        for ((&m, d), a) in m.iter().zip(dolp.iter_mut()).zip(aolp.iter_mut()) {
            if m != mask::VALID {
                *d = f32::NAN;
                *a = f32::NAN;
            }
        }
    }
}

/// DoLP and AoLP images from Stokes images (all `width × height`), NaN where `mask`
/// (if given) rejects the pixel or `S0 <= 0`. See [`dolp_aolp_pixel`].
pub fn dolp_aolp(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    mask: Option<&[u8]>,
    dolp: &mut [f32],
    aolp: &mut [f32],
) -> Result<()> {
    let n = s0.len();
    check_image(width, n)?;
    check_len("s1", s1.len(), n)?;
    check_len("s2", s2.len(), n)?;
    check_len("dolp", dolp.len(), n)?;
    check_len("aolp", aolp.len(), n)?;
    if let Some(m) = mask {
        check_len("mask", m.len(), n)?;
    }
    dolp.par_chunks_mut(width)
        .zip(aolp.par_chunks_mut(width))
        .enumerate()
        .for_each(|(y, (rd, ra))| {
            let r = y * width..(y + 1) * width;
            polar_row(
                &s0[r.clone()],
                &s1[r.clone()],
                &s2[r.clone()],
                mask.map(|m| &m[r]),
                rd,
                ra,
            );
        });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan2_fast_matches_std() {
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let t = i as f64 * 0.0031416 - 3.1;
            for r in [1e-3f64, 1.0, 1e4] {
                let (y, x) = ((r * t.sin()) as f32, (r * t.cos()) as f32);
                let e = (atan2_fast(y, x) as f64 - (y as f64).atan2(x as f64)).abs();
                worst = worst.max(e);
            }
        }
        assert!(worst < 5e-7, "worst {worst}");
        assert_eq!(atan2_fast(0.0, 0.0), 0.0);
        assert!((atan2_fast(0.0, -1.0) - std::f32::consts::PI).abs() < 1e-6);
    }

    #[test]
    fn dolp_aolp_conventions() {
        let (d, a) = dolp_aolp_pixel(2.0, 0.0, 1.0);
        assert!((d - 0.5).abs() < 1e-7 && (a - 45.0).abs() < 1e-4);
        let (_, a) = dolp_aolp_pixel(2.0, -1.0, -1e-9);
        assert!((0.0..180.0).contains(&a) && (a - 90.0).abs() < 1e-3, "{a}");
        let (_, a) = dolp_aolp_pixel(2.0, 1.0, -1e-3);
        assert!((0.0..180.0).contains(&a) && a > 179.9, "{a}");
        let (d, _) = dolp_aolp_pixel(1.0, 3.0, 0.0);
        assert_eq!(d, 1.0);
        assert!(dolp_aolp_pixel(0.0, 1.0, 0.0).0.is_nan());
    }
}
