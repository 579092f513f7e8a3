//! Levenberg–Marquardt polishes of many fits at once, one fit per SIMD lane.
//!
//! Every polish evaluates eq. (9) and its gradient at a trial point, then decides
//! (accept, reject, stop). Running [`W`] polishes side by side, each lane on its own
//! fit, turns the evaluation loop over the `T` source positions into straight f64x4
//! arithmetic (AVX2 + FMA when the caller is compiled for them, see
//! `FitPlan::fit_checked`) with no padding lanes and no horizontal sums, and the
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

/// Fits polished side by side (one f64x8 vector, or two f64x4).
pub(crate) const W: usize = 8;

type L = [f64; W];

/// Damping factor after a rejected step.
const LAM_UP: f64 = 5.0;
/// Damping factor after an accepted step.
const LAM_DOWN: f64 = 0.2;
/// Initial damping.
const LAM_0: f64 = 1e-6;

/// The f64x4 operations the engine needs: AVX2 + FMA intrinsics (`Avx2`, only
/// called from functions compiled for those features) or plain lane loops
/// ([`Portable`]). Comparisons give masks; `min`/`max` are `a < b ? a : b` /
/// `a > b ? a : b` (no NaN handling).
pub(crate) trait Simd: Copy {
    /// Four f64.
    type V: Copy;
    /// Four lane flags.
    type M: Copy;
    fn splat(x: f64) -> Self::V;
    /// The first four values of `p`.
    fn load(p: &[f64]) -> Self::V;
    /// Into the first four values of `p`.
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
}

/// [`Simd`] with AVX2 + FMA intrinsics, two f64x4 per vector. Only for code inlined
/// into a function compiled with `#[target_feature(enable = "avx2,fma")]`, on a CPU
/// that has them (the fit checks at run time before it calls such a function).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct Avx2;

/// [`Simd`] with AVX-512F intrinsics, one f64x8 per vector. Only for code inlined into
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
            unsafe { [$f($($a[0]),*), $f($($a[1]),*)] }
        };
    }

    // SAFETY (every method): `Avx2` is only used inside functions compiled for
    // AVX2 + FMA and called after a run-time check that the CPU has them; loads and
    // stores go through slices of length W (bounds-checked) before the pointer is used.
    impl Simd for Avx2 {
        type V = [__m256d; 2];
        type M = [__m256d; 2];
        #[inline(always)]
        fn splat(x: f64) -> Self::V {
            unsafe { [_mm256_set1_pd(x); 2] }
        }
        #[inline(always)]
        fn load(p: &[f64]) -> Self::V {
            let p = &p[..W];
            unsafe { [_mm256_loadu_pd(p.as_ptr()), _mm256_loadu_pd(p.as_ptr().add(4))] }
        }
        #[inline(always)]
        fn store(v: Self::V, p: &mut [f64]) {
            let p = &mut p[..W];
            unsafe {
                _mm256_storeu_pd(p.as_mut_ptr(), v[0]);
                _mm256_storeu_pd(p.as_mut_ptr().add(4), v[1]);
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
                ]
            }
        }
        #[inline(always)]
        fn le(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm256_cmp_pd::<_CMP_LE_OQ>(a[0], b[0]),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(a[1], b[1]),
                ]
            }
        }
        #[inline(always)]
        fn eq(a: Self::V, b: Self::V) -> Self::M {
            unsafe {
                [
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(a[0], b[0]),
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(a[1], b[1]),
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
            let ones = unsafe { [_mm256_castsi256_pd(_mm256_set1_epi64x(-1)); 2] };
            pair!(_mm256_xor_pd(a, ones))
        }
        #[inline(always)]
        fn select(m: Self::M, a: Self::V, b: Self::V) -> Self::V {
            pair!(_mm256_blendv_pd(b, a, m))
        }
    }

    // SAFETY (every method): as for `Avx2`, with AVX-512F.
    impl Simd for Avx512 {
        type V = __m512d;
        type M = __mmask8;
        #[inline(always)]
        fn splat(x: f64) -> __m512d {
            unsafe { _mm512_set1_pd(x) }
        }
        #[inline(always)]
        fn load(p: &[f64]) -> __m512d {
            let p = &p[..W];
            unsafe { _mm512_loadu_pd(p.as_ptr()) }
        }
        #[inline(always)]
        fn store(v: __m512d, p: &mut [f64]) {
            let p = &mut p[..W];
            unsafe { _mm512_storeu_pd(p.as_mut_ptr(), v) }
        }
        #[inline(always)]
        fn add(a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_add_pd(a, b) }
        }
        #[inline(always)]
        fn sub(a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_sub_pd(a, b) }
        }
        #[inline(always)]
        fn mul(a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_mul_pd(a, b) }
        }
        #[inline(always)]
        fn div(a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_div_pd(a, b) }
        }
        #[inline(always)]
        fn sqrt(a: __m512d) -> __m512d {
            unsafe { _mm512_sqrt_pd(a) }
        }
        #[inline(always)]
        fn fma(a: __m512d, b: __m512d, c: __m512d) -> __m512d {
            unsafe { _mm512_fmadd_pd(a, b, c) }
        }
        #[inline(always)]
        fn abs(a: __m512d) -> __m512d {
            unsafe { _mm512_abs_pd(a) }
        }
        #[inline(always)]
        fn min(a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_min_pd(a, b) }
        }
        #[inline(always)]
        fn max(a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_max_pd(a, b) }
        }
        #[inline(always)]
        fn lt(a: __m512d, b: __m512d) -> __mmask8 {
            unsafe { _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a, b) }
        }
        #[inline(always)]
        fn le(a: __m512d, b: __m512d) -> __mmask8 {
            unsafe { _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b) }
        }
        #[inline(always)]
        fn eq(a: __m512d, b: __m512d) -> __mmask8 {
            unsafe { _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a, b) }
        }
        #[inline(always)]
        fn and(a: __mmask8, b: __mmask8) -> __mmask8 {
            a & b
        }
        #[inline(always)]
        fn or(a: __mmask8, b: __mmask8) -> __mmask8 {
            a | b
        }
        #[inline(always)]
        fn not(a: __mmask8) -> __mmask8 {
            !a
        }
        #[inline(always)]
        fn select(m: __mmask8, a: __m512d, b: __m512d) -> __m512d {
            unsafe { _mm512_mask_blend_pd(m, b, a) }
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

#[derive(Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// No job.
    Empty,
    /// Evaluating the Gauss–Newton start.
    Start,
    /// Evaluating the grid node (the start was worse).
    Node,
    /// Levenberg–Marquardt iterations.
    Lm,
}

