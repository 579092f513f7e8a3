//! Fits → decisions against a trained model or a material library (paper section 6): the
//! workflow of `polarid classify`, optionally with Wolff's metal/dielectric baseline
//! computed from the measurements.
//!
//! Multi-band fits (rows with `wavelength_nm`, one per target per band) are classified
//! per target on all its bands at once ([`group_fits`], [`multi_estimate_of`],
//! `polarid_core::classify::bands`); the row says which bands were compared
//! (`bands_used`).

pub(crate) mod bench;
mod explain;
pub mod reference;
pub mod rows;
mod wolff;

use std::path::{Path, PathBuf};

use polarid_core::classify::{
    Classifier, ClassifierConfig, Cov2, Decision, Estimate, EstimateBand, MultiEstimate,
    MultiPrototype, Prototype, Rule,
};
use polarid_io::library::Library;
use polarid_io::model::Model;
use polarid_io::table::CsvTable;
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::{self, FitRow};

pub use bench::{
    Comparison, estimate_for, multi_estimate_for, noise_cov, prototypes_for, same_bench, sample_cov,
};
pub use explain::{
    ConfidenceRegion, DecisionRegion, RegionPlane, confidence_region, decision_regions, explain,
    regions_text,
};
pub use wolff::{WolffData, WolffSettings};

use crate::error::ensure;
use crate::{PipelineError, Result, Warning};

/// The estimate of a fit row: covariance from `n_se`, `k_se`, `nk_corr` when usable (a
/// NaN correlation counts as 0).
pub fn estimate_of(f: &FitRow) -> Estimate {
    let corr = if f.nk_corr.is_nan() { 0.0 } else { f.nk_corr };
    Estimate {
        n: f.n,
        k: f.k,
        cov: Cov2::from_se(f.n_se, f.k_se, corr),
        fit_status: f.status,
    }
}

/// The fit rows of each target, as indices into `fits`: rows with a `wavelength_nm` are
/// grouped by target (targets in first-appearance order, bands in file order); a row
/// without a wavelength is a target of its own (single-band files: one group per row).
pub fn group_fits(fits: &[(u64, FitRow)]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, (_, f)) in fits.iter().enumerate() {
        let same = f.wavelength_nm.is_some().then(|| {
            groups.iter().position(|g| {
                let first = &fits[g[0]].1;
                first.wavelength_nm.is_some() && first.target == f.target
            })
        });
        match same.flatten() {
            Some(g) => groups[g].push(i),
            None => groups.push(vec![i]),
        }
    }
    groups
}

/// The estimate of a target's fit rows (one per band; see [`estimate_of`]).
pub fn multi_estimate_of<'a>(rows: impl IntoIterator<Item = &'a FitRow>) -> MultiEstimate {
    MultiEstimate {
        bands: rows
            .into_iter()
            .map(|f| EstimateBand {
                wavelength_nm: f.wavelength_nm,
                estimate: estimate_of(f),
                film: f.film,
            })
            .collect(),
    }
}

/// Read a fits CSV with the line number of each row.
pub fn read_fits(path: &Path) -> Result<Vec<(u64, FitRow)>> {
    let t = CsvTable::read(path)?;
    let rows = fits::from_table(&t)?;
    Ok(t.rows.iter().map(|r| r.0).zip(rows).collect())
}

/// Where the prototypes come from.
#[derive(Debug, Clone)]
pub enum PrototypeSource {
    /// A model JSON written by `polarid train`.
    Model(PathBuf),
    /// A library: `builtin`, `paper2007` or a library CSV (see `polarid_io::library`).
    Library(String),
    /// Prototypes given directly, with a label for messages (e.g. `the prototypes`).
    List(Vec<Prototype>, String),
}

impl PrototypeSource {
    /// A catalogue shipped with polarid (`builtin`, `builtin-rgb`, `paper2007`): an open
    /// world, where a transparent material alone is an index, not a name
    /// ([`polarid_core::classify::Decision::open_world`]). A library CSV or a model is the
    /// user's own list of what the scene holds.
    pub fn is_catalogue(&self) -> bool {
        matches!(self, PrototypeSource::Library(s) if polarid_io::library::BUILTIN_NAMES.contains(&s.as_str()))
    }

