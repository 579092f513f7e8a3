//! The exact 0/45/90/135° Stokes form, one pixel at a time: `S0 = ½ ΣI − 2·dark`,
//! `S1 = I0 − I90`, `S2 = I45 − I135`, the mask, the counts and (fused) DoLP/AoLP.
//! Portable source: the loops are branch-free so that the compiler vectorises them,
//! for the baseline target here and for AVX2 + FMA when inlined into `avx2.rs`.

use crate::stokes::mask;
use crate::stokes::pixels::{PixelCounts, PixelRules, Sample};
use crate::stokes::polar::dolp_aolp_pixel;

/// One block of pixels of the exact 0/45/90/135° kernel (see `quad_image`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn quad_block<T: Sample, const POLAR: bool>(
    q: [&[T]; 4],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
    rd: &mut [f32],
    ra: &mut [f32],
) -> PixelCounts {
    let n = r0.len();
    let (q0, q1, q2, q3) = (&q[0][..n], &q[1][..n], &q[2][..n], &q[3][..n]);
    let (r1, r2, rm) = (&mut r1[..n], &mut r2[..n], &mut rm[..n]);
    let dark2 = 2.0 * rules.dark_level;
    let sat = rules.saturation;
    let min_s0 = rules.min_s0;
    let (mut n_sat, mut n_dark, mut n_inv) = (0u32, 0u32, 0u32);
    // `POLAR` is a constant: the branch below costs nothing per pixel, and the
    // non-polar instance never touches `rd`, `ra` (which may then be empty).
    let (rd, ra) = if POLAR {
        (&mut rd[..n], &mut ra[..n])
    } else {
        (&mut rd[..0], &mut ra[..0])
    };
    for i in 0..n {
        let (a, b, c, d) = (
            q0[i].to_f32(),
            q1[i].to_f32(),
            q2[i].to_f32(),
            q3[i].to_f32(),
        );
        let (v0, v1, v2, m) = quad_pixel(a, b, c, d, dark2, sat, min_s0);
        r0[i] = v0;
        r1[i] = v1;
        r2[i] = v2;
        rm[i] = m;
        n_sat += (m == mask::SATURATED) as u32;
        n_dark += (m == mask::DARK) as u32;
        n_inv += (m == mask::INVALID) as u32;
        if POLAR {
            let (pd, pa) = dolp_aolp_pixel(v0, v1, v2);
            let ok = m == mask::VALID;
            rd[i] = if ok { pd } else { f32::NAN };
            ra[i] = if ok { pa } else { f32::NAN };
        }
    }
    let rejected = (n_sat + n_dark + n_inv) as u64;
    PixelCounts {
        valid: n as u64 - rejected,
        saturated: n_sat as u64,
        dark: n_dark as u64,
        invalid: n_inv as u64,
    }
}

/// One pixel of the exact 0/45/90/135° form: `(S0, S1, S2, mask)` from the raw values
/// at 0, 45, 90 and 135° (`dark2` = twice the dark level).
#[inline(always)]
fn quad_pixel(
    a: f32,
    b: f32,
    c: f32,
    d: f32,
    dark2: f32,
    sat: f32,
    min_s0: f32,
) -> (f32, f32, f32, u8) {
    let sum = (a + c) + (b + d);
    let s0 = 0.5 * sum - dark2;
    let s1 = a - c;
    let s2 = b - d;
    let mx = a.max(b).max(c.max(d));
    let nonfinite = !(sum.is_finite() && (s1 + s2).is_finite());
    let m = if nonfinite {
        mask::INVALID
    } else if mx >= sat {
        mask::SATURATED
    } else if s0 <= min_s0 {
        mask::DARK
    } else {
        mask::VALID
    };
    (s0, s1, s2, m)
}

/// Raw Stokes of one row by the exact 0/45/90/135° form, with the raw flag bits of
/// [`StokesSolver::stokes_row_raw`](crate::stokes::StokesSolver::stokes_row_raw).
pub(in crate::stokes) fn quad_row_raw<T: Sample>(
    q: [&[T]; 4],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
) {
    let n = r0.len();
    let (q0, q1, q2, q3) = (&q[0][..n], &q[1][..n], &q[2][..n], &q[3][..n]);
    let (r1, r2, rm) = (&mut r1[..n], &mut r2[..n], &mut rm[..n]);
    let dark2 = 2.0 * rules.dark_level;
    let sat = rules.saturation;
    for i in 0..n {
        let (a, b, c, d) = (
            q0[i].to_f32(),
            q1[i].to_f32(),
            q2[i].to_f32(),
            q3[i].to_f32(),
        );
        let sum = (a + c) + (b + d);
        r0[i] = 0.5 * sum - dark2;
        r1[i] = a - c;
        r2[i] = b - d;
        let mx = a.max(b).max(c.max(d));
        rm[i] = (mx >= sat) as u8 | ((!sum.is_finite()) as u8) << 1;
    }
}
