//! Partial failure (issue 16, deliverable 4; docs/FORMATS.md "Partial failure"): a dark
//! region or one without a usable pixel in a capture becomes a measurement row with a
//! status and a reason, a target that cannot be fitted a fits row with status
//! `invalid_input`; the commands finish the rest and exit 0 with a warning, exit 2 only
//! when nothing is usable, and `--strict` restores the error at the first problem.

use crate::common;

use std::path::Path;

use common::{csv_rows, polarid_in, text};
use polarid_io::image::write_gray16;

const W: usize = 40;
const H: usize = 20;

/// Four 12-bit frames of a scene whose left half (region `lit`) reflects with DoLP
/// `0.1 + 0.1 i` at capture `i` and whose right half (region `shade`) is `shade_dn` DN
/// above the dark level 64 (0: exactly the dark level) and, when `burn`, the left half
/// saturated instead.
fn write_capture(dir: &Path, i: usize, shade_dn: f64, burn: bool) -> String {
    let p = 0.1 + 0.1 * i as f64;
    let mut items = Vec::new();
    for a in [0u32, 45, 90, 135] {
        let c = (2.0 * f64::from(a)).to_radians().cos();
        let data: Vec<u16> = (0..W * H)
            .map(|k| {
                let x = k % W;
                // A little deterministic texture so that the standard errors are not 0.
                let t = ((k * 7919) % 13) as f64 - 6.0;
                let v = if x < W / 2 {
                    if burn {
                        4095.0
                    } else {
                        64.0 + 1000.0 * (1.0 + p * c) + t
                    }
                } else {
                    64.0 + shade_dn * (1.0 + 0.3 * c) + t.signum() * t.abs().min(1.0)
                };
                v.round().clamp(0.0, 4095.0) as u16
            })
            .collect();
        let name = format!("c{i}_{a:03}.tif");
        write_gray16(&dir.join(&name), true, W, H, &data).unwrap();
        items.push(format!("{{ angle_deg = {a}.0, file = \"{name}\" }}"));
    }
    format!(
        "[[capture]]\ntheta_i_deg = {}\nframes = [{}]\n",
        30 + 10 * i,
        items.join(", ")
    )
}

/// A manifest of four captures; capture 2 has the shade at `shade_dn` (the others 500
/// DN), capture 3 has the lit half saturated when `burn`.
fn write_manifest(dir: &Path, shade_dn: f64, burn: bool) {
    let mut text = String::from(
        "theta_r_deg = 40.0\ndark_level = 64.0\nsaturation = 4095.0\n\n\
         [[region]]\nname = \"lit\"\nrect = [2, 2, 16, 16]\n\n\
         [[region]]\nname = \"shade\"\nrect = [22, 2, 16, 16]\n\n",
    );
    for i in 0..4 {
        let shade = if i == 1 { shade_dn } else { 500.0 };
        text += &write_capture(dir, i, shade, burn && i == 2);
    }
    std::fs::write(dir.join("m.toml"), text).unwrap();
}

fn run(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let o = polarid_in(dir, args);
    (o.status.code(), text(&o.stderr))
}

