//! What the commands built on `polarid_pipeline` share: the pipeline's errors as the
//! CLI's (exit statuses and messages), its progress reports as progress bars, and its
//! warnings on standard error.

use std::sync::Mutex;

use polarid_pipeline::{PipelineError, Warning};

use crate::{BadInput, Ctx};

/// A pipeline error as the CLI reports it: I/O and core errors keep their type (exit
/// status by kind), a configuration error reads `OPTION REASON, got VALUE` (e.g.
/// `--bin must be in 1..=64, got 0`), other bad data is a [`BadInput`] (exit status 2).
pub fn cli_err(e: PipelineError) -> anyhow::Error {
    match e {
        PipelineError::Io(e) => e.into(),
        PipelineError::Core(e) => e.into(),
        PipelineError::Config {
            option,
            value,
            reason,
        } => BadInput(format!("{option} {reason}, got {value}")).into(),
        e => BadInput(e.to_string()).into(),
    }
}

/// `result.cli()?`: [`cli_err`] on a pipeline result.
pub trait CliResult<T> {
    /// Convert the error with [`cli_err`].
    fn cli(self) -> anyhow::Result<T>;
}

impl<T> CliResult<T> for Result<T, PipelineError> {
    fn cli(self) -> anyhow::Result<T> {
        self.map_err(cli_err)
    }
}

/// Print warnings (`polarid: warning: ...`) unless `--quiet`.
pub fn warn_all<'a>(ctx: &Ctx, warnings: impl IntoIterator<Item = &'a Warning>) {
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
