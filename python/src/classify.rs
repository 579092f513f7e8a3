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

use std::collections::{HashMap, HashSet};
use std::path::Path;

use ndarray::{ArrayD, ArrayViewD, IxDyn};
use polarid_core::FitStatus;
use polarid_core::classify::{
    AMBIGUOUS, ClassifierConfig, Cov2, Estimate, EstimateBand, MultiEstimate, Prototype, Rule,
    UNKNOWN,
};
use polarid_core::systematic::FilmShifts;
use polarid_pipeline::classify::{
    self as pipe, ClassifyConfig, PrototypeSource, multi_classifier, read_fits,
};
use polarid_pipeline::options::{self, ClassifierOptions};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use rayon::prelude::*;

use crate::arrays::{F64Like, broadcast_shape, broadcast_to, fmt_shape, str_array, to_numpy};
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

/// The classifier settings of `rule` (`set_rule`) and the nearest rule's options,
/// checked as `polarid classify` checks them (errors name the option).
fn classifier_config(
    set_rule: bool,
    confidence: f64,
    metric: Option<&str>,
    neighbours: usize,
    reject: Option<f64>,
    max_distance: Option<f64>,
) -> PyResult<ClassifierConfig> {
    ClassifierOptions {
        rule: if set_rule { Rule::Set } else { Rule::Nearest },
        confidence,
        metric: metric.map(options::parse_metric).transpose().py_err()?,
        neighbours,
        reject,
        max_distance,
    }
    .config()
    .py_err()
}

