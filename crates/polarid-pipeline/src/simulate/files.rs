//! The text files of a simulated capture set: `manifest.toml` and `truth.csv`.

use std::fmt::Write as _;
use std::path::Path;

use polarid_io::IoError;
use polarid_io::manifest::{CameraOrientation, SourceSpec};
use polarid_io::scene::{Calibrated, CaptureKind, Geometry, Scene};
use polarid_io::table::{fmt_f64, write_rows};

use super::{TruthRow, frame_file};

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
    let theta_i: &[f64] = match &scene.geometry {
        Geometry::FarField {
            theta_r_deg,
            phi_deg,
            theta_i_deg,
        } => {
            let _ = writeln!(m, "theta_r_deg = {}", toml_num(*theta_r_deg));
            let _ = writeln!(m, "phi_deg = {}", toml_num(*phi_deg));
            theta_i_deg
        }
        Geometry::Calibrated(_) => &[],
    };
    let cal = scene.calibrated();
    let _ = writeln!(m, "dark_level = {}", toml_num(sensor.dark_level_dn));
    let _ = writeln!(m, "saturation = {}", toml_num(sensor.max_dn()));
    if let Some(wl) = scene.wavelength_nm {
        let _ = writeln!(m, "wavelength_nm = {}", toml_num(wl));
    }
    if let CaptureKind::ColourDofp { bands, .. } = &scene.capture {
        let b: Vec<String> = bands
            .iter()
            .map(|b| format!("{} = {}", b.letter, toml_num(b.wavelength_nm)))
            .collect();
        let _ = writeln!(m, "bands = {{ {} }}", b.join(", "));
    }
    if let Some(c) = cal {
        geometry_tables(&mut m, c);
    }
    for p in &scene.plates {
        let r = p.region;
        let _ = writeln!(m, "\n[[region]]\nname = {}", toml_str(&p.name));
        let _ = writeln!(m, "rect = [{}, {}, {}, {}]", r.x, r.y, r.width, r.height);
        if let (Some(c), Some(pl)) = (cal, &p.placement)
            && let Some(plane) = c.planes.get(pl.plane)
        {
            let _ = writeln!(m, "plane = {}", toml_str(&plane.name));
        }
        if let Some(c) = &p.class {
            let _ = writeln!(m, "class = {}", toml_str(c));
        }
    }
    capture_tables(&mut m, scene, exposures, theta_i);
    m
}

/// The manifest's `[[capture]]` tables: per capture its source (or `theta_i_deg`), its
/// relative exposure and its frame files.
fn capture_tables(m: &mut String, scene: &Scene, exposures: &[f64], theta_i: &[f64]) {
    let cal = scene.calibrated();
    for (ci, &x) in exposures.iter().enumerate() {
        match cal.and_then(|c| c.sources.get(ci)) {
            Some(s) => {
                let _ = writeln!(m, "\n[[capture]]");
                if let Some(n) = &s.name {
                    let _ = writeln!(m, "name = {}", toml_str(n));
                }
                let src = match &s.spec {
                    SourceSpec::Position(p) => format!("position = {}", toml_vec(p)),
                    SourceSpec::Direction(d) => format!("direction = {}", toml_vec(d)),
                    SourceSpec::Sun { time, .. } => format!("sun = {}", toml_str(time)),
                };
                let _ = writeln!(m, "source = {{ {src} }}");
            }
            None => {
                let ti = theta_i.get(ci).copied().unwrap_or(f64::NAN);
                let _ = writeln!(m, "\n[[capture]]\ntheta_i_deg = {}", toml_num(ti));
            }
        }
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
            CaptureKind::Dofp { .. } | CaptureKind::ColourDofp { .. } => {
                let color = match &scene.capture {
                    CaptureKind::ColourDofp { pattern, .. } => {
                        format!(", color = {}", toml_str(&pattern.color()))
                    }
                    _ => String::new(),
                };
                let _ = writeln!(
                    m,
                    "dofp = {{ file = {}, pattern = {}{color} }}",
                    toml_str(&frame_file(scene, ci, 0)),
                    toml_vec(&scene.capture.angles_deg()),
                );
            }
        }
    }
}