/// Cost and normal equations of every lane.
#[derive(Clone, Copy, Default)]
struct EvalL {
    cost: L,
    h00: L,
    h01: L,
    h11: L,
    g0: L,
    g1: L,
}

impl EvalL {
    #[inline(always)]
    fn lane(&self, l: usize) -> Eval {
        Eval {
            cost: self.cost[l],
            ss: self.cost[l],
            h00: self.h00[l],
            h01: self.h01[l],
            h11: self.h11[l],
            g0: self.g0[l],
            g1: self.g1[l],
        }
    }

    #[inline(always)]
    fn set(&mut self, l: usize, o: &EvalL) {
        self.cost[l] = o.cost[l];
        self.h00[l] = o.h00[l];
        self.h01[l] = o.h01[l];
        self.h11[l] = o.h11[l];
        self.g0[l] = o.g0[l];
        self.g1[l] = o.g1[l];
    }
}

/// Cost `Σ w (P − y)²` and normal equations at `(n_l, k_l)` for every lane: eq. (9)
/// and its analytic gradient in the arithmetic of [`crate::dop::dop_grad_terms`] (the
/// `hypot` fallback dropped, exact for bounds below `1e100`, checked by the plan).
/// `y`, `w`: lane-major, `y[t * W + l]`.
#[inline(always)]
fn eval_lanes<S: Simd>(
    lanes: &Lanes,
    t_len: usize,
    y: &[f64],
    w: &[f64],
    n: &L,
    k: &L,
    out: &mut EvalL,
) {
    let (y, w) = (&y[..t_len * W], &w[..t_len * W]);
    let (s2v, cv, c2v, s4v, numv) = lanes.terms(t_len);
    let (vn, vk) = (S::load(n), S::load(k));
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
        let wt = S::load(&w[t * W..]);
        let wr = S::mul(wt, res);
        let wjn = S::mul(wt, jn);
        a_cost = S::fma(wr, res, a_cost);
        a_h00 = S::fma(wjn, jn, a_h00);
        a_h01 = S::fma(wjn, jk, a_h01);
        a_h11 = S::fma(S::mul(wt, jk), jk, a_h11);
        a_g0 = S::fma(jn, wr, a_g0);
        a_g1 = S::fma(jk, wr, a_g1);
    }
    S::store(a_cost, &mut out.cost);
    S::store(a_h00, &mut out.h00);
    S::store(a_h01, &mut out.h01);
    S::store(a_h11, &mut out.h11);
    S::store(a_g0, &mut out.g0);
    S::store(a_g1, &mut out.g1);
}

