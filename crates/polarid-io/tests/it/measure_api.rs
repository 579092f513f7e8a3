//! The shared measure pipeline (`polarid_io::measure`): synthetic captures of known
//! DoLP written to a temporary directory (rotating-polarizer frames, a DoFP mosaic and
//! float Stokes images) are measured back within their standard errors, and bad inputs
//! give errors naming the file, field and value.

use std::path::{Path, PathBuf};

use polarid_core::mosaic::Pattern;
use polarid_core::stokes::PixelRules;
use polarid_io::IoError;
use polarid_io::image::{self, Frame, write_gray16, write_tiff_f32};
use polarid_io::manifest;
use polarid_io::measure::{self, Demosaic, StokesImages};

const W: usize = 64;
const H: usize = 48;
/// Mean S0, DN (16-bit frames).
const S0: f64 = 20000.0;
/// Standard deviation of the additive noise, DN.
const SIGMA: f64 = 150.0;

/// Truth of the two halves of the scene: (DoLP, AoLP degrees).
const LEFT: (f64, f64) = (0.3, 20.0);
const RIGHT: (f64, f64) = (0.6, -35.0);

/// Regions well inside each half (bilinear DoFP interpolation does not reach across).
const MANIFEST_REGIONS: &str = r#"
[[region]]
name = "A"
rect = [4, 8, 24, 30]
class = "left"

[[region]]
name = "B"
rect = [36, 8, 24, 30]
"#;

/// Deterministic noise: xorshift64* uniform numbers, Gaussian by Box-Muller.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let r = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        ((r >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn gauss(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

fn truth(x: usize) -> (f64, f64) {
    if x < W / 2 { LEFT } else { RIGHT }
}

/// Intensity behind a polarizer at `angle_deg` (Malus, partially polarized light).
fn intensity(x: usize, angle_deg: f64) -> f64 {
    let (p, aolp) = truth(x);
    0.5 * S0 * (1.0 + p * (2.0 * (angle_deg - aolp)).to_radians().cos())
}

fn to_dn(v: f64) -> u16 {
    v.round().clamp(0.0, 65535.0) as u16
}

fn write_frame(dir: &Path, name: &str, angle_deg: f64, noise: &mut Noise) {
    let data: Vec<u16> = (0..W * H)
        .map(|i| to_dn(intensity(i % W, angle_deg) + SIGMA * noise.gauss()))
        .collect();
    write_gray16(&dir.join(name), false, W, H, &data).unwrap();
}

/// Writes frames (i30), a DoFP mosaic (i40) and Stokes images (i50); returns the
/// manifest path.
fn write_capture_set(dir: &Path) -> PathBuf {
    let mut noise = Noise(0x9e37_79b9_7f4a_7c15);
    for a in [0, 45, 90, 135] {
        write_frame(dir, &format!("pol{a:03}.png"), a as f64, &mut noise);
    }
    // Default pattern: 90 45 / 135 0, row by row from the top-left.
    let pattern = Pattern::default().angles_deg();
    let raw: Vec<u16> = (0..W * H)
        .map(|i| {
            let (x, y) = (i % W, i / W);
            let a = pattern[(y % 2) * 2 + x % 2];
            to_dn(intensity(x, a) + SIGMA * noise.gauss())
        })
        .collect();
    write_gray16(&dir.join("raw.png"), false, W, H, &raw).unwrap();
    let mut s = [Vec::new(), Vec::new(), Vec::new()];
    for i in 0..W * H {
        let (p, aolp) = truth(i % W);
        let two = (2.0 * aolp).to_radians();
        s[0].push((S0 + SIGMA * noise.gauss()) as f32);
        s[1].push((S0 * p * two.cos() + SIGMA * noise.gauss()) as f32);
        s[2].push((S0 * p * two.sin() + SIGMA * noise.gauss()) as f32);
    }
    for (k, d) in s.iter().enumerate() {
        write_tiff_f32(&dir.join(format!("s{k}.tif")), false, W, H, d).unwrap();
    }
    let text = format!(
        r#"theta_r_deg = 30.0
{MANIFEST_REGIONS}
[[capture]]
theta_i_deg = 30.0
exposure = 2.0
frames = [
  {{ angle_deg = 0.0, file = "pol000.png" }},
  {{ angle_deg = 45.0, file = "pol045.png" }},
  {{ angle_deg = 90.0, file = "pol090.png" }},
  {{ angle_deg = 135.0, file = "pol135.png" }},
]

[[capture]]
theta_i_deg = 40.0
dofp = {{ file = "raw.png" }}

[[capture]]
theta_i_deg = 50.0
stokes = {{ s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }}
"#
    );
    let m = dir.join("scene.toml");
    std::fs::write(&m, text).unwrap();
    m
}

