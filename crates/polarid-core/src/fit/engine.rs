//! Levenberg–Marquardt polishes of many fits at once, one fit per SIMD lane.
//!
//! Every polish evaluates eq. (9) and its gradient at a trial point, then decides
//! (accept, reject, stop). Running [`W`] polishes side by side, each lane on its own
//! fit, turns the evaluation loop over the `T` source positions into straight vector
//! arithmetic (two f64x8 with AVX-512F, four f64x4 with AVX2 + FMA, lane loops
//! elsewhere: the backends of `simd/`, passed in as the token of [`crate::cpu`] that
//! proves the CPU has the instructions; the chunk driver, `chunk.rs`, inlines the
//! engine into a function compiled for them) with no padding lanes and no horizontal
//! sums, and the
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
use super::lanes::{self, Lanes};
use super::lm::{ARC_MAX, Eval, K_FLOOR, K_U};
use super::simd::{Simd, W};
use crate::dop::BetaTerms;

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

/// Smallest `r = √C` and `q = cos²β·r + sin⁴β` of the one-reciprocal evaluation in
/// [`eval_lanes`]: with `r, q ∈ [R_LO, R_HI]` the product `ρ·q·r·(v + r)` and every
/// partial product lie within about `1e±180`, far from overflow and underflow.
const R_LO: f64 = 1e-50;
/// Largest `r` and `q` of the one-reciprocal evaluation (see [`R_LO`]).
const R_HI: f64 = 1e50;

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

impl Settings {
    /// The settings of the fit options `o`.
    #[inline]
    pub fn new(o: &super::FitOptions) -> Self {
        Self {
            bounds: o.bounds,
            max_iter: o.max_iter,
            xtol: o.xtol,
            ftol: o.ftol,
        }
    }
}

/// The β terms of eq. (9) at one source position of one pixel, as the lane evaluation
/// reads them (a fit with a β per pixel, see [`run`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct LaneTerms {
    /// `sin²β`.
    pub s2: f64,
    /// `cos β`.
    pub c: f64,
    /// `cos²β`.
    pub c2: f64,
    /// `sin⁴β`.
    pub s4: f64,
    /// `2 sin²β cos β`.
    pub num: f64,
}

impl LaneTerms {
    /// The terms of `bt` (the arithmetic of [`Lanes::new`], so that a pixel's terms
    /// equal the shared ones bit for bit at the same β).
    #[inline]
    pub fn new(bt: &BetaTerms) -> Self {
        Self {
            s2: bt.s2,
            c: bt.c,
            c2: bt.c2,
            s4: bt.s4,
            num: lanes::num(bt),
        }
    }
}

/// Lane-major copies of the measurements of the jobs in the lanes:
/// `y[t * W + l]`, `w[t * W + l]`; with a β per pixel also their β terms
/// (`b[i][t * W + l]`, `i` = `sin²β`, `cos β`, `cos²β`, `sin⁴β`, `2 sin²β cos β`).
#[derive(Debug, Clone, Default)]
pub(crate) struct LaneScratch {
    y: Vec<f64>,
    w: Vec<f64>,
    b: [Vec<f64>; 5],
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
    fn select(s: S, m: S::M, a: &Self, b: &Self) -> Self {
        Self {
            cost: s.select(m, a.cost, b.cost),
            h00: s.select(m, a.h00, b.h00),
            h01: s.select(m, a.h01, b.h01),
            h11: s.select(m, a.h11, b.h11),
            g0: s.select(m, a.g0, b.g0),
            g1: s.select(m, a.g1, b.g1),
        }
    }
}

/// Lane `l` of `v`.
#[inline(always)]
fn lane<S: Simd>(s: S, v: S::V, l: usize) -> f64 {
    let mut a = [0.0; W];
    s.store(v, &mut a);
    a[l]
}

/// Cost `Σ w (P − y)²` and normal equations at `(n_l, k_l)` for every lane: eq. (9)
/// and its analytic gradient in the arithmetic of [`crate::dop::dop_grad_terms`] (the
/// `hypot` fallback dropped, exact for bounds below `1e100`, checked by the plan),
/// except that the quotients by `ρ`, `q`, `r` and `r (v + r)` share one reciprocal
/// (see [`R_LO`]): equal up to rounding.
/// The measurements and weights: those of `sc`, lane-major, `y[t * W + l]`. The β
/// terms: `PIX = false`, those of `lanes`, shared by every lane; `PIX = true`, each
/// lane's own from `sc` (lane-major, see [`LaneScratch`]; `lanes` is then not read).
///
/// When every lane has `nk ≥ 2 R_LO` and `n² + k² ≤ 1e49`, every source position has
/// `r, q ∈ [R_LO, R_HI]` (`r ≥ 2nk`, `r ≤ 2(n² + k²) + 1`; `q ≥ c²r ≥ nk` where
/// `cos²β ≥ ½`, else `q ≥ sin⁴β ≥ ¼`), so the per-position range test and the `r = 0`
/// guards are skipped: the same values bit for bit.
#[inline(always)]
fn eval_lanes<S: Simd, const WEIGHTED: bool, const PIX: bool>(
    s: S,
    lanes: &Lanes,
    t_len: usize,
    sc: &LaneScratch,
    vn: S::V,
    vk: S::V,
) -> EvalV<S> {
    let nk = s.mul(vn, vk);
    let nn_kk = s.add(s.mul(vn, vn), s.mul(vk, vk));
    let safe = s.and(s.le(s.splat(2.0 * R_LO), nk), s.le(nn_kk, s.splat(1e49)));
    if s.bits(safe) == (1u32 << W) - 1 {
        eval_terms::<S, WEIGHTED, PIX, false>(s, lanes, t_len, sc, vn, vk)
    } else {
        eval_terms::<S, WEIGHTED, PIX, true>(s, lanes, t_len, sc, vn, vk)
    }
}

