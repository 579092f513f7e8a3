//! Levenberg–Marquardt polishes of many fits at once, one fit per SIMD lane.
//!
//! Every polish evaluates eq. (9) and its gradient at a trial point, then decides
//! (accept, reject, stop). Running [`W`] polishes side by side, each lane on its own
//! fit, turns the evaluation loop over the `T` source positions into straight vector
//! arithmetic (two f64x8 with AVX-512F, four f64x4 with AVX2 + FMA, lane loops
//! elsewhere; the caller is compiled for the instruction set, see
//! `FitPlan::fit_chunk`) with no padding lanes and no horizontal sums, and the
//! Levenberg–Marquardt step into branch-free lane code. A lane whose polish ends takes
//! the next job of the queue at once ("lane refill"), so lanes do not wait for each
//! other: a polish is the same sequence of trial points whatever its neighbours do,
//! and its result does not depend on the batch it ran in.
//!
//! One job is one polish: the stored-Jacobian Gauss–Newton start of a grid node, the
//! node itself if that start is worse than the node, then Levenberg–Marquardt with
//! Marquardt scaling, the bounded `(n, u = k²)` steps below `k = 1`, and the stopping
//! rules of the module documentation of `fit` (relative step below `xtol`, predicted or
//! accepted relative decrease below `ftol`, iteration limit).

use super::FitBounds;
use super::lm::{Eval, K_FLOOR, K_U};
use super::simd::Lanes;

/// Fits polished side by side (two f64x8 vectors, or four f64x4).
pub(crate) const W: usize = 16;

type L = [f64; W];

/// Damping factor after a rejected step.
const LAM_UP: f64 = 5.0;
/// Damping factor after an accepted step.
const LAM_DOWN: f64 = 0.2;
/// Initial damping.
const LAM_0: f64 = 1e-6;
/// Smallest damping after a rejected step: a rejection means the Gauss–Newton model
/// failed at this scale (typically a curved valley), and climbing there from `1e-6` by
/// factors of [`LAM_UP`] would cost several rejected evaluations.
const LAM_REJECT: f64 = 1e-3;

