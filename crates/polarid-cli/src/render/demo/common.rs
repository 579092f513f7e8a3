//! Pieces of the figures and reports that the paper demo ([`super`]) and the bench demo
//! ([`crate::render::bench`]) build alike.

use std::collections::BTreeMap;

use polarid_io::model::ModelPrototype;
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;

use crate::render::plots;
use crate::render::report;

/// The measurements of each target, in their order.
pub fn by_target<'a>(
    meas: impl IntoIterator<Item = &'a Measurement>,
) -> BTreeMap<&'a str, Vec<&'a Measurement>> {
    let mut by_target: BTreeMap<&str, Vec<&Measurement>> = BTreeMap::new();
    for m in meas {
        by_target.entry(m.target.as_str()).or_default().push(m);
    }
    by_target
}

/// One plate's DoLP against β: its measurements `ms` (±1 standard error) and, with its
/// fit `f` and measurements, the curve of eq. (9) of the fit, 2° beyond the measured β on
/// each side.
pub fn dolp_series(label: String, f: Option<&FitRow>, ms: &[&Measurement]) -> plots::DolpSeries {
    let points: Vec<plots::DolpPoint> = ms
        .iter()
        .map(|m| plots::DolpPoint {
            beta_deg: m.beta_deg,
            dolp: m.dolp,
            dolp_se: m.dolp_se,
        })
        .collect();
    let lo = points.iter().map(|q| q.beta_deg).fold(f64::MAX, f64::min);
    let hi = points.iter().map(|q| q.beta_deg).fold(f64::MIN, f64::max);
    plots::DolpSeries {
        label,
        curve: match f {
            Some(f) if !points.is_empty() => plots::eq9_curve(f.n, f.k, lo - 2.0, hi + 2.0, 60),
            _ => Vec::new(),
        },
        curve_label: f.map(|f| format!("fit n = {:.2}, k = {:.2}", f.n, f.k)),
        points,
    }
}

/// A model's prototypes as the (n, k) plane draws them.
pub fn prototypes<'a>(ps: impl IntoIterator<Item = &'a ModelPrototype>) -> Vec<plots::Prototype> {
    ps.into_iter()
        .map(|p| plots::Prototype {
            class: p.class.clone(),
            n: p.n,
            k: p.k,
        })
        .collect()
}

/// The report's row of the fit `f` (view angle `theta_r_deg` where one applies).
pub fn estimate_row(f: &FitRow, theta_r_deg: Option<f64>) -> report::EstimateRow {
    report::EstimateRow {
        target: f.target.clone(),
        class: f.class.clone(),
        theta_r_deg,
        n: f.n,
        n_se: f.n_se,
        k: f.k,
        k_se: f.k_se,
        nk_corr: f.nk_corr,
        rms_residual: f.rms_residual,
        measurements: f.measurements as usize,
        status: f.status,
    }
}

/// The report's inputs: each scene (`scene_detail` of its staged name) followed by its
/// manifest (`manifest_detail`), then the `(role, path, detail)` of the files the demo
/// wrote.
pub fn inputs(
    scenes: &[String],
    manifests: &[String],
    scene_detail: impl Fn(&str) -> String,
    manifest_detail: &str,
    files: &[(&str, &str, &str)],
) -> Vec<report::InputItem> {
    let mut inputs: Vec<report::InputItem> = Vec::new();
    for (s, m) in scenes.iter().zip(manifests) {
        inputs.push(report::InputItem::new("scene", s.clone(), scene_detail(s)));
        inputs.push(report::InputItem::new(
            "manifest",
            m.clone(),
            manifest_detail,
        ));
    }
    for &(role, path, detail) in files {
        inputs.push(report::InputItem::new(role, path, detail));
    }
    inputs
}

/// How many classification rows predict their known class.
pub fn correct(rows: &[ClassificationRow]) -> usize {
    rows.iter()
        .filter(|c| c.class.as_deref() == Some(c.predicted.as_str()))
        .count()
}
