//! One block of a material map from in-memory frames (`_map_block`), the kernel of
//! `polarid.dask.material_map`, and the global noise-model step of its weighted fits
//! (`_noise_block`, `_estimate_noise`).
//!
//! A block is a rectangle of every capture's frames (rotating-polarizer frames, or a
//! DoFP mosaic with a halo of raw pixels around it). The steps are those of
//! `polarid_pipeline::map::map_manifest` (`polarid map`), with the same kernels, in
//! the same order, on the block's pixels only: per capture the binned DoLP and signal
//! flags (`polarid_core::map::frames_dolp_noise`, or `mosaic::bilinear_stokes` then
//! `map::stokes_dolp_noise` for DoFP), with the same pixel rules and dark threshold
//! (`polarid_pipeline::map::rules::min_s0_for`) and, for weighted fits, the noise terms
//! `(A, B)` of every block (`polarid_core::map::noise`); with a β per pixel, the
//! calibrated rules (a pixel's dark or saturated captures are left out of its own fit,
//! at least 3 must remain); then `map::fit_and_classify` with the model's per-pixel
//! classifier (`polarid_pipeline::map::pixel_classifier`), answering by the set rule
//! (`PixelClassifier::with_set_rule`, the systematic error model of `polarid map`) or
//! the nearest prototype. Every output pixel depends only on its own `bin × bin` block
//! of frames (and, for DoFP, the raw pixels within 2 of it) and on the map's noise model
//! (two numbers), so a map made of blocks whose edges are multiples of `bin` (and even,
//! for DoFP) equals the map of the whole frame.
//!
//! The noise model of `polarid map` (`polarid_core::map::noise::estimate_noise`) is a
//! global estimate: a sample of every `m`-th usable pixel of the whole map (row-major
//! order, `m = ⌈usable / NOISE_SAMPLE⌉`) is fitted and its residuals regressed. The
//! Dask map reproduces it exactly in two passes over the blocks: `_noise_block`
//! without `row_offsets` counts the usable pixels of every row of a block; with the
//! offsets (usable pixels before each row of the block in the map's row-major order)
//! and `stride = m`, it returns the block's sampled pixels (their DoLP, noise terms and
//! β); `_estimate_noise` runs `estimate_noise` on the gathered sample, in the map's
//! pixel order, which gives the very numbers `polarid map` estimates.

use std::path::PathBuf;

use ndarray::{ArrayD, IxDyn};
use numpy::PyUntypedArrayMethods;
use polarid_core::CoreError;
use polarid_core::classify::AMBIGUOUS;
use polarid_core::fit::{FitOptions, FitPlan, PixelBetaPlan};
use polarid_core::map::noise::{NoiseAnalyzer, NoiseModel, estimate_noise};
use polarid_core::map::sets::MapErrorModel;
use polarid_core::map::{
    self as cmap, Betas, MapNoise, MapOutputs, NoiseOut, PixelClassifier, signal_reason,
};
use polarid_core::mosaic::{self, Pattern};
use polarid_core::stokes::{PixelRules, Sample, StokesSolver};
use polarid_core::systematic::Polarimetric;
use polarid_io::model::Model;
use polarid_pipeline::map::rules::min_s0_for;
use polarid_pipeline::map::{self, MapConfig, MapErrors, REASON_NAMES, Rule};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{f64_contiguous, fmt_shape, raw_array, to_numpy};
use crate::errors::{IntoPyErr, PyResultExt, value_error};
use crate::stokes::pixel_rules;
use crate::with_raw;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(_map_block, m)?)?;
    m.add_function(wrap_pyfunction!(_map_names, m)?)?;
    m.add_function(wrap_pyfunction!(_noise_block, m)?)?;
    m.add_function(wrap_pyfunction!(_estimate_noise, m)?)?;
    // The most pixels of the noise-model sample (`noise::NOISE_SAMPLE`).
    m.add("_NOISE_SAMPLE", polarid_core::map::noise::NOISE_SAMPLE)?;
    Ok(())
}