/// The vector operations on [`W`] lanes the engine needs: AVX-512F or AVX2 + FMA
/// intrinsics (`Avx512`, `Avx2`, only called from functions compiled for those
/// features) or plain lane loops
/// ([`Portable`]). Comparisons give masks; `min`/`max` are `a < b ? a : b` /
/// `a > b ? a : b` (no NaN handling).
pub(crate) trait Simd: Copy {
    /// [`W`] f64.
    type V: Copy;
    /// [`W`] lane flags.
    type M: Copy;
    fn splat(x: f64) -> Self::V;
    /// The first [`W`] values of `p`.
    fn load(p: &[f64]) -> Self::V;
    /// Into the first [`W`] values of `p`.
    fn store(v: Self::V, p: &mut [f64]);
    fn add(a: Self::V, b: Self::V) -> Self::V;
    fn sub(a: Self::V, b: Self::V) -> Self::V;
    fn mul(a: Self::V, b: Self::V) -> Self::V;
    fn div(a: Self::V, b: Self::V) -> Self::V;
    fn sqrt(a: Self::V) -> Self::V;
    /// `a·b + c` (fused on AVX2 + FMA).
    fn fma(a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    fn abs(a: Self::V) -> Self::V;
    /// `a < b ? a : b`.
    fn min(a: Self::V, b: Self::V) -> Self::V;
    /// `a > b ? a : b`.
    fn max(a: Self::V, b: Self::V) -> Self::V;
    fn lt(a: Self::V, b: Self::V) -> Self::M;
    fn le(a: Self::V, b: Self::V) -> Self::M;
    fn eq(a: Self::V, b: Self::V) -> Self::M;
    fn and(a: Self::M, b: Self::M) -> Self::M;
    fn or(a: Self::M, b: Self::M) -> Self::M;
    fn not(a: Self::M) -> Self::M;
    /// `m ? a : b` lane by lane.
    fn select(m: Self::M, a: Self::V, b: Self::V) -> Self::V;
    /// Bit `l` set when lane `l` of `m` is set.
    fn bits(m: Self::M) -> u32;
    /// The mask with lane `l` set when bit `l` of `b` is.
    fn from_bits(b: u32) -> Self::M;
}

/// [`Simd`] by lane loops (any CPU).
#[derive(Clone, Copy)]
pub(crate) struct Portable;

macro_rules! lanes {
    (|$($x:ident),*| $e:expr) => {{
        let mut o = [Default::default(); W];
        for l in 0..W {
            $(let $x = $x[l];)*
            o[l] = $e;
        }
        o
    }};
}

impl Simd for Portable {
    type V = L;
    type M = [bool; W];
    #[inline(always)]
    fn splat(x: f64) -> L {
        [x; W]
    }
    #[inline(always)]
    fn load(p: &[f64]) -> L {
        let mut v = [0.0; W];
        v.copy_from_slice(&p[..W]);
        v
    }
    #[inline(always)]
    fn store(v: L, p: &mut [f64]) {
        p[..W].copy_from_slice(&v);
    }
    #[inline(always)]
    fn add(a: L, b: L) -> L {
        lanes!(|a, b| a + b)
    }
    #[inline(always)]
    fn sub(a: L, b: L) -> L {
        lanes!(|a, b| a - b)
    }
    #[inline(always)]
    fn mul(a: L, b: L) -> L {
        lanes!(|a, b| a * b)
    }
    #[inline(always)]
    fn div(a: L, b: L) -> L {
        lanes!(|a, b| a / b)
    }
    #[inline(always)]
    fn sqrt(a: L) -> L {
        lanes!(|a| a.sqrt())
    }
    #[inline(always)]
    fn fma(a: L, b: L, c: L) -> L {
        lanes!(|a, b, c| a * b + c)
    }
    #[inline(always)]
    fn abs(a: L) -> L {
        lanes!(|a| a.abs())
    }
    #[inline(always)]
    fn min(a: L, b: L) -> L {
        lanes!(|a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn max(a: L, b: L) -> L {
        lanes!(|a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn lt(a: L, b: L) -> [bool; W] {
        lanes!(|a, b| a < b)
    }
    #[inline(always)]
    fn le(a: L, b: L) -> [bool; W] {
        lanes!(|a, b| a <= b)
    }
    #[inline(always)]
    fn eq(a: L, b: L) -> [bool; W] {
        lanes!(|a, b| a == b)
    }
    #[inline(always)]
    fn and(a: [bool; W], b: [bool; W]) -> [bool; W] {
        lanes!(|a, b| a & b)
    }
    #[inline(always)]
    fn or(a: [bool; W], b: [bool; W]) -> [bool; W] {
        lanes!(|a, b| a | b)
    }
    #[inline(always)]
    fn not(a: [bool; W]) -> [bool; W] {
        lanes!(|a| !a)
    }
    #[inline(always)]
    fn select(m: [bool; W], a: L, b: L) -> L {
        lanes!(|m, a, b| if m { a } else { b })
    }
    #[inline(always)]
    fn bits(m: [bool; W]) -> u32 {
        m.iter()
            .enumerate()
            .fold(0, |acc, (l, &v)| acc | (u32::from(v) << l))
    }
    #[inline(always)]
    fn from_bits(b: u32) -> [bool; W] {
        let mut m = [false; W];
        for (l, v) in m.iter_mut().enumerate() {
            *v = (b >> l) & 1 == 1;
        }
        m
    }
}

/// [`Simd`] with AVX2 + FMA intrinsics, four f64x4 per vector. Only for code inlined
/// into a function compiled with `#[target_feature(enable = "avx2,fma")]`, on a CPU
/// that has them (the fit checks at run time before it calls such a function).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct Avx2;

/// [`Simd`] with AVX-512F intrinsics, two f64x8 per vector. Only for code inlined into
/// a function compiled with `#[target_feature(enable = "avx512f,avx2,fma")]`, on a CPU
/// that has them.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct Avx512;

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{Avx2, Avx512, Simd, W};
    use std::arch::x86_64::*;

    macro_rules! pair {
        ($f:ident($($a:ident),*)) => {
            unsafe { [$f($($a[0]),*), $f($($a[1]),*), $f($($a[2]),*), $f($($a[3]),*)] }
        };
    }
    macro_rules! pair2 {
        ($f:ident($($a:ident),*)) => {
            unsafe { [$f($($a[0]),*), $f($($a[1]),*)] }
        };
    }

    // SAFETY (every method): `Avx2` is only used inside functions compiled for
    // AVX2 + FMA and called after a run-time check that the CPU has them; loads and
    // stores go through slices of length W (bounds-checked) before the pointer is used.
    impl Simd for Avx2 {
        type V = [__m256d; 4];
        type M = [__m256d; 4];
        #[inline(always)]
        fn splat(x: f64) -> Self::V {
            unsafe { [_mm256_set1_pd(x); 4] }
        }
        #[inline(always)]
        fn load(p: &[f64]) -> Self::V {
            let p = &p[..W];
            unsafe {
                [
                    _mm256_loadu_pd(p.as_ptr()),
                    _mm256_loadu_pd(p.as_ptr().add(4)),
                    _mm256_loadu_pd(p.as_ptr().add(8)),
                    _mm256_loadu_pd(p.as_ptr().add(12)),
                ]
            }
        }
        #[inline(always)]
        fn store(v: Self::V, p: &mut [f64]) {
            let p = &mut p[..W];
            unsafe {
                _mm256_storeu_pd(p.as_mut_ptr(), v[0]);
                _mm256_storeu_pd(p.as_mut_ptr().add(4), v[1]);
                _mm256_storeu_pd(p.as_mut_ptr().add(8), v[2]);
                _mm256_storeu_pd(p.as_mut_ptr().add(12), v[3]);
            }
        }
        #[inline(always)]
        fn add(a: Self::V, b: Self::V) -> Self::V {
            pair!(_mm256_add_pd(a, b))
        }
        #[inline(always)]
        fn sub(a: Self::V, b: Self::V) -> Self::V {
            pair!(_mm256_sub_pd(a, b))
        }
        #[inline(always)]
        fn mul(a: Self::V, b: Self::V) -> Self::V {
            pair!(_mm256_mul_pd(a, b))
        }
        #[inline(always)]
        fn div(a: Self::V, b: Self::V) -> Self::V {
            pair!(_mm256_div_pd(a, b))
        }
        #[inline(always)]
        fn sqrt(a: Self::V) -> Self::V {
            pair!(_mm256_sqrt_pd(a))
        }
        #[inline(always)]
        fn fma(a: Self::V, b: Self::V, c: Self::V) -> Self::V {
            pair!(_mm256_fmadd_pd(a, b, c))
        }
        #[inline(always)]
        fn abs(a: Self::V) -> Self::V {
            let m = Self::splat(-0.0);
            pair!(_mm256_andnot_pd(m, a))
        }
        #[inline(always)]
        fn min(a: Self::V, b: Self::V) -> Self::V {
            // vminpd gives the second operand unless a < b.
            pair!(_mm256_min_pd(a, b))
        }
        #[inline(always)]
        fn max(a: Self::V, b: Self::V) -> Self::V {
            pair!(_mm256_max_pd(a, b))
        }
        #[inline(always)]
        fn lt(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm256_cmp_pd::<_CMP_LT_OQ>(a[0], b[0]),
                    _mm256_cmp_pd::<_CMP_LT_OQ>(a[1], b[1]),
                    _mm256_cmp_pd::<_CMP_LT_OQ>(a[2], b[2]),
                    _mm256_cmp_pd::<_CMP_LT_OQ>(a[3], b[3]),
                ]
            }
        }
        #[inline(always)]
        fn le(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm256_cmp_pd::<_CMP_LE_OQ>(a[0], b[0]),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(a[1], b[1]),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(a[2], b[2]),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(a[3], b[3]),
                ]
            }
        }
        #[inline(always)]
        fn eq(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(a[0], b[0]),
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(a[1], b[1]),
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(a[2], b[2]),
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(a[3], b[3]),
                ]
            }
        }
        #[inline(always)]
        fn and(a: Self::M, b: Self::M) -> Self::M {
            pair!(_mm256_and_pd(a, b))
        }
        #[inline(always)]
        fn or(a: Self::M, b: Self::M) -> Self::M {
            pair!(_mm256_or_pd(a, b))
        }
        #[inline(always)]
        fn not(a: Self::M) -> Self::M {
            let ones = unsafe { [_mm256_castsi256_pd(_mm256_set1_epi64x(-1)); 4] };
            pair!(_mm256_xor_pd(a, ones))
        }
        #[inline(always)]
        fn select(m: Self::M, a: Self::V, b: Self::V) -> Self::V {
            pair!(_mm256_blendv_pd(b, a, m))
        }
        #[inline(always)]
        fn bits(m: Self::M) -> u32 {
            unsafe {
                (_mm256_movemask_pd(m[0])
                    | (_mm256_movemask_pd(m[1]) << 4)
                    | (_mm256_movemask_pd(m[2]) << 8)
                    | (_mm256_movemask_pd(m[3]) << 12)) as u32
            }
        }
        #[inline(always)]
        fn from_bits(b: u32) -> Self::M {
            unsafe {
                let sel = _mm256_set_epi64x(8, 4, 2, 1);
                let part = |q: u32| {
                    let v = _mm256_set1_epi64x(i64::from((b >> (4 * q)) & 15));
                    _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(v, sel), sel))
                };
                [part(0), part(1), part(2), part(3)]
            }
        }
    }

    // SAFETY (every method): as for `Avx2`, with AVX-512F.
    impl Simd for Avx512 {
        type V = [__m512d; 2];
        type M = [__mmask8; 2];
        #[inline(always)]
        fn splat(x: f64) -> Self::V {
            unsafe { [_mm512_set1_pd(x); 2] }
        }
        #[inline(always)]
        fn load(p: &[f64]) -> Self::V {
            let p = &p[..W];
            unsafe {
                [
                    _mm512_loadu_pd(p.as_ptr()),
                    _mm512_loadu_pd(p.as_ptr().add(8)),
                ]
            }
        }
        #[inline(always)]
        fn store(v: Self::V, p: &mut [f64]) {
            let p = &mut p[..W];
            unsafe {
                _mm512_storeu_pd(p.as_mut_ptr(), v[0]);
                _mm512_storeu_pd(p.as_mut_ptr().add(8), v[1]);
            }
        }
        #[inline(always)]
        fn add(a: Self::V, b: Self::V) -> Self::V {
            pair2!(_mm512_add_pd(a, b))
        }
        #[inline(always)]
        fn sub(a: Self::V, b: Self::V) -> Self::V {
            pair2!(_mm512_sub_pd(a, b))
        }
        #[inline(always)]
        fn mul(a: Self::V, b: Self::V) -> Self::V {
            pair2!(_mm512_mul_pd(a, b))
        }
        #[inline(always)]
        fn div(a: Self::V, b: Self::V) -> Self::V {
            pair2!(_mm512_div_pd(a, b))
        }
        #[inline(always)]
        fn sqrt(a: Self::V) -> Self::V {
            pair2!(_mm512_sqrt_pd(a))
        }
        #[inline(always)]
        fn fma(a: Self::V, b: Self::V, c: Self::V) -> Self::V {
            pair2!(_mm512_fmadd_pd(a, b, c))
        }
        #[inline(always)]
        fn abs(a: Self::V) -> Self::V {
            pair2!(_mm512_abs_pd(a))
        }
        #[inline(always)]
        fn min(a: Self::V, b: Self::V) -> Self::V {
            pair2!(_mm512_min_pd(a, b))
        }
        #[inline(always)]
        fn max(a: Self::V, b: Self::V) -> Self::V {
            pair2!(_mm512_max_pd(a, b))
        }
        #[inline(always)]
        fn lt(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a[0], b[0]),
                    _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a[1], b[1]),
                ]
            }
        }
        #[inline(always)]
        fn le(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a[0], b[0]),
                    _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a[1], b[1]),
                ]
            }
        }
        #[inline(always)]
        fn eq(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a[0], b[0]),
                    _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a[1], b[1]),
                ]
            }
        }
        #[inline(always)]
        fn and(a: Self::M, b: Self::M) -> Self::M {
            [a[0] & b[0], a[1] & b[1]]
        }
        #[inline(always)]
        fn or(a: Self::M, b: Self::M) -> Self::M {
            [a[0] | b[0], a[1] | b[1]]
        }
        #[inline(always)]
        fn not(a: Self::M) -> Self::M {
            [!a[0], !a[1]]
        }
        #[inline(always)]
        fn select(m: Self::M, a: Self::V, b: Self::V) -> Self::V {
            unsafe {
                [
                    _mm512_mask_blend_pd(m[0], b[0], a[0]),
                    _mm512_mask_blend_pd(m[1], b[1], a[1]),
                ]
            }
        }
        #[inline(always)]
        fn bits(m: Self::M) -> u32 {
            u32::from(m[0]) | (u32::from(m[1]) << 8)
        }
        #[inline(always)]
        fn from_bits(b: u32) -> Self::M {
            [b as u8, (b >> 8) as u8]
        }
    }
}

