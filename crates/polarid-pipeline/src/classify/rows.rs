//! Classification from the measured rows: each material hypothesis (as it is found: its
//! bulk under its native layer, a polarimeter that only loses DoLP, a bounded common
//! angle offset) tested directly against a target's DoLP rows
//! (`polarid_core::classify::hypothesis`; docs/CLASSIFY.md "Testing each material against
//! the rows"). The workflow of `polarid classify MEASUREMENTS.csv`.
//!
//! Each target is also fitted (the fit pipeline, [`crate::fit::fit`]) and its `(n, k)`
//! fit is kept as the description of the surface; a target whose fit status is not `ok`
//! (too few rows, depolarized, model mismatch) is not classified, as with fits.

// NaN-safe negated comparisons on purpose; index loops over 3×3 blocks read as the
// equations.
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    clippy::needless_range_loop,
    clippy::nonminimal_bool,
    clippy::type_complexity,
    clippy::manual_range_contains
)]

use std::path::Path;

use polarid_core::FitStatus;
use polarid_core::classify::{
    Decision, HypRow, HypothesisConfig, HypothesisOutcome, MultiPrototype, Status, classify_rows,
    reference::classify_rows_within,
};
use polarid_io::table::CsvTable;
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;

use super::reference::SceneCalibration;
use super::{ClassifyConfig, ClassifyOutput, PrototypeSource};
use crate::error::ensure;
use crate::fit::{FitConfig, fit, index_or_push};
use crate::{PipelineError, Result};

/// The rule's name in the classification CSV (`rule` column).
pub const RULE_NAME: &str = "hypothesis";

/// Whether a table is a measurements table (the rows of `polarid measure`, with `dolp`
/// and `beta_deg` or `theta_i_deg`) rather than a fits table (with `n`).
pub fn is_measurements(t: &CsvTable) -> bool {
    t.col("dolp").is_some()
        && (t.col("beta_deg").is_some() || t.col("theta_i_deg").is_some())
        && t.col("n").is_none()
}

/// The user's priors (`--prior NAME=W`, each weight finite and ≥ 0 as
/// [`ClassifyConfig::validate`] checks) as one weight per prototype (1 for a material not
/// named). Errors name the prior: an unknown material, all weights 0.
pub fn prior_weights(priors: &[(String, f64)], protos: &[MultiPrototype]) -> Result<Vec<f64>> {
    let mut w = vec![1.0; protos.len()];
    for (name, v) in priors {
        let mut found = false;
        for (wi, p) in w.iter_mut().zip(protos) {
            if &p.class == name {
                *wi = *v;
                found = true;
            }
        }
        let why = "names no material of the library or model";
        ensure(found, "prior", format!("{name}={v}"), why)?;
    }
    let why = "at least one material needs a weight > 0";
    ensure(!w.iter().all(|&x| x == 0.0), "prior", "all 0", why)?;
    Ok(w)
}

/// One target's usable rows (status `ok`), and its in-scene reference material if it is
/// one.
struct TargetRows<'a> {
    target: &'a str,
    rows: Vec<&'a Measurement>,
    reference: Option<polarid_io::table::measurements::Reference>,
}

fn group<'a>(rows: &'a [(u64, Measurement)]) -> Vec<TargetRows<'a>> {
    let mut out: Vec<TargetRows> = Vec::new();
    for (_, m) in rows {
        let new = || TargetRows {
            target: &m.target,
            rows: Vec::new(),
            reference: None,
        };
        let i = index_or_push(&mut out, |g| g.target == m.target, new);
        if m.reference.is_some() {
            out[i].reference.clone_from(&m.reference);
        }
        if m.status.is_ok() {
            out[i].rows.push(m);
        }
    }
    out
}

