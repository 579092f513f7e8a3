//! `polarid fit MEASUREMENTS.csv [-o fits.csv] [--reflectance specular|mixed]`:
//! the complex index `(n, k)` of every target from its DoLP measurements (paper
//! section 5, eq. 16), written as the fits CSV of `shared/FORMATS.md`.
//!
//! Rows are grouped by `target` (targets keep the order of their first row); each
//! target needs at least 3 measurements. When every row of a target has a `dolp_se`,
//! the fit is weighted by `1/dolp_se²` and the standard errors follow from them;
//! otherwise it is unweighted and the standard errors are scaled by the residual.
//!
//! `--reflectance specular` (default) is the paper's DoLP-only fit. A target whose DoLP
//! stays below `--depolarized-dolp` (default 0.02) at every source position gets the
//! status `depolarized` (see [`polarid_core::mixed::depolarized_reason`]): DoLP alone
//! cannot tell it from a diffuse surface, so it must not be classified.
//!
//! `--reflectance mixed` fits the radiometric model of `polarid_core::mixed` (specular
//! plus Lambertian diffuse, using `s0`, the exposure-normalised mean S0), selects between
//! it and the pure-specular radiometric model by BIC, and writes the selected fit with
//! `model`, `sigma`, `rho_d` (and `theta_r_deg` with `--estimate-theta-r`). `--models
//! FILE` writes both fits of every target with their information criteria.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use polarid_core::FitStatus;
use polarid_core::fit::{FitBounds, FitOptions, FitPlan};
use polarid_core::mixed::{
    self, DEPOLARIZED_MAX_DOLP, MixedCapture, MixedFit, MixedOptions, MixedReport, Shadowing,
};
use polarid_io::table::fits::{self, FitRow};
use polarid_io::table::measurements::{self, Measurement};
use polarid_io::table::{CsvTable, fmt_f64, write_rows};

use crate::{BadInput, Ctx};

/// Reflectance model of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Reflectance {
    /// Specular Fresnel reflection only (the paper's eq. 9).
    Specular,
    /// Specular plus a Lambertian depolarized diffuse term; uses `s0` too.
    Mixed,
}

/// Shadowing factor of the mixed model's specular term.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ShadowingArg {
    /// None: the paper's eq. (3).
    None,
    /// Smith G1(θi)·G1(θr) of a Beckmann surface (α = √2 σ).
    Smith,
}

/// Arguments of `polarid fit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Measurements CSV (written by `polarid measure`).
    pub measurements: PathBuf,
    /// Output fits CSV (standard output when absent).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Reflectance model.
    #[arg(long, value_enum, default_value = "specular")]
    pub reflectance: Reflectance,
    /// Search box for n, as MIN,MAX.
    #[arg(long, value_name = "MIN,MAX", default_value = "0.01,10", value_parser = parse_range)]
    pub n_range: (f64, f64),
    /// Search box for k, as MIN,MAX (MIN >= 0).
    #[arg(long, value_name = "MIN,MAX", default_value = "0,15", value_parser = parse_range)]
    pub k_range: (f64, f64),
    /// Specular fit: status `depolarized` when the DoLP stays below this at every
    /// source position.
    #[arg(long, value_name = "DOLP", default_value_t = DEPOLARIZED_MAX_DOLP, value_parser = parse_unit)]
    pub depolarized_dolp: f64,
    /// Mixed fit: estimate the camera zenith θr (known: each capture's beta, i.e. the
    /// source-camera angle; in-plane captures only).
    #[arg(long)]
    pub estimate_theta_r: bool,
    /// Mixed fit: shadowing factor of the specular term.
    #[arg(long, value_enum, default_value = "none")]
    pub shadowing: ShadowingArg,
    /// Mixed fit: relative standard deviation of s0 (weight of the intensity residuals).
    #[arg(long, value_name = "FRACTION", default_value_t = 0.02, value_parser = parse_unit)]
    pub s0_rel_sd: f64,
    /// Mixed fit: search range of the roughness sigma, as MIN,MAX.
    #[arg(long, value_name = "MIN,MAX", default_value = "0.02,1", value_parser = parse_range)]
    pub sigma_range: (f64, f64),
    /// Mixed fit: also write both models' fits of every target (CSV) to this file.
    #[arg(long, value_name = "CSV")]
    pub models: Option<PathBuf>,
}

/// Parse a number in (0, 1].
fn parse_unit(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if v > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(format!("need a value in (0, 1], got {v}"))
    }
}

/// How `fit` models the reflection (see [`fit_measurements_with`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitConfig {
    /// Reflectance model.
    pub reflectance: Reflectance,
    /// Options of the mixed fit (its `bounds` are replaced by the [`FitOptions`] box).
    pub mixed: MixedOptions,
    /// Specular fit: the `depolarized` threshold on the largest DoLP.
    pub depolarized_dolp: f64,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            reflectance: Reflectance::Specular,
            mixed: MixedOptions::default(),
            depolarized_dolp: DEPOLARIZED_MAX_DOLP,
        }
    }
}

