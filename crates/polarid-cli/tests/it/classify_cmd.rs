//! `polarid train`, `classify`, `evaluate`: outputs, explanations, exit statuses and
//! messages.

use crate::common;

use common::{polarid_in, text};

use std::path::{Path, PathBuf};

const HEADER: &str = "target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n";

/// Paper Table 1 estimates as a fits CSV (plus an unusable fit).
fn write_training(dir: &Path) -> PathBuf {
    let p = dir.join("train.csv");
    std::fs::write(
        &p,
        format!(
            "{HEADER}G,green paint,1.47,0.47,0.05,0.05,0.1,0.001,9,ok\n\
             A,aluminum,1.64,4.56,0.2,0.3,0.5,0.001,10,ok\n\
             C,copper,0.54,3.19,0.1,0.2,0.3,0.001,8,ok\n\
             X,copper,nan,nan,nan,nan,nan,nan,3,not_converged\n"
        ),
    )
    .unwrap();
    p
}

/// Paper Table 2 estimates, plus a fit that must not be classified.
fn write_test(dir: &Path) -> PathBuf {
    let p = dir.join("test.csv");
    std::fs::write(
        &p,
        format!(
            "{HEADER}T60,aluminum,1.37,3.97,0.2,0.3,0.4,0.001,10,ok\n\
             T50,aluminum,1.60,4.34,0.2,0.3,0.4,0.001,10,ok\n\
             B,,1.5,0.2,0.1,0.1,0,0.01,3,depolarized\n"
        ),
    )
    .unwrap();
    p
}

fn rows(csv: &str) -> Vec<Vec<String>> {
    csv.lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let mut rdr = csv::ReaderBuilder::new()
                .has_headers(false)
                .from_reader(l.as_bytes());
            rdr.records()
                .next()
                .unwrap()
                .unwrap()
                .iter()
                .map(String::from)
                .collect()
        })
        .collect()
}

fn col(rows: &[Vec<String>], name: &str) -> usize {
    rows[0].iter().position(|h| h == name).unwrap()
}

#[test]
fn classify_train_then_classify_reproduces_paper_table2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_training(d);
    write_test(d);
    let o = polarid_in(
        d,
        &["train", "train.csv", "-o", "model.json", "--allow-not-ok"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(
        err.contains("skipped labelled fit X (not_converged"),
        "{err}"
    );
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("model.json")).unwrap()).unwrap();
    assert_eq!(model["format_version"], 1);
    let protos = model["prototypes"].as_array().unwrap();
    assert_eq!(protos.len(), 3);
    assert_eq!(protos[1]["class"], "aluminum");
    assert_eq!(protos[1]["source"]["file"], "train.csv");
    assert_eq!(protos[1]["source"]["line"], 3);
    assert_eq!(protos[1]["source"]["target"], "A");

    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--model",
            "model.json",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    let r = rows(&out);
    assert_eq!(
        r[0][..7].join(","),
        "target,class,predicted,distance,runner_up,runner_up_distance,status"
    );
    let (p, s, ru) = (
        col(&r, "predicted"),
        col(&r, "status"),
        col(&r, "runner_up"),
    );
    assert_eq!(r[1][p], "aluminum");
    assert_eq!(r[2][p], "aluminum");
    assert_eq!(r[1][ru], "copper");
    assert_eq!(r[1][s], "ok");
    let dist: f64 = r[2][col(&r, "distance")].parse().unwrap();
    assert!((dist - 0.04f64.hypot(0.22)).abs() < 1e-12);
    // The depolarized fit is not classified, and says why.
    assert_eq!(r[3][p], "unknown");
    assert_eq!(r[3][s], "fit_depolarized");
    assert!(r[3][col(&r, "reason")].contains("depolarized"));
    assert_eq!(r[3][col(&r, "distance")], "");
}