#[test]
fn synthetic_captures_give_the_true_dolp_within_the_se() {
    let dir = tempfile::tempdir().unwrap();
    let m = manifest::load(&write_capture_set(dir.path())).unwrap();
    let mut calls = Vec::new();
    let rows = measure::measure_manifest(&m, &mut |done| calls.push(done)).unwrap();
    assert_eq!(calls, [1, 2, 3], "progress after each capture");
    assert_eq!(rows.len(), 6, "2 targets x 3 captures");
    for (i, r) in rows.iter().enumerate() {
        let (capture, region) = (i / 2, i % 2);
        assert_eq!(r.target, ["A", "B"][region]);
        assert_eq!(r.class.as_deref(), [Some("left"), None][region]);
        let p_true = [LEFT.0, RIGHT.0][region];
        let se = r.dolp_se.expect("noisy data have a standard error");
        assert!(se > 0.0 && se < 0.01, "row {i}: se {se}");
        assert!(
            (r.dolp - p_true).abs() < 4.0 * se,
            "row {i}: dolp {} vs {p_true}, se {se}",
            r.dolp
        );
        assert_eq!(r.pixels, Some(24 * 30), "row {i}");
        assert_eq!((r.rejected, r.saturated), (Some(0), Some(0)), "row {i}");
        // In the plane of incidence beta = (theta_i + theta_r) / 2 (eqs. 5, 10).
        let theta_i = [30.0, 40.0, 50.0][capture];
        assert_eq!(r.theta_i_deg, Some(theta_i));
        assert!(
            (r.beta_deg - (theta_i + 30.0) / 2.0).abs() < 1e-9,
            "{}",
            r.beta_deg
        );
        let exposure = [2.0, 1.0, 1.0][capture];
        assert_eq!(r.exposure, Some(exposure));
        let s0 = r.s0.unwrap() * exposure;
        assert!((s0 - S0).abs() < 0.01 * S0, "row {i}: S0 {s0}");
    }
    assert!(measure::saturation_warnings(&m, &rows).is_empty());
    // The one-capture entry point gives the same rows.
    let again = measure::measure_capture(&m, &m.captures[1]).unwrap();
    assert_eq!(again, rows[2..4]);
}

#[test]
fn saturated_pixels_are_counted_and_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_capture_set(dir.path());
    // A 4x4 block at full scale inside region A of the 0-degree frame: 16 of 720
    // pixels (2.2 %) saturated.
    let f = image::read_frame(&dir.path().join("pol000.png")).unwrap();
    let mut data: Vec<u16> = f.data.iter().map(|&v| v as u16).collect();
    for y in 10..14 {
        for x in 6..10 {
            data[y * W + x] = u16::MAX;
        }
    }
    write_gray16(&dir.path().join("pol000.png"), true, W, H, &data).unwrap();
    let m = manifest::load(&path).unwrap();
    let rows = measure::measure_manifest(&m, &mut |_| {}).unwrap();
    assert_eq!(rows[0].saturated, Some(16));
    assert_eq!(rows[0].rejected, Some(16));
    assert_eq!(rows[0].pixels, Some(24 * 30 - 16));
    let w = measure::saturation_warnings(&m, &rows);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("target \"A\", capture 1 (line")
            && w[0].contains("16 of 720 pixels (2.2%) saturated"),
        "{}",
        w[0]
    );
}

