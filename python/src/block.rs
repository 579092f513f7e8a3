//! One block of a material map from in-memory frames (`_map_block`), the kernel of
//! `polarid.dask.material_map`, and the global noise-model step of its weighted fits
//! (`_noise_block`, `_estimate_noise`).
//!
//! A block is a rectangle of every capture's frames: rotating-polarizer frames, or DoFP
//! mosaics (monochrome or colour) with a halo of raw pixels around it. Its map is
//! `polarid_pipeline::map::map_frames`: the stages of `polarid map` on the block's
//! pixels (one unnamed band, or one per wavelength of a colour pattern; calibrated
//! geometry with a β per pixel; the fits weighted by the map's noise model when given;
//! every pixel decided as `polarid map` decides it). Every output pixel depends only on
//! its own `bin × bin` block of frames (and, for DoFP, the raw pixels of the halo) and
//! on the map's noise model (two numbers), so a map made of blocks whose edges are
//! multiples of `bin` (and of the mosaic's period) equals the map of the whole frame.
//!
//! The noise model of weighted fits is the whole map's, as `polarid map` estimates it:
//! `_noise_block` and `_estimate_noise` translate the two passes over the blocks and
//! the estimate of `polarid_pipeline::map::noise_sample`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use numpy::PyUntypedArrayMethods;
use polarid_core::CoreError;
use polarid_core::map::noise::NoiseModel;
use polarid_core::map::sets::MapErrorModel;
use polarid_core::map::{self as cmap};
use polarid_core::mosaic::{ColourPattern, Pattern};
use polarid_core::stokes::{PixelRules, StokesSolver};
use polarid_core::systematic::Polarimetric;
use polarid_io::model::Model;
use polarid_pipeline::map::noise_sample::{
    BlockBeta, estimate_sample, noise_sample, usable_per_row,
};
use polarid_pipeline::map::{
    self, Frames, FramesSource, MapConfig, MapErrors, MapPrototypes, REASON_NAMES, band_order,
    frames_bands, frames_class_names, map_frames,
};
use pyo3::IntoPyObjectExt;
use pyo3::prelude::*;

use crate::arrays::{f64_contiguous, fmt_shape, raw_array, shaped};
use crate::colour::wavelengths;
use crate::errors::{PyResultExt, value_error};
use crate::map::map_config;
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

/// The float32 planes of a band in a block's result: n, k, n_se, k_se, rms_residual,
/// the band's reason.
const BAND_PLANES: usize = 6;

/// The options of a map as ``polarid.dask.material_map`` passes them (a dict): the
/// prototypes (`model_json`, a model's text that `label` names, or `library`: `builtin`,
/// `builtin-rgb`, a library CSV), the options of `polarid map` and the set rule's
/// systematic error model (one angle uncertainty per capture, degrees, and the
/// analyzer's terms).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct MapOptions {
    model_json: Option<String>,
    library: Option<String>,
    label: String,
    max_distance: Option<f64>,
    metric: String,
    tile: usize,
    rule: String,
    confidence: f64,
    angle_sd_deg: Vec<f64>,
    dolp_floor: f64,
    extinction_ratio: f64,
    retardance_deg: f64,
    bench: String,
}

/// The prototypes of a map: a model JSON's text (and the path `label` names it by) or a
/// library.
enum Protos {
    Model(Model, PathBuf),
    Library(String),
}