/// A target's rows as the hypothesis tests take them, the rows' band wavelengths (nm;
/// rows without one: the built-in library's band) and the largest direction uncertainty
/// (radians), with the error model of `fit_cfg`.
fn hyp_rows(rows: &[&Measurement], fit_cfg: &FitConfig) -> (Vec<HypRow>, Vec<f64>, f64) {
    let mut bands: Vec<f64> = Vec::new();
    let mut hrows = Vec::with_capacity(rows.len());
    let mut angle_max: f64 = 0.0;
    for m in rows {
        let w = m
            .wavelength_nm
            .unwrap_or(polarid_io::library::BUILTIN_WAVELENGTH_NM);
        let band = index_or_push(&mut bands, |&b| b == w, || w);
        let angle_sd = m.angle_sd_deg.unwrap_or(fit_cfg.angle_sd_deg).to_radians();
        angle_max = angle_max.max(angle_sd);
        let se = m.dolp_se.unwrap_or(0.0);
        hrows.push(HypRow {
            beta: m.beta_deg.to_radians(),
            dolp: m.dolp,
            dolp_sd: (se * se + fit_cfg.dolp_floor * fit_cfg.dolp_floor).sqrt(),
            angle_sd,
            band,
        });
    }
    (hrows, bands, angle_max)
}

/// The classification CSV row of a hypothesis decision: `candidates` with their
/// probabilities, `probability` of the answer (the named material's; the sum of the set's
/// for `ambiguous`; empty for `unknown`), `distance`/`gate` the best material's `χ²`,
/// `rule` `hypothesis`, `metric` `chi2`.
pub fn hypothesis_row(
    f: &FitRow,
    out: Option<&HypothesisOutcome>,
    d: &Decision,
    confidence: f64,
) -> ClassificationRow {
    let probability = match d.status {
        Status::Ok | Status::Ambiguous => Some(
            d.candidates
                .iter()
                .map(|c| c.probability.unwrap_or(0.0))
                .sum(),
        ),
        _ => None,
    };
    ClassificationRow {
        candidate_probabilities: d
            .candidates
            .iter()
            .map(|c| c.probability.unwrap_or(f64::NAN))
            .collect(),
        probability,
        category: d.set_category.clone(),
        metric: "chi2".into(),
        rule: RULE_NAME.into(),
        confidence: out.map(|_| confidence),
        bands_used: if d.bands_used.len() > 1 {
            d.bands_used_text()
        } else {
            String::new()
        },
        ..super::decision_row(f, d)
    }
}

