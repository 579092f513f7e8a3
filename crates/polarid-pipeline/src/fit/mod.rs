//! Measurement table → one `(n, k)` fit per target (paper section 5, eq. 16): the
//! workflow of `polarid fit` and of Python's `polarid.fit_table`.
//!
//! Rows are grouped by `target` (targets keep the order of their first row) and, for
//! multi-band data, by `wavelength_nm` (one fit per target per band, the bands of a
//! target in the order of their first row; a target's rows either all have a wavelength
//! or none has); each (target, band) needs at least 3 usable measurements, and its rows
//! may not disagree on `class`.
//!
//! Partial failure (docs/FORMATS.md): measurement rows whose `status` is not `ok` (dark,
//! no usable pixel) are skipped; a target with fewer than 3 usable rows, or whose data
//! the fit rejects, becomes a row with status `invalid_input` and the reason (`n`, `k`
//! NaN), and the other targets are fitted. Only when no target can be fitted is it an
//! error. [`FitConfig::strict`] restores the error at the first problem. When
//! every row of a target has a `dolp_se`, the fit is weighted by `1/dolp_se²` and the
//! standard errors follow from them; otherwise it is unweighted and the standard errors
//! are scaled by the residual.
//!
//! [`Reflectance::Auto`] (default) is [`Reflectance::Specular`] followed by the
//! brightness check (docs/MIXED.md) when the rows carry `s0` and `exposure`; an
//! explicit [`Reflectance::Specular`] is the paper's DoLP-only fit and nothing else, one [`FitPlan`](polarid_core::fit::FitPlan) per
//! distinct β set ([`PlanCache`]). Rows with a `beta_sd_deg` (regions of calibrated
//! captures, which span a range of β) are fitted with the second-order spread model
//! `P(β̄) + ½ P''(β̄) s_β²` ([`spread`], docs/GEOMETRY.md); a target none of whose rows
//! has a spread is fitted exactly as before. A target whose DoLP stays below
//! [`FitConfig::depolarized_dolp`] at every source position gets the status
//! `depolarized` (see [`polarid_core::mixed::depolarized_reason`]): DoLP alone cannot
//! tell it from a diffuse surface, so it must not be classified.
//!
//! The specular fit's `n_se`, `k_se`, `nk_corr` are the total uncertainty: the noise's
//! plus the systematic errors of the geometry's angles and of the polarimeter's
//! calibration, propagated by the sandwich `Cov_noise + A Σ Aᵀ` ([`errors`],
//! docs/ERRORS.md); the noise's part alone is in `n_se_noise`, `k_se_noise`,
//! `nk_corr_noise`. An `ok` fit whose residuals fail the χ² test against the total
//! covariance, or whose AoLP is not perpendicular to the plane of incidence, at p below
//! [`FitConfig::mismatch_p`], becomes `model_mismatch` with the worst rows as reason.
//!
//! [`Reflectance::Mixed`] fits the radiometric model of `polarid_core::mixed` (specular
//! plus Lambertian diffuse, using `s0`, the exposure-normalised mean S0), selects between
//! it and the pure-specular radiometric model by BIC, and returns the selected fit as the
//! row (with `model`, `sigma`, `rho_d`, and `theta_r_deg` when estimated) and both fits
//! as the target's [`MixedReport`] ([`model_rows`] lays them out as a table).

mod config;
pub mod errors;
mod mixed;
mod plans;
pub mod spread;

use std::collections::HashMap;
use std::path::Path;

use polarid_core::FitStatus;
use polarid_core::fit::FitOptions;
use polarid_core::mixed::MixedReport;
use polarid_io::table::CsvTable;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::{self, Measurement};

pub use config::{
    DEFAULT_ANGLE_SD_DEG, DEFAULT_DOLP_FLOOR, DEFAULT_EXTINCTION_RATIO, DEFAULT_FILM_SD_NM,
    DEFAULT_MISMATCH_P, DEFAULT_RETARDANCE_DEG, DEFAULT_WAVELENGTH_NM, FitConfig, Reflectance,
    check_range, parse_shadowing, range_problem, shadowing_name,
};
pub use errors::ErrorReport;
pub use mixed::{MODEL_COLUMNS, model_rows};
pub use plans::PlanCache;
pub use spread::{fit_with_spread, spread_corrections};

