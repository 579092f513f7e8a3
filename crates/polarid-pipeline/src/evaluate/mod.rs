//! Leave-one-out evaluation of the classifier over a labelled set of fits (or, with a
//! model, evaluation of the model on a labelled test set): the workflow of
//! `polarid evaluate`, with Wolff's metal/dielectric baseline next to it.
//!
//! # Wolff's baseline
//!
//! The paper's comparison: the (n, k) classifier tells materials apart *within* a category
//! (aluminum from copper), Wolff's Fresnel-ratio rule only metal from dielectric. With
//! [`EvaluateConfig::wolff`], the same evaluated targets (labelled, fit status `ok`) are
//! also classified by Wolff's rule from their DoLP measurements, and its
//! metal/dielectric confusion matrix and accuracy are reported next to the
//! classifier's, together with the classifier's own accuracy on those targets by
//! material and by metal/dielectric.
//!
//! The true category of a label is, first match wins:
//!
//! 1. [`WolffEvalRequest::categories`] (`--wolff-category CLASS=CATEGORY`);
//! 2. with a model, the `category` of the model's prototypes of that class;
//! 3. the `category` of the material of that name in [`WolffEvalRequest::library`]
//!    (`builtin` by default, `paper2007`, or a library CSV `name,n,k,category`): the
//!    library is where categories are curated (a model trained by `polarid train` has
//!    none).
//!
//! Names match ignoring case, with spaces and underscores equivalent (`green paint` is
//! `green_paint`). Only targets whose category is `metal` or `dielectric` are scored; the
//! others (`semiconductor`, `other`, or no category) are listed as not scored. Wolff's
//! `unknown` (no measurement in the β window) counts as wrong.

mod wolff;

use std::path::{Path, PathBuf};

use polarid_core::classify::{
    Classifier, ClassifierConfig, Evaluation, Labelled, evaluate as core_evaluate, leave_one_out,
};
use polarid_io::model::Model;
use polarid_io::table::fits::FitRow;

pub use wolff::{CATEGORIES, WolffEval, WolffItem, ratio};

use crate::classify::{WolffSettings, check_classifier, group_fits, multi_estimate_of};
use crate::error::ensure;
use crate::{PipelineError, Result, Warning};

/// Wolff's baseline as requested for an evaluation.
#[derive(Debug, Clone)]
pub struct WolffEvalRequest {
    /// The measurements CSV (the one given to `polarid fit`).
    pub measurements: PathBuf,
    /// The rule's settings.
    pub settings: WolffSettings,
    /// Library giving each class's true category (`builtin`, `paper2007` or a CSV).
    pub library: String,
    /// `(class, category)` given by the user, before the model's and the library's;
    /// category one of [`CATEGORIES`].
    pub categories: Vec<(String, String)>,
}

/// Settings of [`evaluate`]. The default is the set rule at 95% confidence (as for
/// `classify`), no Wolff baseline.
#[derive(Debug, Clone)]
pub struct EvaluateConfig {
    /// The classifier (rule, confidence, metric, neighbours, reject option).
    pub classifier: ClassifierConfig,
    /// Also score Wolff's metal/dielectric baseline.
    pub wolff: Option<WolffEvalRequest>,
}

impl Default for EvaluateConfig {
    fn default() -> Self {
        Self {
            classifier: ClassifierConfig::set(polarid_core::classify::DEFAULT_CONFIDENCE),
            wolff: None,
        }
    }
}

impl EvaluateConfig {
    /// Check every value ([`PipelineError::Config`] naming it).
    pub fn validate(&self) -> Result<()> {
        check_classifier(&self.classifier)?;
        if let Some(w) = &self.wolff {
            w.settings.validate()?;
            let why = format!(
                "expected CLASS=CATEGORY with CATEGORY one of {}",
                CATEGORIES.join(", ")
            );
            for (class, cat) in &w.categories {
                let ok = !class.trim().is_empty() && CATEGORIES.contains(&cat.as_str());
                ensure(ok, "wolff_category", format!("{class}={cat}"), &why)?;
            }
        }
        Ok(())
    }
}

