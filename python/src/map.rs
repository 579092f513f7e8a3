//! Per-pixel `(n, k)` and material maps of a capture set (`map_manifest`), and the
//! conversion of `polarid_pipeline` errors into Python exceptions.
//!
//! `map_manifest` calls `polarid_pipeline::map::map_manifest`, the function `polarid
//! map` calls, so the arrays equal the CLI's TIFFs (python/tests/test_map_manifest.py).

use polarid_core::classify::Bench;
use polarid_io::manifest;
use polarid_io::model::Model;
use polarid_pipeline::map::{self, MapConfig};
use polarid_pipeline::progress::no_progress;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::shaped;
use crate::errors::{PyResultExt, value_error};
use crate::files::{path_arg, warn_all, warn_texts};

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(map_manifest, m)?)?;
    Ok(())
}

/// Per-pixel ``(n, k)`` and material maps of a capture set: ``polarid map`` as arrays.
///
/// For each capture, the (binned) DoLP of every pixel; then every pixel that is not
/// saturated, dark or invalid in any capture is fitted for (n, k) (paper eq. 9) and
/// answered with the set of the model's materials consistent with it (``rule="set"``:
/// a material, ``ambiguous`` or unknown) or the nearest prototype (``rule="nearest"``). Same code as ``polarid map
/// MANIFEST --model MODEL`` (its TIFFs hold the very same numbers). The GIL is released.
///
/// A manifest with colour captures (``dofp`` with ``color``, docs/BANDS.md) is mapped per
/// band, as ``polarid map`` maps it: every band is fitted per pixel on its own (the
/// arrays of ``bands``, the CLI's ``n_450.tif`` ...), and every pixel is classified once
/// on all its bands together (``class``, ``reason``) against a multi-band model or a
/// library (``library="builtin-rgb"`` or a multi-band library CSV).
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
/// model : str or os.PathLike, optional
///     A model JSON written by ``polarid train`` (``--model``; for a colour manifest, a
///     multi-band model).
/// library : str, optional
///     Instead of ``model``: a material library (``--library``): ``"builtin"``,
///     ``"builtin-rgb"`` or a library CSV; under the set rule each material, as it is
///     found, is tested against every pixel's rows (single-band captures at their
///     ``wavelength_nm``).
/// bin : int, default 1
///     Sum ``bin`` × ``bin`` blocks of pixels before the DoLP (1 to 64).
/// min_s0 : float, optional
///     Dark threshold on a block's mean dark-subtracted S0, DN (default: 1 % of the range
///     from the dark level to saturation for integer frames, 0 for float frames).
/// max_distance : float, optional
///     Leave pixels whose nearest prototype is farther ``unknown`` (reason ``rejected``).
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
///     With a model on the same bench (``bench="same"``) the pixel's noise covariance
///     is compared with the prototypes' sample covariance (``polarid map --bench``).
/// confidence : float, default 0.95
///     Confidence of the consistent set, in (0, 1).
/// weights : {"auto", "noise", "none"}, default "auto"
///     Weight each pixel's fit by its DoLP standard errors from the noise model
///     estimated on the map (``auto``: with calibrated geometry only).
/// angle_sd_deg, dolp_floor, extinction_ratio, retardance_deg : float
///     The set rule's systematic error model (defaults as ``polarid fit``:
///     0.2, 0.002, 100, 0).
/// bench : {"same", "other"}, default "same"
///     Where the model was trained (``--bench``): ``other`` compares both sides' total
///     covariance. No effect with a library.
///
/// Returns
/// -------
/// dict
///     ``n``, ``k``, ``n_se``, ``k_se``, ``rms_residual``: float32 (H, W), NaN where not
///     fitted (single-band manifests); for a colour manifest instead ``bands``: a dict
///     keyed by each band's wavelength in nm (float, increasing; ``bands[450]``) of
///     dicts ``wavelength_nm``, ``captures`` (the band's captures, numbered from 1 as in
///     ``map_summary.json``), ``n``, ``k``, ``n_se``, ``k_se``, ``rms_residual``
///     (float32 (H, W), the band's per-pixel fit: the CLI's ``n_450.tif`` ...),
///     ``reason`` (uint8 (H, W): why the band's fit of a pixel is not used by the
///     classification, codes into ``reason_names``; ``classified``: fitted ``ok``) and
///     ``reason_counts``; ``class``: uint8 (H, W) class codes (uint16 above 255
///     classes), 0 = ``unknown`` (no material; ``reason`` says why), code ``i`` is
///     ``class_names[i]``; ``reason``: uint8 (H, W), why a pixel is (not) classified, code ``i`` is ``reason_names[i]``; ``class_names`` (list,
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
///     A missing manifest, model or library file.
/// ValueError
///     An invalid option (``bin must be in 1..=64, got 0``), manifest, model, library
///     or image; neither or both of ``model`` and ``library``; a library with a
///     single-band manifest.
///
/// Warns
/// -----
/// UserWarning
///     The manifest's warnings and those of the map (e.g. too few pixels for the noise
///     model), as ``polarid map`` prints them.
#[pyfunction]
#[pyo3(signature = (manifest_path, model = None, *, library = None, bin = 1, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE, rule = "set", confidence = 0.95, weights = "auto", angle_sd_deg = map::MapErrors::default().angle_sd_deg, dolp_floor = map::MapErrors::default().dolp_floor, extinction_ratio = map::MapErrors::default().extinction_ratio, retardance_deg = map::MapErrors::default().retardance_deg, bench = "same"))]
#[allow(clippy::too_many_arguments)]
pub fn map_manifest<'py>(
    py: Python<'py>,
    manifest_path: &Bound<'py, PyAny>,
    model: Option<&Bound<'py, PyAny>>,
    library: Option<&str>,
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
    bench: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let errors = map::MapErrors {
        angle_sd_deg,
        dolp_floor,
        extinction_ratio,
        retardance_deg,
    };
    let opts = (bin, min_s0, max_distance, metric, tile);
    let cfg = map_config(opts, (rule, confidence), errors, bench)?
        .with_weights(map::parse_weights(weights).py_err()?);
    let mpath = path_arg(manifest_path)?;
    let model_path = model.map(path_arg).transpose()?;
    if model_path.is_some() == library.is_some() {
        return Err(value_error(
            "give model (a model JSON of polarid train) or library (\"builtin\", \
             \"builtin-rgb\" or a library CSV), not both or neither",
        ));
    }
    let m = py.detach(|| manifest::load(&mpath)).py_err()?;
    warn_all(py, &m)?;
    let r = match (&model_path, &library) {
        (Some(p), _) => {
            let mdl = py.detach(|| Model::read(p)).py_err()?;
            py.detach(|| map::map_manifest(&cfg, &m, &mdl, p, &no_progress))
        }
        (None, spec) => {
            let spec = spec.unwrap_or_default();
            py.detach(|| {
                map::map_manifest_from(&cfg, &m, map::MapPrototypes::Library(spec), &no_progress)
            })
        }
    }
    .py_err()?;
    warn_texts(
        py,
        r.warnings
            .iter()
            .skip(m.warnings.len())
            .map(|w| w.0.as_str()),
    )?;
    result(py, r)
}