/// One polish to run.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Job {
    /// Row of the job's measurements in the `y` (and `w`) given to [`run`].
    pub pixel: usize,
    /// First trial point (the stored-Jacobian Gauss–Newton step from the node).
    pub start: (f64, f64),
    /// The grid node, tried when `start` is worse than the node's grid cost.
    pub node: (f64, f64),
    /// Cost of the node on the grid (f32 precision).
    pub grid_cost: f64,
}

/// Outcome of one polish.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct JobOut {
    pub n: f64,
    pub k: f64,
    pub ev: Eval,
    pub iters: u32,
    pub evals: u32,
    pub converged: bool,
}

/// Solver settings shared by every job.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settings {
    pub bounds: FitBounds,
    pub max_iter: u32,
    pub xtol: f64,
    pub ftol: f64,
}

/// Lane-major copies of the measurements of the jobs in the lanes:
/// `y[t * W + l]`, `w[t * W + l]`.
#[derive(Debug, Clone, Default)]
pub(crate) struct LaneScratch {
    y: Vec<f64>,
    w: Vec<f64>,
}

/// Cost and normal equations of every lane.
struct EvalV<S: Simd> {
    cost: S::V,
    h00: S::V,
    h01: S::V,
    h11: S::V,
    g0: S::V,
    g1: S::V,
}

