//! Per-pixel `(n, k)` and material maps of a capture set (`map_manifest`), and the
//! conversion of `polarid_pipeline` errors into Python exceptions.
//!
//! `map_manifest` calls `polarid_pipeline::map::map_manifest`, the function `polarid
//! map` calls, so the arrays equal the CLI's TIFFs (python/tests/test_map_manifest.py).

use ndarray::{ArrayD, IxDyn};
use polarid_io::manifest;
use polarid_io::model::Model;
use polarid_pipeline::map::{self, MapConfig};
use polarid_pipeline::progress::no_progress;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::to_numpy;
use crate::errors::{IntoPyErr, PyResultExt, value_error};
use crate::files::{path_arg, warn_all};

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(map_manifest, m)?)?;
    Ok(())
}

fn image<'py, T: numpy::Element>(
    py: Python<'py>,
    h: usize,
    w: usize,
    v: Vec<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let a = ArrayD::from_shape_vec(IxDyn(&[h, w]), v).map_err(|e| value_error(e.to_string()))?;
    Ok(to_numpy(py, a))
}

/// Per-pixel ``(n, k)`` and material maps of a capture set: ``polarid map`` as arrays.
///
/// For each capture, the (binned) DoLP of every pixel; then every pixel that is not
/// saturated, dark or invalid in any capture is fitted for (n, k) (paper eq. 9) and
/// answered with the set of the model's materials consistent with it (``rule="set"``:
/// a material, ``ambiguous`` or unknown) or the nearest prototype (``rule="nearest"``). Same code as ``polarid map
/// MANIFEST --model MODEL`` (its TIFFs hold the very same numbers). The GIL is released.
///
/// A manifest with calibrated geometry (``[camera]``, ``[[plane]]``, a ``source`` per
/// capture) is mapped with a β per pixel and capture: where the ray through the centre
/// of the pixel's ``bin`` × ``bin`` block (coordinates of the files as stored) meets
/// its plane (the plane of the first region whose rectangle contains that centre, else
/// the first plane). Pixels without a geometry in some capture (the ray misses the
/// plane, the source is below its horizon) get the reason ``no_geometry``.
///
/// Parameters
/// ----------
/// manifest_path : str or os.PathLike
///     The capture-set manifest (TOML).
/// model : str or os.PathLike
///     A model JSON written by ``polarid train``.
/// bin : int, default 1
///     Sum ``bin`` × ``bin`` blocks of pixels before the DoLP (1 to 64).
/// min_s0 : float, optional
///     Dark threshold on a block's mean dark-subtracted S0, DN (default: 1 % of the range
///     from the dark level to saturation for integer frames, 0 for float frames).
/// max_distance : float, optional
///     Leave pixels whose nearest prototype is farther unclassified (``rejected``).
/// metric : {"euclidean", "mahalanobis"}
///     Distance to the prototypes (``mahalanobis``: with each pixel's fit covariance;
///     ``max_distance`` is then in standard deviations).
/// tile : int, default 65536
///     Pixels per fitting tile (memory of the fit stage ≈ 200 bytes per pixel).
/// rule : {"set", "nearest"}, default "set"
///     ``set``: a pixel is the one material consistent with its estimate at
///     ``confidence`` (noise plus the systematic error model), ``ambiguous`` (the last
///     class name) when several are, unknown (code 0, reason ``rejected``) when none is;
///     ``nearest``: the paper's nearest prototype (``metric``, ``max_distance``).
/// confidence : float, default 0.95
///     Confidence of the consistent set, in (0, 1).
/// weights : {"auto", "noise", "none"}, default "auto"
///     Weight each pixel's fit by its DoLP standard errors from the noise model
///     estimated on the map (``auto``: with calibrated geometry only).
/// angle_sd_deg, dolp_floor, extinction_ratio, retardance_deg : float
///     The set rule's systematic error model (defaults as ``polarid fit``:
///     0.2, 0.002, 100, 0).
///
/// Returns
/// -------
/// dict
///     ``n``, ``k``, ``n_se``, ``k_se``, ``rms_residual``: float32 (H, W), NaN where not
///     fitted; ``class``: uint8 (H, W) class codes (uint16 above 255 classes), 0 = not
///     classified, code ``i`` is ``class_names[i]``; ``reason``: uint8 (H, W), why a pixel
///     is (not) classified, code ``i`` is ``reason_names[i]``; ``class_names`` (list,
///     ``"unknown"`` first), ``reason_names`` (list, ``"classified"`` first);
///     ``class_counts``, ``reason_counts``: int64 pixel counts per code; ``summary``:
///     the content of ``map_summary.json`` without the input paths and timings (size,
///     binning, thresholds, per-region class shares; with calibrated geometry also
///     ``geometry`` and each capture's ``beta_range_deg``). With calibrated geometry
///     also ``beta_deg``: float64 (T, H, W), every pixel's β per capture in degrees
///     (NaN without geometry).
///
/// Raises
/// ------
/// FileNotFoundError
///     A missing manifest or model.
/// ValueError
///     An invalid option (``bin must be in 1..=64, got 0``), manifest, model or image.
#[pyfunction]
#[pyo3(signature = (manifest_path, model, *, bin = 1, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE, rule = "set", confidence = 0.95, weights = "auto", angle_sd_deg = map::MapErrors::default().angle_sd_deg, dolp_floor = map::MapErrors::default().dolp_floor, extinction_ratio = map::MapErrors::default().extinction_ratio, retardance_deg = map::MapErrors::default().retardance_deg))]
#[allow(clippy::too_many_arguments)]
pub fn map_manifest<'py>(
    py: Python<'py>,
    manifest_path: &Bound<'py, PyAny>,
    model: &Bound<'py, PyAny>,
    bin: usize,
    min_s0: Option<f64>,
    max_distance: Option<f64>,
    metric: &str,
    tile: usize,
    rule: &str,
    confidence: f64,
    weights: &str,
    angle_sd_deg: f64,
    dolp_floor: f64,
    extinction_ratio: f64,
    retardance_deg: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let metric = map::parse_metric(metric).py_err()?;
    let errors = map::MapErrors {
        angle_sd_deg,
        dolp_floor,
        extinction_ratio,
        retardance_deg,
    };
    let cfg = MapConfig::new(bin, min_s0, max_distance, metric, tile)
        .and_then(|c| c.with_rule(map::parse_rule(rule)?, confidence))
        .and_then(|c| c.with_errors(errors))
        .and_then(|c| Ok(c.with_weights(map::parse_weights(weights)?)))
        .py_err()?;
    let mpath = path_arg(manifest_path)?;
    let model_path = path_arg(model)?;
    let m = py
        .detach(|| manifest::load(&mpath))
        .map_err(IntoPyErr::into_py_err)?;
    warn_all(py, &m)?;
    let mdl = py
        .detach(|| Model::read(&model_path))
        .map_err(IntoPyErr::into_py_err)?;
    let r = py
        .detach(|| map::map_manifest(&cfg, &m, &mdl, &model_path, &no_progress))
        .py_err()?;
    let summary = r.summary_json().to_string();
    let (h, w) = (r.height, r.width);
    let d = PyDict::new(py);
    let mut names = vec![r.class_name(0).to_string()];
    names.extend(r.class_names.iter().cloned());
    d.set_item("class_names", names)?;
    d.set_item("reason_names", r.reason_names().to_vec())?;
    let counts = |v: Vec<i64>| -> PyResult<Bound<'py, PyAny>> {
        let a =
            ArrayD::from_shape_vec(IxDyn(&[v.len()]), v).map_err(|e| value_error(e.to_string()))?;
        Ok(to_numpy(py, a))
    };
    let classes: Vec<i64> = r.counts.classes.iter().map(|&c| c as i64).collect();
    let reasons: Vec<i64> = r.counts.reasons[..r.reason_names().len()]
        .iter()
        .map(|&c| c as i64)
        .collect();
    d.set_item("class_counts", counts(classes)?)?;
    d.set_item("reason_counts", counts(reasons)?)?;
    let json = py.import("json")?;
    d.set_item("summary", json.call_method1("loads", (summary,))?)?;
    if r.class_names.len() <= u8::MAX as usize {
        let c8: Vec<u8> = r.class.iter().map(|&c| c as u8).collect();
        d.set_item("class", image(py, h, w, c8)?)?;
    } else {
        d.set_item("class", image(py, h, w, r.class)?)?;
    }
    d.set_item("reason", image(py, h, w, r.reason)?)?;
    d.set_item("n", image(py, h, w, r.n)?)?;
    d.set_item("k", image(py, h, w, r.k)?)?;
    d.set_item("n_se", image(py, h, w, r.n_se)?)?;
    d.set_item("k_se", image(py, h, w, r.k_se)?)?;
    d.set_item("rms_residual", image(py, h, w, r.rms_residual)?)?;
    if r.calibrated {
        let t = r.beta_maps_deg.len();
        let flat: Vec<f64> = r.beta_maps_deg.into_iter().flatten().collect();
        let a = ArrayD::from_shape_vec(IxDyn(&[t, h, w]), flat)
            .map_err(|e| value_error(e.to_string()))?;
        d.set_item("beta_deg", to_numpy(py, a))?;
    }
    Ok(d)
}
