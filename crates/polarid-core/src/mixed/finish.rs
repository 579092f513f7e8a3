//! From a polished minimum to a [`MixedFit`]: the covariance
//!
//! ```text
//! Cov = s² (JᵀJ)⁻¹,   s² = max(1, χ²/(2T − p)) with DoLP standard errors, χ²/(2T − p) without
//! ```
//!
//! (in `u = k²` near `k = 0`, giving a one-sigma upper deviation `√(k² + se_u) − k`), the
//! RMS residuals, the specular share range, the information criteria and the status
//! (`depolarized`, `ill_conditioned`, `not_converged`, `at_bound`, `ok`, in that order).

use super::linalg::spd_inverse;
use super::lm::Polished;
use super::model::point;
use super::problem::Problem;
use super::{
    FitStatus, K_FLOOR, K_U, MixedCapture, MixedFit, MixedModel, NPAR, P_K, P_LN_E, P_N, P_RHO,
    P_SIGMA, P_THETA_R,
};

/// `AIC = χ²/s² + 2p`, `BIC = χ²/s² + p ln m` (Gaussian likelihood with the error
/// scale `s²`; `m = 2T` residuals).
pub(super) fn set_criteria(fit: &mut MixedFit, s2: f64) {
    let m = (fit.dof + fit.params) as f64;
    let s2 = if s2 > 0.0 && s2.is_finite() { s2 } else { 1.0 };
    let c = fit.chi2 / s2;
    fit.aic = c + 2.0 * fit.params as f64;
    fit.bic = c + fit.params as f64 * m.ln();
}

pub(super) fn finish(
    pb: &Problem,
    caps: &[MixedCapture],
    model: MixedModel,
    best: &Polished,
    iters: u32,
) -> MixedFit {
    let o = pb.opts;
    let x = best.x;
    let est = o.estimate_theta_r;
    let t_len = caps.len();
    let m = 2 * t_len;
    let p_count = pb.free.iter().filter(|&&f| f).count();
    let dof = m.saturating_sub(p_count);
    // Jacobian at the solution (k evaluated at the floor when it was reported as 0).
    let mut xe = x;
    if xe[P_K] < K_FLOOR {
        xe[P_K] = K_FLOOR;
    }
    let (mut r, mut j) = (Vec::new(), Vec::new());
    let chi2 = pb.eval(&xe, &mut r, &mut j);
    let given_se = caps.iter().all(|c| c.dolp_se.is_some());
    let s2 = if dof == 0 {
        f64::NAN
    } else if given_se {
        (chi2 / dof as f64).max(1.0)
    } else {
        chi2 / dof as f64
    };
    let mut fit = MixedFit {
        model,
        n: x[P_N],
        k: x[P_K],
        sigma: x[P_SIGMA],
        rho_d: x[P_RHO],
        scale: x[P_LN_E].exp(),
        theta_r: if est { x[P_THETA_R] } else { caps[0].theta_r },
        theta_r_estimated: est,
        n_se: f64::NAN,
        k_se: f64::NAN,
        sigma_se: f64::NAN,
        rho_d_se: f64::NAN,
        scale_rel_se: f64::NAN,
        theta_r_se: f64::NAN,
        nk_corr: f64::NAN,
        chi2,
        dof,
        params: p_count,
        rms_dolp: 0.0,
        rms_s0_rel: 0.0,
        aic: f64::NAN,
        bic: f64::NAN,
        specular_share_min: f64::INFINITY,
        specular_share_max: f64::NEG_INFINITY,
        iterations: iters,
        status: FitStatus::Ok,
        reason: String::new(),
    };
    let cov = Covariance {
        idx: (0..NPAR).filter(|&a| pb.free[a]).collect(),
        j: &j,
        k: xe[P_K],
        s2,
    };
    let singular = !cov.set_errors(&mut fit, o.bounds.k_min == 0.0);
    set_residuals(&mut fit, pb, caps, &xe);
    set_criteria(&mut fit, s2);
    let (status, reason) = status(pb, &fit, best, m, singular);
    fit.status = status;
    fit.reason = reason;
    fit
}

/// The Jacobian at the solution and what the standard errors read of it.
struct Covariance<'a> {
    /// The free parameters (indices into the parameter vector).
    idx: Vec<usize>,
    /// Jacobian rows at the solution.
    j: &'a [[f64; NPAR]],
    /// `k` at which `j` was evaluated (at least the floor).
    k: f64,
    /// The error scale `s²`.
    s2: f64,
}