use crate::{PipelineError, Progress, Result, Warning};

/// One fitted target: the fits CSV row and, for the mixed fit, both models.
#[derive(Debug, Clone)]
pub struct TargetFit {
    /// The row of the fits CSV.
    pub row: FitRow,
    /// Both radiometric fits and the selection ([`Reflectance::Mixed`] only).
    pub report: Option<MixedReport>,
}

/// What [`fit`] returns.
#[derive(Debug, Clone)]
pub struct FitOutput {
    /// One per target, in the order of the targets' first rows.
    pub targets: Vec<TargetFit>,
    /// E.g. how many targets have a status other than `ok`.
    pub warnings: Vec<Warning>,
}

impl FitOutput {
    /// The rows of the fits CSV.
    pub fn rows(&self) -> Vec<FitRow> {
        self.targets.iter().map(|t| t.row.clone()).collect()
    }
}

/// Read a measurements CSV (a file, a FIFO, or standard input for `-`) with the line
/// number of each row (for [`fit`]'s messages).
///
/// Errors: those of the CSV readers; a capture-set manifest given instead (TOML with
/// `[[capture]]` or `[[region]]` tables) is a [`PipelineError::Data`] saying so and
/// that `polarid measure` turns it into measurements.
pub fn read_measurements(path: &Path) -> Result<Vec<(u64, Measurement)>> {
    let bytes = polarid_io::limits::read_capped(path, polarid_io::limits::text_cap(), "CSV")?;
    let label = polarid_io::table::input_label(path);
    let parsed = CsvTable::from_reader(&label, bytes.as_slice())
        .and_then(|table| Ok((measurements::from_table(&table)?, table)));
    match parsed {
        Ok((rows, table)) => Ok(table.rows.iter().map(|(line, _)| *line).zip(rows).collect()),
        Err(e) => {
            let text = String::from_utf8_lossy(&bytes);
            if polarid_io::manifest::looks_like_manifest(&text) {
                Err(data(
                    &label,
                    format!(
                        "this is a capture-set manifest, not a measurements table; run \
                         `polarid measure {} -o measurements.csv` first and fit that",
                        label.display()
                    ),
                ))
            } else {
                Err(e.into())
            }
        }
    }
}

/// One target's rows, with their line numbers in the input.
pub(crate) struct Group<'a> {
    pub(crate) target: &'a str,
    /// The band (`None`: single-band data).
    pub(crate) wavelength_nm: Option<f64>,
    pub(crate) rows: Vec<(u64, &'a Measurement)>,
}

impl Group<'_> {
    /// The line numbers, for messages: `12, 13`.
    fn lines(&self) -> String {
        self.rows
            .iter()
            .map(|(l, _)| l.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Group rows by target and band: targets in first-appearance order, then a target's
/// bands in first-appearance order. A target with rows both with and without a
/// `wavelength_nm` is an error naming its first such line.
fn group<'a>(path: &Path, rows: &'a [(u64, Measurement)]) -> Result<Vec<Group<'a>>> {
    let mut targets: Vec<Vec<Group>> = Vec::new();
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (line, m) in rows {
        let ti = *index.entry(m.target.as_str()).or_insert_with(|| {
            targets.push(Vec::new());
            targets.len() - 1
        });
        let bands = &mut targets[ti];
        if let Some(first) = bands.first()
            && first.wavelength_nm.is_some() != m.wavelength_nm.is_some()
        {
            return Err(data(
                path,
                format!(
                    "line {line}: target {:?} has rows with and without wavelength_nm                      (line {} {} one)",
                    m.target,
                    first.rows[0].0,
                    if first.wavelength_nm.is_some() {
                        "has"
                    } else {
                        "has no"
                    }
                ),
            ));
        }
        // Bands are the exact wavelengths written by `measure` (the manifest's values).
        let gi = index_or_push(
            bands,
            |g| g.wavelength_nm == m.wavelength_nm,
            || Group {
                target: m.target.as_str(),
                wavelength_nm: m.wavelength_nm,
                rows: Vec::new(),
            },
        );
        bands[gi].rows.push((*line, m));
    }
    Ok(targets.into_iter().flatten().collect())
}

