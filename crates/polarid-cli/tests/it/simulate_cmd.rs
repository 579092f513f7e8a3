//! `polarid simulate`: simulated captures fed back through `measure` and `fit` recover
//! each plate's (n, k) within 3 standard errors; scene errors exit 2 and create nothing.

use crate::common;

use common::{csv_rows, polarid};

use std::path::{Path, PathBuf};
use std::process::Output;

fn ok(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed ({:?}): {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/scenes/{name}.toml"))
}

fn num(row: &std::collections::HashMap<String, String>, col: &str) -> f64 {
    row[col].parse().unwrap()
}

/// simulate -> measure -> fit; returns the fits.
fn pipeline(scene_name: &str, dir: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let out = dir.join(scene_name);
    let o = out.to_str().unwrap();
    ok(
        &polarid(&["simulate", scene(scene_name).to_str().unwrap(), "-o", o]),
        "simulate",
    );
    let m = out.join("measurements.csv");
    ok(
        &polarid(&[
            "measure",
            out.join("manifest.toml").to_str().unwrap(),
            "-o",
            m.to_str().unwrap(),
        ]),
        "measure",
    );
    // Every measured DoLP is near the noise-free truth.
    let truth = csv_rows(&out.join("truth.csv"));
    let meas = csv_rows(&m);
    assert_eq!(truth.len(), meas.len());
    for (t, mm) in truth.iter().zip(&meas) {
        assert_eq!(t["target"], mm["target"]);
        let z = (num(mm, "dolp") - num(t, "dolp")) / num(mm, "dolp_se");
        assert!(
            z.abs() < 5.0,
            "{scene_name}: {} at theta_i {}: dolp {} vs truth {} ({z:.1} SE)",
            t["target"],
            t["theta_i_deg"],
            mm["dolp"],
            t["dolp"]
        );
        // S0 / exposure is comparable across captures: within 2 % of the truth.
        let rel = num(mm, "s0") / num(t, "s0") - 1.0;
        assert!(rel.abs() < 0.02, "{scene_name}: s0 off by {rel}");
    }
    let f = out.join("fits.csv");
    ok(
        &polarid(&["fit", m.to_str().unwrap(), "-o", f.to_str().unwrap()]),
        "fit",
    );
    csv_rows(&f)
}

#[test]
fn simulate_measure_fit_recovers_nk_within_3_se() {
    let tmp = tempfile::tempdir().unwrap();
    let truth: &[(&str, &str, f64, f64)] = &[
        ("paper_training_60", "green_paint", 1.39, 0.34),
        ("paper_training_60", "aluminum", 1.24, 6.60),
        ("paper_training_60", "copper", 0.40, 2.95),
        ("aluminum_test_60", "aluminum_test_60", 1.24, 6.60),
        ("aluminum_test_50", "aluminum_test_50", 1.24, 6.60),
        ("dofp_plates", "gold", 0.18, 3.1),
        ("dofp_plates", "glass", 1.52, 0.0),
    ];
    let mut fits = std::collections::HashMap::new();
    for (s, target, n, k) in truth {
        let rows = fits
            .entry(*s)
            .or_insert_with(|| pipeline(s, tmp.path()))
            .clone();
        let r = rows
            .iter()
            .find(|r| r["target"] == *target)
            .unwrap_or_else(|| panic!("{s}: no fit for {target}"));
        assert_eq!(r["status"], "ok", "{s} {target}");
        let (nh, kh, nse, kse) = (num(r, "n"), num(r, "k"), num(r, "n_se"), num(r, "k_se"));
        assert!(
            nse > 0.0 && kse > 0.0,
            "{s} {target}: standard errors {nse}, {kse}"
        );
        assert!(
            (nh - n).abs() <= 3.0 * nse,
            "{s} {target}: n = {nh} ± {nse}, true {n}"
        );
        assert!(
            (kh - k).abs() <= 3.0 * kse,
            "{s} {target}: k = {kh} ± {kse}, true {k}"
        );
    }
}

#[test]
fn simulate_is_deterministic_and_writes_the_manifest() {
    let tmp = tempfile::tempdir().unwrap();
    let sc = scene("dofp_plates");
    for d in ["a", "b"] {
        let o = tmp.path().join(d);
        ok(
            &polarid(&["simulate", sc.to_str().unwrap(), "-o", o.to_str().unwrap()]),
            "simulate",
        );
    }
    let a = std::fs::read(tmp.path().join("a/i45/raw.tif")).unwrap();
    let b = std::fs::read(tmp.path().join("b/i45/raw.tif")).unwrap();
    assert_eq!(a, b, "same scene, same seed: same frames");
    let m = std::fs::read_to_string(tmp.path().join("a/manifest.toml")).unwrap();
    assert!(m.contains("dofp = { file = \"i45/raw.tif\", pattern = [90.0, 45.0, 135.0, 0.0] }"));
    assert!(m.contains("exposure = 0.25"), "{m}");
    assert!(m.contains("saturation = 4095.0") && m.contains("dark_level = 32.0"));
    assert!(tmp.path().join("a/scene.toml").is_file());
    // Existing outputs are kept without --force.
    let o = tmp.path().join("a");
    let out = polarid(&["simulate", sc.to_str().unwrap(), "-o", o.to_str().unwrap()]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("--force"));
}

#[test]
fn simulate_scene_errors_name_line_and_field_and_create_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(scene("aluminum_test_60")).unwrap();
    let cases: &[(&str, &str, &str, &str)] = &[
        ("sigma = 0.30", "sigma = -0.3", "plate[1].sigma", "sigma"),
        (
            "theta_r_deg = 60.0",
            "theta_r_deg = 90.0",
            "theta_r_deg",
            "theta_r_deg",
        ),
        (
            "fraction = 0.7",
            "fraction = 1.7",
            "exposure.fraction",
            "fraction",
        ),
        ("bit_depth = 12", "bit_depht = 12", "bit_depht", "bit_depht"),
        (
            "region = [16, 16, 96, 96]",
            "region = [16, 16, 200, 96]",
            "plate[1].region",
            "region",
        ),
        ("seed = 2067", "seed = \"x\"", "seed", "seed"),
    ];
    for (from, to, field, key) in cases {
        assert!(good.contains(from), "{from}");
        let text = good.replace(from, to);
        let line = text
            .lines()
            .position(|l| l.trim_start().starts_with(&format!("{key} =")))
            .unwrap()
            + 1;
        let p = tmp.path().join("bad.toml");
        std::fs::write(&p, &text).unwrap();
        let out_dir = tmp.path().join("out");
        let out = polarid(&[
            "simulate",
            p.to_str().unwrap(),
            "-o",
            out_dir.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{to}: {err}");
        assert!(
            err.contains(&format!("line {line},")) && err.contains(&format!("`{field}`")),
            "{to}: expected line {line} and field {field}: {err}"
        );
        assert!(!out_dir.exists(), "{to}: output directory created");
        let left: Vec<_> = std::fs::read_dir(tmp.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left.len(), 1, "{to}: left {left:?}");
    }
    let out = polarid(&["simulate", "no-such-scene.toml", "-o", "x"]);
    assert_eq!(out.status.code(), Some(2));
}
