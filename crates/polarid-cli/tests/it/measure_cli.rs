//! `polarid measure` end to end on generated rotating-polarizer, DoFP and Stokes
//! captures of two uniform plates; errors name the manifest line; no partial output.

use crate::common;

use common::polarid;

use std::path::Path;
use std::process::Output;

use polarid_io::image;
use polarid_io::table::measurements;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const W: usize = 40;
const H: usize = 20;

/// Plate A (columns < 20): S = (2000, 600, 0) → DoLP 0.3; plate B: S = (1000, 0, -100)
/// → DoLP 0.1; times `gain`; plus the dark level 50.
fn stokes_at(x: usize, gain: f64) -> [f64; 3] {
    if x < 20 {
        [2000.0 * gain, 600.0 * gain, 0.0]
    } else {
        [1000.0 * gain, 0.0, -100.0 * gain]
    }
}

fn intensity(s: [f64; 3], a: f64) -> f64 {
    let a = 2.0 * a.to_radians();
    50.0 + 0.5 * (s[0] + s[1] * a.cos() + s[2] * a.sin())
}

fn make_scene(d: &Path) {
    // Capture 1: four 16-bit PNG frames, exposure 2 (twice the signal), one saturated
    // pixel in plate A.
    for a in [0.0, 45.0, 90.0, 135.0] {
        let mut v: Vec<u16> = (0..W * H)
            .map(|i| intensity(stokes_at(i % W, 2.0), a) as u16)
            .collect();
        if a == 0.0 {
            v[5 * W + 5] = 4095;
        }
        image::write_gray16(&d.join(format!("f{a:03}.png")), false, W, H, &v).unwrap();
    }
    // Capture 2: DoFP raw (pattern 90,45,135,0) as 16-bit TIFF.
    let pat = [90.0, 45.0, 135.0, 0.0];
    let raw: Vec<u16> = (0..W * H)
        .map(|i| intensity(stokes_at(i % W, 1.0), pat[2 * ((i / W) % 2) + (i % W) % 2]) as u16)
        .collect();
    image::write_gray16(&d.join("raw.tif"), false, W, H, &raw).unwrap();
    // Capture 3: Stokes float TIFFs.
    for k in 0..3 {
        let v: Vec<f32> = (0..W * H)
            .map(|i| stokes_at(i % W, 1.0)[k] as f32)
            .collect();
        image::write_tiff_f32(&d.join(format!("s{k}.tif")), false, W, H, &v).unwrap();
    }
}

const MANIFEST: &str = r#"theta_r_deg = 60.0
dark_level = 50
saturation = 4095

[[region]]
name = "A"
rect = [2, 2, 16, 16]
class = "aluminum"

[[region]]
name = "B"
rect = [22, 2, 16, 16]

[[capture]]
theta_i_deg = 30.0
exposure = 2.0
frames = [
  { angle_deg = 0.0, file = "f000.png" },
  { angle_deg = 45.0, file = "f045.png" },
  { angle_deg = 90.0, file = "f090.png" },
  { angle_deg = 135.0, file = "f135.png" },
]

[[capture]]
theta_i_deg = 40.0
theta_r_deg = 50.0
dofp = { file = "raw.tif" }

[[capture]]
theta_i_deg = 50.0
phi_deg = 90.0
stokes = { s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }
"#;

