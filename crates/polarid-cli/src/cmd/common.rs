//! Pieces shared by the commands that call `polarid_pipeline`: the pipeline's errors as
//! the CLI's (exit statuses and messages), its progress reports as progress bars, its
//! warnings on standard error, and the classifier options of `classify` and `evaluate`.

use std::path::Path;
use std::sync::Mutex;

use clap::ValueEnum;
use polarid_core::classify::{ClassifierConfig, Confusion, Metric, Rule};
use polarid_io::atomic::StagedDir;
use polarid_pipeline::PipelineError;
use polarid_pipeline::options::ClassifierOptions;

use crate::{BadInput, Ctx};

/// A pipeline error as a CLI error with the same message and exit status: file and core
/// errors keep their type (their exit status follows from it), the rest (a configuration
/// error reads `OPTION REASON, got VALUE`) is a [`BadInput`] (status 2) or, if not the
/// user's fault, a plain error (status 1).
pub fn cli_err(e: PipelineError) -> anyhow::Error {
    match e {
        PipelineError::Io(e) => e.into(),
        PipelineError::Core(e) => e.into(),
        e if e.is_bad_input() => BadInput(e.to_string()).into(),
        e => anyhow::anyhow!(e.to_string()),
    }
}

/// `result.cli()?`: a pipeline result as an `anyhow` one, through [`cli_err`].
pub trait PipeResult<T> {
    /// Map the error with [`cli_err`].
    fn cli(self) -> anyhow::Result<T>;
}

impl<T> PipeResult<T> for polarid_pipeline::Result<T> {
    fn cli(self) -> anyhow::Result<T> {
        self.map_err(cli_err)
    }
}

/// The staging of the output directory `dir` (an existing file there is a usage error).
pub fn output_dir(dir: &Path, ctx: &Ctx) -> anyhow::Result<StagedDir> {
    if dir.is_file() {
        return Err(BadInput(format!(
            "{}: the output must be a directory, and this is a file",
            dir.display()
        ))
        .into());
    }
    Ok(StagedDir::new(dir, ctx.force)?)
}

/// Print warnings (`polarid: warning: ...`) unless `--quiet`.
pub fn warn_all(ctx: &Ctx, warnings: impl IntoIterator<Item = impl std::fmt::Display>) {
    for w in warnings {
        ctx.info(format!("polarid: warning: {w}"));
    }
}

/// Progress bars for a pipeline's [`polarid_pipeline::Progress`] reports: one bar per
/// stage, replaced when the stage changes, cleared on drop.
pub struct Bars<'a> {
    ctx: &'a Ctx,
    current: Mutex<Option<(String, indicatif::ProgressBar)>>,
}

impl<'a> Bars<'a> {
    /// No bar yet.
    pub fn new(ctx: &'a Ctx) -> Self {
        Self {
            ctx,
            current: Mutex::new(None),
        }
    }

    /// The progress callback: `(stage, done, total)`.
    pub fn report(&self, stage: &str, done: u64, total: u64) {
        let Ok(mut cur) = self.current.lock() else {
            return;
        };
        if cur.as_ref().is_none_or(|(s, _)| s != stage) {
            if let Some((_, pb)) = cur.take() {
                pb.finish_and_clear();
            }
            *cur = Some((stage.to_string(), self.ctx.progress(total, stage)));
        }
        if let Some((_, pb)) = cur.as_ref() {
            pb.set_position(done);
        }
    }
}

impl Drop for Bars<'_> {
    fn drop(&mut self) {
        if let Ok(mut cur) = self.current.lock()
            && let Some((_, pb)) = cur.take()
        {
            pb.finish_and_clear();
        }
    }
}

/// Distance metric on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MetricArg {
    /// Euclidean distance in (n, k): the paper's rule.
    Euclidean,
    /// Mahalanobis distance with the estimates' (and prototypes') covariance.
    Mahalanobis,
}

/// Decision rule on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RuleArg {
    /// Every material consistent with the estimate at --confidence: one → it, several →
    /// `ambiguous`, none → `unknown` (Mahalanobis distance; needs standard errors).
    Set,
    /// The paper's nearest neighbour (with --metric, --k, --reject, --max-distance).
    Nearest,
}

/// Classifier options shared by `classify` and `evaluate`.
#[derive(Debug, Clone, clap::Args)]
pub struct MethodArgs {
    /// Decision rule (see docs/CLASSIFY.md): `set` (the default) answers with every
    /// material consistent with the estimate; `nearest` is the paper's rule.
    #[arg(long, value_enum, default_value_t = RuleArg::Set)]
    pub rule: RuleArg,
    /// Confidence of the consistent set, in (0, 1): a material is consistent when its
    /// squared Mahalanobis distance is at most -2 ln(1 - P) (chi-square, 2 dof).
    #[arg(long, value_name = "P", default_value_t = 0.95)]
    pub confidence: f64,
    /// Distance metric of the nearest rule (default euclidean, the paper's); the set rule
    /// uses the Mahalanobis distance.
    #[arg(long, value_enum)]
    pub metric: Option<MetricArg>,
    /// Number of nearest prototypes that vote (1: the paper's nearest neighbour; ties in
    /// votes go to the class with the nearest member).
    #[arg(long = "k", value_name = "N", default_value_t = 1)]
    pub neighbours: usize,
    /// Answer `unknown` when the nearest prototype fails a chi-square gate (2 dof) on the
    /// Mahalanobis distance at probability P, e.g. 0.99 (needs standard errors).
    #[arg(long, value_name = "CHI2_P", conflicts_with = "max_distance")]
    pub reject: Option<f64>,
    /// Answer `unknown` when the nearest prototype is farther than D (in the metric's
    /// units).
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
}

impl MethodArgs {
    /// The classifier settings, checked (a bad value is a usage error naming the option
    /// and the value).
    pub fn config(&self) -> anyhow::Result<ClassifierConfig> {
        Ok(ClassifierOptions {
            rule: match self.rule {
                RuleArg::Set => Rule::Set,
                RuleArg::Nearest => Rule::Nearest,
            },
            confidence: self.confidence,
            metric: self.metric.map(|m| match m {
                MetricArg::Euclidean => Metric::Euclidean,
                MetricArg::Mahalanobis => Metric::Mahalanobis,
            }),
            neighbours: self.neighbours,
            reject: self.reject,
            max_distance: self.max_distance,
        }
        .config()?)
    }
}

/// A confusion matrix as an aligned text table with a `total` column.
pub fn matrix(c: &Confusion, corner: &str) -> String {
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
