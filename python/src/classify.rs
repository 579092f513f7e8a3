//! Material classification of `(n, k)` estimates (paper section 6) against a library, a
//! trained model or a list of prototypes (`polarid_core::classify::Classifier`): arrays of
//! estimates (`classify`, one or several bands per estimate) and fits CSVs
//! (`classify_table`, the `polarid classify` workflow itself).
//!
//! Both take their prototypes as `polarid classify` does
//! (`polarid_pipeline::classify::PrototypeSource::load_multi_for`: single-band or
//! multi-band models and libraries, the built-in libraries evaluated at the estimates'
//! wavelengths) and classify with the multi-band classifier of the pipeline
//! (`multi_classifier`, `Classifier::classify_multi`).

use std::collections::HashSet;
use std::path::Path;

use ndarray::{ArrayD, ArrayViewD, IxDyn};
use polarid_core::FitStatus;
use polarid_core::classify::{
    AMBIGUOUS, Classifier, ClassifierConfig, Cov2, Decision, Estimate, EstimateBand, MultiEstimate,
    Prototype, Rule, UNKNOWN,
};
use polarid_core::systematic::FilmShifts;
use polarid_pipeline::classify::{
    self as pipe, ClassifyConfig, PrototypeSource, multi_classifier, read_fits,
};
use polarid_pipeline::options::{self, ClassifierOptions};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use rayon::prelude::*;

use crate::arrays::{
    F64Like, NameTable, broadcast_shape, broadcast_to, fmt_shape, shaped, str_array, to_numpy,
};
use crate::errors::{PyResultExt, value_error};
use crate::files::{path_arg, warn_texts};

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(classify, m)?)?;
    m.add_function(wrap_pyfunction!(classify_table, m)?)?;
    Ok(())
}

/// Where the prototypes come from: a library name or file path (`.json`: a model of
/// `polarid train`; otherwise a library CSV), a sequence of `(class, n, k[, category])`,
/// or `None` (the library `builtin`).
fn prototype_source(obj: Option<&Bound<'_, PyAny>>) -> PyResult<PrototypeSource> {
    let Some(obj) = obj else {
        return Ok(PrototypeSource::Library("builtin".into()));
    };
    let py = obj.py();
    let spec: Option<String> = if obj.is_instance_of::<PyString>() {
        Some(obj.extract()?)
    } else if obj.hasattr("__fspath__")? {
        Some(py.import("os")?.call_method1("fspath", (obj,))?.extract()?)
    } else {
        None
    };
    if let Some(spec) = spec {
        return Ok(if spec.to_ascii_lowercase().ends_with(".json") {
            PrototypeSource::Model(spec.into())
        } else {
            PrototypeSource::Library(spec)
        });
    }
    let mut out = Vec::new();
    for (i, item) in obj.try_iter()?.enumerate() {
        let item = item?;
        let parsed: PyResult<(String, f64, f64, Option<String>)> = item
            .extract::<(String, f64, f64)>()
            .map(|(c, n, k)| (c, n, k, None))
            .or_else(|_| item.extract::<(String, f64, f64, Option<String>)>());
        let (class, n, k, category) = parsed.map_err(|_| {
            value_error(format!(
                "prototype {} must be a tuple (class, n, k) or (class, n, k, category), got {}",
                i + 1,
                item.repr().map(|r| r.to_string()).unwrap_or_default()
            ))
        })?;
        out.push(Prototype {
            class,
            n,
            k,
            cov: None,
            category,
            source: format!("prototype {}", i + 1),
        });
    }
    Ok(PrototypeSource::List(out, "the prototypes".into()))
}

/// The nearest rule's options as Python names them: `metric`, `neighbours`, `reject`,
/// `max_distance`.
type NearestArgs<'a> = (Option<&'a str>, usize, Option<f64>, Option<f64>);

/// The classifier settings of `rule` and the nearest rule's options, checked as
/// `polarid classify` checks them (errors name the option).
fn classifier_config(
    rule: Rule,
    confidence: f64,
    (metric, neighbours, reject, max_distance): NearestArgs<'_>,
) -> PyResult<ClassifierConfig> {
    ClassifierOptions {
        rule,
        confidence,
        metric: metric.map(options::parse_metric).transpose().py_err()?,
        neighbours,
        reject,
        max_distance,
    }
    .config()
    .py_err()
}

