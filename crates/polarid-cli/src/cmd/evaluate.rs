//! `polarid evaluate FITS.csv`: leave-one-out evaluation of the classifier over a labelled
//! set of fits (or, with `--model`, evaluation of a trained model on a labelled test set):
//! confusion matrix and accuracy, printed as a table and optionally written as CSV or JSON.

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::ValueEnum;
use polarid_core::classify::{Classifier, Evaluation, Labelled, evaluate, leave_one_out};
use polarid_io::IoError;
use polarid_io::model::Model;
use polarid_io::table::{fmt_f64, write_rows};

use super::classify::{MethodArgs, estimate_of, read_fits};
use crate::{BadInput, Ctx};

/// Output format of the confusion matrix file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// CSV: `truth,<predicted classes...>,total`, with the accuracy in a `#` comment.
    Csv,
    /// JSON with the matrix, accuracy, skipped and per-target decisions.
    Json,
}

/// Arguments of `polarid evaluate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Fits CSV with a `class` for every target to evaluate (rows without one are ignored).
    pub fits: PathBuf,
    /// Evaluate this trained model on FITS instead of leave-one-out.
    #[arg(long, value_name = "MODEL.json")]
    pub model: Option<PathBuf>,
    #[command(flatten)]
    pub method: MethodArgs,
    /// Also write the confusion matrix to this file.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Format of --output (default: from its extension, `.json` → json, else csv).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
}

/// The table printed on standard output.
fn table(ev: &Evaluation, mode: &str) -> String {
    let c = &ev.confusion;
    let mut s = format!("{mode}: confusion matrix (rows: true class, columns: predicted)\n");
    let w0 = c
        .truth
        .iter()
        .map(String::len)
        .chain([10])
        .max()
        .unwrap_or(10);
    let widths: Vec<usize> = c.predicted.iter().map(|p| p.len().max(5)).collect();
    s.push_str(&format!("{:<w0$}", "true\\pred"));
    for (p, w) in c.predicted.iter().zip(&widths) {
        s.push_str(&format!("  {p:>w$}"));
    }
    s.push_str("  total\n");
    // ok (c.counts[r]): the confusion matrix has one row of counts per true class.
    for (r, t) in c.truth.iter().enumerate() {
        s.push_str(&format!("{t:<w0$}"));
        for (v, w) in c.counts[r].iter().zip(&widths) {
            s.push_str(&format!("  {v:>w$}"));
        }
        s.push_str(&format!("  {:>5}\n", c.counts[r].iter().sum::<u64>()));
    }
    s.push_str(&format!(
        "accuracy: {:.4} ({}/{})\n",
        ev.accuracy,
        c.correct(),
        c.total()
    ));
    for (t, st) in &ev.skipped {
        s.push_str(&format!("skipped {t}: fit status `{st}`, not classified\n"));
    }
    for u in &ev.unrepresented {
        s.push_str(&format!(
            "warning: class `{u}` has no prototype to be compared with; its targets cannot be \
             classified correctly\n"
        ));
    }
    s
}

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
    write_rows(
        w,
        path,
        &cols,
        // ok (c.counts[r]): one row of counts per true class.
        c.truth.iter().enumerate().map(|(r, t)| {
            let mut row = vec![t.clone()];
            row.extend(c.counts[r].iter().map(u64::to_string));
            row.push(c.counts[r].iter().sum::<u64>().to_string());
            row
        }),
    )
}

fn to_json(ev: &Evaluation, mode: &str, metric: &str, k: usize) -> serde_json::Value {
    let c = &ev.confusion;
    let num = |x: f64| {
        if x.is_finite() {
            serde_json::json!(x)
        } else {
            serde_json::Value::Null
        }
    };
    serde_json::json!({
        "mode": mode,
        "metric": metric,
        "k": k,
        "accuracy": num(ev.accuracy),
        "correct": c.correct(),
        "total": c.total(),
        "truth": c.truth,
        "predicted": c.predicted,
        "counts": c.counts,
        "skipped": ev.skipped.iter().map(|(t, s)| serde_json::json!({"target": t, "status": s})).collect::<Vec<_>>(),
        "unrepresented": ev.unrepresented,
        "items": ev.items.iter().map(|i| serde_json::json!({
            "target": i.target,
            "class": i.class,
            "predicted": i.decision.predicted,
            "distance": num(i.decision.distance),
            "runner_up": i.decision.runner_up,
            "runner_up_distance": num(i.decision.runner_up_distance),
            "status": i.decision.status.label(),
        })).collect::<Vec<_>>(),
    })
}

/// Run `polarid evaluate`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let cfg = args.method.config()?;
    let fits = read_fits(&args.fits)?;
    let items: Vec<Labelled> = fits
        .iter()
        .filter_map(|(line, f)| {
            f.class.as_ref().map(|c| Labelled {
                target: f.target.clone(),
                class: c.clone(),
                estimate: estimate_of(f),
                source: format!("{}:{line} target {}", args.fits.display(), f.target),
            })
        })
        .collect();
    if items.is_empty() {
        return Err(BadInput(format!(
            "{}: no labelled fits (the `class` column is missing or empty in all {} row(s))",
            args.fits.display(),
            fits.len()
        ))
        .into());
    }
    let (ev, mode) = match &args.model {
        Some(m) => {
            let model = Model::read(m)?;
            let clf = Classifier::new(model.prototypes(), cfg)?;
            (
                evaluate(&clf, &items)
                    .map_err(|e| BadInput(format!("{}: {e}", args.fits.display())))?,
                format!("model {}", m.display()),
            )
        }
        None => (
            leave_one_out(&items, cfg)
                .map_err(|e| BadInput(format!("{}: {e}", args.fits.display())))?,
            "leave-one-out".to_string(),
        ),
    };
    if ev.items.is_empty() {
        return Err(BadInput(format!(
            "{}: no labelled fit has status `ok`; nothing to evaluate",
            args.fits.display()
        ))
        .into());
    }
    let text = table(&ev, &mode);
    if let Some(out) = &args.output {
        let format = args.format.unwrap_or(
            if out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("json"))
            {
                Format::Json
            } else {
                Format::Csv
            },
        );
        let mut inputs: Vec<&Path> = vec![&args.fits];
        if let Some(m) = &args.model {
            inputs.push(m);
        }
        ctx.write_output(Some(out), &inputs, |w| match format {
            Format::Csv => write_csv(
                w,
                out,
                &ev,
                &format!(
                    "# {mode}, metric {}, k = {}: accuracy {} ({}/{})\n",
                    cfg.metric.name(),
                    cfg.k,
                    fmt_f64(ev.accuracy),
                    ev.confusion.correct(),
                    ev.confusion.total()
                ),
            ),
            Format::Json => {
                let v = to_json(&ev, &mode, cfg.metric.name(), cfg.k);
                let s = serde_json::to_string_pretty(&v)
                    .map_err(|e| IoError::io(out, std::io::Error::other(e.to_string())))?;
                w.write_all(s.as_bytes())
                    .and_then(|_| w.write_all(b"\n"))
                    .map_err(|e| IoError::io(out, e))
            }
        })?;
    }
    let mut stdout = std::io::stdout().lock();
    stdout.write_all(text.as_bytes())?;
    stdout.flush()?;
    Ok(())
}
