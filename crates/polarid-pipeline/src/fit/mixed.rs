//! The mixed (radiometric) fit of one target, and the table of both models' fits.

use std::path::Path;

use polarid_core::mixed::{self, MixedCapture, MixedFit, MixedOptions};
use polarid_io::table::fits::FitRow;
use polarid_io::table::fmt_f64;

use super::{Group, TargetFit, data};
use crate::Result;

/// Fit both radiometric models to one target and select one by BIC.
pub(super) fn fit_target(
    path: &Path,
    g: &Group,
    class: Option<&str>,
    opts: &MixedOptions,
) -> Result<TargetFit> {
    let caps = captures(path, g, opts)?;
    let rep = mixed::fit_mixed(&caps, opts).map_err(|e| {
        data(
            path,
            format!("target {:?} (lines {}): {e}", g.target, g.lines()),
        )
    })?;
    let row = row(g, class, rep.best());
    Ok(TargetFit {
        row,
        report: Some(rep),
    })
}

/// The captures of one target for the mixed fit; every row needs a positive `s0` and
/// (unless θr is estimated) `theta_i_deg` and `theta_r_deg`.
fn captures(path: &Path, g: &Group, opts: &MixedOptions) -> Result<Vec<MixedCapture>> {
    let mut caps = Vec::with_capacity(g.rows.len());
    for (line, m) in &g.rows {
        let bad = |what: String| data(path, format!("line {line}: target {:?}: {what}", g.target));
        let s0 = match m.s0 {
            Some(v) if v.is_finite() && v > 0.0 => v,
            Some(v) => {
                return Err(bad(format!(
                    "--reflectance mixed needs s0 > 0 (mean S0 divided by the exposure), got {v}"
                )));
            }
            None => {
                return Err(bad(
                    "--reflectance mixed needs column `s0` (mean S0 divided by the exposure), missing"
                        .into(),
                ));
            }
        };
        let phi = m.phi_deg.to_radians();
        let beta = m.beta_deg.to_radians();
        let (ti, tr) = if opts.estimate_theta_r {
            if (m.phi_deg - 180.0).abs() > 1e-6 {
                return Err(bad(format!(
                    "--estimate-theta-r needs in-plane captures (phi_deg = 180), got phi_deg = {}",
                    m.phi_deg
                )));
            }
            (
                m.theta_i_deg.map_or(f64::NAN, f64::to_radians),
                m.theta_r_deg.map_or(f64::NAN, f64::to_radians),
            )
        } else {
            match (m.theta_i_deg, m.theta_r_deg) {
                (Some(a), Some(b)) => (a.to_radians(), b.to_radians()),
                _ => {
                    return Err(bad(
                        "--reflectance mixed needs theta_i_deg and theta_r_deg (or --estimate-theta-r, which needs only beta_deg)"
                            .into(),
                    ));
                }
            }
        };
        caps.push(MixedCapture {
            theta_i: ti,
            theta_r: tr,
            phi,
            beta,
            dolp: m.dolp,
            dolp_se: m.dolp_se,
            s0,
        });
    }
    Ok(caps)
}

/// The fits CSV row of a radiometric fit.
fn row(g: &Group, class: Option<&str>, f: &MixedFit) -> FitRow {
    FitRow {
        target: g.target.to_string(),
        class: class.map(str::to_string),
        n: f.n,
        k: f.k,
        n_se: f.n_se,
        k_se: f.k_se,
        nk_corr: f.nk_corr,
        rms_residual: f.rms_dolp,
        measurements: g.rows.len() as u64,
        status: f.status,
        reason: f.reason.clone(),
        model: f.model.as_str().to_string(),
        sigma: Some(f.sigma),
        rho_d: Some(f.rho_d),
        theta_r_deg: f.theta_r_estimated.then(|| f.theta_r.to_degrees()),
        // The error model (docs/ERRORS.md) is that of the specular fit only.
        ..Default::default()
    }
}

/// Columns of the models table ([`model_rows`]; `polarid fit --models`).
pub const MODEL_COLUMNS: [&str; 27] = [
    "target",
    "model",
    "selected",
    "n",
    "k",
    "n_se",
    "k_se",
    "nk_corr",
    "sigma",
    "sigma_se",
    "rho_d",
    "rho_d_se",
    "scale",
    "scale_rel_se",
    "theta_r_deg",
    "theta_r_se_deg",
    "chi2",
    "dof",
    "aic",
    "bic",
    "delta_bic",
    "rms_dolp",
    "rms_s0_rel",
    "specular_share_min",
    "specular_share_max",
    "status",
    "reason",
];

/// Both radiometric fits of every target of a mixed fit, as text cells in the order of
/// [`MODEL_COLUMNS`] (two rows per target: specular, mixed; targets without a report
/// are left out).
pub fn model_rows(fits: &[TargetFit]) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    for t in fits {
        let Some(rep) = &t.report else { continue };
        for f in [&rep.specular, &rep.mixed] {
            rows.push(vec![
                t.row.target.clone(),
                f.model.as_str().to_string(),
                (f.model == rep.selected).to_string(),
                fmt_f64(f.n),
                fmt_f64(f.k),
                fmt_f64(f.n_se),
                fmt_f64(f.k_se),
                fmt_f64(f.nk_corr),
                fmt_f64(f.sigma),
                fmt_f64(f.sigma_se),
                fmt_f64(f.rho_d),
                fmt_f64(f.rho_d_se),
                fmt_f64(f.scale),
                fmt_f64(f.scale_rel_se),
                fmt_f64(f.theta_r.to_degrees()),
                fmt_f64(f.theta_r_se.to_degrees()),
                fmt_f64(f.chi2),
                f.dof.to_string(),
                fmt_f64(f.aic),
                fmt_f64(f.bic),
                fmt_f64(rep.delta_bic),
                fmt_f64(f.rms_dolp),
                fmt_f64(f.rms_s0_rel),
                fmt_f64(f.specular_share_min),
                fmt_f64(f.specular_share_max),
                f.status.as_str().to_string(),
                f.reason.clone(),
            ]);
        }
    }
    rows
}
