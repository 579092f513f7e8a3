//! Stage 1 of the map: the (binned) DoLP image of one capture and its signal flags.

use std::path::Path;

use polarid_core::map::noise::NoiseAnalyzer;
use polarid_core::map::{self, NoiseOut};
use polarid_core::mosaic;
use polarid_core::stokes::StokesSolver;
use polarid_io::IoError;
use polarid_io::image::{self, Frame};
use polarid_io::manifest::{Capture, CaptureSource};
use polarid_io::measure::rules_for;

use super::MapConfig;
use super::rules::min_s0_for;
use crate::error::{PipelineError, Result};

/// The map's geometry: frame size, binned size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Dims {
    pub width: usize,
    pub height: usize,
    pub out_w: usize,
    pub out_h: usize,
}

fn core_err(path: &Path) -> impl FnOnce(polarid_core::CoreError) -> IoError + '_ {
    move |e| IoError::Core {
        path: path.to_path_buf(),
        source: e,
    }
}

/// Check that a capture's frame has the map's size (set by the first capture).
pub(crate) fn check_dims(dims: &mut Option<Dims>, f: &Frame, bin: usize) -> Result<Dims> {
    match dims {
        Some(d) => {
            if (d.width, d.height) != (f.width, f.height) {
                return Err(IoError::Image {
                    path: f.path.clone(),
                    reason: format!(
                        "is {}x{} pixels but the first capture's frames are {}x{}: every capture of a map must have the same size",
                        f.width, f.height, d.width, d.height
                    ),
                }
                .into());
            }
            Ok(*d)
        }
        None => {
            let (out_w, out_h) = map::binned_size(f.width, f.height, bin).map_err(|e| {
                PipelineError::config(
                    "--bin",
                    bin,
                    format!(
                        "does not fit the {}x{} frames of {}: {e}",
                        f.width,
                        f.height,
                        f.path.display()
                    ),
                )
            })?;
            let d = Dims {
                width: f.width,
                height: f.height,
                out_w,
                out_h,
            };
            *dims = Some(d);
            Ok(d)
        }
    }
}

/// DoLP (binned) of one capture into `dolp`, ORing its signal flags into `flags`, and
/// with `noise` the noise terms `(A, B)` of every block (`polarid_core::map::noise`);
/// returns the dark threshold used (DN).
pub(crate) fn capture_dolp(
    c: &Capture,
    cfg: &MapConfig,
    dims: &mut Option<Dims>,
    dolp: &mut Vec<f32>,
    flags: &mut Vec<u8>,
    mut noise: Option<(&mut Vec<f32>, &mut Vec<f32>)>,
) -> Result<f32> {
    let bin = cfg.bin;
    let alloc = |d: Dims,
                 dolp: &mut Vec<f32>,
                 flags: &mut Vec<u8>,
                 noise: &mut Option<(&mut Vec<f32>, &mut Vec<f32>)>| {
        let n = d.out_w * d.out_h;
        dolp.resize(n, 0.0);
        if flags.is_empty() {
            flags.resize(n, 0);
        }
        if let Some((a, b)) = noise {
            a.resize(n, 0.0);
            b.resize(n, 0.0);
        }
    };
    let quad = NoiseAnalyzer::quad();
    match &c.source {
        CaptureSource::Frames(frames) => {
            let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
            let solver = StokesSolver::from_degrees(&angles)?;
            let paths: Vec<&Path> = frames.iter().map(|f| f.file.as_path()).collect();
            let imgs = image::read_frames(&paths)?;
            let Some(first) = imgs.first() else {
                return Err(IoError::Core {
                    path: c.source.files().first().map_or_else(
                        || std::path::PathBuf::from("<no frames>"),
                        |p| p.to_path_buf(),
                    ),
                    source: polarid_core::CoreError::TooFew {
                        what: "frames",
                        needed: solver.len(),
                        got: 0,
                    },
                }
                .into());
            };
            let d = check_dims(dims, first, bin)?;
            alloc(d, dolp, flags, &mut noise);
            let an = NoiseAnalyzer::of_solver(&solver);
            let mut rules = rules_for(first, c.dark_level, c.saturation);
            rules.min_s0 = min_s0_for(&rules, first.kind.is_integer(), cfg.min_s0);
            let views: Vec<&[f32]> = imgs.iter().map(|f| f.data.as_slice()).collect();
            let nz = noise_out(&an, 1.0, &mut noise);
            map::frames_dolp_noise(&solver, &views, d.width, &rules, bin, dolp, flags, nz)
                .map_err(core_err(&first.path))?;
            Ok(rules.min_s0)
        }
        CaptureSource::Dofp { file, pattern } => {
            let raw = image::read_frame(file)?;
            let d = check_dims(dims, &raw, bin)?;
            alloc(d, dolp, flags, &mut noise);
            let mut rules = rules_for(&raw, c.dark_level, c.saturation);
            let min_s0 = min_s0_for(&rules, raw.kind.is_integer(), cfg.min_s0);
            // The dark test is made on the block mean by stokes_dolp.
            rules.min_s0 = f32::MIN;
            let n = raw.width * raw.height;
            let (mut s0, mut s1, mut s2, mut m) =
                (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0u8; n]);
            mosaic::bilinear_stokes(
                &raw.data, raw.width, pattern, &rules, false, &mut s0, &mut s1, &mut s2, &mut m,
            )
            .map_err(core_err(file))?;
            drop(raw);
            let nz = noise_out(&quad, 1.0, &mut noise);
            map::stokes_dolp_noise(
                d.width,
                &s0,
                &s1,
                &s2,
                Some(&m),
                min_s0,
                bin,
                dolp,
                flags,
                nz,
            )
            .map_err(core_err(file))?;
            Ok(min_s0)
        }
        CaptureSource::ColourDofp { file, .. } => Err(PipelineError::Data {
            path: file.display().to_string(),
            reason: "internal error: a colour capture is mapped per band (map::bands), not as \
                     one DoLP image"
                .into(),
        }),
        CaptureSource::Stokes { s0, s1, s2 } => {
            let imgs = image::read_frames(&[s0, s1, s2])?;
            let [i0, i1, i2] = &imgs[..] else {
                return Err(PipelineError::Data {
                    path: s0.display().to_string(),
                    reason: "expected three Stokes images (S0, S1, S2)".into(),
                });
            };
            let d = check_dims(dims, i0, bin)?;
            alloc(d, dolp, flags, &mut noise);
            let min_s0 = cfg.min_s0.unwrap_or(0.0) / c.exposure;
            // S in DN / exposure: back to DN for the noise model.
            let nz = noise_out(&quad, c.exposure, &mut noise);
            map::stokes_dolp_noise(
                d.width,
                &i0.data,
                &i1.data,
                &i2.data,
                None,
                min_s0 as f32,
                bin,
                dolp,
                flags,
                nz,
            )
            .map_err(core_err(s0))?;
            Ok(min_s0 as f32)
        }
    }
}

/// The noise output of a capture's DoLP kernel, when the map wants one.
fn noise_out<'a>(
    analyzer: &'a NoiseAnalyzer,
    scale: f64,
    noise: &'a mut Option<(&mut Vec<f32>, &mut Vec<f32>)>,
) -> Option<NoiseOut<'a>> {
    noise.as_mut().map(|(a, b)| NoiseOut {
        analyzer,
        scale,
        read: a.as_mut_slice(),
        shot: b.as_mut_slice(),
    })
}
