//! `classify` / `evaluate` with answers as sets: the CSV columns, one / several / no
//! candidate, the nearest rule beside it, coverage in `evaluate`, and bad options.

use crate::common;

use common::{csv_rows, polarid_in, text};

const HEADER: &str = "target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n";

fn setup(dir: &std::path::Path) {
    std::fs::write(
        dir.join("lib.csv"),
        "name,n,k,category\nalpha,1.20,7.00,metal\nbeta,1.30,6.90,metal\n\
         gamma,0.20,3.50,metal\nglass,1.50,0.00,dielectric\nsilicon,3.88,0.02,semiconductor\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("fits.csv"),
        format!(
            "{HEADER}ONE,gamma,0.22,3.45,0.05,0.05,0,0.001,9,ok\n\
             TWO,alpha,1.25,6.95,0.1,0.1,0,0.001,9,ok\n\
             NONE,silicon,2.5,2.0,0.02,0.02,0,0.001,9,ok\n\
             GLASS,glass,1.51,0.0,0.02,0.03,0.2,0.001,9,ok\n\
             BAD,glass,1.5,0.0,0.02,0.03,0.2,0.001,9,depolarized\n"
        ),
    )
    .unwrap();
}

#[test]
fn set_rule_is_the_default_with_candidates_and_category() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    setup(d);
    let o = polarid_in(
        d,
        &[
            "classify",
            "fits.csv",
            "--library",
            "lib.csv",
            "-o",
            "c.csv",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let head = std::fs::read_to_string(d.join("c.csv")).unwrap();
    assert!(head.starts_with(
        "target,class,predicted,distance,runner_up,runner_up_distance,status,candidates,"
    ));
    let r = csv_rows(&d.join("c.csv"));
    let get = |t: &str, c: &str| r.iter().find(|x| x["target"] == t).unwrap()[c].clone();
    assert_eq!(get("ONE", "predicted"), "gamma");
    assert_eq!(get("ONE", "status"), "ok");
    assert_eq!(get("ONE", "candidates"), "gamma");
    assert_eq!(get("ONE", "category"), "metal");
    assert_eq!(get("TWO", "predicted"), "ambiguous");
    assert_eq!(get("TWO", "status"), "ambiguous");
    assert_eq!(get("TWO", "category"), "metal");
    let c2 = get("TWO", "candidates");
    assert!(c2 == "alpha;beta" || c2 == "beta;alpha", "{c2}");
    assert_eq!(get("NONE", "predicted"), "unknown");
    assert_eq!(get("NONE", "status"), "rejected");
    assert_eq!(get("NONE", "candidates"), "");
    assert_eq!(get("GLASS", "predicted"), "glass");
    assert_eq!(get("GLASS", "category"), "dielectric");
    assert_eq!(get("BAD", "status"), "fit_depolarized");
    assert_eq!(get("ONE", "rule"), "set");
    assert_eq!(get("ONE", "metric"), "mahalanobis");
    assert_eq!(get("ONE", "confidence"), "0.95");
    let err = text(&o.stderr);
    assert!(
        err.contains("1 ambiguous") && err.contains("consistent at 95%"),
        "{err}"
    );
    assert!(
        err.contains("alpha (metal)") && err.contains("all metal"),
        "{err}"
    );
}

#[test]
fn nearest_rule_keeps_the_nearest_and_reports_the_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    setup(d);
    let args = [
        "classify",
        "fits.csv",
        "--library",
        "lib.csv",
        "--rule",
        "nearest",
        "-o",
        "n.csv",
    ];
    let o = polarid_in(d, &args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let r = csv_rows(&d.join("n.csv"));
    let two = r.iter().find(|x| x["target"] == "TWO").unwrap();
    assert_eq!(two["predicted"], "alpha");
    assert_eq!(two["status"], "ok");
    assert_eq!(two["rule"], "nearest");
    assert_eq!(two["metric"], "euclidean");
    assert_eq!(two["candidates"].split(';').count(), 2);
    let none = r.iter().find(|x| x["target"] == "NONE").unwrap();
    assert_ne!(none["predicted"], "unknown");
    // A smaller confidence shrinks TWO's set (never grows it).
    let o = polarid_in(
        d,
        &[
            "classify",
            "fits.csv",
            "--library",
            "lib.csv",
            "--confidence",
            "0.2",
            "-o",
            "s.csv",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let r = csv_rows(&d.join("s.csv"));
    let two = r.iter().find(|x| x["target"] == "TWO").unwrap();
    assert_eq!(two["candidates"].split(';').count(), 1, "{two:?}");
    assert_eq!(two["confidence"], "0.2");
}

#[test]
fn bad_options_exit_2_naming_option_and_value() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    setup(d);
    for (args, want) in [
        (vec!["--confidence", "1.5"], vec!["--confidence", "1.5"]),
        (vec!["--confidence", "0"], vec!["--confidence", "0"]),
        (
            vec!["--metric", "euclidean"],
            vec!["--metric", "euclidean", "--rule nearest"],
        ),
        (vec!["--k", "3"], vec!["--k", "3"]),
        (vec!["--reject", "0.99"], vec!["--reject", "0.99"]),
    ] {
        let mut a = vec![
            "classify",
            "fits.csv",
            "--library",
            "lib.csv",
            "-o",
            "x.csv",
        ];
        a.extend(args.iter());
        let o = polarid_in(d, &a);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o.stderr));
        let err = text(&o.stderr);
        for w in want {
            assert!(err.contains(w), "{args:?}: {err}");
        }
        assert!(!d.join("x.csv").exists());
    }
    let o = polarid_in(d, &["evaluate", "fits.csv", "--confidence", "1.5"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("--confidence"));
}

#[test]
fn evaluate_reports_coverage_and_set_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("fits.csv"),
        format!(
            "{HEADER}A1,al,1.60,4.50,0.1,0.1,0,0.001,9,ok\n\
             A2,al,1.55,4.45,0.1,0.1,0,0.001,9,ok\n\
             C1,cu,0.50,3.20,0.1,0.1,0,0.001,9,ok\n\
             C2,cu,0.55,3.15,0.1,0.1,0,0.001,9,ok\n\
             X1,x,0.52,3.18,0.1,0.1,0,0.001,9,ok\n\
             X2,x,9.0,9.0,0.1,0.1,0,0.001,9,ok\n"
        ),
    )
    .unwrap();
    let o = polarid_in(d, &["evaluate", "fits.csv", "-o", "e.json"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(
        out.contains("sets at 95%: coverage 0.6667 (4/6), mean size 1.17; one: 3 (2 correct), several: 2, none: 1"),
        "{out}"
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("e.json")).unwrap()).unwrap();
    assert_eq!(j["rule"], "set");
    assert_eq!(j["sets"]["covered"], 4);
    assert_eq!(j["sets"]["several"], 2);
}