/// One fitted target: the fits CSV row and, for the mixed fit, both models.
#[derive(Debug, Clone)]
pub struct TargetFit {
    /// The row of the fits CSV.
    pub row: FitRow,
    /// Both radiometric fits and the selection (`--reflectance mixed` only).
    pub report: Option<MixedReport>,
}

/// Parse `MIN,MAX` (finite, MIN >= 0, MIN < MAX).
fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected MIN,MAX, got {s:?}"))?;
    let parse = |t: &str| -> Result<f64, String> {
        let v: f64 = t
            .trim()
            .parse()
            .map_err(|_| format!("{t:?} is not a number"))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{t:?} is not finite"))
        }
    };
    let (lo, hi) = (parse(a)?, parse(b)?);
    if !(lo >= 0.0 && hi > lo) {
        return Err(format!("need 0 <= MIN < MAX, got {lo},{hi}"));
    }
    Ok((lo, hi))
}

/// One target's rows, with their line numbers in the input.
struct Group<'a> {
    target: &'a str,
    rows: Vec<(u64, &'a Measurement)>,
}

/// Fit every target of a set of measurements (each with the line it came from in
/// `path`, for messages): rows grouped by target in first-appearance order, one
/// [`FitPlan`] per distinct β set. Errors (exit status 2) name the file, target and lines.
pub fn fit_measurements(
    path: &Path,
    rows: &[(u64, Measurement)],
    opts: FitOptions,
    ctx: &Ctx,
) -> anyhow::Result<Vec<FitRow>> {
    Ok(
        fit_measurements_with(path, rows, opts, &FitConfig::default(), ctx)?
            .into_iter()
            .map(|t| t.row)
            .collect(),
    )
}

