//! One block of a colour material map (`_map_block_colour`, `_map_names_colour`): the
//! kernel of `polarid.dask.material_map` on colour polarization mosaics (a 2×2 polarizer
//! block under each colour of a 2×2 colour pattern, docs/BANDS.md).
//!
//! The steps are those of `polarid_pipeline::map::map_manifest_from` (`polarid map` on
//! a colour manifest), on the block's pixels: per capture the bilinear per-band Stokes
//! images of the mosaic (`polarid_core::mosaic::colour_polar`, as
//! `polarid_io::bands::colour_stokes` with the same pixel rules and dark threshold),
//! each band's binned DoLP and flags (`map::stokes_dolp_noise`), then the pipeline's own
//! stages 2 and 3 (`polarid_pipeline::map::fit_bands`: every band fitted per pixel,
//! every pixel classified on all its bands). The bilinear interpolation of a band reads
//! raw pixels up to 3 away, so a block carries a halo of 4 raw pixels (a whole period)
//! on its inner sides, and its edges are multiples of 4 (and of the bin): a map made of
//! blocks equals the map of the whole frame. Far field only (one β per capture),
//! unweighted fits (`polarid map`'s default without calibrated geometry).

use std::path::Path;

use ndarray::{ArrayD, IxDyn};
use polarid_core::CoreError;
use polarid_core::classify::MultiPrototype;
use polarid_core::map as cmap;
use polarid_core::mosaic::{ColourMethod, ColourPattern, DofpOutputs, Pattern, colour_polar};
use polarid_core::stokes::{PixelRules, Sample};
use polarid_io::library::Library;
use polarid_io::model::Model;
use polarid_pipeline::map::rules::min_s0_for;
use polarid_pipeline::map::{
    self, BandDolp, FitGeometry, MapConfig, MapErrors, REASON_NAMES, band_class_names, fit_bands,
};
use pyo3::prelude::*;

use crate::arrays::{fmt_shape, raw_array, to_numpy};
use crate::block::{ErrorArgs, config, crop};
use crate::colour::wavelengths;
use crate::errors::{IntoPyErr, PyResultExt, value_error};
use crate::stokes::pixel_rules;
use crate::with_raw;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(_map_block_colour, m)?)?;
    m.add_function(wrap_pyfunction!(_map_names_colour, m)?)?;
    Ok(())
}

/// The float32 planes of a band in a block's result: n, k, n_se, k_se, rms_residual,
/// the band's reason.
const BAND_PLANES: usize = 6;

/// The multi-band prototypes: a model JSON's text, or a library (`builtin-rgb` or a
/// library CSV path).
fn profiles(
    model_json: Option<&str>,
    library: Option<&str>,
    label: &str,
) -> PyResult<Vec<MultiPrototype>> {
    match (model_json, library) {
        (Some(j), None) => Ok(Model::parse(Path::new(label), j)
            .map_err(IntoPyErr::into_py_err)?
            .multi_prototypes()),
        (None, Some(spec)) => Ok(Library::load(spec).py_err()?.multi_prototypes()),
        _ => Err(value_error(
            "give model_json or library, not both or neither",
        )),
    }
}

/// The colour pattern and its bands' wavelengths, in the pattern's band order.
fn colour_pattern(
    color: &str,
    pattern: Vec<f64>,
    bands: Option<std::collections::HashMap<String, f64>>,
) -> PyResult<(ColourPattern, Vec<f64>)> {
    let cp = ColourPattern::new(Pattern::new(&pattern).py_err()?, color).py_err()?;
    let nms = wavelengths(&cp, bands)?;
    Ok((cp, nms))
}

/// The distinct wavelengths of `nms`, increasing (the map's band order), and the index of
/// each pattern band among them.
fn band_order(nms: &[f64]) -> (Vec<f64>, Vec<usize>) {
    let mut all = nms.to_vec();
    all.sort_by(f64::total_cmp);
    all.dedup_by(|a, b| polarid_core::classify::same_band(Some(*a), Some(*b)));
    let of = nms
        .iter()
        .map(|&w| {
            all.iter()
                .position(|&a| polarid_core::classify::same_band(Some(a), Some(w)))
                .unwrap_or(0)
        })
        .collect();
    (all, of)
}

