//! One block of a material map from in-memory frames (`_map_block`), the kernel of
//! `polarid.dask.material_map`.
//!
//! A block is a rectangle of every capture's frames (rotating-polarizer frames, or a
//! DoFP mosaic with a halo of raw pixels around it). The steps are those of
//! `polarid_pipeline::map::map_manifest` (`polarid map`), with the same kernels, in
//! the same order, on the block's pixels only: per capture the binned DoLP and signal
//! flags (`polarid_core::map::frames_dolp`, or `mosaic::bilinear_stokes` then
//! `map::stokes_dolp` for DoFP), with the same pixel rules and dark threshold
//! (`polarid_pipeline::map::rules::min_s0_for`); with a β per pixel, the calibrated
//! rules (a pixel's dark or saturated captures are left out of its own fit, at least 3
//! must remain); then `map::fit_and_classify` with the model's per-pixel classifier
//! (`polarid_pipeline::map::pixel_classifier`). Every output pixel depends only on its
//! own `bin × bin` block of frames (and, for DoFP, the raw pixels within 2 of it), so a
//! map made of blocks whose edges are multiples of `bin` (and even, for DoFP) equals
//! the map of the whole frame.

use std::path::PathBuf;

use ndarray::{ArrayD, IxDyn};
use numpy::PyUntypedArrayMethods;
use polarid_core::CoreError;
use polarid_core::fit::{FitOptions, FitPlan, PixelBetaPlan};
use polarid_core::map::{self as cmap, Betas, MapOutputs, PixelClassifier};
use polarid_core::mosaic::{self, Pattern};
use polarid_core::stokes::{PixelRules, Sample, StokesSolver};
use polarid_io::model::Model;
use polarid_pipeline::map::rules::min_s0_for;
use polarid_pipeline::map::{self, MapConfig, REASON_NAMES};
use pyo3::prelude::*;

use crate::arrays::{f64_contiguous, fmt_shape, raw_array, to_numpy};
use crate::errors::{IntoPyErr, PyResultExt, value_error};
use crate::stokes::pixel_rules;
use crate::with_raw;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(_map_block, m)?)?;
    m.add_function(wrap_pyfunction!(_map_names, m)?)?;
    Ok(())
}

/// Number of float32 planes of a block's result: n, k, n_se, k_se, rms_residual, class,
/// reason.
const PLANES: usize = 7;

fn parse_model(model_json: &str, label: &str) -> PyResult<Model> {
    Model::parse(&PathBuf::from(label), model_json).map_err(IntoPyErr::into_py_err)
}

fn config(
    bin: usize,
    min_s0: Option<f64>,
    max_distance: Option<f64>,
    metric: &str,
    tile: usize,
) -> PyResult<MapConfig> {
    let metric = map::parse_metric(metric).py_err()?;
    MapConfig::new(bin, min_s0, max_distance, metric, tile).py_err()
}

/// The class names (``"unknown"`` first, then the model's classes sorted: index = class
/// code of a map) and the reason names (index = reason code; ``no_geometry`` only when
/// ``per_pixel_beta``) of a map with this model. Checks the options as ``_map_block``
/// does (errors name the option).
#[pyfunction]
#[pyo3(signature = (model_json, *, label = "<model>", per_pixel_beta = false, bin = 1, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE))]
#[allow(clippy::too_many_arguments)]
fn _map_names(
    model_json: &str,
    label: &str,
    per_pixel_beta: bool,
    bin: usize,
    min_s0: Option<f64>,
    max_distance: Option<f64>,
    metric: &str,
    tile: usize,
) -> PyResult<(Vec<String>, Vec<String>)> {
    let cfg = config(bin, min_s0, max_distance, metric, tile)?;
    let model = parse_model(model_json, label)?;
    let pc = map::pixel_classifier(&cfg, &model, &PathBuf::from(label)).py_err()?;
    let mut classes = vec![polarid_core::classify::UNKNOWN.to_string()];
    classes.extend(pc.names().iter().cloned());
    // Every reason, as `map_summary.json`'s `reason_codes` lists them (far field too).
    let _ = per_pixel_beta;
    let reasons = REASON_NAMES.iter().map(|s| s.to_string()).collect();
    Ok((classes, reasons))
}

