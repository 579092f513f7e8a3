//! One model fitted to a target's captures ([`fit_model`]): validation, the grid start,
//! a polish from each start, the best minimum, then `finish` (covariance and status).
//! `ρd = 0` is held for [`MixedModel::Specular`]; `θr` is free when it is estimated.

use super::finish::finish;
use super::lm::{Polished, polish};
use super::model::prepare_one;
use super::problem::{Problem, param_box, validate};
use super::start::grid_starts;
use super::{
    K_FLOOR, MixedCapture, MixedFit, MixedModel, MixedOptions, NPAR, P_K, P_RHO, P_THETA_R,
};
use crate::error::{CoreError, Result};

/// Fit one model ([`MixedModel::Specular`]: `ρd = 0` fixed) to a target's captures.
///
/// Errors: fewer than 3 captures, invalid values (DoLP outside `[0, 1]`, `S0 ≤ 0`,
/// angles out of range, `φ ≠ 180°` when estimating `θr`), invalid options.
pub fn fit_model(
    caps: &[MixedCapture],
    opts: &MixedOptions,
    model: MixedModel,
) -> Result<MixedFit> {
    validate(caps, opts)?;
    let (lo, hi) = param_box(caps, opts);
    let mut free = [true; NPAR];
    free[P_RHO] = model == MixedModel::Mixed;
    free[P_THETA_R] = opts.estimate_theta_r;
    let pb = Problem {
        caps: caps.iter().map(|c| prepare_one(c, opts.dolp_sd)).collect(),
        opts,
        free,
        lo,
        hi,
        inv_eps: 1.0 / opts.s0_rel_sd,
    };
    let mut best: Option<Polished> = None;
    let mut iters = 0;
    for x0 in grid_starts(&pb, model, 4) {
        let p = polish(&pb, x0);
        iters += p.iters;
        if best.as_ref().is_none_or(|b| p.cost < b.cost) {
            best = Some(p);
        }
    }
    let Some(mut best) = best else {
        return Err(CoreError::OutOfRange {
            name: "mixed fit",
            value: f64::NAN,
            expected: "a finite cost somewhere in the parameter box",
        });
    };
    if opts.bounds.k_min == 0.0 && best.x[P_K] <= K_FLOOR * 1.0001 {
        best.x[P_K] = 0.0;
    }
    Ok(finish(&pb, caps, model, &best, iters))
}