/// The index of the first item of `v` that is `found`, else of `new()` pushed.
pub(crate) fn index_or_push<T>(
    v: &mut Vec<T>,
    found: impl FnMut(&T) -> bool,
    new: impl FnOnce() -> T,
) -> usize {
    v.iter().position(found).unwrap_or_else(|| {
        v.push(new());
        v.len() - 1
    })
}

/// A [`PipelineError::Data`] about `path`.
fn data(path: &Path, reason: String) -> PipelineError {
    PipelineError::Data {
        path: path.display().to_string(),
        reason,
    }
}

/// The class of a target: the first non-empty `class`; rows may not disagree.
fn class_of<'a>(path: &Path, g: &Group<'a>) -> Result<Option<&'a str>> {
    let mut class: Option<&str> = None;
    for (line, m) in &g.rows {
        if let Some(c) = m.class.as_deref().filter(|c| !c.is_empty()) {
            match class {
                None => class = Some(c),
                Some(prev) if prev != c => {
                    return Err(data(
                        path,
                        format!(
                            "line {line}: target {:?} has class {c:?} but an earlier row says {prev:?}",
                            g.target
                        ),
                    ));
                }
                _ => {}
            }
        }
    }
    Ok(class)
}

/// Fit every target of a set of measurements (each with the line it came from in
/// `path`, for messages; see [`read_measurements`]) with the model of `cfg`.
///
/// Reports `("fitting", done, targets)` to `progress`. Errors name the file, target and
/// lines: no rows, conflicting classes, no target that can be fitted; with
/// [`FitConfig::strict`] also a skipped row, a target with fewer than 3 usable rows,
/// unusable values (and for the mixed fit a missing or non-positive `s0`, missing
/// angles). Without it those become `invalid_input` rows (module docs).
pub fn fit(
    path: &Path,
    rows: &[(u64, Measurement)],
    cfg: &FitConfig,
    progress: Progress,
) -> Result<FitOutput> {
    cfg.validate()?;
    let groups = group(path, rows)?;
    if groups.is_empty() {
        return Err(data(path, "no measurements".into()));
    }
    let total = groups.len() as u64;
    progress("fitting", 0, total);
    let opts = cfg.fit_options();
    let mopts = cfg.mixed_options();
    let mut plans = PlanCache::unbounded();
    let mut out = Vec::with_capacity(groups.len());
    let mut skipped_rows = 0usize;
    let mut first_problem: Option<PipelineError> = None;
    for g in &groups {
        let class = class_of(path, g)?;
        let (usable, skipped): (Vec<_>, Vec<_>) =
            g.rows.iter().partition(|(_, m)| m.status.is_ok());
        skipped_rows += skipped.len();
        let skipped_text = skipped
            .iter()
            .map(|(l, m)| format!("line {l} {}", m.status))
            .collect::<Vec<_>>()
            .join(", ");
        if cfg.strict
            && let Some((line, m)) = skipped.first()
        {
            return Err(data(
                path,
                format!(
                    "line {line}: target {:?}: measurement status {} ({}); without --strict \
                     such rows are skipped",
                    g.target, m.status, m.reason
                ),
            ));
        }
        let ug = Group {
            target: g.target,
            wavelength_nm: g.wavelength_nm,
            rows: usable,
        };
        let attempt = if ug.rows.len() < 3 {
            Err(data(
                path,
                format!(
                    "target {:?}{} has {} {}measurement(s) ({} {}); at least 3 are needed{}",
                    g.target,
                    g.wavelength_nm
                        .map_or(String::new(), |w| format!(" at {w} nm")),
                    ug.rows.len(),
                    if skipped.is_empty() { "" } else { "usable " },
                    if ug.rows.len() == 1 { "line" } else { "lines" },
                    ug.lines(),
                    if skipped.is_empty() {
                        String::new()
                    } else {
                        format!(" (skipped: {skipped_text})")
                    }
                ),
            ))
        } else {
            match cfg.reflectance {
                Reflectance::Mixed => mixed::fit_target(path, &ug, class, &mopts, cfg),
                Reflectance::Specular => specular(path, &ug, class, opts, cfg, &mut plans),
                Reflectance::Auto => specular(path, &ug, class, opts, cfg, &mut plans)
                    .map(|spec| mixed::brightness_check(&ug, class, spec, &mopts, cfg)),
            }
        };
        let mut t = match attempt {
            Ok(t) => t,
            Err(e @ PipelineError::Data { .. }) if !cfg.strict => {
                let t = unfitted(g.target, class, ug.rows.len(), cfg.reflectance, &e);
                first_problem.get_or_insert(e);
                t
            }
            Err(e) => return Err(e),
        };
        t.row.wavelength_nm = g.wavelength_nm;
        mark_ill_conditioned(&mut t.row, cfg);
        out.push(t);
        progress("fitting", out.len() as u64, total);
    }
    if let Some(e) = first_problem
        && out.iter().all(|t| t.row.status == FitStatus::InvalidInput)
    {
        // No target could be fitted: the input as a whole is unusable.
        return Err(e);
    }
    let warnings = fit_warnings(cfg, rows, skipped_rows, &out);
    Ok(FitOutput {
        targets: out,
        warnings,
    })
}