/// Number of float32 planes of a block's result: n, k, n_se, k_se, rms_residual, class,
/// reason.
const PLANES: usize = 7;

fn parse_model(model_json: &str, label: &str) -> PyResult<Model> {
    Model::parse(&PathBuf::from(label), model_json).map_err(IntoPyErr::into_py_err)
}

/// The map's options, checked as `polarid map` checks them (errors name the option).
#[allow(clippy::too_many_arguments)]
pub(crate) fn config(
    bin: usize,
    min_s0: Option<f64>,
    max_distance: Option<f64>,
    metric: &str,
    tile: usize,
    rule: &str,
    confidence: f64,
    errors: &ErrorArgs,
) -> PyResult<MapConfig> {
    let metric = map::parse_metric(metric).py_err()?;
    let first_sd = errors
        .angle_sd_deg
        .first()
        .copied()
        .unwrap_or(MapErrors::default().angle_sd_deg);
    MapConfig::new(bin, min_s0, max_distance, metric, tile)
        .and_then(|c| c.with_rule(map::parse_rule(rule)?, confidence))
        .and_then(|c| {
            c.with_errors(MapErrors {
                angle_sd_deg: first_sd,
                dolp_floor: errors.dolp_floor,
                extinction_ratio: errors.extinction_ratio,
                retardance_deg: errors.retardance_deg,
            })
        })
        .py_err()
}

/// The set rule's systematic error model as the Python side passes it: one angle
/// uncertainty per capture (degrees) and the analyzer's terms.
pub(crate) struct ErrorArgs {
    pub(crate) angle_sd_deg: Vec<f64>,
    pub(crate) dolp_floor: f64,
    pub(crate) extinction_ratio: f64,
    pub(crate) retardance_deg: f64,
}

impl ErrorArgs {
    /// `polarid map`'s defaults for `t` captures.
    pub(crate) fn default_for(t: usize) -> Self {
        let d = MapErrors::default();
        Self {
            angle_sd_deg: vec![d.angle_sd_deg; t],
            dolp_floor: d.dolp_floor,
            extinction_ratio: d.extinction_ratio,
            retardance_deg: d.retardance_deg,
        }
    }

    /// Check every capture's angle uncertainty as `--angle-sd-deg` is checked.
    pub(crate) fn check(&self) -> PyResult<()> {
        for &a in &self.angle_sd_deg {
            if !(a.is_finite() && (0.0..90.0).contains(&a)) {
                return Err(value_error(format!(
                    "angle_sd_deg must be in [0, 90), got {a}"
                )));
            }
        }
        Ok(())
    }

    /// The core error model (as `polarid_pipeline::map`'s `error_model`: radians, no
    /// surface-film term in maps).
    pub(crate) fn model(&self) -> MapErrorModel {
        MapErrorModel {
            polarimetric: Polarimetric {
                dolp_floor: self.dolp_floor,
                extinction_ratio: self.extinction_ratio,
                retardance: self.retardance_deg.to_radians(),
                film_sd_waves: 0.0,
            },
            angle_sd: self.angle_sd_deg.iter().map(|a| a.to_radians()).collect(),
        }
    }
}

/// The per-pixel classifier of a model under the options (set rule at `confidence`
/// with the error model, or nearest prototype).
fn classifier(
    cfg: &MapConfig,
    confidence: f64,
    model_json: &str,
    label: &str,
    errors: &ErrorArgs,
) -> PyResult<PixelClassifier> {
    errors.check()?;
    let model = parse_model(model_json, label)?;
    let pc = map::pixel_classifier(cfg, &model, &PathBuf::from(label)).py_err()?;
    if cfg.rule() == Rule::Set {
        pc.with_set_rule(confidence, errors.model()).py_err()
    } else {
        Ok(pc)
    }
}