impl MapOptions {
    /// The map's configuration with `bin` and `min_s0`, checked as `polarid map` checks
    /// it (errors name the option; every capture's angle uncertainty is checked as
    /// `--angle-sd-deg` is, the first one in the options), and its prototypes.
    fn setup(&self, bin: usize, min_s0: Option<f64>) -> PyResult<(MapConfig, Protos)> {
        let bad = |a: &&f64| !(a.is_finite() && (0.0..90.0).contains(*a));
        if let Some(a) = self.angle_sd_deg.iter().find(bad) {
            return Err(value_error(format!(
                "angle_sd_deg must be in [0, 90), got {a}"
            )));
        }
        let errors = MapErrors {
            angle_sd_deg: self
                .angle_sd_deg
                .first()
                .copied()
                .unwrap_or(MapErrors::default().angle_sd_deg),
            dolp_floor: self.dolp_floor,
            extinction_ratio: self.extinction_ratio,
            retardance_deg: self.retardance_deg,
        };
        let rule = (self.rule.as_str(), self.confidence);
        let opts = (
            bin,
            min_s0,
            self.max_distance,
            self.metric.as_str(),
            self.tile,
        );
        let cfg = map_config(opts, rule, errors, &self.bench)?;
        let protos = match (&self.model_json, &self.library) {
            (Some(j), None) => {
                let path = PathBuf::from(&self.label);
                let m = Model::parse(&path, j).py_err()?;
                Protos::Model(m, path)
            }
            (None, Some(spec)) => Protos::Library(spec.clone()),
            _ => {
                return Err(value_error(
                    "give model_json or library, not both or neither",
                ));
            }
        };
        Ok((cfg, protos))
    }

    /// The core error model (as `polarid_pipeline::map`'s `error_model`: radians, no
    /// surface-film term in maps).
    fn error_model(&self) -> MapErrorModel {
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

impl Protos {
    fn src(&self) -> MapPrototypes<'_> {
        match self {
            Protos::Model(model, path) => MapPrototypes::Model { model, path },
            Protos::Library(spec) => MapPrototypes::Library(spec),
        }
    }
}

/// A colour pattern (`pattern` by default IMX250MYR's 90, 45, 135, 0) and the wavelength
/// of each of its bands (pattern order).
fn colour_pattern(
    color: &str,
    pattern: Option<Vec<f64>>,
    bands: Option<HashMap<String, f64>>,
) -> PyResult<(ColourPattern, Vec<f64>)> {
    let pattern = pattern.unwrap_or_else(|| vec![90.0, 45.0, 135.0, 0.0]);
    let cp = ColourPattern::new(Pattern::new(&pattern).py_err()?, color).py_err()?;
    let nms = wavelengths(&cp, bands)?;
    Ok((cp, nms))
}

/// The class names (``"unknown"`` first, then the prototypes' classes sorted, then
/// ``"ambiguous"`` with the set rule: index = class code of a map), the reason names
/// (index = reason code, as ``map_summary.json`` lists them) and the bands' wavelengths
/// (increasing; empty for single-band frames) of a map. Checks the options as
/// ``_map_block`` does (errors name the option). ``options``: as ``_map_block``'s.
#[pyfunction]
#[pyo3(signature = (options, *, color = None, pattern = None, bands = None, bin = 1, min_s0 = None))]
fn _map_names(
    options: MapOptions,
    color: Option<&str>,
    pattern: Option<Vec<f64>>,
    bands: Option<HashMap<String, f64>>,
    bin: usize,
    min_s0: Option<f64>,
) -> PyResult<(Vec<String>, Vec<String>, Vec<f64>)> {
    let (cfg, protos) = options.setup(bin, min_s0)?;
    let wls = match color {
        Some(c) => band_order(&colour_pattern(c, pattern, bands)?.1).0,
        None => Vec::new(),
    };
    let bands_of: Vec<Option<f64>> = if wls.is_empty() {
        vec![None]
    } else {
        wls.iter().map(|&w| Some(w)).collect()
    };
    let names = frames_class_names(&cfg, protos.src(), &bands_of, color.is_some()).py_err()?;
    let mut classes = vec![polarid_core::classify::UNKNOWN.to_string()];
    classes.extend(names);
    let reasons = REASON_NAMES.iter().map(|s| s.to_string()).collect();
    Ok((classes, reasons, wls))
}

/// The checked inputs of a block (frames, their kind, β, pixel rules), shared by
/// `_map_block` and `_noise_block`.
struct Inputs<'py> {
    raw: crate::arrays::RawArray<'py>,
    t_len: usize,
    hh: usize,
    ww: usize,
    halo: [usize; 4],
    ow: usize,
    oh: usize,
    per_pixel: bool,
    beta: Vec<f64>,
    kind: Kind,
    rules: Vec<PixelRules>,
}

