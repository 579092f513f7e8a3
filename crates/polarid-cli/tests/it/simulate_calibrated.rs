//! `polarid simulate` on calibrated scenes (a pinhole camera, plates on a plane, lamps,
//! a distant source, the sun): the frames written hold, pixel by pixel, the DoLP of
//! eq. (9) at the pixel's own β and an AoLP perpendicular to the plane of incidence,
//! both computed from the *written manifest* with `polarid_core::geometry`; brightness
//! falls as 1/r² with the lamp's distance; a smooth plate's highlight sits at the lamp's
//! mirror point; the manifest loads and validates; the truth holds each plate's (n, k).
//! Bad scenes exit 2 naming the field and write nothing. `demo --bench` either runs end
//! to end or stops, cleanly, where measurement with calibrated geometry is missing.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{csv_rows, polarid, text};
use polarid_core::geometry::{GeometryMaps, ViewGeometry};
use polarid_io::manifest::{self, CaptureSource, Manifest, SourceSpec};

fn ok(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed ({:?}): {}",
        out.status.code(),
        text(&out.stderr)
    );
}

fn num(row: &std::collections::HashMap<String, String>, col: &str) -> f64 {
    row[col]
        .parse()
        .unwrap_or_else(|_| panic!("{col} = {:?}", row[col]))
}

/// A noiseless 16-bit camera (201 × 151, 40° across, no distortion: pixel (100, 75)
/// looks at the origin) 0.8 m from a table; three plates; a lamp in the plane of
/// incidence, a lamp out of it, the same lamp direction at twice the distance, and a
/// distant source.
const SCENE: &str = r#"name = "calibrated_test"
width = 201
height = 151
wavelength_nm = 650.0
seed = 4

[sensor]
bit_depth = 16
full_well_e = 1000000.0
read_noise_e = 0.0
dark_level_dn = 100.0
shot_noise = false

[exposure]
mode = "auto"
fraction = 0.9

[camera]
focal_px = 276.2
principal_point_px = [100.0, 75.0]
position = [-0.6128, 0.0, 0.5142]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]

[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[[source]]
position = [0.35, 0.0, 0.49]
name = "near"

[[source]]
position = [0.70, 0.0, 0.98]
name = "far"

[[source]]
position = [0.45, 0.25, 0.45]

[[source]]
direction = [0.6, -0.2, 0.75]
intensity = 3.0

[[plate]]
name = "al"
class = "aluminum"
n = 1.558
k = 7.712
sigma = 0.2
center = [0.0, 0.0, 0.0]
size = 0.12

[[plate]]
name = "cu"
class = "copper"
n = 0.238
k = 3.626
sigma = 0.2
center = [0.0, -0.16, 0.0]
size = [0.12, 0.1]

[[plate]]
name = "pc"
class = "polycarbonate"
n = 1.579
k = 0.0
sigma = 0.25
center = [-0.16, 0.02, 0.0]
size = [0.1, 0.12]
axis = [1.0, 0.3, 0.0]
"#;

fn simulate(dir: &Path, name: &str, scene: &str) -> (PathBuf, Manifest) {
    let sp = dir.join(format!("{name}.toml"));
    std::fs::write(&sp, scene).unwrap();
    let out = dir.join(name);
    ok(
        &polarid(&[
            "simulate",
            sp.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]),
        "simulate",
    );
    let m = manifest::load(&out.join("manifest.toml")).expect("the manifest loads");
    (out, m)
}

/// Per-pixel (S0, S1, S2) in DN above the dark level of a 0/45/90/135 capture.
fn stokes(m: &Manifest, ci: usize) -> (usize, Vec<[f64; 3]>) {
    let c = &m.captures[ci];
    let CaptureSource::Frames(frames) = &c.source else {
        panic!("frames expected")
    };
    let f: Vec<_> = frames
        .iter()
        .map(|f| polarid_io::image::read_frame(&f.file).unwrap())
        .collect();
    let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
    assert_eq!(angles, [0.0, 45.0, 90.0, 135.0]);
    let d = c.dark_level;
    let s = (0..f[0].data.len())
        .map(|i| {
            let v = |k: usize| f[k].data[i] as f64 - d;
            [0.5 * (v(0) + v(1) + v(2) + v(3)), v(0) - v(2), v(1) - v(3)]
        })
        .collect();
    (f[0].width, s)
}

fn axial_diff_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(180.0);
    d.min(180.0 - d)
}