#[test]
fn measures_every_target_in_every_capture() {
    let d = tempfile::tempdir().unwrap();
    make_scene(d.path());
    let m = d.path().join("scene.toml");
    std::fs::write(&m, MANIFEST).unwrap();
    let out = d.path().join("meas.csv");
    let o = polarid(&[
        "measure",
        &m.display().to_string(),
        "-o",
        &out.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = measurements::read(&out).unwrap();
    assert_eq!(rows.len(), 6);
    let names: Vec<&str> = rows.iter().map(|r| r.target.as_str()).collect();
    assert_eq!(names, ["A", "B", "A", "B", "A", "B"]);
    for (i, r) in rows.iter().enumerate() {
        let want = if r.target == "A" { 0.3 } else { 0.1 };
        // Frames are quantised to whole DN: DoLP within 1e-3.
        assert!((r.dolp - want).abs() < 1e-3, "row {i}: {r:?}");
        let s0 = if r.target == "A" { 2000.0 } else { 1000.0 };
        assert!(
            (r.s0.unwrap() - s0).abs() < 2.0,
            "row {i}: s0 {:?} (divided by exposure)",
            r.s0
        );
        assert_eq!(
            r.class.as_deref(),
            if r.target == "A" {
                Some("aluminum")
            } else {
                None
            }
        );
    }
    // Saturated pixel: plate A of capture 1 loses one pixel.
    assert_eq!(
        (rows[0].pixels, rows[0].rejected, rows[0].saturated),
        (Some(255), Some(1), Some(1))
    );
    assert_eq!((rows[1].pixels, rows[1].rejected), (Some(256), Some(0)));
    assert_eq!(rows[0].exposure, Some(2.0));
    // Noiseless uniform plates have no pixel scatter: the standard error is left empty
    // (the measurements contract needs dolp_se > 0 when present).
    assert!(rows.iter().all(|r| r.dolp_se.is_none_or(|se| se > 0.0)));
    // Geometry: beta from the capture's own angles.
    assert_eq!(rows[0].theta_r_deg, Some(60.0));
    assert!((rows[0].beta_deg - 45.0).abs() < 1e-9);
    assert_eq!(rows[2].theta_r_deg, Some(50.0));
    assert!((rows[2].beta_deg - 45.0).abs() < 1e-9);
    let b =
        polarid_core::geometry::beta(50f64.to_radians(), 60f64.to_radians(), 90f64.to_radians())
            .to_degrees();
    assert!((rows[4].beta_deg - b).abs() < 1e-6 && rows[4].phi_deg == 90.0);
    // Standard output when no -o.
    let o = polarid(&["measure", &m.display().to_string()]);
    assert!(o.status.success());
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.starts_with(
            "target,class,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,dolp_se,s0,pixels,rejected"
        ),
        "{text}"
    );
    assert_eq!(text.lines().count(), 7);
}

#[test]
fn bad_manifests_exit_2_name_the_line_and_leave_no_output() {
    let d = tempfile::tempdir().unwrap();
    make_scene(d.path());
    let m = d.path().join("scene.toml");
    let out = d.path().join("meas.csv");
    let run = |text: &str| {
        std::fs::write(&m, text).unwrap();
        polarid(&[
            "measure",
            &m.display().to_string(),
            "-o",
            &out.display().to_string(),
        ])
    };
    // Region leaving the frame: found only once the frames are read.
    let o = run(&MANIFEST.replace("rect = [22, 2, 16, 16]", "rect = [30, 2, 16, 16]"));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("line 12") && e.contains("region[2].rect") && e.contains("leaves"),
        "{e}"
    );
    // Missing frame file.
    let o = run(&MANIFEST.replace("f090.png", "nope.png"));
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("line 20") && e.contains("capture[1].frames[3].file") && e.contains("not found"),
        "{e}"
    );
    // A frame of the wrong size.
    image::write_gray16(&d.path().join("small.png"), false, 10, 10, &[0; 100]).unwrap();
    let o = run(&MANIFEST.replace("f090.png", "small.png"));
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("small.png") && stderr(&o).contains("same size"),
        "{}",
        stderr(&o)
    );
    // Bad value.
    let o = run(&MANIFEST.replace("theta_i_deg = 40.0", "theta_i_deg = 140.0"));
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("line 25") && stderr(&o).contains("capture[2].theta_i_deg"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists(), "partial output");
    // Existing output kept without --force; overwriting an input refused.
    std::fs::write(&out, "old").unwrap();
    let o = run(MANIFEST);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "old");
    let o = polarid(&[
        "--force",
        "measure",
        &m.display().to_string(),
        "-o",
        &m.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("input"), "{}", stderr(&o));
}