impl<S: Simd> Clone for EvalV<S> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<S: Simd> Copy for EvalV<S> {}

impl<S: Simd> EvalV<S> {
    /// `m ? a : b` for every field.
    #[inline(always)]
    fn select(m: S::M, a: &Self, b: &Self) -> Self {
        Self {
            cost: S::select(m, a.cost, b.cost),
            h00: S::select(m, a.h00, b.h00),
            h01: S::select(m, a.h01, b.h01),
            h11: S::select(m, a.h11, b.h11),
            g0: S::select(m, a.g0, b.g0),
            g1: S::select(m, a.g1, b.g1),
        }
    }
}

/// Lane `l` of `v`.
#[inline(always)]
fn lane<S: Simd>(v: S::V, l: usize) -> f64 {
    let mut a = [0.0; W];
    S::store(v, &mut a);
    a[l]
}

/// Cost `Σ w (P − y)²` and normal equations at `(n_l, k_l)` for every lane: eq. (9)
/// and its analytic gradient in the arithmetic of [`crate::dop::dop_grad_terms`] (the
/// `hypot` fallback dropped, exact for bounds below `1e100`, checked by the plan).
/// `y`, `w`: lane-major, `y[t * W + l]`.
#[inline(always)]
fn eval_lanes<S: Simd, const WEIGHTED: bool>(
    lanes: &Lanes,
    t_len: usize,
    y: &[f64],
    w: &[f64],
    vn: S::V,
    vk: S::V,
) -> EvalV<S> {
    let (y, w) = (&y[..t_len * W], &w[..t_len * W]);
    let (s2v, cv, c2v, s4v, numv) = lanes.terms(t_len);
    let nn = S::mul(vn, vn);
    let kk = S::mul(vk, vk);
    let nk = S::mul(vn, vk);
    let nn_kk = S::add(nn, kk);
    let d0 = S::sub(nn, kk);
    let q4 = S::mul(S::mul(S::splat(4.0), nk), nk);
    let two_n = S::add(vn, vn);
    let two_k = S::add(vk, vk);
    let (zero, half, one, tiny) = (
        S::splat(0.0),
        S::splat(0.5),
        S::splat(1.0),
        S::splat(f64::MIN_POSITIVE),
    );
    let mut a_cost = zero;
    let mut a_h00 = zero;
    let mut a_h01 = zero;
    let mut a_h11 = zero;
    let mut a_g0 = zero;
    let mut a_g1 = zero;
    for t in 0..t_len {
        let (s2, c, c2, s4, num) = (
            S::splat(s2v[t]),
            S::splat(cv[t]),
            S::splat(c2v[t]),
            S::splat(s4v[t]),
            S::splat(numv[t]),
        );
        let d = S::sub(d0, s2); // eq. (15)
        let r = S::sqrt(S::fma(d, d, q4)); // √C, eq. (14)
        let rho = S::sqrt(S::mul(S::add(r, S::abs(d)), half));
        let small = S::div(nk, S::max(rho, tiny));
        let pos = S::le(zero, d);
        let a = S::select(pos, rho, small);
        let b = S::select(pos, small, rho);
        let q = S::fma(c2, r, s4);
        let inv_q = S::div(one, q);
        // P, eq. (9), with the cancellation-free form above 1/2 (see dop::p_value).
        let x = S::mul(c, a);
        let p_lo = S::mul(S::mul(S::add(x, x), s2), inv_q);
        let ex = S::sub(x, s2);
        let cb = S::mul(c, b);
        let p_hi = S::sub(one, S::mul(S::fma(ex, ex, S::mul(cb, cb)), inv_q));
        let p = S::select(S::lt(half, p_lo), p_hi, p_lo);
        let p = S::min(S::max(p, zero), one);
        // Gradient (dop::dop_grad_terms).
        let ok = S::lt(zero, r);
        let inv_r = S::div(one, S::max(r, tiny));
        let u = S::sub(nn_kk, s2);
        let v = S::add(nn_kk, s2);
        let da_dn = S::mul(S::fma(vn, a, S::mul(vk, b)), inv_r);
        let da_dk = S::div(S::mul(S::mul(S::mul(two_n, s2), b), inv_r), S::add(v, r));
        let dr_dn = S::mul(S::mul(two_n, u), inv_r);
        let dr_dk = S::mul(S::mul(two_k, v), inv_r);
        let ac2 = S::mul(a, c2);
        let f = S::mul(S::mul(num, inv_q), inv_q);
        let jn = S::mul(f, S::sub(S::mul(da_dn, q), S::mul(ac2, dr_dn)));
        let jk = S::mul(f, S::sub(S::mul(da_dk, q), S::mul(ac2, dr_dk)));
        let jn = S::select(ok, jn, zero);
        let jk = S::select(ok, jk, zero);
        let p = S::select(ok, p, zero);
        let res = S::sub(p, S::load(&y[t * W..]));
        // Unweighted: the same sums without the multiplications by w = 1 (bitwise
        // equal: 1·x = x).
        let (wr, wjn, wjk) = if WEIGHTED {
            let wt = S::load(&w[t * W..]);
            (S::mul(wt, res), S::mul(wt, jn), S::mul(wt, jk))
        } else {
            (res, jn, jk)
        };
        a_cost = S::fma(wr, res, a_cost);
        a_h00 = S::fma(wjn, jn, a_h00);
        a_h01 = S::fma(wjn, jk, a_h01);
        a_h11 = S::fma(wjk, jk, a_h11);
        a_g0 = S::fma(jn, wr, a_g0);
        a_g1 = S::fma(jk, wr, a_g1);
    }
    EvalV {
        cost: a_cost,
        h00: a_h00,
        h01: a_h01,
        h11: a_h11,
        g0: a_g0,
        g1: a_g1,
    }
}

