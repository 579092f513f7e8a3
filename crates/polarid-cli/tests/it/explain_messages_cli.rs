//! `classify`'s explanation shows the confidence region and the candidates (issue 16);
//! `--wolff-beta MIN,MAX` is one word in degrees and its errors say degrees; a failed
//! write to standard output says so (issue 19).

use crate::common;

use common::{polarid_in, text};

const HEADER: &str = "target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n";

fn setup(dir: &std::path::Path) {
    std::fs::write(
        dir.join("lib.csv"),
        "name,n,k,category\nalpha,1.20,7.00,metal\nbeta,1.30,6.90,metal\n\
         gamma,0.20,3.50,metal\nglass,1.50,0.00,dielectric\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("fits.csv"),
        format!(
            "{HEADER}TWO,alpha,1.25,6.95,0.1,0.1,0,0.001,9,ok\n\
             NONE,,2.5,2.0,0.02,0.02,0,0.001,9,ok\n\
             GLASS,glass,1.51,0.0,0.02,0.03,0.2,0.001,9,ok\n"
        ),
    )
    .unwrap();
    // Measurements for Wolff's rule: one target, DoLP of glass-like and metal-like rows.
    let mut m = String::from("target,class,capture,beta_deg,dolp,dolp_se\n");
    for (i, b) in [35.0, 45.0, 55.0, 65.0].iter().enumerate() {
        m.push_str(&format!(
            "TWO,alpha,{i},{b},0.1,0.01\nGLASS,glass,{i},{b},0.9,0.01\n"
        ));
    }
    std::fs::write(dir.join("meas.csv"), m).unwrap();
}

#[test]
fn explanation_shows_region_candidates_and_answer() {
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
    let err = text(&o.stderr);
    let line = |t: &str| {
        err.lines()
            .find(|l| l.starts_with(&format!("{t}: ")))
            .unwrap_or_else(|| panic!("no explanation for {t}: {err}"))
            .to_string()
    };
    // Two metals within the 95% region of n 1.25 ± 2.448 · 0.1.
    let two = line("TWO");
    assert!(two.starts_with("TWO: ambiguous"), "{two}");
    assert!(
        two.contains("consistent at 95% (Mahalanobis <= 2.448): alpha (metal)")
            && two.contains("beta (metal)")
            && two.contains("all metal"),
        "{two}"
    );
    assert!(
        two.contains("95% region (Mahalanobis <= 2.448): n 1.005–1.495, k 6.705–7.195 in (n, k)"),
        "{two}"
    );
    let none = line("NONE");
    assert!(
        none.starts_with("NONE: unknown") && none.contains("): none"),
        "{none}"
    );
    assert!(none.contains("95% region"), "{none}");
    // Near k = 0: the region is in (n, u = k²) and never below k = 0.
    let glass = line("GLASS");
    assert!(glass.starts_with("GLASS: glass"), "{glass}");
    assert!(
        glass.contains("in (n, u = k²)") && glass.contains(", k 0.000–"),
        "{glass}"
    );
}

#[test]
fn wolff_beta_is_one_word_in_degrees() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    setup(d);
    let base = [
        "classify",
        "fits.csv",
        "--library",
        "lib.csv",
        "--wolff",
        "meas.csv",
    ];
    let run = |extra: &[&str], out: &str| {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        a.extend_from_slice(&["-o", out]);
        polarid_in(d, &a)
    };
    let o = run(&["--wolff-beta", "40,70"], "a.csv");
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o2 = run(&[], "b.csv");
    assert!(o2.status.success());
    assert_eq!(
        std::fs::read(d.join("a.csv")).unwrap(),
        std::fs::read(d.join("b.csv")).unwrap(),
        "40,70 is the default"
    );
    assert!(text(&o.stderr).contains("beta in [40, 70] deg"));
    let o = run(&["--wolff-beta", "30,60"], "c.csv");
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("beta in [30, 60] deg"));
    for (bad, want) in [
        ("70,40", "MIN must be <= MAX, got \"70,40\" degrees"),
        ("40,95", "beta must be in [0, 90] degrees"),
        ("40", "expected MIN,MAX in degrees (one word)"),
        ("40,nan", "is not finite"),
    ] {
        let o = run(&["--wolff-beta", bad], "x.csv");
        assert_eq!(o.status.code(), Some(2), "{bad}");
        let e = text(&o.stderr);
        assert!(e.contains("--wolff-beta") && e.contains(want), "{bad}: {e}");
        assert!(!e.contains("radian"), "{e}");
        assert!(!d.join("x.csv").exists());
    }
    let o = run(&["--wolff-threshold", "0.5"], "x.csv");
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("--wolff-threshold must be a finite number > 1, got 0.5"),
        "{}",
        text(&o.stderr)
    );
    let help = text(&polarid_in(d, &["classify", "--help"]).stdout);
    assert!(
        help.contains("--wolff-beta <MIN,MAX>") && help.contains("[default: 40,70]"),
        "{help}"
    );
}

#[cfg(target_os = "linux")]
#[test]
fn failed_writes_to_standard_output_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    setup(d);
    for args in [
        &["classify", "fits.csv", "--library", "lib.csv"][..],
        &["evaluate", "fits.csv"][..],
    ] {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let o = common::polarid_cmd()
            .current_dir(d)
            .args(args)
            .stdout(full)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        let e = text(&o.stderr);
        assert!(
            e.contains("polarid: error: cannot write to standard output"),
            "{args:?}: {e}"
        );
    }
}