#[test]
fn classify_with_builtin_library_says_metal_and_why() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_test(d);
    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "builtin",
            "-o",
            "c.csv",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let r = rows(&std::fs::read_to_string(d.join("c.csv")).unwrap());
    let c = col(&r, "category");
    assert_eq!(r[1][c], "metal");
    assert_eq!(r[2][c], "metal");
    let err = text(&o.stderr);
    assert!(err.contains("T60: nickel, classified as a metal"), "{err}");
    assert!(
        err.contains("nearest: nickel (metal) 0.6720, lead (metal) 0.7095"),
        "{err}"
    );
    assert!(
        err.contains("nearest non-metal: graphite_o (other)"),
        "{err}"
    );
    // Output exists: refused without --force (exit 2), accepted with it.
    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "builtin",
            "-o",
            "c.csv",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("output exists"));
    let o = polarid_in(
        d,
        &[
            "--force",
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "builtin",
            "-o",
            "c.csv",
        ],
    );
    assert!(o.status.success());
}

#[test]
fn classify_mahalanobis_reject_and_user_library() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_test(d);
    // A user library with n_band/k_band columns only.
    std::fs::write(
        d.join("lib.csv"),
        "# my filter\nname,category,n_band,k_band\nal_oxidized,metal,1.5,4.2\nglass,dielectric,1.5,0\n",
    )
    .unwrap();
    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "lib.csv",
            "--metric",
            "mahalanobis",
            "--reject",
            "0.99",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let r = rows(&text(&o.stdout));
    let (p, s, g) = (col(&r, "predicted"), col(&r, "status"), col(&r, "gate"));
    // T50: Δ = (0.1, 0.14) with n_se 0.2, k_se 0.3, ρ 0.4: well inside the gate.
    assert_eq!(r[2][p], "al_oxidized");
    assert_eq!(r[2][s], "ok");
    assert_eq!(r[2][col(&r, "metric")], "mahalanobis");
    // T60: Δ = (−0.13, −0.23): also inside; gate value is the Mahalanobis distance.
    let gate: f64 = r[1][g].parse().unwrap();
    let (sn, sk, rho) = (0.2, 0.3, 0.4);
    let (dn, dk): (f64, f64) = (1.37 - 1.5, 3.97 - 4.2);
    let det = sn * sn * sk * sk * (1.0 - rho * rho);
    let q = (sk * sk * dn * dn - 2.0 * rho * sn * sk * dn * dk + sn * sn * dk * dk) / det;
    assert!((gate - q.sqrt()).abs() < 1e-12, "{gate}");
    // A tight Euclidean threshold rejects both.
    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "lib.csv",
            "--max-distance",
            "0.05",
        ],
    );
    let r = rows(&text(&o.stdout));
    assert_eq!(r[1][col(&r, "predicted")], "unknown");
    assert_eq!(r[1][col(&r, "status")], "rejected");
    assert_eq!(r[1][col(&r, "nearest")], "al_oxidized");
    // Bad options are usage errors.
    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "lib.csv",
            "--reject",
            "1.5",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("1.5"), "{}", text(&o.stderr));
    let o = polarid_in(d, &["classify", "--rule", "nearest", "test.csv"]);
    assert_eq!(o.status.code(), Some(2));
    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "missing.csv",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("missing.csv"));
}

