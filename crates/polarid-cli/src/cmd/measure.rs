//! `polarid measure MANIFEST [-o measurements.csv]`: each region's DoLP per capture.
//!
//! Captures are processed one after the other (each one in parallel inside), so memory
//! holds one capture at a time. For every region and capture the row holds the DoLP of
//! the region's mean Stokes vector, its standard error from the pixel scatter
//! (`polarid_core::region`), the mean S0 divided by the capture's exposure, the pixels
//! used and rejected, and `beta` from the geometry (eq. 5).
//!
//! A standard error that comes out as 0 (noiseless data) is written as an empty cell.
//!
//! Saturation is reported, not hidden: `rejected` counts every pixel of the region left
//! out (saturated, dark or invalid — for DoFP, a pixel is rejected when any raw pixel its
//! bilinear interpolation uses is), and `saturated` the part of `rejected` that is
//! saturated (a raw value at or above the capture's `saturation`, default the type's
//! maximum). `pixels + rejected` is the region's area. When more than
//! [`SATURATED_WARN`] of a region is saturated, a warning on standard error names the
//! target, the capture and the fraction.
//!
//! DoFP captures are demosaiced bilinearly at full resolution (so that `rect` is in raw
//! pixel coordinates) without rounding, and their standard errors use the bilinear
//! variance inflation. Stokes captures (float TIFF) are used as they are: `dark_level`
//! and `saturation` do not apply; pixels with `S0 <= 0` or non-finite values are
//! rejected.

use std::path::{Path, PathBuf};

use polarid_core::geometry;
use polarid_core::region::{Sampling, region_stats};
use polarid_core::stokes::{self, StokesSolver};
use polarid_io::IoError;
use polarid_io::image;
use polarid_io::manifest::{self, Capture, CaptureSource, Manifest};
use polarid_io::table::measurements::{self, Measurement};

use super::stokes::{Demosaic, StokesImages, dofp_stokes, frames_stokes, rules_for};
use crate::Ctx;

/// Arguments of `polarid measure`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The capture-set manifest (TOML, shared/FORMATS.md).
    pub manifest: PathBuf,
    /// Output CSV (default: standard output).
    #[arg(short = 'o', long, value_name = "CSV")]
    pub output: Option<PathBuf>,
}

/// Fraction of a region's pixels above which saturation is warned about (1 %).
pub const SATURATED_WARN: f64 = 0.01;

/// Stokes images of one capture.
fn capture_images(c: &Capture) -> anyhow::Result<StokesImages> {
    Ok(match &c.source {
        CaptureSource::Frames(frames) => {
            let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
            let solver = StokesSolver::from_degrees(&angles)?;
            let paths: Vec<&Path> = frames.iter().map(|f| f.file.as_path()).collect();
            let imgs = image::read_frames(&paths)?;
            // ok: the manifest guarantees at least three frames.
            let rules = rules_for(&imgs[0], c.dark_level, c.saturation);
            frames_stokes(&imgs, &solver, &rules)?
        }
        CaptureSource::Dofp { file, pattern } => {
            let raw = image::read_frame(file)?;
            let rules = rules_for(&raw, c.dark_level, c.saturation);
            dofp_stokes(&raw, pattern, &rules, Demosaic::Bilinear, false)?
        }
        CaptureSource::Stokes { s0, s1, s2 } => {
            let imgs = image::read_frames(&[s0, s1, s2])?;
            for f in &imgs {
                image::check_float(f, "a Stokes image")?;
            }
            // ok: read_frames returned one frame per path (three).
            let (w, h) = (imgs[0].width, imgs[0].height);
            let mut it = imgs.into_iter().map(|f| f.data);
            let (d0, d1, d2) = match (it.next(), it.next(), it.next()) {
                (Some(a), Some(b), Some(c)) => (a, b, c),
                _ => anyhow::bail!("internal error: three Stokes images expected"),
            };
            let mut mask = vec![0u8; w * h];
            let counts = stokes::mask_stokes(w, &d0, &d1, &d2, 0.0, &mut mask).map_err(|e| {
                IoError::Core {
                    path: s0.clone(),
                    source: e,
                }
            })?;
            StokesImages {
                width: w,
                height: h,
                s0: d0,
                s1: d1,
                s2: d2,
                mask,
                counts,
                sampling: Sampling::Independent,
            }
        }
    })
}

