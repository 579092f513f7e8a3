//! The exact text of `polarid: error: …` for errors with causes: the message, then each
//! cause once, joined by `: ` (issue 14). The message of a file the system cannot read
//! is the file's name followed by the operating system's reason; a bad manifest field
//! names file, line, field, reason and value; a core error is preceded by the file whose
//! data it rejects.

use crate::common;

use common::{polarid_in, text};

use polarid_io::image;

/// Run `polarid ARGS` in `dir`; (exit status, standard error).
fn run(dir: &std::path::Path, args: &[&str]) -> (Option<i32>, String) {
    let o = polarid_in(dir, args);
    (o.status.code(), text(&o.stderr))
}

#[test]
fn missing_file_names_the_file_then_the_system_reason_once() {
    let d = tempfile::tempdir().unwrap();
    // The operating system's wording, as the standard library shows it.
    let reason = std::fs::read_to_string(d.path().join("missing.toml"))
        .unwrap_err()
        .to_string();
    let (status, err) = run(d.path(), &["measure", "missing.toml", "-o", "m.csv"]);
    assert_eq!(status, Some(2), "{err}");
    assert_eq!(err, format!("polarid: error: missing.toml: {reason}\n"));
    assert_eq!(err.matches(&reason).count(), 1, "{err}");
    assert!(!d.path().join("m.csv").exists());
}

#[test]
fn bad_manifest_field_is_one_line_naming_file_line_field_and_value() {
    let d = tempfile::tempdir().unwrap();
    let v: Vec<u16> = (0..64).map(|i| 1000 + i as u16).collect();
    for n in ["a.png", "b.png", "c.png", "d.png"] {
        image::write_gray16(&d.path().join(n), false, 8, 8, &v).unwrap();
    }
    let manifest = "theta_r_deg = 90.0\n\n[[region]]\nname = \"A\"\nrect = [1, 1, 4, 4]\n\n\
                    [[capture]]\ntheta_i_deg = 30.0\nframes = [\n\
                    \x20 { angle_deg = 0.0, file = \"a.png\" },\n\
                    \x20 { angle_deg = 45.0, file = \"b.png\" },\n\
                    \x20 { angle_deg = 90.0, file = \"c.png\" },\n\
                    \x20 { angle_deg = 135.0, file = \"d.png\" },\n]\n";
    std::fs::write(d.path().join("m.toml"), manifest).unwrap();
    let (status, err) = run(d.path(), &["measure", "m.toml", "-o", "m.csv"]);
    assert_eq!(status, Some(2), "{err}");
    assert_eq!(
        err,
        "polarid: error: m.toml: line 1, field `theta_r_deg`: zenith angle must be in \
         [0, 90) degrees (value 90.0)\n"
    );
}

#[test]
fn core_error_follows_the_file_it_rejects_once() {
    let d = tempfile::tempdir().unwrap();
    let v: Vec<u16> = (0..72).map(|i| 1000 + i as u16).collect();
    image::write_gray16(&d.path().join("raw.png"), false, 9, 8, &v).unwrap();
    let (status, err) = run(d.path(), &["stokes", "--dofp", "raw.png", "-o", "out"]);
    assert_eq!(status, Some(2), "{err}");
    assert_eq!(
        err,
        "polarid: error: raw.png: image of 9x8 pixels cannot be used: a 2x2 polarizer \
         mosaic needs an even width and height\n"
    );
    assert!(!d.path().join("out").exists());
}
