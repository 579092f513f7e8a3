//! Simulation of a far-field scene seen by a colour polarization camera (`[capture]
//! color`, docs/SCENE.md): one raw colour mosaic per capture
//! (`polarid_core::simulate::colour`), written as `CAPTURE/raw.png` (or `.tif`) with a
//! manifest carrying `bands` and `dofp.color` (docs/FORMATS.md, "Colour polarization
//! cameras"), and a `truth.csv` with one row per plate, capture and band.
//!
//! Per capture, each band `b` of each plate has the radiance of the monochrome simulator
//! with the band's optics (`plate_radiance`, paper eq. 3); the exposure `x` is resolved
//! from the brightest plate pixel over every band and polarizer angle, each band's
//! radiance weighted by its response `r_b` (`[sensor] band_response`); band `b`'s pixels
//! get `x · full_well · r_b` expected electrons per unit radiance. `truth.csv`'s `s0` of
//! band `b` is then `r_b ·` the radiance in DN per unit exposure (what `measure` reports
//! for the band).

use polarid_core::dop::dop;
use polarid_core::geometry;
use polarid_core::mosaic::ColourPattern;
use polarid_core::simulate::{
    ColourRect, colour_plate_radiance, frame_seed, peak_intensity, render_colour_frame, stokes_dolp,
};
use polarid_io::IoError;
use polarid_io::atomic::StagedDir;
use polarid_io::scene::{Geometry, Scene, SceneBand};
use rayon::prelude::*;

use super::{
    ColourFrames, Simulated, TruthBand, TruthRow, frame_file, manifest_text, write_text_files,
};
use crate::error::Result;
use crate::progress::{Progress, Warning};

/// The radiance, exposure and truth of every capture of a colour scene.
struct Plan<'a> {
    pattern: &'a ColourPattern,
    rects: Vec<Vec<ColourRect>>,
    /// Expected electrons per unit radiance, per capture and band.
    epu: Vec<Vec<f64>>,
    exposures: Vec<f64>,
    truth: Vec<TruthRow>,
    warnings: Vec<Warning>,
}

/// The colour pattern and bands of `scene` (an internal error for another capture kind).
fn colour_of(scene: &Scene) -> Result<(&ColourPattern, &[SceneBand])> {
    match &scene.capture {
        polarid_io::scene::CaptureKind::ColourDofp { pattern, bands } => Ok((pattern, bands)),
        _ => Err(crate::PipelineError::Data {
            path: scene.path.display().to_string(),
            reason: "internal error: not a colour scene".into(),
        }),
    }
}

/// Plan a far-field colour scene (no rendering yet).
fn plan(scene: &Scene) -> Result<Plan<'_>> {
    let (pattern, bands) = colour_of(scene)?;
    let Geometry::FarField {
        theta_r_deg,
        phi_deg,
        theta_i_deg,
    } = &scene.geometry
    else {
        return Err(crate::PipelineError::Data {
            path: scene.path.display().to_string(),
            reason: "colour captures are simulated in the far field only".into(),
        });
    };
    let sensor = &scene.sensor;
    let (theta_r_deg, phi_deg) = (*theta_r_deg, *phi_deg);
    let (tr, phi) = (theta_r_deg.to_radians(), phi_deg.to_radians());
    let angles = super::angles_rad(&scene.capture);
    let label = |e: polarid_core::CoreError| IoError::core(&scene.path, e);
    let resp: Vec<f64> = bands.iter().map(|b| b.response).collect();
    let mut out = Plan {
        pattern,
        rects: Vec::new(),
        epu: Vec::new(),
        exposures: Vec::new(),
        truth: Vec::new(),
        warnings: Vec::new(),
    };
    for &ti_deg in theta_i_deg {
        let ti = ti_deg.to_radians();
        let mut caps = Vec::with_capacity(scene.plates.len());
        for p in &scene.plates {
            let s = colour_plate_radiance(&p.bands, ti, tr, phi).map_err(label)?;
            caps.push(ColourRect {
                x: p.rect.x,
                y: p.rect.y,
                width: p.rect.width,
                height: p.rect.height,
                stokes: s,
            });
        }
        // The brightest pixel over plates, bands (weighted by their response) and angles.
        let weighted: Vec<[f64; 3]> = caps
            .iter()
            .flat_map(|r| r.stokes.iter().zip(&resp).map(|(s, &w)| s.map(|x| x * w)))
            .collect();
        let exposure = scene
            .exposure
            .resolve(peak_intensity(&weighted, &angles))
            .map_err(label)?;
        let epu: Vec<f64> = resp
            .iter()
            .map(|&w| sensor.electrons_per_unit(exposure) * w)
            .collect();
        let beta = geometry::beta(ti, tr, phi);
        for (p, r) in scene.plates.iter().zip(&caps) {
            for (b, band) in bands.iter().enumerate() {
                let (s, o) = (&r.stokes[b], &p.bands[b]);
                let peak_e = epu[b] * peak_intensity(&[*s], &angles);
                if peak_e < 100.0 {
                    out.warnings.push(Warning(format!(
                        "plate {:?} at theta_i = {ti_deg} deg is dim in band {} ({} nm): \
                         {peak_e:.0} electrons at its brightest; its DoLP will be noisy",
                        p.name, band.letter, band.wavelength_nm
                    )));
                } else if peak_e > sensor.full_well_e {
                    out.warnings.push(Warning(format!(
                        "plate {:?} at theta_i = {ti_deg} deg saturates in band {} ({} nm): \
                         {peak_e:.0} electrons expected, full well {}",
                        p.name, band.letter, band.wavelength_nm, sensor.full_well_e
                    )));
                }
                out.truth.push(TruthRow {
                    target: p.name.clone(),
                    class: p.class.clone(),
                    theta_i_deg: ti_deg,
                    theta_r_deg,
                    phi_deg,
                    beta_deg: beta.to_degrees(),
                    dolp: stokes_dolp(s),
                    s0: s[0] * band.response * sensor.dn_per_unit(),
                    dolp_eq9_specular: dop(o.n, o.k, beta),
                    exposure,
                    peak_electrons: peak_e,
                    calibrated: None,
                    band: Some(TruthBand {
                        letter: band.letter,
                        wavelength_nm: band.wavelength_nm,
                        n: o.n,
                        k: o.k,
                    }),
                });
            }
        }
        out.rects.push(caps);
        out.epu.push(epu);
        out.exposures.push(exposure);
    }
    Ok(out)
}