impl Covariance<'_> {
    /// `(JᵀJ)⁻¹` over the free parameters, in `u = k²` when `use_u`; `None` when
    /// singular.
    fn inverse(&self, use_u: bool) -> Option<[[f64; NPAR]; NPAR]> {
        let idx = &self.idx;
        let d = idx.len();
        let mut h = [[0.0; NPAR]; NPAR];
        for row in self.j {
            let mut row = *row;
            if use_u {
                row[P_K] /= 2.0 * self.k;
            }
            for p in 0..d {
                for q in 0..d {
                    h[p][q] += row[idx[p]] * row[idx[q]];
                }
            }
        }
        spd_inverse(&h, d)
    }

    /// Position of parameter `a` among the free ones.
    fn pos(&self, a: usize) -> Option<usize> {
        self.idx.iter().position(|&b| b == a)
    }

    /// Standard error of parameter `a` from the inverse `c` (NaN when `a` is fixed).
    fn se(&self, c: &[[f64; NPAR]; NPAR], a: usize) -> f64 {
        self.pos(a)
            .map_or(f64::NAN, |p| (c[p][p] * self.s2).max(0.0).sqrt())
    }

    /// Every standard error and the n–k correlation of `fit` from the inverse `c`
    /// (`k_se` from its `u = k²` entry when `in_u`).
    fn set_from(&self, fit: &mut MixedFit, c: &[[f64; NPAR]; NPAR], in_u: bool) {
        fit.n_se = self.se(c, P_N);
        if in_u {
            let se_u = self.se(c, P_K);
            fit.k_se = (fit.k * fit.k + se_u).sqrt() - fit.k;
        } else {
            fit.k_se = self.se(c, P_K);
        }
        fit.sigma_se = self.se(c, P_SIGMA);
        fit.rho_d_se = self.se(c, P_RHO);
        fit.scale_rel_se = self.se(c, P_LN_E);
        fit.theta_r_se = self.se(c, P_THETA_R);
        if let (Some(pn), Some(pk)) = (self.pos(P_N), self.pos(P_K)) {
            fit.nk_corr = c[pn][pk] / (c[pn][pn] * c[pk][pk]).sqrt();
        }
    }

    /// Set the standard errors of `fit` (`k_free_to_zero`: the box reaches `k = 0`);
    /// `false` when `JᵀJ` is singular in both `k` and `u = k²`.
    fn set_errors(&self, fit: &mut MixedFit, k_free_to_zero: bool) -> bool {
        match self.inverse(false) {
            Some(c) => {
                self.set_from(fit, &c, false);
                if k_free_to_zero && fit.k < fit.k_se && self.k < K_U {
                    // Near k = 0 the model depends on u = k²: one-sigma upper deviation.
                    if let Some(cu) = self.inverse(true) {
                        let se_u = self.se(&cu, P_K);
                        fit.k_se = (fit.k * fit.k + se_u).sqrt() - fit.k;
                    }
                }
                true
            }
            // k = 0 exactly: the k column vanishes; try u = k².
            None => match self.inverse(true) {
                Some(c) => {
                    self.set_from(fit, &c, true);
                    true
                }
                None => false,
            },
        }
    }
}

/// The RMS residuals and the specular share range of `fit` at `xe`.
fn set_residuals(fit: &mut MixedFit, pb: &Problem, caps: &[MixedCapture], xe: &[f64; NPAR]) {
    let o = pb.opts;
    let (mut sd, mut ss) = (0.0, 0.0);
    for (c, p) in caps.iter().zip(&pb.caps) {
        let mp = point(p, xe, o.estimate_theta_r, o.shadowing);
        sd += (mp.dolp - c.dolp).powi(2);
        ss += (mp.ln_s0 - p.ln_s0).powi(2);
        fit.specular_share_min = fit.specular_share_min.min(mp.specular_share);
        fit.specular_share_max = fit.specular_share_max.max(mp.specular_share);
    }
    let t_len = caps.len();
    fit.rms_dolp = (sd / t_len as f64).sqrt();
    fit.rms_s0_rel = (ss / t_len as f64).sqrt();
}

/// The reason the solution `best` sits at a bound of the box, if it does.
fn at_bound(pb: &Problem, best: &Polished) -> Option<&'static str> {
    let x = best.x;
    let at = |a: usize| pb.free[a] && (x[a] <= pb.lo[a] || x[a] >= pb.hi[a]);
    let b = &pb.opts.bounds;
    [
        (
            x[P_N] <= pb.lo[P_N] || x[P_N] >= pb.hi[P_N],
            "n at a bound of the box",
        ),
        (
            x[P_K] >= pb.hi[P_K] || (b.k_min > 0.0 && x[P_K] <= b.k_min),
            "k at a bound of the box",
        ),
        (at(P_SIGMA), "sigma at a bound of its range"),
        (
            pb.free[P_RHO] && x[P_RHO] >= pb.hi[P_RHO],
            "rho_d at its upper bound",
        ),
        (at(P_THETA_R), "theta_r at a bound of its feasible range"),
    ]
    .into_iter()
    .find(|(c, _)| *c)
    .map(|(_, r)| r)
}

/// The status of `fit` and its reason (see the module documentation for the order);
/// `m`: the number of residuals.
fn status(
    pb: &Problem,
    fit: &MixedFit,
    best: &Polished,
    m: usize,
    singular: bool,
) -> (FitStatus, String) {
    let o = pb.opts;
    if fit.specular_share_max < o.min_specular_share {
        (
            FitStatus::Depolarized,
            format!(
                "diffuse light dominates at every source position (specular share <= {:.3} < {})",
                fit.specular_share_max, o.min_specular_share
            ),
        )
    } else if fit.dof == 0 {
        (
            FitStatus::IllConditioned,
            format!(
                "{m} residuals for {} parameters: no degree of freedom",
                fit.params
            ),
        )
    } else if singular {
        (
            FitStatus::IllConditioned,
            "singular J^T J: the DoLP and S0 curves do not determine the parameters".into(),
        )
    } else if o.estimate_theta_r && !(fit.theta_r_se <= o.theta_r_se_max) {
        (
            FitStatus::IllConditioned,
            format!(
                "theta_r not identifiable: the intensity lobe does not pin the view angle (se {:.2} deg > {:.2} deg)",
                fit.theta_r_se.to_degrees(),
                o.theta_r_se_max.to_degrees()
            ),
        )
    } else if !best.converged {
        (
            FitStatus::NotConverged,
            "Levenberg-Marquardt did not converge within the iteration limit".into(),
        )
    } else if let Some(r) = at_bound(pb, best) {
        (FitStatus::AtBound, r.into())
    } else {
        (FitStatus::Ok, String::new())
    }
}
