//! Classification CSV — written by `classify`.
//!
//! `target,class,predicted,distance,runner_up,runner_up_distance,status` (the columns of
//! `docs/FORMATS.md`), `candidates` (the materials consistent with the estimate at the
//! confidence, `;`-separated, best first), then polarid's extra columns: `margin` (runner-up
//! distance minus distance), `nearest` (class of the nearest prototype, also when
//! rejected), `category` (set rule: the candidates' common category; nearest rule: that of
//! the nearest prototype; e.g. `metal`), `metric`, `rule` (`nearest` or `set`),
//! `confidence` (of the set), `gate` (the
//! statistic compared with the reject threshold), `votes` (k-NN votes for the class),
//! `reason` (why a status is not `ok`), and Wolff's baseline when it was run:
//! `wolff_class` (`metal`, `dielectric` or `unknown`), `wolff_fr_max` (largest Fresnel
//! ratio `(1 + P)/(1 − P)` over the measurements in the window), `wolff_beta_deg` (its β).
//!
//! Multi-band targets (fits with `wavelength_nm`) get one row per target and the column
//! `bands_used` after `candidates`: the wavelengths (nm, `;`-separated) of the target's bands
//! compared with the nearest prototype — fewer than the target's bands when a band's fit
//! was not `ok` or the prototypes lack it. It is written only when some row has one, so
//! single-band files keep exactly the columns above.
//!
//! Targets classified by the hypothesis tests against their measured rows (`classify
//! MEASUREMENTS.csv`, `rule` `hypothesis`) carry each candidate's probability in
//! `candidates` (`aluminum:0.97;copper:0.03`) and the column `probability` at the end:
//! the probability of the answer (the named material's; for `ambiguous` the set's
//! total; empty for `unknown`). `probability` is written only when some row has one.
//!
//! `predicted` is a class name, `ambiguous` or `unknown`; distances of an unclassified target are empty.

use std::io::Write;
use std::path::Path;

use super::{CsvTable, fmt_opt, write_rows};
use crate::error::Result;

/// Column order of the classification CSV.
pub const COLUMNS: [&str; 20] = [
    "target",
    "class",
    "predicted",
    "distance",
    "runner_up",
    "runner_up_distance",
    "status",
    "candidates",
    "margin",
    "nearest",
    "category",
    "metric",
    "rule",
    "confidence",
    "gate",
    "votes",
    "reason",
    "wolff_class",
    "wolff_fr_max",
    "wolff_beta_deg",
];

/// One classified target.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ClassificationRow {
    /// Target name.
    pub target: String,
    /// Known class, if any.
    pub class: Option<String>,
    /// Predicted class, `ambiguous` or `unknown`.
    pub predicted: String,
    /// Distance to the nearest prototype of `nearest`.
    pub distance: Option<f64>,
    /// Nearest other class.
    pub runner_up: Option<String>,
    /// Distance to the runner-up.
    pub runner_up_distance: Option<f64>,
    /// `ok`, `ambiguous`, `rejected`, `fit_<status>`, `no_covariance`, `invalid_estimate`.
    pub status: String,
    /// The consistent materials, best first (empty when none or not tested).
    pub candidates: Vec<String>,
    /// The candidates' probabilities (hypothesis tests; empty otherwise), in the order
    /// of `candidates`.
    pub candidate_probabilities: Vec<f64>,
    /// The probability of the answer (hypothesis tests): the named material's, or the
    /// set's total for `ambiguous`.
    pub probability: Option<f64>,
    /// `runner_up_distance − distance`.
    pub margin: Option<f64>,
    /// Class of the nearest prototype (also when rejected).
    pub nearest: Option<String>,
    /// Set rule: the candidates' common category; nearest rule: the nearest prototype's.
    pub category: Option<String>,
    /// `euclidean` or `mahalanobis`.
    pub metric: String,
    /// `nearest` or `set` (empty when unknown).
    pub rule: String,
    /// Confidence of the consistent set.
    pub confidence: Option<f64>,
    /// Statistic compared with the reject threshold.
    pub gate: Option<f64>,
    /// Votes for the class among the k nearest.
    pub votes: Option<u64>,
    /// Why the status is not `ok`.
    pub reason: String,
    /// Wolff's class, when run.
    pub wolff_class: Option<String>,
    /// Wavelengths compared, `;`-separated (e.g. `450;550;650`; empty for single-band
    /// data without wavelengths).
    pub bands_used: String,
    /// Wolff's largest Fresnel ratio.
    pub wolff_fr_max: Option<f64>,
    /// β of that ratio, degrees.
    pub wolff_beta_deg: Option<f64>,
}

