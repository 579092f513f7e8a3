//! `polarid evaluate FITS.csv`: leave-one-out evaluation of the classifier over a labelled
//! set of fits (or, with `--model`, evaluation of a trained model on a labelled test set):
//! confusion matrix and accuracy, printed as a table and optionally written as CSV or JSON.
//!
//! # Wolff's baseline (`--wolff MEASUREMENTS.csv`)
//!
//! The paper's comparison: the (n, k) classifier tells materials apart *within* a category
//! (aluminum from copper), Wolff's Fresnel-ratio rule only metal from dielectric. With
//! `--wolff`, the same evaluated targets (labelled, fit status `ok`) are also classified by
//! Wolff's rule from their DoLP measurements, and its metal/dielectric confusion matrix and
//! accuracy are reported next to the classifier's, together with the classifier's own
//! accuracy on those targets by material and by metal/dielectric.
//!
//! The true category of a label is, first match wins:
//!
//! 1. `--wolff-category CLASS=CATEGORY` (repeatable);
//! 2. with `--model`, the `category` of the model's prototypes of that class;
//! 3. the `category` of the material of that name in `--wolff-library` (`builtin` by
//!    default, `paper2007`, or a library CSV `name,n,k,category`): the library is where
//!    categories are curated (a model trained by `polarid train` has none).
//!
//! Names match ignoring case, with spaces and underscores equivalent (`green paint` is
//! `green_paint`). Only targets whose category is `metal` or `dielectric` are scored; the
//! others (`semiconductor`, `other`, or no category) are listed as not scored. Wolff's
//! `unknown` (no measurement in the β window) counts as wrong.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use clap::ValueEnum;
use polarid_core::classify::{
    Classifier, Confusion, Evaluation, Labelled, Prototype, WolffDecision, evaluate, leave_one_out,
    wolff_classify,
};
use polarid_io::IoError;
use polarid_io::library::Library;
use polarid_io::model::Model;
use polarid_io::table::{fmt_f64, write_rows};

use super::classify::{MethodArgs, WolffArgs, estimate_of, read_fits};
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

/// Categories accepted by `--wolff-category`.
const CATEGORIES: [&str; 4] = ["metal", "dielectric", "semiconductor", "other"];

/// A class name as matched against categories: lower case, spaces as underscores.
fn name_key(class: &str) -> String {
    class.trim().to_lowercase().replace(' ', "_")
}

/// Where the true categories of the classes come from, in order of precedence.
struct Categories {
    /// `(source label, class key → category)`, first match wins.
    sources: Vec<(String, BTreeMap<String, String>)>,
}

impl Categories {
    fn new(args: &Args, model: Option<&[Prototype]>) -> anyhow::Result<Self> {
        let mut sources = Vec::new();
        if !args.wolff_category.is_empty() {
            let mut m = BTreeMap::new();
            for spec in &args.wolff_category {
                let (class, cat) = spec
                    .split_once('=')
                    .map(|(a, b)| (a.trim(), b.trim()))
                    .filter(|(a, b)| !a.is_empty() && CATEGORIES.contains(b))
                    .ok_or_else(|| {
                        BadInput(format!(
                            "--wolff-category `{spec}`: expected CLASS=CATEGORY with CATEGORY \
                             one of {}",
                            CATEGORIES.join(", ")
                        ))
                    })?;
                m.insert(name_key(class), cat.to_string());
            }
            sources.push(("--wolff-category".to_string(), m));
        }
        let keyed = |protos: &[Prototype]| {
            let mut m = BTreeMap::new();
            for p in protos {
                if let Some(c) = &p.category {
                    m.entry(name_key(&p.class)).or_insert_with(|| c.clone());
                }
            }
            m
        };
        if let (Some(protos), Some(path)) = (model, &args.model) {
            sources.push((format!("model {}", path.display()), keyed(protos)));
        }
        let lib = Library::load(&args.wolff_library)?;
        sources.push((
            format!("library {}", args.wolff_library),
            keyed(&lib.prototypes()),
        ));
        Ok(Self { sources })
    }

    /// The category of `class` and where it came from.
    fn of(&self, class: &str) -> Option<(&str, &str)> {
        let key = name_key(class);
        self.sources
            .iter()
            .find_map(|(src, m)| m.get(&key).map(|c| (c.as_str(), src.as_str())))
    }

