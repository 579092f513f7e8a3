//! Model selection ([`fit_mixed`]): the pure-specular (`ρd = 0`, `p − 1` parameters) and
//! the mixed model are both fitted (the mixed fit re-polished from the specular optimum
//! when that is better, since the models are nested) and compared with
//!
//! ```text
//! AIC = χ²/s² + 2p,   BIC = χ²/s² + p ln m        (m = 2T residuals)
//! ```
//!
//! on the error scale `s²` of the larger (mixed) model; the mixed model is selected when
//! its BIC is lower.

use super::finish::{finish, set_criteria};
use super::lm::polish;
use super::problem::Problem;
use super::{
    K_FLOOR, MixedCapture, MixedFit, MixedModel, MixedOptions, MixedReport, NPAR, P_K, P_LN_E, P_N,
    P_RHO, P_SIGMA, P_THETA_R, fit_model,
};
use crate::error::Result;

/// The variance scale `s²` of a fit: `max(1, χ²/dof)` when every capture has a DoLP
/// standard error, `χ²/dof` otherwise (NaN without degrees of freedom).
fn error_scale(fit: &MixedFit, caps: &[MixedCapture]) -> f64 {
    let given_se = caps.iter().all(|c| c.dolp_se.is_some());
    if fit.dof == 0 {
        f64::NAN
    } else if given_se {
        (fit.chi2 / fit.dof as f64).max(1.0)
    } else {
        fit.chi2 / fit.dof as f64
    }
}

/// Fit both the pure-specular and the mixed radiometric model to a target's captures
/// and select one by BIC (see the module documentation).
///
/// `caps[t]` holds capture `t`'s geometry, DoLP (with optional standard error) and
/// exposure-normalised `S0`. Errors: see [`fit_model`].
pub fn fit_mixed(caps: &[MixedCapture], opts: &MixedOptions) -> Result<MixedReport> {
    let specular = fit_model(caps, opts, MixedModel::Specular)?;
    let mut mixed = fit_model(caps, opts, MixedModel::Mixed)?;
    // The mixed model nests the specular one (ρd = 0): never accept a worse minimum.
    if specular.chi2 < mixed.chi2 * (1.0 - 1e-9) {
        let mut x0 = [0.0; NPAR];
        x0[P_N] = specular.n.max(opts.bounds.n_min);
        x0[P_K] = specular.k.max(K_FLOOR);
        x0[P_SIGMA] = specular.sigma;
        x0[P_RHO] = 0.0;
        x0[P_LN_E] = specular.scale.ln();
        x0[P_THETA_R] = if opts.estimate_theta_r {
            specular.theta_r
        } else {
            0.0
        };
        let pb = Problem::new(caps, opts, MixedModel::Mixed);
        let p = polish(&pb, x0);
        if p.cost < mixed.chi2 {
            let it = mixed.iterations + p.iters;
            mixed = finish(&pb, caps, MixedModel::Mixed, &p, it);
        }
    }
    // Both criteria on the error scale of the larger (mixed) model.
    let s2 = error_scale(&mixed, caps);
    let mut specular = specular;
    set_criteria(&mut specular, s2);
    set_criteria(&mut mixed, s2);
    let delta_bic = specular.bic - mixed.bic;
    let delta_aic = specular.aic - mixed.aic;
    let selected = if delta_bic > 0.0 {
        MixedModel::Mixed
    } else {
        MixedModel::Specular
    };
    Ok(MixedReport {
        specular,
        mixed,
        selected,
        delta_bic,
        delta_aic,
    })
}
