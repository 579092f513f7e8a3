//! `polarid fit`: measurements CSV in, fits CSV out (docs/FORMATS.md).

use crate::common;

use common::polarid_cmd;

use std::path::Path;

use polarid_core::dop::dop;

/// Measurement rows of a target at θr = 60°, θi = 35…80° (DoLP from eq. 9).
fn rows(target: &str, class: &str, n: f64, k: f64, theta_is: &[f64], se: bool) -> String {
    let mut s = String::new();
    for &ti in theta_is {
        let beta = (ti + 60.0) / 2.0;
        let p = dop(n, k, f64::to_radians(beta));
        let se = if se {
            "0.001".to_string()
        } else {
            String::new()
        };
        s.push_str(&format!(
            "{target},{class},{ti},60,180,{beta},{p:.12},{se},1000,100,0\n"
        ));
    }
    s
}

const HEADER: &str =
    "target,class,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,dolp_se,s0,pixels,rejected\n";

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn all_angles() -> Vec<f64> {
    (0..10).map(|i| 35.0 + 5.0 * i as f64).collect()
}

#[test]
fn fits_targets_in_first_appearance_order() {
    let dir = tempfile::tempdir().unwrap();
    let a = all_angles();
    // Interleave the rows of two targets; B (copper) appears first.
    let cu = rows("B", "copper", 0.4, 2.95, &a, false);
    let gp = rows("A", "paint", 1.39, 0.34, &a, true);
    let mut text = String::from("# a comment\n");
    text.push_str(HEADER);
    for (l1, l2) in cu.lines().zip(gp.lines()) {
        text.push_str(l1);
        text.push('\n');
        text.push_str(l2);
        text.push('\n');
    }
    let input = write(dir.path(), "m.csv", &text);
    let out = dir.path().join("fits.csv");
    let st = polarid_cmd()
        .args(["fit", input.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let fits = polarid_io::table::fits::read(&out).unwrap();
    assert_eq!(fits.len(), 2);
    assert_eq!(fits[0].target, "B");
    assert_eq!(fits[0].class.as_deref(), Some("copper"));
    assert!(
        (fits[0].n - 0.4).abs() < 1e-6 && (fits[0].k - 2.95).abs() < 1e-6,
        "{:?}",
        fits[0]
    );
    assert_eq!(fits[1].target, "A");
    assert!(
        (fits[1].n - 1.39).abs() < 1e-6 && (fits[1].k - 0.34).abs() < 1e-6,
        "{:?}",
        fits[1]
    );
    for f in &fits {
        assert_eq!(f.status, polarid_core::FitStatus::Ok);
        assert_eq!(f.measurements, 10);
        assert_eq!(f.model, "specular");
        assert!(f.n_se.is_finite() && f.k_se.is_finite() && f.nk_corr.abs() <= 1.0);
    }
    // Weighted (dolp_se given) fit of exact data: standard errors from the se.
    assert!(fits[1].k_se > 1e-5, "{:?}", fits[1]);
    // Column order of FORMATS.md.
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.starts_with("target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status")
    );
    // Without -o: to standard output.
    let st = polarid_cmd()
        .args(["fit", input.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(st.status.success());
    assert_eq!(String::from_utf8_lossy(&st.stdout), text);
}

#[test]
fn box_options_and_at_bound_status() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!(
        "{HEADER}{}",
        rows("Cu", "", 0.4, 2.95, &all_angles(), false)
    );
    let input = write(dir.path(), "m.csv", &text);
    let st = polarid_cmd()
        .args(["fit", input.to_str().unwrap(), "--k-range", "0,2"])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let out = String::from_utf8_lossy(&st.stdout);
    let line = out.lines().nth(1).unwrap();
    assert!(line.contains(",at_bound,"), "{line}");
    let st = polarid_cmd()
        .args(["fit", input.to_str().unwrap(), "--n-range", "3,1"])
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(2));
}

fn expect_bad(text: &str, needles: &[&str], extra: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "m.csv", text);
    let out = dir.path().join("fits.csv");
    let st = polarid_cmd()
        .args(["fit", input.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(extra)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&st.stderr);
    assert_eq!(st.status.code(), Some(2), "{err}");
    for n in needles {
        assert!(err.contains(n), "{n:?} not in {err}");
    }
    assert!(!out.exists(), "partial output left behind");
}

#[test]
fn bad_input_is_exit_2_and_names_the_fault() {
    let a = all_angles();
    // Fewer than 3 measurements for a target.
    let text = format!(
        "{HEADER}{}{}",
        rows("good", "", 1.5, 0.5, &a, false),
        rows("short", "", 1.5, 0.5, &a[..2], false)
    );
    // With --strict: without it the target gets an invalid_input row (partial_failure.rs).
    expect_bad(
        &text,
        &["short", "at least 3", "lines 12, 13"],
        &["--strict"],
    );
    // Non-finite DoLP.
    let mut text = format!("{HEADER}{}", rows("T", "", 1.5, 0.5, &a, false));
    text = text.replacen(
        ",1000,100,0\n",
        ",1000,100,0\nT,,50,60,180,55,nan,,1000,100,0\n",
        1,
    );
    expect_bad(&text, &["line 3", "dolp"], &[]);
    // DoLP outside [0, 1].
    let text = format!(
        "{HEADER}{}T,,50,60,180,55,1.5,,1000,100,0\n",
        rows("T", "", 1.5, 0.5, &a, false)
    );
    expect_bad(&text, &["line 12", "dolp", "1.5"], &[]);
    // Mixed reflectance needs a positive s0 on every row.
    let text = format!("{HEADER}{}", rows("T", "", 1.5, 0.5, &a, false)).replacen(
        ",1000,100,0\n",
        ",0,100,0\n",
        1,
    );
    expect_bad(&text, &["line 2", "s0", "T"], &["--reflectance", "mixed"]);
    // Missing file.
    let st = polarid_cmd()
        .args(["fit", "/nonexistent/m.csv"])
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(2));
}
