//! The steps both demos run from their simulated captures, as the commands would, each
//! writing its file into the staging directory and the next step re-reading it:
//! measure → fit ([`measure_and_fit`]), then train → classify ([`train_and_classify`]).

use std::path::Path;

use polarid_core::classify::{Bench, Classifier, ClassifierConfig, DEFAULT_CONFIDENCE};
use polarid_io::atomic::StagedDir;
use polarid_io::manifest::{self, Manifest};
use polarid_io::model::Model;
use polarid_io::scene::Scene;
use polarid_io::table::classification::{self, ClassificationRow};
use polarid_io::table::fits::{self, FitRow};
use polarid_io::table::measurements::{self, Measurement};

use super::stage;
use crate::classify::{
    Comparison, classification_row, estimate_for, explain, read_fits, same_bench,
};
use crate::fit::{FitConfig, fit, read_measurements};
use crate::measure::measure;
use crate::progress::{Progress, Warning};
use crate::train::train;
use crate::{PipelineError, Result};

/// What [`measure_and_fit`] read and wrote.
pub(super) struct Fitted {
    /// The manifests, as loaded from the staging directory.
    pub manifests: Vec<Manifest>,
    /// The measurements as re-read from `measurements.csv` (with their line numbers).
    pub measurements: Vec<(u64, Measurement)>,
    /// The fits as re-read from `fits.csv` (with their line numbers).
    pub fits: Vec<(u64, FitRow)>,
}

/// Measure every staged manifest (`polarid measure`) into `measurements.csv`, fit that
/// file as `polarid fit` reads it into `fits.csv`, and re-read the fits. The
/// measurement warnings are appended to `warnings`.
pub(super) fn measure_and_fit(
    staged: &StagedDir,
    manifests: &[String],
    progress: Progress,
    warnings: &mut Vec<Warning>,
) -> Result<Fitted> {
    let mut rows: Vec<Measurement> = Vec::new();
    let mut loaded = Vec::new();
    for m in manifests {
        let man = manifest::load(&staged.path(m)?)?;
        let got = measure(&man, progress)?;
        warnings.extend(got.warnings);
        rows.extend(got.rows);
        loaded.push(man);
    }
    let (measurements, fits) = fit_staged(staged, &rows, progress)?;
    Ok(Fitted {
        manifests: loaded,
        measurements,
        fits,
    })
}

/// Write `rows` to `measurements.csv`, fit that file as `polarid fit` reads it (default
/// settings) into `fits.csv`, and re-read both: the measurements and the fits with
/// their line numbers.
pub(super) fn fit_staged(
    staged: &StagedDir,
    rows: &[Measurement],
    progress: Progress,
) -> Result<(Vec<(u64, Measurement)>, Vec<(u64, FitRow)>)> {
    let meas_path = stage(staged, "measurements.csv", |w| {
        measurements::write(w, Path::new("measurements.csv"), rows)
    })?;
    let meas = read_measurements(&meas_path)?;
    let fit_rows = fit(
        Path::new("measurements.csv"),
        &meas,
        &FitConfig::default(),
        progress,
    )?
    .rows();
    let fits_path = stage(staged, "fits.csv", |w| {
        fits::write(w, Path::new("fits.csv"), &fit_rows)
    })?;
    Ok((meas, read_fits(&fits_path)?))
}

/// Train a model on `training` (`polarid train`) into `model.json`; the training
/// warnings are appended to `warnings`.
pub(super) fn train_staged(
    staged: &StagedDir,
    training: &[(u64, FitRow)],
    warnings: &mut Vec<Warning>,
) -> Result<Model> {
    let trained = train(training, Path::new("fits.csv"), "fits.csv")?;
    warnings.extend(trained.warnings);
    let model = trained.model;
    stage(staged, "model.json", |w| {
        model.write(w, Path::new("model.json"))
    })?;
    Ok(model)
}

/// Parse the demo scene `text` (at `path`; an internal error when it is invalid).
pub(super) fn parse_scene(path: &Path, text: &str) -> Result<Scene> {
    polarid_io::scene::parse(path, text).map_err(|e| PipelineError::Data {
        path: path.display().to_string(),
        reason: format!(
            "internal error: a demo scene is invalid: {}",
            polarid_io::error::chain_message(&e)
        ),
    })
}

/// What [`train_and_classify`] produced.
pub(super) struct Classified {
    /// The model trained on the training fits.
    pub model: Model,
    /// The test fits' classification rows.
    pub rows: Vec<ClassificationRow>,
    /// One explanation per test fit (nearest prototypes and distances).
    pub notes: Vec<String>,
}

/// Train a model on `training` (`polarid train`) into `model.json`, classify `tests`
/// with it (`polarid classify`, default settings: the set rule at 95%, the model from
/// the same bench) into `classification.csv`. The training warnings are appended to
/// `warnings`.
pub(super) fn train_and_classify(
    staged: &StagedDir,
    training: &[(u64, FitRow)],
    tests: &[(u64, FitRow)],
    warnings: &mut Vec<Warning>,
) -> Result<Classified> {
    let model = train_staged(staged, training, warnings)?;
    let clf = same_bench_classifier(&model)?;
    let cmp = Comparison {
        bench: Bench::Same,
        same: model.has_sample_covariances(),
    };
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    for (_, f) in tests {
        let est = estimate_for(f, cmp);
        let d = clf.classify(&est);
        notes.push(explain(&f.target, &est, &d, &clf, 3));
        rows.push(classification_row(f, &d, &clf));
    }
    stage_classification(staged, "classification.csv", &rows)?;
    Ok(Classified { model, rows, notes })
}

/// Write classification `rows` to the staged file `name`.
pub(super) fn stage_classification(
    staged: &StagedDir,
    name: &str,
    rows: &[ClassificationRow],
) -> Result<()> {
    stage(staged, name, |w| {
        classification::write(w, Path::new(name), rows)
    })?;
    Ok(())
}

/// The classifier `polarid classify --model` uses by default: the set rule at 95% over
/// the model's prototypes with their same-bench (sample) covariances.
pub fn same_bench_classifier(model: &Model) -> Result<Classifier> {
    Classifier::multi(
        same_bench(model).0,
        ClassifierConfig::set(DEFAULT_CONFIDENCE),
    )
    .map_err(|e| PipelineError::Data {
        path: "model.json".into(),
        reason: format!("cannot use the trained model: {e}"),
    })
}