/// The class names (``"unknown"`` first, then the model's classes sorted, then
/// ``"ambiguous"`` with the set rule: index = class code of a map) and the reason names
/// (index = reason code, every reason as ``map_summary.json`` lists them). Checks the
/// options as ``_map_block`` does (errors name the option).
#[pyfunction]
#[pyo3(signature = (model_json, *, label = "<model>", per_pixel_beta = false, bin = 1, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE, rule = "set", confidence = polarid_core::classify::DEFAULT_CONFIDENCE, angle_sd_deg = vec![MapErrors::default().angle_sd_deg], dolp_floor = MapErrors::default().dolp_floor, extinction_ratio = MapErrors::default().extinction_ratio, retardance_deg = MapErrors::default().retardance_deg))]
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
    rule: &str,
    confidence: f64,
    angle_sd_deg: Vec<f64>,
    dolp_floor: f64,
    extinction_ratio: f64,
    retardance_deg: f64,
) -> PyResult<(Vec<String>, Vec<String>)> {
    let errors = ErrorArgs {
        angle_sd_deg,
        dolp_floor,
        extinction_ratio,
        retardance_deg,
    };
    let cfg = config(
        bin,
        min_s0,
        max_distance,
        metric,
        tile,
        rule,
        confidence,
        &errors,
    )?;
    let pc = classifier(&cfg, confidence, model_json, label, &errors)?;
    let mut classes = vec![polarid_core::classify::UNKNOWN.to_string()];
    classes.extend(pc.names().iter().cloned());
    if pc.ambiguous().is_some() {
        classes.push(AMBIGUOUS.to_string());
    }
    // Every reason, as `map_summary.json`'s `reason_codes` lists them (far field too).
    let _ = per_pixel_beta;
    let reasons = REASON_NAMES.iter().map(|s| s.to_string()).collect();
    Ok((classes, reasons))
}

/// Crop rows `top..h-bottom` and columns `left..w-right` of a `w`-wide image.
pub(crate) fn crop<T: Copy>(v: &[T], w: usize, h: usize, c: [usize; 4]) -> Vec<T> {
    let [top, bottom, left, right] = c;
    let mut out = Vec::with_capacity((h - top - bottom) * (w - left - right));
    for y in top..h - bottom {
        out.extend_from_slice(&v[y * w + left..(y + 1) * w - right]);
    }
    out
}

/// The checked inputs of a block (frames, angles or pattern, β, pixel rules), shared by
/// `_map_block` and `_noise_block`.
struct Inputs<'py> {
    raw: crate::arrays::RawArray<'py>,
    t_len: usize,
    a_len: usize,
    hh: usize,
    ww: usize,
    halo: [usize; 4],
    ow: usize,
    oh: usize,
    per_pixel: bool,
    beta: Vec<f64>,
    solver: Option<StokesSolver>,
    pattern: Option<Pattern>,
    rules: Vec<PixelRules>,
}

#[allow(clippy::too_many_arguments)]
fn inputs<'py>(
    frames: &Bound<'py, PyAny>,
    angles_deg: Option<Vec<f64>>,
    beta_deg: &Bound<'py, PyAny>,
    pattern: Option<Vec<f64>>,
    halo: (usize, usize, usize, usize),
    bin: usize,
    dark_level: Option<Vec<f64>>,
    saturation: Option<Vec<Option<f64>>>,
) -> PyResult<Inputs<'py>> {
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
    let beta_arr = f64_contiguous("beta_deg", beta_deg)?;
    let bshape = beta_arr.shape().to_vec();
    let beta = beta_arr.as_slice()?.to_vec();
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
    Ok(Inputs {
        raw,
        t_len,
        a_len,
        hh,
        ww,
        halo,
        ow,
        oh,
        per_pixel,
        beta,
        solver,
        pattern,
        rules,
    })
}