/// How a block's captures were taken (owning what `FramesSource` borrows).
enum Kind {
    Polarizer(StokesSolver),
    Dofp(Pattern),
    Colour(ColourPattern, Vec<f64>),
}

/// A block's frames and how they were taken, as ``polarid.dask`` passes them (a dict,
/// the first argument of `_map_block` and `_noise_block`).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct BlockArgs<'py> {
    frames: Bound<'py, PyAny>,
    angles_deg: Option<Vec<f64>>,
    beta_deg: Bound<'py, PyAny>,
    pattern: Option<Vec<f64>>,
    color: Option<String>,
    bands: Option<HashMap<String, f64>>,
    halo: (usize, usize, usize, usize),
    bin: usize,
    dark_level: Option<Vec<f64>>,
    saturation: Option<Vec<Option<f64>>>,
    min_s0: Option<f64>,
}

/// The checked inputs of block `a`.
fn inputs<'py>(a: &BlockArgs<'py>) -> PyResult<Inputs<'py>> {
    let (pattern, angles_deg, halo) = (a.pattern.clone(), &a.angles_deg, a.halo);
    let colour = a.color.as_deref().map(|c| (c, a.bands.clone()));
    let raw = raw_array("frames", &a.frames)?;
    let shape = raw.shape();
    let mosaic = pattern.is_some() || colour.is_some();
    let (t_len, a_len, hh, ww) = match (&shape[..], mosaic) {
        (&[t, h, w], true) => (t, 1, h, w),
        (&[t, a, h, w], false) => (t, a, h, w),
        _ => {
            return Err(value_error(format!(
                "frames must have shape {}, got shape {}",
                if mosaic {
                    "(captures, rows, columns) (DoFP mosaics)"
                } else {
                    "(captures, angles, rows, columns)"
                },
                fmt_shape(&shape)
            )));
        }
    };
    let halo = [halo.0, halo.1, halo.2, halo.3];
    if !mosaic && halo != [0; 4] {
        return Err(value_error("a halo is for DoFP mosaics only".to_string()));
    }
    if halo[0] + halo[1] >= hh || halo[2] + halo[3] >= ww {
        return Err(value_error(format!(
            "halo {halo:?} leaves no pixel of a {hh}x{ww} block"
        )));
    }
    let (h, w) = (hh - halo[0] - halo[1], ww - halo[2] - halo[3]);
    let (ow, oh) = cmap::binned_size(w, h, a.bin).py_err()?;
    let dark = a.dark_level.clone().unwrap_or_else(|| vec![0.0; t_len]);
    let sat = a.saturation.clone().unwrap_or_else(|| vec![None; t_len]);
    if dark.len() != t_len || sat.len() != t_len {
        return Err(value_error(format!(
            "dark_level and saturation need one value per capture ({t_len}), got {} and {}",
            dark.len(),
            sat.len()
        )));
    }
    // β: one per capture (far field) or one per pixel and capture (calibrated rules).
    let beta_arr = f64_contiguous("beta_deg", &a.beta_deg)?;
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
    let kind = match (colour, pattern, angles_deg) {
        (Some((c, bands)), p, _) => {
            let (cp, nms) = colour_pattern(c, p, bands)?;
            Kind::Colour(cp, nms)
        }
        (None, Some(p), _) => Kind::Dofp(Pattern::new(&p).py_err()?),
        (None, None, Some(a)) if a.len() == a_len => {
            Kind::Polarizer(StokesSolver::from_degrees(a).py_err()?)
        }
        (None, None, a) => {
            return Err(value_error(format!(
                "angles_deg must give one angle per frame of a capture ({a_len}), got {}",
                a.as_ref().map_or(0, Vec::len)
            )));
        }
    };
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
        hh,
        ww,
        halo,
        ow,
        oh,
        per_pixel,
        beta,
        kind,
        rules,
    })
}