/// The damped step of `lm::step` for every lane, without branches: solve
/// `(H + λ diag H) δ = −g` (in `(n, u = k²)` below `k = 1`), hold a parameter fixed on
/// a bound the descent direction points out of, project into the box, and return the
/// trial points and the decrease the Gauss–Newton model predicts for them.
#[inline(always)]
fn step_lanes<S: Simd>(
    e: &EvalV<S>,
    lam: S::V,
    vn: S::V,
    vk: S::V,
    b: &FitBounds,
) -> (S::V, S::V, S::V) {
    let k_lo = if b.k_min > 0.0 { b.k_min } else { K_FLOOR };
    let (zero, one, two, neg) = (S::splat(0.0), S::splat(1.0), S::splat(2.0), S::splat(-1.0));
    let in_u = S::and(S::lt(vk, S::splat(K_U)), S::lt(zero, vk));
    let s = S::div(S::splat(0.5), vk);
    let (h00, h01, h11, g0, g1) = (e.h00, e.h01, e.h11, e.g0, e.g1);
    let h01 = S::select(in_u, S::mul(h01, s), h01);
    let h11 = S::select(in_u, S::mul(h11, S::mul(s, s)), h11);
    let g1 = S::select(in_u, S::mul(g1, s), g1);
    let finite = S::eq(S::mul(S::add(S::add(h00, h01), h11), zero), zero);
    let damp = S::add(one, lam);
    let a00 = S::mul(h00, damp);
    let a11 = S::mul(h11, damp);
    let a01 = h01;
    let (n_min, n_max) = (S::splat(b.n_min), S::splat(b.n_max));
    let (k_lo_v, k_max) = (S::splat(k_lo), S::splat(b.k_max));
    let n_blocked = S::or(
        S::and(S::le(vn, n_min), S::lt(zero, g0)),
        S::and(S::le(n_max, vn), S::lt(g0, zero)),
    );
    let k_blocked = S::or(
        S::and(S::le(vk, k_lo_v), S::lt(zero, g1)),
        S::and(S::le(k_max, vk), S::lt(g1, zero)),
    );
    let n_free = S::and(S::not(n_blocked), S::lt(zero, h00));
    let k_free = S::and(S::not(k_blocked), S::lt(zero, h11));
    let det = S::sub(S::mul(a00, a11), S::mul(a01, a01));
    let dn_1 = S::div(S::mul(neg, g0), a00);
    let dk_1 = S::div(S::mul(neg, g1), a11);
    let joint = S::lt(S::mul(S::splat(1e-15), S::mul(a00, a11)), det);
    let inv_det = S::div(neg, det);
    let dn_2 = S::select(
        joint,
        S::mul(S::sub(S::mul(a11, g0), S::mul(a01, g1)), inv_det),
        dn_1,
    );
    let dk_2 = S::select(
        joint,
        S::mul(S::sub(S::mul(a00, g1), S::mul(a01, g0)), inv_det),
        dk_1,
    );
    let dn = S::select(n_free, S::select(k_free, dn_2, dn_1), zero);
    let dk = S::select(k_free, S::select(n_free, dk_2, dk_1), zero);
    let u = S::min(
        S::max(S::fma(vk, vk, dk), S::splat(k_lo * k_lo)),
        S::splat(b.k_max * b.k_max),
    );
    let k_raw = S::select(in_u, S::sqrt(u), S::add(vk, dk));
    let n_raw = S::add(vn, dn);
    let n_p = if b.n_min == 0.0 { S::abs(n_raw) } else { n_raw };
    let k_p = if b.k_min == 0.0 { S::abs(k_raw) } else { k_raw };
    let n1 = S::min(S::max(n_p, n_min), n_max);
    let k1 = S::min(S::max(k_p, k_lo_v), k_max);
    let en = S::sub(n1, vn);
    let ek = S::select(in_u, S::sub(S::mul(k1, k1), S::mul(vk, vk)), S::sub(k1, vk));
    // −(2 gᵀδ + δᵀ H δ)
    let lin = S::mul(two, S::add(S::mul(g0, en), S::mul(g1, ek)));
    let quad = S::add(
        S::mul(S::mul(h00, en), en),
        S::add(
            S::mul(S::mul(S::mul(two, h01), en), ek),
            S::mul(S::mul(h11, ek), ek),
        ),
    );
    let p = S::sub(zero, S::add(lin, quad));
    (
        S::select(finite, n1, vn),
        S::select(finite, k1, vk),
        S::select(finite, p, zero),
    )
}