#[test]
fn a_bad_frame_gives_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_capture_set(dir.path());
    let bad = dir.path().join("pol090.png");
    std::fs::write(&bad, b"not a png").unwrap();
    let m = manifest::load(&path).unwrap();
    let mut calls = 0;
    let e = measure::measure_manifest(&m, &mut |_| calls += 1).unwrap_err();
    assert_eq!(calls, 0, "the first capture failed");
    assert!(e.is_bad_input());
    let msg = e.to_string();
    assert!(msg.contains(&bad.display().to_string()), "{msg}");
    match &e {
        IoError::Image { path, .. } => assert_eq!(path, &bad),
        other => panic!("expected IoError::Image, got {other:?}"),
    }
}

#[test]
fn an_integer_stokes_image_is_rejected_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_capture_set(dir.path());
    // Integer images (all three: the reader first checks that they share a type).
    for k in 0..3 {
        let p = dir.path().join(format!("s{k}.tif"));
        write_gray16(&p, true, W, H, &vec![100u16; W * H]).unwrap();
    }
    let s0 = dir.path().join("s0.tif");
    let m = manifest::load(&path).unwrap();
    let e = measure::capture_images(&m, &m.captures[2]).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains(&s0.display().to_string()) && msg.contains("32-bit float"),
        "{msg}"
    );
}

#[test]
fn a_region_outside_the_frame_names_the_region_capture_and_size() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_capture_set(dir.path());
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("rect = [36, 8, 24, 30]", "rect = [50, 8, 24, 30]");
    std::fs::write(&path, text).unwrap();
    let m = manifest::load(&path).unwrap();
    let e = measure::measure_manifest(&m, &mut |_| {}).unwrap_err();
    match &e {
        IoError::Manifest {
            path: p,
            line,
            field,
            value,
            reason,
        } => {
            assert_eq!(p, &path);
            assert_eq!(*line, 10, "line of region B's rect");
            assert_eq!(field, "region[2].rect");
            assert_eq!(value, "[50, 8, 24, 30]");
            assert!(
                reason.contains("in capture 1 (line ") && reason.contains("64x48 pixels"),
                "{reason}"
            );
        }
        other => panic!("expected IoError::Manifest, got {other:?}"),
    }
}

#[test]
fn stokes_kernels_name_the_file_and_report_sizes() {
    let raw = Frame {
        path: PathBuf::from("odd.png"),
        width: 5,
        height: 4,
        kind: image::SampleKind::U16,
        data: vec![100.0; 20],
        recorded_max: None,
    };
    let rules = measure::rules_for(&raw, 10.0, None);
    assert_eq!(
        rules,
        PixelRules {
            dark_level: 10.0,
            saturation: 65535.0,
            min_s0: 0.0
        }
    );
    assert_eq!(
        measure::rules_for(&raw, 0.0, Some(4095.0)).saturation,
        4095.0
    );
    let e = measure::dofp_stokes(&raw, &Pattern::default(), &rules, Demosaic::Bilinear, false)
        .unwrap_err();
    assert!(
        matches!(&e, IoError::Core { path, .. } if path == Path::new("odd.png")),
        "{e:?}"
    );
    let even = Frame {
        width: 6,
        data: vec![100.0; 24],
        ..raw
    };
    let sp: StokesImages = measure::dofp_stokes(
        &even,
        &Pattern::default(),
        &rules,
        Demosaic::Superpixel,
        false,
    )
    .unwrap();
    assert_eq!((sp.width, sp.height, sp.s0.len()), (3, 2, 6));
    let solver = polarid_core::stokes::StokesSolver::from_degrees(&[0.0, 45.0, 90.0]).unwrap();
    let e = measure::frames_stokes(&[], &solver, &rules).unwrap_err();
    let msg = polarid_io::error::chain_message(&e);
    assert!(msg.contains("need at least 3 frames, got 0"), "{msg}");
}