/// The terms of eq. (9) that depend on `(n, k)` only, for every lane.
#[derive(Clone, Copy)]
struct LanePoint<S: Simd> {
    vn: S::V,
    vk: S::V,
    nk: S::V,
    nn_kk: S::V,
    /// `n² − k²`.
    d0: S::V,
    /// `4 n² k²`.
    q4: S::V,
    two_n: S::V,
    two_k: S::V,
}

impl<S: Simd> LanePoint<S> {
    #[inline(always)]
    fn new(s: S, vn: S::V, vk: S::V) -> Self {
        let nn = s.mul(vn, vn);
        let kk = s.mul(vk, vk);
        let nk = s.mul(vn, vk);
        Self {
            vn,
            vk,
            nk,
            nn_kk: s.add(nn, kk),
            d0: s.sub(nn, kk),
            q4: s.mul(s.mul(s.splat(4.0), nk), nk),
            two_n: s.add(vn, vn),
            two_k: s.add(vk, vk),
        }
    }

    /// `P` of eq. (9) and its gradient `(∂P/∂n, ∂P/∂k)` at one source position, with
    /// its β terms `[sin²β, cos β, cos²β, sin⁴β, 2 sin²β cos β]` (see [`eval_terms`]).
    #[inline(always)]
    fn p_grad<const CHECK: bool>(
        &self,
        s: S,
        [s2, c, c2, s4, num]: [S::V; 5],
    ) -> (S::V, S::V, S::V) {
        let Self {
            vn,
            vk,
            nk,
            nn_kk,
            d0,
            q4,
            two_n,
            two_k,
        } = *self;
        let (zero, half, one, tiny) = (
            s.splat(0.0),
            s.splat(0.5),
            s.splat(1.0),
            s.splat(f64::MIN_POSITIVE),
        );
        let d = s.sub(d0, s2); // eq. (15)
        let r = s.sqrt(s.fma(d, d, q4)); // √C, eq. (14)
        let rho = s.sqrt(s.mul(s.add(r, s.abs(d)), half));
        let q = s.fma(c2, r, s4);
        let u = s.sub(nn_kk, s2);
        let v = s.add(nn_kk, s2);
        let vr = s.add(v, r);
        // The four quotients by ρ, q, r and r (v + r) from one reciprocal of the
        // product ρ·q·r·(v + r) (one division instead of four): exact up to rounding
        // while every factor stays far from the ends of the f64 range, which
        // `r, q ∈ [R_LO, R_HI]` guarantees (ρ ≥ √(r/2), r ≤ v + r ≤ 3r + 2, see
        // [`R_LO`]); other lanes (r = 0, extreme bounds) take the four divisions.
        let rvr = s.mul(r, vr);
        let qrvr = s.mul(q, rvr);
        let inv = s.div(one, s.mul(rho, qrvr));
        let rho_inv = s.mul(rho, inv); // 1 / (q r (v + r))
        let mut inv_rvr = s.mul(q, rho_inv);
        let mut inv_r = s.mul(vr, inv_rvr);
        let mut inv_q = s.mul(rvr, rho_inv);
        let mut small = s.mul(nk, s.mul(qrvr, inv));
        if CHECK {
            let (lo, hi) = (s.splat(R_LO), s.splat(R_HI));
            let fast = s.and(s.le(lo, s.min(r, q)), s.le(s.max(r, q), hi));
            if s.bits(s.not(fast)) != 0 {
                let slow_r = s.div(one, s.max(r, tiny));
                inv_r = s.select(fast, inv_r, slow_r);
                inv_rvr = s.select(fast, inv_rvr, s.div(slow_r, vr));
                inv_q = s.select(fast, inv_q, s.div(one, q));
                small = s.select(fast, small, s.div(nk, s.max(rho, tiny)));
            }
        }
        let pos = s.le(zero, d);
        let a = s.select(pos, rho, small);
        let b = s.select(pos, small, rho);
        // P, eq. (9), with the cancellation-free form above 1/2 (see dop::p_value).
        let x = s.mul(c, a);
        let p_lo = s.mul(s.mul(s.add(x, x), s2), inv_q);
        let ex = s.sub(x, s2);
        let cb = s.mul(c, b);
        let p_hi = s.sub(one, s.mul(s.fma(ex, ex, s.mul(cb, cb)), inv_q));
        let p = s.select(s.lt(half, p_lo), p_hi, p_lo);
        let p = s.min(s.max(p, zero), one);
        // Gradient (dop::dop_grad_terms).
        let da_dn = s.mul(s.fma(vn, a, s.mul(vk, b)), inv_r);
        let da_dk = s.mul(s.mul(s.mul(two_n, s2), b), inv_rvr);
        let dr_dn = s.mul(s.mul(two_n, u), inv_r);
        let dr_dk = s.mul(s.mul(two_k, v), inv_r);
        let ac2 = s.mul(a, c2);
        let f = s.mul(s.mul(num, inv_q), inv_q);
        let jn = s.mul(f, s.sub(s.mul(da_dn, q), s.mul(ac2, dr_dn)));
        let jk = s.mul(f, s.sub(s.mul(da_dk, q), s.mul(ac2, dr_dk)));
        let (jn, jk, p) = if CHECK {
            let ok = s.lt(zero, r);
            (
                s.select(ok, jn, zero),
                s.select(ok, jk, zero),
                s.select(ok, p, zero),
            )
        } else {
            (jn, jk, p)
        };
        (p, jn, jk)
    }
}

