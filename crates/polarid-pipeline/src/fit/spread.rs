//! The specular fit of rows whose region spans a range of β (calibrated geometry,
//! `beta_sd_deg`; docs/GEOMETRY.md).
//!
//! A calibrated region's DoLP is the brightness-weighted mean of eq. (9) over its pixels,
//! `E_w[P(β)]`, and its `beta_deg` is the weighted mean `β̄`, so (Taylor about `β̄`, whose
//! first-order term vanishes)
//!
//! ```text
//! E_w[P(β)] ≈ P(β̄) + ½ P''(β̄; n, k) s_β²
//! ```
//!
//! with `s_β` the row's `beta_sd_deg`. The core fit models `P(β̄)` only, so the spread
//! term is handled by a fixed point: fit, subtract `c_t = ½ P''(β̄_t; n̂, k̂) s_t²`
//! ([`polarid_core::dop::dop_beta_derivs`]) from the measured DoLP, refit, until the
//! corrections change by less than [`SPREAD_TOLERANCE`] (at most [`SPREAD_ITERATIONS`]
//! refits; the correction depends on `(n, k)` only through `P''`, so one or two refits
//! settle it). The fixed point solves the normal equations of the full model up to the
//! term `Σ w r ∂c/∂(n, k)`, which is a product of two small numbers (residuals and the
//! sensitivity of an already small correction); its standard errors are those of the
//! last fit. Corrected values are clamped to `[0, 1]`.
//!
//! Rows without `beta_sd_deg` (or with 0) need no correction: when no row of a target
//! has a spread, the fit is the plain one, bit for bit.

use polarid_core::dop::dop_beta_derivs;
use polarid_core::fit::{FitPlan, NkFit};

use polarid_core::CoreError;

/// Most refits of the fixed point.
pub const SPREAD_ITERATIONS: usize = 4;

/// The fixed point stops when no correction changes by more than this (DoLP units).
pub const SPREAD_TOLERANCE: f64 = 1e-9;

/// The spread corrections `½ P''(β_t; n, k) s_t²` of eq. (9) at `betas` with spreads
/// `beta_sd` (both radians).
pub fn spread_corrections(n: f64, k: f64, betas: &[f64], beta_sd: &[f64]) -> Vec<f64> {
    betas
        .iter()
        .zip(beta_sd)
        .map(|(&b, &s)| {
            if s == 0.0 {
                0.0
            } else {
                0.5 * dop_beta_derivs(n, k, b).d2p_dbeta2 * s * s
            }
        })
        .collect()
}

/// Fit `dolp` measured over regions with weighted mean β `plan.betas()` and weighted SD
/// `beta_sd` (radians, one per row) with the second-order spread model (module docs).
/// Returns the fit and the corrections subtracted from `dolp` (all zero, and the plain
/// [`FitPlan::fit`], when every spread is 0).
///
/// Errors: those of [`FitPlan::fit`].
pub fn fit_with_spread(
    plan: &FitPlan,
    dolp: &[f64],
    dolp_se: Option<&[f64]>,
    beta_sd: &[f64],
) -> Result<(NkFit, Vec<f64>), CoreError> {
    let mut f = plan.fit(dolp, dolp_se)?;
    let mut corr = vec![0.0; dolp.len()];
    if beta_sd.iter().all(|&s| s == 0.0) {
        return Ok((f, corr));
    }
    let mut corrected = dolp.to_vec();
    for _ in 0..SPREAD_ITERATIONS {
        if !(f.n.is_finite() && f.k.is_finite()) {
            break;
        }
        let next = spread_corrections(f.n, f.k, plan.betas(), beta_sd);
        let change = next
            .iter()
            .zip(&corr)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        corr = next;
        if change <= SPREAD_TOLERANCE {
            break;
        }
        for ((c, d), k) in corrected.iter_mut().zip(dolp).zip(&corr) {
            *c = (d - k).clamp(0.0, 1.0);
        }
        f = plan.fit(&corrected, dolp_se)?;
    }
    Ok((f, corr))
}

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_core::dop::dop;
    use polarid_core::fit::FitOptions;

    #[test]
    fn recovers_nk_from_spread_means_and_is_plain_without_spread() {
        let (n, k) = (1.38, 1.92);
        let betas: Vec<f64> = [30.0f64, 40.0, 50.0, 60.0, 70.0]
            .iter()
            .map(|d| d.to_radians())
            .collect();
        let sd: Vec<f64> = [2.5f64, 2.0, 1.5, 3.0, 1.0]
            .iter()
            .map(|d| d.to_radians())
            .collect();
        // Exact means over symmetric three-point distributions of β with those SDs.
        let dolp: Vec<f64> = betas
            .iter()
            .zip(&sd)
            .map(|(&b, &s)| {
                let h = s * 1.5f64.sqrt();
                (dop(n, k, b - h) + dop(n, k, b) + dop(n, k, b + h)) / 3.0
            })
            .collect();
        let plan = FitPlan::new(&betas, FitOptions::default()).unwrap();
        let plain = plan.fit(&dolp, None).unwrap();
        let (f, corr) = fit_with_spread(&plan, &dolp, None, &sd).unwrap();
        assert!(corr.iter().any(|c| c.abs() > 1e-4), "{corr:?}");
        // The fourth-order remainder is ~1e-6 in DoLP here.
        assert!(
            (f.n - n).abs() < 2e-3 && (f.k - k).abs() < 2e-3,
            "{f:?} (plain {plain:?})"
        );
        assert!(
            (plain.n - n).abs() > 10.0 * (f.n - n).abs(),
            "plain {plain:?}"
        );
        let zero = vec![0.0; betas.len()];
        let (g, c0) = fit_with_spread(&plan, &dolp, None, &zero).unwrap();
        assert_eq!(g, plain);
        assert!(c0.iter().all(|&c| c == 0.0));
    }
}
