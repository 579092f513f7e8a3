//! The fit → train → classify → evaluate workflows of `polarid_pipeline` on exact
//! synthetic DoLP data: results, progress reports, warnings and error messages.

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use polarid_core::FitStatus;
use polarid_core::dop::dop;
use polarid_io::table::measurements::Measurement;
use polarid_pipeline::classify::{self, ClassifyConfig, PrototypeSource};
use polarid_pipeline::evaluate::{self, EvaluateConfig};
use polarid_pipeline::fit::{self, FitConfig, Reflectance};
use polarid_pipeline::progress::no_progress;
use polarid_pipeline::{PipelineError, train};

const BETAS: [f64; 6] = [30.0, 40.0, 50.0, 60.0, 70.0, 80.0];

/// Rows of one target of index (n, k), line numbers from `first_line`.
fn target(name: &str, class: &str, n: f64, k: f64, first_line: u64) -> Vec<(u64, Measurement)> {
    BETAS
        .iter()
        .enumerate()
        .map(|(i, &b)| {
            (
                first_line + i as u64,
                Measurement {
                    target: name.into(),
                    class: Some(class.into()),
                    phi_deg: 180.0,
                    beta_deg: b,
                    dolp: dop(n, k, b.to_radians()),
                    ..Default::default()
                },
            )
        })
        .collect()
}

fn data() -> Vec<(u64, Measurement)> {
    let mut rows = target("al1", "aluminum", 1.2, 7.0, 2);
    rows.extend(target("al2", "aluminum", 1.25, 6.9, 8));
    rows.extend(target("cu1", "copper", 0.27, 3.4, 14));
    rows.extend(target("cu2", "copper", 0.3, 3.5, 20));
    rows
}

#[test]
fn fit_train_classify_evaluate() {
    let path = Path::new("m.csv");
    let calls = AtomicU64::new(0);
    let progress = |stage: &str, done: u64, total: u64| {
        assert_eq!((stage, total), ("fitting", 4));
        assert!(done <= total);
        calls.fetch_add(1, Ordering::Relaxed);
    };
    // Clean simulated surfaces: no surface-layer allowance (with the default 3 nm the
    // aluminium and copper sets overlap: `ambiguous`, docs/ERRORS.md).
    let cfg = FitConfig {
        film_sd_nm: 0.0,
        ..FitConfig::default()
    };
    let out = fit::fit(path, &data(), &cfg, &progress).unwrap();
    assert_eq!(calls.load(Ordering::Relaxed), 5);
    assert!(out.warnings.is_empty());
    let rows = out.rows();
    let names: Vec<&str> = rows.iter().map(|r| r.target.as_str()).collect();
    assert_eq!(names, ["al1", "al2", "cu1", "cu2"]);
    assert!((rows[0].n - 1.2).abs() < 1e-6 && (rows[0].k - 7.0).abs() < 1e-5);
    assert!(
        rows.iter()
            .all(|r| r.status == FitStatus::Ok && r.model == "specular")
    );

    let fits: Vec<(u64, _)> = rows
        .into_iter()
        .enumerate()
        .map(|(i, r)| (i as u64 + 2, r))
        .collect();
    let trained = train::train(&fits, Path::new("fits.csv"), "fits.csv").unwrap();
    assert_eq!(trained.model.prototypes.len(), 4);
    assert_eq!(train::classes(&trained.model), ["aluminum", "copper"]);

    let source = PrototypeSource::List(trained.model.prototypes(), "the model".into());
    let cfg = ClassifyConfig {
        explain: 2,
        ..Default::default()
    };
    let c = classify::classify(Path::new("fits.csv"), &fits, &source, &cfg).unwrap();
    let predicted: Vec<&str> = c.rows.iter().map(|r| r.predicted.as_str()).collect();
    assert_eq!(predicted, ["aluminum", "aluminum", "copper", "copper"]);
    assert_eq!(c.notes.len(), 4);
    assert_eq!(c.label, "the model");

    // The paper's nearest rule: every held-out target goes to its class.
    let nearest = EvaluateConfig {
        classifier: polarid_core::classify::ClassifierConfig::default(),
        ..Default::default()
    };
    let ev = evaluate::evaluate(Path::new("fits.csv"), &fits, None, &nearest).unwrap();
    assert_eq!(ev.mode, "leave-one-out");
    assert_eq!(ev.evaluation.accuracy, 1.0);
    // The default set rule: the fits' standard errors include the default systematic
    // error (docs/ERRORS.md), so every held-out target is consistent with at least one
    // material (its own: the sets' coverage is checked below).
    let sets = evaluate::evaluate(
        Path::new("fits.csv"),
        &fits,
        None,
        &EvaluateConfig::default(),
    )
    .unwrap();
    let st = sets.evaluation.sets.as_ref().unwrap();
    assert_eq!((st.tested, st.empty), (4, 0));
    assert_eq!(st.covered, 4);
    assert!(ev.wolff.is_none() && ev.warnings.is_empty());
}

