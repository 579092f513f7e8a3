//! `polarid evaluate --wolff`: Wolff's metal/dielectric baseline next to the (n, k)
//! classifier's leave-one-out accuracy, on simulated captures (`simulate` → `measure` →
//! `fit`), and its bad-input handling.

use crate::common;

use common::{polarid_in, text};

use std::path::Path;
use std::process::Output;

fn ok(o: &Output, what: &str) {
    assert!(o.status.success(), "{what}: {}", text(&o.stderr));
}

/// One 32 × 32 plate of the scene.
fn plate(name: &str, class: &str, n: f64, k: f64, sigma: f64, x: u32) -> String {
    format!(
        "[[plate]]\nname = \"{name}\"\nclass = \"{class}\"\nn = {n}\nk = {k}\nsigma = {sigma}\n\
         rect = [{x}, 0, 32, 32]\n"
    )
}

/// The paper's plates (Table 1 reference indices) twice each, a glass (N-BK7, a
/// dielectric of the built-in library) twice, and one silicon plate (category
/// `semiconductor`): simulated at θr = 60°, θi = 35…80°, measured and fitted into
/// `meas.csv` and `fits.csv` in `d`.
fn labelled_set(d: &Path) {
    let plates = [
        ("al1", "aluminum", 1.24, 6.60, 0.20),
        ("al2", "aluminum", 1.24, 6.60, 0.25),
        ("cu1", "copper", 0.40, 2.95, 0.15),
        ("cu2", "copper", 0.40, 2.95, 0.20),
        ("bk1", "N-BK7", 1.51, 0.0, 0.20),
        ("bk2", "N-BK7", 1.51, 0.0, 0.25),
        ("gp1", "green paint", 1.39, 0.34, 0.25),
        ("gp2", "green paint", 1.39, 0.34, 0.20),
        ("si", "silicon", 3.85, 0.02, 0.20),
    ];
    let mut scene = format!(
        "name = \"wolff_eval\"\nwidth = {}\nheight = 32\ntheta_r_deg = 60.0\n\
         theta_i_deg = {{ start = 35, stop = 80, step = 5 }}\nseed = 11\n",
        32 * plates.len()
    );
    for (i, (name, class, n, k, sigma)) in plates.iter().enumerate() {
        scene.push_str(&plate(name, class, *n, *k, *sigma, 32 * i as u32));
    }
    std::fs::write(d.join("scene.toml"), scene).unwrap();
    ok(
        &polarid_in(d, &["simulate", "scene.toml", "-o", "sim"]),
        "simulate",
    );
    ok(
        &polarid_in(d, &["measure", "sim/manifest.toml", "-o", "meas.csv"]),
        "measure",
    );
    ok(
        &polarid_in(d, &["fit", "meas.csv", "-o", "fits.csv"]),
        "fit",
    );
}

fn lines_without_comments(s: &str) -> Vec<&str> {
    s.lines().filter(|l| !l.starts_with('#')).collect()
}