impl Inputs<'_> {
    /// The block's job (borrowing the checked inputs).
    fn job<'a>(&'a self, bin: usize, min_s0: Option<f64>, tile: usize) -> Job<'a> {
        Job {
            t_len: self.t_len,
            a_len: self.a_len,
            hh: self.hh,
            ww: self.ww,
            halo: self.halo,
            bin,
            per_pixel: self.per_pixel,
            solver: self.solver.as_ref(),
            pattern: self.pattern.as_ref(),
            rules: &self.rules,
            is_int: self.raw.is_integer(),
            min_s0,
            tile,
            beta: &self.beta,
        }
    }
}

/// One block of a material map (private: called by ``polarid.dask.material_map``).
///
/// ``frames``: (T, A, h, w) polarizer frames (``angles_deg`` the A angles), or with
/// ``pattern`` a (T, h, w) DoFP mosaic stack whose first ``halo = (top, bottom, left,
/// right)`` rows/columns are neighbours of the block (read by the bilinear
/// interpolation, not mapped). ``beta_deg``: (T,) one β per capture, or (T, h/bin,
/// w/bin) per pixel (NaN: no geometry). ``dark_level`` (T,), ``saturation`` (T,) or
/// None. ``rule``, ``confidence``, ``angle_sd_deg`` (one per capture), ``dolp_floor``,
/// ``extinction_ratio``, ``retardance_deg``: the answer rule and its error model, as
/// ``polarid map``. ``noise``: ``(read_var_dn2, inv_gain)`` of the map's noise model
/// (weighted fits) or None (unweighted). Returns float32 (7, h/bin, w/bin): n, k, n_se,
/// k_se, rms_residual, class code, reason code (the map's values; see ``_map_names``).
#[pyfunction]
#[pyo3(signature = (frames, angles_deg, beta_deg, model_json, *, label = "<model>", pattern = None, halo = (0, 0, 0, 0), bin = 1, dark_level = None, saturation = None, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE, rule = "set", confidence = polarid_core::classify::DEFAULT_CONFIDENCE, angle_sd_deg = None, dolp_floor = MapErrors::default().dolp_floor, extinction_ratio = MapErrors::default().extinction_ratio, retardance_deg = MapErrors::default().retardance_deg, noise = None))]
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
    rule: &str,
    confidence: f64,
    angle_sd_deg: Option<Vec<f64>>,
    dolp_floor: f64,
    extinction_ratio: f64,
    retardance_deg: f64,
    noise: Option<(f64, f64)>,
) -> PyResult<Bound<'py, PyAny>> {
    let inp = inputs(
        frames, angles_deg, beta_deg, pattern, halo, bin, dark_level, saturation,
    )?;
    let errors = ErrorArgs {
        angle_sd_deg: angle_sd_deg
            .unwrap_or_else(|| vec![MapErrors::default().angle_sd_deg; inp.t_len]),
        dolp_floor,
        extinction_ratio,
        retardance_deg,
    };
    if errors.angle_sd_deg.len() != inp.t_len {
        return Err(value_error(format!(
            "angle_sd_deg needs one value per capture ({}), got {}",
            inp.t_len,
            errors.angle_sd_deg.len()
        )));
    }
    let cfg = config(
        bin,
        min_s0,
        max_distance,
        metric,
        tile,
        rule,
        confidence,
        &errors,
    )?;
    let pc = classifier(&cfg, confidence, model_json, label, &errors)?;
    let noise = match noise {
        Some((r2, ig)) => {
            if !(r2.is_finite() && ig.is_finite() && r2 >= 0.0 && ig >= 0.0 && r2 + ig > 0.0) {
                return Err(value_error(format!(
                    "noise must be (read_var_dn2, inv_gain), finite, >= 0 and not both 0, got ({r2}, {ig})"
                )));
            }
            Some(NoiseModel {
                read_var_dn2: r2,
                inv_gain: ig,
            })
        }
        None => None,
    };
    let job = inp.job(bin, min_s0, tile);
    let (ow, oh) = (inp.ow, inp.oh);
    let out = with_raw!(&inp.raw, |data| py.detach(|| job.run(data, &pc, noise)));
    let out = out.py_err()?;
    let a = ArrayD::from_shape_vec(IxDyn(&[PLANES, oh, ow]), out)
        .map_err(|e| value_error(e.to_string()))?;
    Ok(to_numpy(py, a))
}