/// A wavelength checked as `polarid classify --wavelength-nm` checks it.
fn check_wavelength(w: f64) -> PyResult<()> {
    ClassifyConfig {
        wavelength_nm: Some(w),
        ..ClassifyConfig::default()
    }
    .validate()
    .py_err()
}

/// The elements of `v` in logical order, with axis `band` (when given) moved last: the
/// bands of an estimate are then consecutive.
fn flat_bands<T: Copy>(v: &ndarray::ArrayViewD<'_, T>, band: Option<usize>) -> Vec<T> {
    match band {
        None => v.iter().copied().collect(),
        Some(ax) => {
            let mut perm: Vec<usize> = (0..v.ndim()).filter(|&i| i != ax).collect();
            perm.push(ax);
            v.clone().permuted_axes(perm).iter().copied().collect()
        }
    }
}

/// Fit statuses as `(table of statuses, index into it per element)`: status words, or
/// the codes of `fit_nk`'s `status_code`.
fn fit_statuses(
    obj: &Bound<'_, PyAny>,
    shape: &[usize],
) -> PyResult<(Vec<FitStatus>, ArrayD<u32>)> {
    let np = obj.py().import("numpy")?;
    let a = np.call_method1("asarray", (obj,))?;
    let a = np
        .call_method1("broadcast_to", (a, shape.to_vec()))
        .map_err(|_| {
            value_error(format!(
                "fit_status cannot be broadcast to the shape {} of n and k",
                fmt_shape(shape)
            ))
        })?;
    let kind: String = a.getattr("dtype")?.getattr("kind")?.extract()?;
    let flat = np.call_method1("ravel", (a,))?;
    let (table, codes): (Vec<FitStatus>, Vec<i64>) = if matches!(kind.as_str(), "i" | "u") {
        let codes: Vec<i64> = flat.call_method0("tolist")?.extract()?;
        for &c in &codes {
            if c < 0 || c as usize >= FitStatus::ALL.len() {
                return Err(value_error(format!(
                    "fit_status code {c} is not a status code (0 to {})",
                    FitStatus::ALL.len() - 1
                )));
            }
        }
        (FitStatus::ALL.to_vec(), codes)
    } else {
        let kw = PyDict::new(obj.py());
        kw.set_item("return_inverse", true)?;
        let flat = flat.call_method1("astype", ("U",))?;
        let res = np.call_method("unique", (flat,), Some(&kw))?;
        let words: Vec<String> = res.get_item(0)?.call_method0("tolist")?.extract()?;
        let codes: Vec<i64> = res.get_item(1)?.call_method0("tolist")?.extract()?;
        let table = words
            .iter()
            .map(|w| {
                FitStatus::parse(w).ok_or_else(|| {
                    let known: Vec<&str> = FitStatus::ALL.iter().map(|s| s.as_str()).collect();
                    value_error(format!(
                        "fit_status {w:?} is not a fit status (one of {})",
                        known.join(", ")
                    ))
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        (table, codes)
    };
    let codes = ArrayD::from_shape_vec(IxDyn(shape), codes.into_iter().map(|c| c as u32).collect())
        .map_err(|e| value_error(e.to_string()))?;
    Ok((table, codes))
}

/// Classify complex-index estimates by their nearest prototypes (paper section 6).
///
/// The paper's rule (the default) is the nearest prototype by Euclidean distance in the
/// (n, k) plane; k-NN voting, the Mahalanobis distance and a reject option are the
/// options of ``polarid classify`` (same code, same decisions). An estimate may have
/// several bands (colour cameras, docs/BANDS.md): it is then compared with each
/// prototype on the bands they have in common, as ``polarid classify`` compares a
/// target's fit rows.
///
/// Parameters
/// ----------
/// n, k : float or array_like
///     The estimates (broadcast together; e.g. the ``n`` and ``k`` of `fit_nk`).
/// library_or_model : str, os.PathLike or sequence, default "builtin"
///     ``"builtin"`` (39 materials at 650 nm, evaluated at other wavelengths from their
///     refractiveindex.info data), ``"builtin-rgb"`` (the same materials at 450, 550 and
///     650 nm) or ``"paper2007"`` (the paper's Table 1), a path to a model JSON
///     (``*.json``, written by ``polarid train``, single- or multi-band) or to a
///     library CSV (``name,n,k[,category][,wavelength_nm]``; a multi-band library has
///     one row per material and band), or a sequence of prototypes ``(class, n, k)`` /
///     ``(class, n, k, category)``. As ``polarid classify --library/--model``.
/// n_se, k_se, nk_corr : float or array_like, optional
///     Standard errors and correlation of the estimates (needed by the Mahalanobis
///     metric and the chi-square reject gate). NaN ``nk_corr`` counts as 0.
/// fit_status : str, array of str or of status codes, optional
///     Fit status per estimate (``fit_nk``'s ``status`` or ``status_code``); estimates
///     whose fit is not ``ok`` are not classified (``predicted = "unknown"``, status
///     ``fit_<status>``). Default: all ``ok``.
/// wavelength_nm : float or array_like, optional
///     The wavelength (nm) of each estimate (broadcast with ``n`` and ``k``; NaN: none),
///     as the fit rows' ``wavelength_nm`` (``polarid classify --wavelength-nm`` gives
///     rows without one a wavelength). The built-in libraries are evaluated at these
///     wavelengths (docs/CLASSIFY.md "Wavelength"); a multi-band model or library is
///     compared on the band of each estimate's wavelength (``no_common_band`` when it
///     has none). Default: no wavelength (compared with ``builtin``'s 650 nm values, or
///     with a single-band model or library as it is). How the prototypes were matched
///     to the wavelengths is issued as ``UserWarning`` (``polarid classify``'s warnings).
/// band_axis : int, optional
///     The axis of the broadcast inputs that holds the bands of one estimate (with
///     ``wavelength_nm`` giving each band's wavelength, e.g. ``n`` of shape (3, H, W),
///     ``wavelength_nm=[[[450]], [[550]], [[650]]]``, ``band_axis=0``): each estimate is
///     classified on all its bands at once (bands whose fit is not ``ok`` are left out)
///     and the results lack that axis.
/// film_shifts : array_like, optional
///     The fits' surface-layer shifts (the fits table's ``film1_dn, film1_dk, film2_dn,
///     film2_dk, film3_dn, film3_dk``), shape = the inputs' broadcast shape + (6,); NaN
///     where a fit has none. With them the bands of one estimate share ONE surface
///     layer, as in ``polarid classify`` (docs/BANDS.md); without, each band keeps the
///     allowance folded into its covariance.
/// rule : {"set", "nearest"}, optional
///     ``set``: every material consistent with the estimate at ``confidence`` (squared
///     Mahalanobis distance <= the chi-square quantile of 2 dof per band compared, in
///     (n, u = k^2) near k = 0; see docs/CLASSIFY.md): one -> it, several ->
///     ``"ambiguous"``, none -> ``"unknown"`` (status ``rejected``). ``nearest``: the
///     paper's nearest neighbour. Default: ``set`` when ``n_se`` and ``k_se`` are given
///     and no option of the nearest rule (``metric``, ``neighbours``, ``reject``,
///     ``max_distance``) is, else ``nearest`` (the set needs standard errors).
/// confidence : float, default 0.95
///     Confidence of the consistent set, in (0, 1). The set (``candidates``) is
///     returned under both rules when standard errors are given.
/// metric : {"euclidean", "mahalanobis"}, optional
///     Distance of the nearest rule (default euclidean); the set rule is Mahalanobis.
/// neighbours : int, default 1
///     Number of nearest prototypes that vote (ties go to the class with the nearest
///     member).
/// reject : float, optional
///     Chi-square gate probability p in (0, 1): ``unknown`` when the nearest prototype's
///     squared Mahalanobis distance exceeds the quantile (needs standard errors).
/// max_distance : float, optional
///     ``unknown`` when the nearest prototype is farther than this (metric units).
/// strings : bool, default False
///     Array input only: also return the names as str arrays (see Returns).
///
/// Returns
/// -------
/// dict
///     ``predicted`` (class name, ``"ambiguous"`` or ``"unknown"``), ``distance`` (to
///     the nearest prototype of the predicted class), ``runner_up`` (nearest other
///     class; ``""`` when there is none), ``runner_up_distance``, ``margin``
///     (``runner_up_distance - distance``), ``status`` (``ok``, ``ambiguous``,
///     ``rejected``, ``fit_<status>``, ``no_covariance``, ``invalid_estimate``,
///     ``no_common_band``), ``candidates`` (the consistent materials, best first),
///     ``n_candidates``, ``category`` (the candidates' common category, e.g.
///     ``"metal"``) and ``bands_used`` (the wavelengths compared with the nearest
///     prototype, ``;``-joined, e.g. ``"450;550;650"``; ``""`` without wavelengths):
///     strings, floats and a list of str for scalar input (``runner_up`` and
///     ``category`` are None when there is none).
///
///     Array input: arrays of the broadcast shape (without ``band_axis``), the names as
///     integer codes (uint32) into name tables, so that large maps hold no strings:
///     ``predicted_code`` and ``runner_up_code`` index ``class_names``
///     (``class_names[0] == ""``: no runner-up; then ``"unknown"``, ``"ambiguous"`` and
///     the classes), ``status_code`` indexes ``status_names``, ``candidates_code``
///     indexes ``candidates_names`` (the distinct ``;``-joined sets, ``""`` for none),
///     ``category_code`` indexes ``category_names``, ``bands_used_code`` indexes
///     ``bands_used_names``; ``distance``, ``runner_up_distance``, ``margin`` (NaN where
///     unclassified), ``n_candidates``. With ``strings=True`` also ``predicted``,
///     ``runner_up``, ``status``, ``candidates``, ``category``, ``bands_used`` as str
///     arrays (``names[code]``).
///
/// Raises
/// ------
/// ValueError
///     Unknown library name or unreadable file (the message of ``polarid classify``),
///     invalid prototypes, invalid options, a wavelength outside [100, 100000) nm,
///     shapes that do not broadcast.
/// FileNotFoundError
///     A library or model file that does not exist.
#[pyfunction]
#[pyo3(signature = (n, k, library_or_model = None, *, n_se = None, k_se = None, nk_corr = None, fit_status = None, wavelength_nm = None, film_shifts = None, band_axis = None, rule = None, confidence = 0.95, metric = None, neighbours = 1, reject = None, max_distance = None, strings = false))]
#[allow(clippy::too_many_arguments)]
pub fn classify<'py>(
    py: Python<'py>,
    n: F64Like<'py>,
    k: F64Like<'py>,
    library_or_model: Option<&Bound<'py, PyAny>>,
    n_se: Option<F64Like<'py>>,
    k_se: Option<F64Like<'py>>,
    nk_corr: Option<F64Like<'py>>,
    fit_status: Option<&Bound<'py, PyAny>>,
    wavelength_nm: Option<F64Like<'py>>,
    film_shifts: Option<F64Like<'py>>,
    band_axis: Option<isize>,
    rule: Option<&str>,
    confidence: f64,
    metric: Option<&str>,
    neighbours: usize,
    reject: Option<f64>,
    max_distance: Option<f64>,
    strings: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let nearest = (metric, neighbours, reject, max_distance);
    let rule = match rule {
        Some(r) => options::parse_rule(r).py_err()?,
        // The set rule needs standard errors and takes no nearest-rule option.
        None if n_se.is_some() && k_se.is_some() && nearest == (None, 1, None, None) => Rule::Set,
        None => Rule::Nearest,
    };
    let cfg = classifier_config(rule, confidence, nearest)?;
    let source = prototype_source(library_or_model)?;
    let (nv, kv) = (n.as_array(), k.as_array());
    let sn = n_se.as_ref().map(|x| x.as_array());
    let sk = k_se.as_ref().map(|x| x.as_array());
    let sc = nk_corr.as_ref().map(|x| x.as_array());
    let wv = wavelength_nm.as_ref().map(|x| x.as_array());
    let mut shapes: Vec<(&str, &[usize])> = vec![("n", nv.shape()), ("k", kv.shape())];
    for (name, v) in [
        ("n_se", &sn),
        ("k_se", &sk),
        ("nk_corr", &sc),
        ("wavelength_nm", &wv),
    ] {
        if let Some(v) = v {
            shapes.push((name, v.shape()));
        }
    }
    let shape = broadcast_shape(&shapes)?;
    let band = band_axis_of(band_axis, wv.is_some(), &shape)?;
    let flat = |name: &str, v: &ArrayViewD<'_, f64>| -> PyResult<Vec<f64>> {
        Ok(flat_bands(&broadcast_to(name, v, &shape)?, band))
    };
    let opt =
        |name: &str, v: &Option<ArrayViewD<'_, f64>>| v.as_ref().map(|v| flat(name, v)).transpose();
    let (status_words, status) = match fit_status {
        Some(s) => {
            let (w, c) = fit_statuses(s, &shape)?;
            let status = flat_bands(&c.view(), band)
                .iter()
                .map(|&c| w[c as usize])
                .collect();
            (w, Some(status))
        }
        None => (vec![FitStatus::Ok], None),
    };
    let inputs = Flat {
        bands: band.map_or(1, |a| shape[a]),
        n: flat("n", &nv)?,
        k: flat("k", &kv)?,
        n_se: opt("n_se", &sn)?,
        k_se: opt("k_se", &sk)?,
        corr: opt("nk_corr", &sc)?,
        wavelength: opt("wavelength_nm", &wv)?,
        film: film_columns(film_shifts.as_ref().map(|x| x.as_array()), &flat)?,
        status,
    };
    // The prototypes for these wavelengths, as `polarid classify` takes them.
    let (wavelengths, without) = distinct_wavelengths(inputs.wavelength.as_deref())?;
    let (protos, label, warnings) = py
        .detach(|| source.load_multi_for(&wavelengths, without))
        .py_err()?;
    warn_texts(py, warnings.iter().map(|w| w.0.as_str()))?;
    let clf = multi_classifier(protos, &label, cfg).py_err()?;
    let names = Names::new(&clf, &status_words);
    let res: Vec<(Row, Set)> = py.detach(|| {
        (0..inputs.n.len() / inputs.bands.max(1))
            .into_par_iter()
            .map(|i| names.row(&clf.classify_multi(&inputs.estimate(i))))
            .collect()
    });
    let out_shape: Vec<usize> = (0..shape.len())
        .filter(|&i| Some(i) != band)
        .map(|i| shape[i])
        .collect();
    if out_shape.is_empty() {
        scalar_result(py, &names, res.into_iter().next())
    } else {
        array_result(py, &names, res, &out_shape, strings)
    }
}

/// `band_axis` as an axis of inputs of `shape` (it needs `wavelength_nm`).
fn band_axis_of(
    band_axis: Option<isize>,
    wavelengths: bool,
    shape: &[usize],
) -> PyResult<Option<usize>> {
    let Some(a) = band_axis else {
        return Ok(None);
    };
    if !wavelengths {
        return Err(value_error(
            "band_axis needs wavelength_nm (the wavelength of every band)",
        ));
    }
    let nd = shape.len() as isize;
    if !(-nd..nd).contains(&a) {
        return Err(value_error(format!(
            "band_axis {a} is out of range for inputs of shape {}",
            fmt_shape(shape)
        )));
    }
    Ok(Some(if a < 0 { (a + nd) as usize } else { a as usize }))
}

/// The six surface-layer shift columns of `film_shifts` (last axis 6), each flattened
/// by `flat` like the other inputs.
fn film_columns(
    v: Option<ArrayViewD<'_, f64>>,
    flat: &dyn Fn(&str, &ArrayViewD<'_, f64>) -> PyResult<Vec<f64>>,
) -> PyResult<Option<Vec<Vec<f64>>>> {
    let Some(v) = v else {
        return Ok(None);
    };
    let nd = v.ndim();
    if nd == 0 || v.shape()[nd - 1] != 6 {
        return Err(value_error(format!(
            "film_shifts needs a last axis of length 6 (film1_dn, film1_dk, ..., \
             film3_dk), got shape {}",
            fmt_shape(v.shape())
        )));
    }
    (0..6)
        .map(|c| flat("film_shifts", &v.index_axis(ndarray::Axis(nd - 1), c)))
        .collect::<PyResult<Vec<_>>>()
        .map(Some)
}

/// The distinct wavelengths of `w` (checked as `--wavelength-nm`), in order of first
/// appearance, and the number of estimates without one (NaN).
fn distinct_wavelengths(w: Option<&[f64]>) -> PyResult<(Vec<f64>, usize)> {
    let (mut wavelengths, mut without) = (Vec::new(), 0usize);
    let mut seen: HashSet<u64> = HashSet::new();
    for &x in w.unwrap_or_default() {
        if x.is_nan() {
            without += 1;
        } else if seen.insert(x.to_bits()) {
            check_wavelength(x)?;
            wavelengths.push(x);
        }
    }
    Ok((wavelengths, without))
}

/// The inputs of `classify` flattened in estimate order (the bands of an estimate
/// consecutive).
struct Flat {
    bands: usize,
    n: Vec<f64>,
    k: Vec<f64>,
    n_se: Option<Vec<f64>>,
    k_se: Option<Vec<f64>>,
    corr: Option<Vec<f64>>,
    wavelength: Option<Vec<f64>>,
    film: Option<Vec<Vec<f64>>>,
    /// The fit status of every band (None: all ok).
    status: Option<Vec<FitStatus>>,
}

impl Flat {
    /// Estimate `i` on its bands.
    fn estimate(&self, i: usize) -> MultiEstimate {
        let band = |j: usize| {
            let cov = match (&self.n_se, &self.k_se) {
                (Some(a), Some(b)) => {
                    let c = self.corr.as_ref().map_or(0.0, |c| c[j]);
                    Cov2::from_se(a[j], b[j], if c.is_nan() { 0.0 } else { c })
                }
                _ => None,
            };
            let fit_status = self.status.as_ref().map_or(FitStatus::Ok, |c| c[j]);
            // Without shifts each band keeps the allowance folded into its covariance.
            let film = self.film.as_ref().and_then(|c| {
                let a = [[c[0][j], c[1][j]], [c[2][j], c[3][j]], [c[4][j], c[5][j]]];
                a.iter()
                    .flatten()
                    .all(|x| x.is_finite())
                    .then_some(FilmShifts(a))
            });
            EstimateBand {
                wavelength_nm: self
                    .wavelength
                    .as_ref()
                    .map(|w| w[j])
                    .filter(|w| !w.is_nan()),
                estimate: Estimate {
                    n: self.n[j],
                    k: self.k[j],
                    cov,
                    fit_status,
                },
                film,
            }
        };
        MultiEstimate {
            bands: (i * self.bands..(i + 1) * self.bands).map(band).collect(),
        }
    }
}

/// An estimate's candidates, category and bands used.
type Set = (Vec<String>, Option<String>, String);

/// The name tables of the results: classes (`""`, `"unknown"`, `"ambiguous"`, the
/// prototypes' classes) and decision statuses.
struct Names {
    classes: Vec<String>,
    labels: Vec<String>,
}

impl Names {
    fn new(clf: &Classifier, status_words: &[FitStatus]) -> Self {
        let mut classes: Vec<String> = vec![String::new(), UNKNOWN.to_string(), AMBIGUOUS.into()];
        for p in clf.prototypes() {
            if !classes.contains(&p.class) {
                classes.push(p.class.clone());
            }
        }
        let fixed = [
            "ok",
            "rejected",
            "no_covariance",
            "invalid_estimate",
            "ambiguous",
            "no_common_band",
        ];
        let labels = fixed
            .iter()
            .map(|s| s.to_string())
            .chain(status_words.iter().map(|w| format!("fit_{w}")))
            .collect();
        Self { classes, labels }
    }

    /// A decision as codes into the tables, and its set.
    fn row(&self, d: &Decision) -> (Row, Set) {
        let code = |names: &[String], s: &str, other: u32| {
            names
                .iter()
                .position(|c| c == s)
                .map_or(other, |i| i as u32)
        };
        let ci = |c: &str| code(&self.classes, c, 1);
        let nan_unless = |b: bool, x: f64| if b { x } else { f64::NAN };
        let row = (
            ci(&d.predicted),
            nan_unless(d.nearest.is_some(), d.distance),
            d.runner_up.as_deref().map_or(0, ci),
            nan_unless(d.runner_up.is_some(), d.runner_up_distance),
            d.margin,
            code(&self.labels, &d.status.label(), 3),
        );
        let set = (
            d.candidates.iter().map(|c| c.class.clone()).collect(),
            d.set_category.clone(),
            d.bands_used_text(),
        );
        (row, set)
    }
}

/// The result of a scalar estimate: names, numbers and a list of candidates.
fn scalar_result<'py>(
    py: Python<'py>,
    names: &Names,
    res: Option<(Row, Set)>,
) -> PyResult<Bound<'py, PyDict>> {
    let (r, (cands, cat, bands)) =
        res.unwrap_or(((1, f64::NAN, 0, f64::NAN, f64::NAN, 3), Default::default()));
    let out = PyDict::new(py);
    out.set_item("predicted", &names.classes[r.0 as usize])?;
    out.set_item("distance", r.1)?;
    out.set_item(
        "runner_up",
        (r.2 != 0).then(|| names.classes[r.2 as usize].clone()),
    )?;
    out.set_item("runner_up_distance", r.3)?;
    out.set_item("margin", r.4)?;
    out.set_item("status", &names.labels[r.5 as usize])?;
    out.set_item("n_candidates", cands.len())?;
    out.set_item("candidates", cands)?;
    out.set_item("category", cat)?;
    out.set_item("bands_used", bands)?;
    Ok(out)
}

/// The result of array estimates (`shape`): numbers and codes into name tables (and
/// with `strings` the names).
fn array_result<'py>(
    py: Python<'py>,
    names: &Names,
    res: Vec<(Row, Set)>,
    shape: &[usize],
    strings: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (res, sets): (Vec<Row>, Vec<Set>) = res.into_iter().unzip();
    let dim = IxDyn(shape);
    let arr = |v: Vec<u32>| {
        ArrayD::from_shape_vec(dim.clone(), v).map_err(|e| value_error(e.to_string()))
    };
    let fl = |f: fn(&Row) -> f64| shaped(py, shape, res.iter().map(f).collect());
    // Candidates (`;`-joined), categories and bands used: codes into tables of distinct
    // values.
    let (mut joined, mut cats, mut bands) = Default::default();
    let (mut jc, mut cc, mut bc, mut nc) = (vec![], vec![], vec![], vec![]);
    for (cands, cat, used) in &sets {
        jc.push(NameTable::code(&mut joined, &cands.join(";")));
        cc.push(NameTable::code(&mut cats, cat.as_deref().unwrap_or("")));
        bc.push(NameTable::code(&mut bands, used));
        nc.push(cands.len() as u32);
    }
    let class_refs: Vec<&str> = names.classes.iter().map(String::as_str).collect();
    let label_refs: Vec<&str> = names.labels.iter().map(String::as_str).collect();
    let coded: [(&str, &str, Vec<&str>, ArrayD<u32>); 6] = [
        (
            "predicted",
            "class_names",
            class_refs.clone(),
            arr(res.iter().map(|r| r.0).collect())?,
        ),
        (
            "runner_up",
            "",
            class_refs,
            arr(res.iter().map(|r| r.2).collect())?,
        ),
        (
            "status",
            "status_names",
            label_refs,
            arr(res.iter().map(|r| r.5).collect())?,
        ),
        ("candidates", "candidates_names", joined.refs(), arr(jc)?),
        ("category", "category_names", cats.refs(), arr(cc)?),
        ("bands_used", "bands_used_names", bands.refs(), arr(bc)?),
    ];
    let out = PyDict::new(py);
    if strings {
        for (name, _, table, codes) in &coded {
            out.set_item(*name, str_array(py, table, codes.clone())?)?;
        }
    }
    out.set_item("distance", fl(|r| r.1)?)?;
    out.set_item("runner_up_distance", fl(|r| r.3)?)?;
    out.set_item("margin", fl(|r| r.4)?)?;
    for (name, table_name, table, codes) in coded {
        out.set_item(format!("{name}_code"), to_numpy(py, codes))?;
        if !table_name.is_empty() {
            out.set_item(table_name, table)?;
        }
    }
    out.set_item("n_candidates", shaped(py, shape, nc)?)?;
    Ok(out)
}