fn finite(x: Option<f64>) -> Option<f64> {
    x.filter(|v| !v.is_nan())
}

/// Write classification rows in the documented column order ([`COLUMNS`], with
/// `bands_used` after `candidates` when some row has bands).
pub fn write<W: Write + ?Sized>(w: &mut W, path: &Path, rows: &[ClassificationRow]) -> Result<()> {
    let banded = rows.iter().any(|r| !r.bands_used.is_empty());
    let probable = rows
        .iter()
        .any(|r| r.probability.is_some() || !r.candidate_probabilities.is_empty());
    let mut headers: Vec<&str> = COLUMNS.to_vec();
    if banded {
        headers.insert(8, "bands_used");
    }
    if probable {
        headers.push("probability");
    }
    write_rows(
        w,
        path,
        &headers,
        rows.iter().map(|r| {
            let mut cells = vec![
                r.target.clone(),
                r.class.clone().unwrap_or_default(),
                r.predicted.clone(),
                fmt_opt(finite(r.distance)),
                r.runner_up.clone().unwrap_or_default(),
                fmt_opt(finite(r.runner_up_distance)),
                r.status.clone(),
                candidates_text(r),
                fmt_opt(finite(r.margin)),
                r.nearest.clone().unwrap_or_default(),
                r.category.clone().unwrap_or_default(),
                r.metric.clone(),
                r.rule.clone(),
                fmt_opt(finite(r.confidence)),
                fmt_opt(finite(r.gate)),
                r.votes.map(|v| v.to_string()).unwrap_or_default(),
                r.reason.clone(),
                r.wolff_class.clone().unwrap_or_default(),
                fmt_opt(finite(r.wolff_fr_max)),
                fmt_opt(finite(r.wolff_beta_deg)),
            ];
            if banded {
                cells.insert(8, r.bands_used.clone());
            }
            if probable {
                cells.push(fmt_opt(r.probability.filter(|p| p.is_finite())));
            }
            cells
        }),
    )
}

/// The `candidates` cell: names joined with `;`, each as `name:probability` (3
/// significant decimals) when the row has probabilities.
fn candidates_text(r: &ClassificationRow) -> String {
    if r.candidate_probabilities.len() == r.candidates.len() && !r.candidates.is_empty() {
        r.candidates
            .iter()
            .zip(&r.candidate_probabilities)
            .map(|(c, p)| format!("{c}:{}", prob_text(*p)))
            .collect::<Vec<_>>()
            .join(";")
    } else {
        r.candidates.join(";")
    }
}

/// A probability with 4 decimals, or in scientific notation below 1e-4.
fn prob_text(p: f64) -> String {
    if p == 0.0 || p >= 1e-4 {
        format!("{p:.4}")
    } else {
        format!("{p:.2e}")
    }
}

/// Read a classification CSV (needs `target`, `predicted`, `status`; the rest optional).
pub fn read(path: &Path) -> Result<Vec<ClassificationRow>> {
    let t = CsvTable::read(path)?;
    from_table(&t)
}