/// The explanation of one target: its fit, then the `top` most probable materials with
/// probability, `χ²` (p-value), and the nuisances they needed.
pub fn explain_hypotheses(f: &FitRow, out: &HypothesisOutcome, top: usize, p: f64) -> String {
    let d = &out.decision;
    let mut s = format!(
        "{}: fit n = {:.3}, k = {:.3}; tested against the rows at {}%: ",
        f.target,
        f.n,
        f.k,
        p * 100.0
    );
    s.push_str(&match d.status {
        Status::Ok => format!(
            "{} (probability {:.3})",
            d.predicted,
            d.candidates[0].probability.unwrap_or(f64::NAN)
        ),
        // A transparent material alone: an index, not a name (its reason says so).
        Status::Ambiguous if d.candidates.len() == 1 => format!("ambiguous: {}", d.reason),
        Status::Ambiguous => format!(
            "ambiguous: {}",
            d.candidates
                .iter()
                .map(|c| c.class.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        _ => format!("unknown ({})", d.reason),
    });
    let list: Vec<String> = out
        .tested
        .iter()
        .take(top)
        .filter_map(|c| {
            let fit = c.fit?;
            Some(format!(
                "{}{} p {:.3}, chi2 {:.2} on {:.1} (p-value {:.3}), layer {:.2} nm, scale {:.4}, offset {:+.3} deg",
                c.class,
                if fit.consistent { "" } else { " [rejected]" },
                c.probability.unwrap_or(f64::NAN),
                fit.chi2,
                fit.dof,
                fit.p_value,
                fit.thickness_nm,
                fit.scale,
                fit.offset.to_degrees()
            ))
        })
        .collect();
    if !list.is_empty() {
        s.push_str("; most probable: ");
        s.push_str(&list.join("; "));
    }
    s
}

/// The calibration of the scene by its in-scene references ([`super::reference`]): the
/// hypothesis rows of every reference target, the nuisance prior of every target's
/// largest direction uncertainty.
fn calibrate_references(
    path: &Path,
    groups: &[TargetRows<'_>],
    protos: &[MultiPrototype],
    cfg: &ClassifyConfig,
    fit_cfg: &FitConfig,
) -> Result<(Option<SceneCalibration>, Vec<crate::Warning>)> {
    let mut refs = Vec::new();
    let mut angle_all: f64 = 0.0;
    for g in groups {
        let (hrows, bands, angle_max) = hyp_rows(&g.rows, fit_cfg);
        angle_all = angle_all.max(angle_max);
        if let Some(r) = g.reference.clone() {
            refs.push(super::reference::ReferenceRows {
                target: g.target,
                reference: r,
                rows: hrows,
                bands,
            });
        }
    }
    super::reference::calibrate_scene(
        &path.display().to_string(),
        &refs,
        protos,
        fit_cfg.nuisances(angle_all),
        cfg.classifier.confidence,
    )
}

/// The classification of the targets so far: a row and a note per target, the
/// hypotheses of each tested one.
#[derive(Default)]
struct Classified {
    rows: Vec<ClassificationRow>,
    notes: Vec<String>,
    hypotheses: Vec<super::TargetHypotheses>,
}

/// What classifying each target shares.
struct TargetClassifier<'a> {
    path: &'a Path,
    cfg: &'a ClassifyConfig,
    fit_cfg: &'a FitConfig,
    protos: &'a [MultiPrototype],
    priors: &'a [f64],
    /// The in-scene references' calibration.
    scene: Option<&'a SceneCalibration>,
    /// The materials are a catalogue (an open world), not the user's own list.
    open_world: bool,
}

impl TargetClassifier<'_> {
    /// Classify target `g` (its fits `fits`, `f` the first): a reference's row, an
    /// unclassified row when a fit is not `ok`, else the hypothesis tests on its rows.
    fn target(
        &self,
        g: &TargetRows<'_>,
        fits: &[FitRow],
        f: &FitRow,
        out: &mut Classified,
    ) -> Result<()> {
        let confidence = self.cfg.classifier.confidence;
        if let Some(c) = self.scene
            && let Some(rf) = c.references.iter().find(|r| r.target == g.target)
        {
            out.notes.push(super::reference::explain_reference(rf, c));
            out.rows
                .push(super::reference::reference_row(f, rf, confidence));
            return Ok(());
        }
        let not_ok = fits
            .iter()
            .find(|f| f.target == g.target && f.status != FitStatus::Ok);
        if let Some(bad) = not_ok {
            let d = Decision::unclassified(
                Status::FitNotOk(bad.status),
                format!(
                    "not classified: its fit{} is {} ({})",
                    bad.wavelength_nm
                        .map_or(String::new(), |w| format!(" at {w} nm")),
                    bad.status,
                    bad.reason
                ),
            );
            out.notes.push(format!("{}: {}", g.target, d.reason));
            out.rows.push(hypothesis_row(f, None, &d, confidence));
            return Ok(());
        }
        self.tested(g, f, out)
    }

    /// Target `g` tested against every material on its rows (within the scale and
    /// offset of the in-scene references when they calibrate them).
    fn tested(&self, g: &TargetRows<'_>, f: &FitRow, out: &mut Classified) -> Result<()> {
        let confidence = self.cfg.classifier.confidence;
        let (hrows, bands, angle_max) = hyp_rows(&g.rows, self.fit_cfg);
        let hcfg = HypothesisConfig {
            confidence,
            nuisances: self.fit_cfg.nuisances(angle_max),
            open_world: self.open_world,
        };
        let priors = Some(self.priors);
        let bounds = self.scene.and_then(|c| c.bounds.as_ref());
        let tested = match bounds {
            Some(b) => classify_rows_within(&hrows, &bands, self.protos, priors, &hcfg, b),
            None => classify_rows(&hrows, &bands, self.protos, priors, &hcfg),
        }
        .map_err(|e| PipelineError::Data {
            path: self.path.display().to_string(),
            reason: format!("target {:?}: {e}", g.target),
        })?;
        let mut note = explain_hypotheses(f, &tested, self.cfg.explain, confidence);
        if bounds.is_some() {
            note.push_str(" (scale and offset calibrated by the in-scene reference)");
        }
        out.notes.push(note);
        out.hypotheses.push(super::TargetHypotheses {
            target: g.target.to_string(),
            tested: tested.tested.clone(),
            calibrated: bounds.is_some(),
        });
        out.rows.push(hypothesis_row(
            f,
            Some(&tested),
            &tested.decision,
            confidence,
        ));
        Ok(())
    }
}

/// Classify every target of a measurements table (each row with its line in `path`)
/// against `source` by the hypothesis tests, with the error model of `fit_cfg`
/// (docs/ERRORS.md; nuisance bounds [`FitConfig::nuisances`], the independent
/// parts in each row's `σ`). Rows without `wavelength_nm` take `cfg.wavelength_nm`, else
/// 650 nm (the built-in library's band; a warning says so). One classification row per
/// target, in first-appearance order, with its fit's columns kept in `fits`.
///
/// Errors: unreadable or unusable measurements (naming the file, line and value), bad
/// settings or priors, an unusable library.
pub fn classify_measurements(
    path: &Path,
    rows: &[(u64, Measurement)],
    source: &PrototypeSource,
    cfg: &ClassifyConfig,
    fit_cfg: &FitConfig,
) -> Result<(ClassifyOutput, Vec<FitRow>)> {
    cfg.validate()?;
    fit_cfg.validate()?;
    let assigned: Vec<(u64, Measurement)> = rows
        .iter()
        .map(|(l, m)| {
            let mut m = m.clone();
            m.wavelength_nm = m.wavelength_nm.or(cfg.wavelength_nm);
            (*l, m)
        })
        .collect();
    let fitted = fit(path, &assigned, fit_cfg, &|_, _, _| {})?;
    let fits = fitted.rows();
    let mut wavelengths: Vec<f64> = Vec::new();
    for w in assigned.iter().filter_map(|(_, m)| m.wavelength_nm) {
        index_or_push(&mut wavelengths, |&x| x == w, || w);
    }
    let without = fits.iter().filter(|f| f.wavelength_nm.is_none()).count();
    let (protos, label, mut warnings) = source.load_multi_for(&wavelengths, without)?;
    let priors = prior_weights(&cfg.priors, &protos)?;
    let with_layer = protos.iter().filter(|p| p.surface.is_some()).count();
    if with_layer < protos.len() {
        warnings.push(crate::Warning(format!(
            "{} of {} materials of {label} carry no native layer: they are tested bare",
            protos.len() - with_layer,
            protos.len()
        )));
    }
    let groups = group(&assigned);
    // In-scene references calibrate the scale and the offset of every other target.
    let (scene, ref_warnings) = calibrate_references(path, &groups, &protos, cfg, fit_cfg)?;
    warnings.extend(ref_warnings);
    let classifier = TargetClassifier {
        path,
        cfg,
        fit_cfg,
        protos: &protos,
        priors: &priors,
        scene: scene.as_ref(),
        open_world: source.is_catalogue(),
    };
    let mut out = Classified::default();
    for g in &groups {
        if let Some(f) = fits.iter().find(|f| f.target == g.target) {
            classifier.target(g, &fits, f, &mut out)?;
        }
    }
    let clf = super::multi_classifier(protos, &label, cfg.classifier)?;
    Ok((
        ClassifyOutput {
            rows: out.rows,
            notes: out.notes,
            label,
            classifier: clf,
            warnings,
            hypotheses: out.hypotheses,
            calibration: scene,
        },
        fits,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_core::classify::layered_dolp;

    fn rows(bulk: (f64, f64), layer: (f64, f64), d: f64) -> Vec<(u64, Measurement)> {
        (0..8)
            .map(|i| {
                let beta = 47.5 + 22.5 * i as f64 / 7.0;
                let y = 0.99 * layered_dolp(bulk, layer, d / 650.0, (beta + 0.1f64).to_radians());
                (
                    i as u64 + 2,
                    Measurement {
                        target: "T".into(),
                        beta_deg: beta,
                        phi_deg: 180.0,
                        // A deterministic ±0.002 pattern in place of noise.
                        dolp: y + if i % 2 == 0 { 0.002 } else { -0.002 },
                        dolp_se: Some(0.003),
                        ..Default::default()
                    },
                )
            })
            .collect()
    }

    #[test]
    fn measurements_are_tested_against_the_library() {
        let src = PrototypeSource::Library("builtin".into());
        let cfg = ClassifyConfig::default();
        let m = rows((1.55803, 7.7124), (1.65, 0.0), 3.0);
        let (out, fits) =
            classify_measurements(Path::new("m.csv"), &m, &src, &cfg, &FitConfig::default())
                .unwrap();
        assert_eq!(fits.len(), 1);
        let r = &out.rows[0];
        assert_eq!(r.rule, RULE_NAME);
        assert!(r.candidates.iter().any(|c| c == "aluminum"), "{r:?}");
        assert_eq!(r.candidates.len(), r.candidate_probabilities.len());
        assert!(r.probability.is_some_and(|p| p > 0.0 && p <= 1.0 + 1e-12));
        assert!(out.notes[0].contains("aluminum p "), "{}", out.notes[0]);
        // Priors: a zero weight removes aluminium's probability; a name not in the
        // library is a configuration error naming it.
        let cfg0 = ClassifyConfig {
            priors: vec![("aluminum".into(), 0.0)],
            ..ClassifyConfig::default()
        };
        let (out0, _) =
            classify_measurements(Path::new("m.csv"), &m, &src, &cfg0, &FitConfig::default())
                .unwrap();
        let r0 = &out0.rows[0];
        if let Some(i) = r0.candidates.iter().position(|c| c == "aluminum") {
            assert_eq!(r0.candidate_probabilities[i], 0.0);
        }
        let bad = ClassifyConfig {
            priors: vec![("alumin".into(), 1.0)],
            ..ClassifyConfig::default()
        };
        let e = classify_measurements(Path::new("m.csv"), &m, &src, &bad, &FitConfig::default())
            .unwrap_err();
        assert!(e.to_string().contains("alumin=1"), "{e}");
    }

    /// A transparent material is an index, not a name, against a library (LSAT, n 2.02,
    /// is ZnO's index twin): never `ok`; against the user's own prototypes it is named.
    #[test]
    fn a_transparent_target_is_an_index_against_a_library() {
        let m = rows((2.02, 0.0), (1.5, 0.0), 1.0);
        let fit_cfg = FitConfig::default();
        let cfg = ClassifyConfig::default();
        let lib = PrototypeSource::Library("builtin".into());
        let (out, _) = classify_measurements(Path::new("m.csv"), &m, &lib, &cfg, &fit_cfg).unwrap();
        let r = &out.rows[0];
        assert_eq!(r.status, "ambiguous", "{r:?}");
        assert_eq!(r.candidates, ["ZnO_o"], "{r:?}");
        assert_eq!(r.category.as_deref(), Some("dielectric"), "{r:?}");
        assert!(
            r.reason.contains("transparent material of ZnO_o's index"),
            "{r:?}"
        );
        assert!(
            out.notes[0].contains("transparent material"),
            "{}",
            out.notes[0]
        );
        let zno = polarid_core::classify::Prototype {
            class: "ZnO".into(),
            n: 2.0,
            k: 0.0,
            cov: None,
            category: Some("dielectric".into()),
            source: "test".into(),
        };
        let own = PrototypeSource::List(vec![zno], "the prototypes".into());
        let (out, _) = classify_measurements(Path::new("m.csv"), &m, &own, &cfg, &fit_cfg).unwrap();
        assert_eq!(
            (out.rows[0].predicted.as_str(), out.rows[0].status.as_str()),
            ("ZnO", "ok")
        );
    }

    #[test]
    fn measurements_tables_are_recognised() {
        let dir = std::env::temp_dir().join(format!("polarid-rows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("m.csv");
        std::fs::write(&p, "target,beta_deg,dolp\nT,50,0.1\n").unwrap();
        assert!(is_measurements(&CsvTable::read(&p).unwrap()));
        std::fs::write(&p, "target,n,k,status\nT,1,2,ok\n").unwrap();
        assert!(!is_measurements(&CsvTable::read(&p).unwrap()));
        std::fs::remove_dir_all(&dir).ok();
    }
}