#[test]
fn classify_with_wolff_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_test(d);
    // DoLP of the paper's estimates at beta = 47.5..70 deg from eq. (9), written by hand:
    // a metal-like target (aluminum estimate) and a dielectric-like one (green paint).
    let mut m = String::from("target,beta_deg,dolp\n");
    for b in [47.5f64, 52.5, 57.5, 62.5, 67.5] {
        let p_al = polarid_core::dop::dop(1.60, 4.34, b.to_radians());
        let p_gp = polarid_core::dop::dop(1.47, 0.47, b.to_radians());
        m.push_str(&format!("T50,{b},{p_al}\nB,{b},{p_gp}\n"));
    }
    std::fs::write(d.join("meas.csv"), m).unwrap();
    let o = polarid_in(
        d,
        &[
            "classify",
            "--rule",
            "nearest",
            "test.csv",
            "--library",
            "builtin",
            "--wolff",
            "meas.csv",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let r = rows(&text(&o.stdout));
    let w = col(&r, "wolff_class");
    assert_eq!(r[1][w], "unknown"); // T60 has no measurements
    assert_eq!(r[2][w], "metal");
    assert_eq!(r[3][w], "dielectric"); // Wolff works from DoLP, even for the unusable fit
    let fr: f64 = r[2][col(&r, "wolff_fr_max")].parse().unwrap();
    let p = polarid_core::dop::dop(1.60, 4.34, 67.5f64.to_radians());
    assert!((fr - (1.0 + p) / (1.0 - p)).abs() < 1e-9, "{fr}");
    // A negative prior weight is a usage error naming the prior and its value.
    let o = polarid_in(
        d,
        &[
            "classify",
            "meas.csv",
            "--library",
            "builtin",
            "--prior",
            "aluminum=-1",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    let e = text(&o.stderr);
    assert!(
        e.contains("prior weights must be finite and >= 0, got aluminum=-1"),
        "{e}"
    );
}

#[test]
fn classify_train_exit_statuses_and_messages() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // No labelled ok fit: exit 2, message names the file and why.
    std::fs::write(
        d.join("nolabel.csv"),
        format!("{HEADER}A,,1.5,4.4,0.1,0.1,0,0,5,ok\nB,copper,nan,nan,nan,nan,nan,nan,3,ill_conditioned\n"),
    )
    .unwrap();
    let o = polarid_in(
        d,
        &["train", "nolabel.csv", "-o", "m.json", "--allow-not-ok"],
    );
    assert_eq!(o.status.code(), Some(2));
    let e = text(&o.stderr);
    assert!(
        e.contains("nolabel.csv")
            && e.contains("nothing to train on")
            && e.contains("B (ill_conditioned"),
        "{e}"
    );
    assert!(!d.join("m.json").exists());
    // Empty training file.
    std::fs::write(d.join("empty.csv"), HEADER).unwrap();
    let o = polarid_in(d, &["train", "empty.csv", "-o", "m.json"]);
    assert_eq!(o.status.code(), Some(2));
    // Reserved class name.
    std::fs::write(
        d.join("reserved.csv"),
        format!("{HEADER}A,unknown,1.5,4.4,0.1,0.1,0,0,5,ok\n"),
    )
    .unwrap();
    let o = polarid_in(d, &["train", "reserved.csv", "-o", "m.json"]);
    assert_eq!(o.status.code(), Some(2));
    let e = text(&o.stderr);
    assert!(
        e.contains("line 2") && e.contains("class") && e.contains("reserved"),
        "{e}"
    );
    // Model of another version: exit 2 naming the version.
    write_training(d);
    write_test(d);
    assert!(
        polarid_in(d, &["train", "train.csv", "-o", "m.json", "--allow-not-ok"])
            .status
            .success()
    );
    let m = std::fs::read_to_string(d.join("m.json"))
        .unwrap()
        .replace("\"format_version\": 1", "\"format_version\": 7");
    std::fs::write(d.join("m7.json"), m).unwrap();
    let o = polarid_in(
        d,
        &[
            "classify", "--rule", "nearest", "test.csv", "--model", "m7.json",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    let e = text(&o.stderr);
    assert!(e.contains("m7.json") && e.contains("version 7"), "{e}");
    assert!(o.stdout.is_empty());
}

#[test]
fn classify_evaluate_leave_one_out() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("set.csv"),
        format!(
            "{HEADER}a1,aluminum,1.64,4.56,0.1,0.1,0,0,9,ok\n\
             a2,aluminum,1.37,3.97,0.1,0.1,0,0,9,ok\n\
             a3,aluminum,1.60,4.34,0.1,0.1,0,0,9,ok\n\
             c1,copper,0.54,3.19,0.1,0.1,0,0,9,ok\n\
             c2,copper,0.45,3.30,0.1,0.1,0,0,9,ok\n\
             g1,green paint,1.47,0.47,0.1,0.1,0,0,9,ok\n\
             g2,green paint,1.39,0.34,0.1,0.1,0,0,9,ok\n\
             bad,copper,nan,nan,nan,nan,nan,nan,2,not_converged\n\
             u,,1.0,1.0,0.1,0.1,0,0,9,ok\n"
        ),
    )
    .unwrap();
    let o = polarid_in(
        d,
        &["evaluate", "--rule", "nearest", "set.csv", "-o", "cm.csv"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("accuracy: 1.0000 (7/7)"), "{out}");
    assert!(
        out.contains("skipped bad: fit status `not_converged`"),
        "{out}"
    );
    let cm = std::fs::read_to_string(d.join("cm.csv")).unwrap();
    assert!(
        cm.starts_with("# leave-one-out, rule nearest, metric euclidean, k = 1: accuracy 1 (7/7)"),
        "{cm}"
    );
    let r = rows(&cm);
    assert_eq!(r[0].join(","), "truth,aluminum,copper,green paint,total");
    assert_eq!(r[1].join(","), "aluminum,3,0,0,3");
    assert_eq!(r[2].join(","), "copper,0,2,0,2");
    // JSON output.
    let o = polarid_in(
        d,
        &[
            "evaluate", "--rule", "nearest", "set.csv", "-o", "cm.json", "--k", "3",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("cm.json")).unwrap()).unwrap();
    assert_eq!(j["k"], 3);
    assert_eq!(j["total"], 7);
    assert_eq!(j["skipped"][0]["target"], "bad");
    // With k = 3 a lone green-paint neighbour is outvoted: the three nearest of g1 are g2
    // (0.15), c1 (2.88) and c2 (3.01), so copper wins 2 votes to 1.
    assert_eq!(j["predicted"].as_array().unwrap().len(), 3);
    let items = j["items"].as_array().unwrap();
    let g1 = items.iter().find(|i| i["target"] == "g1").unwrap();
    assert_eq!(g1["predicted"], "copper");
}

#[test]
fn classify_evaluate_against_model_names_unknown_classes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_training(d);
    assert!(
        polarid_in(d, &["train", "train.csv", "-o", "m.json", "--allow-not-ok"])
            .status
            .success()
    );
    std::fs::write(
        d.join("held.csv"),
        format!(
            "{HEADER}t1,aluminum,1.37,3.97,0.1,0.1,0,0,9,ok\n\
             t2,brass,0.45,3.69,0.1,0.1,0,0,9,ok\n"
        ),
    )
    .unwrap();
    let o = polarid_in(
        d,
        &[
            "evaluate", "--rule", "nearest", "held.csv", "--model", "m.json",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("accuracy: 0.5000 (1/2)"), "{out}");
    assert!(out.contains("class `brass` has no prototype"), "{out}");
    // A class named `unknown` in the evaluation set is refused (exit 2).
    std::fs::write(
        d.join("bad.csv"),
        format!(
            "{HEADER}t1,Unknown,1.37,3.97,0.1,0.1,0,0,9,ok\nt2,aluminum,1.6,4.3,0.1,0.1,0,0,9,ok\n"
        ),
    )
    .unwrap();
    let o = polarid_in(d, &["evaluate", "--rule", "nearest", "bad.csv"]);
    assert_eq!(o.status.code(), Some(2));
    let e = text(&o.stderr);
    assert!(
        e.contains("bad.csv") && e.contains("Unknown") && e.contains("reserved"),
        "{e}"
    );
    // No labelled rows at all.
    std::fs::write(
        d.join("none.csv"),
        format!("{HEADER}t1,,1.37,3.97,0.1,0.1,0,0,9,ok\n"),
    )
    .unwrap();
    let o = polarid_in(d, &["evaluate", "--rule", "nearest", "none.csv"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("no labelled fits"));
}
