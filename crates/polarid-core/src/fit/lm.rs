//! Hand-written, bounded, weighted two-parameter Levenberg–Marquardt on `(n, k)`.
//!
//! The residuals are `r_t = P(n, k, β_t) − y_t` (eq. 16) with weights `w_t`; the
//! normal equations `JᵀWJ`, `JᵀWr` are accumulated on the fly (no arrays) from
//! [`dop_grad_terms`] and the 2×2 damped system is solved in closed form.

use crate::dop::{BetaTerms, dop_grad_terms};

use super::FitBounds;

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
        match arc_step(n, k, dn, dk, b, n_free && k_free) {
            Some(p) => p,
            None => project(n + dn, k + dk, b),
        }
    };
    // Decrease of the cost predicted by the Gauss–Newton model for the step taken.
    let en = nt - n;
    let ek = if in_u { kt * kt - k * k } else { kt - k };
    let pred = -(2.0 * (g0 * en + g1 * ek) + h00 * en * en + 2.0 * h01 * en * ek + h11 * ek * ek);
    (nt, kt, pred)
}

/// Largest `|δN| / |N|` of an [`arc_step`].
pub(crate) const ARC_MAX: f64 = 0.7;

/// The step `δN = δn + i δk` taken along the straight line through `1/N` instead of
/// `N`: `N' = N² / (N − δN)` (`1/N' = 1/N − δN/N²`, the first-order image of `δN`), the
/// same step to first order. For a strongly absorbing medium eq. (9) depends to first
/// order in `1/|N|` on `Re(1/N) = n/(n² + k²)` only (the Fresnel reflectances are
/// `1 − 4 cos β Re(1/N)` and `1 − 4 Re(1/N)/cos β` to that order), so the long, curved
/// valleys of χ² of metals (`n ∝ k²` along the valley) are nearly straight lines in
/// `1/N`, and Gauss–Newton steps taken there follow them instead of overshooting.
///
/// Taken only when both parameters are free (`free`), `(n, k)` is strictly inside the
/// box, `|δN| < ARC_MAX |N|` and `N'` is strictly inside the box too; `None`
/// otherwise (the caller takes the straight step).
#[inline(always)]
pub(crate) fn arc_step(
    n: f64,
    k: f64,
    dn: f64,
    dk: f64,
    b: &FitBounds,
    free: bool,
) -> Option<(f64, f64)> {
    let (ar, ai) = (n * n - k * k, 2.0 * n * k);
    let (br, bi) = (n - dn, k - dk);
    let inv = 1.0 / (br * br + bi * bi);
    let na = (ar * br + ai * bi) * inv;
    let ka = (ai * br - ar * bi) * inv;
    let k_lo = if b.k_min > 0.0 { b.k_min } else { K_FLOOR };
    let ok = free
        && n > b.n_min
        && n < b.n_max
        && k < b.k_max
        && dn * dn + dk * dk < ARC_MAX * ARC_MAX * (n * n + k * k)
        && na > b.n_min
        && na < b.n_max
        && ka > k_lo
        && ka < b.k_max;
    ok.then_some((na, ka))
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
