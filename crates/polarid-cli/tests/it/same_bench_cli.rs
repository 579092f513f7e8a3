//! `classify --model` compares a test plate with prototypes from the same bench by
//! default (the estimate's noise against each prototype's noise and surface-layer
//! variation), `--bench other` with both sides' total covariance, and a model without
//! sample covariances (trained before) as from another bench, with a warning
//! (docs/CLASSIFY.md "Trained models"). The README's step-by-step example.

use crate::common;

use std::path::{Path, PathBuf};

use common::{csv_rows, polarid_in, text};

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/scenes/{name}.toml"))
}

fn run(dir: &Path, args: &[&str]) -> String {
    let out = polarid_in(dir, args);
    assert!(out.status.success(), "{args:?}: {}", text(&out.stderr));
    text(&out.stderr)
}

#[test]
fn same_bench_is_the_default_and_other_bench_adds_the_systematics() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    for (sc, out) in [("paper_training_60", "train"), ("aluminum_test_60", "test")] {
        let s = scene(sc);
        run(dir, &["simulate", s.to_str().unwrap(), "-o", out]);
        run(
            dir,
            &[
                "measure",
                &format!("{out}/manifest.toml"),
                "-o",
                &format!("{out}/m.csv"),
            ],
        );
        run(
            dir,
            &[
                "fit",
                &format!("{out}/m.csv"),
                "-o",
                &format!("{out}/fits.csv"),
            ],
        );
    }
    // The fits carry the sample columns, the model the sample covariances.
    let fits = csv_rows(&dir.join("train/fits.csv"));
    assert!(fits.iter().all(|r| !r["n_se_sample"].is_empty()
        && r["k_se_sample"].parse::<f64>().unwrap() < r["k_se"].parse::<f64>().unwrap()));
    run(dir, &["train", "train/fits.csv", "-o", "model.json"]);
    let model = std::fs::read_to_string(dir.join("model.json")).unwrap();
    assert_eq!(model.matches("\"sample_covariance\"").count(), 3, "{model}");

    let classify = |extra: &[&str], out: &str| {
        let mut args = vec![
            "classify",
            "test/fits.csv",
            "--model",
            "model.json",
            "-o",
            out,
        ];
        args.extend_from_slice(extra);
        let err = run(dir, &args);
        (csv_rows(&dir.join(out)).remove(0), err)
    };
    let (same, _) = classify(&[], "same.csv");
    assert_eq!(same["predicted"], "aluminum");
    assert_eq!(same["candidates"], "aluminum");
    let (other, _) = classify(&["--bench", "other"], "other.csv");
    assert_eq!(other["predicted"], "ambiguous");
    assert_eq!(other["candidates"], "aluminum;copper");

    // A model without sample covariances: compared as from another bench, with a
    // warning saying so.
    let old: serde_json::Value = serde_json::from_str(&model).unwrap();
    let mut old = old;
    for p in old["prototypes"].as_array_mut().unwrap() {
        p.as_object_mut().unwrap().remove("sample_covariance");
    }
    std::fs::write(dir.join("old.json"), old.to_string()).unwrap();
    let err = run(
        dir,
        &[
            "classify",
            "test/fits.csv",
            "--model",
            "old.json",
            "-o",
            "old.csv",
        ],
    );
    assert!(
        err.contains("no sample covariances") && err.contains("another bench"),
        "{err}"
    );
    assert_eq!(
        csv_rows(&dir.join("old.csv"))[0]["candidates"],
        "aluminum;copper"
    );
}
