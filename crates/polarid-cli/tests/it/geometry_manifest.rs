//! Calibrated geometry in manifests (`[camera]`, `[[plane]]`, `[site]`, `source`):
//! `polarid measure` refuses bad geometry with exit status 2 and a message naming the
//! field, and refuses a valid calibrated manifest cleanly (not implemented yet).

use crate::common;

use std::path::Path;

use common::{polarid_in, text};
use polarid_io::image;

const W: usize = 64;
const H: usize = 48;

fn write_stokes(d: &Path) {
    for (k, val) in [(0, 1000.0f32), (1, 200.0), (2, 0.0)] {
        let v = vec![val; W * H];
        image::write_tiff_f32(&d.join(format!("s{k}.tif")), false, W, H, &v).unwrap();
    }
}

const CAMERA: &str = r#"[camera]
focal_px = [60.0, 60.0]
principal_point_px = [31.5, 23.5]
position = [0.5, 0.0, 0.6]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
"#;

const REGION: &str = r#"[[region]]
name = "A"
rect = [20, 14, 24, 20]
"#;

const CAPTURE: &str = r#"[[capture]]
source = { position = [-0.4, 0.0, 0.6] }
stokes = { s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }
"#;

/// Run `polarid measure` on `manifest`; return (exit code, stderr).
fn measure(manifest: &str) -> (Option<i32>, String) {
    let d = tempfile::tempdir().unwrap();
    write_stokes(d.path());
    std::fs::write(d.path().join("m.toml"), manifest).unwrap();
    let o = polarid_in(d.path(), &["measure", "m.toml", "-o", "out.csv"]);
    assert!(
        !d.path().join("out.csv").exists(),
        "partial output left behind"
    );
    (o.status.code(), text(&o.stderr))
}

fn expect_bad(name: &str, manifest: &str, field: &str, words: &[&str]) {
    let (code, err) = measure(manifest);
    assert_eq!(code, Some(2), "{name}: exit status {code:?}, stderr: {err}");
    assert!(
        err.contains(&format!("field `{field}`")),
        "{name}: expected field `{field}` in: {err}"
    );
    for w in words {
        assert!(err.contains(w), "{name}: expected {w:?} in: {err}");
    }
}

#[test]
fn camera_behind_the_plane() {
    let cam = CAMERA.replace("position = [0.5, 0.0, 0.6]", "position = [0.5, 0.0, -0.6]");
    expect_bad(
        "default plane",
        &format!("{cam}\n{REGION}\n{CAPTURE}"),
        "camera.position",
        &["not in front of the plane"],
    );
    let plane = "[[plane]]\nname = \"bench\"\npoint = [0, 0, 0]\nnormal = [0, 0, -1]\n";
    expect_bad(
        "flipped normal",
        &format!("{CAMERA}\n{plane}\n{REGION}\n{CAPTURE}"),
        "plane[1].normal",
        &["not in front of the plane", "[0, 0, -1]"],
    );
}

#[test]
fn ray_parallel_to_the_plane() {
    // Looking horizontally: the top rows of the image look above the horizon.
    let cam = CAMERA
        .replace("position = [0.5, 0.0, 0.6]", "position = [0.0, 0.0, 0.5]")
        .replace("look_at = [0.0, 0.0, 0.0]", "look_at = [1.0, 0.0, 0.5]");
    let region = "[[region]]\nname = \"A\"\nrect = [20, 0, 10, 5]\n";
    expect_bad(
        "ray parallel",
        &format!("{cam}\n{region}\n{CAPTURE}"),
        "region[1].rect",
        &["does not meet the plane", "[20, 0, 10, 5]"],
    );
}

#[test]
fn source_below_the_horizon() {
    let cap = CAPTURE.replace("[-0.4, 0.0, 0.6]", "[-0.4, 0.0, -0.2]");
    expect_bad(
        "lamp below",
        &format!("{CAMERA}\n{REGION}\n{cap}"),
        "capture[1].source.position",
        &["below the horizon", "target \"A\""],
    );
    let cap = CAPTURE.replace(
        "position = [-0.4, 0.0, 0.6]",
        "direction = [1.0, 0.0, -0.1]",
    );
    expect_bad(
        "direction below",
        &format!("{CAMERA}\n{REGION}\n{cap}"),
        "capture[1].source.direction",
        &["below the horizon"],
    );
}