#[test]
fn frames_hold_the_per_pixel_physics_of_the_written_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let (out, m) = simulate(dir.path(), "bench", SCENE);
    // The manifest: the calibrated geometry, regions on the plane, one source a capture.
    let cam = m.camera.as_ref().expect("[camera]").to_camera();
    assert_eq!(m.planes.len(), 1);
    assert_eq!(m.regions.len(), 3);
    assert!(m.regions.iter().all(|r| r.plane == 0));
    assert_eq!(m.captures.len(), 4);
    assert_eq!(m.captures[0].name.as_deref(), Some("near"));
    assert!(matches!(
        m.captures[3].illumination,
        Some(SourceSpec::Direction(_))
    ));
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let truth = csv_rows(&out.join("truth.csv"));
    assert_eq!(truth.len(), 12);
    let optics = [(1.558, 7.712), (0.238, 3.626), (1.579, 0.0)];
    let view = ViewGeometry::new(cam, m.planes[0].to_plane().unwrap()).unwrap();
    let mut checked = 0;
    for (ci, cap) in m.captures.iter().enumerate() {
        let (w, s) = stokes(&m, ci);
        let src = cap.illumination.as_ref().unwrap().to_source().unwrap();
        for (ri, r) in m.regions.iter().enumerate() {
            let (n, k) = optics[ri];
            let t = &truth[ci * 3 + ri];
            assert_eq!(t["target"], r.name);
            assert_eq!((num(t, "n"), num(t, "k")), (n, k));
            let px = r.rect.width * r.rect.height;
            assert_eq!(num(t, "pixels") as usize, px);
            let (mut b, mut ti, mut tr, mut ph, mut poi) = (
                vec![0.0; px],
                vec![0.0; px],
                vec![0.0; px],
                vec![0.0; px],
                vec![0.0; px],
            );
            view.fill(
                r.rect,
                &src,
                GeometryMaps {
                    beta: &mut b,
                    theta_i: &mut ti,
                    theta_r: &mut tr,
                    phi: &mut ph,
                    poi_angle: Some(&mut poi),
                },
            )
            .unwrap();
            let mut sum = [0.0f64; 3];
            for (j, &beta) in b.iter().enumerate() {
                let (x, y) = (r.rect.x + j % r.rect.width, r.rect.y + j / r.rect.width);
                let p = s[y * w + x];
                for (a, v) in sum.iter_mut().zip(p) {
                    *a += v;
                }
                if p[0] < 2000.0 {
                    continue;
                }
                let dolp = p[1].hypot(p[2]) / p[0];
                let want = polarid_core::dop::dop(n, k, beta);
                assert!(
                    (dolp - want).abs() < 3.0 / p[0],
                    "capture {ci} {} pixel ({x}, {y}): DoLP {dolp} vs eq. 9 {want} at β {}",
                    r.name,
                    beta.to_degrees()
                );
                if dolp * p[0] > 2000.0 {
                    let aolp = 0.5 * p[2].atan2(p[1]).to_degrees();
                    let want = poi[j].to_degrees() + 90.0;
                    assert!(
                        axial_diff_deg(aolp, want) < 0.1,
                        "capture {ci} {} pixel ({x}, {y}): AoLP {aolp} vs {want}",
                        r.name
                    );
                }
                checked += 1;
            }
            // The truth's DoLP is the region's summed Stokes vector's.
            let region_dolp = sum[1].hypot(sum[2]) / sum[0];
            assert!(
                (region_dolp - num(t, "dolp")).abs() < 2e-4,
                "{ci} {}: {region_dolp} vs {}",
                r.name,
                t["dolp"]
            );
            let (lo, mid, hi) = (
                num(t, "beta_min_deg"),
                num(t, "beta_deg"),
                num(t, "beta_max_deg"),
            );
            assert!(lo < mid && mid < hi && hi - lo > 0.2, "{lo} {mid} {hi}");
            let bmax = b.iter().copied().fold(f64::MIN, f64::max).to_degrees();
            assert!((bmax - hi).abs() < 1e-9, "β max {bmax} vs truth {hi}");
        }
    }
    assert!(checked > 5_000, "{checked} pixels checked");
    // Out of the plane of incidence: capture 3 puts the copper plate far from φ = 180°.
    assert!(
        (num(&truth[7], "phi_deg") - 180.0).abs() > 20.0,
        "{:?}",
        truth[7]
    );
}

