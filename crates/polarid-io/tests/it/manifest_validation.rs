//! Capture-set manifests: a full valid manifest, and validation errors that name the
//! manifest line and field at fault.

use std::path::{Path, PathBuf};

use polarid_io::IoError;
use polarid_io::manifest::{self, CaptureSource};

fn setup() -> (tempfile::TempDir, PathBuf) {
    let d = tempfile::tempdir().unwrap();
    for f in [
        "i35/pol000.tif",
        "i35/pol045.tif",
        "i35/pol090.tif",
        "i35/pol135.tif",
        "i40/raw.tif",
        "i45/s0.tif",
        "i45/s1.tif",
        "i45/s2.tif",
    ] {
        let p = d.path().join(f);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, b"x").unwrap();
    }
    let m = d.path().join("scene.toml");
    (d, m)
}

const GOOD: &str = r#"theta_r_deg = 60.0        # camera zenith
phi_deg = 180.0
dark_level = 64
saturation = 4095.0
wavelength_nm = 650.0

[[region]]
name = "A"
rect = [12, 44, 40, 40]
class = "aluminum"

[[region]]
name = "B"
rect = [80, 44, 40, 40]

[[capture]]
theta_i_deg = 35.0
exposure = 2.0
frames = [
  { angle_deg = 0.0,   file = "i35/pol000.tif" },
  { angle_deg = 45.0,  file = "i35/pol045.tif" },
  { angle_deg = 90.0,  file = "i35/pol090.tif" },
  { angle_deg = 135.0, file = "i35/pol135.tif" },
]

[[capture]]
theta_i_deg = 40.0
theta_r_deg = 55
dofp = { file = "i40/raw.tif", pattern = [0, 45, 135, 90] }

[[capture]]
theta_i_deg = 45.0
stokes = { s0 = "i45/s0.tif", s1 = "i45/s1.tif", s2 = "i45/s2.tif" }
"#;

