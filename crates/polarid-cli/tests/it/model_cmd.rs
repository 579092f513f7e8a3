//! `polarid model` end to end: it reproduces the oracle files of `data/oracles/`
//! (DoP 1e-12; pBRDF each element 1e-9·m00 in both frames, `dolp` 1e-12), and bad
//! rows give exit status 2, a message naming the file, line, column and value, and no
//! output file.

use crate::common;

use common::polarid;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

const ORACLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data/oracles");
const EXAMPLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/model");

/// Header and numeric rows of a CSV (comments skipped).
fn read_csv(path: &Path) -> (HashMap<String, usize>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text
        .lines()
        .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty());
    let header = lines.next().expect("header");
    let cols = header
        .split(',')
        .enumerate()
        .map(|(i, h)| (h.trim().to_string(), i))
        .collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|c| c.trim().parse::<f64>().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    (cols, rows)
}

fn run_model(input: &Path, dir: &Path) -> PathBuf {
    let out = dir.join("out.csv");
    let o = polarid(&[
        "model",
        "--input",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        o.status.success(),
        "status {:?}: {}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

#[test]
fn reproduces_dop_oracle() {
    let dir = tempfile::tempdir().unwrap();
    let oracle = Path::new(ORACLES).join("dop_reference.csv");
    let out = run_model(&oracle, dir.path());
    let (oc, orows) = read_csv(&oracle);
    let (c, rows) = read_csv(&out);
    let names: Vec<&str> = {
        let mut v: Vec<(&String, &usize)> = c.iter().collect();
        v.sort_by_key(|(_, i)| **i);
        v.into_iter().map(|(n, _)| n.as_str()).collect()
    };
    assert_eq!(names, ["n", "k", "beta_deg", "dop"]);
    assert_eq!(rows.len(), orows.len());
    let mut worst = 0.0f64;
    for (i, (r, o)) in rows.iter().zip(&orows).enumerate() {
        for name in ["n", "k", "beta_deg"] {
            assert_eq!(r[c[name]], o[oc[name]], "row {i} {name}");
        }
        let e = (r[c["dop"]] - o[oc["dop"]]).abs();
        assert!(e <= 1e-12, "row {i}: {} vs {}", r[c["dop"]], o[oc["dop"]]);
        worst = worst.max(e);
    }
    println!("model on dop_reference.csv: max |dop error| = {worst:.3e}");
}

#[test]
fn reproduces_pbrdf_oracle() {
    let dir = tempfile::tempdir().unwrap();
    let oracle = Path::new(ORACLES).join("pbrdf_reference.csv");
    let out = run_model(&oracle, dir.path());
    let (oc, orows) = read_csv(&oracle);
    let (c, rows) = read_csv(&out);
    assert_eq!(rows.len(), orows.len());
    // Every oracle column is written, and nothing else.
    let mut want: Vec<&String> = oc.keys().collect();
    let mut got: Vec<&String> = c.keys().collect();
    want.sort();
    got.sort();
    assert_eq!(got, want);
    let mut worst = (0.0f64, 0.0f64);
    for (i, (r, o)) in rows.iter().zip(&orows).enumerate() {
        let m00 = o[oc["m00"]];
        for (name, &j) in &oc {
            let (g, w) = (r[c[name]], o[j]);
            let e = (g - w).abs();
            if name.starts_with('m') {
                assert!(e <= 1e-9 * m00, "row {i} {name}: {g} vs {w}");
                worst.0 = worst.0.max(e / m00);
            } else if name == "dolp" {
                assert!(e <= 1e-12, "row {i} dolp: {g} vs {w}");
                worst.1 = worst.1.max(e);
            } else {
                assert!(e <= 1e-9, "row {i} {name}: {g} vs {w}");
            }
        }
    }
    println!(
        "model on pbrdf_reference.csv: max |error|/m00 = {:.3e}, max |dolp error| = {:.3e}",
        worst.0, worst.1
    );
}

#[test]
fn stdout_and_extra_columns() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rows.csv");
    std::fs::write(
        &input,
        "# glass and a metal\nlabel,n,k,beta_deg\nglass,1.5,0,56.309932474020215\nal,1.2,7,0\n",
    )
    .unwrap();
    let o = polarid(&["model", "--input", input.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "n,k,beta_deg,dop,label");
    assert_eq!(lines[1], "1.5,0,56.309932474020215,1,glass"); // Brewster: exactly 1
    assert_eq!(lines[2], "1.2,7,0,0,al");
}

#[test]
fn example_inputs_run() {
    let dir = tempfile::tempdir().unwrap();
    for (name, col) in [("dop_rows.csv", "dop"), ("pbrdf_rows.csv", "m22_psps")] {
        let out = run_model(&Path::new(EXAMPLES).join(name), dir.path());
        let (c, rows) = read_csv(&out);
        assert!(c.contains_key(col) && !rows.is_empty(), "{name}");
        assert!(rows.iter().flatten().all(|v| v.is_finite()), "{name}");
        std::fs::remove_file(out).unwrap();
    }
}

#[test]
fn bad_rows_exit_2_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "n,k,beta_deg\n1.5,0,10\n1.5,-0.5,20\n",
            "line 3",
            "`k`",
            "-0.5",
        ),
        (
            "n,k,beta_deg\n1.5,0,10\n# c\n1.5,0,NaN\n",
            "line 4",
            "`beta_deg`",
            "NaN",
        ),
        ("n,k,beta_deg\n1.5,0,95\n", "line 2", "`beta_deg`", "95"),
        (
            "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1.5,0,0.1,10,20,180\n1.5,0,0,10,20,180\n",
            "line 3",
            "`sigma`",
            "\"0\"",
        ),
        (
            "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1.5,0,0.1,90,20,180\n",
            "line 2",
            "`theta_i_deg`",
            "90",
        ),
        (
            "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1.5,0,0.1,10,-3,180\n",
            "line 2",
            "`theta_r_deg`",
            "-3",
        ),
        (
            "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1.5,abc,0.1,10,3,180\n",
            "line 2",
            "`k`",
            "abc",
        ),
    ];
    for (i, (text, line, col, value)) in cases.iter().enumerate() {
        let input = dir.path().join(format!("bad{i}.csv"));
        std::fs::write(&input, text).unwrap();
        let out = dir.path().join(format!("out{i}.csv"));
        let o = polarid(&[
            "model",
            "--input",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "case {i}: {err}");
        assert!(
            err.contains(&format!("bad{i}.csv"))
                && err.contains(line)
                && err.contains(col)
                && err.contains(value),
            "case {i}: {err}"
        );
        assert!(!out.exists(), "case {i}: output written");
        // Nothing else left in the directory (no temporary files).
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().starts_with("out"))
            .collect();
        assert!(left.is_empty(), "case {i}: {left:?}");
    }
    // Missing columns: exit 2 naming the expected columns.
    let input = dir.path().join("nocols.csv");
    std::fs::write(&input, "n,k\n1,2\n").unwrap();
    let o = polarid(&["model", "--input", input.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("beta_deg") && err.contains("nocols.csv"),
        "{err}"
    );
    assert!(o.stdout.is_empty());
}