/// [`eval_lanes`]; `CHECK`: test every position's `r, q` range (else every lane is
/// known to be in range).
#[inline(always)]
fn eval_terms<S: Simd, const WEIGHTED: bool, const PIX: bool, const CHECK: bool>(
    s: S,
    lanes: &Lanes,
    t_len: usize,
    sc: &LaneScratch,
    vn: S::V,
    vk: S::V,
) -> EvalV<S> {
    let (y, w, pb) = (&sc.y[..t_len * W], &sc.w[..t_len * W], &sc.b);
    let (s2v, cv, c2v, s4v, numv) = if PIX {
        (&[][..], &[][..], &[][..], &[][..], &[][..])
    } else {
        lanes.terms(t_len)
    };
    let pt = LanePoint::new(s, vn, vk);
    let zero = s.splat(0.0);
    let mut a_cost = zero;
    let mut a_h00 = zero;
    let mut a_h01 = zero;
    let mut a_h11 = zero;
    let mut a_g0 = zero;
    let mut a_g1 = zero;
    for (t, (yt, wt)) in y.chunks_exact(W).zip(w.chunks_exact(W)).enumerate() {
        let bt = if PIX {
            [
                s.load(&pb[0][t * W..]),
                s.load(&pb[1][t * W..]),
                s.load(&pb[2][t * W..]),
                s.load(&pb[3][t * W..]),
                s.load(&pb[4][t * W..]),
            ]
        } else {
            [
                s.splat(s2v[t]),
                s.splat(cv[t]),
                s.splat(c2v[t]),
                s.splat(s4v[t]),
                s.splat(numv[t]),
            ]
        };
        let (p, jn, jk) = pt.p_grad::<CHECK>(s, bt);
        let res = s.sub(p, s.load(yt));
        // Unweighted: the same sums without the multiplications by w = 1 (bitwise
        // equal: 1·x = x).
        let (wr, wjn, wjk) = if WEIGHTED {
            let wt = s.load(wt);
            (s.mul(wt, res), s.mul(wt, jn), s.mul(wt, jk))
        } else {
            (res, jn, jk)
        };
        a_cost = s.fma(wr, res, a_cost);
        a_h00 = s.fma(wjn, jn, a_h00);
        a_h01 = s.fma(wjn, jk, a_h01);
        a_h11 = s.fma(wjk, jk, a_h11);
        a_g0 = s.fma(jn, wr, a_g0);
        a_g1 = s.fma(jk, wr, a_g1);
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
/// trial points and the decrease the Gauss–Newton model predicts for them. Lanes
/// outside `live` get unspecified values.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn step_lanes<S: Simd>(
    s: S,
    live: S::M,
    e: &EvalV<S>,
    lam: S::V,
    vn: S::V,
    vk: S::V,
    b: &FitBounds,
) -> (S::V, S::V, S::V) {
    let k_lo = if b.k_min > 0.0 { b.k_min } else { K_FLOOR };
    let (zero, one, neg) = (s.splat(0.0), s.splat(1.0), s.splat(-1.0));
    let in_u = s.and(s.lt(vk, s.splat(K_U)), s.lt(zero, vk));
    // The divisions and square root below run only when some live lane reads them
    // (the divider bounds the engine's speed); other lanes' values are never selected.
    let any_u = s.bits(s.and(live, in_u)) != 0;
    let (h00, h01, h11, g0, g1) = (e.h00, e.h01, e.h11, e.g0, e.g1);
    let (h01, h11, g1) = if any_u {
        let su = s.div(s.splat(0.5), vk);
        (
            s.select(in_u, s.mul(h01, su), h01),
            s.select(in_u, s.mul(h11, s.mul(su, su)), h11),
            s.select(in_u, s.mul(g1, su), g1),
        )
    } else {
        (h01, h11, g1)
    };
    let finite = s.eq(s.mul(s.add(s.add(h00, h01), h11), zero), zero);
    let damp = s.add(one, lam);
    let a00 = s.mul(h00, damp);
    let a11 = s.mul(h11, damp);
    let a01 = h01;
    let (n_min, n_max) = (s.splat(b.n_min), s.splat(b.n_max));
    let (k_lo_v, k_max) = (s.splat(k_lo), s.splat(b.k_max));
    let n_blocked = s.or(
        s.and(s.le(vn, n_min), s.lt(zero, g0)),
        s.and(s.le(n_max, vn), s.lt(g0, zero)),
    );
    let k_blocked = s.or(
        s.and(s.le(vk, k_lo_v), s.lt(zero, g1)),
        s.and(s.le(k_max, vk), s.lt(g1, zero)),
    );
    let n_free = s.and(s.not(n_blocked), s.lt(zero, h00));
    let k_free = s.and(s.not(k_blocked), s.lt(zero, h11));
    let det = s.sub(s.mul(a00, a11), s.mul(a01, a01));
    let joint = s.lt(s.mul(s.splat(1e-15), s.mul(a00, a11)), det);
    // The one-parameter steps, read by lanes with one parameter free or a singular
    // joint system only.
    let both = s.and(s.and(n_free, k_free), joint);
    let (dn_1, dk_1) = if s.bits(s.and(live, s.and(s.or(n_free, k_free), s.not(both)))) != 0 {
        (s.div(s.mul(neg, g0), a00), s.div(s.mul(neg, g1), a11))
    } else {
        (zero, zero)
    };
    let inv_det = s.div(neg, det);
    let dn_2 = s.select(
        joint,
        s.mul(s.sub(s.mul(a11, g0), s.mul(a01, g1)), inv_det),
        dn_1,
    );
    let dk_2 = s.select(
        joint,
        s.mul(s.sub(s.mul(a00, g1), s.mul(a01, g0)), inv_det),
        dk_1,
    );
    let dn = s.select(n_free, s.select(k_free, dn_2, dn_1), zero);
    let dk = s.select(k_free, s.select(n_free, dk_2, dk_1), zero);
    let u = s.min(
        s.max(s.fma(vk, vk, dk), s.splat(k_lo * k_lo)),
        s.splat(b.k_max * b.k_max),
    );
    let k_raw = if any_u {
        s.select(in_u, s.sqrt(u), s.add(vk, dk))
    } else {
        s.add(vk, dk)
    };
    let n_raw = s.add(vn, dn);
    let n_p = if b.n_min == 0.0 { s.abs(n_raw) } else { n_raw };
    let k_p = if b.k_min == 0.0 { s.abs(k_raw) } else { k_raw };
    let n1 = s.min(s.max(n_p, n_min), n_max);
    let k1 = s.min(s.max(k_p, k_lo_v), k_max);
    // The step along the line through 1/N (lm::arc_step), where it applies.
    let both_free = s.and(s.not(in_u), s.and(n_free, k_free));
    let (n1, k1) = arc_step(
        s,
        [n_min, n_max, k_lo_v, k_max],
        (vn, vk),
        (dn, dk),
        both_free,
        (n1, k1),
    );
    let en = s.sub(n1, vn);
    let ek = s.select(in_u, s.sub(s.mul(k1, k1), s.mul(vk, vk)), s.sub(k1, vk));
    let p = predicted(s, [h00, h01, h11, g0, g1], en, ek);
    (
        s.select(finite, n1, vn),
        s.select(finite, k1, vk),
        s.select(finite, p, zero),
    )
}

/// The step along the line through `1/N` of `lm::arc_step` from `(vn, vk)` for the
/// Gauss–Newton step `(dn, dk)`, in the lanes of `eligible` (both parameters free, in
/// `k`) where it applies: strictly inside the box `[n_min, n_max, k_lo, k_max]`, the
/// step shorter than `ARC_MAX |N|` and the arc point inside the box; other lanes keep
/// `(n1, k1)`.
#[inline(always)]
fn arc_step<S: Simd>(
    s: S,
    [n_min, n_max, k_lo_v, k_max]: [S::V; 4],
    (vn, vk): (S::V, S::V),
    (dn, dk): (S::V, S::V),
    eligible: S::M,
    (n1, k1): (S::V, S::V),
) -> (S::V, S::V) {
    let (one, two) = (s.splat(1.0), s.splat(2.0));
    let ar = s.sub(s.mul(vn, vn), s.mul(vk, vk));
    let ai = s.mul(two, s.mul(vn, vk));
    let br = s.sub(vn, dn);
    let bi = s.sub(vk, dk);
    let inv = s.div(one, s.add(s.mul(br, br), s.mul(bi, bi)));
    let na = s.mul(s.add(s.mul(ar, br), s.mul(ai, bi)), inv);
    let ka = s.mul(s.sub(s.mul(ai, br), s.mul(ar, bi)), inv);
    let arc = s.and(
        s.and(
            eligible,
            s.and(s.and(s.lt(n_min, vn), s.lt(vn, n_max)), s.lt(vk, k_max)),
        ),
        s.and(
            s.lt(
                s.add(s.mul(dn, dn), s.mul(dk, dk)),
                s.mul(
                    s.splat(ARC_MAX * ARC_MAX),
                    s.add(s.mul(vn, vn), s.mul(vk, vk)),
                ),
            ),
            s.and(
                s.and(s.lt(n_min, na), s.lt(na, n_max)),
                s.and(s.lt(k_lo_v, ka), s.lt(ka, k_max)),
            ),
        ),
    );
    (s.select(arc, na, n1), s.select(arc, ka, k1))
}

/// The decrease `−(2 gᵀδ + δᵀ H δ)` the Gauss–Newton model `[h00, h01, h11, g0, g1]`
/// predicts for the step `δ = (en, ek)`.
#[inline(always)]
fn predicted<S: Simd>(s: S, [h00, h01, h11, g0, g1]: [S::V; 5], en: S::V, ek: S::V) -> S::V {
    let two = s.splat(2.0);
    let lin = s.mul(two, s.add(s.mul(g0, en), s.mul(g1, ek)));
    let quad = s.add(
        s.mul(s.mul(h00, en), en),
        s.add(
            s.mul(s.mul(s.mul(two, h01), en), ek),
            s.mul(s.mul(h11, ek), ek),
        ),
    );
    s.sub(s.splat(0.0), s.add(lin, quad))
}

/// Run every job of `jobs`, writing `out[j]` for job `j`. `y` holds the measurements
/// row by row (`T = t_len` values per row; `w` the weights, the same layout, or every
/// weight 1 when `None`).
///
/// The β terms: `PIX = false`, those of `lanes`, shared by every job (`pix` is not
/// read); `PIX = true`, every pixel's own, `pix` row by row like `y` (`lanes` is not
/// read), copied into the lane's slots of the scratch when a lane takes a job. The
/// arithmetic is the same either way, so a pixel whose terms equal the shared ones
/// gets the same result bit for bit.
///
/// Every step of every lane is vector code; only a lane whose polish ends (about one
/// evaluation in seven) takes a scalar detour to store its result and load the next
/// job.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn run<S: Simd, const PIX: bool>(
    s: S,
    lanes: &Lanes,
    pix: &[LaneTerms],
    t_len: usize,
    set: &Settings,
    jobs: &[Job],
    y: &[f64],
    w: Option<&[f64]>,
    out: &mut [JobOut],
    sc: &mut LaneScratch,
) {
    sc.reset::<PIX>(t_len);
    let b = &set.bounds;
    let (zero, one) = (s.splat(0.0), s.splat(1.0));
    let mut q = Queue::<PIX> {
        jobs,
        y,
        w,
        pix,
        t_len,
        k_floor: if b.k_min == 0.0 { K_FLOOR } else { b.k_min },
        next: 0,
        job: [usize::MAX; W],
        start_n: [1.0; W],
        start_k: [1.0; W],
        node_n: [1.0; W],
        node_k: [1.0; W],
        grid_cost: [0.0; W],
        free_b: (1u32 << W) - 1,
    };
    // Phases as lane bits: evaluating the start, evaluating the node, iterating.
    let (mut start_b, mut node_b, mut lm_b) = (0u32, 0u32, 0u32);
    // Vector state.
    let mut st = LaneState::new(s);
    start_b |= q.refill(sc);
    let (xtol, ftol) = (s.splat(set.xtol), s.splat(set.ftol));
    let max_iter = s.splat(f64::from(set.max_iter));
    loop {
        // 1. Levenberg–Marquardt lanes: the next trial point, or the end of the
        //    polish (before an evaluation).
        let lm_m = s.mask(lm_b);
        let (nt, kt, pred) = step_lanes(s, lm_m, &st.cur, st.lam, st.n, st.k, b);
        let maxed = s.and(lm_m, s.le(max_iter, st.iters));
        let going = s.and(lm_m, s.not(maxed));
        st.iters = s.add(st.iters, s.select(going, one, zero));
        let (n, k, lam) = (st.n, st.k, st.lam);
        let still = s.and(
            s.le(s.abs(s.sub(nt, n)), s.mul(xtol, s.add(s.abs(n), xtol))),
            s.le(
                s.abs(s.sub(kt, k)),
                s.mul(xtol, s.add(s.abs(k), s.splat(1e-12))),
            ),
        );
        let flat = s.and(
            s.and(s.le(lam, s.splat(1e-5)), s.le(zero, pred)),
            s.le(pred, s.mul(ftol, st.cur.cost)),
        );
        let stop = s.and(going, s.or(s.or(s.eq(st.cur.cost, zero), still), flat));
        let done = s.bits(s.or(maxed, stop));
        if done != 0 {
            st.retire(s, done, s.bits(stop), &mut q.job, out);
            lm_b &= !done;
            q.free_b |= done;
            start_b |= q.refill(sc);
        }
        let active = start_b | node_b | lm_b;
        if active == 0 {
            break;
        }
        // 2. Trial points of every lane, and their evaluation.
        let (start_m, node_m, lm_m) = (s.mask(start_b), s.mask(node_b), s.mask(lm_b));
        let (tn, tk) = q.trial_points(s, [start_m, node_m, lm_m], nt, kt);
        let ev = if w.is_some() {
            eval_lanes::<S, true, PIX>(s, lanes, t_len, sc, tn, tk)
        } else {
            eval_lanes::<S, false, PIX>(s, lanes, t_len, sc, tn, tk)
        };
        st.evals = s.add(st.evals, s.select(s.mask(active), one, zero));
        // 3. Accept or reject. Start and node evaluations are always taken; a start
        //    worse than its node's grid cost is followed by the node.
        let first = s.or(start_m, node_m);
        let bad = s.and(
            start_m,
            s.not(s.le(
                ev.cost,
                s.add(
                    s.mul(s.load(&q.grid_cost), s.splat(1.0 + 1e-4)),
                    s.splat(1e-12),
                ),
            )),
        );
        let (conv_b, over_b) = st.take(s, &ev, (tn, tk), first, lm_m, ftol);
        let bad_b = s.bits(bad);
        lm_b |= (start_b & !bad_b) | node_b;
        node_b = bad_b;
        start_b = 0;
        if conv_b | over_b != 0 {
            let ok_b = conv_b | st.minima(s, over_b, b);
            let done = conv_b | over_b;
            st.retire(s, done, ok_b, &mut q.job, out);
            lm_b &= !done;
            q.free_b |= done;
            start_b |= q.refill(sc);
        }
    }
}