impl Inputs<'_> {
    /// The block's frames for the pipeline.
    fn frames<'a, T>(&'a self, data: &'a [T]) -> Frames<'a, T> {
        Frames {
            data,
            captures: self.t_len,
            rows: self.hh,
            columns: self.ww,
            halo: self.halo,
            source: match &self.kind {
                Kind::Polarizer(s) => FramesSource::Polarizer(s, None),
                Kind::Dofp(p) => FramesSource::Dofp(p, None),
                Kind::Colour(cp, nms) => FramesSource::Colour(cp, nms),
            },
            rules: &self.rules,
            is_integer: self.raw.is_integer(),
        }
    }

    /// β in radians, as the fit takes it.
    fn beta_rad(&self) -> BlockBeta {
        BlockBeta::from_degrees(&self.beta, self.per_pixel, self.ow * self.oh)
    }
}

/// One block of a material map (private: called by ``polarid.dask.material_map``).
///
/// ``block``: a dict of ``frames``: (T, A, h, w) polarizer frames (``angles_deg`` the A
/// angles), or with ``pattern`` (and, for colour mosaics, ``color`` and ``bands``) a
/// (T, h, w) DoFP mosaic stack whose first ``halo = (top, bottom, left, right)``
/// rows/columns are neighbours of the block (read by the bilinear interpolation, not
/// mapped); ``beta_deg``: (T,) one β per capture, or (T, h/bin, w/bin) per pixel (NaN:
/// no geometry); ``bin``, ``min_s0``; ``dark_level`` (T,), ``saturation`` (T,) or None.
/// ``options``: a dict of the prototypes (``model_json``, a model's text that ``label``
/// names, or ``library``; the other None), ``max_distance``, ``metric``, ``tile`` and
/// ``rule``, ``confidence``, ``angle_sd_deg`` (one per capture), ``dolp_floor``,
/// ``extinction_ratio``, ``retardance_deg``, ``bench``: the answer rule and its error
/// model, as ``polarid map``. ``noise``: weighted fits with the map's noise model of every band (a list,
/// increasing wavelength, of ``(read_var_dn2, inv_gain)`` or None: that band unweighted),
/// or None (unweighted). Returns float32 (6 B + 2, h/bin, w/bin): for each band
/// (one for single-band frames, else in increasing wavelength) n, k, n_se, k_se,
/// rms_residual and the band's reason code, then the map's class and reason codes
/// (see ``_map_names``).
#[pyfunction]
#[pyo3(signature = (block, options, *, noise = None))]
fn _map_block<'py>(
    py: Python<'py>,
    block: BlockArgs<'py>,
    options: MapOptions,
    noise: Option<Vec<Option<(f64, f64)>>>,
) -> PyResult<Bound<'py, PyAny>> {
    let inp = inputs(&block)?;
    if options.angle_sd_deg.len() != inp.t_len {
        return Err(value_error(format!(
            "angle_sd_deg needs one value per capture ({}), got {}",
            inp.t_len,
            options.angle_sd_deg.len()
        )));
    }
    let (cfg, protos) = options.setup(block.bin, block.min_s0)?;
    let bad = |&(r2, ig): &(f64, f64)| {
        !(r2.is_finite() && ig.is_finite() && r2 >= 0.0 && ig >= 0.0 && r2 + ig > 0.0)
    };
    if let Some((r2, ig)) = noise.iter().flatten().flatten().copied().find(bad) {
        return Err(value_error(format!(
            "noise must be (read_var_dn2, inv_gain), finite, >= 0 and not both 0, got ({r2}, {ig})"
        )));
    }
    let models: Option<Vec<Option<NoiseModel>>> = noise.map(|v| {
        let model = |(read_var_dn2, inv_gain)| NoiseModel {
            read_var_dn2,
            inv_gain,
        };
        v.into_iter().map(|m| m.map(model)).collect()
    });
    let noise = models.as_deref();
    let model = options.error_model();
    let (far, beta): (Vec<f64>, Vec<Vec<f32>>) = match inp.beta_rad() {
        BlockBeta::Shared(b) => (b, Vec::new()),
        BlockBeta::PerPixel(m) => (vec![f64::NAN; inp.t_len], m),
    };
    let (src, label) = (protos.src(), Path::new(&options.label));
    let fit = with_raw!(&inp.raw, |data| {
        let f = inp.frames(data);
        py.detach(|| map_frames(&cfg, src, &f, &far, &beta, &model, noise, label))
    });
    let fit = fit.py_err()?;
    let (ow, oh) = (inp.ow, inp.oh);
    let npix = ow * oh;
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
    shaped(py, &[BAND_PLANES * nb + 2, oh, ow], out)
}