#[test]
fn depolarized_and_warnings() {
    let cfg = FitConfig {
        depolarized_dolp: 0.9,
        ..Default::default()
    };
    let out = fit::fit(Path::new("m.csv"), &data(), &cfg, &no_progress).unwrap();
    assert!(
        out.targets
            .iter()
            .all(|t| t.row.status == FitStatus::Depolarized)
    );
    assert_eq!(
        out.warnings[0].0,
        "4 of 4 target(s) fitted with a status other than ok (see the status and reason columns)"
    );
}

#[test]
fn errors_name_file_target_and_lines() {
    let p = Path::new("m.csv");
    let msg = |rows: &[(u64, Measurement)], cfg: &FitConfig| {
        fit::fit(p, rows, cfg, &no_progress)
            .unwrap_err()
            .to_string()
    };
    let cfg = FitConfig::default();
    assert_eq!(msg(&[], &cfg), "m.csv: no measurements");
    let rows = data();
    assert_eq!(
        msg(&rows[..2], &cfg),
        "m.csv: target \"al1\" has 2 measurement(s) (lines 2, 3); at least 3 are needed"
    );
    let mut bad = data();
    bad[3].1.class = Some("copper".into());
    assert_eq!(
        msg(&bad, &cfg),
        "m.csv: line 5: target \"al1\" has class \"copper\" but an earlier row says \"aluminum\""
    );
    let mixed = FitConfig {
        reflectance: Reflectance::Mixed,
        ..Default::default()
    };
    assert!(
        msg(&rows, &mixed)
            .starts_with("m.csv: line 2: target \"al1\": --reflectance mixed needs column `s0`")
    );
    // Configuration errors name the option and the value.
    let bad_range = FitConfig {
        n_range: (2.0, 1.0),
        ..Default::default()
    };
    let e = fit::fit(p, &rows, &bad_range, &no_progress).unwrap_err();
    assert!(
        matches!(&e, PipelineError::Range { option, .. } if option == "n_range"),
        "{e}"
    );
    assert!(e.to_string().contains("need 0 <= MIN < MAX, got 2,1"));
    let e = FitConfig {
        estimate_theta_r: true,
        ..Default::default()
    }
    .validate()
    .unwrap_err();
    assert!(
        e.to_string()
            .starts_with("estimate_theta_r needs reflectance mixed"),
        "{e}"
    );
    // Nothing to train on.
    let fits: Vec<(u64, _)> = vec![(2, Default::default())];
    let e = train::train(&fits, Path::new("fits.csv"), "fits.csv").unwrap_err();
    assert!(
        e.to_string().starts_with("fits.csv: nothing to train on"),
        "{e}"
    );
    // Nothing to classify.
    let e = classify::classify(
        Path::new("fits.csv"),
        &[],
        &PrototypeSource::Library("builtin".into()),
        &ClassifyConfig::default(),
    )
    .unwrap_err();
    assert_eq!(e.to_string(), "fits.csv: no fits to classify");
}
