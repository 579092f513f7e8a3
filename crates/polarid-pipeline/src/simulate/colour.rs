//! Frames of a far-field scene seen by a colour polarization camera (`[capture] color`,
//! docs/SCENE.md): one raw colour mosaic per capture (`polarid_core::simulate::colour`),
//! written as `CAPTURE/raw.png` (or `.tif`) with a manifest carrying `bands` and
//! `dofp.color` (docs/FORMATS.md, "Colour polarization cameras"), and a `truth.csv` with
//! one row per plate, capture and band. The radiance, exposure and truth of every band
//! are planned as for a single-band scene (`super::plan`, a single-band scene being one
//! band): band `b`'s pixels get `x · full_well · r_b` expected electrons per unit
//! radiance, and `truth.csv`'s `s0` of band `b` is `r_b ·` the radiance in DN per unit
//! exposure (what `measure` reports for the band).

use polarid_core::mosaic::ColourPattern;
use polarid_core::simulate::{frame_seed, render_colour_frame};
use polarid_io::IoError;
use polarid_io::scene::{CaptureKind, Scene};
use rayon::prelude::*;

use super::{ColourFrames, Plan, plan};
use crate::error::Result;

/// The colour pattern of `scene` (an internal error for another capture kind).
fn colour_of(scene: &Scene) -> Result<&ColourPattern> {
    match &scene.capture {
        CaptureKind::ColourDofp { pattern, .. } => Ok(pattern),
        _ => Err(crate::PipelineError::Data {
            path: scene.path.display().to_string(),
            reason: "internal error: not a colour scene".into(),
        }),
    }
}

impl Plan {
    /// Render the raw colour mosaic of capture `ci` of `scene` into `buf` (noise seed
    /// `frame_seed(seed, ci, 0)`).
    pub(super) fn render_colour(&self, scene: &Scene, ci: usize, buf: &mut [u16]) -> Result<()> {
        let pattern = colour_of(scene)?;
        let bg = vec![[scene.background, 0.0, 0.0]; pattern.bands().len()];
        render_colour_frame(
            scene.width,
            scene.height,
            &self.rects[ci],
            &bg,
            pattern,
            &scene.sensor,
            &self.epu[ci],
            frame_seed(scene.seed, ci as u64, 0),
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
    let pattern = colour_of(scene)?;
    if let Some(cal) = scene.calibrated() {
        return super::calibrated::render_colour_set(scene, cal, pattern);
    }
    let plan = plan(scene)?;
    let npix = scene.width * scene.height;
    let frames = (0..plan.rects.len())
        .into_par_iter()
        .map(|ci| {
            let mut buf = vec![0u16; npix];
            plan.render_colour(scene, ci, &mut buf)?;
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