#[test]
fn the_formats_example_parses() {
    let (d, m) = setup();
    std::fs::write(&m, GOOD).unwrap();
    let man = manifest::load(&m).unwrap();
    assert!(man.warnings.is_empty(), "{:?}", man.warnings);
    assert_eq!(man.regions.len(), 2);
    assert_eq!(man.regions[0].class.as_deref(), Some("aluminum"));
    assert_eq!(man.regions[1].class, None);
    assert_eq!((man.regions[0].rect.x, man.regions[0].rect.y), (12, 44));
    assert_eq!(man.regions[0].line, 9);
    assert_eq!(man.captures.len(), 3);
    let c = &man.captures[0];
    assert_eq!(
        (
            c.theta_i_deg,
            c.theta_r_deg,
            c.phi_deg,
            c.exposure,
            c.dark_level
        ),
        (35.0, 60.0, 180.0, 2.0, 64.0)
    );
    assert_eq!(c.saturation, Some(4095.0));
    match &c.source {
        CaptureSource::Frames(f) => {
            assert_eq!(f.len(), 4);
            assert_eq!(f[1].angle_deg, 45.0);
            assert_eq!(f[1].file, d.path().join("i35/pol045.tif"));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(man.captures[1].theta_r_deg, 55.0);
    match &man.captures[1].source {
        CaptureSource::Dofp { pattern, .. } => {
            assert_eq!(pattern.angles_deg(), [0.0, 45.0, 135.0, 90.0])
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        man.captures[2].source,
        CaptureSource::Stokes { .. }
    ));
}

/// Replace `from` by `to` in the good manifest and return the error.
fn error_for(from: &str, to: &str) -> (String, usize, String) {
    let (_d, m) = setup();
    assert!(GOOD.contains(from), "{from}");
    std::fs::write(&m, GOOD.replacen(from, to, 1)).unwrap();
    match manifest::load(&m) {
        Err(e @ IoError::Manifest { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains(&m.display().to_string()), "{msg}");
            let IoError::Manifest { line, field, .. } = e else {
                unreachable!()
            };
            (msg, line, field)
        }
        other => panic!("{from} -> {to}: expected a manifest error, got {other:?}"),
    }
}

#[test]
fn validation_errors_name_line_and_field() {
    let cases: &[(&str, &str, usize, &str, &str)] = &[
        (
            "theta_r_deg = 60.0",
            "theta_r_deg = 95.0",
            1,
            "theta_r_deg",
            "[0, 90)",
        ),
        (
            "dark_level = 64",
            "dark_level = -1",
            3,
            "dark_level",
            ">= 0",
        ),
        (
            "saturation = 4095.0",
            "saturation = 10.0",
            4,
            "saturation",
            "above the dark level",
        ),
        (
            "rect = [12, 44, 40, 40]",
            "rect = [12, 44, 0, 40]",
            9,
            "region[1].rect",
            "width and height > 0",
        ),
        (
            "rect = [80, 44, 40, 40]",
            "rect = [80, -4, 40, 40]",
            14,
            "region[2].rect",
            "non-negative",
        ),
        (
            "name = \"B\"",
            "name = \"A\"",
            13,
            "region[2].name",
            "duplicate",
        ),
        (
            "exposure = 2.0",
            "exposure = 0",
            18,
            "capture[1].exposure",
            "> 0",
        ),
        (
            "theta_i_deg = 35.0",
            "theta_i_deg = \"35\"",
            17,
            "capture[1].theta_i_deg",
            "expected a number",
        ),
        (
            "angle_deg = 45.0,  file = \"i35/pol045.tif\" },\n  { angle_deg = 90.0,  file = \"i35/pol090.tif\" },\n  { angle_deg = 135.0,",
            "angle_deg = 180.0,  file = \"i35/pol045.tif\" },\n  { angle_deg = 90.0,  file = \"i35/pol090.tif\" },\n  { angle_deg = 270.0,",
            19,
            "capture[1].frames",
            "singular",
        ),
        (
            "file = \"i35/pol135.tif\"",
            "file = \"i35/nope.tif\"",
            23,
            "capture[1].frames[4].file",
            "not found",
        ),
        (
            "pattern = [0, 45, 135, 90]",
            "pattern = [0, 45, 135, 45]",
            29,
            "capture[2].dofp.pattern",
            "distinct",
        ),
        (
            "s2 = \"i45/s2.tif\" }",
            "}",
            33,
            "capture[3].stokes.s2",
            "missing",
        ),
    ];
    for (from, to, line, field, word) in cases {
        let (msg, got_line, got_field) = error_for(from, to);
        assert_eq!(got_line, *line, "{msg}");
        assert_eq!(got_field, *field, "{msg}");
        assert!(msg.contains(word), "`{word}` not in: {msg}");
        assert!(msg.contains(&format!("line {line}")), "{msg}");
    }
}

#[test]
fn structural_errors() {
    // Two sources in one capture.
    let (msg, line, _) = error_for("theta_r_deg = 55\n", "theta_r_deg = 55\nframes = []\n");
    assert!(msg.contains("exactly one of"), "{msg}");
    assert_eq!(line, 27);
    // TOML syntax error.
    let (msg, line, _) = error_for("phi_deg = 180.0", "phi_deg = = 180.0");
    assert!(msg.contains("invalid TOML"), "{msg}");
    assert_eq!(line, 2);
    // No camera zenith anywhere.
    let (msg, _, field) = error_for("theta_r_deg = 60.0        # camera zenith", "");
    assert_eq!(field, "capture[1].theta_r_deg");
    assert!(msg.contains("camera zenith"), "{msg}");
}

#[test]
fn unknown_keys_are_warnings_and_paths_are_relative_to_the_manifest() {
    let (d, _) = setup();
    let sub = d.path().join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let m = sub.join("m.toml");
    let text = GOOD
        .replace("\"i3", "\"../i3")
        .replace("\"i4", "\"../i4")
        .replace("phi_deg = 180.0", "phi_deg = 180.0\nthta_i_deg = 3");
    std::fs::write(&m, text).unwrap();
    let man = manifest::load(&m).unwrap();
    assert_eq!(man.warnings.len(), 1);
    assert!(
        man.warnings[0].contains("line 3") && man.warnings[0].contains("thta_i_deg"),
        "{:?}",
        man.warnings
    );
    let files = man.captures[1].source.files();
    assert_eq!(files, vec![Path::new(&sub.join("../i40/raw.tif"))]);
}