/// The damped step of `lm::step` for every lane, without branches: solve
/// `(H + λ diag H) δ = −g` (in `(n, u = k²)` below `k = 1`), hold a parameter fixed on
/// a bound the descent direction points out of, project into the box, and return the
/// trial points and the decrease the Gauss–Newton model predicts for them.
#[inline(always)]
fn step_lanes<S: Simd>(e: &EvalL, lam: &L, n: &L, k: &L, b: &FitBounds) -> (L, L, L) {
    let k_lo = if b.k_min > 0.0 { b.k_min } else { K_FLOOR };
    let (zero, one, two, neg) = (S::splat(0.0), S::splat(1.0), S::splat(2.0), S::splat(-1.0));
    let (vn, vk) = (S::load(n), S::load(k));
    let in_u = S::and(S::lt(vk, S::splat(K_U)), S::lt(zero, vk));
    let s = S::div(S::splat(0.5), vk);
    let h00 = S::load(&e.h00);
    let h01 = S::load(&e.h01);
    let h11 = S::load(&e.h11);
    let g0 = S::load(&e.g0);
    let g1 = S::load(&e.g1);
    let h01 = S::select(in_u, S::mul(h01, s), h01);
    let h11 = S::select(in_u, S::mul(h11, S::mul(s, s)), h11);
    let g1 = S::select(in_u, S::mul(g1, s), g1);
    let finite = S::eq(S::mul(S::add(S::add(h00, h01), h11), zero), zero);
    let damp = S::add(one, S::load(lam));
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
    let mut nt = [0.0; W];
    let mut kt = [0.0; W];
    let mut pred = [0.0; W];
    S::store(S::select(finite, n1, vn), &mut nt);
    S::store(S::select(finite, k1, vk), &mut kt);
    S::store(S::select(finite, p, zero), &mut pred);
    (nt, kt, pred)
}

/// The lanes' state.
struct State {
    job: [usize; W],
    phase: [Phase; W],
    n: L,
    k: L,
    lam: L,
    cur: EvalL,
    tn: L,
    tk: L,
    iters: [u32; W],
    evals: [u32; W],
}

