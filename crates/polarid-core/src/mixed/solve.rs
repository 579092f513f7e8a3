//! One model fitted to a target's captures ([`fit_model`]): validation, the grid start,
//! a polish from each start, the best minimum, then `finish` (covariance and status).
//! `ρd = 0` is held for [`MixedModel::Specular`]; `θr` is free when it is estimated.

use super::finish::finish;
use super::lm::{Polished, polish};
use super::problem::{Problem, validate};
use super::start::grid_starts;
use super::{K_FLOOR, MixedCapture, MixedFit, MixedModel, MixedOptions, P_K};
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
    let pb = Problem::new(caps, opts, model);
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