/// Run every job of `jobs`, writing `out[j]` for job `j`. `y` holds the measurements
/// row by row (`T = t_len` values per row; `w` the weights, the same layout, or every
/// weight 1 when `None`).
///
/// Every step of every lane is vector code; only a lane whose polish ends (about one
/// evaluation in seven) takes a scalar detour to store its result and load the next
/// job.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn run<S: Simd>(
    lanes: &Lanes,
    t_len: usize,
    s: &Settings,
    jobs: &[Job],
    y: &[f64],
    w: Option<&[f64]>,
    out: &mut [JobOut],
    sc: &mut LaneScratch,
) {
    if sc.y.len() != t_len * W {
        sc.y = vec![0.0; t_len * W];
    }
    // Unweighted: every lane's weights stay 1.
    sc.w.clear();
    sc.w.resize(t_len * W, 1.0);
    let b = &s.bounds;
    let k_floor = if b.k_min == 0.0 { K_FLOOR } else { b.k_min };
    let (zero, one) = (S::splat(0.0), S::splat(1.0));
    // Per-lane job data (written when a lane takes a job).
    let mut job = [usize::MAX; W];
    let mut start_n = [1.0; W];
    let mut start_k = [1.0; W];
    let mut node_n = [1.0; W];
    let mut node_k = [1.0; W];
    let mut grid_cost = [0.0; W];
    // Phases as lane bits: evaluating the start, evaluating the node, iterating.
    let (mut start_b, mut node_b, mut lm_b) = (0u32, 0u32, 0u32);
    // Lanes without a job.
    let mut free_b: u32 = (1u32 << W) - 1;
    // Vector state.
    let mut n = one;
    let mut k = one;
    let mut lam = S::splat(LAM_0);
    let mut iters = zero;
    let mut evals = zero;
    let mut cur = EvalV::<S> {
        cost: zero,
        h00: zero,
        h01: zero,
        h11: zero,
        g0: zero,
        g1: zero,
    };
    let mut next = 0usize;

    // End the polishes of the lanes in `done` (converged: bits of `conv`) and give
    // their lanes the next jobs.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn retire<S: Simd>(
        done: u32,
        conv: u32,
        n: S::V,
        k: S::V,
        cur: &EvalV<S>,
        iters: &mut S::V,
        evals: &mut S::V,
        lam: &mut S::V,
        job: &mut [usize; W],
        out: &mut [JobOut],
    ) {
        let mut a = [[0.0; W]; 10];
        for (dst, v) in a.iter_mut().zip([
            n, k, cur.cost, cur.h00, cur.h01, cur.h11, cur.g0, cur.g1, *iters, *evals,
        ]) {
            S::store(v, dst);
        }
        let mut bits = done;
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            {
                out[job[l]] = JobOut {
                    n: a[0][l],
                    k: a[1][l],
                    ev: Eval {
                        cost: a[2][l],
                        ss: a[2][l],
                        h00: a[3][l],
                        h01: a[4][l],
                        h11: a[5][l],
                        g0: a[6][l],
                        g1: a[7][l],
                    },
                    iters: a[8][l] as u32,
                    evals: a[9][l] as u32,
                    converged: conv >> l & 1 == 1,
                };
                job[l] = usize::MAX;
            }
        }
        let m = S::from_bits(done);
        *iters = S::select(m, S::splat(0.0), *iters);
        *evals = S::select(m, S::splat(0.0), *evals);
        *lam = S::select(m, S::splat(LAM_0), *lam);
    }

    // Give every lane without a job the next job of the queue.
    let mut refill = |job: &mut [usize; W],
                      start_n: &mut L,
                      start_k: &mut L,
                      node_n: &mut L,
                      node_k: &mut L,
                      grid_cost: &mut L,
                      sc: &mut LaneScratch,
                      free_b: &mut u32|
     -> u32 {
        let mut started = 0u32;
        let mut free = *free_b;
        while free != 0 && next < jobs.len() {
            let l = free.trailing_zeros() as usize;
            free &= free - 1;
            let j = &jobs[next];
            job[l] = next;
            next += 1;
            started |= 1 << l;
            start_n[l] = j.start.0;
            start_k[l] = j.start.1.max(k_floor);
            node_n[l] = j.node.0;
            node_k[l] = j.node.1.max(k_floor);
            grid_cost[l] = j.grid_cost;
            let row = &y[j.pixel * t_len..(j.pixel + 1) * t_len];
            for (t, &v) in row.iter().enumerate() {
                sc.y[t * W + l] = v;
            }
            if let Some(w) = w {
                let row = &w[j.pixel * t_len..(j.pixel + 1) * t_len];
                for (t, &v) in row.iter().enumerate() {
                    sc.w[t * W + l] = v;
                }
            }
        }
        *free_b &= !started;
        started
    };

    start_b |= refill(
        &mut job,
        &mut start_n,
        &mut start_k,
        &mut node_n,
        &mut node_k,
        &mut grid_cost,
        sc,
        &mut free_b,
    );
    let (xtol, ftol) = (S::splat(s.xtol), S::splat(s.ftol));
    let max_iter = S::splat(f64::from(s.max_iter));
    loop {
        // 1. Levenberg–Marquardt lanes: the next trial point, or the end of the
        //    polish (before an evaluation).
        let lm_m = S::from_bits(lm_b);
        let (nt, kt, pred) = step_lanes::<S>(&cur, lam, n, k, b);
        let maxed = S::and(lm_m, S::le(max_iter, iters));
        let going = S::and(lm_m, S::not(maxed));
        iters = S::add(iters, S::select(going, one, zero));
        let still = S::and(
            S::le(S::abs(S::sub(nt, n)), S::mul(xtol, S::add(S::abs(n), xtol))),
            S::le(
                S::abs(S::sub(kt, k)),
                S::mul(xtol, S::add(S::abs(k), S::splat(1e-12))),
            ),
        );
        let flat = S::and(
            S::and(S::le(lam, S::splat(1e-5)), S::le(zero, pred)),
            S::le(pred, S::mul(ftol, cur.cost)),
        );
        let stop = S::and(going, S::or(S::or(S::eq(cur.cost, zero), still), flat));
        let done = S::bits(S::or(maxed, stop));
        if done != 0 {
            retire::<S>(
                done,
                S::bits(stop),
                n,
                k,
                &cur,
                &mut iters,
                &mut evals,
                &mut lam,
                &mut job,
                out,
            );
            lm_b &= !done;
            free_b |= done;
            start_b |= refill(
                &mut job,
                &mut start_n,
                &mut start_k,
                &mut node_n,
                &mut node_k,
                &mut grid_cost,
                sc,
                &mut free_b,
            );
        }
        let active = start_b | node_b | lm_b;
        if active == 0 {
            break;
        }
        // 2. Trial points of every lane, and their evaluation.
        let (start_m, node_m, lm_m) = (
            S::from_bits(start_b),
            S::from_bits(node_b),
            S::from_bits(lm_b),
        );
        let tn = S::select(
            lm_m,
            nt,
            S::select(
                start_m,
                S::load(&start_n),
                S::select(node_m, S::load(&node_n), one),
            ),
        );
        let tk = S::select(
            lm_m,
            kt,
            S::select(
                start_m,
                S::load(&start_k),
                S::select(node_m, S::load(&node_k), one),
            ),
        );
        let ev = if w.is_some() {
            eval_lanes::<S, true>(lanes, t_len, &sc.y, &sc.w, tn, tk)
        } else {
            eval_lanes::<S, false>(lanes, t_len, &sc.y, &sc.w, tn, tk)
        };
        evals = S::add(evals, S::select(S::from_bits(active), one, zero));
        // 3. Accept or reject. Start and node evaluations are always taken; a start
        //    worse than its node's grid cost is followed by the node.
        let first = S::or(start_m, node_m);
        let bad = S::and(
            start_m,
            S::not(S::le(
                ev.cost,
                S::add(
                    S::mul(S::load(&grid_cost), S::splat(1.0 + 1e-4)),
                    S::splat(1e-12),
                ),
            )),
        );
        let accept = S::and(lm_m, S::le(ev.cost, cur.cost));
        let reject = S::and(lm_m, S::not(S::le(ev.cost, cur.cost)));
        let small_dec = S::le(S::sub(cur.cost, ev.cost), S::mul(ftol, ev.cost));
        let take = S::or(first, accept);
        cur = EvalV::select(take, &ev, &cur);
        n = S::select(take, tn, n);
        k = S::select(take, tk, k);
        lam = S::select(
            accept,
            S::max(S::mul(lam, S::splat(LAM_DOWN)), S::splat(1e-12)),
            S::select(
                reject,
                S::max(S::mul(lam, S::splat(LAM_UP)), S::splat(LAM_REJECT)),
                lam,
            ),
        );
        let conv = S::and(accept, S::and(small_dec, S::le(lam, S::splat(1e-3))));
        let over = S::and(reject, S::lt(S::splat(1e10), lam));
        let bad_b = S::bits(bad);
        lm_b |= (start_b & !bad_b) | node_b;
        node_b = bad_b;
        start_b = 0;
        let conv_b = S::bits(conv);
        let over_b = S::bits(over);
        if conv_b | over_b != 0 {
            // No further decrease at this precision: a minimum if the undamped
            // Gauss–Newton model predicts nothing to gain.
            let mut ok_b = conv_b;
            for l in 0..W {
                if over_b >> l & 1 == 1 {
                    let e = Eval {
                        cost: lane::<S>(cur.cost, l),
                        ss: 0.0,
                        h00: lane::<S>(cur.h00, l),
                        h01: lane::<S>(cur.h01, l),
                        h11: lane::<S>(cur.h11, l),
                        g0: lane::<S>(cur.g0, l),
                        g1: lane::<S>(cur.g1, l),
                    };
                    let (_, _, p0) = super::lm::step(&e, 0.0, lane::<S>(n, l), lane::<S>(k, l), b);
                    if p0 <= 1e-9 * e.cost + 1e-28 {
                        ok_b |= 1 << l;
                    }
                }
            }
            let done = conv_b | over_b;
            retire::<S>(
                done, ok_b, n, k, &cur, &mut iters, &mut evals, &mut lam, &mut job, out,
            );
            lm_b &= !done;
            free_b |= done;
            start_b |= refill(
                &mut job,
                &mut start_n,
                &mut start_k,
                &mut node_n,
                &mut node_k,
                &mut grid_cost,
                sc,
                &mut free_b,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dop::BetaTerms;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// Lane `l`'s values of an evaluation.
    fn lane_eval<S: Simd>(e: &EvalV<S>, l: usize) -> [f64; 6] {
        [
            lane::<S>(e.cost, l),
            lane::<S>(e.h00, l),
            lane::<S>(e.h01, l),
            lane::<S>(e.h11, l),
            lane::<S>(e.g0, l),
            lane::<S>(e.g1, l),
        ]
    }

    /// Evaluate `pts` (eight at a time) with kernel `S`.
    #[inline(always)]
    fn eval_all<S: Simd>(lanes: &Lanes, y: &[f64], w: &[f64], pts: &[(f64, f64)]) -> Vec<[f64; 6]> {
        let t_len = y.len();
        let mut yl = vec![0.0; t_len * W];
        let mut wl = vec![0.0; t_len * W];
        for t in 0..t_len {
            for l in 0..W {
                yl[t * W + l] = y[t];
                wl[t * W + l] = w[t];
            }
        }
        let mut out = vec![];
        for c in pts.chunks(W) {
            let mut n = [1.0; W];
            let mut k = [1.0; W];
            for (l, &(a, b)) in c.iter().enumerate() {
                n[l] = a;
                k[l] = b;
            }
            let e = eval_lanes::<S, true>(lanes, t_len, &yl, &wl, S::load(&n), S::load(&k));
            out.extend((0..c.len()).map(|l| lane_eval(&e, l)));
        }
        out
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn eval_avx2(lanes: &Lanes, y: &[f64], w: &[f64], pts: &[(f64, f64)]) -> Vec<[f64; 6]> {
        eval_all::<Avx2>(lanes, y, w, pts)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn eval_avx512(lanes: &Lanes, y: &[f64], w: &[f64], pts: &[(f64, f64)]) -> Vec<[f64; 6]> {
        eval_all::<Avx512>(lanes, y, w, pts)
    }

    /// The lane evaluation of every kernel agrees with the scalar one built on
    /// `dop_grad_terms`, weighted and unweighted, including `k = 0`, `n < 1` and index
    /// matching (`n² = k² + sin²β`).
    #[test]
    fn lane_eval_matches_scalar_eval() {
        let betas: Vec<f64> = (0..7).map(|i| 0.3 + 0.17 * i as f64).collect();
        let terms: Vec<BetaTerms> = betas.iter().map(|&b| BetaTerms::new(b)).collect();
        let lanes = Lanes::new(&terms);
        let mut rng = StdRng::seed_from_u64(3);
        let mut pts: Vec<(f64, f64)> = (0..2000)
            .map(|_| (rng.random_range(0.01..10.0), rng.random_range(0.0..15.0)))
            .collect();
        pts.extend([
            (1.0, 0.0),
            (0.3, 0.0),
            (1.5, 0.0),
            (0.5, 1e-9),
            (10.0, 15.0),
            (terms[2].s2.sqrt(), 0.0),
        ]);
        let y: Vec<f64> = (0..7).map(|t| 0.1 * t as f64 + 0.05).collect();
        let w: Vec<f64> = (0..7).map(|t| 1.0 + t as f64 % 3.0).collect();
        for weighted in [false, true] {
            let wv = if weighted { w.clone() } else { vec![1.0; 7] };
            let mut runs = vec![eval_all::<Portable>(&lanes, &y, &wv, &pts)];
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU has AVX2 + FMA (checked above).
                    runs.push(unsafe { eval_avx2(&lanes, &y, &wv, &pts) });
                }
                if std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU has AVX-512F, AVX2 and FMA (checked above).
                    runs.push(unsafe { eval_avx512(&lanes, &y, &wv, &pts) });
                }
            }
            for run in &runs {
                for (i, &(n, k)) in pts.iter().enumerate() {
                    let b = super::super::lm::eval(&terms, &y, weighted.then_some(&w[..]), n, k);
                    let want = [b.cost, b.h00, b.h01, b.h11, b.g0, b.g1];
                    for (x, z) in run[i].iter().zip(want) {
                        assert!(
                            (x - z).abs() <= 1e-12 * (x.abs() + z.abs()) + 1e-14,
                            "({n}, {k}) weighted {weighted}: {:?} vs {want:?}",
                            run[i]
                        );
                    }
                }
            }
        }
    }
}
