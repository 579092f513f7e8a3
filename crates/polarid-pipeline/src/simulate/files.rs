//! The text files of a simulated capture set: `manifest.toml` and `truth.csv`.

use std::fmt::Write as _;
use std::path::Path;

use polarid_io::IoError;
use polarid_io::scene::{CaptureKind, Scene};
use polarid_io::table::{fmt_f64, write_rows};

use super::{TruthRow, capture_dir, frame_file};

/// A TOML number (always with a decimal point or exponent).
fn toml_num(x: f64) -> String {
    let s = format!("{x:?}");
    if s.contains(['.', 'e', 'E']) || !x.is_finite() {
        s
    } else {
        format!("{s}.0")
    }
}

/// A TOML basic string.
fn toml_str(s: &str) -> String {
    let mut o = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04X}", c as u32);
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

/// The capture-set manifest of a simulated scene (`docs/FORMATS.md`), with the
/// relative exposure of every capture.
pub fn manifest_text(scene: &Scene, exposures: &[f64]) -> String {
    let sensor = &scene.sensor;
    let mut m = String::new();
    let _ = writeln!(
        m,
        "# polarid capture set simulated by `polarid simulate` from {}{}",
        scene
            .path
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default(),
        scene
            .name
            .as_ref()
            .map(|n| format!(" (scene {n})"))
            .unwrap_or_default()
    );
    let _ = writeln!(
        m,
        "# sensor: {} bit, full well {} e-, read noise {} e-, shot noise {}; ground truth in truth.csv",
        sensor.bit_depth,
        sensor.full_well_e,
        sensor.read_noise_e,
        if sensor.shot_noise { "on" } else { "off" }
    );
    let _ = writeln!(m, "theta_r_deg = {}", toml_num(scene.theta_r_deg));
    let _ = writeln!(m, "phi_deg = {}", toml_num(scene.phi_deg));
    let _ = writeln!(m, "dark_level = {}", toml_num(sensor.dark_level_dn));
    let _ = writeln!(m, "saturation = {}", toml_num(sensor.max_dn()));
    if let Some(wl) = scene.wavelength_nm {
        let _ = writeln!(m, "wavelength_nm = {}", toml_num(wl));
    }
    for p in &scene.plates {
        let r = p.region;
        let _ = writeln!(m, "\n[[region]]\nname = {}", toml_str(&p.name));
        let _ = writeln!(m, "rect = [{}, {}, {}, {}]", r.x, r.y, r.width, r.height);
        if let Some(c) = &p.class {
            let _ = writeln!(m, "class = {}", toml_str(c));
        }
    }
    for (ci, (&ti, &x)) in scene.theta_i_deg.iter().zip(exposures).enumerate() {
        let _ = writeln!(m, "\n[[capture]]\ntheta_i_deg = {}", toml_num(ti));
        let _ = writeln!(m, "exposure = {}", toml_num(x));
        match &scene.capture {
            CaptureKind::Frames { angles_deg } => {
                let _ = writeln!(m, "frames = [");
                for (fi, a) in angles_deg.iter().enumerate() {
                    let _ = writeln!(
                        m,
                        "  {{ angle_deg = {}, file = {} }},",
                        toml_num(*a),
                        toml_str(&frame_file(scene, ci, fi))
                    );
                }
                let _ = writeln!(m, "]");
            }
            CaptureKind::Dofp { pattern } => {
                let p = pattern.angles_deg().map(toml_num);
                let _ = writeln!(
                    m,
                    "dofp = {{ file = {}, pattern = [{}] }}",
                    toml_str(&format!(
                        "{}/raw.{}",
                        capture_dir(scene, ci),
                        scene.format.extension()
                    )),
                    p.join(", ")
                );
            }
        }
    }
    m
}

/// Write `truth.csv` (a comment line, then one row per capture and plate).
pub fn write_truth(
    w: &mut dyn std::io::Write,
    path: &Path,
    truth: &[TruthRow],
) -> polarid_io::Result<()> {
    w.write_all(
        b"# noise-free plate values; s0 in DN / exposure (the units of `polarid measure`)\n",
    )
    .map_err(|e| IoError::io(path, e))?;
    write_rows(
        w,
        path,
        &[
            "target",
            "class",
            "theta_i_deg",
            "theta_r_deg",
            "phi_deg",
            "beta_deg",
            "dolp",
            "s0",
            "dolp_eq9_specular",
            "exposure",
            "peak_electrons",
        ],
        truth.iter().map(|t| {
            vec![
                t.target.clone(),
                t.class.clone().unwrap_or_default(),
                fmt_f64(t.theta_i_deg),
                fmt_f64(t.theta_r_deg),
                fmt_f64(t.phi_deg),
                fmt_f64(t.beta_deg),
                fmt_f64(t.dolp),
                fmt_f64(t.s0),
                fmt_f64(t.dolp_eq9_specular),
                fmt_f64(t.exposure),
                fmt_f64(t.peak_electrons),
            ]
        }),
    )
}
