//! The confusion matrix file of `polarid evaluate` (`--output`, CSV or JSON) and the
//! sets' summary line shared with the printed table.

use std::io::Write;
use std::path::Path;

use polarid_core::classify::{ClassifierConfig, Evaluation, SetStats};
use polarid_io::IoError;
use polarid_io::table::{fmt_f64, write_rows};
use polarid_pipeline::evaluate::{EvaluateConfig, EvaluateOutput};

use super::Format;
use crate::cmd::wolff::{num, wolff_csv_header, wolff_json};

/// `sets at 95%: coverage 0.9500 (19/20), mean size 1.30; one: 14 (13 correct), several: 5,
/// none: 1`.
pub(super) fn sets_line(st: &SetStats) -> String {
    format!(
        "sets at {}%: coverage {:.4} ({}/{}), mean size {:.2}; one: {} ({} correct), several: \
         {}, none: {}",
        st.confidence * 100.0,
        st.coverage,
        st.covered,
        st.tested,
        st.mean_size,
        st.single,
        st.single_correct,
        st.several,
        st.empty
    )
}

/// The consistent sets' statistics as JSON.
fn sets_json(st: &SetStats) -> serde_json::Value {
    serde_json::json!({
        "confidence": st.confidence,
        "tested": st.tested,
        "covered": st.covered,
        "coverage": num(st.coverage),
        "mean_size": num(st.mean_size),
        "single": st.single,
        "single_correct": st.single_correct,
        "several": st.several,
        "empty": st.empty,
    })
}

/// The CSV file: `header`, then `truth,<predicted classes...>,total` per true class.
fn write_csv(
    w: &mut dyn Write,
    path: &Path,
    ev: &Evaluation,
    header: &str,
) -> polarid_io::Result<()> {
    let c = &ev.confusion;
    w.write_all(header.as_bytes())
        .map_err(|e| IoError::io(path, e))?;
    let mut cols: Vec<&str> = vec!["truth"];
    cols.extend(c.predicted.iter().map(String::as_str));
    cols.push("total");
    // ok (c.counts[r]): one row of counts per true class.
    let rows = c.truth.iter().enumerate().map(|(r, t)| {
        let mut row = vec![t.clone()];
        row.extend(c.counts[r].iter().map(u64::to_string));
        row.push(c.counts[r].iter().sum::<u64>().to_string());
        row
    });
    write_rows(w, path, &cols, rows)
}

/// The JSON file (without Wolff's baseline).
fn to_json(ev: &Evaluation, mode: &str, cfg: &ClassifierConfig) -> serde_json::Value {
    let c = &ev.confusion;
    serde_json::json!({
        "mode": mode,
        "rule": cfg.rule.name(),
        "metric": cfg.distance_metric().name(),
        "k": cfg.k,
        "sets": ev.sets.as_ref().map(sets_json),
        "accuracy": num(ev.accuracy),
        "correct": c.correct(),
        "total": c.total(),
        "truth": c.truth,
        "predicted": c.predicted,
        "counts": c.counts,
        "skipped": ev.skipped.iter().map(|(t, s)| serde_json::json!({"target": t, "status": s.as_str()})).collect::<Vec<_>>(),
        "unrepresented": ev.unrepresented,
        "items": ev.items.iter().map(|i| serde_json::json!({
            "target": i.target,
            "class": i.class,
            "predicted": i.decision.predicted,
            "distance": num(i.decision.distance),
            "runner_up": i.decision.runner_up,
            "runner_up_distance": num(i.decision.runner_up_distance),
            "status": i.decision.status.label(),
            "candidates": i.decision.candidates.iter().map(|c| serde_json::json!({"class": c.class, "distance": num(c.distance)})).collect::<Vec<_>>(),
            "category": i.decision.set_category,
        })).collect::<Vec<_>>(),
    })
}

/// Write the confusion matrix file in `format`.
pub(super) fn write_file(
    w: &mut dyn Write,
    out: &Path,
    format: Format,
    o: &EvaluateOutput,
    cfg: &EvaluateConfig,
) -> polarid_io::Result<()> {
    let (ev, mode, metric, k) = (
        &o.evaluation,
        &o.mode,
        cfg.classifier.distance_metric().name(),
        cfg.classifier.k,
    );
    match format {
        Format::Csv => {
            let header = format!(
                "# {mode}, rule {}, metric {metric}, k = {k}: accuracy {} ({}/{})\n{}{}",
                cfg.classifier.rule.name(),
                fmt_f64(ev.accuracy),
                ev.confusion.correct(),
                ev.confusion.total(),
                ev.sets
                    .as_ref()
                    .map(|st| format!("# {}\n", sets_line(st)))
                    .unwrap_or_default(),
                o.wolff.as_ref().map(wolff_csv_header).unwrap_or_default()
            );
            write_csv(w, out, ev, &header)
        }
        Format::Json => {
            let mut v = to_json(ev, mode, &cfg.classifier);
            if let (Some(wo), Some(obj)) = (&o.wolff, v.as_object_mut()) {
                obj.insert("wolff".into(), wolff_json(wo));
            }
            let s = serde_json::to_string_pretty(&v)
                .map_err(|e| IoError::io(out, std::io::Error::other(e.to_string())))?;
            w.write_all(s.as_bytes())
                .and_then(|_| w.write_all(b"\n"))
                .map_err(|e| IoError::io(out, e))
        }
    }
}