impl LaneScratch {
    /// Size the scratch for rows of `t_len` values: every weight 1 (unweighted lanes
    /// keep them), with a β per pixel (`PIX`) harmless terms (β = 45°) for lanes
    /// without a job.
    #[inline(always)]
    fn reset<const PIX: bool>(&mut self, t_len: usize) {
        if self.y.len() != t_len * W {
            self.y = vec![0.0; t_len * W];
        }
        if PIX {
            for v in self.b.iter_mut() {
                // Lanes without a job keep harmless terms (β = 45°).
                v.clear();
                v.resize(t_len * W, 0.5);
            }
        }
        // Unweighted: every lane's weights stay 1.
        self.w.clear();
        self.w.resize(t_len * W, 1.0);
    }
}

/// The job queue of [`run`] and the job data of every lane (written when a lane takes
/// a job).
struct Queue<'a, const PIX: bool> {
    jobs: &'a [Job],
    /// Measurements, weights and β terms of the jobs' pixels (see [`run`]).
    y: &'a [f64],
    w: Option<&'a [f64]>,
    pix: &'a [LaneTerms],
    t_len: usize,
    /// Smallest `k` of a start or node.
    k_floor: f64,
    /// Next job of the queue.
    next: usize,
    /// Job of every lane (`usize::MAX`: none).
    job: [usize; W],
    start_n: L,
    start_k: L,
    node_n: L,
    node_k: L,
    grid_cost: L,
    /// Lanes without a job.
    free_b: u32,
}

