//! The mixed (radiometric) fit of one target, the brightness check of the default fit
//! (docs/MIXED.md "Brightness known"), and the table of both models' fits.

use std::path::Path;

use polarid_core::FitStatus;
use polarid_core::mixed::{self, MixedCapture, MixedFit, MixedModel, MixedOptions};
use polarid_core::systematic::chi2_sf;
use polarid_io::table::fits::FitRow;
use polarid_io::table::fmt_f64;

use super::errors::{aolp_check, overrides};
use super::{FitConfig, Group, TargetFit, data};
use crate::Result;

/// Below this p-value the brightness contradicts Lambert's cosine law (a specular lobe
/// is seen); at or above it the target shows no specular lobe (docs/MIXED.md).
pub const LAMBERT_P: f64 = 0.001;

/// Fit both radiometric models to one target and select one by BIC.
pub(super) fn fit_target(
    path: &Path,
    g: &Group,
    class: Option<&str>,
    opts: &MixedOptions,
    cfg: &FitConfig,
) -> Result<TargetFit> {
    let caps = captures(path, g, opts)?;
    let rep = fit_and_select(g, &caps, opts, cfg).map_err(|e| {
        data(
            path,
            format!("target {:?} (lines {}): {e}", g.target, g.lines()),
        )
    })?;
    let row = checked_row(g, class, &caps, opts, cfg, rep.best());
    Ok(TargetFit {
        row,
        report: Some(rep),
    })
}

/// Brightness is known for a target when every row carries a positive `s0` and
/// `exposure` (as `polarid measure` writes them) and both zenith angles.
pub(super) fn brightness_known(g: &Group) -> bool {
    g.rows.iter().all(|(_, m)| {
        m.s0.is_some_and(|v| v.is_finite() && v > 0.0)
            && m.exposure.is_some_and(|v| v.is_finite() && v > 0.0)
            && m.theta_i_deg.is_some()
            && m.theta_r_deg.is_some()
    })
}

/// Lambert's cosine law against the brightness: `ln s0_t − ln cos θi_t` constant up to
/// the relative error `eps`; returns `(χ², dof, p)`.
fn lambert(caps: &[MixedCapture], eps: f64) -> (f64, usize, f64) {
    let v: Vec<f64> = caps
        .iter()
        .map(|c| c.s0.ln() - c.theta_i.cos().max(1e-12).ln())
        .collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let chi2 = v.iter().map(|x| ((x - mean) / eps).powi(2)).sum::<f64>();
    let dof = v.len() - 1;
    (chi2, dof, chi2_sf(chi2, dof as f64))
}

/// The brightness check of the default (specular) fit: when brightness is known
/// ([`brightness_known`]), decide whether the target reflects specularly at all before
/// any class is given.
///
/// 1. `s0` follows Lambert's cosine law (p ≥ [`LAMBERT_P`] at the relative error
///    `s0_rel_sd`): no specular lobe, status `depolarized`;
/// 2. else both radiometric models are fitted and compared (BIC, [`fit_and_select`]):
///    the pure specular model selected, the DoLP-only fit `spec` stands unchanged; the
///    mixed model selected, its fit is the row (`model = mixed`, total errors, the AoLP
///    check), `depolarized` when its specular share stays below 0.1 everywhere.
pub(super) fn brightness_check(
    g: &Group,
    class: Option<&str>,
    spec: TargetFit,
    opts: &MixedOptions,
    cfg: &FitConfig,
) -> TargetFit {
    if !cfg.brightness_check || !brightness_known(g) {
        return spec;
    }
    let Ok(caps) = captures(Path::new(""), g, opts) else {
        return spec;
    };
    let (chi2, dof, p) = lambert(&caps, opts.s0_rel_sd);
    if p >= LAMBERT_P {
        let mut row = spec.row;
        row.status = FitStatus::Depolarized;
        row.reason = format!(
            "brightness: s0 follows Lambert's cosine law within {:.1}% (chi2 = {chi2:.1} on {dof} dof, p = {p:.2e}): no specular lobe",
            100.0 * opts.s0_rel_sd
        );
        return TargetFit { row, report: None };
    }
    let Ok(rep) = fit_and_select(g, &caps, opts, cfg) else {
        return spec;
    };
    if rep.selected == MixedModel::Specular {
        return spec;
    }
    let mut row = checked_row(g, class, &caps, opts, cfg, &rep.mixed);
    if row.status == FitStatus::Depolarized {
        row.reason = format!(
            "brightness: the mixed model is selected (delta BIC {:.1}) and {}",
            rep.delta_bic, row.reason
        );
    }
    TargetFit {
        row,
        report: Some(rep),
    }
}