    /// The single-band prototypes and a label for messages (`model PATH`, `library
    /// SPEC`). A multi-band model or library (with `wavelength_nm`) is an error naming it:
    /// its bands are not separate prototypes; use [`PrototypeSource::load_multi`].
    pub fn load(&self) -> Result<(Vec<Prototype>, String)> {
        let (protos, label, bands) = match self {
            PrototypeSource::Model(m) => {
                let model = Model::read(m)?;
                let bands = model.prototypes.iter().any(|p| p.wavelength_nm.is_some());
                (model.prototypes(), format!("model {}", m.display()), bands)
            }
            PrototypeSource::Library(spec) => {
                let lib = Library::load(spec)?;
                let bands = lib.materials.iter().any(|m| m.wavelength_nm.is_some());
                (lib.prototypes(), format!("library {spec}"), bands)
            }
            PrototypeSource::List(p, label) => return Ok((p.clone(), label.clone())),
        };
        if bands {
            return Err(PipelineError::Data {
                path: format!("cannot use {label}"),
                reason: "it has several bands (wavelength_nm); classify multi-band fits against \
                         it (polarid classify), or use a single-band model or library here"
                    .into(),
            });
        }
        Ok((protos, label))
    }

    /// The prototypes with all their bands (a multi-band model or library) and a label
    /// for messages.
    pub fn load_multi(&self) -> Result<(Vec<MultiPrototype>, String)> {
        Ok(match self {
            PrototypeSource::Model(m) => (
                Model::read(m)?.multi_prototypes(),
                format!("model {}", m.display()),
            ),
            PrototypeSource::Library(spec) => (
                Library::load(spec)?.multi_prototypes(),
                format!("library {spec}"),
            ),
            PrototypeSource::List(p, label) => (
                p.iter().cloned().map(MultiPrototype::from).collect(),
                label.clone(),
            ),
        })
    }
}