impl<const PIX: bool> Queue<'_, PIX> {
    /// Give every lane without a job the next job of the queue, its measurements into
    /// the lane's slots of `sc`; the lanes started, as bits.
    #[inline(always)]
    fn refill(&mut self, sc: &mut LaneScratch) -> u32 {
        let t_len = self.t_len;
        let mut started = 0u32;
        let mut free = self.free_b;
        while free != 0 && self.next < self.jobs.len() {
            let l = free.trailing_zeros() as usize;
            free &= free - 1;
            let j = &self.jobs[self.next];
            self.job[l] = self.next;
            self.next += 1;
            started |= 1 << l;
            self.start_n[l] = j.start.0;
            self.start_k[l] = j.start.1.max(self.k_floor);
            self.node_n[l] = j.node.0;
            self.node_k[l] = j.node.1.max(self.k_floor);
            self.grid_cost[l] = j.grid_cost;
            let row = &self.y[j.pixel * t_len..(j.pixel + 1) * t_len];
            for (t, &v) in row.iter().enumerate() {
                sc.y[t * W + l] = v;
            }
            if let Some(w) = self.w {
                let row = &w[j.pixel * t_len..(j.pixel + 1) * t_len];
                for (t, &v) in row.iter().enumerate() {
                    sc.w[t * W + l] = v;
                }
            }
            if PIX {
                let row = &self.pix[j.pixel * t_len..(j.pixel + 1) * t_len];
                for (t, b) in row.iter().enumerate() {
                    sc.b[0][t * W + l] = b.s2;
                    sc.b[1][t * W + l] = b.c;
                    sc.b[2][t * W + l] = b.c2;
                    sc.b[3][t * W + l] = b.s4;
                    sc.b[4][t * W + l] = b.num;
                }
            }
        }
        self.free_b &= !started;
        started
    }

    /// The trial point of every lane: the start, the node or the
    /// Levenberg–Marquardt step `(nt, kt)` by the phase masks `[start, node, lm]`
    /// (`(1, 1)` for idle lanes).
    #[inline(always)]
    fn trial_points<S: Simd>(
        &self,
        s: S,
        [start_m, node_m, lm_m]: [S::M; 3],
        nt: S::V,
        kt: S::V,
    ) -> (S::V, S::V) {
        let one = s.splat(1.0);
        let tn = s.select(
            lm_m,
            nt,
            s.select(
                start_m,
                s.load(&self.start_n),
                s.select(node_m, s.load(&self.node_n), one),
            ),
        );
        let tk = s.select(
            lm_m,
            kt,
            s.select(
                start_m,
                s.load(&self.start_k),
                s.select(node_m, s.load(&self.node_k), one),
            ),
        );
        (tn, tk)
    }
}