/// Crop rows `top..h-bottom` and columns `left..w-right` of a `w`-wide image.
fn crop<T: Copy>(v: &[T], w: usize, h: usize, c: [usize; 4]) -> Vec<T> {
    let [top, bottom, left, right] = c;
    let mut out = Vec::with_capacity((h - top - bottom) * (w - left - right));
    for y in top..h - bottom {
        out.extend_from_slice(&v[y * w + left..(y + 1) * w - right]);
    }
    out
}

/// One block of a material map (private: called by ``polarid.dask.material_map``).
///
/// ``frames``: (T, A, h, w) polarizer frames (``angles_deg`` the A angles), or with
/// ``pattern`` a (T, h, w) DoFP mosaic stack whose first ``halo = (top, bottom, left,
/// right)`` rows/columns are neighbours of the block (read by the bilinear
/// interpolation, not mapped). ``beta_deg``: (T,) one β per capture, or (T, h/bin,
/// w/bin) per pixel (NaN: no geometry). ``dark_level`` (T,), ``saturation`` (T,) or
/// None. Returns float32 (7, h/bin, w/bin): n, k, n_se, k_se, rms_residual, class code,
/// reason code (the map's values; see ``_map_names``).
#[pyfunction]
#[pyo3(signature = (frames, angles_deg, beta_deg, model_json, *, label = "<model>", pattern = None, halo = (0, 0, 0, 0), bin = 1, dark_level = None, saturation = None, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE))]
#[allow(clippy::too_many_arguments)]
fn _map_block<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyAny>,
    angles_deg: Option<Vec<f64>>,
    beta_deg: &Bound<'py, PyAny>,
    model_json: &str,
    label: &str,
    pattern: Option<Vec<f64>>,
    halo: (usize, usize, usize, usize),
    bin: usize,
    dark_level: Option<Vec<f64>>,
    saturation: Option<Vec<Option<f64>>>,
    min_s0: Option<f64>,
    max_distance: Option<f64>,
    metric: &str,
    tile: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let cfg = config(bin, min_s0, max_distance, metric, tile)?;
    let model = parse_model(model_json, label)?;
    let pc = map::pixel_classifier(&cfg, &model, &PathBuf::from(label)).py_err()?;
    let raw = raw_array("frames", frames)?;
    let shape = raw.shape();
    let dofp = pattern.is_some();
    let (t_len, a_len, hh, ww) = match (&shape[..], dofp) {
        (&[t, h, w], true) => (t, 1, h, w),
        (&[t, a, h, w], false) => (t, a, h, w),
        _ => {
            return Err(value_error(format!(
                "frames must have shape {}, got shape {}",
                if dofp {
                    "(captures, rows, columns) (DoFP mosaics)"
                } else {
                    "(captures, angles, rows, columns)"
                },
                fmt_shape(&shape)
            )));
        }
    };
    let halo = [halo.0, halo.1, halo.2, halo.3];
    if !dofp && halo != [0; 4] {
        return Err(value_error("a halo is for DoFP mosaics only".to_string()));
    }
    if halo[0] + halo[1] >= hh || halo[2] + halo[3] >= ww {
        return Err(value_error(format!(
            "halo {halo:?} leaves no pixel of a {hh}x{ww} block"
        )));
    }
    let (h, w) = (hh - halo[0] - halo[1], ww - halo[2] - halo[3]);
    let (ow, oh) = cmap::binned_size(w, h, bin).py_err()?;
    let dark = dark_level.unwrap_or_else(|| vec![0.0; t_len]);
    let sat = saturation.unwrap_or_else(|| vec![None; t_len]);
    if dark.len() != t_len || sat.len() != t_len {
        return Err(value_error(format!(
            "dark_level and saturation need one value per capture ({t_len}), got {} and {}",
            dark.len(),
            sat.len()
        )));
    }
    // β: one per capture (far field) or one per pixel and capture (calibrated rules).
    let beta = f64_contiguous("beta_deg", beta_deg)?;
    let bshape = beta.shape().to_vec();
    let beta = beta.as_slice()?;
    let per_pixel = match &bshape[..] {
        [t] if *t == t_len => false,
        [t, bh, bw] if *t == t_len && (*bh, *bw) == (oh, ow) => true,
        _ => {
            return Err(value_error(format!(
                "beta_deg must have shape ({t_len},) (one angle per capture) or ({t_len}, {oh}, {ow}) (one per map pixel), got shape {}",
                fmt_shape(&bshape)
            )));
        }
    };
    let solver = match (&angles_deg, dofp) {
        (_, true) => None,
        (Some(a), false) if a.len() == a_len => Some(StokesSolver::from_degrees(a).py_err()?),
        (a, false) => {
            return Err(value_error(format!(
                "angles_deg must give one angle per frame of a capture ({a_len}), got {}",
                a.as_ref().map_or(0, Vec::len)
            )));
        }
    };
    let pattern = pattern.map(|p| Pattern::new(&p)).transpose().py_err()?;
    let mut rules = Vec::with_capacity(t_len);
    for (d, s) in dark.iter().zip(&sat) {
        rules.push(pixel_rules(*d, *s, raw.type_max(), 0.0)?);
    }
    if per_pixel && t_len < 3 {
        return Err(CoreError::TooFew {
            what: "DoLP measurements (source positions)",
            needed: 3,
            got: t_len,
        })
        .py_err();
    }
    let job = Job {
        t_len,
        a_len,
        hh,
        ww,
        halo,
        bin,
        per_pixel,
        solver: solver.as_ref(),
        pattern: pattern.as_ref(),
        rules: &rules,
        is_int: raw.is_integer(),
        min_s0,
        tile,
        beta,
        classifier: &pc,
    };
    let out = with_raw!(&raw, |data| py.detach(|| job.run(data)));
    let out = out.py_err()?;
    let a = ArrayD::from_shape_vec(IxDyn(&[PLANES, oh, ow]), out)
        .map_err(|e| value_error(e.to_string()))?;
    Ok(to_numpy(py, a))
}

