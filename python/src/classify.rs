//! Material classification of `(n, k)` estimates (paper section 6) against a library, a
//! trained model or a list of prototypes (`polarid_core::classify::Classifier`).

use std::collections::HashMap;

use ndarray::{ArrayD, ArrayViewD, IxDyn};
use polarid_core::FitStatus;
use polarid_core::classify::{
    AMBIGUOUS, ClassifierConfig, Cov2, Estimate, Metric, Prototype, Reject, UNKNOWN,
};
use polarid_io::library::Library;
use polarid_pipeline::classify::{PrototypeSource, classifier};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use rayon::prelude::*;

use crate::arrays::{F64Like, broadcast_shape, broadcast_to, fmt_shape, str_array, to_numpy};
use crate::errors::{PyResultExt, value_error};

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(classify, m)?)?;
    Ok(())
}

/// Prototypes from a library name, a file path (`.json`: a model of `polarid train`;
/// otherwise a library CSV) or a sequence of `(class, n, k[, category])`.
fn prototypes(obj: &Bound<'_, PyAny>) -> PyResult<(Vec<Prototype>, String)> {
    let py = obj.py();
    let spec: Option<String> = if obj.is_instance_of::<PyString>() {
        Some(obj.extract()?)
    } else if obj.hasattr("__fspath__")? {
        Some(py.import("os")?.call_method1("fspath", (obj,))?.extract()?)
    } else {
        None
    };
    if let Some(spec) = spec {
        let source = if spec.to_ascii_lowercase().ends_with(".json") {
            PrototypeSource::Model(spec.into())
        } else {
            PrototypeSource::Library(spec)
        };
        return source.load().py_err();
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
    Ok((out, "the prototypes".into()))
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
/// options of ``polarid classify`` (same code, same decisions).
///
/// Parameters
/// ----------
/// n, k : float or array_like
///     The estimates (broadcast together; e.g. the ``n`` and ``k`` of `fit_nk`).
/// library_or_model : str, os.PathLike or sequence, default "builtin"
///     ``"builtin"`` (39 materials at 650 nm) or ``"paper2007"`` (the paper's Table 1),
///     a path to a model JSON (``*.json``, written by ``polarid train``) or to a
///     library CSV (``name,n,k[,category]``), or a sequence of prototypes
///     ``(class, n, k)`` / ``(class, n, k, category)``.
/// n_se, k_se, nk_corr : float or array_like, optional
///     Standard errors and correlation of the estimates (needed by the Mahalanobis
///     metric and the chi-square reject gate). NaN ``nk_corr`` counts as 0.
/// fit_status : str, array of str or of status codes, optional
///     Fit status per estimate (``fit_nk``'s ``status`` or ``status_code``); estimates
///     whose fit is not ``ok`` are not classified (``predicted = "unknown"``, status
///     ``fit_<status>``). Default: all ``ok``.
/// rule : {"set", "nearest"}, optional
///     ``set``: every material consistent with the estimate at ``confidence`` (squared
///     Mahalanobis distance <= -2 ln(1 - confidence), in (n, u = k^2) near k = 0; see
///     docs/CLASSIFY.md): one -> it, several -> ``"ambiguous"``, none -> ``"unknown"``
///     (status ``rejected``). ``nearest``: the paper's nearest neighbour. Default: ``set``
///     when ``n_se`` and ``k_se`` are given and no option of the nearest rule
///     (``metric``, ``neighbours``, ``reject``, ``max_distance``) is, else ``nearest``
///     (the set needs standard errors).
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
///     squared Mahalanobis distance exceeds the 2-dof quantile (needs standard errors).
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
///     ``rejected``, ``fit_<status>``, ``no_covariance``, ``invalid_estimate``),
///     ``candidates`` (the consistent materials, best first), ``n_candidates`` and
///     ``category`` (the candidates' common category, e.g. ``"metal"``): strings,
///     floats and a list of str for scalar input (``runner_up`` and ``category`` are
///     None when there is none).
///
///     Array input: arrays of the broadcast shape, the names as integer codes (uint32)
///     into name tables, so that large maps hold no strings: ``predicted_code`` and
///     ``runner_up_code`` index ``class_names`` (``class_names[0] == ""``: no runner-up;
///     then ``"unknown"``, ``"ambiguous"`` and the classes), ``status_code`` indexes
///     ``status_names``, ``candidates_code`` indexes ``candidates_names`` (the distinct
///     ``;``-joined sets, ``""`` for none), ``category_code`` indexes
///     ``category_names``; ``distance``, ``runner_up_distance``, ``margin`` (NaN where
///     unclassified), ``n_candidates``. With ``strings=True`` also ``predicted``,
///     ``runner_up``, ``status``, ``candidates``, ``category`` as str arrays
///     (``names[code]``).
///
/// Raises
/// ------
/// ValueError
///     Unknown library name or unreadable file (the message of ``polarid classify``),
///     invalid prototypes, invalid options, shapes that do not broadcast.
/// FileNotFoundError
///     A library or model file that does not exist.
#[pyfunction]
#[pyo3(signature = (n, k, library_or_model = None, *, n_se = None, k_se = None, nk_corr = None, fit_status = None, rule = None, confidence = 0.95, metric = None, neighbours = 1, reject = None, max_distance = None, strings = false))]
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
    rule: Option<&str>,
    confidence: f64,
    metric: Option<&str>,
    neighbours: usize,
    reject: Option<f64>,
    max_distance: Option<f64>,
    strings: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let set_rule = match rule {
        Some("set") => true,
        Some("nearest") => false,
        None => {
            n_se.is_some()
                && k_se.is_some()
                && metric.is_none()
                && neighbours == 1
                && reject.is_none()
                && max_distance.is_none()
        }
        Some(r) => {
            return Err(value_error(format!(
                "rule must be \"set\" or \"nearest\", got {r:?}"
            )));
        }
    };
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(value_error(format!(
            "confidence must be in (0, 1), got {confidence}"
        )));
    }
    if set_rule
        && (metric == Some("euclidean")
            || neighbours != 1
            || reject.is_some()
            || max_distance.is_some())
    {
        return Err(value_error(
            "metric=\"euclidean\", neighbours, reject and max_distance are options of \
             rule=\"nearest\"; the set rule uses the Mahalanobis distance and rejects by \
             confidence",
        ));
    }
    let metric = match metric.unwrap_or("euclidean") {
        "euclidean" => Metric::Euclidean,
        "mahalanobis" => Metric::Mahalanobis,
        metric => {
            return Err(value_error(format!(
                "metric must be \"euclidean\" or \"mahalanobis\", got {metric:?}"
            )));
        }
    };
    let reject = match (reject, max_distance) {
        (Some(_), Some(_)) => {
            return Err(value_error("give reject or max_distance, not both"));
        }
        (Some(p), None) => Reject::Chi2 { p },
        (None, Some(d)) => Reject::MaxDistance(d),
        (None, None) => Reject::Never,
    };
    let cfg = if set_rule {
        ClassifierConfig::set(confidence)
    } else {
        ClassifierConfig {
            metric,
            k: neighbours,
            reject,
            confidence,
            ..ClassifierConfig::default()
        }
    };
    cfg.validate()
        .map_err(|e| value_error(format!("invalid classifier option: {e}")))?;
    let (protos, label) = match library_or_model {
        Some(o) => prototypes(o)?,
        None => {
            let lib = Library::builtin().py_err()?;
            (lib.prototypes(), "library builtin".into())
        }
    };
    let clf = classifier(protos, &label, cfg).py_err()?;

    // Broadcast the numeric inputs.
    let nv = n.as_array();
    let kv = k.as_array();
    let sn = n_se.as_ref().map(|x| x.as_array());
    let sk = k_se.as_ref().map(|x| x.as_array());
    let sc = nk_corr.as_ref().map(|x| x.as_array());
    let mut shapes: Vec<(&str, &[usize])> = vec![("n", nv.shape()), ("k", kv.shape())];
    for (name, v) in [("n_se", &sn), ("k_se", &sk), ("nk_corr", &sc)] {
        if let Some(v) = v {
            shapes.push((name, v.shape()));
        }
    }
    let shape = broadcast_shape(&shapes)?;
    let bn = broadcast_to("n", &nv, &shape)?;
    let bk = broadcast_to("k", &kv, &shape)?;
    let bsn = sn
        .as_ref()
        .map(|v| broadcast_to("n_se", v, &shape))
        .transpose()?;
    let bsk = sk
        .as_ref()
        .map(|v| broadcast_to("k_se", v, &shape))
        .transpose()?;
    let bsc = sc
        .as_ref()
        .map(|v| broadcast_to("nk_corr", v, &shape))
        .transpose()?;
    let (status_words, status_codes) = match fit_status {
        Some(s) => {
            let (w, c) = fit_statuses(s, &shape)?;
            (w, Some(c))
        }
        None => (vec![FitStatus::Ok], None),
    };

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

    let flat = |v: &ArrayViewD<'_, f64>| -> Vec<f64> { v.iter().copied().collect() };
    let (fn_, fk) = (flat(&bn), flat(&bk));
    let fsn = bsn.as_ref().map(flat);
    let fsk = bsk.as_ref().map(flat);
    let fsc = bsc.as_ref().map(flat);
    let fst: Option<Vec<u32>> = status_codes.map(|c| c.iter().copied().collect());
    let len = fn_.len();
    type Set = (Vec<String>, Option<String>);
    let res: Vec<((u32, f64, u32, f64, f64, u32), Set)> = py.detach(|| {
        (0..len)
            .into_par_iter()
            .map(|i| {
                let cov = match (&fsn, &fsk) {
                    (Some(a), Some(b)) => {
                        let c = fsc.as_ref().map_or(0.0, |c| c[i]);
                        Cov2::from_se(a[i], b[i], if c.is_nan() { 0.0 } else { c })
                    }
                    _ => None,
                };
                let fit_status = match &fst {
                    Some(c) => status_words[c[i] as usize],
                    None => FitStatus::Ok,
                };
                let d = clf.classify(&Estimate {
                    n: fn_[i],
                    k: fk[i],
                    cov,
                    fit_status,
                });
                let ci = |c: &str| class_idx.get(c).copied().unwrap_or(1);
                let ru = d.runner_up.as_deref().map_or(0, ci);
                let set = (
                    d.candidates.iter().map(|c| c.class.clone()).collect(),
                    d.set_category.clone(),
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
    let (res, sets): (Vec<(u32, f64, u32, f64, f64, u32)>, Vec<Set>) = res.into_iter().unzip();

    let out = PyDict::new(py);
    if shape.is_empty() {
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
        let (cands, cat) = sets.into_iter().next().unwrap_or_default();
        out.set_item("n_candidates", cands.len())?;
        out.set_item("candidates", cands)?;
        out.set_item("category", cat)?;
        return Ok(out);
    }
    let dim = IxDyn(&shape);
    type Row = (u32, f64, u32, f64, f64, u32);
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
    // Candidates (`;`-joined) and categories: codes into tables of distinct values.
    let mut joined: Vec<String> = vec![String::new()];
    let mut cats: Vec<String> = vec![String::new()];
    let mut joined_idx: HashMap<String, u32> = HashMap::from([(String::new(), 0)]);
    let mut cats_idx: HashMap<String, u32> = HashMap::from([(String::new(), 0)]);
    let mut jc = Vec::with_capacity(sets.len());
    let mut cc = Vec::with_capacity(sets.len());
    let mut nc = Vec::with_capacity(sets.len());
    for (cands, cat) in &sets {
        let j = cands.join(";");
        let ji = *joined_idx.entry(j).or_insert_with_key(|j| {
            joined.push(j.clone());
            (joined.len() - 1) as u32
        });
        let c = cat.as_deref().unwrap_or("");
        let ki = match cats_idx.get(c) {
            Some(&i) => i,
            None => {
                cats.push(c.to_string());
                cats_idx.insert(c.to_string(), (cats.len() - 1) as u32);
                (cats.len() - 1) as u32
            }
        };
        jc.push(ji);
        cc.push(ki);
        nc.push(cands.len() as u32);
    }
    drop(sets);
    let arr = |v: Vec<u32>| {
        ArrayD::from_shape_vec(dim.clone(), v).map_err(|e| value_error(e.to_string()))
    };
    let jr: Vec<&str> = joined.iter().map(String::as_str).collect();
    let cr: Vec<&str> = cats.iter().map(String::as_str).collect();
    let (pc, rc, sc, jcs, ccs) = (u(|r| r.0)?, u(|r| r.2)?, u(|r| r.5)?, arr(jc)?, arr(cc)?);
    if strings {
        out.set_item("predicted", str_array(py, &class_refs, pc.clone())?)?;
        out.set_item("runner_up", str_array(py, &class_refs, rc.clone())?)?;
        out.set_item("status", str_array(py, &label_refs, sc.clone())?)?;
        out.set_item("candidates", str_array(py, &jr, jcs.clone())?)?;
        out.set_item("category", str_array(py, &cr, ccs.clone())?)?;
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
    out.set_item("n_candidates", to_numpy(py, arr(nc)?))?;
    Ok(out)
}