/// What [`evaluate`] returns.
#[derive(Debug, Clone)]
pub struct EvaluateOutput {
    /// Confusion matrix, accuracy, decisions, skipped and unrepresented classes.
    pub evaluation: Evaluation,
    /// `leave-one-out` or `model PATH`.
    pub mode: String,
    /// Wolff's baseline, when requested.
    pub wolff: Option<WolffEval>,
    /// E.g. classes without a prototype, targets without measurements for Wolff's rule.
    pub warnings: Vec<Warning>,
}

/// Evaluate the classifier on the labelled fits (each with its line in `fits_path`):
/// leave-one-out, or the model at `model` when given.
///
/// Errors: no labelled fit, no labelled fit with status `ok`, too few for leave-one-out,
/// unreadable files, bad Wolff input (naming the file and target).
pub fn evaluate(
    fits_path: &Path,
    fits: &[(u64, FitRow)],
    model: Option<&Path>,
    cfg: &EvaluateConfig,
) -> Result<EvaluateOutput> {
    cfg.validate()?;
    let data = |reason: String| PipelineError::Data {
        path: fits_path.display().to_string(),
        reason,
    };
    // One item per target: a multi-band target's rows together (group_fits).
    let items: Vec<Labelled> = group_fits(fits)
        .into_iter()
        .filter_map(|g| {
            // ok: group_fits returns non-empty groups of indices into `fits`.
            let (line, f) = &fits[g[0]];
            let source = if g.len() > 1 {
                format!("{} target {}", fits_path.display(), f.target)
            } else {
                format!("{}:{line} target {}", fits_path.display(), f.target)
            };
            f.class.as_ref().map(|c| Labelled {
                target: f.target.clone(),
                class: c.clone(),
                estimate: multi_estimate_of(g.iter().map(|&i| &fits[i].1)),
                source,
            })
        })
        .collect();
    if items.is_empty() {
        return Err(data(format!(
            "no labelled fits (the `class` column is missing or empty in all {} row(s))",
            fits.len()
        )));
    }
    let model = model
        .map(|m| Model::read(m).map(|model| (m, model.prototypes(), model.multi_prototypes())))
        .transpose()?;
    let (evaluation, mode) = match &model {
        Some((m, _, multi)) => {
            let clf = Classifier::multi(multi.clone(), cfg.classifier)?;
            (
                core_evaluate(&clf, &items).map_err(|e| data(e.to_string()))?,
                format!("model {}", m.display()),
            )
        }
        None => (
            leave_one_out(&items, cfg.classifier).map_err(|e| data(e.to_string()))?,
            "leave-one-out".to_string(),
        ),
    };
    if evaluation.items.is_empty() {
        return Err(data(
            "no labelled fit has status `ok`; nothing to evaluate".into(),
        ));
    }
    let wolff = cfg
        .wolff
        .as_ref()
        .map(|w| {
            wolff::score(
                w,
                &evaluation,
                model.as_ref().map(|(m, p, _)| (*m, p.as_slice())),
            )
        })
        .transpose()?;
    let mut warnings: Vec<Warning> = evaluation
        .unrepresented
        .iter()
        .map(|u| {
            Warning(format!(
                "class `{u}` has no prototype to be compared with; its targets cannot be \
                 classified correctly"
            ))
        })
        .collect();
    if let Some(w) = &wolff {
        warnings.extend(w.no_rows.iter().map(|t| {
            Warning(format!(
                "wolff: target {t} has no row in {}; Wolff answers unknown",
                w.measurements.display()
            ))
        }));
    }
    Ok(EvaluateOutput {
        evaluation,
        mode,
        wolff,
        warnings,
    })
}
