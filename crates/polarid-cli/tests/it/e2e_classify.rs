//! Issue 5's end-to-end acceptance: training plates (aluminum, copper, green paint at
//! θr = 60°) and a test aluminum plate of another roughness at θr = 60° and 50° classify
//! correctly through the `measure` → `fit` → `train` → `classify` commands, on captures
//! from polarid's simulator and (when `POLARID_RENDERS` names the directory holding
//! `paper_lab_60/` and `paper_lab_50/`) on independent Mitsuba 3 renders.

use crate::common;

use common::{csv_rows, polarid};

use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn run(args: &[&str]) -> String {
    let out = polarid(args);
    assert!(
        out.status.success(),
        "polarid {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// measure + fit a manifest into `dir`; returns the fits CSV.
fn measure_fit(manifest: &Path, dir: &Path, tag: &str) -> PathBuf {
    let m = dir.join(format!("{tag}_measurements.csv"));
    let f = dir.join(format!("{tag}_fits.csv"));
    run(&["measure", s(manifest), "-o", s(&m)]);
    run(&["fit", s(&m), "-o", s(&f)]);
    f
}

/// Keep only the rows of a fits CSV whose target is in `targets` (header and comments
/// kept), as a user would with a text filter.
fn filter_fits(from: &Path, to: &Path, keep: impl Fn(&str) -> bool) {
    let text = std::fs::read_to_string(from).unwrap();
    let mut out = String::new();
    for (i, l) in text.lines().enumerate() {
        let header_or_comment = l.starts_with('#') || i == 0 || l.starts_with("target,");
        if header_or_comment || keep(l.split(',').next().unwrap_or("")) {
            out.push_str(l);
            out.push('\n');
        }
    }
    std::fs::write(to, out).unwrap();
}

/// Classify `fits` against `model`; returns (target, class, predicted, margin) rows and
/// prints them.
fn classify(fits: &Path, model: &Path, out: &Path, label: &str) -> Vec<HashMap<String, String>> {
    run(&[
        "classify",
        "--rule",
        "nearest",
        s(fits),
        "--model",
        s(model),
        "-o",
        s(out),
    ]);
    let rows = csv_rows(out);
    let f = csv_rows(fits);
    for r in &rows {
        let e = f.iter().find(|x| x["target"] == r["target"]).unwrap();
        eprintln!(
            "{label}: {} n = {} ± {}, k = {} ± {} -> {} (runner-up {} at {}, margin {})",
            r["target"],
            e["n"],
            e["n_se"],
            e["k"],
            e["k_se"],
            r["predicted"],
            r["runner_up"],
            r["runner_up_distance"],
            r.get("margin").map(String::as_str).unwrap_or("")
        );
    }
    rows
}

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/scenes/{name}.toml"))
}

#[test]
fn e2e_simulator_captures_classify_through_the_cli() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    for sc in ["paper_training_60", "aluminum_test_60", "aluminum_test_50"] {
        run(&["simulate", s(&scene(sc)), "-o", s(&d.join(sc))]);
    }
    let train_fits = measure_fit(&d.join("paper_training_60/manifest.toml"), d, "train");
    let model = d.join("model.json");
    run(&["train", s(&train_fits), "-o", s(&model)]);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["prototypes"].as_array().map(Vec::len), Some(3), "{m}");
    for view in ["60", "50"] {
        let fits = measure_fit(
            &d.join(format!("aluminum_test_{view}/manifest.toml")),
            d,
            &format!("test{view}"),
        );
        let rows = classify(
            &fits,
            &model,
            &d.join(format!("class{view}.csv")),
            &format!("simulator, theta_r = {view}"),
        );
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0]["class"], "aluminum");
        assert_eq!(rows[0]["predicted"], "aluminum", "{:?}", rows[0]);
        assert_eq!(rows[0]["status"], "ok", "{:?}", rows[0]);
    }
}

#[test]
fn e2e_mitsuba_renders_classify_through_the_cli() {
    let Some(root) = std::env::var_os("POLARID_RENDERS").map(PathBuf::from) else {
        polarid_testkit::note!(
            "skipped: set POLARID_RENDERS to the directory holding paper_lab_60/ and \
             paper_lab_50/ (tools/render/README.md)"
        );
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let f60 = measure_fit(&root.join("paper_lab_60/manifest.toml"), d, "lab60");
    let f50 = measure_fit(&root.join("paper_lab_50/manifest.toml"), d, "lab50");
    // Train on the three training plates of paper_lab_60.
    let train = d.join("train_fits.csv");
    filter_fits(&f60, &train, |t| {
        ["green_paint", "aluminum", "copper"].contains(&t)
    });
    let model = d.join("model.json");
    run(&["train", s(&train), "-o", s(&model)]);
    for (view, fits) in [("60", &f60), ("50", &f50)] {
        let test = d.join(format!("test{view}_fits.csv"));
        filter_fits(fits, &test, |t| t == "aluminum_rough");
        let rows = classify(
            &test,
            &model,
            &d.join(format!("class{view}.csv")),
            &format!("Mitsuba, theta_r = {view}"),
        );
        assert_eq!(rows.len(), 1, "{rows:?}");
        assert_eq!(rows[0]["predicted"], "aluminum", "{:?}", rows[0]);
    }
    // Every plate's index is recovered close to the truth.
    for (fits, label) in [(&f60, "60"), (&f50, "50")] {
        for r in csv_rows(fits) {
            let (n, k): (f64, f64) = match r["class"].as_str() {
                "green_paint" => (1.39, 0.34),
                "aluminum" => (1.24, 6.60),
                "copper" => (0.40, 2.95),
                other => panic!("unexpected class {other}"),
            };
            let (nh, kh): (f64, f64) = (r["n"].parse().unwrap(), r["k"].parse().unwrap());
            eprintln!("Mitsuba {label}: {} n = {nh:.4}, k = {kh:.4}", r["target"]);
            assert!(
                (nh - n).abs() < 0.1 && (kh - k).abs() < 0.3,
                "{label} {}: ({nh}, {kh}) vs ({n}, {k})",
                r["target"]
            );
        }
    }
}
