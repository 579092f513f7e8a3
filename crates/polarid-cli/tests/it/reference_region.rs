//! `polarid classify MEASUREMENTS.csv` with an in-scene reference (the `reference`
//! column): the reference is reported as its material with what it measured, the
//! explanation shows the calibration, and `--report` tabulates the references and every
//! tested material with the layer thickness and scale it needed.

use crate::common;

use common::{csv_rows, polarid_in, text};

/// An N-BK7 slide and an aluminium target seen through an analyzer of scale 0.9 with a
/// common offset of +0.3°, eight captures (β 47.5–70°), a ±0.002 pattern for noise.
fn measurements() -> String {
    let mut s = String::from("target,beta_deg,dolp,dolp_se,angle_sd_deg,reference\n");
    let off = 0.3f64.to_radians();
    for (target, (n, k), reference) in [
        ("slide", (1.5145, 0.0), "N-BK7"),
        ("plate", (1.55803, 7.7124), ""),
    ] {
        for i in 0..8 {
            let beta = 47.5 + 22.5 * i as f64 / 7.0;
            let y = 0.9 * polarid_core::dop::dop(n, k, beta.to_radians() + off)
                + if i % 2 == 0 { 0.002 } else { -0.002 };
            s.push_str(&format!("{target},{beta},{y:.6},0.003,0.2,{reference}\n"));
        }
    }
    s
}

#[test]
fn a_reference_calibrates_and_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.csv"), measurements()).unwrap();
    let out = polarid_in(
        dir.path(),
        &[
            "classify",
            "m.csv",
            "--library",
            "builtin",
            "-o",
            "c.csv",
            "--report",
            "rep",
        ],
    );
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    // The explanation: the reference's calibration and the boxes it leaves.
    assert!(
        err.contains("slide: in-scene reference N-BK7: scale 0.9"),
        "{err}"
    );
    assert!(
        err.contains("the other targets are tested with scale in"),
        "{err}"
    );
    assert!(
        err.contains("calibrated by the in-scene reference"),
        "{err}"
    );
    // A scale of 0.9 is outside the default error model's (100:1): said.
    assert!(err.contains("worse than its error model"), "{err}");
    let rows = csv_rows(&dir.path().join("c.csv"));
    let slide = rows.iter().find(|r| r["target"] == "slide").unwrap();
    assert_eq!(slide["status"], "reference");
    assert_eq!(slide["predicted"], "N-BK7");
    assert!(slide["reason"].contains("scale 0.9"), "{slide:?}");
    let plate = rows.iter().find(|r| r["target"] == "plate").unwrap();
    assert!(plate["candidates"].contains("aluminum"), "{plate:?}");
    let html = std::fs::read_to_string(dir.path().join("rep/report.html")).unwrap();
    for s in ["In-scene references", "Layer (nm)", "Scale", "aluminum"] {
        assert!(html.contains(s), "{s} not in the report");
    }
    // Without the column the slide is one more target, tested like the others, and
    // nothing is calibrated.
    let plain = measurements().replace(",N-BK7\n", ",\n");
    std::fs::write(dir.path().join("p.csv"), plain).unwrap();
    let out = polarid_in(
        dir.path(),
        &["classify", "p.csv", "--library", "builtin", "-o", "q.csv"],
    );
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(!err.contains("in-scene reference"), "{err}");
    let rows = csv_rows(&dir.path().join("q.csv"));
    let slide = rows.iter().find(|r| r["target"] == "slide").unwrap();
    assert_eq!(slide["rule"], "hypothesis", "{slide:?}");
}
