//! Uncertainties and trust status of a polished minimum: the covariance `(JᵀWJ)⁻¹`
//! (scaled by the reduced χ² when no standard errors are given), in `(n, u = k²)` when
//! the linearised interval on `k` reaches 0, and the [`FitStatus`] with its reason
//! (see "Uncertainty" in the module documentation of [`crate::fit`]).

use super::engine;
use super::grid::Grid;
use super::lm;
use super::{FitPlan, FitStatus, NkFit};
use crate::dop::{BetaTerms, dop_grad_terms, dop_terms};

impl FitPlan {
    /// Standard errors, correlation and status of a polished minimum.
    #[inline]
    pub(super) fn finish(&self, out: &engine::JobOut, y: &[f64], w: Option<&[f64]>) -> NkFit {
        self.grid.finish(&self.terms, self.issue, out, y, w)
    }
}

impl Grid {
    /// Standard errors, correlation and status of a polished minimum of a fit at the
    /// angles of `terms`; `issue`: why that β set is ill-conditioned, if it is.
    pub(super) fn finish(
        &self,
        terms: &[BetaTerms],
        issue: Option<&'static str>,
        out: &engine::JobOut,
        y: &[f64],
        w: Option<&[f64]>,
    ) -> NkFit {
        let t_len = terms.len();
        let b = &self.opts.bounds;
        let ev = &out.ev;
        let (n, k) = (out.n, out.k);
        // The lane evaluation returns the weighted cost; the rms residual is unweighted.
        let ss = match w {
            Some(_) => lm::eval(terms, y, None, n, k).ss,
            None => ev.cost,
        };
        let s2 = match w {
            Some(_) => 1.0,
            None => ev.cost / (t_len as f64 - 2.0),
        };
        // The u-steps stop at k = K_FLOOR when the lower bound is 0: that is k = 0.
        let k = if b.k_min == 0.0 && k <= lm::K_FLOOR {
            0.0
        } else {
            k
        };
        let mut fit = NkFit {
            n,
            k,
            rms_residual: (ss / t_len as f64).sqrt(),
            cost: ev.cost,
            ..Default::default()
        };
        // Linearised covariance in (n, k).
        let lin = inv2(ev.h00, ev.h01, ev.h11);
        let k_se_lin = lin.map_or(f64::INFINITY, |(_, _, c11)| (c11 * s2).sqrt());
        let use_u = b.k_min == 0.0 && (lin.is_none() || k < k_se_lin);
        let mut singular = false;
        if use_u {
            // (n, u = k²): P depends on k through k² only (eq. 14–15), so
            // ∂P/∂u = (∂P/∂k)/(2k) exactly: the polish's normal equations give the
            // (n, u) ones for k ≥ 1e-4; closer to 0 (where ∂P/∂k vanishes with k),
            // ∂P/∂u by a secant over Δu = 1e-6.
            let (a00, a01, a11) = if out.k >= 1e-4 {
                let s = 0.5 / out.k;
                (ev.h00, ev.h01 * s, ev.h11 * s * s)
            } else {
                let du = 1e-6;
                let k1 = (k * k + du).sqrt();
                let (mut a00, mut a01, mut a11) = (0.0, 0.0, 0.0);
                for (t, bt) in terms.iter().enumerate() {
                    let d = dop_grad_terms(n, k, bt);
                    let ju = (dop_terms(n, k1, bt) - d.p) / (k1 * k1 - k * k);
                    let wt = w.map_or(1.0, |w| w[t]);
                    a00 += wt * d.dp_dn * d.dp_dn;
                    a01 += wt * d.dp_dn * ju;
                    a11 += wt * ju * ju;
                }
                (a00, a01, a11)
            };
            match inv2(a00, a01, a11) {
                Some((c00, c01, c11)) => {
                    let se_u = (c11 * s2).sqrt();
                    fit.n_se = (c00 * s2).sqrt();
                    fit.k_se = (k * k + se_u).sqrt() - k;
                    fit.nk_corr = c01 / (c00 * c11).sqrt();
                }
                None => singular = true,
            }
        } else if let Some((c00, c01, c11)) = lin {
            fit.n_se = (c00 * s2).sqrt();
            fit.k_se = (c11 * s2).sqrt();
            fit.nk_corr = c01 / (c00 * c11).sqrt();
        } else {
            singular = true;
        }
        if singular {
            fit.n_se = f64::NAN;
            fit.k_se = f64::NAN;
            fit.nk_corr = f64::NAN;
        }
        // Plain comparisons (the data are validated: no NaN), one instruction each.
        let (ymin, ymax) = y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (if v < a { v } else { a }, if v > b { v } else { b })
            });
        let (status, reason) = if let Some(r) = issue {
            (FitStatus::IllConditioned, r)
        } else if ymax - ymin <= 1e-9 {
            (
                FitStatus::IllConditioned,
                "flat DoLP curve: the same DoLP at every beta",
            )
        } else if singular {
            (
                FitStatus::IllConditioned,
                "singular J^T W J: the DoLP curve does not determine n and k here",
            )
        } else if !out.converged {
            (
                FitStatus::NotConverged,
                "Levenberg-Marquardt did not converge within the iteration limit",
            )
        } else if b.n_min > 0.0 && n <= b.n_min {
            (FitStatus::AtBound, "n at the lower bound of the box")
        } else if n >= b.n_max {
            (FitStatus::AtBound, "n at the upper bound of the box")
        } else if b.k_min > 0.0 && k <= b.k_min {
            (FitStatus::AtBound, "k at the lower bound of the box")
        } else if k >= b.k_max {
            (FitStatus::AtBound, "k at the upper bound of the box")
        } else {
            (FitStatus::Ok, "")
        };
        fit.status = status;
        fit.reason = reason;
        fit
    }
}

/// Inverse of the symmetric 2×2 `[[a, b], [b, c]]` as `(i00, i01, i11)`, or `None`
/// when it is singular (a zero diagonal or `1 − ρ² < 1e-12`).
fn inv2(a: f64, b: f64, c: f64) -> Option<(f64, f64, f64)> {
    if !(a > 0.0 && c > 0.0) || !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return None;
    }
    let det = a * c - b * b;
    if !(det > 1e-12 * a * c) {
        return None;
    }
    Some((c / det, -b / det, a / det))
}