/// Run every job of `jobs`, writing `out[j]` for job `j`. `y` holds the measurements
/// row by row (`T = t_len` values per row; `w` the weights, the same layout, or every
/// weight 1 when `None`).
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
        sc.w = vec![1.0; t_len * W];
    }
    let b = &s.bounds;
    let k_floor = if b.k_min == 0.0 { K_FLOOR } else { b.k_min };
    let mut st = State {
        job: [0; W],
        phase: [Phase::Empty; W],
        n: [1.0; W],
        k: [1.0; W],
        lam: [LAM_0; W],
        cur: EvalL::default(),
        tn: [1.0; W],
        tk: [1.0; W],
        iters: [0; W],
        evals: [0; W],
    };
    let mut next = 0usize;
    // Load the next job into lane `l` (or leave it empty).
    let mut load = |st: &mut State, sc: &mut LaneScratch, l: usize| {
        if next < jobs.len() {
            let j = &jobs[next];
            st.job[l] = next;
            st.phase[l] = Phase::Start;
            st.iters[l] = 0;
            st.evals[l] = 0;
            st.lam[l] = LAM_0;
            let row = &y[j.pixel * t_len..(j.pixel + 1) * t_len];
            for (t, &v) in row.iter().enumerate() {
                sc.y[t * W + l] = v;
            }
            if let Some(w) = w {
                let row = &w[j.pixel * t_len..(j.pixel + 1) * t_len];
                for (t, &v) in row.iter().enumerate() {
                    sc.w[t * W + l] = v;
                }
            } else {
                for t in 0..t_len {
                    sc.w[t * W + l] = 1.0;
                }
            }
            next += 1;
        } else {
            st.phase[l] = Phase::Empty;
        }
    };
    let done = |st: &State, out: &mut [JobOut], l: usize, converged: bool| {
        out[st.job[l]] = JobOut {
            n: st.n[l],
            k: st.k[l],
            ev: st.cur.lane(l),
            iters: st.iters[l],
            evals: st.evals[l],
            converged,
        };
    };
    for l in 0..W {
        load(&mut st, sc, l);
    }
    let mut ev = EvalL::default();
    loop {
        // 1. Trial points (lanes in Levenberg–Marquardt may stop here, before an
        //    evaluation, and take a new job).
        let (nt, kt, pred) = step_lanes::<S>(&st.cur, &st.lam, &st.n, &st.k, b);
        let mut active = false;
        for l in 0..W {
            loop {
                match st.phase[l] {
                    Phase::Empty => {
                        st.tn[l] = 1.0;
                        st.tk[l] = 1.0;
                    }
                    Phase::Start => {
                        let j = &jobs[st.job[l]];
                        st.tn[l] = j.start.0;
                        st.tk[l] = j.start.1.max(k_floor);
                        active = true;
                    }
                    Phase::Node => {
                        let j = &jobs[st.job[l]];
                        st.tn[l] = j.node.0;
                        st.tk[l] = j.node.1.max(k_floor);
                        active = true;
                    }
                    Phase::Lm => {
                        let stop = if st.iters[l] >= s.max_iter {
                            Some(false)
                        } else {
                            st.iters[l] += 1;
                            let (n, k, c) = (st.n[l], st.k[l], st.cur.cost[l]);
                            let mv_n = (nt[l] - n).abs();
                            let mv_k = (kt[l] - k).abs();
                            if c == 0.0
                                || (mv_n <= s.xtol * (n.abs() + s.xtol)
                                    && mv_k <= s.xtol * (k.abs() + 1e-12))
                                || (st.lam[l] <= 1e-5 && pred[l] >= 0.0 && pred[l] <= s.ftol * c)
                            {
                                Some(true)
                            } else {
                                None
                            }
                        };
                        match stop {
                            Some(conv) => {
                                done(&st, out, l, conv);
                                load(&mut st, sc, l);
                                continue;
                            }
                            None => {
                                st.tn[l] = nt[l];
                                st.tk[l] = kt[l];
                                active = true;
                            }
                        }
                    }
                }
                break;
            }
        }
        if !active {
            break;
        }
        // 2. Evaluate every lane at its trial point.
        eval_lanes::<S>(lanes, t_len, &sc.y, &sc.w, &st.tn, &st.tk, &mut ev);
        // 3. Accept or reject.
        for l in 0..W {
            match st.phase[l] {
                Phase::Empty => continue,
                Phase::Start | Phase::Node => {
                    st.evals[l] += 1;
                    st.n[l] = st.tn[l];
                    st.k[l] = st.tk[l];
                    st.cur.set(l, &ev);
                    let g = jobs[st.job[l]].grid_cost;
                    st.phase[l] = if st.phase[l] == Phase::Start
                        && !(ev.cost[l] <= g * (1.0 + 1e-4) + 1e-12)
                    {
                        Phase::Node
                    } else {
                        Phase::Lm
                    };
                }
                Phase::Lm => {
                    st.evals[l] += 1;
                    let (c_new, c_old) = (ev.cost[l], st.cur.cost[l]);
                    if c_new <= c_old {
                        st.n[l] = st.tn[l];
                        st.k[l] = st.tk[l];
                        st.cur.set(l, &ev);
                        st.lam[l] = (st.lam[l] * LAM_DOWN).max(1e-12);
                        if c_old - c_new <= s.ftol * c_new && st.lam[l] <= 1e-3 {
                            done(&st, out, l, true);
                            load(&mut st, sc, l);
                        }
                    } else {
                        st.lam[l] *= LAM_UP;
                        if st.lam[l] > 1e10 {
                            // No further decrease at this precision: a minimum if the
                            // undamped Gauss–Newton model predicts nothing to gain.
                            let (_, _, p0) =
                                super::lm::step(&st.cur.lane(l), 0.0, st.n[l], st.k[l], b);
                            let conv = p0 <= 1e-9 * c_old + 1e-28;
                            done(&st, out, l, conv);
                            load(&mut st, sc, l);
                        }
                    }
                }
            }
        }
    }
}
