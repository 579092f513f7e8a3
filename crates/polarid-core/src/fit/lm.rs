//! Hand-written, bounded, weighted two-parameter Levenberg–Marquardt on `(n, k)`.
//!
//! The residuals are `r_t = P(n, k, β_t) − y_t` (eq. 16) with weights `w_t`; the
//! normal equations `JᵀWJ`, `JᵀWr` are accumulated on the fly (no arrays) from
//! [`dop_grad_terms`] and the 2×2 damped system is solved in closed form.

use crate::dop::{BetaTerms, dop_grad_terms};

use super::FitBounds;
use super::simd::{self, Lanes};

/// Cost and normal equations at one point.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Eval {
    /// Weighted sum of squared residuals `Σ w r²`.
    pub cost: f64,
    /// Unweighted sum of squared residuals `Σ r²`.
    pub ss: f64,
    /// `Σ w Jn²`.
    pub h00: f64,
    /// `Σ w Jn Jk`.
    pub h01: f64,
    /// `Σ w Jk²`.
    pub h11: f64,
    /// `Σ w Jn r`.
    pub g0: f64,
    /// `Σ w Jk r`.
    pub g1: f64,
}

/// Evaluate the cost and the normal equations at `(n, k)`.
#[inline]
pub(crate) fn eval(terms: &[BetaTerms], y: &[f64], w: Option<&[f64]>, n: f64, k: f64) -> Eval {
    let mut e = Eval::default();
    match w {
        None => {
            for (t, &yt) in terms.iter().zip(y) {
                let d = dop_grad_terms(n, k, t);
                let r = d.p - yt;
                e.ss += r * r;
                e.h00 += d.dp_dn * d.dp_dn;
                e.h01 += d.dp_dn * d.dp_dk;
                e.h11 += d.dp_dk * d.dp_dk;
                e.g0 += d.dp_dn * r;
                e.g1 += d.dp_dk * r;
            }
            e.cost = e.ss;
        }
        Some(w) => {
            for ((t, &yt), &wt) in terms.iter().zip(y).zip(w) {
                let d = dop_grad_terms(n, k, t);
                let r = d.p - yt;
                let wr = wt * r;
                e.ss += r * r;
                e.cost += wr * r;
                e.h00 += wt * d.dp_dn * d.dp_dn;
                e.h01 += wt * d.dp_dn * d.dp_dk;
                e.h11 += wt * d.dp_dk * d.dp_dk;
                e.g0 += d.dp_dn * wr;
                e.g1 += d.dp_dk * wr;
            }
        }
    }
    e
}

/// Outcome of a polish.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LmOut {
    pub n: f64,
    pub k: f64,
    pub ev: Eval,
    pub iters: u32,
    pub evals: u32,
    pub converged: bool,
}

/// Solver settings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LmSettings {
    pub max_iter: u32,
    pub xtol: f64,
    pub ftol: f64,
}

/// Damping factor after a rejected step (a milder schedule than ×10/÷10 saves ~0.3
/// evaluations per fit in curved valleys, where accepted and rejected steps alternate).
const LAM_UP: f64 = 5.0;
/// Damping factor after an accepted step.
const LAM_DOWN: f64 = 0.2;

/// Below this `k` the polish steps in `u = k²` instead of `k`.
pub(crate) const K_U: f64 = 1.0;
/// Smallest `k` the `u`-steps reach when the lower bound is 0 (`u ≥ K_FLOOR²`); a fit
/// ending there is reported as `k = 0`.
pub(crate) const K_FLOOR: f64 = 1e-9;