/// The warnings of a fit of `rows` into `out` (`skipped_rows`: rows whose status is not
/// ok): the mixed fit's mean geometry, skipped rows, targets not `ok`.
fn fit_warnings(
    cfg: &FitConfig,
    rows: &[(u64, Measurement)],
    skipped_rows: usize,
    out: &[TargetFit],
) -> Vec<Warning> {
    let mut warnings = Vec::new();
    if cfg.reflectance == Reflectance::Mixed
        && rows
            .iter()
            .any(|(_, m)| m.beta_sd_deg.is_some_and(|s| s > 0.0))
    {
        warnings.push(Warning(
            "the mixed fit uses each row's mean geometry and does not model the spread of \
             beta within a region (beta_sd_deg); the specular fit does"
                .into(),
        ));
    }
    if skipped_rows > 0 {
        warnings.push(Warning(format!(
            "{skipped_rows} measurement row(s) skipped: their status is not ok (dark, or no \
             usable pixel; see the measurements' status and reason columns)"
        )));
    }
    let not_ok = out.iter().filter(|t| !t.row.status.is_ok()).count();
    if not_ok > 0 {
        warnings.push(Warning(format!(
            "{not_ok} of {} target(s) fitted with a status other than ok (see the status and reason columns)",
            out.len()
        )));
    }
    warnings
}

/// The largest standard error of an `ok` estimate, in widths of its search box
/// ([`FitConfig::n_range`], [`FitConfig::k_range`]): an `n_se` above 3 times the width
/// of the `n` box (or a `k_se` above 3 times the `k` box) means the ±1 standard error
/// interval spans six boxes of plausible materials, so the data do not locate the
/// estimate, and the fit is `ill_conditioned` (`mark_ill_conditioned`). With the
/// default boxes (`n` in 0.01..10, `k` in 0..15): `n_se > 29.97` or `k_se > 45`.
///
/// Why so wide: metals are fitted along a ridge of nearly perfectly correlated `(n, k)`
/// whose marginal errors are large while the covariance still locates the material
/// across it; the multi-band acceptance study (docs/BANDS.md) classifies such aluminum
/// estimates with `n_se` up to 21.5 (2.2 box widths, correlation 1.000) correctly. The
/// bound lies above that and removes the estimates that say nothing, such as
/// `5.56 ± 44 + (13.9 ± 25)i` (4.4 widths of the `n` box).
pub const MAX_SE_BOX_FRACTION: f64 = 3.0;

/// Make an `ok` fit whose standard error (`n_se` or `k_se`, total: noise and systematic
/// errors) exceeds [`MAX_SE_BOX_FRACTION`] of its search box `ill_conditioned`, with the
/// reason naming the error and the bound.
fn mark_ill_conditioned(row: &mut FitRow, cfg: &FitConfig) {
    if row.status != FitStatus::Ok {
        return;
    }
    let bound = |(lo, hi): (f64, f64)| MAX_SE_BOX_FRACTION * (hi - lo);
    let (bn, bk) = (bound(cfg.n_range), bound(cfg.k_range));
    let mut why = Vec::new();
    if row.n_se > bn {
        why.push(format!("n_se = {:.3} > {bn}", row.n_se));
    }
    if row.k_se > bk {
        why.push(format!("k_se = {:.3} > {bk}", row.k_se));
    }
    if !why.is_empty() {
        row.status = FitStatus::IllConditioned;
        row.reason = format!(
            "{}: a standard error more than {MAX_SE_BOX_FRACTION} times the width of the \
             search box (n {}..{}, k {}..{}); the data do not locate the estimate \
             (n = {:.3}, k = {:.3})",
            why.join(", "),
            cfg.n_range.0,
            cfg.n_range.1,
            cfg.k_range.0,
            cfg.k_range.1,
            row.n,
            row.k
        );
    }
}