/// Parse classification rows from an already read table.
pub fn from_table(t: &CsvTable) -> Result<Vec<ClassificationRow>> {
    let c_target = t.require("target")?;
    let c_pred = t.require("predicted")?;
    let c_status = t.require("status")?;
    let c = |n: &str| t.col(n);
    let mut out = Vec::with_capacity(t.rows.len());
    for r in 0..t.rows.len() {
        let fnum = |n: &str| -> Result<Option<f64>> {
            match c(n) {
                Some(col) if t.text(r, col).eq_ignore_ascii_case("inf") => Ok(Some(f64::INFINITY)),
                col => t.opt_f64(r, col),
            }
        };
        let mut names = Vec::new();
        let mut probs = Vec::new();
        for item in t
            .opt_text(r, c("candidates"))
            .unwrap_or_default()
            .split(';')
            .map(str::trim)
            .filter(|x| !x.is_empty())
        {
            match item
                .rsplit_once(':')
                .and_then(|(n, p)| Some((n, p.parse::<f64>().ok()?)))
            {
                Some((n, p)) => {
                    names.push(n.to_string());
                    probs.push(p);
                }
                None => names.push(item.to_string()),
            }
        }
        if probs.len() != names.len() {
            probs.clear();
        }
        out.push(ClassificationRow {
            target: t.text(r, c_target).to_string(),
            class: t.opt_text(r, c("class")),
            predicted: t.text(r, c_pred).to_string(),
            distance: fnum("distance")?,
            runner_up: t.opt_text(r, c("runner_up")),
            runner_up_distance: fnum("runner_up_distance")?,
            status: t.text(r, c_status).to_string(),
            candidates: names,
            candidate_probabilities: probs,
            probability: fnum("probability")?,
            margin: fnum("margin")?,
            nearest: t.opt_text(r, c("nearest")),
            category: t.opt_text(r, c("category")),
            metric: t.opt_text(r, c("metric")).unwrap_or_default(),
            rule: t.opt_text(r, c("rule")).unwrap_or_default(),
            confidence: fnum("confidence")?,
            gate: fnum("gate")?,
            votes: t.opt_u64(r, c("votes"))?,
            reason: t.opt_text(r, c("reason")).unwrap_or_default(),
            bands_used: t.opt_text(r, c("bands_used")).unwrap_or_default(),
            wolff_class: t.opt_text(r, c("wolff_class")),
            wolff_fr_max: fnum("wolff_fr_max")?,
            wolff_beta_deg: fnum("wolff_beta_deg")?,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let rows = vec![
            ClassificationRow {
                target: "T1".into(),
                class: Some("aluminum".into()),
                predicted: "aluminum".into(),
                distance: Some(0.25),
                runner_up: Some("copper".into()),
                runner_up_distance: Some(1.5),
                status: "ok".into(),
                margin: Some(1.25),
                nearest: Some("aluminum".into()),
                metric: "euclidean".into(),
                votes: Some(1),
                candidates: vec!["aluminum".into(), "tin".into()],
                rule: "set".into(),
                confidence: Some(0.95),
                wolff_class: Some("metal".into()),
                wolff_fr_max: Some(1.5),
                wolff_beta_deg: Some(60.0),
                ..Default::default()
            },
            ClassificationRow {
                target: "T2".into(),
                predicted: "unknown".into(),
                distance: Some(f64::NAN),
                status: "fit_not_converged".into(),
                reason: "not classified, because".into(),
                metric: "euclidean".into(),
                ..Default::default()
            },
        ];
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.csv");
        let mut buf = Vec::new();
        write(&mut buf, &p, &rows).unwrap();
        let text = String::from_utf8(buf.clone()).unwrap();
        assert!(text.starts_with(
            "target,class,predicted,distance,runner_up,runner_up_distance,status,candidates,margin"
        ));
        std::fs::write(&p, buf).unwrap();
        let back = read(&p).unwrap();
        let mut expect = rows.clone();
        expect[1].distance = None;
        assert_eq!(back, expect);
        // Bands: the column after `candidates`, only when some row has bands.
        let mut banded = rows.clone();
        banded[0].bands_used = "450;550;650".into();
        let mut buf = Vec::new();
        write(&mut buf, &p, &banded).unwrap();
        let text = String::from_utf8(buf.clone()).unwrap();
        assert!(text.starts_with(
            "target,class,predicted,distance,runner_up,runner_up_distance,status,candidates,\
             bands_used,margin"
        ));
        std::fs::write(&p, buf).unwrap();
        let mut expect = banded.clone();
        expect[1].distance = None;
        assert_eq!(read(&p).unwrap(), expect);
        // Probabilities: in `candidates` and the last column, only when some row has them.
        let mut prob = rows.clone();
        prob[0].candidate_probabilities = vec![0.9712, 0.0288];
        prob[0].probability = Some(1.0);
        let mut buf = Vec::new();
        write(&mut buf, &p, &prob).unwrap();
        let text = String::from_utf8(buf.clone()).unwrap();
        assert!(
            text.lines()
                .next()
                .unwrap()
                .ends_with(",wolff_beta_deg,probability")
        );
        assert!(text.contains(",aluminum:0.9712;tin:0.0288,"), "{text}");
        std::fs::write(&p, buf).unwrap();
        let mut expect = prob.clone();
        expect[1].distance = None;
        assert_eq!(read(&p).unwrap(), expect);
    }
}