#[test]
fn brightness_falls_with_the_square_of_the_lamp_distance() {
    // Captures "near" and "far" put the lamp at d and 2d along the same direction from
    // the origin, which pixel (100, 75) sees: S0 / exposure there differs by 4.
    let dir = tempfile::tempdir().unwrap();
    let (_, m) = simulate(dir.path(), "falloff", SCENE);
    let at = |ci: usize| {
        let (w, s) = stokes(&m, ci);
        let p = s[75 * w + 100];
        (p[0] / m.captures[ci].exposure, p[1].hypot(p[2]) / p[0])
    };
    let ((near, p_near), (far, p_far)) = (at(0), at(1));
    assert!((near / far - 4.0).abs() < 4e-3, "{}", near / far);
    assert!((p_near - p_far).abs() < 1e-3);
}

#[test]
fn a_smooth_plate_shines_at_the_lamp_mirror_point() {
    // One large smooth aluminum plate.
    let one = &SCENE[..SCENE.find("[[plate]]\nname = \"cu\"").unwrap()];
    let scene = one.replace(
        "sigma = 0.2\ncenter = [0.0, 0.0, 0.0]\nsize = 0.12",
        "sigma = 0.04\ncenter = [0.0, 0.0, 0.0]\nsize = 0.5",
    );
    let dir = tempfile::tempdir().unwrap();
    let (_, m) = simulate(dir.path(), "mirror", &scene);
    let cam = m.camera.as_ref().unwrap().to_camera();
    for ci in [0, 2] {
        let (w, s) = stokes(&m, ci);
        let (imax, _) =
            s.iter().enumerate().fold(
                (0, f64::MIN),
                |b, (i, p)| if p[0] > b.1 { (i, p[0]) } else { b },
            );
        let Some(SourceSpec::Position(l)) = m.captures[ci].illumination else {
            panic!("lamp expected")
        };
        // The camera sees the lamp's mirror image (x, y, −z) through the table at X.
        let c = cam.position();
        let mz = -l[2];
        let t = c[2] / (c[2] - mz);
        let x = [c[0] + t * (l[0] - c[0]), c[1] + t * (l[1] - c[1]), 0.0];
        let [u, v] = cam.project(x).unwrap();
        let (bu, bv) = ((imax % w) as f64, (imax / w) as f64);
        assert!(
            (bu - u).hypot(bv - v) < 2.5,
            "capture {ci}: brightest pixel ({bu}, {bv}), mirror point ({u:.1}, {v:.1})"
        );
    }
}

#[test]
fn the_example_bench_and_a_sun_scene_simulate() {
    let dir = tempfile::tempdir().unwrap();
    let example =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes/bench_lamp_lens.toml");
    let text = std::fs::read_to_string(&example).unwrap();
    let (out, m) = simulate(dir.path(), "example", &text);
    assert_eq!((m.regions.len(), m.captures.len()), (5, 9));
    assert!(m.camera.as_ref().unwrap().distortion[0] < 0.0);
    let truth = csv_rows(&out.join("truth.csv"));
    assert_eq!(truth.len(), 45);
    // The side plates sit 20-45° out of the plane of incidence; β spreads over a region.
    let out_of_plane = truth
        .iter()
        .filter(|t| ["copper", "brass"].contains(&t["target"].as_str()))
        .map(|t| (num(t, "phi_deg") - 180.0).abs())
        .fold(0.0f64, f64::max);
    assert!((20.0..60.0).contains(&out_of_plane), "{out_of_plane}");
    assert!(truth.iter().all(|t| num(t, "beta_sd_deg") > 0.02));

    // The sun over a horizontal table: θi of every pixel is the sun's zenith.
    let sun = SCENE.replace(
        "direction = [0.6, -0.2, 0.75]",
        "sun = \"2003-10-17T12:30:30-07:00\"",
    ) + "\n[site]\nlatitude_deg = 39.742476\nlongitude_deg = -105.1786\nelevation_m = 1830.14\npressure_mbar = 820.0\ntemperature_c = 11.0\n";
    // The camera looks from the west; the sun stands in the south-south-west.
    let sun = sun.replace(
        "position = [-0.6128, 0.0, 0.5142]",
        "position = [0.0, 0.6128, 0.5142]",
    );
    let (out, m) = simulate(dir.path(), "sun", &sun);
    let Some(SourceSpec::Sun { zenith_deg, .. }) = m.captures[3].illumination else {
        panic!("sun expected")
    };
    assert!((zenith_deg - 50.1116).abs() < 0.01, "{zenith_deg}");
    let truth = csv_rows(&out.join("truth.csv"));
    for t in &truth[9..12] {
        assert!((num(t, "theta_i_deg") - zenith_deg).abs() < 1e-6, "{t:?}");
    }
    let text = std::fs::read_to_string(out.join("manifest.toml")).unwrap();
    assert!(text.contains("source = { sun = \"2003-10-17T12:30:30-07:00\" }"));
    assert!(text.contains("[site]"));
}