/// The options of `polarid map` as Python names them: `bin`, `min_s0`, `max_distance`,
/// `metric`, `tile`.
pub type MapArgs<'a> = (usize, Option<f64>, Option<f64>, &'a str, usize);

/// The map's options, checked as `polarid map` checks them (errors name the option).
pub fn map_config(
    (bin, min_s0, max_distance, metric, tile): MapArgs<'_>,
    (rule, confidence): (&str, f64),
    errors: map::MapErrors,
    bench: &str,
) -> PyResult<MapConfig> {
    let bench = match bench {
        "same" => Bench::Same,
        "other" => Bench::Other,
        b => {
            return Err(value_error(format!(
                "bench must be \"same\" or \"other\", got {b:?}"
            )));
        }
    };
    let metric = map::parse_metric(metric).py_err()?;
    MapConfig::new(bin, min_s0, max_distance, metric, tile)
        .and_then(|c| c.with_rule(map::parse_rule(rule)?, confidence))
        .and_then(|c| c.with_errors(errors))
        .map(|c| c.with_bench(bench))
        .py_err()
}

/// A map's images, counts and summary as the dict of `map_manifest`.
fn result(py: Python<'_>, mut r: map::MapResult) -> PyResult<Bound<'_, PyDict>> {
    let summary = r.summary_json().to_string();
    let colour = r.is_colour();
    let (h, w) = (r.height, r.width);
    let d = PyDict::new(py);
    let mut names = vec![r.class_name(0).to_string()];
    names.extend(r.class_names.iter().cloned());
    d.set_item("class_names", names)?;
    d.set_item("reason_names", r.reason_names().to_vec())?;
    let counts = |v: Vec<i64>| shaped(py, &[v.len()], v);
    // The fit images of a band (`n`, `k`, ...) into `d`.
    let fit_images = |d: &Bound<'_, PyDict>, b: &mut map::BandMap| -> PyResult<()> {
        let all = [
            &mut b.n,
            &mut b.k,
            &mut b.n_se,
            &mut b.k_se,
            &mut b.rms_residual,
        ];
        for (name, v) in map::BAND_IMAGES.iter().zip(all) {
            d.set_item(*name, shaped(py, &[h, w], std::mem::take(v))?)?;
        }
        Ok(())
    };
    let classes: Vec<i64> = r.counts.classes.iter().map(|&c| c as i64).collect();
    let nreasons = r.reason_names().len();
    let reasons: Vec<i64> = r.counts.reasons[..nreasons]
        .iter()
        .map(|&c| c as i64)
        .collect();
    d.set_item("class_counts", counts(classes)?)?;
    d.set_item("reason_counts", counts(reasons)?)?;
    let json = py.import("json")?;
    d.set_item("summary", json.call_method1("loads", (summary,))?)?;
    if r.class_names.len() <= u8::MAX as usize {
        let c8: Vec<u8> = r.class.iter().map(|&c| c as u8).collect();
        d.set_item("class", shaped(py, &[h, w], c8)?)?;
    } else {
        d.set_item("class", shaped(py, &[h, w], r.class)?)?;
    }
    d.set_item("reason", shaped(py, &[h, w], r.reason)?)?;
    if !colour && let Some(mut b) = r.bands.pop() {
        fit_images(&d, &mut b)?;
    } else {
        let bands = PyDict::new(py);
        for mut b in r.bands {
            let bd = PyDict::new(py);
            bd.set_item("wavelength_nm", b.wavelength_nm)?;
            let caps: Vec<usize> = b.captures.iter().map(|&i| i + 1).collect();
            bd.set_item("captures", caps)?;
            fit_images(&bd, &mut b)?;
            bd.set_item("reason", shaped(py, &[h, w], b.reason)?)?;
            let rc: Vec<i64> = b.reasons[..nreasons].iter().map(|&c| c as i64).collect();
            bd.set_item("reason_counts", counts(rc)?)?;
            bands.set_item(b.wavelength_nm, bd)?;
        }
        d.set_item("bands", bands)?;
    }
    if r.calibrated {
        let t = r.beta_maps_deg.len();
        let flat: Vec<f64> = r.beta_maps_deg.into_iter().flatten().collect();
        d.set_item("beta_deg", shaped(py, &[t, h, w], flat)?)?;
    }
    Ok(d)
}