#[test]
fn evaluate_reports_wolff_next_to_the_classifier() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    labelled_set(d);

    // Without --wolff: the reference output.
    let base = polarid_in(
        d,
        &[
            "evaluate", "--rule", "nearest", "fits.csv", "-o", "base.csv",
        ],
    );
    ok(&base, "evaluate");
    let base_out = text(&base.stdout);
    assert!(base_out.contains("accuracy: 0.8889 (8/9)"), "{base_out}");
    assert!(!base_out.contains("Wolff"), "{base_out}");

    // Categories from the built-in library: aluminum, copper metal; N-BK7 dielectric;
    // green paint unknown to it and silicon a semiconductor, so neither is scored.
    let o = polarid_in(
        d,
        &[
            "evaluate", "--rule", "nearest", "fits.csv", "--wolff", "meas.csv", "-o", "w.csv",
        ],
    );
    ok(&o, "evaluate --wolff");
    let out = text(&o.stdout);
    // The classifier's part is unchanged.
    assert!(out.starts_with(&base_out), "{out}");
    assert!(
        out.contains("Fresnel ratio threshold 6, beta in [40, 70] deg")
            && out.contains("true categories from library builtin"),
        "{out}"
    );
    assert!(
        out.contains("wolff accuracy (metal/dielectric): 1.0000 (6/6)"),
        "{out}"
    );
    assert!(
        out.contains(
            "nearest neighbour on the same targets: 1.0000 (6/6) by material, 1.0000 (6/6) by \
             metal/dielectric"
        ),
        "{out}"
    );
    assert!(
        out.contains("not scored gp1: class `green paint` has no category"),
        "{out}"
    );
    assert!(
        out.contains("not scored si: class `silicon` has category `semiconductor`"),
        "{out}"
    );
    // The CSV keeps its first line and its table; Wolff's lines are comments.
    let base_csv = std::fs::read_to_string(d.join("base.csv")).unwrap();
    let w_csv = std::fs::read_to_string(d.join("w.csv")).unwrap();
    assert_eq!(base_csv.lines().next(), w_csv.lines().next());
    assert_eq!(
        lines_without_comments(&base_csv),
        lines_without_comments(&w_csv)
    );
    assert!(
        w_csv.contains("# wolff confusion: truth,dielectric,metal,total\n")
            && w_csv.contains("# wolff confusion: dielectric,2,0,2\n")
            && w_csv.contains("# wolff confusion: metal,0,4,4\n")
            && w_csv.contains("accuracy 1 (6/6)"),
        "{w_csv}"
    );

    // Green paint declared a dielectric: scored, and Wolff gets it right; JSON output.
    let o = polarid_in(
        d,
        &[
            "evaluate",
            "--rule",
            "nearest",
            "fits.csv",
            "--wolff",
            "meas.csv",
            "--wolff-category",
            "Green_Paint=dielectric",
            "-o",
            "w.json",
        ],
    );
    ok(&o, "evaluate --wolff --wolff-category");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("w.json")).unwrap()).unwrap();
    assert_eq!(j["total"], 9); // the classifier's fields are unchanged
    assert_eq!(j["correct"], 8);
    let w = &j["wolff"];
    assert_eq!(w["total"], 8);
    assert_eq!(w["correct"], 8);
    assert_eq!(w["accuracy"], 1.0);
    assert_eq!(w["classifier_correct_material"], 8);
    assert_eq!(w["not_scored"].as_array().unwrap().len(), 1);
    let items = w["items"].as_array().unwrap();
    let item = |t: &str| items.iter().find(|i| i["target"] == t).unwrap();
    assert_eq!(item("gp1")["category"], "dielectric");
    assert_eq!(item("gp1")["category_from"], "--wolff-category");
    assert_eq!(item("gp1")["wolff"], "dielectric");
    assert_eq!(item("al1")["category_from"], "library builtin");
    for t in ["al1", "al2", "cu1", "cu2"] {
        assert_eq!(item(t)["wolff"], "metal", "{t}");
        assert!(item(t)["fr_max"].as_f64().unwrap() < 6.0);
    }
    for t in ["bk1", "bk2", "gp1", "gp2"] {
        assert_eq!(item(t)["wolff"], "dielectric", "{t}");
        assert!(item(t)["fr_max"].as_f64().unwrap() > 6.0);
    }
    // The paper's point: Wolff's ratio cannot tell aluminum from copper (their largest
    // Fresnel ratios in the window agree within 2 %), while the (n, k) classifier does.
    let (fa, fc) = (
        item("al1")["fr_max"].as_f64().unwrap(),
        item("cu1")["fr_max"].as_f64().unwrap(),
    );
    assert!((fa - fc).abs() < 0.02 * fa, "{fa} {fc}");
    assert_eq!(item("al1")["predicted"], "aluminum");
    assert_eq!(item("cu1")["predicted"], "copper");
}

