//! `polarid simulate SCENE.toml -o DIR`: synthetic captures of plates of known optics.
//!
//! For every source zenith of the scene, the radiance Stokes vector of each plate
//! follows from the Priest–Meier pBRDF (paper eq. 3) plus an optional Lambertian
//! depolarized term (`polarid_core::simulate::plate_radiance`); the sensor model adds
//! shot and read noise, quantizes and saturates. `DIR` receives the frames, a capture
//! manifest (`shared/FORMATS.md`) that `polarid measure` reads, `truth.csv` (the
//! noise-free DoLP and S0 of every plate per capture) and a copy of the scene. Everything
//! is written into a staging directory first, so a failure leaves nothing behind.
//!
//! Units: with relative exposure `x`, a radiance `I` behind the polarizer gives
//! `x · I · full_well` expected electrons; the manifest records `x` as the capture's
//! `exposure`, so `S0 / exposure` in DN (what `measure` writes) equals the radiance times
//! `2^bits − 1 − dark_level` whatever the exposure; `truth.csv`'s `s0` is in these units.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use polarid_core::dop::dop;
use polarid_core::geometry;
use polarid_core::simulate::{
    Analyzer, UniformRect, frame_seed, peak_intensity, plate_radiance, render_frame, stokes_dolp,
};
use polarid_io::IoError;
use polarid_io::atomic::StagedDir;
use polarid_io::image;
use polarid_io::scene::{self, CaptureKind, ImageFormat, Scene};
use polarid_io::table::{fmt_f64, write_rows};
use rayon::prelude::*;

use crate::Ctx;

/// Arguments of `polarid simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene (TOML, docs/SCENE.md).
    pub scene: PathBuf,
    /// Output directory (frames, manifest.toml, truth.csv, scene.toml).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
}

/// Noise-free values of one plate in one capture (a row of `truth.csv`).
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    /// Plate (target) name.
    pub target: String,
    /// Plate class, if any.
    pub class: Option<String>,
    /// Source zenith, degrees.
    pub theta_i_deg: f64,
    /// Camera zenith, degrees.
    pub theta_r_deg: f64,
    /// `phi_r − phi_i`, degrees.
    pub phi_deg: f64,
    /// β (eq. 5), degrees.
    pub beta_deg: f64,
    /// Noise-free DoLP of the plate's radiance.
    pub dolp: f64,
    /// Noise-free S0, DN per unit exposure (the units of `measure`'s `s0`).
    pub s0: f64,
    /// Eq. (9) DoLP of the plate's index at β (equals `dolp` when `rho_d = 0`).
    pub dolp_eq9_specular: f64,
    /// The capture's relative exposure.
    pub exposure: f64,
    /// Expected electrons of the plate's brightest polarizer angle.
    pub peak_electrons: f64,
}

/// What [`simulate_into`] wrote.
#[derive(Debug, Clone)]
pub struct Simulated {
    /// Staged name of the manifest (`PREFIX/manifest.toml`).
    pub manifest: String,
    /// Number of captures.
    pub captures: usize,
    /// Number of image files.
    pub frames: usize,
    /// The noise-free values, per capture then per plate (also in `truth.csv`).
    #[allow(dead_code)]
    pub truth: Vec<TruthRow>,
    /// Warnings (dim or saturated plates).
    pub warnings: Vec<String>,
}

/// Directory name of capture `i` (0-based) at source zenith `theta_i`: `i35`, `i37p5`;
/// prefixed by the capture number when two captures share a zenith.
fn capture_dir(scene: &Scene, i: usize) -> String {
    let t = scene.theta_i_deg[i];
    let base = format!("i{}", fmt_f64(t).replace('.', "p"));
    let dup = scene.theta_i_deg.iter().filter(|&&x| x == t).count() > 1;
    if dup {
        format!("c{:02}_{base}", i + 1)
    } else {
        base
    }
}

/// One image file to render.
struct Job {
    capture: usize,
    frame: usize,
    analyzer: Analyzer,
    name: String,
}

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

