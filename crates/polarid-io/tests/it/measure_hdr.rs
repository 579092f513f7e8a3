//! HDR brackets and dark regions in `polarid_io::measure`: a bright target that
//! saturates the long exposure is measured right once the brackets are merged (frames
//! and DoFP), a faint one is `dark` by the default threshold, and bad bracket tables are
//! refused naming the field.

use std::path::{Path, PathBuf};

use polarid_core::mosaic::Pattern;
use polarid_io::image::write_gray16;
use polarid_io::manifest;
use polarid_io::measure::{self, measure_manifest, measure_manifest_with};
use polarid_io::table::measurements::RowStatus;

const W: usize = 64;
const H: usize = 48;
const DARK: f64 = 64.0;
const SAT: f64 = 4095.0;
/// Electrons per DN (shot noise) and read noise, DN.
const GAIN: f64 = 8.0;
const READ: f64 = 2.0;
const LONG: f64 = 8.0;
const SHORT: f64 = 1.0;

/// Targets: name, x range, S0 per unit exposure (DN), DoLP, AoLP (degrees).
const TARGETS: [(&str, usize, f64, f64, f64); 3] = [
    ("bright", 0, 1000.0, 0.4, 30.0),
    ("dim", 22, 100.0, 0.25, 70.0),
    ("faint", 44, 2.0, 0.3, 10.0),
];

fn target_at(x: usize) -> (f64, f64, f64) {
    let t = TARGETS
        .iter()
        .rev()
        .find(|t| x >= t.1)
        .unwrap_or(&TARGETS[0]);
    (t.2, t.3, t.4)
}

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

/// 12-bit raw value of pixel column `x` behind a polarizer at `angle` at `exposure`.
fn raw(x: usize, angle: f64, exposure: f64, noise: &mut Noise) -> u16 {
    let (s0, p, aolp) = target_at(x);
    let i = 0.5 * exposure * s0 * (1.0 + p * (2.0 * (angle - aolp)).to_radians().cos());
    let sd = (READ * READ + i / GAIN).sqrt();
    (i + DARK + sd * noise.gauss()).round().clamp(0.0, SAT) as u16
}

fn write_frames(dir: &Path, tag: &str, exposure: f64, noise: &mut Noise) -> String {
    let mut items = Vec::new();
    for a in [0u32, 45, 90, 135] {
        let name = format!("{tag}_{a:03}.tif");
        let data: Vec<u16> = (0..W * H)
            .map(|i| raw(i % W, f64::from(a), exposure, noise))
            .collect();
        write_gray16(&dir.join(&name), true, W, H, &data).unwrap();
        items.push(format!("{{ angle_deg = {a}.0, file = \"{name}\" }}"));
    }
    format!("[{}]", items.join(", "))
}

fn write_mosaic(dir: &Path, tag: &str, exposure: f64, noise: &mut Noise) -> String {
    let pattern = Pattern::default().angles_deg();
    let data: Vec<u16> = (0..W * H)
        .map(|i| {
            let (x, y) = (i % W, i / W);
            raw(x, pattern[(y % 2) * 2 + x % 2], exposure, noise)
        })
        .collect();
    let name = format!("{tag}.tif");
    write_gray16(&dir.join(&name), true, W, H, &data).unwrap();
    name
}

const REGIONS: &str = r#"
[[region]]
name = "bright"
rect = [3, 4, 16, 40]

[[region]]
name = "dim"
rect = [25, 4, 16, 40]

[[region]]
name = "faint"
rect = [47, 4, 14, 40]
"#;

fn write_manifest(dir: &Path, captures: &str) -> PathBuf {
    let p = dir.join("scene.toml");
    let text = format!(
        "theta_r_deg = 30.0\ndark_level = {DARK}\nsaturation = {SAT}\n{REGIONS}\n{captures}"
    );
    std::fs::write(&p, text).unwrap();
    p
}