/// The vector state of the polishes in the lanes.
struct LaneState<S: Simd> {
    n: S::V,
    k: S::V,
    lam: S::V,
    iters: S::V,
    evals: S::V,
    /// Cost and normal equations at `(n, k)`.
    cur: EvalV<S>,
}

impl<S: Simd> LaneState<S> {
    /// Every lane at `(1, 1)` with the initial damping, no iteration or evaluation.
    #[inline(always)]
    fn new(s: S) -> Self {
        let (zero, one) = (s.splat(0.0), s.splat(1.0));
        Self {
            n: one,
            k: one,
            lam: s.splat(LAM_0),
            iters: zero,
            evals: zero,
            cur: EvalV::<S> {
                cost: zero,
                h00: zero,
                h01: zero,
                h11: zero,
                g0: zero,
                g1: zero,
            },
        }
    }

    /// Take the evaluation `ev` at the trial points `(tn, tk)` where it is a first
    /// evaluation (`first`) or an accepted step of a Levenberg–Marquardt lane (`lm_m`),
    /// and update the damping; the lanes that converged (an accepted step with a small
    /// decrease at small damping) and those whose damping overflowed, as bits.
    #[inline(always)]
    fn take(
        &mut self,
        s: S,
        ev: &EvalV<S>,
        (tn, tk): (S::V, S::V),
        first: S::M,
        lm_m: S::M,
        ftol: S::V,
    ) -> (u32, u32) {
        let accept = s.and(lm_m, s.le(ev.cost, self.cur.cost));
        let reject = s.and(lm_m, s.not(s.le(ev.cost, self.cur.cost)));
        let small_dec = s.le(s.sub(self.cur.cost, ev.cost), s.mul(ftol, ev.cost));
        let take = s.or(first, accept);
        self.cur = EvalV::select(s, take, ev, &self.cur);
        self.n = s.select(take, tn, self.n);
        self.k = s.select(take, tk, self.k);
        let lam = self.lam;
        self.lam = s.select(
            accept,
            s.max(s.mul(lam, s.splat(LAM_DOWN)), s.splat(1e-12)),
            s.select(
                reject,
                s.max(s.mul(lam, s.splat(LAM_UP)), s.splat(LAM_REJECT)),
                lam,
            ),
        );
        let conv = s.and(accept, s.and(small_dec, s.le(self.lam, s.splat(1e-3))));
        let over = s.and(reject, s.lt(s.splat(1e10), self.lam));
        (s.bits(conv), s.bits(over))
    }