/// One estimate's numbers: predicted code, distance, runner-up code, runner-up
/// distance, margin, status code.
type Row = (u32, f64, u32, f64, f64, u32);

/// Classify every target of a fits CSV exactly as ``polarid classify`` does.
///
/// The fits CSV written by ``polarid fit`` (or ``fit_table``'s columns saved as one);
/// the rows of a target with a ``wavelength_nm`` (one per band, colour cameras) are
/// classified together on all their bands (docs/BANDS.md). Same code as ``polarid
/// classify FITS --library LIB`` / ``--model MODEL.json`` (its CSV holds the very same
/// values); its warnings (how the prototypes were matched to the fits' wavelengths) are
/// issued as ``UserWarning``. The GIL is released.
///
/// Parameters
/// ----------
/// fits : str or os.PathLike
///     The fits CSV.
/// library_or_model : str, os.PathLike or sequence, default "builtin"
///     As `classify`: ``"builtin"``, ``"builtin-rgb"``, ``"paper2007"``, a model JSON
///     (``*.json``), a library CSV (single- or multi-band) or a sequence of prototypes.
/// wavelength_nm : float, optional
///     The wavelength (nm) of the fit rows that carry no ``wavelength_nm``
///     (``--wavelength-nm``; docs/CLASSIFY.md "Wavelength").
/// rule : {"set", "nearest"}, default "set"
///     The decision rule (``--rule``; the set rule needs the fits' standard errors).
/// confidence : float, default 0.95
///     Confidence of the consistent set (``--confidence``).
/// metric : {"euclidean", "mahalanobis"}, optional
///     Nearest rule: the distance (``--metric``, default euclidean).
/// neighbours : int, default 1
///     Nearest rule: the prototypes that vote (``--k``).
/// reject : float, optional
///     Nearest rule: chi-square gate probability (``--reject``).
/// max_distance : float, optional
///     Nearest rule: farthest accepted prototype (``--max-distance``).
///
/// Returns
/// -------
/// dict
///     The columns of the classification CSV, in its order, one list element per
///     target: ``target``, ``class`` (str or None), ``predicted``, ``distance`` (float
///     or None), ``runner_up`` (str or None), ``runner_up_distance``, ``status``,
///     ``candidates`` (list of str, best first), ``bands_used`` (str, e.g.
///     ``"450;550;650"``; only when some target has wavelengths, as in the CSV),
///     ``margin``, ``nearest``, ``category``, ``metric``, ``rule``, ``confidence``,
///     ``gate``, ``votes`` (int or None), ``reason``.
///
/// Raises
/// ------
/// FileNotFoundError
///     A missing fits, library or model file.
/// ValueError
///     An invalid fits CSV, library, model or option (the messages of ``polarid
///     classify``).
#[pyfunction]
#[pyo3(signature = (fits, library_or_model = None, *, wavelength_nm = None, rule = "set", confidence = 0.95, metric = None, neighbours = 1, reject = None, max_distance = None))]
#[allow(clippy::too_many_arguments)]
pub fn classify_table<'py>(
    py: Python<'py>,
    fits: &Bound<'py, PyAny>,
    library_or_model: Option<&Bound<'py, PyAny>>,
    wavelength_nm: Option<f64>,
    rule: &str,
    confidence: f64,
    metric: Option<&str>,
    neighbours: usize,
    reject: Option<f64>,
    max_distance: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let nearest = (metric, neighbours, reject, max_distance);
    let classifier = classifier_config(options::parse_rule(rule).py_err()?, confidence, nearest)?;
    let cfg = ClassifyConfig {
        classifier,
        wavelength_nm,
        ..ClassifyConfig::default()
    };
    cfg.validate().py_err()?;
    let source = prototype_source(library_or_model)?;
    let path = path_arg(fits)?;
    let out = py
        .detach(|| {
            let rows = read_fits(&path)?;
            pipe::classify(Path::new(&path), &rows, &source, &cfg)
        })
        .py_err()?;
    warn_texts(py, out.warnings.iter().map(|w| w.0.as_str()))?;
    let rows = &out.rows;
    let d = PyDict::new(py);
    let finite = |x: Option<f64>| x.filter(|v| !v.is_nan());
    macro_rules! col {
        ($name:literal, $f:expr) => {
            d.set_item($name, PyList::new(py, rows.iter().map($f))?)?;
        };
    }
    col!("target", |r| r.target.clone());
    col!("class", |r| r.class.clone());
    col!("predicted", |r| r.predicted.clone());
    col!("distance", |r| finite(r.distance));
    col!("runner_up", |r| r.runner_up.clone());
    col!("runner_up_distance", |r| finite(r.runner_up_distance));
    col!("status", |r| r.status.clone());
    col!("candidates", |r| r.candidates.clone());
    if rows.iter().any(|r| !r.bands_used.is_empty()) {
        col!("bands_used", |r| r.bands_used.clone());
    }
    col!("margin", |r| finite(r.margin));
    col!("nearest", |r| r.nearest.clone());
    col!("category", |r| r.category.clone());
    col!("metric", |r| r.metric.clone());
    col!("rule", |r| r.rule.clone());
    col!("confidence", |r| finite(r.confidence));
    col!("gate", |r| finite(r.gate));
    col!("votes", |r| r.votes);
    col!("reason", |r| r.reason.clone());
    Ok(d)
}