#[test]
fn degenerate_look_at_and_up() {
    let parallel = CAMERA.replace("up = [0.0, 0.0, 1.0]", "up = [5.0, 0.0, 6.0]");
    expect_bad(
        "up parallel",
        &format!("{parallel}\n{REGION}\n{CAPTURE}"),
        "camera.up",
        &["parallel", "[5.0, 0.0, 6.0]"],
    );
    let coincident = CAMERA.replace("look_at = [0.0, 0.0, 0.0]", "look_at = [0.5, 0.0, 0.6]");
    expect_bad(
        "look_at at the camera",
        &format!("{coincident}\n{REGION}\n{CAPTURE}"),
        "camera.look_at",
        &["coincides"],
    );
    let zero_up = CAMERA.replace("up = [0.0, 0.0, 1.0]", "up = [0, 0, 0]");
    expect_bad(
        "zero up",
        &format!("{zero_up}\n{REGION}\n{CAPTURE}"),
        "camera.up",
        &["non-zero length"],
    );
}

#[test]
fn non_rotation_matrix() {
    let rot = CAMERA.replace("look_at = [0.0, 0.0, 0.0]\n", "").replace(
        "up = [0.0, 0.0, 1.0]",
        "rotation = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
    );
    expect_bad(
        "scaled",
        &format!("{rot}\n{REGION}\n{CAPTURE}"),
        "camera.rotation",
        &["not a rotation", "orthonormal"],
    );
    let refl = rot.replace("[[2.0, 0.0, 0.0]", "[[-1.0, 0.0, 0.0]");
    expect_bad(
        "reflection",
        &format!("{refl}\n{REGION}\n{CAPTURE}"),
        "camera.rotation",
        &["determinant"],
    );
    let both = format!("{CAMERA}rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\n");
    expect_bad(
        "rotation and look_at",
        &format!("{both}\n{REGION}\n{CAPTURE}"),
        "camera.rotation",
        &["not both"],
    );
}

#[test]
fn non_positive_focal_length() {
    let cam = CAMERA.replace("focal_px = [60.0, 60.0]", "focal_px = [60.0, -1.0]");
    expect_bad(
        "focal",
        &format!("{cam}\n{REGION}\n{CAPTURE}"),
        "camera.focal_px",
        &["> 0"],
    );
}

#[test]
fn angles_and_source_together() {
    let cap = CAPTURE.replace("[[capture]]\n", "[[capture]]\ntheta_i_deg = 35.0\n");
    expect_bad(
        "both",
        &format!("{CAMERA}\n{REGION}\n{cap}"),
        "capture[1].theta_i_deg",
        &["not both"],
    );
    // Angles alone under [camera].
    let cap = "[[capture]]\ntheta_i_deg = 35.0\nstokes = { s0 = \"s0.tif\", s1 = \"s1.tif\", s2 = \"s2.tif\" }\n";
    expect_bad(
        "angles with camera",
        &format!("{CAMERA}\n{REGION}\n{cap}"),
        "capture[1].theta_i_deg",
        &["instead of angles"],
    );
    expect_bad(
        "top-level view angle with camera",
        &format!("theta_r_deg = 60.0\n{CAMERA}\n{REGION}\n{CAPTURE}"),
        "theta_r_deg",
        &["[camera]"],
    );
}

#[test]
fn source_without_camera() {
    expect_bad(
        "no camera",
        &format!("theta_r_deg = 60.0\n{REGION}\n{CAPTURE}"),
        "capture[1].source",
        &["[camera]"],
    );
}

#[test]
fn sun_without_site() {
    let cap = CAPTURE.replace(
        "position = [-0.4, 0.0, 0.6]",
        "sun = \"2003-10-17T12:30:30-07:00\"",
    );
    expect_bad(
        "sun",
        &format!("{CAMERA}\n{REGION}\n{cap}"),
        "capture[1].source.sun",
        &["[site]", "2003-10-17T12:30:30-07:00"],
    );
}