/// `rule` as the set rule (`true`) or the nearest rule.
fn parse_rule(rule: &str) -> PyResult<bool> {
    Ok(options::parse_rule(rule).py_err()? == Rule::Set)
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
    let set_rule = match rule {
        Some(r) => parse_rule(r)?,
        None => {
            n_se.is_some()
                && k_se.is_some()
                && metric.is_none()
                && neighbours == 1
                && reject.is_none()
                && max_distance.is_none()
        }
    };
    let cfg = classifier_config(
        set_rule,
        confidence,
        metric,
        neighbours,
        reject,
        max_distance,
    )?;
    let source = prototype_source(library_or_model)?;

    // Broadcast the numeric inputs.
    let nv = n.as_array();
    let kv = k.as_array();
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
    // The band axis, and the shape of the result.
    let band = match band_axis {
        None => None,
        Some(_) if wv.is_none() => {
            return Err(value_error(
                "band_axis needs wavelength_nm (the wavelength of every band)",
            ));
        }
        Some(a) => {
            let nd = shape.len() as isize;
            if !(-nd..nd).contains(&a) {
                return Err(value_error(format!(
                    "band_axis {a} is out of range for inputs of shape {}",
                    fmt_shape(&shape)
                )));
            }
            Some(if a < 0 { (a + nd) as usize } else { a as usize })
        }
    };
    let nb = band.map_or(1, |a| shape[a]);
    let out_shape: Vec<usize> = match band {
        Some(a) => shape
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != a)
            .map(|(_, &d)| d)
            .collect(),
        None => shape.clone(),
    };
    let flat = |name: &str, v: &ArrayViewD<'_, f64>| -> PyResult<Vec<f64>> {
        Ok(flat_bands(&broadcast_to(name, v, &shape)?, band))
    };
    let fn_ = flat("n", &nv)?;
    let fk = flat("k", &kv)?;
    let fsn = sn.as_ref().map(|v| flat("n_se", v)).transpose()?;
    let fsk = sk.as_ref().map(|v| flat("k_se", v)).transpose()?;
    let fsc = sc.as_ref().map(|v| flat("nk_corr", v)).transpose()?;
    let fw = wv.as_ref().map(|v| flat("wavelength_nm", v)).transpose()?;
    // The six surface-layer shift columns, each flattened like the other inputs.
    let ffilm: Option<Vec<Vec<f64>>> = match film_shifts.as_ref().map(|x| x.as_array()) {
        None => None,
        Some(v) => {
            let nd = v.ndim();
            if nd == 0 || v.shape()[nd - 1] != 6 {
                return Err(value_error(format!(
                    "film_shifts needs a last axis of length 6 (film1_dn, film1_dk, ..., \
                     film3_dk), got shape {}",
                    fmt_shape(v.shape())
                )));
            }
            let mut cols = Vec::with_capacity(6);
            for c in 0..6 {
                let comp = v.index_axis(ndarray::Axis(nd - 1), c);
                cols.push(flat("film_shifts", &comp)?);
            }
            Some(cols)
        }
    };
    let (status_words, status_codes) = match fit_status {
        Some(s) => {
            let (w, c) = fit_statuses(s, &shape)?;
            (w, Some(c))
        }
        None => (vec![FitStatus::Ok], None),
    };
    let fst: Option<Vec<u32>> = status_codes.map(|c| flat_bands(&c.view(), band));

    // The prototypes for these wavelengths, as `polarid classify` takes them.
    let mut wavelengths: Vec<f64> = Vec::new();
    let mut without = 0usize;
    if let Some(w) = &fw {
        let mut seen: HashSet<u64> = HashSet::new();
        for &x in w {
            if x.is_nan() {
                without += 1;
            } else if seen.insert(x.to_bits()) {
                check_wavelength(x)?;
                wavelengths.push(x);
            }
        }
    }
    let (protos, label, warnings) = py
        .detach(|| source.load_multi_for(&wavelengths, without))
        .py_err()?;
    warn_texts(py, warnings.iter().map(|w| w.0.as_str()))?;
    let clf = multi_classifier(protos, &label, cfg).py_err()?;

    // Name tables: classes (and "unknown", ""), decision statuses.
    let mut classes: Vec<String> = vec![String::new(), UNKNOWN.to_string(), AMBIGUOUS.into()];
    for p in clf.prototypes() {
        if !classes.contains(&p.class) {
            classes.push(p.class.clone());
        }
    }
    let class_idx: HashMap<&str, u32> = classes
        .iter()
        .enumerate()
        .map(|(i, c)| (c.as_str(), i as u32))
        .collect();
    let mut labels: Vec<String> = [
        "ok",
        "rejected",
        "no_covariance",
        "invalid_estimate",
        "ambiguous",
        "no_common_band",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for w in &status_words {
        labels.push(format!("fit_{w}"));
    }
    let label_idx: HashMap<&str, u32> = labels
        .iter()
        .enumerate()
        .map(|(i, c)| (c.as_str(), i as u32))
        .collect();

    let len = fn_.len() / nb.max(1);
    // Candidates, category, bands used.
    type Set = (Vec<String>, Option<String>, String);
    let res: Vec<(Row, Set)> = py.detach(|| {
        (0..len)
            .into_par_iter()
            .map(|i| {
                let est = MultiEstimate {
                    bands: (i * nb..(i + 1) * nb)
                        .map(|j| {
                            let cov = match (&fsn, &fsk) {
                                (Some(a), Some(b)) => {
                                    let c = fsc.as_ref().map_or(0.0, |c| c[j]);
                                    Cov2::from_se(a[j], b[j], if c.is_nan() { 0.0 } else { c })
                                }
                                _ => None,
                            };
                            let fit_status = match &fst {
                                Some(c) => status_words[c[j] as usize],
                                None => FitStatus::Ok,
                            };
                            EstimateBand {
                                wavelength_nm: fw.as_ref().map(|w| w[j]).filter(|w| !w.is_nan()),
                                estimate: Estimate {
                                    n: fn_[j],
                                    k: fk[j],
                                    cov,
                                    fit_status,
                                },
                                // Without shifts each band keeps the allowance folded
                                // into its covariance.
                                film: ffilm.as_ref().and_then(|c| {
                                    let a = [
                                        [c[0][j], c[1][j]],
                                        [c[2][j], c[3][j]],
                                        [c[4][j], c[5][j]],
                                    ];
                                    a.iter()
                                        .flatten()
                                        .all(|x| x.is_finite())
                                        .then_some(FilmShifts(a))
                                }),
                            }
                        })
                        .collect(),
                };
                let d = clf.classify_multi(&est);
                let ci = |c: &str| class_idx.get(c).copied().unwrap_or(1);
                let ru = d.runner_up.as_deref().map_or(0, ci);
                let set = (
                    d.candidates.iter().map(|c| c.class.clone()).collect(),
                    d.set_category.clone(),
                    d.bands_used_text(),
                );
                (
                    (
                        ci(&d.predicted),
                        if d.nearest.is_some() {
                            d.distance
                        } else {
                            f64::NAN
                        },
                        ru,
                        if d.runner_up.is_some() {
                            d.runner_up_distance
                        } else {
                            f64::NAN
                        },
                        d.margin,
                        label_idx
                            .get(d.status.label().as_str())
                            .copied()
                            .unwrap_or(3),
                    ),
                    set,
                )
            })
            .collect()
    });
    let (res, sets): (Vec<Row>, Vec<Set>) = res.into_iter().unzip();

    let out = PyDict::new(py);
    if out_shape.is_empty() {
        let r = res
            .first()
            .copied()
            .unwrap_or((1, f64::NAN, 0, f64::NAN, f64::NAN, 3));
        out.set_item("predicted", &classes[r.0 as usize])?;
        out.set_item("distance", r.1)?;
        out.set_item(
            "runner_up",
            (r.2 != 0).then(|| classes[r.2 as usize].clone()),
        )?;
        out.set_item("runner_up_distance", r.3)?;
        out.set_item("margin", r.4)?;
        out.set_item("status", &labels[r.5 as usize])?;
        let (cands, cat, bands) = sets.into_iter().next().unwrap_or_default();
        out.set_item("n_candidates", cands.len())?;
        out.set_item("candidates", cands)?;
        out.set_item("category", cat)?;
        out.set_item("bands_used", bands)?;
        return Ok(out);
    }
    let dim = IxDyn(&out_shape);
    let u = |f: fn(&Row) -> u32| -> PyResult<ArrayD<u32>> {
        ArrayD::from_shape_vec(dim.clone(), res.iter().map(f).collect())
            .map_err(|e| value_error(e.to_string()))
    };
    let fl = |f: fn(&Row) -> f64| -> PyResult<ArrayD<f64>> {
        ArrayD::from_shape_vec(dim.clone(), res.iter().map(f).collect())
            .map_err(|e| value_error(e.to_string()))
    };
    let class_refs: Vec<&str> = classes.iter().map(String::as_str).collect();
    let label_refs: Vec<&str> = labels.iter().map(String::as_str).collect();
    // Candidates (`;`-joined), categories and bands used: codes into tables of distinct
    // values.
    let mut joined = NameTable::default();
    let mut cats = NameTable::default();
    let mut bands = NameTable::default();
    let mut jc = Vec::with_capacity(sets.len());
    let mut cc = Vec::with_capacity(sets.len());
    let mut bc = Vec::with_capacity(sets.len());
    let mut nc = Vec::with_capacity(sets.len());
    for (cands, cat, used) in &sets {
        jc.push(joined.code(&cands.join(";")));
        cc.push(cats.code(cat.as_deref().unwrap_or("")));
        bc.push(bands.code(used));
        nc.push(cands.len() as u32);
    }
    drop(sets);
    let arr = |v: Vec<u32>| {
        ArrayD::from_shape_vec(dim.clone(), v).map_err(|e| value_error(e.to_string()))
    };
    let jr = joined.refs();
    let cr = cats.refs();
    let br = bands.refs();
    let (pc, rc, sc, jcs, ccs, bcs) = (
        u(|r| r.0)?,
        u(|r| r.2)?,
        u(|r| r.5)?,
        arr(jc)?,
        arr(cc)?,
        arr(bc)?,
    );
    if strings {
        out.set_item("predicted", str_array(py, &class_refs, pc.clone())?)?;
        out.set_item("runner_up", str_array(py, &class_refs, rc.clone())?)?;
        out.set_item("status", str_array(py, &label_refs, sc.clone())?)?;
        out.set_item("candidates", str_array(py, &jr, jcs.clone())?)?;
        out.set_item("category", str_array(py, &cr, ccs.clone())?)?;
        out.set_item("bands_used", str_array(py, &br, bcs.clone())?)?;
    }
    out.set_item("distance", to_numpy(py, fl(|r| r.1)?))?;
    out.set_item("runner_up_distance", to_numpy(py, fl(|r| r.3)?))?;
    out.set_item("margin", to_numpy(py, fl(|r| r.4)?))?;
    out.set_item("predicted_code", to_numpy(py, pc))?;
    out.set_item("runner_up_code", to_numpy(py, rc))?;
    out.set_item("class_names", class_refs)?;
    out.set_item("status_code", to_numpy(py, sc))?;
    out.set_item("status_names", label_refs)?;
    out.set_item("candidates_code", to_numpy(py, jcs))?;
    out.set_item("candidates_names", jr)?;
    out.set_item("category_code", to_numpy(py, ccs))?;
    out.set_item("category_names", cr)?;
    out.set_item("bands_used_code", to_numpy(py, bcs))?;
    out.set_item("bands_used_names", br)?;
    out.set_item("n_candidates", to_numpy(py, arr(nc)?))?;
    Ok(out)
}

/// One estimate's numbers: predicted code, distance, runner-up code, runner-up
/// distance, margin, status code.
type Row = (u32, f64, u32, f64, f64, u32);

/// Distinct strings and their codes (`""` is code 0).
struct NameTable {
    names: Vec<String>,
    index: HashMap<String, u32>,
}

impl Default for NameTable {
    fn default() -> Self {
        Self {
            names: vec![String::new()],
            index: HashMap::from([(String::new(), 0)]),
        }
    }
}

impl NameTable {
    /// The code of `s`, added when new.
    fn code(&mut self, s: &str) -> u32 {
        if let Some(&i) = self.index.get(s) {
            return i;
        }
        self.names.push(s.to_string());
        let i = (self.names.len() - 1) as u32;
        self.index.insert(s.to_string(), i);
        i
    }

    fn refs(&self) -> Vec<&str> {
        self.names.iter().map(String::as_str).collect()
    }
}

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
    let classifier = classifier_config(
        parse_rule(rule)?,
        confidence,
        metric,
        neighbours,
        reject,
        max_distance,
    )?;
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