/// Simulate `scene` into `staged` under `prefix` (`""` or a directory name ending in
/// `/`): the frames, `manifest.toml`, `truth.csv` and `scene.toml`. Frames render in
/// parallel; the result is the same for a given scene (seeded noise).
pub fn simulate_into(
    scene: &Scene,
    staged: &StagedDir,
    prefix: &str,
    ctx: &Ctx,
) -> anyhow::Result<Simulated> {
    let sensor = &scene.sensor;
    let (tr, phi) = (scene.theta_r_deg.to_radians(), scene.phi_deg.to_radians());
    let angles_deg = scene.capture.angles_deg();
    let angles: Vec<f64> = angles_deg.iter().map(|a| a.to_radians()).collect();
    let label = |e: polarid_core::CoreError| IoError::Core {
        path: scene.path.clone(),
        source: e,
    };

    // Radiance, exposure and truth per capture.
    let mut rects: Vec<Vec<UniformRect>> = Vec::with_capacity(scene.theta_i_deg.len());
    let mut exposures = Vec::with_capacity(scene.theta_i_deg.len());
    let mut truth = Vec::new();
    let mut warnings = Vec::new();
    for &ti_deg in &scene.theta_i_deg {
        let ti = ti_deg.to_radians();
        let mut caps = Vec::with_capacity(scene.plates.len());
        for p in &scene.plates {
            let s = plate_radiance(&p.optics, ti, tr, phi).map_err(label)?;
            caps.push(UniformRect {
                x: p.rect.x,
                y: p.rect.y,
                width: p.rect.width,
                height: p.rect.height,
                stokes: s,
            });
        }
        let stokes: Vec<[f64; 3]> = caps.iter().map(|r| r.stokes).collect();
        let exposure = scene
            .exposure
            .resolve(peak_intensity(&stokes, &angles))
            .map_err(label)?;
        let epu = sensor.electrons_per_unit(exposure);
        let beta = geometry::beta(ti, tr, phi);
        for (p, r) in scene.plates.iter().zip(&caps) {
            let peak_e = epu * peak_intensity(&[r.stokes], &angles);
            if peak_e < 100.0 {
                warnings.push(format!(
                    "plate {:?} at theta_i = {ti_deg} deg is dim: {peak_e:.0} electrons at its \
                     brightest (its specular lobe misses the camera, or another plate is much \
                     brighter); its DoLP will be noisy",
                    p.name
                ));
            } else if peak_e > sensor.full_well_e {
                warnings.push(format!(
                    "plate {:?} at theta_i = {ti_deg} deg saturates ({peak_e:.0} electrons \
                     expected, full well {})",
                    p.name, sensor.full_well_e
                ));
            }
            truth.push(TruthRow {
                target: p.name.clone(),
                class: p.class.clone(),
                theta_i_deg: ti_deg,
                theta_r_deg: scene.theta_r_deg,
                phi_deg: scene.phi_deg,
                beta_deg: beta.to_degrees(),
                dolp: stokes_dolp(&r.stokes),
                s0: r.stokes[0] * sensor.dn_per_unit(),
                dolp_eq9_specular: dop(p.optics.n, p.optics.k, beta),
                exposure,
                peak_electrons: peak_e,
            });
        }
        rects.push(caps);
        exposures.push(exposure);
    }

    // The image files.
    let ext = scene.format.extension();
    let mut jobs = Vec::new();
    for ci in 0..scene.theta_i_deg.len() {
        let dir = capture_dir(scene, ci);
        match &scene.capture {
            CaptureKind::Frames { angles_deg } => {
                for (fi, a) in angles_deg.iter().enumerate() {
                    jobs.push(Job {
                        capture: ci,
                        frame: fi,
                        analyzer: Analyzer::Uniform(a.to_radians()),
                        name: format!("{dir}/pol{}.{ext}", fmt_angle(*a)),
                    });
                }
            }
            CaptureKind::Dofp { pattern } => {
                let p = pattern.angles_deg().map(f64::to_radians);
                jobs.push(Job {
                    capture: ci,
                    frame: 0,
                    analyzer: Analyzer::Mosaic(p),
                    name: format!("{dir}/raw.{ext}"),
                });
            }
        }
    }
    let (w, h) = (scene.width, scene.height);
    let background = [scene.background, 0.0, 0.0];
    let pb = ctx.progress(jobs.len() as u64, "frames");
    jobs.par_iter().try_for_each(|job| -> anyhow::Result<()> {
        let mut buf = vec![0u16; w * h];
        render_frame(
            w,
            h,
            &rects[job.capture],
            background,
            job.analyzer,
            sensor,
            sensor.electrons_per_unit(exposures[job.capture]),
            frame_seed(scene.seed, job.capture as u64, job.frame as u64),
            &mut buf,
        )
        .map_err(label)?;
        let path = staged.path(&format!("{prefix}{}", job.name))?;
        if sensor.bit_depth <= 8 {
            let b: Vec<u8> = buf.iter().map(|&v| v as u8).collect();
            image::write_gray8(&path, false, w, h, &b)?;
        } else {
            image::write_gray16(&path, false, w, h, &buf)?;
        }
        pb.inc(1);
        Ok(())
    })?;
    pb.finish_and_clear();

    // The manifest.
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
    for (ci, (&ti, &x)) in scene.theta_i_deg.iter().zip(&exposures).enumerate() {
        let _ = writeln!(m, "\n[[capture]]\ntheta_i_deg = {}", toml_num(ti));
        let _ = writeln!(m, "exposure = {}", toml_num(x));
        let dir = capture_dir(scene, ci);
        match &scene.capture {
            CaptureKind::Frames { angles_deg } => {
                let _ = writeln!(m, "frames = [");
                for a in angles_deg {
                    let _ = writeln!(
                        m,
                        "  {{ angle_deg = {}, file = {} }},",
                        toml_num(*a),
                        toml_str(&format!("{dir}/pol{}.{ext}", fmt_angle(*a)))
                    );
                }
                let _ = writeln!(m, "]");
            }
            CaptureKind::Dofp { pattern } => {
                let p = pattern.angles_deg().map(toml_num);
                let _ = writeln!(
                    m,
                    "dofp = {{ file = {}, pattern = [{}] }}",
                    toml_str(&format!("{dir}/raw.{ext}")),
                    p.join(", ")
                );
            }
        }
    }
    let manifest = format!("{prefix}manifest.toml");
    let mpath = staged.path(&manifest)?;
    polarid_io::atomic::write_atomic(&mpath, false, |w| {
        w.write_all(m.as_bytes())
            .map_err(|e| IoError::io(&mpath, e))
    })?;

    // truth.csv and the scene.
    let tpath = staged.path(&format!("{prefix}truth.csv"))?;
    polarid_io::atomic::write_atomic(&tpath, false, |w| {
        w.write_all(
            b"# noise-free plate values; s0 in DN / exposure (the units of `polarid measure`)\n",
        )
        .map_err(|e| IoError::io(&tpath, e))?;
        write_rows(
            w,
            &tpath,
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
    })?;
    let spath = staged.path(&format!("{prefix}scene.toml"))?;
    polarid_io::atomic::write_atomic(&spath, false, |w| {
        w.write_all(scene.text.as_bytes())
            .map_err(|e| IoError::io(&spath, e))
    })?;
    Ok(Simulated {
        manifest,
        captures: scene.theta_i_deg.len(),
        frames: jobs.len(),
        truth,
        warnings,
    })
}

/// A polarizer angle in a file name: `000`, `045`, `022p5`.
fn fmt_angle(a: f64) -> String {
    if a.fract() == 0.0 && (0.0..1000.0).contains(&a) {
        format!("{:03}", a as u32)
    } else {
        fmt_f64(a).replace(['.', '-'], "p")
    }
}

/// Run `polarid simulate`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let scene = scene::load(&args.scene)?;
    if args.output.is_file() {
        return Err(crate::BadInput(format!(
            "{}: the output must be a directory, and this is a file",
            args.output.display()
        ))
        .into());
    }
    let staged = StagedDir::new(&args.output, ctx.force)?;
    let sim = simulate_into(&scene, &staged, "", ctx)
        .with_context(|| format!("simulating {}", args.scene.display()))?;
    staged.commit()?;
    for w in &sim.warnings {
        ctx.info(format!("polarid: warning: {w}"));
    }
    let kind = match &scene.capture {
        CaptureKind::Frames { angles_deg } => format!("{} polarizer angles", angles_deg.len()),
        CaptureKind::Dofp { .. } => "DoFP mosaics".to_string(),
    };
    ctx.info(format!(
        "polarid simulate: {} plate(s), {} capture(s) ({kind}), {} {} file(s) -> {}",
        scene.plates.len(),
        sim.captures,
        sim.frames,
        match scene.format {
            ImageFormat::Png => "PNG",
            ImageFormat::Tiff => "TIFF",
        },
        args.output.join(&sim.manifest).display()
    ));
    Ok(())
}