/// The noise-model sample of a block (private: the global step of
/// ``polarid.dask.material_map``'s weighted fits; see the module documentation).
///
/// Inputs as ``_map_block``. Without ``row_offsets``: int64 (h/bin,), the number of
/// usable pixels of every map row of the block (pixels without a flag whose captures'
/// DoLP, noise terms and β are finite: all captures, or at least 3 with a β per pixel).
/// With ``row_offsets`` (int64 (h/bin,): the usable pixels of the whole map before each
/// row of the block, row-major) and ``stride``: a dict of the block's usable pixels
/// whose map rank is a multiple of ``stride``: ``index`` int64 (S,) (row-major within
/// the block's map pixels), ``dolp``, ``read``, ``shot`` float32 (S, T) and, with a β
/// per pixel, ``beta_rad`` float32 (S, T) (the radians the fit uses).
#[pyfunction]
#[pyo3(signature = (frames, angles_deg, beta_deg, *, pattern = None, halo = (0, 0, 0, 0), bin = 1, dark_level = None, saturation = None, min_s0 = None, row_offsets = None, stride = 1))]
#[allow(clippy::too_many_arguments)]
fn _noise_block<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyAny>,
    angles_deg: Option<Vec<f64>>,
    beta_deg: &Bound<'py, PyAny>,
    pattern: Option<Vec<f64>>,
    halo: (usize, usize, usize, usize),
    bin: usize,
    dark_level: Option<Vec<f64>>,
    saturation: Option<Vec<Option<f64>>>,
    min_s0: Option<f64>,
    row_offsets: Option<Vec<i64>>,
    stride: usize,
) -> PyResult<Bound<'py, PyAny>> {
    // The options as the map checks them (nearest rule: no model needed here).
    if bin == 0 || bin > 64 {
        return Err(value_error(format!("bin must be in 1..=64, got {bin}")));
    }
    let inp = inputs(
        frames, angles_deg, beta_deg, pattern, halo, bin, dark_level, saturation,
    )?;
    let job = inp.job(bin, min_s0, 1);
    let (ow, oh, t_len) = (inp.ow, inp.oh, inp.t_len);
    if let Some(o) = &row_offsets
        && o.len() != oh
    {
        return Err(value_error(format!(
            "row_offsets needs one value per map row of the block ({oh}), got {}",
            o.len()
        )));
    }
    let stride = stride.max(1) as i64;
    let st = with_raw!(&inp.raw, |data| py.detach(|| job.stage1(data, true)));
    let st = st.py_err()?;
    let beta_rad = job.beta_rad(ow * oh);
    let masks: Vec<u64> = (0..ow * oh)
        .map(|p| usable_mask(&st, &beta_rad, t_len, p))
        .collect();
    let Some(offsets) = row_offsets else {
        let counts: Vec<i64> = masks
            .chunks_exact(ow.max(1))
            .map(|r| r.iter().filter(|&&m| m != 0).count() as i64)
            .collect();
        let a =
            ArrayD::from_shape_vec(IxDyn(&[oh]), counts).map_err(|e| value_error(e.to_string()))?;
        return Ok(to_numpy(py, a));
    };
    let mut index: Vec<i64> = Vec::new();
    for (y, off) in offsets.iter().enumerate() {
        let mut rank = *off;
        for x in 0..ow {
            let p = y * ow + x;
            if masks[p] != 0 {
                if rank % stride == 0 {
                    index.push(p as i64);
                }
                rank += 1;
            }
        }
    }
    let s = index.len();
    let gather = |imgs: &[Vec<f32>]| -> PyResult<Bound<'py, PyAny>> {
        let mut v = Vec::with_capacity(s * t_len);
        for &p in &index {
            v.extend(imgs.iter().map(|im| im[p as usize]));
        }
        let a = ArrayD::from_shape_vec(IxDyn(&[s, t_len]), v)
            .map_err(|e| value_error(e.to_string()))?;
        Ok(to_numpy(py, a))
    };
    let d = PyDict::new(py);
    d.set_item("dolp", gather(&st.dolp)?)?;
    d.set_item("read", gather(&st.read)?)?;
    d.set_item("shot", gather(&st.shot)?)?;
    if let BetaRad::PerPixel(maps) = &beta_rad {
        d.set_item("beta_rad", gather(maps)?)?;
    }
    let idx = ArrayD::from_shape_vec(IxDyn(&[s]), index).map_err(|e| value_error(e.to_string()))?;
    d.set_item("index", to_numpy(py, idx))?;
    Ok(d.into_any())
}