/// The measured DoLP of each target lies within 4 standard errors of the truth, the
/// brightness per unit exposure within 2 %, and no pixel of the bright and dim targets is
/// saturated or rejected.
fn check_merged(rows: &[polarid_io::table::measurements::Measurement], what: &str) {
    for (name, _, s0, p, _) in TARGETS.iter().take(2) {
        let r = rows.iter().find(|r| &r.target == name).unwrap();
        assert_eq!(r.status, RowStatus::Ok, "{what} {name}: {}", r.reason);
        let se = r.dolp_se.unwrap();
        assert!(se < 0.01, "{what} {name}: se {se}");
        assert!(
            (r.dolp - p).abs() < 4.0 * se,
            "{what} {name}: DoLP {} truth {p} se {se}",
            r.dolp
        );
        let got = r.s0.unwrap();
        assert!(
            (got / s0 - 1.0).abs() < 0.02,
            "{what} {name}: s0 {got} truth {s0}"
        );
        assert_eq!(r.saturated, Some(0), "{what} {name}");
        assert_eq!(r.exposure, Some(LONG), "{what} {name}");
    }
}

#[test]
fn a_bright_target_saturating_the_long_exposure_is_measured_after_merging() {
    let dir = tempfile::tempdir().unwrap();
    let mut noise = Noise(0x1234_5678_9abc_def1);
    let long = write_frames(dir.path(), "long", LONG, &mut noise);
    let short = write_frames(dir.path(), "short", SHORT, &mut noise);
    // The long exposure alone: every pixel of the bright target saturates.
    let alone = write_manifest(
        dir.path(),
        &format!("[[capture]]\ntheta_i_deg = 30.0\nexposure = {LONG}\nframes = {long}\n"),
    );
    let m = manifest::load(&alone).unwrap();
    let rows = measure_manifest(&m, &mut |_| {}).unwrap();
    assert_eq!(rows[0].status, RowStatus::Saturated, "{:?}", rows[0]);
    assert_eq!(rows[0].pixels, Some(0));
    assert!(
        rows[0].reason.contains("no usable pixel (640 saturated"),
        "{}",
        rows[0].reason
    );
    assert!(rows[0].dolp.is_nan());
    let e = measure_manifest_with(&m, true, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("region[1].rect") && e.contains("saturated"),
        "{e}"
    );

    // Both brackets (short one listed first: polarid orders them).
    let hdr = write_manifest(
        dir.path(),
        &format!(
            "[[capture]]\ntheta_i_deg = 30.0\nbrackets = [\n  {{ exposure = {SHORT}, frames = {short} }},\n  {{ exposure = {LONG}, frames = {long} }},\n]\n"
        ),
    );
    let m = manifest::load(&hdr).unwrap();
    let c = &m.captures[0];
    assert_eq!(c.exposure, LONG);
    assert_eq!(c.brackets.len(), 2);
    assert_eq!(c.files().len(), 8);
    let rows = measure_manifest(&m, &mut |_| {}).unwrap();
    check_merged(&rows, "frames");
    // The faint target (16 DN in the long exposure) is dark by the default threshold
    // (1 % of 4095 - 64 = 40.31 DN) and says so.
    let faint = &rows[2];
    assert_eq!(faint.status, RowStatus::Dark, "{faint:?}");
    assert!(
        faint.reason.contains("below the dark threshold 40.310 DN"),
        "{}",
        faint.reason
    );
    let e = measure_manifest_with(&m, true, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("region[3].rect") && e.contains("dark"), "{e}");
    // A threshold of 0 turns the test off.
    let text = std::fs::read_to_string(&hdr).unwrap();
    std::fs::write(&hdr, format!("dark_signal_dn = 0\n{text}")).unwrap();
    let m = manifest::load(&hdr).unwrap();
    let rows = measure_manifest(&m, &mut |_| {}).unwrap();
    assert_eq!(rows[2].status, RowStatus::Ok);
}