#[test]
fn unknown_plane_name() {
    let plane = "[[plane]]\nname = \"bench\"\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n";
    let region = format!("{REGION}plane = \"table\"\n");
    expect_bad(
        "unknown plane",
        &format!("{CAMERA}\n{plane}\n{region}\n{CAPTURE}"),
        "region[1].plane",
        &["unknown plane", "bench", "\"table\""],
    );
}

#[test]
fn valid_calibrated_manifest_is_mapped() {
    let d = tempfile::tempdir().unwrap();
    write_stokes(d.path());
    // Three lamp positions (a map needs at least 3 captures).
    let more: String = ["[-0.3, 0.1, 0.6]", "[-0.5, -0.1, 0.5]"]
        .iter()
        .map(|p| CAPTURE.replace("[-0.4, 0.0, 0.6]", p))
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(
        d.path().join("m.toml"),
        format!("{CAMERA}\n{REGION}\n{CAPTURE}\n{more}"),
    )
    .unwrap();
    // A model: train on a two-row fits file.
    std::fs::write(
        d.path().join("fits.csv"),
        "target,class,n,k\na,aluminum,1.24,6.6\nc,copper,0.4,2.95\n",
    )
    .unwrap();
    let o = polarid_in(d.path(), &["train", "fits.csv", "-o", "model.json"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = polarid_in(
        d.path(),
        &["map", "m.toml", "--model", "model.json", "-o", "out"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let summary = std::fs::read_to_string(d.path().join("out").join("map_summary.json")).unwrap();
    assert!(
        summary.contains("\"geometry\": \"calibrated\""),
        "{summary}"
    );
    // Fewer than 3 captures: refused before any work, nothing written.
    std::fs::write(
        d.path().join("one.toml"),
        format!("{CAMERA}\n{REGION}\n{CAPTURE}"),
    )
    .unwrap();
    let o = polarid_in(
        d.path(),
        &["map", "one.toml", "--model", "model.json", "-o", "out1"],
    );
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("one.toml") && err.contains("at least 3"),
        "{err}"
    );
    assert!(
        !d.path().join("out1").exists(),
        "partial output left behind"
    );
}

const SITE: &str = r#"[site]
latitude_deg = 39.742476
longitude_deg = -105.1786
elevation_m = 1830.14
pressure_mbar = 820.0
temperature_c = 11.0
"#;

fn sun_capture(time: &str) -> String {
    CAPTURE.replace("position = [-0.4, 0.0, 0.6]", &format!("sun = \"{time}\""))
}

#[test]
fn sun_at_night() {
    let night = "2003-10-17T23:30:30-07:00";
    expect_bad(
        "sun at night",
        &format!("{CAMERA}\n{SITE}\n{REGION}\n{}", sun_capture(night)),
        "capture[1].source.sun",
        &["below the horizon", night, "elevation -"],
    );
}

#[test]
fn sun_with_a_bad_time() {
    let bad = "2003-10-17 12:30:30";
    expect_bad(
        "bad sun time",
        &format!("{CAMERA}\n{SITE}\n{REGION}\n{}", sun_capture(bad)),
        "capture[1].source.sun",
        &[bad, "RFC 3339"],
    );
}

#[test]
fn sun_below_a_planes_horizon() {
    // The sun is to the south-south-west (azimuth 194°, elevation 40°); a plane tilted
    // towards the north puts it below the plane's horizon.
    let plane = "[[plane]]\nname = \"north\"\npoint = [0, 0, 0]\nnormal = [0, 1, 1]\n";
    expect_bad(
        "sun below the plane",
        &format!(
            "{CAMERA}\n{SITE}\n{plane}\n{REGION}\n{}",
            sun_capture("2003-10-17T12:30:30-07:00")
        ),
        "capture[1].source.sun",
        &["below the horizon", "target \"A\""],
    );
}