    /// Of the lanes `over_b` (no further decrease at this precision), those at a
    /// minimum: the undamped Gauss–Newton model predicts nothing to gain.
    #[inline(always)]
    fn minima(&self, s: S, over_b: u32, b: &FitBounds) -> u32 {
        let cur = &self.cur;
        let mut ok_b = 0;
        for l in 0..W {
            if over_b >> l & 1 == 1 {
                let e = Eval {
                    cost: lane(s, cur.cost, l),
                    ss: 0.0,
                    h00: lane(s, cur.h00, l),
                    h01: lane(s, cur.h01, l),
                    h11: lane(s, cur.h11, l),
                    g0: lane(s, cur.g0, l),
                    g1: lane(s, cur.g1, l),
                };
                let (_, _, p0) =
                    super::lm::step(&e, 0.0, lane(s, self.n, l), lane(s, self.k, l), b);
                if p0 <= 1e-9 * e.cost + 1e-28 {
                    ok_b |= 1 << l;
                }
            }
        }
        ok_b
    }

    /// End the polishes of the lanes in `done` (converged: bits of `conv`), writing
    /// `out[job[l]]` and freeing their lanes (`job[l] = usize::MAX`, counters and
    /// damping reset).
    #[inline(always)]
    fn retire(&mut self, s: S, done: u32, conv: u32, job: &mut [usize; W], out: &mut [JobOut]) {
        let cur = &self.cur;
        let mut a = [[0.0; W]; 10];
        for (dst, v) in a.iter_mut().zip([
            self.n, self.k, cur.cost, cur.h00, cur.h01, cur.h11, cur.g0, cur.g1, self.iters,
            self.evals,
        ]) {
            s.store(v, dst);
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
        let m = s.mask(done);
        self.iters = s.select(m, s.splat(0.0), self.iters);
        self.evals = s.select(m, s.splat(0.0), self.evals);
        self.lam = s.select(m, s.splat(LAM_0), self.lam);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::cpu_features;
    use crate::dop::BetaTerms;
    use crate::fit::simd::Portable;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// Lane `l`'s values of an evaluation.
    fn lane_eval<S: Simd>(s: S, e: &EvalV<S>, l: usize) -> [f64; 6] {
        [
            lane(s, e.cost, l),
            lane(s, e.h00, l),
            lane(s, e.h01, l),
            lane(s, e.h11, l),
            lane(s, e.g0, l),
            lane(s, e.g1, l),
        ]
    }

    /// Evaluate `pts` ([`W`] at a time) with backend `s`.
    #[inline(always)]
    fn eval_all<S: Simd>(
        s: S,
        lanes: &Lanes,
        y: &[f64],
        w: &[f64],
        pts: &[(f64, f64)],
    ) -> Vec<[f64; 6]> {
        let t_len = y.len();
        let mut yl = vec![0.0; t_len * W];
        let mut wl = vec![0.0; t_len * W];
        for t in 0..t_len {
            for l in 0..W {
                yl[t * W + l] = y[t];
                wl[t * W + l] = w[t];
            }
        }
        let sc = LaneScratch {
            y: yl,
            w: wl,
            b: Default::default(),
        };
        let mut out = vec![];
        for c in pts.chunks(W) {
            let mut n = [1.0; W];
            let mut k = [1.0; W];
            for (l, &(a, b)) in c.iter().enumerate() {
                n[l] = a;
                k[l] = b;
            }
            let e = eval_lanes::<S, true, false>(s, lanes, t_len, &sc, s.load(&n), s.load(&k));
            out.extend((0..c.len()).map(|l| lane_eval(s, &e, l)));
        }
        out
    }

    /// [`eval_all`] compiled for AVX2 + FMA.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA (the caller holds an `Avx2Fma` token, passed as `s`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn eval_avx2(
        s: crate::cpu::Avx2Fma,
        lanes: &Lanes,
        y: &[f64],
        w: &[f64],
        pts: &[(f64, f64)],
    ) -> Vec<[f64; 6]> {
        eval_all(s, lanes, y, w, pts)
    }

    /// [`eval_all`] compiled for AVX-512F.
    ///
    /// # Safety
    /// The CPU has AVX-512F, AVX2 and FMA (the caller holds an `Avx512` token, passed
    /// as `s`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn eval_avx512(
        s: crate::cpu::Avx512,
        lanes: &Lanes,
        y: &[f64],
        w: &[f64],
        pts: &[(f64, f64)],
    ) -> Vec<[f64; 6]> {
        eval_all(s, lanes, y, w, pts)
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
            let mut runs = vec![eval_all(Portable, &lanes, &y, &wv, &pts)];
            #[cfg(target_arch = "x86_64")]
            {
                if let Some(t) = cpu_features().avx2_fma() {
                    // SAFETY: the token proves the CPU has AVX2 + FMA.
                    runs.push(unsafe { eval_avx2(t, &lanes, &y, &wv, &pts) });
                }
                if let Some(t) = cpu_features().avx512() {
                    // SAFETY: the token proves the CPU has AVX-512F, AVX2 and FMA.
                    runs.push(unsafe { eval_avx512(t, &lanes, &y, &wv, &pts) });
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