#[test]
fn evaluate_wolff_unknown_counts_wrong_and_model_categories_come_first() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    labelled_set(d);
    // cu2 has no measurement: Wolff answers unknown, which counts as wrong.
    let meas = std::fs::read_to_string(d.join("meas.csv")).unwrap();
    let kept: String = meas
        .lines()
        .filter(|l| !l.starts_with("cu2,"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(d.join("meas_no_cu2.csv"), kept).unwrap();
    // A model whose aluminum prototypes carry a category (`train` writes none).
    ok(
        &polarid_in(d, &["train", "fits.csv", "-o", "m.json"]),
        "train",
    );
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("m.json")).unwrap()).unwrap();
    for p in m["prototypes"].as_array_mut().unwrap() {
        if p["class"] == "aluminum" {
            p["category"] = "metal".into();
        }
    }
    std::fs::write(d.join("m.json"), m.to_string()).unwrap();
    let o = polarid_in(
        d,
        &[
            "evaluate",
            "--rule",
            "nearest",
            "fits.csv",
            "--model",
            "m.json",
            "--wolff",
            "meas_no_cu2.csv",
            "-o",
            "w.json",
        ],
    );
    ok(&o, "evaluate --model --wolff");
    let out = text(&o.stdout);
    assert!(
        out.contains("wolff accuracy (metal/dielectric): 0.8333 (5/6)"),
        "{out}"
    );
    assert!(
        out.contains("target cu2 has no row in meas_no_cu2.csv; Wolff answers unknown"),
        "{out}"
    );
    assert!(
        out.contains("true categories from model m.json, library builtin"),
        "{out}"
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("w.json")).unwrap()).unwrap();
    let items = j["wolff"]["items"].as_array().unwrap();
    let item = |t: &str| items.iter().find(|i| i["target"] == t).unwrap();
    assert_eq!(item("cu2")["wolff"], "unknown");
    assert_eq!(item("cu2")["used"], 0);
    assert_eq!(item("al1")["category_from"], "model m.json");
    assert_eq!(item("cu1")["category_from"], "library builtin");
    assert_eq!(
        j["wolff"]["counts"],
        serde_json::json!([[2, 0, 0], [0, 3, 1]])
    );
    assert_eq!(
        j["wolff"]["predicted"],
        serde_json::json!(["dielectric", "metal", "unknown"])
    );
}

#[test]
fn evaluate_wolff_bad_input_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    labelled_set(d);
    let meas = std::fs::read_to_string(d.join("meas.csv")).unwrap();
    let mut lines: Vec<String> = meas.lines().map(String::from).collect();
    // Line 3 (the second data row): a DoLP above 1.
    let mut cells: Vec<&str> = lines[2].split(',').collect();
    cells[6] = "1.5";
    lines[2] = cells.join(",");
    std::fs::write(d.join("bad_dolp.csv"), lines.join("\n") + "\n").unwrap();
    std::fs::write(d.join("no_dolp.csv"), "target,beta_deg\nal1,50\n").unwrap();
    std::fs::write(
        d.join("nan_beta.csv"),
        "target,beta_deg,dolp\nal1,abc,0.1\n",
    )
    .unwrap();

    let cases: [(&[&str], &[&str]); 7] = [
        (
            &["--wolff", "bad_dolp.csv"],
            &["bad_dolp.csv", "line 3", "dolp", "1.5"],
        ),
        (&["--wolff", "no_dolp.csv"], &["no_dolp.csv", "dolp"]),
        (
            &["--wolff", "nan_beta.csv"],
            &["nan_beta.csv", "line 2", "beta_deg", "abc"],
        ),
        (&["--wolff", "missing.csv"], &["missing.csv"]),
        (
            &[
                "--wolff",
                "meas.csv",
                "--wolff-category",
                "green paint=plastic",
            ],
            &["--wolff-category", "green paint=plastic"],
        ),
        (
            &["--wolff", "meas.csv", "--wolff-threshold", "0.5"],
            &["threshold", "0.5"],
        ),
        (
            &["--wolff", "meas.csv", "--wolff-library", "nolib.csv"],
            &["nolib.csv"],
        ),
    ];
    for (extra, needles) in cases {
        let mut args = vec!["evaluate", "--rule", "nearest", "fits.csv", "-o", "out.csv"];
        args.extend_from_slice(extra);
        let o = polarid_in(d, &args);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", text(&o.stderr));
        let e = text(&o.stderr);
        for n in needles {
            assert!(e.contains(n), "{extra:?}: `{n}` not in {e}");
        }
        assert!(o.stdout.is_empty(), "{extra:?}");
        assert!(!d.join("out.csv").exists(), "{extra:?}");
    }
}