impl PrototypeSource {
    /// The prototypes for fits at `wavelengths` (nm; empty: no fit row has one), with a
    /// label and warnings (docs/CLASSIFY.md "Wavelength"):
    ///
    /// - a built-in library (`builtin`, `builtin-rgb`) is evaluated at the fits'
    ///   wavelengths ([`Library::at_wavelengths`]): its own band where a wavelength is one
    ///   (650 nm for `builtin`), else each material's index at that wavelength from its
    ///   refractiveindex.info data; materials whose data do not cover a wavelength are left
    ///   out there, with a warning naming them;
    /// - fits without a wavelength (`without` of them) against `builtin` are compared
    ///   with its 650 nm values, with a warning saying so;
    /// - a library or model without `wavelength_nm` compared with fits that have one is
    ///   used as it is, with a warning (its wavelength is unknown).
    pub fn load_multi_for(
        &self,
        wavelengths: &[f64],
        without: usize,
    ) -> Result<(Vec<MultiPrototype>, String, Vec<Warning>)> {
        let mut warnings = Vec::new();
        let list = |w: &[f64]| {
            w.iter()
                .map(|x| format!("{x}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        if let PrototypeSource::Library(spec) = self
            && Library::is_dispersive_builtin(spec)
        {
            let lib = Library::load(spec)?;
            let label = format!("library {spec}");
            if without > 0 && spec == "builtin" {
                warnings.push(Warning(format!(
                    "{without} fit row(s) carry no wavelength_nm: compared with the built-in \
                     library's 650 nm values (means over 610-690 nm); if the data were taken \
                     at another wavelength give wavelength_nm in the measurements (or \
                     classify --wavelength-nm), and the materials are evaluated there"
                )));
            }
            if wavelengths.is_empty() {
                return Ok((lib.multi_prototypes(), label, warnings));
            }
            let (at, uncovered) = lib.at_wavelengths(wavelengths)?;
            let own: Vec<f64> = lib
                .materials
                .iter()
                .filter_map(|m| {
                    m.wavelength_nm.or_else(|| {
                        (lib.source == "builtin")
                            .then_some(polarid_io::library::BUILTIN_WAVELENGTH_NM)
                    })
                })
                .collect();
            // The fits' wavelengths outside the library's own bands, each band once.
            let mut e: Vec<f64> = Vec::new();
            for &w in wavelengths {
                let same = |x: &f64| polarid_core::classify::same_band(Some(*x), Some(w));
                if !own.iter().any(same) && !e.iter().any(same) {
                    e.push(w);
                }
            }
            if !e.is_empty() {
                warnings.push(Warning(format!(
                    "library {spec} evaluated at {} nm from its refractiveindex.info data \
                     (n and k at that wavelength; its own bands are kept where the fits are in \
                     them)",
                    list(&e)
                )));
            }
            for u in uncovered {
                warnings.push(Warning(format!(
                    "library {spec} at {} nm: no data for {} (left out at that wavelength)",
                    u.wavelength_nm,
                    u.names.join(", ")
                )));
            }
            return Ok((at.multi_prototypes(), label, warnings));
        }
        let (protos, label) = self.load_multi()?;
        if !wavelengths.is_empty()
            && protos
                .iter()
                .all(|p| p.bands.iter().all(|b| b.wavelength_nm.is_none()))
        {
            warnings.push(Warning(format!(
                "{label} has no wavelength_nm: compared with the fits at {} nm as it is \
                 (make sure its values are for that wavelength)",
                list(wavelengths)
            )));
        }
        Ok((protos, label, warnings))
    }
}

/// Wolff's baseline as requested: the measurements CSV and the settings.
#[derive(Debug, Clone)]
pub struct WolffRequest {
    /// The measurements CSV (the one given to `polarid fit`).
    pub measurements: PathBuf,
    /// The rule's settings.
    pub settings: WolffSettings,
}

/// Settings of [`classify`]. The default is the set rule at 95% confidence
/// ([`ClassifierConfig::set`]; see `docs/CLASSIFY.md`), three explained neighbours, no
/// Wolff baseline.
#[derive(Debug, Clone)]
pub struct ClassifyConfig {
    /// The classifier (rule, confidence, metric, neighbours, reject option).
    pub classifier: ClassifierConfig,
    /// How many nearest prototypes each explanation lists.
    pub explain: usize,
    /// Also run Wolff's metal/dielectric baseline.
    pub wolff: Option<WolffRequest>,
    /// The wavelength (nm) of fit rows that carry no `wavelength_nm` (`classify
    /// --wavelength-nm`); `None`: such rows stay without one.
    pub wavelength_nm: Option<f64>,
    /// Where a model was trained (`classify --bench`; default the same bench as the
    /// fits: the estimate's noise against the prototypes' sample covariance). No effect
    /// on libraries.
    pub bench: polarid_core::classify::Bench,
    /// Prior weights of materials for the hypothesis tests (`classify --prior NAME=W`;
    /// materials not named weigh 1). Checked against the library by
    /// [`rows::prior_weights`].
    pub priors: Vec<(String, f64)>,
}

/// A classifier setting as a [`PipelineError::Config`] naming the setting and value.
pub fn check_classifier(cfg: &ClassifierConfig) -> Result<()> {
    cfg.validate().map_err(|e| {
        let (option, value) = match cfg.reject {
            _ if !(cfg.confidence > 0.0 && cfg.confidence < 1.0) => {
                ("confidence", cfg.confidence.to_string())
            }
            _ if cfg.k == 0 => ("k", "0".to_string()),
            _ if cfg.rule == Rule::Set && cfg.k != 1 => ("k", cfg.k.to_string()),
            polarid_core::classify::Reject::Chi2 { p } => ("reject", p.to_string()),
            polarid_core::classify::Reject::MaxDistance(d) => ("max_distance", d.to_string()),
            _ => ("classifier", format!("{cfg:?}")),
        };
        PipelineError::config(
            option,
            value,
            format!("is not usable (invalid classifier option: {e})"),
        )
    })
}

impl Default for ClassifyConfig {
    fn default() -> Self {
        Self {
            classifier: ClassifierConfig::set(polarid_core::classify::DEFAULT_CONFIDENCE),
            explain: 3,
            wolff: None,
            wavelength_nm: None,
            bench: polarid_core::classify::Bench::Same,
            priors: Vec::new(),
        }
    }
}

impl ClassifyConfig {
    /// Check every value ([`PipelineError::Config`] naming it).
    pub fn validate(&self) -> Result<()> {
        check_classifier(&self.classifier)?;
        if let Some(w) = self.wavelength_nm {
            let why = "must be a wavelength in [100, 100000) nm";
            ensure((100.0..100_000.0).contains(&w), "wavelength_nm", w, why)?;
        }
        if let Some(w) = &self.wolff {
            w.settings.validate()?;
        }
        for (name, w) in &self.priors {
            let ok = w.is_finite() && *w >= 0.0;
            let why = "weights must be finite and >= 0";
            ensure(ok, "prior", format!("{name}={w}"), why)?;
        }
        Ok(())
    }
}

/// What [`classify`] returns.
#[derive(Debug, Clone)]
pub struct ClassifyOutput {
    /// One row per fit, in input order (with Wolff's columns when requested).
    pub rows: Vec<ClassificationRow>,
    /// Explanations: per target one line (and one for Wolff's decision when requested).
    pub notes: Vec<String>,
    /// The prototypes' label, e.g. `model model.json`, `library builtin`.
    pub label: String,
    /// The classifier used.
    pub classifier: Classifier,
    /// How the prototypes were matched to the fits' wavelengths
    /// ([`PrototypeSource::load_multi_for`]).
    pub warnings: Vec<Warning>,
    /// The hypothesis tests against measured rows (`classify MEASUREMENTS.csv`): every
    /// tested material of each classified target, with the nuisances it needed (empty
    /// for fits).
    pub hypotheses: Vec<TargetHypotheses>,
    /// The in-scene references' calibration (`classify MEASUREMENTS.csv` with a
    /// `reference` column; [`mod@reference`]).
    pub calibration: Option<reference::SceneCalibration>,
}

/// One target's hypothesis tests: every tested material, most probable first, with its
/// probability and the layer thickness, scale and offset it needed
/// (`polarid_core::classify::HypothesisOutcome::tested`).
#[derive(Debug, Clone, PartialEq)]
pub struct TargetHypotheses {
    /// The target.
    pub target: String,
    /// The tested materials.
    pub tested: Vec<polarid_core::classify::Candidate>,
    /// Whether the scale and offset were calibrated by an in-scene reference.
    pub calibrated: bool,
}

/// The classification CSV row of fit `f` (a target's first band) classified as `d` by
/// `clf` (without Wolff's columns; `bands_used` from the decision). `candidates` is the consistent set (under both rules); `category` is the
/// candidates' common category under the set rule, the nearest prototype's under the
/// nearest rule.
pub fn classification_row(f: &FitRow, d: &Decision, clf: &Classifier) -> ClassificationRow {
    let cfg = clf.config();
    let category = match cfg.rule {
        Rule::Set => d.set_category.clone(),
        Rule::Nearest => d
            .nearest
            // ok: nb.index is an index into clf.prototypes() (from clf.classify).
            .and_then(|nb| clf.prototypes()[nb.index].category.clone()),
    };
    ClassificationRow {
        category,
        metric: cfg.distance_metric().name().into(),
        rule: cfg.rule.name().into(),
        confidence: d.set_tested.then_some(cfg.confidence),
        votes: d.nearest.map(|_| d.votes as u64),
        bands_used: d.bands_used_text(),
        ..decision_row(f, d)
    }
}

/// The columns of fit `f`'s classification row that every rule fills alike from its
/// decision `d` (target, class, answer, status, candidates, nearest and runner-up,
/// margin, gate, reason).
pub(crate) fn decision_row(f: &FitRow, d: &Decision) -> ClassificationRow {
    ClassificationRow {
        target: f.target.clone(),
        class: f.class.clone(),
        predicted: d.predicted.clone(),
        distance: d.nearest.map(|_| d.distance),
        runner_up: d.runner_up.clone(),
        runner_up_distance: d.runner_up.as_ref().map(|_| d.runner_up_distance),
        status: d.status.label(),
        candidates: d.candidates.iter().map(|c| c.class.clone()).collect(),
        margin: Some(d.margin),
        nearest: d.nearest_class.clone(),
        gate: d.gate,
        reason: d.reason.clone(),
        ..Default::default()
    }
}

/// A classifier over multi-band prototypes (labelled `label` in messages).
pub fn multi_classifier(
    protos: Vec<MultiPrototype>,
    label: &str,
    cfg: ClassifierConfig,
) -> Result<Classifier> {
    Classifier::multi(protos, cfg).map_err(|e| PipelineError::Data {
        path: format!("cannot use {label}"),
        reason: e.to_string(),
    })
}

/// A classifier over `protos` (labelled `label` in messages: `cannot use LABEL: ...`).
pub fn classifier(
    protos: Vec<Prototype>,
    label: &str,
    cfg: ClassifierConfig,
) -> Result<Classifier> {
    Classifier::new(protos, cfg).map_err(|e| PipelineError::Data {
        path: format!("cannot use {label}"),
        reason: e.to_string(),
    })
}

/// Classify every target (each fit with its line in `fits_path`; see [`read_fits`];
/// a multi-band target's rows together, [`group_fits`]) against the prototypes of
/// `source`, in input order.
///
/// Errors: no fits, unusable prototypes, unreadable files, and with Wolff's baseline
/// unusable measurements (naming the file, target and line).
pub fn classify(
    fits_path: &Path,
    fits: &[(u64, FitRow)],
    source: &PrototypeSource,
    cfg: &ClassifyConfig,
) -> Result<ClassifyOutput> {
    cfg.validate()?;
    if fits.is_empty() {
        return Err(PipelineError::Data {
            path: fits_path.display().to_string(),
            reason: "no fits to classify".into(),
        });
    }
    let assigned: Vec<(u64, FitRow)>;
    let fits = match cfg.wavelength_nm {
        Some(w) => {
            assigned = fits
                .iter()
                .map(|(l, f)| {
                    let mut f = f.clone();
                    f.wavelength_nm = f.wavelength_nm.or(Some(w));
                    (*l, f)
                })
                .collect();
            &assigned[..]
        }
        None => fits,
    };
    let mut wavelengths: Vec<f64> = Vec::new();
    for w in fits.iter().filter_map(|(_, f)| f.wavelength_nm) {
        crate::fit::index_or_push(&mut wavelengths, |&x| x == w, || w);
    }
    let without = fits
        .iter()
        .filter(|(_, f)| f.wavelength_nm.is_none())
        .count();
    let (protos, label, mut warnings) = source.load_multi_for(&wavelengths, without)?;
    let rows_in: Vec<&FitRow> = fits.iter().map(|(_, f)| f).collect();
    let (protos, cmp) = prototypes_for(source, protos, cfg.bench, &rows_in, &mut warnings)?;
    let clf = multi_classifier(protos, &label, cfg.classifier)?;
    // A library is an open world: a transparent material alone is an index, not a name.
    let open_world =
        source.is_catalogue() && cfg.classifier.rule == polarid_core::classify::Rule::Set;
    let wolff = cfg
        .wolff
        .as_ref()
        .map(|w| WolffData::load(&w.measurements, w.settings))
        .transpose()?;
    let mut rows = Vec::with_capacity(fits.len());
    let mut notes = Vec::new();
    for group in group_fits(fits) {
        // ok: group_fits returns non-empty groups of indices into `fits`.
        let (line, f) = &fits[group[0]];
        let mut d = clf.classify_multi(&multi_estimate_for(group.iter().map(|&i| &fits[i].1), cmp));
        if open_world {
            let w: Vec<f64> = group
                .iter()
                .filter_map(|&i| fits[i].1.wavelength_nm)
                .collect();
            d.open_world(clf.profiles(), &w, cfg.classifier.confidence);
        }
        let mut note = explain(&f.target, &estimate_for(f, cmp), &d, &clf, cfg.explain);
        if f.wavelength_nm.is_some() {
            let have: Vec<String> = group
                .iter()
                .filter_map(|&i| fits[i].1.wavelength_nm.map(|w| format!("{w}")))
                .collect();
            note.push_str(&format!(
                " [bands compared: {} of the target's {}]",
                if d.bands_used.is_empty() {
                    "none".to_string()
                } else {
                    d.bands_used_text()
                },
                have.join(";")
            ));
        }
        notes.push(note);
        let mut row = classification_row(f, &d, &clf);
        if let Some(wd) = &wolff {
            let w = wd.decide(
                &f.target,
                &format!(
                    "target {} (line {line} of {})",
                    f.target,
                    fits_path.display()
                ),
            )?;
            row.wolff_class = Some(w.class.name().into());
            row.wolff_fr_max = Some(w.fr_max);
            row.wolff_beta_deg = Some(w.beta_at_max.to_degrees());
            let (lo, hi) = wd.settings.beta_deg;
            notes.push(format!(
                "{}: Wolff: {} (largest Fresnel ratio {:.3} over {} measurement(s) with beta in \
                 [{lo}, {hi}] deg; threshold {})",
                f.target,
                w.class.name(),
                w.fr_max,
                w.used,
                wd.config.threshold
            ));
        }
        rows.push(row);
    }
    Ok(ClassifyOutput {
        rows,
        notes,
        label,
        classifier: clf,
        warnings,
        hypotheses: Vec::new(),
        calibration: None,
    })
}