/// The noise-model sample of a block (private: the global step of
/// ``polarid.dask.material_map``'s weighted fits,
/// ``polarid_pipeline::map::noise_sample``).
///
/// ``block`` as ``_map_block``'s; ``band``: the band sampled (index in increasing
/// wavelength; 0 for single-band frames). Without ``row_offsets``: the number of usable
/// pixels of every map row of the block (list, h/bin). With ``row_offsets`` (the usable
/// pixels of the whole map before each row of the block, row-major) and ``stride``:
/// ``(index, images)``, the block's usable pixels whose map rank is a multiple of
/// ``stride`` (``index`` row-major within the block's map pixels) and their images per
/// capture: DoLP, read and shot terms and, with a β per pixel, β in radians.
#[pyfunction]
#[pyo3(signature = (block, *, band = 0, row_offsets = None, stride = 1))]
fn _noise_block<'py>(
    py: Python<'py>,
    block: BlockArgs<'py>,
    band: usize,
    row_offsets: Option<Vec<usize>>,
    stride: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let cfg = MapConfig::new(block.bin, block.min_s0, None, map::Metric::Euclidean, 1).py_err()?;
    let inp = inputs(&block)?;
    let per_pixel = inp.per_pixel;
    let bands = with_raw!(&inp.raw, |data| {
        let f = inp.frames(data);
        py.detach(|| frames_bands(&cfg, &f, per_pixel, true))
    });
    let bands = bands.py_err()?;
    let b = bands
        .get(band)
        .ok_or_else(|| value_error(format!("band {band} of a map of {} band(s)", bands.len())))?;
    let beta = inp.beta_rad();
    let Some(offsets) = row_offsets else {
        return usable_per_row(b, &beta, inp.ow, inp.oh).into_bound_py_any(py);
    };
    noise_sample(b, &beta, inp.ow, &offsets, stride)
        .py_err()?
        .into_bound_py_any(py)
}

/// `(read_var_dn2, inv_gain, pixels, outliers, reduced_chi2)` of a noise estimate.
type NoiseTuple = (f64, f64, usize, usize, f64);

/// The map's noise model from the gathered sample (private:
/// ``polarid_pipeline::map::noise_sample::estimate_sample``). ``dolp``, ``read``,
/// ``shot``: per capture, the sampled pixels in the map's row-major order; ``beta_deg``
/// (T,) with one β per capture, or ``beta_rad`` per capture and pixel. Returns None
/// when the sample gives no estimate (too few usable pixels), else ``(read_var_dn2,
/// inv_gain, pixels, outliers, reduced_chi2)``: the estimate of ``polarid map``
/// (``map_summary.json``'s ``noise``).
#[pyfunction]
#[pyo3(signature = (dolp, read, shot, *, beta_deg = None, beta_rad = None))]
fn _estimate_noise(
    py: Python<'_>,
    dolp: Vec<Vec<f32>>,
    read: Vec<Vec<f32>>,
    shot: Vec<Vec<f32>>,
    beta_deg: Option<Vec<f64>>,
    beta_rad: Option<Vec<Vec<f32>>>,
) -> PyResult<Option<NoiseTuple>> {
    let beta = match (beta_deg, beta_rad) {
        (Some(b), None) => BlockBeta::from_degrees(&b, false, 0),
        (None, Some(b)) => BlockBeta::PerPixel(b),
        _ => return Err(value_error("give either beta_deg or beta_rad")),
    };
    let est = py
        .detach(|| estimate_sample(&dolp, &read, &shot, &beta))
        .py_err()?;
    Ok(est.map(|e| {
        let m = e.model;
        (
            m.read_var_dn2,
            m.inv_gain,
            e.pixels,
            e.outliers,
            e.reduced_chi2,
        )
    }))
}