#[test]
fn dark_and_saturated_regions_become_rows_with_a_status() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    write_manifest(dir, 5.0, true);
    let (code, err) = run(dir, &["measure", "m.toml", "-o", "meas.csv"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("2 of 8 rows are not usable") && err.contains("\"shade\" dark"),
        "{err}"
    );
    let rows = csv_rows(&dir.join("meas.csv"));
    let status: Vec<&str> = rows.iter().map(|r| r["status"].as_str()).collect();
    assert_eq!(
        status,
        ["ok", "ok", "ok", "dark", "saturated", "ok", "ok", "ok"]
    );
    assert!(rows[3]["reason"].contains("below the dark threshold 40.310 DN"));
    assert_eq!(rows[4]["pixels"], "0");
    assert_eq!(rows[4]["dolp"], "nan");
    assert!(rows[0]["reason"].is_empty());

    // --strict: exit 2 at the first problem, naming the region and capture; nothing written.
    let (code, err) = run(dir, &["measure", "m.toml", "-o", "strict.csv", "--strict"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("region[2].rect") && err.contains("capture 2") && err.contains("dark"),
        "{err}"
    );
    assert!(!dir.join("strict.csv").exists());

    // fit skips the two rows: each target keeps 3 usable rows and is fitted.
    let (code, err) = run(dir, &["fit", "meas.csv", "-o", "fits.csv"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("2 measurement row(s) skipped"), "{err}");
    let fits = csv_rows(&dir.join("fits.csv"));
    assert_eq!(fits.len(), 2);
    for f in &fits {
        assert_eq!(f["measurements"], "3", "{f:?}");
        assert!(f["n"].parse::<f64>().unwrap().is_finite());
    }
    // fit --strict stops at the first skipped row.
    let (code, err) = run(dir, &["fit", "meas.csv", "-o", "f2.csv", "--strict"]);
    assert_eq!(code, Some(2), "{err}");
    // Targets in order: `lit`'s saturated row (line 6) comes first.
    assert!(
        err.contains("line 6") && err.contains("\"lit\"") && err.contains("saturated"),
        "{err}"
    );
    assert!(!dir.join("f2.csv").exists());
}

#[test]
fn a_target_with_too_few_usable_rows_gets_an_invalid_input_row() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    std::fs::write(
        dir.join("m.csv"),
        "target,class,beta_deg,dolp,dolp_se,status,reason\n\
         A,al,45,0.2,0.01,,\n\
         A,al,50,0.3,0.01,ok,\n\
         A,al,55,0.4,0.01,,\n\
         B,cu,45,0.2,0.01,,\n\
         B,cu,50,nan,,dark,capture 2: too dark\n\
         B,cu,55,0.4,0.01,,\n",
    )
    .unwrap();
    let (code, err) = run(dir, &["fit", "m.csv", "-o", "fits.csv"]);
    assert_eq!(code, Some(0), "{err}");
    let fits = csv_rows(&dir.join("fits.csv"));
    assert_eq!(fits[0]["status"], "ok");
    assert_eq!(fits[1]["status"], "invalid_input");
    assert_eq!(fits[1]["n"], "nan");
    assert_eq!(fits[1]["measurements"], "2");
    // The reason holds commas (quoted in the CSV): read the file as text.
    let out = std::fs::read_to_string(dir.join("fits.csv")).unwrap();
    assert!(
        out.contains(
            "target \"\"B\"\" has 2 usable measurement(s) (lines 5, 7); at least 3 are \
             needed (skipped: line 6 dark)"
        ),
        "{out}"
    );
    // --strict: exit 2.
    let (code, err) = run(dir, &["fit", "m.csv", "-o", "f2.csv", "--strict"]);
    assert_eq!(code, Some(2), "{err}");
    // An unknown status word is bad input, naming the line and the column.
    std::fs::write(
        dir.join("bad.csv"),
        "target,beta_deg,dolp,status\nA,45,0.2,fine\nA,50,0.3,\nA,55,0.4,\n",
    )
    .unwrap();
    let (code, err) = run(dir, &["fit", "bad.csv", "-o", "f3.csv"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("line 2") && err.contains("status") && err.contains("fine"),
        "{err}"
    );
    // No target can be fitted: the input as a whole is unusable (exit 2).
    std::fs::write(
        dir.join("none.csv"),
        "target,beta_deg,dolp,status\nA,45,0.2,\nA,50,0.3,dark\nA,55,0.4,\n",
    )
    .unwrap();
    let (code, err) = run(dir, &["fit", "none.csv", "-o", "f4.csv"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("\"A\"") && err.contains("at least 3"), "{err}");
    assert!(!dir.join("f4.csv").exists());
}

#[test]
fn a_manifest_with_no_usable_row_is_an_error() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    // Only the shade region, below a threshold of 2000 DN in every capture.
    write_manifest(dir, 0.0, false);
    let text = std::fs::read_to_string(dir.join("m.toml"))
        .unwrap()
        .replace("[[region]]\nname = \"lit\"\nrect = [2, 2, 16, 16]\n\n", "");
    // Every shade row below the threshold (S0 is about 1000 DN where lit).
    let text = format!("dark_signal_dn = 2000.0\n{text}");
    std::fs::write(dir.join("m.toml"), text).unwrap();
    let (code, err) = run(dir, &["measure", "m.toml", "-o", "meas.csv"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no usable measurement"), "{err}");
    assert!(!dir.join("meas.csv").exists());
}