/// `(read_var_dn2, inv_gain, pixels, outliers, reduced_chi2)` of a noise estimate.
type NoiseTuple = (f64, f64, usize, usize, f64);

/// The map's noise model from the gathered sample (private: see the module
/// documentation). ``dolp``, ``read``, ``shot``: float32 (S, T), the sampled pixels in
/// the map's row-major order; ``beta_deg`` (T,) with one β per capture, or
/// ``beta_rad`` float32 (S, T) per pixel. Returns None when the sample gives no
/// estimate (too few usable pixels), else ``(read_var_dn2, inv_gain, pixels, outliers,
/// reduced_chi2)``: the estimate of ``polarid map`` (``map_summary.json``'s
/// ``noise``).
#[pyfunction]
#[pyo3(signature = (dolp, read, shot, *, beta_deg = None, beta_rad = None))]
fn _estimate_noise<'py>(
    py: Python<'py>,
    dolp: &Bound<'py, PyAny>,
    read: &Bound<'py, PyAny>,
    shot: &Bound<'py, PyAny>,
    beta_deg: Option<Vec<f64>>,
    beta_rad: Option<&Bound<'py, PyAny>>,
) -> PyResult<Option<NoiseTuple>> {
    let cols = |name: &str, a: &Bound<'py, PyAny>| -> PyResult<(usize, usize, Vec<Vec<f32>>)> {
        let a = f64_contiguous(name, a)?;
        let sh = a.shape().to_vec();
        let [s, t] = sh[..] else {
            return Err(value_error(format!(
                "{name} must have shape (pixels, captures), got shape {}",
                fmt_shape(&sh)
            )));
        };
        let v = a.as_slice()?;
        let imgs = (0..t)
            .map(|c| (0..s).map(|p| v[p * t + c] as f32).collect())
            .collect();
        Ok((s, t, imgs))
    };
    let (s, t, dolp) = cols("dolp", dolp)?;
    let (s1, t1, read) = cols("read", read)?;
    let (s2, t2, shot) = cols("shot", shot)?;
    if (s1, t1) != (s, t) || (s2, t2) != (s, t) {
        return Err(value_error("dolp, read and shot must have the same shape"));
    }
    let flags = vec![0u8; s];
    let dv: Vec<&[f32]> = dolp.iter().map(Vec::as_slice).collect();
    let rv: Vec<&[f32]> = read.iter().map(Vec::as_slice).collect();
    let sv: Vec<&[f32]> = shot.iter().map(Vec::as_slice).collect();
    let est = match (beta_deg, beta_rad) {
        (Some(b), None) => {
            let b: Vec<f64> = b.iter().map(|d| d.to_radians()).collect();
            let plan = FitPlan::new(&b, FitOptions::default()).py_err()?;
            py.detach(|| estimate_noise(Betas::Shared(&plan), &dv, &rv, &sv, &flags))
        }
        (None, Some(b)) => {
            let (sb, tb, maps) = cols("beta_rad", b)?;
            if (sb, tb) != (s, t) {
                return Err(value_error("beta_rad must have the shape of dolp"));
            }
            let bv: Vec<&[f32]> = maps.iter().map(Vec::as_slice).collect();
            let plan = PixelBetaPlan::new(FitOptions::default()).py_err()?;
            py.detach(|| {
                estimate_noise(
                    Betas::PerPixel {
                        plan: &plan,
                        beta: &bv,
                    },
                    &dv,
                    &rv,
                    &sv,
                    &flags,
                )
            })
        }
        _ => return Err(value_error("give either beta_deg or beta_rad")),
    }
    .py_err()?;
    Ok(est.map(|e| {
        (
            e.model.read_var_dn2,
            e.model.inv_gain,
            e.pixels,
            e.outliers,
            e.reduced_chi2,
        )
    }))
}

