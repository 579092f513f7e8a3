//! `polarid evaluate FITS.csv`: leave-one-out evaluation of the classifier over a labelled
//! set of fits (or, with `--model`, evaluation of a trained model on a labelled test set):
//! confusion matrix and accuracy, and the consistent sets' coverage (truth in the set) and
//! sizes, printed as a table and optionally written as CSV or JSON.
//! With `--wolff MEASUREMENTS.csv`, Wolff's metal/dielectric baseline is scored next to
//! it (see `polarid_pipeline::evaluate` for the rules).

mod file;

use std::path::{Path, PathBuf};

use clap::ValueEnum;
use polarid_core::classify::Evaluation;
use polarid_pipeline::classify::read_fits;
use polarid_pipeline::evaluate::{self as pipe, CATEGORIES, EvaluateConfig, WolffEvalRequest};

use self::file::{sets_line, write_file};
use super::common::{MethodArgs, PipeResult, matrix};
use super::wolff::{WolffArgs, wolff_table};
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
        ctx.write_output(Some(out), &inputs, |w, _| {
            write_file(w, out, format, &o, &cfg)
        })?;
    }
    crate::ctx::print_stdout(text.as_bytes())
}