/// The row of a target that could not be fitted: status `invalid_input`, the error's
/// reason, `n`, `k` and their errors NaN.
fn unfitted(
    target: &str,
    class: Option<&str>,
    usable: usize,
    model: Reflectance,
    e: &PipelineError,
) -> TargetFit {
    let reason = match e {
        PipelineError::Data { reason, .. } => reason.clone(),
        other => other.to_string(),
    };
    let nan = f64::NAN;
    TargetFit {
        row: FitRow {
            target: target.to_string(),
            class: class.map(str::to_string),
            n: nan,
            k: nan,
            n_se: nan,
            k_se: nan,
            nk_corr: nan,
            rms_residual: nan,
            measurements: usable as u64,
            status: FitStatus::InvalidInput,
            reason,
            model: match model {
                Reflectance::Mixed => "mixed",
                Reflectance::Auto | Reflectance::Specular => "specular",
            }
            .into(),
            ..FitRow::default()
        },
        report: None,
    }
}

/// The specular (DoLP-only) fit of one target, with the `depolarized` rule.
fn specular(
    path: &Path,
    g: &Group,
    class: Option<&str>,
    opts: FitOptions,
    cfg: &FitConfig,
    plans: &mut PlanCache,
) -> Result<TargetFit> {
    let betas: Vec<f64> = g
        .rows
        .iter()
        .map(|(_, m)| m.beta_deg.to_radians())
        .collect();
    let dolp: Vec<f64> = g.rows.iter().map(|(_, m)| m.dolp).collect();
    let se: Option<Vec<f64>> = g.rows.iter().map(|(_, m)| m.dolp_se).collect();
    let spread: Vec<f64> = g
        .rows
        .iter()
        .map(|(_, m)| m.beta_sd_deg.unwrap_or(0.0).to_radians())
        .collect();
    let plan = plans
        .get(&betas, opts)
        .map_err(|e| data(path, format!("target {:?}: {e}", g.target)))?;
    let (f, corr) = fit_with_spread(&plan, &dolp, se.as_deref(), &spread).map_err(|e| {
        data(
            path,
            format!("target {:?} (lines {}): {e}", g.target, g.lines()),
        )
    })?;
    let (status, reason) =
        match polarid_core::mixed::depolarized_reason(&dolp, cfg.depolarized_dolp) {
            Some(why) if !f.status.is_ok() => (
                FitStatus::Depolarized,
                format!("{why} (fit status was {}: {})", f.status.as_str(), f.reason),
            ),
            Some(why) => (FitStatus::Depolarized, why),
            None => (f.status, f.reason.to_string()),
        };
    let err = errors::assess(g, &f, &corr, cfg);
    let (status, reason) = if status.is_ok() && !err.mismatch.is_empty() {
        (FitStatus::ModelMismatch, err.mismatch.join("; "))
    } else if err.aolp_failed && errors::overrides(status) {
        let why = err.mismatch.join("; ");
        (
            FitStatus::ModelMismatch,
            format!("{why} (fit status was {}: {reason})", status.as_str()),
        )
    } else {
        (status, reason)
    };
    Ok(TargetFit {
        row: FitRow {
            target: g.target.to_string(),
            class: class.map(str::to_string),
            wavelength_nm: g.wavelength_nm,
            n: f.n,
            k: f.k,
            n_se: err.total.0,
            k_se: err.total.1,
            nk_corr: err.total.2,
            rms_residual: f.rms_residual,
            measurements: g.rows.len() as u64,
            status,
            reason,
            model: "specular".into(),
            n_se_noise: Some(f.n_se),
            k_se_noise: Some(f.k_se),
            nk_corr_noise: Some(f.nk_corr),
            gof_p: err.gof_p,
            aolp_p: err.aolp_p,
            n_se_sample: err.sample.map(|c| c.0),
            k_se_sample: err.sample.map(|c| c.1),
            nk_corr_sample: err.sample.map(|c| c.2),
            film: err.film,
            ..FitRow::default()
        },
        report: None,
    })
}