    /// The sources, for messages: `--wolff-category, library builtin`.
    fn describe(&self) -> String {
        self.sources
            .iter()
            .map(|(s, _)| s.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Wolff's decision on one evaluated target.
struct WolffItem {
    target: String,
    class: String,
    /// True category (`metal` or `dielectric`).
    category: String,
    /// Where `category` came from.
    category_source: String,
    decision: WolffDecision,
    /// The (n, k) classifier's prediction.
    predicted: String,
    /// Category of the classifier's prediction (`unknown` when it has none).
    predicted_category: String,
}

/// Wolff's baseline on the evaluated targets.
struct WolffEval {
    /// Settings, e.g. `Fresnel ratio threshold 6, beta in [40, 70] deg`.
    settings: String,
    /// The measurements file.
    measurements: PathBuf,
    /// Where the categories came from.
    categories: String,
    /// Scored targets.
    items: Vec<WolffItem>,
    /// Targets not scored: `(target, class, category)`.
    not_scored: Vec<(String, String, Option<String>)>,
    /// Scored targets without any row in the measurements file.
    no_rows: Vec<String>,
    /// Rows: true category; columns: Wolff's class.
    confusion: Confusion,
    /// Wolff's metal/dielectric accuracy.
    accuracy: f64,
    /// The classifier's `(correct, total)` on the scored targets, by material.
    nn_material: (u64, u64),
    /// The classifier's `(correct, total)` on the scored targets, by metal/dielectric.
    nn_binary: (u64, u64),
}

fn ratio((c, t): (u64, u64)) -> f64 {
    if t == 0 {
        f64::NAN
    } else {
        c as f64 / t as f64
    }
}

/// Run Wolff's rule on the evaluated targets of `ev`.
fn wolff_eval(
    args: &Args,
    ev: &Evaluation,
    model: Option<&[Prototype]>,
) -> anyhow::Result<Option<WolffEval>> {
    let Some((path, cfg, obs)) = args.wolff.load()? else {
        return Ok(None);
    };
    let cats = Categories::new(args, model)?;
    let mut items = Vec::new();
    let mut not_scored = Vec::new();
    let mut no_rows = Vec::new();
    for it in &ev.items {
        let (category, source) = match cats.of(&it.class) {
            Some((c @ ("metal" | "dielectric"), src)) => (c.to_string(), src.to_string()),
            other => {
                not_scored.push((
                    it.target.clone(),
                    it.class.clone(),
                    other.map(|(c, _)| c.to_string()),
                ));
                continue;
            }
        };
        let rows = obs.get(&it.target).map(Vec::as_slice).unwrap_or(&[]);
        if rows.is_empty() {
            no_rows.push(it.target.clone());
        }
        let decision = wolff_classify(rows, &cfg)
            .map_err(|e| BadInput(format!("{}: target {}: {e}", path.display(), it.target)))?;
        let predicted = it.decision.predicted.clone();
        let predicted_category = match cats.of(&predicted) {
            Some((c, _)) => c.to_string(),
            None => polarid_core::classify::UNKNOWN.to_string(),
        };
        items.push(WolffItem {
            target: it.target.clone(),
            class: it.class.clone(),
            category,
            category_source: source,
            decision,
            predicted,
            predicted_category,
        });
    }
    let confusion = Confusion::from_pairs(
        items
            .iter()
            .map(|i| (i.category.as_str(), i.decision.class.name())),
    );
    let accuracy = confusion.accuracy();
    let total = items.len() as u64;
    let nn_material = (
        items.iter().filter(|i| i.predicted == i.class).count() as u64,
        total,
    );
    let nn_binary = (
        items
            .iter()
            .filter(|i| i.predicted_category == i.category)
            .count() as u64,
        total,
    );
    Ok(Some(WolffEval {
        settings: args.wolff.describe(),
        measurements: path.to_path_buf(),
        categories: cats.describe(),
        items,
        not_scored,
        no_rows,
        confusion,
        accuracy,
        nn_material,
        nn_binary,
    }))
}

/// Wolff's part of the printed summary.
fn wolff_table(w: &WolffEval) -> String {
    let mut s = format!(
        "Wolff's baseline, metal vs dielectric ({}; measurements {}; true categories from {}): \
         confusion matrix (rows: true category, columns: Wolff)\n",
        w.settings,
        w.measurements.display(),
        w.categories
    );
    s.push_str(&matrix(&w.confusion, "true\\wolff"));
    s.push_str(&format!(
        "wolff accuracy (metal/dielectric): {:.4} ({}/{})\n",
        w.accuracy,
        w.confusion.correct(),
        w.confusion.total()
    ));
    s.push_str(&format!(
        "nearest neighbour on the same targets: {:.4} ({}/{}) by material, {:.4} ({}/{}) by \
         metal/dielectric\n",
        ratio(w.nn_material),
        w.nn_material.0,
        w.nn_material.1,
        ratio(w.nn_binary),
        w.nn_binary.0,
        w.nn_binary.1
    ));
    for (t, c, cat) in &w.not_scored {
        match cat {
            Some(cat) => s.push_str(&format!(
                "wolff: not scored {t}: class `{c}` has category `{cat}`, not metal or \
                 dielectric\n"
            )),
            None => s.push_str(&format!(
                "wolff: not scored {t}: class `{c}` has no category (give one with \
                 --wolff-category '{c}=metal|dielectric')\n"
            )),
        }
    }
    for t in &w.no_rows {
        s.push_str(&format!(
            "wolff: warning: target {t} has no row in {}; Wolff answers unknown\n",
            w.measurements.display()
        ));
    }
    s
}

/// Wolff's lines of the CSV output (`#` comments after the classifier's header line).
fn wolff_csv_header(w: &WolffEval) -> String {
    let c = &w.confusion;
    let mut s = format!(
        "# wolff, metal vs dielectric ({}; measurements {}; true categories from {}): \
         accuracy {} ({}/{}); nearest neighbour on the same targets: {} ({}/{}) by material, \
         {} ({}/{}) by metal/dielectric\n",
        w.settings,
        w.measurements.display(),
        w.categories,
        fmt_f64(w.accuracy),
        c.correct(),
        c.total(),
        fmt_f64(ratio(w.nn_material)),
        w.nn_material.0,
        w.nn_material.1,
        fmt_f64(ratio(w.nn_binary)),
        w.nn_binary.0,
        w.nn_binary.1
    );
    s.push_str(&format!(
        "# wolff confusion: truth,{},total\n",
        c.predicted.join(",")
    ));
    // ok (c.counts[r]): one row of counts per true category.
    for (r, t) in c.truth.iter().enumerate() {
        let counts: Vec<String> = c.counts[r].iter().map(u64::to_string).collect();
        s.push_str(&format!(
            "# wolff confusion: {t},{},{}\n",
            counts.join(","),
            c.counts[r].iter().sum::<u64>()
        ));
    }
    for (t, cl, cat) in &w.not_scored {
        s.push_str(&format!(
            "# wolff not scored: {t} (class {cl}, category {})\n",
            cat.as_deref().unwrap_or("none")
        ));
    }
    s
}

fn wolff_json(w: &WolffEval) -> serde_json::Value {
    let num = |x: f64| {
        if x.is_finite() {
            serde_json::json!(x)
        } else {
            serde_json::Value::Null
        }
    };
    let c = &w.confusion;
    serde_json::json!({
        "settings": w.settings,
        "measurements": w.measurements.display().to_string(),
        "categories_from": w.categories,
        "accuracy": num(w.accuracy),
        "correct": c.correct(),
        "total": c.total(),
        "truth": c.truth,
        "predicted": c.predicted,
        "counts": c.counts,
        "classifier_accuracy_material": num(ratio(w.nn_material)),
        "classifier_correct_material": w.nn_material.0,
        "classifier_accuracy_metal_dielectric": num(ratio(w.nn_binary)),
        "classifier_correct_metal_dielectric": w.nn_binary.0,
        "not_scored": w.not_scored.iter().map(|(t, c, cat)| serde_json::json!({
            "target": t, "class": c, "category": cat,
        })).collect::<Vec<_>>(),
        "no_rows": w.no_rows,
        "items": w.items.iter().map(|i| serde_json::json!({
            "target": i.target,
            "class": i.class,
            "category": i.category,
            "category_from": i.category_source,
            "wolff": i.decision.class.name(),
            "fr_max": num(i.decision.fr_max),
            "beta_deg": num(i.decision.beta_at_max.to_degrees()),
            "used": i.decision.used,
            "predicted": i.predicted,
            "predicted_category": i.predicted_category,
        })).collect::<Vec<_>>(),
    })
}

/// A confusion matrix as an aligned text table with a `total` column.
fn matrix(c: &Confusion, corner: &str) -> String {
    let mut s = String::new();
    let w0 = c
        .truth
        .iter()
        .map(String::len)
        .chain([10])
        .max()
        .unwrap_or(10);
    let widths: Vec<usize> = c.predicted.iter().map(|p| p.len().max(5)).collect();
    s.push_str(&format!("{corner:<w0$}"));
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
    s
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
    let model = args
        .model
        .as_ref()
        .map(|m| Model::read(m).map(|model| model.prototypes()))
        .transpose()?;
    let (ev, mode) = match (&args.model, &model) {
        (Some(m), Some(protos)) => {
            let clf = Classifier::new(protos.clone(), cfg)?;
            (
                evaluate(&clf, &items)
                    .map_err(|e| BadInput(format!("{}: {e}", args.fits.display())))?,
                format!("model {}", m.display()),
            )
        }
        _ => (
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
    // Wolff's baseline before any output, so that bad input writes nothing.
    let wolff = wolff_eval(&args, &ev, model.as_deref())?;
    let mut text = table(&ev, &mode);
    if let Some(w) = &wolff {
        text.push_str(&wolff_table(w));
    }
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
        if let Some(w) = &args.wolff.wolff {
            inputs.push(w);
        }
        ctx.write_output(Some(out), &inputs, |w| match format {
            Format::Csv => write_csv(
                w,
                out,
                &ev,
                &format!(
                    "# {mode}, metric {}, k = {}: accuracy {} ({}/{})\n{}",
                    cfg.metric.name(),
                    cfg.k,
                    fmt_f64(ev.accuracy),
                    ev.confusion.correct(),
                    ev.confusion.total(),
                    wolff.as_ref().map(wolff_csv_header).unwrap_or_default()
                ),
            ),
            Format::Json => {
                let mut v = to_json(&ev, &mode, cfg.metric.name(), cfg.k);
                if let (Some(w), Some(o)) = (&wolff, v.as_object_mut()) {
                    o.insert("wolff".into(), wolff_json(w));
                }
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