/// Class names (``"unknown"`` first, the prototypes' classes sorted, ``"ambiguous"``
/// with the set rule), reason names and the bands' wavelengths (increasing) of a colour
/// map (private: ``polarid.dask.material_map``). Checks the options as
/// ``_map_block_colour`` does.
#[pyfunction]
#[pyo3(signature = (*, model_json = None, library = None, label = "<model>", color = "RGGB", pattern = vec![90.0, 45.0, 135.0, 0.0], bands = None, bin = 1, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE, rule = "set", confidence = polarid_core::classify::DEFAULT_CONFIDENCE))]
#[allow(clippy::too_many_arguments)]
fn _map_names_colour(
    model_json: Option<&str>,
    library: Option<&str>,
    label: &str,
    color: &str,
    pattern: Vec<f64>,
    bands: Option<std::collections::HashMap<String, f64>>,
    bin: usize,
    min_s0: Option<f64>,
    max_distance: Option<f64>,
    metric: &str,
    tile: usize,
    rule: &str,
    confidence: f64,
) -> PyResult<(Vec<String>, Vec<String>, Vec<f64>)> {
    let errors = ErrorArgs::default_for(1);
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
    let (_, nms) = colour_pattern(color, pattern, bands)?;
    let protos = profiles(model_json, library, label)?;
    let mut classes = vec![polarid_core::classify::UNKNOWN.to_string()];
    classes.extend(band_class_names(&cfg, &protos, label).py_err()?);
    let reasons = REASON_NAMES.iter().map(|s| s.to_string()).collect();
    Ok((classes, reasons, band_order(&nms).0))
}

/// Stage 1 of a colour block: every band's binned DoLP and flags over the captures.
#[allow(clippy::too_many_arguments)]
fn stage1<T: Sample>(
    data: &[T],
    (t_len, hh, ww): (usize, usize, usize),
    halo: [usize; 4],
    cp: &ColourPattern,
    band_of: &[usize],
    wls: &[f64],
    rules: &[PixelRules],
    is_int: bool,
    cfg_min_s0: Option<f64>,
    bin: usize,
) -> Result<(Vec<BandDolp>, usize), CoreError> {
    let (h, w) = (hh - halo[0] - halo[1], ww - halo[2] - halo[3]);
    let (ow, oh) = cmap::binned_size(w, h, bin)?;
    let npix = ow * oh;
    let plane = hh * ww;
    let mut accs: Vec<BandDolp> = wls
        .iter()
        .map(|&wl| BandDolp::new(wl, (0..t_len).collect()))
        .collect();
    let nb = band_of.len();
    for (t, r) in rules.iter().enumerate() {
        let mut r = *r;
        let th = min_s0_for(&r, is_int, cfg_min_s0);
        // The dark test is made on the block mean by stokes_dolp.
        r.min_s0 = f32::MIN;
        let z = || vec![0f32; plane];
        let mut s0: Vec<Vec<f32>> = (0..nb).map(|_| z()).collect();
        let mut s1: Vec<Vec<f32>> = (0..nb).map(|_| z()).collect();
        let mut s2: Vec<Vec<f32>> = (0..nb).map(|_| z()).collect();
        let mut mk: Vec<Vec<u8>> = (0..nb).map(|_| vec![0u8; plane]).collect();
        let outs: Vec<DofpOutputs<'_>> = s0
            .iter_mut()
            .zip(s1.iter_mut())
            .zip(s2.iter_mut())
            .zip(mk.iter_mut())
            .map(|(((a, b), c), m)| DofpOutputs {
                s0: Some(a),
                s1: Some(b),
                s2: Some(c),
                mask: Some(m),
                ..Default::default()
            })
            .collect();
        let cap = &data[t * plane..(t + 1) * plane];
        colour_polar(cap, ww, cp, ColourMethod::Bilinear, &r, outs)?;
        for b in 0..nb {
            let (a0, a1, a2, m) = if halo != [0; 4] {
                (
                    crop(&s0[b], ww, hh, halo),
                    crop(&s1[b], ww, hh, halo),
                    crop(&s2[b], ww, hh, halo),
                    crop(&mk[b], ww, hh, halo),
                )
            } else {
                (
                    std::mem::take(&mut s0[b]),
                    std::mem::take(&mut s1[b]),
                    std::mem::take(&mut s2[b]),
                    std::mem::take(&mut mk[b]),
                )
            };
            let mut dl = vec![0f32; npix];
            let mut cf = vec![0u8; npix];
            cmap::stokes_dolp_noise(w, &a0, &a1, &a2, Some(&m), th, bin, &mut dl, &mut cf, None)?;
            accs[band_of[b]].push(false, dl, &cf, None);
        }
    }
    Ok((accs, npix))
}