/// Both radiometric models fitted to a target's captures ([`mixed::fit_mixed`], the
/// DoLP weighted by its noise), the model selected with the DoLP errors of noise **and**
/// the independent per-capture part of the bench's systematic error (docs/MIXED.md
/// "Model selection"; docs/ERRORS.md, error model):
///
/// ```text
/// se_sel,t² = dolp_se_t² + f² + P'(β_t)² σ_t²/4
/// ```
///
/// (`f` the DoLP floor, `σ_t` the row's angle uncertainty, `P'` at the specular
/// radiometric fit's `(n, k)`). The noise alone would let the DoLP residuals that the
/// bench's angle errors leave (source positions off by 0.2° left a paint's DoLP residuals
/// at 0.002 rms, twenty times the noise of a 96² region) outweigh a misfit of the brightness:
/// the mixed model, trading a 4σ misfit of `S0` at every capture for a better DoLP
/// curve, would be selected with its roughness at a bound. The selection's criteria
/// (`selected`, `delta_bic`, `delta_aic`, each fit's `aic`, `bic`) are those of the fits
/// under these errors; the fits themselves (and their covariances) stay noise-weighted.
/// Captures without `dolp_se` keep the assumed `dolp_sd` (their error scale is estimated
/// from the residuals).
pub(super) fn fit_and_select(
    g: &Group,
    caps: &[MixedCapture],
    opts: &MixedOptions,
    cfg: &FitConfig,
) -> polarid_core::Result<mixed::MixedReport> {
    let mut rep = mixed::fit_mixed(caps, opts)?;
    let (n, k) = (rep.specular.n, rep.specular.k);
    if !(n.is_finite() && k.is_finite()) {
        return Ok(rep);
    }
    let f2 = cfg.dolp_floor * cfg.dolp_floor;
    let sel_caps: Vec<MixedCapture> = caps
        .iter()
        .zip(&g.rows)
        .map(|(c, (_, m))| {
            let s = m.angle_sd_deg.unwrap_or(cfg.angle_sd_deg).to_radians();
            let a = 0.5 * polarid_core::dop::dop_beta_derivs(n, k, c.beta).dp_dbeta * s;
            let sys2 = f2 + a * a;
            MixedCapture {
                dolp_se: c.dolp_se.map(|se| (se * se + sys2).sqrt()),
                ..*c
            }
        })
        .collect();
    if sel_caps.as_slice() == caps {
        return Ok(rep);
    }
    let sel = mixed::fit_mixed(&sel_caps, opts)?;
    rep.selected = sel.selected;
    rep.delta_bic = sel.delta_bic;
    rep.delta_aic = sel.delta_aic;
    rep.specular.aic = sel.specular.aic;
    rep.specular.bic = sel.specular.bic;
    rep.mixed.aic = sel.mixed.aic;
    rep.mixed.bic = sel.mixed.bic;
    Ok(rep)
}

/// The row of a radiometric fit with its total (noise + systematic) errors and the AoLP
/// check (an `ok` fit failing it becomes `model_mismatch`).
fn checked_row(
    g: &Group,
    class: Option<&str>,
    caps: &[MixedCapture],
    opts: &MixedOptions,
    cfg: &FitConfig,
    f: &MixedFit,
) -> FitRow {
    let mut r = row(g, class, f);
    let angle_sd: Vec<f64> = g
        .rows
        .iter()
        .map(|(_, m)| m.angle_sd_deg.unwrap_or(cfg.angle_sd_deg).to_radians())
        .collect();
    if let Some(c) = mixed::total_nk_cov(
        caps,
        opts,
        f,
        &angle_sd,
        &cfg.polarimetric_at(g.wavelength_nm),
    ) {
        r.n_se_noise = Some(r.n_se);
        r.k_se_noise = Some(r.k_se);
        r.nk_corr_noise = Some(r.nk_corr);
        r.n_se = c.n_se;
        r.k_se = c.k_se;
        r.nk_corr = c.nk_corr;
        // The sample covariance (noise and the layer's variation between plates,
        // docs/ERRORS.md "Same bench").
        let pol = super::errors::sample_polarimetric(
            &cfg.polarimetric_at(g.wavelength_nm),
            super::errors::SAMPLE_LAYER_RATIO,
        );
        if let Some(s) = mixed::total_nk_cov(caps, opts, f, &vec![0.0; angle_sd.len()], &pol)
            && s.n_se.is_finite()
            && s.k_se.is_finite()
        {
            r.n_se_sample = Some(s.n_se);
            r.k_se_sample = Some(s.k_se);
            r.nk_corr_sample = Some(s.nk_corr);
        }
    }
    let (aolp_p, why) = aolp_check(g, cfg);
    r.aolp_p = aolp_p;
    if let Some(why) = why {
        if r.status.is_ok() {
            r.status = FitStatus::ModelMismatch;
            r.reason = why;
        } else if overrides(r.status) || r.status == FitStatus::Depolarized {
            // Diffuse light in this model is unpolarized: it cannot turn the AoLP.
            r.reason = format!("{why} (fit status was {}: {})", r.status.as_str(), r.reason);
            r.status = FitStatus::ModelMismatch;
        }
    }
    r
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