/// Solve the damped 2×2 system `(H + λ diag H) δ = −g` in closed form, keeping a
/// parameter fixed when it sits on a bound and the descent direction points out of the
/// box, or when the data carry no information on it. Returns the trial point.
///
/// Near `k = 0`, `P` depends on `k` through `u = k²` (eq. 14–15), `∂P/∂k = 2k ∂P/∂u`
/// vanishes and Gauss–Newton in `k` only halves `k` per step; below [`K_U`] the step is
/// therefore taken in `(n, u)` (`∂P/∂u = (∂P/∂k)/(2k)`), where it is quadratically
/// convergent and `u ≥ 0` is an ordinary bound.
#[inline(always)]
pub(crate) fn step(ev: &Eval, lam: f64, n: f64, k: f64, b: &FitBounds) -> (f64, f64, f64) {
    let in_u = k < K_U && k > 0.0;
    let (h00, mut h01, mut h11, g0, mut g1) = (ev.h00, ev.h01, ev.h11, ev.g0, ev.g1);
    if in_u {
        let s = 0.5 / k;
        h01 *= s;
        h11 *= s * s;
        g1 *= s;
    }
    if !(h00.is_finite() && h11.is_finite() && h01.is_finite()) {
        return (n, k, 0.0);
    }
    // Marquardt scaling: damping proportional to each diagonal (scale-free, which
    // matters because ∂P/∂n and ∂P/∂u can differ by many orders of magnitude).
    let a00 = h00 * (1.0 + lam);
    let a11 = h11 * (1.0 + lam);
    let a01 = h01;
    let k_lo = if b.k_min > 0.0 { b.k_min } else { K_FLOOR };
    // A bound is "blocking" when the parameter sits on it and −g points outwards.
    let n_blocked = (n <= b.n_min && g0 > 0.0) || (n >= b.n_max && g0 < 0.0);
    let k_blocked = (k <= k_lo && g1 > 0.0) || (k >= b.k_max && g1 < 0.0);
    let n_free = !n_blocked && h00 > 0.0;
    let k_free = !k_blocked && h11 > 0.0;
    let (dn, dk) = match (n_free, k_free) {
        (true, true) => {
            let det = a00 * a11 - a01 * a01;
            if det > 1e-15 * a00 * a11 {
                (-(a11 * g0 - a01 * g1) / det, -(a00 * g1 - a01 * g0) / det)
            } else {
                (-g0 / a00, -g1 / a11)
            }
        }
        (true, false) => (-g0 / a00, 0.0),
        (false, true) => (0.0, -g1 / a11),
        (false, false) => (0.0, 0.0),
    };
    let (nt, kt) = if in_u {
        let u = (k * k + dk).clamp(k_lo * k_lo, b.k_max * b.k_max);
        project(n + dn, u.sqrt(), b)
    } else {
        project(n + dn, k + dk, b)
    };
    // Decrease of the cost predicted by the Gauss–Newton model for the step taken.
    let en = nt - n;
    let ek = if in_u { kt * kt - k * k } else { kt - k };
    let pred = -(2.0 * (g0 * en + g1 * ek) + h00 * en * en + 2.0 * h01 * en * ek + h11 * ek * ek);
    (nt, kt, pred)
}

/// Bring a trial point back into the box: reflection at a lower bound of 0 (the model
/// is even in `n` and in `k`, so this is exact), clamping elsewhere.
#[inline(always)]
pub(crate) fn project(n: f64, k: f64, b: &FitBounds) -> (f64, f64) {
    let n = if b.n_min == 0.0 { n.abs() } else { n };
    let k = if b.k_min == 0.0 { k.abs() } else { k };
    let k_lo = if b.k_min > 0.0 { b.k_min } else { K_FLOOR };
    (n.clamp(b.n_min, b.n_max), k.clamp(k_lo, b.k_max))
}

/// Levenberg–Marquardt from `(n, k)` whose evaluation `ev0` is already known.
///
/// `y` and `w` are the measurements and weights padded to the lane length of `lanes`
/// (weight 0 on padding). Stops when the step is below `xtol` (relative), when an
/// accepted step decreased the cost by at most `ftol` (relative), or, before
/// evaluating a step, when the Gauss–Newton model predicts a decrease of at most
/// `ftol` (relative): the minimum is then known to that precision without spending an
/// evaluation on it.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn polish(
    lanes: &Lanes,
    y: &[f64],
    w: &[f64],
    b: &FitBounds,
    s: &LmSettings,
    n0: f64,
    k0: f64,
    ev0: Eval,
) -> LmOut {
    let (mut n, mut k) = (n0, k0);
    let mut cur = ev0;
    let mut lam = 1e-6;
    let mut evals = 0u32;
    let mut iters = 0u32;
    let mut converged = false;
    while iters < s.max_iter {
        iters += 1;
        if cur.cost == 0.0 {
            converged = true;
            break;
        }
        let (nt, kt, pred) = step(&cur, lam, n, k, b);
        let mv_n = (nt - n).abs();
        let mv_k = (kt - k).abs();
        // Stationary to within xtol (relative to each parameter's own scale).
        if mv_n <= s.xtol * (n.abs() + s.xtol) && mv_k <= s.xtol * (k.abs() + 1e-12) {
            converged = true;
            break;
        }
        // Nothing left to gain at this precision (near-Gauss–Newton step only: its
        // quadratic model is accurate close to the minimum).
        if lam <= 1e-5 && pred >= 0.0 && pred <= s.ftol * cur.cost {
            converged = true;
            break;
        }
        let new = simd::eval(lanes, y, w, nt, kt);
        evals += 1;
        if new.cost <= cur.cost {
            let dec = cur.cost - new.cost;
            n = nt;
            k = kt;
            cur = new;
            lam = (lam * LAM_DOWN).max(1e-12);
            if dec <= s.ftol * new.cost && lam <= 1e-3 {
                converged = true;
                break;
            }
        } else {
            lam *= LAM_UP;
            if lam > 1e10 {
                // No further decrease is possible at this precision: accept as a
                // minimum if the undamped Gauss–Newton model predicts nothing to gain.
                let (_, _, pred) = step(&cur, 0.0, n, k, b);
                converged = pred <= 1e-9 * cur.cost + 1e-28;
                break;
            }
        }
    }
    LmOut {
        n,
        k,
        ev: cur,
        iters,
        evals,
        converged,
    }
}