/// One block of a colour material map (private: called by
/// ``polarid.dask.material_map`` with ``color``).
///
/// ``raw``: (T, h, w) colour mosaics (h, w multiples of 4) whose first ``halo = (top,
/// bottom, left, right)`` rows/columns are neighbours of the block (4 on inner sides).
/// ``beta_deg``: (T,) one β per capture. The prototypes: ``model_json`` (a multi-band
/// model's text) or ``library`` (``builtin-rgb`` or a library CSV). Other options as
/// ``_map_block``. Returns float32 (6 B + 2, h/bin, w/bin): for each band in increasing
/// wavelength n, k, n_se, k_se, rms_residual and the band's reason code, then the class
/// and reason codes of the multi-band classification.
#[pyfunction]
#[pyo3(signature = (raw, beta_deg, *, model_json = None, library = None, label = "<model>", color = "RGGB", pattern = vec![90.0, 45.0, 135.0, 0.0], bands = None, halo = (0, 0, 0, 0), bin = 1, dark_level = None, saturation = None, min_s0 = None, max_distance = None, metric = "euclidean", tile = map::DEFAULT_TILE, rule = "set", confidence = polarid_core::classify::DEFAULT_CONFIDENCE, angle_sd_deg = None, dolp_floor = MapErrors::default().dolp_floor, extinction_ratio = MapErrors::default().extinction_ratio, retardance_deg = MapErrors::default().retardance_deg))]
#[allow(clippy::too_many_arguments)]
fn _map_block_colour<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    beta_deg: Vec<f64>,
    model_json: Option<&str>,
    library: Option<&str>,
    label: &str,
    color: &str,
    pattern: Vec<f64>,
    bands: Option<std::collections::HashMap<String, f64>>,
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
) -> PyResult<Bound<'py, PyAny>> {
    let raw = raw_array("raw", raw)?;
    let shape = raw.shape();
    let &[t_len, hh, ww] = &shape[..] else {
        return Err(value_error(format!(
            "raw must have shape (captures, rows, columns) (colour mosaics), got shape {}",
            fmt_shape(&shape)
        )));
    };
    let halo = [halo.0, halo.1, halo.2, halo.3];
    if halo[0] + halo[1] >= hh || halo[2] + halo[3] >= ww {
        return Err(value_error(format!(
            "halo {halo:?} leaves no pixel of a {hh}x{ww} block"
        )));
    }
    if beta_deg.len() != t_len {
        return Err(value_error(format!(
            "beta_deg must have shape ({t_len},) (one angle per capture), got {} values",
            beta_deg.len()
        )));
    }
    let errors = ErrorArgs {
        angle_sd_deg: angle_sd_deg
            .unwrap_or_else(|| vec![MapErrors::default().angle_sd_deg; t_len]),
        dolp_floor,
        extinction_ratio,
        retardance_deg,
    };
    if errors.angle_sd_deg.len() != t_len {
        return Err(value_error(format!(
            "angle_sd_deg needs one value per capture ({t_len}), got {}",
            errors.angle_sd_deg.len()
        )));
    }
    errors.check()?;
    let cfg: MapConfig = config(
        bin,
        min_s0,
        max_distance,
        metric,
        tile,
        rule,
        confidence,
        &errors,
    )?;
    let (cp, nms) = colour_pattern(color, pattern, bands)?;
    let (wls, band_of) = band_order(&nms);
    let protos = profiles(model_json, library, label)?;
    let dark = dark_level.unwrap_or_else(|| vec![0.0; t_len]);
    let sat = saturation.unwrap_or_else(|| vec![None; t_len]);
    if dark.len() != t_len || sat.len() != t_len {
        return Err(value_error(format!(
            "dark_level and saturation need one value per capture ({t_len}), got {} and {}",
            dark.len(),
            sat.len()
        )));
    }
    let mut rules = Vec::with_capacity(t_len);
    for (d, s) in dark.iter().zip(&sat) {
        rules.push(pixel_rules(*d, *s, raw.type_max(), 0.0)?);
    }
    let is_int = raw.is_integer();
    let betas: Vec<f64> = beta_deg.iter().map(|b| b.to_radians()).collect();
    let model = errors.model();
    let dims = (t_len, hh, ww);
    let fit = with_raw!(&raw, |data| py.detach(|| {
        let (accs, npix) = stage1(
            data, dims, halo, &cp, &band_of, &wls, &rules, is_int, min_s0, bin,
        )
        .map_err(|e| {
            polarid_pipeline::PipelineError::from(polarid_io::IoError::Core {
                path: label.into(),
                source: e,
            })
        })?;
        let geo = FitGeometry {
            npix,
            far_betas: &betas,
            beta: &[],
            errors: &model,
        };
        fit_bands(
            &cfg,
            accs,
            geo,
            &protos,
            label,
            Path::new(label),
            &|_, _, _| {},
        )
        .map(|f| (f, npix))
    }))
    .py_err()?;
    let (fit, npix) = fit;
    let (h, w) = (hh - halo[0] - halo[1], ww - halo[2] - halo[3]);
    let (ow, oh) = cmap::binned_size(w, h, bin).py_err()?;
    let nb = fit.bands.len();
    let mut out: Vec<f32> = Vec::with_capacity((BAND_PLANES * nb + 2) * npix);
    for b in &fit.bands {
        for plane in [&b.n, &b.k, &b.n_se, &b.k_se, &b.rms_residual] {
            out.extend_from_slice(plane);
        }
        out.extend(b.reason.iter().map(|&r| r as f32));
    }
    out.extend(fit.class.iter().map(|&c| c as f32));
    out.extend(fit.reason.iter().map(|&r| r as f32));
    let a = ArrayD::from_shape_vec(IxDyn(&[BAND_PLANES * nb + 2, oh, ow]), out)
        .map_err(|e| value_error(e.to_string()))?;
    Ok(to_numpy(py, a))
}
