//! The bench demo's text tables: the fits against the plates' true index, the test
//! plates' classification, and the map's share of correct pixels per plate.

use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;

use super::bench::{MAP_BIN, TEST_PREFIX};
use super::tables::{pm, text_table};
use crate::map::MapResult;
use crate::simulate::TruthRow;

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
    let table1 = text_table(
        "Table 1. Bench fits (simulated lamp-and-lens bench, per-pixel geometry). n, k: the \
         plates' true index; n̂, k̂: estimates ± 1 standard error; z: error in standard errors.",
        &["Target", "set", "n", "k", "n̂", "k̂", "z(n)", "z(k)", "fit"],
        &t1,
    );
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
    let table2 = text_table(
        "Table 2. Test plates (another render, the lamp mirrored across the plane of \
         incidence), nearest neighbour in (n, k) against the training fits.",
        &[
            "Target",
            "truth",
            "Classification",
            "distance",
            "runner-up (distance)",
            "margin",
        ],
        &t2,
    );
    let t3: Vec<Vec<String>> = map
        .regions
        .iter()
        .map(|r| {
            let unknown = r
                .classes
                .iter()
                .find(|(c, _)| c == polarid_core::classify::UNKNOWN)
                .map_or(0, |(_, n)| *n);
            let classified = r.pixels.saturating_sub(unknown);
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
                share(classified, r.pixels),
                share(r.correct, classified),
            ]
        })
        .collect();
    let table3 = text_table(
        &format!(
            "Table 3. Map of the test set ({MAP_BIN} × {MAP_BIN} binning, per-pixel fit and \
             nearest neighbour): per plate region, the share of its blocks classified and \
             the share of those given the right class."
        ),
        &["Region", "class", "blocks", "classified", "correct"],
        &t3,
    );
    format!("{table1}\n{table2}\n{table3}")
}