#[test]
fn dofp_brackets_are_merged_too() {
    let dir = tempfile::tempdir().unwrap();
    let mut noise = Noise(0x0bad_cafe_f00d_1234);
    let long = write_mosaic(dir.path(), "long", LONG, &mut noise);
    let short = write_mosaic(dir.path(), "short", SHORT, &mut noise);
    let hdr = write_manifest(
        dir.path(),
        &format!(
            "[[capture]]\ntheta_i_deg = 30.0\nbrackets = [\n  {{ exposure = {LONG}, dofp = {{ file = \"{long}\" }} }},\n  {{ exposure = {SHORT}, dofp = {{ file = \"{short}\" }} }},\n]\n"
        ),
    );
    let m = manifest::load(&hdr).unwrap();
    let rows = measure_manifest(&m, &mut |_| {}).unwrap();
    check_merged(&rows, "dofp");
    // Without the short bracket the bright target is lost.
    let alone = write_manifest(
        dir.path(),
        &format!(
            "[[capture]]\ntheta_i_deg = 30.0\nexposure = {LONG}\ndofp = {{ file = \"{long}\" }}\n"
        ),
    );
    let m = manifest::load(&alone).unwrap();
    let rows = measure_manifest(&m, &mut |_| {}).unwrap();
    assert_eq!(rows[0].status, RowStatus::Saturated);
    assert!(!measure::saturation_warnings(&m, &rows).is_empty());
}

/// Bad `brackets` tables are refused naming the field.
#[test]
fn bad_brackets_name_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let mut noise = Noise(7);
    let a = write_frames(dir.path(), "a", LONG, &mut noise);
    let b = write_frames(dir.path(), "b", SHORT, &mut noise);
    let three = "[{ angle_deg = 0.0, file = \"a_000.tif\" }, { angle_deg = 60.0, file = \"a_045.tif\" }, { angle_deg = 120.0, file = \"a_090.tif\" }]";
    let cases = [
        (
            format!("brackets = [{{ exposure = 2.0, frames = {a} }}]"),
            "capture[1].brackets",
            "at least 2",
        ),
        (
            format!("brackets = [{{ exposure = 2.0, frames = {a} }}, {{ frames = {b} }}]"),
            "capture[1].brackets[2].exposure",
            "missing exposure",
        ),
        (
            format!(
                "brackets = [{{ exposure = 2.0, frames = {a} }}, {{ exposure = 0.0, frames = {b} }}]"
            ),
            "capture[1].brackets[2].exposure",
            "> 0",
        ),
        (
            format!(
                "brackets = [{{ exposure = 2.0, frames = {a} }}, {{ exposure = 2.0, frames = {b} }}]"
            ),
            "capture[1].brackets[2].exposure",
            "same exposure",
        ),
        (
            format!(
                "brackets = [{{ exposure = 2.0, frames = {a} }}, {{ exposure = 1.0, frames = {three} }}]"
            ),
            "capture[1].brackets[2].frames",
            "differ",
        ),
        (
            format!(
                "brackets = [{{ exposure = 2.0, frames = {a} }}, {{ exposure = 1.0, dofp = {{ file = \"a_000.tif\" }} }}]"
            ),
            "capture[1].brackets[2].dofp",
            "same kind",
        ),
        (
            format!(
                "brackets = [{{ exposure = 2.0, frames = {a} }}, {{ exposure = 1.0, stokes = {{ s0 = \"a_000.tif\", s1 = \"a_045.tif\", s2 = \"a_090.tif\" }} }}]"
            ),
            "capture[1].brackets[2].stokes",
            "raw data",
        ),
        (
            format!(
                "exposure = 2.0\nbrackets = [{{ exposure = 2.0, frames = {a} }}, {{ exposure = 1.0, frames = {b} }}]"
            ),
            "capture[1].exposure",
            "each bracket",
        ),
        (
            format!(
                "frames = {a}\nbrackets = [{{ exposure = 2.0, frames = {a} }}, {{ exposure = 1.0, frames = {b} }}]"
            ),
            "capture[1].frames",
            "each bracket",
        ),
        (
            format!("dark_signal_dn = -1\nframes = {a}"),
            "capture[1].dark_signal_dn",
            ">= 0",
        ),
    ];
    for (body, field, reason) in cases {
        let p = write_manifest(
            dir.path(),
            &format!("[[capture]]\ntheta_i_deg = 30.0\n{body}\n"),
        );
        let e = manifest::load(&p).unwrap_err();
        assert!(e.is_bad_input());
        let msg = e.to_string();
        assert!(
            msg.contains(field) && msg.contains(reason),
            "{body}\nexpected {field} / {reason}, got: {msg}"
        );
    }
}
