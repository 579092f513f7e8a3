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
    let idx: Vec<usize> = (0..NPAR).filter(|&a| pb.free[a]).collect();
    let cov_of = |use_u: bool| -> Option<[[f64; NPAR]; NPAR]> {
        let d = idx.len();
        let mut h = [[0.0; NPAR]; NPAR];
        for row in &j {
            let mut row = *row;
            if use_u {
                row[P_K] /= 2.0 * xe[P_K];
            }
            for p in 0..d {
                for q in 0..d {
                    h[p][q] += row[idx[p]] * row[idx[q]];
                }
            }
        }
        spd_inverse(&h, d)
    };
    let pos = |a: usize| idx.iter().position(|&b| b == a);
    let se_of = |c: &[[f64; NPAR]; NPAR], a: usize| {
        pos(a).map_or(f64::NAN, |p| (c[p][p] * s2).max(0.0).sqrt())
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
    let mut singular = false;
    match cov_of(false) {
        Some(c) => {
            fit.n_se = se_of(&c, P_N);
            fit.k_se = se_of(&c, P_K);
            fit.sigma_se = se_of(&c, P_SIGMA);
            fit.rho_d_se = se_of(&c, P_RHO);
            fit.scale_rel_se = se_of(&c, P_LN_E);
            fit.theta_r_se = se_of(&c, P_THETA_R);
            if let (Some(pn), Some(pk)) = (pos(P_N), pos(P_K)) {
                fit.nk_corr = c[pn][pk] / (c[pn][pn] * c[pk][pk]).sqrt();
            }
            if o.bounds.k_min == 0.0 && fit.k < fit.k_se && xe[P_K] < K_U {
                // Near k = 0 the model depends on u = k²: one-sigma upper deviation.
                if let Some(cu) = cov_of(true) {
                    let se_u = se_of(&cu, P_K);
                    fit.k_se = (fit.k * fit.k + se_u).sqrt() - fit.k;
                }
            }
        }
        None => {
            // k = 0 exactly: the k column vanishes; try u = k².
            match cov_of(true) {
                Some(c) => {
                    fit.n_se = se_of(&c, P_N);
                    let se_u = se_of(&c, P_K);
                    fit.k_se = (fit.k * fit.k + se_u).sqrt() - fit.k;
                    fit.sigma_se = se_of(&c, P_SIGMA);
                    fit.rho_d_se = se_of(&c, P_RHO);
                    fit.scale_rel_se = se_of(&c, P_LN_E);
                    fit.theta_r_se = se_of(&c, P_THETA_R);
                    if let (Some(pn), Some(pk)) = (pos(P_N), pos(P_K)) {
                        fit.nk_corr = c[pn][pk] / (c[pn][pn] * c[pk][pk]).sqrt();
                    }
                }
                None => singular = true,
            }
        }
    }
    let (mut sd, mut ss) = (0.0, 0.0);
    for (c, p) in caps.iter().zip(&pb.caps) {
        let mp = point(p, &xe, est, o.shadowing);
        sd += (mp.dolp - c.dolp).powi(2);
        ss += (mp.ln_s0 - p.ln_s0).powi(2);
        fit.specular_share_min = fit.specular_share_min.min(mp.specular_share);
        fit.specular_share_max = fit.specular_share_max.max(mp.specular_share);
    }
    fit.rms_dolp = (sd / t_len as f64).sqrt();
    fit.rms_s0_rel = (ss / t_len as f64).sqrt();
    set_criteria(&mut fit, s2);
    let at = |a: usize| pb.free[a] && (x[a] <= pb.lo[a] || x[a] >= pb.hi[a]);
    let b = &o.bounds;
    let at_bound = [
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
    .map(|(_, r)| r);
    let (status, reason) = if fit.specular_share_max < o.min_specular_share {
        (
            FitStatus::Depolarized,
            format!(
                "diffuse light dominates at every source position (specular share <= {:.3} < {})",
                fit.specular_share_max, o.min_specular_share
            ),
        )
    } else if dof == 0 {
        (
            FitStatus::IllConditioned,
            format!("{m} residuals for {p_count} parameters: no degree of freedom"),
        )
    } else if singular {
        (
            FitStatus::IllConditioned,
            "singular J^T J: the DoLP and S0 curves do not determine the parameters".into(),
        )
    } else if est && !(fit.theta_r_se <= o.theta_r_se_max) {
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
    } else if let Some(r) = at_bound {
        (FitStatus::AtBound, r.into())
    } else {
        (FitStatus::Ok, String::new())
    };
    fit.status = status;
    fit.reason = reason;
    fit
}
