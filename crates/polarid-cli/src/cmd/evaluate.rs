//! `polarid evaluate FITS.csv`: leave-one-out evaluation of the classifier over a labelled
//! set of fits (or, with `--model`, evaluation of a trained model on a labelled test set):
//! confusion matrix and accuracy, and the consistent sets' coverage (truth in the set) and
//! sizes, printed as a table and optionally written as CSV or JSON.
//! With `--wolff MEASUREMENTS.csv`, Wolff's metal/dielectric baseline is scored next to
//! it (see `polarid_pipeline::evaluate` for the rules).

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::ValueEnum;
use polarid_core::classify::{ClassifierConfig, Evaluation, SetStats};
use polarid_io::IoError;
use polarid_io::table::{fmt_f64, write_rows};
use polarid_pipeline::classify::read_fits;
use polarid_pipeline::evaluate::{
    self as pipe, CATEGORIES, EvaluateConfig, EvaluateOutput, WolffEvalRequest,
};

use super::common::{MethodArgs, PipeResult, matrix};
use super::wolff::{WolffArgs, num, wolff_csv_header, wolff_json, wolff_table};
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
    #[command(flatten)]
    pub wolff: WolffArgs,
    /// Library giving each class's true category for Wolff's accuracy (`builtin`,
    /// `paper2007` or a library CSV with a `category` column); classes match materials by
    /// name.
    #[arg(
        long,
        value_name = "LIB",
        default_value = "builtin",
        requires = "wolff"
    )]
    pub wolff_library: String,
    /// True category of a class for Wolff's accuracy, before the model's and the library's:
    /// CLASS=metal, CLASS=dielectric (scored) or CLASS=semiconductor|other (not scored).
    /// Repeatable.
    #[arg(long, value_name = "CLASS=CATEGORY", requires = "wolff")]
    pub wolff_category: Vec<String>,
}

/// `--wolff-category CLASS=CATEGORY` values as `(class, category)`.
fn categories(specs: &[String]) -> anyhow::Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for spec in specs {
        let (class, cat) = spec
            .split_once('=')
            .map(|(a, b)| (a.trim(), b.trim()))
            .filter(|(a, b)| !a.is_empty() && CATEGORIES.contains(b))
            .ok_or_else(|| {
                BadInput(format!(
                    "--wolff-category `{spec}`: expected CLASS=CATEGORY with CATEGORY one of {}",
                    CATEGORIES.join(", ")
                ))
            })?;
        out.push((class.to_string(), cat.to_string()));
    }
    Ok(out)
}

/// The table printed on standard output.
fn table(ev: &Evaluation, mode: &str) -> String {
    let c = &ev.confusion;
    let mut s = format!("{mode}: confusion matrix (rows: true class, columns: predicted)\n");
    s.push_str(&matrix(c, "true\\pred"));
    s.push_str(&format!(
        "accuracy: {:.4} ({}/{})\n",
        ev.accuracy,
        c.correct(),
        c.total()
    ));
    if let Some(st) = &ev.sets {
        s.push_str(&sets_line(st));
        s.push('\n');
    }
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

/// `sets at 95%: coverage 0.9500 (19/20), mean size 1.30; 1: 14 (13 correct), several: 5,
/// none: 1`.
fn sets_line(st: &SetStats) -> String {
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
fn write_file(
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

/// Run `polarid evaluate`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let classifier = args.method.config()?;
    let fits = read_fits(&args.fits).cli()?;
    let wolff = match args.wolff.request()? {
        Some(r) => Some(WolffEvalRequest {
            measurements: r.measurements,
            settings: r.settings,
            library: args.wolff_library.clone(),
            categories: categories(&args.wolff_category)?,
        }),
        None => None,
    };
    let cfg = EvaluateConfig { classifier, wolff };
    // Everything (Wolff's baseline too) before any output, so that bad input writes nothing.
    let o = pipe::evaluate(&args.fits, &fits, args.model.as_deref(), &cfg).cli()?;
    let mut text = table(&o.evaluation, &o.mode);
    if let Some(w) = &o.wolff {
        text.push_str(&wolff_table(w));
    }
    if let Some(out) = &args.output {
        let json = out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        let format = args
            .format
            .unwrap_or(if json { Format::Json } else { Format::Csv });
        let mut inputs: Vec<&Path> = vec![&args.fits];
        inputs.extend(args.model.as_deref());
        inputs.extend(args.wolff.wolff.as_deref());
        ctx.write_output(Some(out), &inputs, |w| write_file(w, out, format, &o, &cfg))?;
    }
    crate::ctx::print_stdout(text.as_bytes())
}