/// `[x, y, z]` as TOML numbers.
fn toml_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|&x| toml_num(x)).collect();
    format!("[{}]", parts.join(", "))
}

/// The `[camera]`, `[[plane]]` and `[site]` tables of a calibrated scene (FORMATS.md,
/// "Calibrated geometry").
fn geometry_tables(m: &mut String, c: &Calibrated) {
    let cam = &c.camera;
    let _ = writeln!(m, "\n[camera]");
    let _ = writeln!(m, "focal_px = {}", toml_vec(&cam.focal_px));
    let _ = writeln!(
        m,
        "principal_point_px = {}",
        toml_vec(&cam.principal_point_px)
    );
    if cam.distortion.iter().any(|&d| d != 0.0) {
        let _ = writeln!(m, "distortion = {}", toml_vec(&cam.distortion));
    }
    let _ = writeln!(m, "position = {}", toml_vec(&cam.position));
    match &cam.orientation {
        CameraOrientation::LookAt { look_at, up } => {
            let _ = writeln!(m, "look_at = {}", toml_vec(look_at));
            let _ = writeln!(m, "up = {}", toml_vec(up));
        }
        CameraOrientation::Rotation(r) => {
            let rows: Vec<String> = r.iter().map(|row| toml_vec(row)).collect();
            let _ = writeln!(m, "rotation = [{}]", rows.join(", "));
        }
    }
    for p in &c.planes {
        let _ = writeln!(m, "\n[[plane]]\nname = {}", toml_str(&p.name));
        let _ = writeln!(m, "point = {}", toml_vec(&p.point));
        let _ = writeln!(m, "normal = {}", toml_vec(&p.normal));
    }
    if let Some(s) = &c.site {
        let _ = writeln!(m, "\n[site]");
        let _ = writeln!(m, "latitude_deg = {}", toml_num(s.latitude_deg));
        let _ = writeln!(m, "longitude_deg = {}", toml_num(s.longitude_deg));
        let _ = writeln!(m, "elevation_m = {}", toml_num(s.elevation_m));
        let _ = writeln!(m, "pressure_mbar = {}", toml_num(s.pressure_mbar));
        let _ = writeln!(m, "temperature_c = {}", toml_num(s.temperature_c));
    }
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
    let calibrated = !truth.is_empty() && truth.iter().all(|t| t.calibrated.is_some());
    let mut header = vec![
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
    ];
    let colour = !truth.is_empty() && truth.iter().all(|t| t.band.is_some());
    if colour {
        header.extend(["band", "wavelength_nm", "n", "k"]);
    }
    if calibrated {
        header.push("capture");
        // A colour row already has the band's n and k.
        if !colour {
            header.extend(["n", "k"]);
        }
        header.extend([
            "sigma",
            "rho_d",
            "beta_sd_deg",
            "beta_min_deg",
            "beta_max_deg",
            "dolp_eq9_mean",
            "pixels",
        ]);
    }
    write_rows(
        w,
        path,
        &header,
        truth.iter().map(|t| {
            let mut row = vec![t.target.clone(), t.class.clone().unwrap_or_default()];
            row.extend(
                [
                    t.theta_i_deg,
                    t.theta_r_deg,
                    t.phi_deg,
                    t.beta_deg,
                    t.dolp,
                    t.s0,
                    t.dolp_eq9_specular,
                    t.exposure,
                    t.peak_electrons,
                ]
                .map(fmt_f64),
            );
            if let (true, Some(b)) = (colour, &t.band) {
                row.push(b.letter.to_string());
                row.extend([b.wavelength_nm, b.n, b.k].map(fmt_f64));
            }
            if let (true, Some(c)) = (calibrated, &t.calibrated) {
                row.push(c.capture.clone());
                if !colour {
                    row.extend([c.n, c.k].map(fmt_f64));
                }
                row.extend(
                    [
                        c.sigma,
                        c.rho_d,
                        c.beta_sd_deg,
                        c.beta_min_deg,
                        c.beta_max_deg,
                        c.dolp_eq9_mean,
                    ]
                    .map(fmt_f64),
                );
                row.push(c.pixels.to_string());
            }
            row
        }),
    )
}