impl Plan<'_> {
    /// Render capture `ci` into `buf` with noise seed `seed`.
    fn render(&self, scene: &Scene, ci: usize, seed: u64, buf: &mut [u16]) -> Result<()> {
        let bg = vec![[scene.background, 0.0, 0.0]; self.pattern.bands().len()];
        render_colour_frame(
            scene.width,
            scene.height,
            &self.rects[ci],
            &bg,
            self.pattern,
            &scene.sensor,
            &self.epu[ci],
            seed,
            buf,
        )
        .map_err(|e| IoError::core(&scene.path, e).into())
    }
}

/// Render every capture of a colour scene in memory (the frames that
/// [`super::simulate_into`] writes, bit for bit: the same seeds), in parallel for a
/// far-field scene, one capture at a time for a calibrated one.
///
/// Errors: [`crate::PipelineError::Data`] for a scene without a colour capture; the
/// core's errors naming the scene (e.g. a frame that is not whole 4×4 periods).
pub fn render_colour_set(scene: &Scene) -> Result<ColourFrames> {
    if let Some(cal) = scene.calibrated() {
        let (pattern, bands) = colour_of(scene)?;
        return super::calibrated::render_colour_set(scene, cal, pattern, bands);
    }
    let plan = plan(scene)?;
    let npix = scene.width * scene.height;
    let frames = (0..plan.rects.len())
        .into_par_iter()
        .map(|ci| {
            let mut buf = vec![0u16; npix];
            plan.render(scene, ci, frame_seed(scene.seed, ci as u64, 0), &mut buf)?;
            Ok(buf)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(ColourFrames {
        width: scene.width,
        height: scene.height,
        frames,
        exposures: plan.exposures,
        truth: plan.truth,
        warnings: plan.warnings,
    })
}

/// Simulate a far-field colour scene into `staged` under `prefix` (as
/// [`super::simulate_into`]).
pub(super) fn simulate(
    scene: &Scene,
    staged: &StagedDir,
    prefix: &str,
    progress: Progress<'_>,
) -> Result<Simulated> {
    let plan = plan(scene)?;
    let n = plan.rects.len();
    let (w, h) = (scene.width, scene.height);
    let done = std::sync::atomic::AtomicU64::new(0);
    (0..n).into_par_iter().try_for_each(|ci| -> Result<()> {
        let mut buf = vec![0u16; w * h];
        plan.render(scene, ci, frame_seed(scene.seed, ci as u64, 0), &mut buf)?;
        let name = format!("{prefix}{}", frame_file(scene, ci, 0));
        super::write_frame(staged, &name, &scene.sensor, w, h, &buf)?;
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress("frames", d, n as u64);
        Ok(())
    })?;
    let text = manifest_text(scene, &plan.exposures);
    write_text_files(scene, staged, prefix, &text, &plan.truth)?;
    Ok(Simulated {
        manifest: format!("{prefix}manifest.toml"),
        captures: scene.captures(),
        frames: n,
        truth: plan.truth,
        warnings: plan.warnings,
    })
}