#[test]
fn a_far_field_scene_out_of_the_plane_of_incidence() {
    // phi_deg != 180: β from eq. (5), and measure finds the truth's DoLP.
    let dir = tempfile::tempdir().unwrap();
    let scene = r#"width = 64
height = 64
theta_r_deg = 50
phi_deg = 150
theta_i_deg = [40, 55, 70]
seed = 9
[[plate]]
name = "cu"
n = 0.238
k = 3.626
sigma = 0.3
rect = [0, 0, 64, 64]
"#;
    let (out, m) = simulate(dir.path(), "offplane", scene);
    assert_eq!(m.captures[0].phi_deg, 150.0);
    let truth = csv_rows(&out.join("truth.csv"));
    for t in &truth {
        let (ti, tr, phi) = (
            num(t, "theta_i_deg").to_radians(),
            50f64.to_radians(),
            150f64.to_radians(),
        );
        let c2b = ti.cos() * tr.cos() + ti.sin() * tr.sin() * phi.cos();
        assert!((num(t, "beta_deg") - (0.5 * c2b.acos()).to_degrees()).abs() < 1e-9);
        let want = polarid_core::dop::dop(0.238, 3.626, num(t, "beta_deg").to_radians());
        assert!((num(t, "dolp") - want).abs() < 1e-12);
    }
    let meas = out.join("m.csv");
    ok(
        &polarid(&[
            "measure",
            out.join("manifest.toml").to_str().unwrap(),
            "-o",
            meas.to_str().unwrap(),
        ]),
        "measure",
    );
    for (t, mm) in truth.iter().zip(csv_rows(&meas)) {
        let z = (num(&mm, "dolp") - num(t, "dolp")) / num(&mm, "dolp_se");
        assert!(z.abs() < 5.0, "{z}");
        assert!((num(&mm, "beta_deg") - num(t, "beta_deg")).abs() < 1e-9);
    }
}

#[test]
fn bad_calibrated_scenes_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for (bad, field, line) in [
        (
            SCENE.replace("seed = 4", "seed = 4\ntheta_i_deg = [40]"),
            "theta_i_deg",
            6,
        ),
        (
            SCENE.replace(
                "position = [0.70, 0.0, 0.98]",
                "position = [0.70, 0.0, -0.98]",
            ),
            "source[2].position",
            35,
        ),
        (
            SCENE.replace("center = [0.0, -0.16, 0.0]", "center = [0.0, -0.16, 0.2]"),
            "plate[2].center",
            60,
        ),
        (
            SCENE.replace("up = [0.0, 0.0, 1.0]", "up = [0.6128, 0.0, -0.5142]"),
            "camera.up",
            23,
        ),
        (
            SCENE.replace(
                "[[source]]\nposition = [0.35",
                "[[source]]\nsun = \"2020-01-01T12:00:00Z\"\n#",
            ),
            "source[1].sun",
            31,
        ),
    ] {
        let sp = dir.path().join("bad.toml");
        std::fs::write(&sp, &bad).unwrap();
        let out = dir.path().join("out");
        let o = polarid(&[
            "simulate",
            sp.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{field}: {err}");
        assert!(
            err.contains(&format!("`{field}`")) && err.contains(&format!("line {line}")),
            "{field} line {line}: {err}"
        );
        assert!(!out.exists(), "{field}: output written");
    }
}

#[test]
fn demo_bench_runs_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let o = polarid(&["demo", "--bench", "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    for f in [
        "report.html",
        "report.md",
        "tables.txt",
        "measurements.csv",
        "fits.csv",
        "model.json",
        "classification.csv",
        "map/map_summary.json",
        "map/class.png",
        "plots/beta_c01.png",
        "captures/train/manifest.toml",
        "captures/test/truth.csv",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let class = csv_rows(&out.join("classification.csv"));
    assert_eq!(class.len(), 5);
    let right = class
        .iter()
        .filter(|c| c["class"] == c["predicted"])
        .count();
    assert!(right >= 4, "{class:?}");
}
