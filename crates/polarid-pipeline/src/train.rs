//! Labelled fits → a classification model (the workflow of `polarid train`): one
//! prototype per target with a `class` and fit status `ok` (several per class allowed),
//! each recording the file, line and target it came from. Multi-band fits give one
//! prototype per target per band with its `wavelength_nm` (the bands whose fit is `ok`);
//! the model groups them back by class, file and target (`Model::multi_prototypes`).
//! Each prototype keeps the fit's total covariance and, when the fits have the sample
//! columns, its sample covariance (noise and the surface layer's variation between
//! plates), for estimates from the same bench (docs/CLASSIFY.md).

use std::path::Path;

use polarid_core::classify::check_class_name;
use polarid_io::IoError;
use polarid_io::model::{Model, ModelPrototype, PrototypeSource, cov_matrix};
use polarid_io::table::fits::FitRow;

use crate::classify::estimate_of;
pub use crate::classify::{noise_cov, sample_cov};
use crate::{PipelineError, Result, Warning};

/// What [`train`] returns.
#[derive(Debug, Clone)]
pub struct TrainOutput {
    /// The model.
    pub model: Model,
    /// The labelled rows left out because their status is not `ok`, as
    /// `target (status, line N)`.
    pub skipped: Vec<String>,
    /// One per skipped row: `skipped labelled fit ...: its status is not ok`.
    pub warnings: Vec<Warning>,
}

/// Prototypes from labelled fits (each with its line in `fits_path`; see
/// [`crate::classify::read_fits`]): one per row with a `class` and status `ok`, each
/// recording `file` (the fits file as the model should name it, e.g. relative to the
/// model), the line and the target.
///
/// Errors name `fits_path`: a bad class name (with its line), or nothing to train on.
pub fn train(fits: &[(u64, FitRow)], fits_path: &Path, file: &str) -> Result<TrainOutput> {
    let mut protos = Vec::new();
    let mut unlabelled = 0usize;
    let mut not_ok: Vec<String> = Vec::new();
    for (line, f) in fits {
        let Some(class) = f.class.as_deref() else {
            unlabelled += 1;
            continue;
        };
        check_class_name(class).map_err(|e| IoError::Csv {
            path: fits_path.to_path_buf(),
            line: *line,
            column: "class".into(),
            value: class.into(),
            reason: e.to_string(),
        })?;
        if !f.status.is_ok() {
            not_ok.push(format!("{} ({}, line {line})", f.target, f.status));
            continue;
        }
        let est = estimate_of(f);
        protos.push(ModelPrototype {
            class: class.to_string(),
            wavelength_nm: f.wavelength_nm,
            n: f.n,
            k: f.k,
            covariance: est.cov.as_ref().map(cov_matrix),
            sample_covariance: sample_cov(f).as_ref().map(cov_matrix),
            film_shifts: f.film.map(|h| h.0),
            category: None,
            source: PrototypeSource {
                file: file.to_string(),
                line: *line,
                target: f.target.clone(),
            },
        });
    }
    if protos.is_empty() {
        let mut reason = format!(
            "nothing to train on: no fit has both a class and status `ok` ({} row(s), {} \
             without a class",
            fits.len(),
            unlabelled
        );
        if !not_ok.is_empty() {
            reason.push_str(&format!(", labelled but not ok: {}", not_ok.join(", ")));
        }
        reason.push(')');
        return Err(PipelineError::Data {
            path: fits_path.display().to_string(),
            reason,
        });
    }
    let warnings = not_ok
        .iter()
        .map(|s| Warning(format!("skipped labelled fit {s}: its status is not ok")))
        .collect();
    Ok(TrainOutput {
        model: Model::new(protos),
        skipped: not_ok,
        warnings,
    })
}

/// Error unless every labelled fit (a row with a `class`) has status `ok`: a prototype
/// from a fit that is not `ok` (`ill_conditioned`, `at_bound`, ...) would be trusted by
/// the classifier as if it were. The [`PipelineError::Data`] names `fits_path` and every
/// such row (target, status, line). `polarid train` calls it unless `--allow-not-ok`
/// (then [`train`] skips those rows with a warning).
pub fn refuse_not_ok(fits: &[(u64, FitRow)], fits_path: &Path) -> Result<()> {
    let bad: Vec<String> = fits
        .iter()
        .filter(|(_, f)| f.class.is_some() && !f.status.is_ok())
        .map(|(line, f)| {
            let band = f
                .wavelength_nm
                .map_or(String::new(), |w| format!(" at {w} nm"));
            format!("{}{band} ({}, line {line})", f.target, f.status)
        })
        .collect();
    if bad.is_empty() {
        return Ok(());
    }
    Err(PipelineError::Data {
        path: fits_path.display().to_string(),
        reason: format!(
            "{} labelled fit(s) are not `ok` and cannot be prototypes: {} (refit them, \
             remove their class, or pass --allow-not-ok to train on the others)",
            bad.len(),
            bad.join(", ")
        ),
    })
}

/// The distinct classes of a model, sorted.
pub fn classes(model: &Model) -> Vec<&str> {
    let mut classes: Vec<&str> = model.prototypes.iter().map(|p| p.class.as_str()).collect();
    classes.sort();
    classes.dedup();
    classes
}