fn measure_capture(m: &Manifest, c: &Capture) -> anyhow::Result<Vec<Measurement>> {
    let img = capture_images(c)?;
    let beta_deg = geometry::beta(
        c.theta_i_deg.to_radians(),
        c.theta_r_deg.to_radians(),
        c.phi_deg.to_radians(),
    )
    .to_degrees();
    let first_file = c
        .source
        .files()
        .first()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let mut rows = Vec::with_capacity(m.regions.len());
    for r in &m.regions {
        let st = region_stats(
            img.width,
            &img.s0,
            &img.s1,
            &img.s2,
            &img.mask,
            r.rect,
            img.sampling,
        )
        .map_err(|e| IoError::Manifest {
            path: m.path.clone(),
            line: r.line,
            field: format!("region[{}].rect", r.index),
            value: format!(
                "[{}, {}, {}, {}]",
                r.rect.x, r.rect.y, r.rect.width, r.rect.height
            ),
            reason: format!(
                "in capture {} (line {}, {first_file}, {}x{} pixels): {e}",
                c.index, c.line, img.width, img.height
            ),
        })?;
        rows.push(Measurement {
            target: r.name.clone(),
            class: r.class.clone(),
            theta_i_deg: Some(c.theta_i_deg),
            theta_r_deg: Some(c.theta_r_deg),
            phi_deg: c.phi_deg,
            beta_deg,
            dolp: st.dolp,
            // Noiseless data have no scatter; an SE of 0 is left empty (the CSV
            // contract requires dolp_se > 0 when present).
            dolp_se: st.dolp_se.filter(|se| se.is_finite() && *se > 0.0),
            s0: Some(st.s0() / c.exposure),
            pixels: Some(st.pixels),
            rejected: Some(st.rejected),
            exposure: Some(c.exposure),
            saturated: Some(st.saturated),
        });
    }
    Ok(rows)
}

/// Measure every region of every capture of a loaded manifest (one row per target per
/// capture, captures in manifest order), with a progress bar over the captures.
pub fn measure_manifest(m: &Manifest, ctx: &Ctx) -> anyhow::Result<Vec<Measurement>> {
    let pb = ctx.progress(m.captures.len() as u64, "captures");
    let mut rows = Vec::with_capacity(m.captures.len() * m.regions.len());
    for c in &m.captures {
        rows.extend(measure_capture(m, c)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    for (i, r) in rows.iter().enumerate() {
        let (Some(sat), Some(px), Some(rej)) = (r.saturated, r.pixels, r.rejected) else {
            continue;
        };
        let area = px + rej;
        if area > 0 && sat as f64 > SATURATED_WARN * area as f64 {
            let c = m.regions.len().max(1);
            let cap = m.captures.get(i / c);
            ctx.info(format!(
                "polarid: warning: target {:?}, capture {} (line {}): {sat} of {area} pixels \
                 ({:.1}%) saturated and left out",
                r.target,
                cap.map_or(0, |c| c.index),
                cap.map_or(0, |c| c.line),
                100.0 * sat as f64 / area as f64
            ));
        }
    }
    Ok(rows)
}

/// Run `polarid measure`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let m = manifest::load(&args.manifest)?;
    for w in &m.warnings {
        if !ctx.quiet {
            eprintln!("polarid: warning: {w}");
        }
    }
    let mut inputs: Vec<&Path> = vec![args.manifest.as_path()];
    for c in &m.captures {
        inputs.extend(c.source.files());
    }
    if let Some(out) = &args.output {
        polarid_io::atomic::check_output(out, ctx.force, &inputs)?;
    }
    let rows = measure_manifest(&m, ctx)?;
    let label = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from("<stdout>"));
    ctx.write_output(args.output.as_deref(), &inputs, |w| {
        measurements::write(w, &label, &rows)
    })?;
    if let Some(out) = &args.output {
        ctx.info(format!(
            "polarid measure: {} rows ({} targets x {} captures) written to {}",
            rows.len(),
            m.regions.len(),
            m.captures.len(),
            out.display()
        ));
    }
    Ok(())
}