/// The β of a block's fits: radians, one per capture or one image per capture (f32, as
/// the pipeline's geometry stage stores them).
enum BetaRad {
    Shared(Vec<f64>),
    PerPixel(Vec<Vec<f32>>),
}

/// The captures a pixel can use in the noise-model sample, as a bit mask (0: not
/// usable): the rule of `polarid_core::map::noise::estimate_noise` (no signal flag;
/// DoLP, noise terms and β finite, a term positive; every capture, or with a β per
/// pixel and fewer than 64 captures at least 3 of them).
fn usable_mask(st: &Stage1, beta: &BetaRad, t_len: usize, p: usize) -> u64 {
    if signal_reason(st.flags[p]) != 0 {
        return 0;
    }
    let ok = |t: usize| {
        let (d, a, b) = (st.dolp[t][p], st.read[t][p], st.shot[t][p]);
        let bt = match beta {
            BetaRad::Shared(v) => v[t],
            BetaRad::PerPixel(m) => m[t][p] as f64,
        };
        d.is_finite() && a.is_finite() && b.is_finite() && (a > 0.0 || b > 0.0) && bt.is_finite()
    };
    let per_pixel = matches!(beta, BetaRad::PerPixel(_)) && t_len < 64;
    if per_pixel {
        let m = (0..t_len)
            .filter(|&t| ok(t))
            .fold(0u64, |m, t| m | (1 << t));
        if m.count_ones() >= 3 { m } else { 0 }
    } else if (0..t_len).all(ok) {
        u64::MAX
    } else {
        0
    }
}

/// Stage 1 of a block: the DoLP of every capture, the signal flags (calibrated rules
/// applied) and, when asked, the noise terms `(A, B)` of every capture.
struct Stage1 {
    dolp: Vec<Vec<f32>>,
    flags: Vec<u8>,
    read: Vec<Vec<f32>>,
    shot: Vec<Vec<f32>>,
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
}

