//! The bench demo's text tables: the fits against the plates' true index, the test
//! plates' classification, and the map's share of correct pixels per plate.

use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;

use super::tables::{pm, text_table};
use crate::map::MapResult;
use crate::simulate::TruthRow;

/// Prefix of the test set's target names.
pub const TEST_PREFIX: &str = "test_";

/// Binning of the demo's map (`polarid map --bin 4`).
pub const MAP_BIN: usize = 4;

/// The plate's true `(n, k)` from the truth rows.
fn true_index(truth: &[TruthRow], target: &str) -> Option<(f64, f64)> {
    truth
        .iter()
        .find(|t| t.target == target)
        .and_then(|t| t.calibrated.as_ref())
        .map(|c| (c.n, c.k))
}

/// `(estimate − truth) / se`, or `—`.
fn z(est: f64, truth: f64, se: f64) -> String {
    if se.is_finite() && se > 0.0 {
        format!("{:+.1}", (est - truth) / se)
    } else {
        "—".into()
    }
}

/// The three tables as text.
pub(super) fn tables(
    truth: &[TruthRow],
    fits: &[(u64, FitRow)],
    class_rows: &[ClassificationRow],
    map: &MapResult,
) -> String {
    let table1 = fits_table(truth, fits);
    let table2 = classification_table(class_rows);
    let table3 = map_table(map);
    format!("{table1}\n{table2}\n{table3}")
}

/// Table 1: the fits against the plates' true index.
fn fits_table(truth: &[TruthRow], fits: &[(u64, FitRow)]) -> String {
    let mut t1 = Vec::new();
    for (_, f) in fits {
        let Some((n, k)) = true_index(truth, &f.target) else {
            continue;
        };
        let set = if f.target.starts_with(TEST_PREFIX) {
            "test"
        } else {
            "training"
        };
        t1.push(vec![
            f.target.clone(),
            set.to_string(),
            format!("{n:.3}"),
            format!("{k:.3}"),
            pm(f.n, f.n_se),
            pm(f.k, f.k_se),
            z(f.n, n, f.n_se),
            z(f.k, k, f.k_se),
            f.status.to_string(),
        ]);
    }
    text_table(
        "Table 1. Bench fits (simulated lamp-and-lens bench, per-pixel geometry). n, k: the \
         plates' true index; n̂, k̂: estimates ± 1 standard error; z: error in standard errors.",
        &["Target", "set", "n", "k", "n̂", "k̂", "z(n)", "z(k)", "fit"],
        &t1,
    )
}

/// Table 2: the test plates' classification.
fn classification_table(class_rows: &[ClassificationRow]) -> String {
    let t2: Vec<Vec<String>> = class_rows
        .iter()
        .map(|c| {
            vec![
                c.target.clone(),
                c.class.clone().unwrap_or_default(),
                c.predicted.clone(),
                c.distance.map(|d| format!("{d:.3}")).unwrap_or_default(),
                c.runner_up
                    .as_ref()
                    .map(|r| format!("{r} ({:.3})", c.runner_up_distance.unwrap_or(f64::NAN)))
                    .unwrap_or_default(),
                c.margin.map(|m| format!("{m:.3}")).unwrap_or_default(),
            ]
        })
        .collect();
    text_table(
        &format!(
            "Table 2. Test plates (another render, the lamp mirrored across the plane of \
             incidence) against the training fits, {}. Classification: a material, \
             `ambiguous` or `unknown` (docs/FORMATS.md, \"Answers\").",
            rows_rule(class_rows)
        ),
        &[
            "Target",
            "truth",
            "Classification",
            "distance",
            "runner-up (distance)",
            "margin",
        ],
        &t2,
    )
}

/// Table 3: the map's shares per plate region.
fn map_table(map: &MapResult) -> String {
    let t3: Vec<Vec<String>> = map
        .regions
        .iter()
        .map(|r| {
            let count = |word: &str| {
                r.classes
                    .iter()
                    .find(|(c, _)| c == word)
                    .map_or(0, |(_, n)| *n)
            };
            let unknown = count(polarid_core::classify::UNKNOWN);
            let ambiguous = if map.ambiguous_class().is_some() {
                count(polarid_core::classify::AMBIGUOUS)
            } else {
                0
            };
            // One material: neither `unknown` nor `ambiguous`.
            let material = r.pixels.saturating_sub(unknown + ambiguous);
            let share = |a: u64, b: u64| {
                if b > 0 {
                    format!("{:.1} %", 100.0 * a as f64 / b as f64)
                } else {
                    "—".into()
                }
            };
            vec![
                r.name.clone(),
                r.class.clone().unwrap_or_default(),
                r.pixels.to_string(),
                share(material, r.pixels),
                share(ambiguous, r.pixels),
                share(unknown, r.pixels),
                share(r.correct, material),
            ]
        })
        .collect();
    text_table(
        &format!(
            "Table 3. Map of the test set ({MAP_BIN} × {MAP_BIN} binning, per-pixel fit, {}): \
             per plate region, the share of its blocks given one material, `ambiguous` and \
             `unknown`, and the share of the one-material blocks given the right class.",
            map_rule(map)
        ),
        &[
            "Region",
            "class",
            "blocks",
            "one material",
            "ambiguous",
            "unknown",
            "correct",
        ],
        &t3,
    )
}

/// The rule of the classification rows in words (their `rule` and `confidence`
/// columns): e.g. "set rule at 95% (Mahalanobis)".
pub fn rows_rule(rows: &[ClassificationRow]) -> String {
    let Some(r) = rows.first() else {
        return "no targets".into();
    };
    rule_words(&r.rule, r.confidence, &r.metric)
}

/// The rule of a map in words: e.g. "set rule at 95% (Mahalanobis)".
pub fn map_rule(map: &MapResult) -> String {
    let confidence = (map.rule == crate::map::Rule::Set).then_some(map.confidence);
    rule_words(map.rule.name(), confidence, map.metric.name())
}

fn rule_words(rule: &str, confidence: Option<f64>, metric: &str) -> String {
    match (rule, confidence) {
        ("set", Some(c)) => format!("set rule at {}% (Mahalanobis)", c * 100.0),
        ("hypothesis", Some(c)) => format!("hypothesis tests at {}%", c * 100.0),
        ("nearest", _) => format!("nearest prototype ({metric})"),
        (r, _) => format!("{r} rule"),
    }
}
