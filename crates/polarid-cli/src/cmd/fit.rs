//! `polarid fit MEASUREMENTS.csv [-o fits.csv] [--reflectance specular|mixed]`:
//! the complex index `(n, k)` of every target from its DoLP measurements (paper
//! section 5, eq. 16), written as the fits CSV of `shared/FORMATS.md`.
//!
//! Rows are grouped by `target` (targets keep the order of their first row); each
//! target needs at least 3 measurements. When every row of a target has a `dolp_se`,
//! the fit is weighted by `1/dolp_se²` and the standard errors follow from them;
//! otherwise it is unweighted and the standard errors are scaled by the residual.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use polarid_core::fit::{FitBounds, FitOptions, FitPlan};
use polarid_io::table::CsvTable;
use polarid_io::table::fits::{self, FitRow};
use polarid_io::table::measurements::{self, Measurement};

use crate::{BadInput, Ctx};

/// Reflectance model of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Reflectance {
    /// Specular Fresnel reflection only (the paper's eq. 9).
    Specular,
    /// Specular plus a depolarized diffuse term (not available yet).
    Mixed,
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
        out.push(FitRow {
            target: g.target.to_string(),
            class: class.map(str::to_string),
            n: f.n,
            k: f.k,
            n_se: f.n_se,
            k_se: f.k_se,
            nk_corr: f.nk_corr,
            rms_residual: f.rms_residual,
            measurements: g.rows.len() as u64,
            status: f.status.as_str().to_string(),
            reason: f.reason.to_string(),
            model: "specular".into(),
            sigma: None,
            rho_d: None,
            theta_r_deg: None,
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(out)
}

/// Run `polarid fit`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    if args.reflectance == Reflectance::Mixed {
        return Err(BadInput(
            "--reflectance mixed is not available yet (use --reflectance specular)".into(),
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
    let out = fit_measurements(path, &rows, opts, ctx)?;
    let not_ok = out.iter().filter(|r| r.status != "ok").count();
    if not_ok > 0 {
        ctx.info(format!(
            "{not_ok} of {} target(s) fitted with a status other than ok (see the status and reason columns)",
            out.len()
        ));
    }
    let out_path = args.output.clone().unwrap_or_else(|| PathBuf::from("-"));
    ctx.write_output(args.output.as_deref(), &[path.as_path()], |w| {
        fits::write(w, &out_path, &out)
    })
}