impl Job<'_> {
    /// β in radians, as the fit takes it (see [`BetaRad`]).
    fn beta_rad(&self, npix: usize) -> BetaRad {
        if self.per_pixel {
            BetaRad::PerPixel(
                self.beta
                    .chunks_exact(npix.max(1))
                    .map(|b| b.iter().map(|d| d.to_radians() as f32).collect())
                    .collect(),
            )
        } else {
            BetaRad::Shared(self.beta.iter().map(|d| d.to_radians()).collect())
        }
    }

    /// Stage 1: the pipeline's `capture_dolp` per capture (with the noise terms when
    /// `noise`), then its calibrated rules.
    fn stage1<T: Sample>(&self, data: &[T], noise: bool) -> Result<Stage1, CoreError> {
        let (hh, ww, halo, bin) = (self.hh, self.ww, self.halo, self.bin);
        let (h, w) = (hh - halo[0] - halo[1], ww - halo[2] - halo[3]);
        let (ow, oh) = cmap::binned_size(w, h, bin)?;
        let npix = ow * oh;
        let plane = hh * ww;
        let mut flags = vec![0u8; npix];
        let mut capture_flags = vec![0u8; npix];
        let mut dropped = vec![0u8; npix];
        let mut dolp: Vec<Vec<f32>> = Vec::with_capacity(self.t_len);
        let (mut read, mut shot) = (Vec::new(), Vec::new());
        let quad = NoiseAnalyzer::quad();
        for (t, r) in self.rules.iter().enumerate() {
            let mut d = vec![0f32; npix];
            let (mut ra, mut rb) = if noise {
                (vec![0f32; npix], vec![0f32; npix])
            } else {
                (Vec::new(), Vec::new())
            };
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
                    let an = NoiseAnalyzer::of_solver(solver);
                    let nz = noise.then(|| NoiseOut {
                        analyzer: &an,
                        scale: 1.0,
                        read: &mut ra,
                        shot: &mut rb,
                    });
                    let views: Vec<&[T]> = cap.chunks_exact(plane).collect();
                    cmap::frames_dolp_noise(solver, &views, ww, &r, bin, &mut d, f, nz)?;
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
                    let nz = noise.then(|| NoiseOut {
                        analyzer: &quad,
                        scale: 1.0,
                        read: &mut ra,
                        shot: &mut rb,
                    });
                    cmap::stokes_dolp_noise(w, &s0, &s1, &s2, Some(&m), th, bin, &mut d, f, nz)?;
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
            if noise {
                read.push(ra);
                shot.push(rb);
            }
        }
        if self.per_pixel {
            for (p, (f, g)) in flags.iter_mut().zip(&dropped).enumerate() {
                if dolp.iter().filter(|d| !d[p].is_nan()).count() < 3 {
                    *f |= g;
                }
            }
        }
        Ok(Stage1 {
            dolp,
            flags,
            read,
            shot,
        })
    }

    /// Stage 1 and stage 2 (`fit_and_classify`, weighted by `noise` when given); the
    /// planes of the result.
    fn run<T: Sample>(
        &self,
        data: &[T],
        pc: &PixelClassifier,
        noise: Option<NoiseModel>,
    ) -> Result<Vec<f32>, CoreError> {
        let st = self.stage1(data, noise.is_some())?;
        let npix = st.flags.len();
        let mut res = vec![0f32; PLANES * npix];
        let (n, rest) = res.split_at_mut(npix);
        let (k, rest) = rest.split_at_mut(npix);
        let (n_se, rest) = rest.split_at_mut(npix);
        let (k_se, rest) = rest.split_at_mut(npix);
        let (rms, rest) = rest.split_at_mut(npix);
        let (class_f, reason_f) = rest.split_at_mut(npix);
        let mut class = vec![0u16; npix];
        let mut why = vec![0u8; npix];
        let views: Vec<&[f32]> = st.dolp.iter().map(Vec::as_slice).collect();
        let rv: Vec<&[f32]> = st.read.iter().map(Vec::as_slice).collect();
        let sv: Vec<&[f32]> = st.shot.iter().map(Vec::as_slice).collect();
        let map_noise = noise.map(|model| MapNoise {
            model,
            read: &rv,
            shot: &sv,
        });
        let outputs = MapOutputs {
            n,
            k,
            n_se,
            k_se,
            rms_residual: rms,
            class: &mut class,
            reason: &mut why,
        };
        match self.beta_rad(npix) {
            BetaRad::PerPixel(maps) => {
                let bviews: Vec<&[f32]> = maps.iter().map(Vec::as_slice).collect();
                let plan = PixelBetaPlan::new(FitOptions::default())?;
                let betas = Betas::PerPixel {
                    plan: &plan,
                    beta: &bviews,
                };
                cmap::fit_and_classify(
                    betas,
                    pc,
                    &views,
                    map_noise,
                    &st.flags,
                    self.tile,
                    outputs,
                    &|_| {},
                )?;
            }
            BetaRad::Shared(b) => {
                let plan = FitPlan::new(&b, FitOptions::default())?;
                let betas = Betas::Shared(&plan);
                cmap::fit_and_classify(
                    betas,
                    pc,
                    &views,
                    map_noise,
                    &st.flags,
                    self.tile,
                    outputs,
                    &|_| {},
                )?;
            }
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