/// [`fit_measurements`] with a choice of reflectance model ([`FitConfig`]): the
/// specular fit (with the `depolarized` rule), or the mixed radiometric fit of
/// `polarid_core::mixed` with model selection. Errors (exit status 2) name the file,
/// target and lines (for the mixed fit: a missing or non-positive `s0`, missing angles).
pub fn fit_measurements_with(
    path: &Path,
    rows: &[(u64, Measurement)],
    opts: FitOptions,
    cfg: &FitConfig,
    ctx: &Ctx,
) -> anyhow::Result<Vec<TargetFit>> {
    // Group by target, first-appearance order.
    let mut groups: Vec<Group> = Vec::new();
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (line, m) in rows {
        let gi = *index.entry(m.target.as_str()).or_insert_with(|| {
            groups.push(Group {
                target: m.target.as_str(),
                rows: Vec::new(),
            });
            groups.len() - 1
        });
        groups[gi].rows.push((*line, m));
    }
    if groups.is_empty() {
        return Err(BadInput(format!("{}: no measurements", path.display())).into());
    }
    // One plan per distinct β set (targets of one capture set share it).
    let mut plans: HashMap<Vec<u64>, FitPlan> = HashMap::new();
    let pb = ctx.progress(groups.len() as u64, "fitting");
    let mut out = Vec::with_capacity(groups.len());
    for g in &groups {
        let lines = || {
            g.rows
                .iter()
                .map(|(l, _)| l.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        if g.rows.len() < 3 {
            return Err(BadInput(format!(
                "{}: target {:?} has {} measurement(s) ({} {}); at least 3 are needed",
                path.display(),
                g.target,
                g.rows.len(),
                if g.rows.len() == 1 { "line" } else { "lines" },
                lines()
            ))
            .into());
        }
        let mut class: Option<&str> = None;
        for (line, m) in &g.rows {
            if let Some(c) = m.class.as_deref().filter(|c| !c.is_empty()) {
                match class {
                    None => class = Some(c),
                    Some(prev) if prev != c => {
                        return Err(BadInput(format!(
                            "{}: line {line}: target {:?} has class {c:?} but an earlier row says {prev:?}",
                            path.display(),
                            g.target
                        ))
                        .into());
                    }
                    _ => {}
                }
            }
        }
        if cfg.reflectance == Reflectance::Mixed {
            let caps = mixed_captures(path, g, cfg)?;
            let mopts = MixedOptions {
                bounds: opts.bounds,
                ..cfg.mixed
            };
            let rep = mixed::fit_mixed(&caps, &mopts).with_context(|| {
                format!(
                    "{}: target {:?} (lines {})",
                    path.display(),
                    g.target,
                    lines()
                )
            })?;
            let row = mixed_row(g, class, rep.best());
            out.push(TargetFit {
                row,
                report: Some(rep),
            });
            pb.inc(1);
            continue;
        }
        let betas: Vec<f64> = g
            .rows
            .iter()
            .map(|(_, m)| m.beta_deg.to_radians())
            .collect();
        let dolp: Vec<f64> = g.rows.iter().map(|(_, m)| m.dolp).collect();
        let se: Option<Vec<f64>> = g.rows.iter().map(|(_, m)| m.dolp_se).collect();
        let key: Vec<u64> = betas.iter().map(|b| b.to_bits()).collect();
        let plan = match plans.entry(key) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => e.insert(
                FitPlan::new(&betas, opts)
                    .with_context(|| format!("{}: target {:?}", path.display(), g.target))?,
            ),
        };
        let f = plan.fit(&dolp, se.as_deref()).with_context(|| {
            format!(
                "{}: target {:?} (lines {})",
                path.display(),
                g.target,
                lines()
            )
        })?;
        let (status, reason) = match mixed::depolarized_reason(&dolp, cfg.depolarized_dolp) {
            Some(why) if !f.status.is_ok() => (
                FitStatus::Depolarized,
                format!("{why} (fit status was {}: {})", f.status.as_str(), f.reason),
            ),
            Some(why) => (FitStatus::Depolarized, why),
            None => (f.status, f.reason.to_string()),
        };
        out.push(TargetFit {
            row: FitRow {
                target: g.target.to_string(),
                class: class.map(str::to_string),
                n: f.n,
                k: f.k,
                n_se: f.n_se,
                k_se: f.k_se,
                nk_corr: f.nk_corr,
                rms_residual: f.rms_residual,
                measurements: g.rows.len() as u64,
                status,
                reason,
                model: "specular".into(),
                sigma: None,
                rho_d: None,
                theta_r_deg: None,
            },
            report: None,
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(out)
}

/// The captures of one target for the mixed fit; every row needs a positive `s0` and
/// (unless θr is estimated) `theta_i_deg` and `theta_r_deg`.
fn mixed_captures(path: &Path, g: &Group, cfg: &FitConfig) -> anyhow::Result<Vec<MixedCapture>> {
    let mut caps = Vec::with_capacity(g.rows.len());
    for (line, m) in &g.rows {
        let bad = |what: String| -> anyhow::Error {
            BadInput(format!(
                "{}: line {line}: target {:?}: {what}",
                path.display(),
                g.target
            ))
            .into()
        };
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
        let (ti, tr) = if cfg.mixed.estimate_theta_r {
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
fn mixed_row(g: &Group, class: Option<&str>, f: &MixedFit) -> FitRow {
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
    }
}

/// Columns of the `--models` CSV (two rows per target: specular, mixed).
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

/// Write the `--models` CSV: both radiometric fits of every target.
pub fn write_models(
    w: &mut dyn std::io::Write,
    path: &Path,
    fits: &[TargetFit],
) -> polarid_io::Result<()> {
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
    write_rows(w, path, &MODEL_COLUMNS, rows)
}

/// Run `polarid fit`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    if args.reflectance != Reflectance::Mixed
        && (args.estimate_theta_r || args.models.is_some() || args.shadowing != ShadowingArg::None)
    {
        return Err(BadInput(
            "--estimate-theta-r, --shadowing and --models need --reflectance mixed".into(),
        )
        .into());
    }
    let path = &args.measurements;
    let table = CsvTable::read(path)?;
    let rows = measurements::from_table(&table)?;
    let rows: Vec<(u64, Measurement)> =
        table.rows.iter().map(|(line, _)| *line).zip(rows).collect();
    let opts = FitOptions {
        bounds: FitBounds {
            n_min: args.n_range.0,
            n_max: args.n_range.1,
            k_min: args.k_range.0,
            k_max: args.k_range.1,
        },
        ..Default::default()
    };
    let cfg = FitConfig {
        reflectance: args.reflectance,
        mixed: MixedOptions {
            estimate_theta_r: args.estimate_theta_r,
            shadowing: match args.shadowing {
                ShadowingArg::None => Shadowing::None,
                ShadowingArg::Smith => Shadowing::SmithBeckmann,
            },
            s0_rel_sd: args.s0_rel_sd,
            sigma_min: args.sigma_range.0.max(1e-3),
            sigma_max: args.sigma_range.1,
            ..MixedOptions::default()
        },
        depolarized_dolp: args.depolarized_dolp,
    };
    let fits = fit_measurements_with(path, &rows, opts, &cfg, ctx)?;
    if let Some(mp) = &args.models {
        if args.output.as_deref() == Some(mp.as_path()) {
            return Err(
                BadInput(format!("--models {} is the same file as -o", mp.display())).into(),
            );
        }
        polarid_io::atomic::check_output(mp, ctx.force, &[path.as_path()])?;
    }
    for t in &fits {
        if let Some(rep) = &t.report {
            ctx.info(format!(
                "{}: selected {} (BIC specular - mixed = {:.2}; rho_d = {:.4})",
                t.row.target,
                rep.selected.as_str(),
                rep.delta_bic,
                rep.mixed.rho_d
            ));
        }
    }
    let out: Vec<FitRow> = fits.iter().map(|t| t.row.clone()).collect();
    let not_ok = out.iter().filter(|r| !r.status.is_ok()).count();
    if not_ok > 0 {
        ctx.info(format!(
            "{not_ok} of {} target(s) fitted with a status other than ok (see the status and reason columns)",
            out.len()
        ));
    }
    let out_path = args.output.clone().unwrap_or_else(|| PathBuf::from("-"));
    ctx.write_output(args.output.as_deref(), &[path.as_path()], |w| {
        fits::write(w, &out_path, &out)
    })?;
    if let Some(mp) = &args.models {
        polarid_io::atomic::write_atomic(mp, ctx.force, |w| write_models(w, mp, &fits))?;
    }
    Ok(())
}