/// Everything a block's computation needs, checked (built with the GIL held).
struct Job<'a> {
    t_len: usize,
    a_len: usize,
    hh: usize,
    ww: usize,
    halo: [usize; 4],
    bin: usize,
    per_pixel: bool,
    solver: Option<&'a StokesSolver>,
    pattern: Option<&'a Pattern>,
    rules: &'a [PixelRules],
    is_int: bool,
    min_s0: Option<f64>,
    tile: usize,
    beta: &'a [f64],
    classifier: &'a PixelClassifier,
}

impl Job<'_> {
    /// Stage 1 (the pipeline's `capture_dolp` per capture, then its calibrated rules)
    /// and stage 2 (`fit_and_classify`); the planes of the result.
    fn run<T: Sample>(&self, data: &[T]) -> Result<Vec<f32>, CoreError> {
        let (hh, ww, halo, bin) = (self.hh, self.ww, self.halo, self.bin);
        let (h, w) = (hh - halo[0] - halo[1], ww - halo[2] - halo[3]);
        let (ow, oh) = cmap::binned_size(w, h, bin)?;
        let npix = ow * oh;
        let plane = hh * ww;
        let mut flags = vec![0u8; npix];
        let mut capture_flags = vec![0u8; npix];
        let mut dropped = vec![0u8; npix];
        let mut dolp: Vec<Vec<f32>> = Vec::with_capacity(self.t_len);
        for (t, r) in self.rules.iter().enumerate() {
            let mut d = vec![0f32; npix];
            let f = if self.per_pixel {
                capture_flags.fill(0);
                &mut capture_flags
            } else {
                &mut flags
            };
            let mut r = *r;
            let th = min_s0_for(&r, self.is_int, self.min_s0);
            let cap = &data[t * self.a_len * plane..(t + 1) * self.a_len * plane];
            match (self.solver, self.pattern) {
                (Some(solver), _) => {
                    r.min_s0 = th;
                    let views: Vec<&[T]> = cap.chunks_exact(plane).collect();
                    cmap::frames_dolp(solver, &views, ww, &r, bin, &mut d, f)?;
                }
                (None, Some(p)) => {
                    // The dark test is made on the block mean by stokes_dolp.
                    r.min_s0 = f32::MIN;
                    let z = || vec![0f32; plane];
                    let (mut s0, mut s1, mut s2, mut m) = (z(), z(), z(), vec![0u8; plane]);
                    mosaic::bilinear_stokes(
                        cap, ww, p, &r, false, &mut s0, &mut s1, &mut s2, &mut m,
                    )?;
                    if halo != [0; 4] {
                        s0 = crop(&s0, ww, hh, halo);
                        s1 = crop(&s1, ww, hh, halo);
                        s2 = crop(&s2, ww, hh, halo);
                        m = crop(&m, ww, hh, halo);
                    }
                    cmap::stokes_dolp(w, &s0, &s1, &s2, Some(&m), th, bin, &mut d, f)?;
                }
                (None, None) => {
                    return Err(CoreError::TooFew {
                        what: "polarizer angles or a DoFP pattern",
                        needed: 1,
                        got: 0,
                    });
                }
            }
            if self.per_pixel {
                // Calibrated rules: a capture in which the pixel is dark or saturated
                // is left out of its own fit.
                let drop = cmap::flag::DARK | cmap::flag::SATURATED;
                for (((f, g), cf), v) in flags
                    .iter_mut()
                    .zip(dropped.iter_mut())
                    .zip(&capture_flags)
                    .zip(d.iter_mut())
                {
                    if cf & drop != 0 {
                        *v = f32::NAN;
                    }
                    *g |= cf & drop;
                    *f |= cf & !drop;
                }
            }
            dolp.push(d);
        }
        if self.per_pixel {
            for (p, (f, g)) in flags.iter_mut().zip(&dropped).enumerate() {
                if dolp.iter().filter(|d| !d[p].is_nan()).count() < 3 {
                    *f |= g;
                }
            }
        }

        let mut res = vec![0f32; PLANES * npix];
        let (n, rest) = res.split_at_mut(npix);
        let (k, rest) = rest.split_at_mut(npix);
        let (n_se, rest) = rest.split_at_mut(npix);
        let (k_se, rest) = rest.split_at_mut(npix);
        let (rms, rest) = rest.split_at_mut(npix);
        let (class_f, reason_f) = rest.split_at_mut(npix);
        let mut class = vec![0u16; npix];
        let mut why = vec![0u8; npix];
        let views: Vec<&[f32]> = dolp.iter().map(Vec::as_slice).collect();
        let outputs = MapOutputs {
            n,
            k,
            n_se,
            k_se,
            rms_residual: rms,
            class: &mut class,
            reason: &mut why,
        };
        let pc = self.classifier;
        if self.per_pixel {
            // β images in radians, f32, as the pipeline's geometry stage stores them.
            let maps: Vec<Vec<f32>> = self
                .beta
                .chunks_exact(npix.max(1))
                .map(|b| b.iter().map(|d| d.to_radians() as f32).collect())
                .collect();
            let bviews: Vec<&[f32]> = maps.iter().map(Vec::as_slice).collect();
            let plan = PixelBetaPlan::new(FitOptions::default())?;
            let betas = Betas::PerPixel {
                plan: &plan,
                beta: &bviews,
            };
            cmap::fit_and_classify(betas, pc, &views, None, &flags, self.tile, outputs, &|_| {})?;
        } else {
            let b: Vec<f64> = self.beta.iter().map(|d| d.to_radians()).collect();
            let plan = FitPlan::new(&b, FitOptions::default())?;
            let betas = Betas::Shared(&plan);
            cmap::fit_and_classify(betas, pc, &views, None, &flags, self.tile, outputs, &|_| {})?;
        }
        for (o, &c) in class_f.iter_mut().zip(&class) {
            *o = c as f32;
        }
        for (o, &r) in reason_f.iter_mut().zip(&why) {
            *o = r as f32;
        }
        Ok(res)
    }
}
