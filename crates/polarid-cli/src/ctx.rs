//! Run context shared by the commands: output policy, progress, exit statuses, and
//! the small helpers every command uses to write its outputs.

use std::io::{IsTerminal, Write};
use std::path::Path;

use polarid_core::CoreError;
use polarid_io::IoError;
use polarid_pipeline::PipelineError;

/// Options common to every command.
#[derive(Debug, Clone)]
pub struct Ctx {
    /// Overwrite existing outputs.
    pub force: bool,
    /// Suppress progress and informational messages.
    pub quiet: bool,
    /// Standard error is a terminal (progress bars are drawn only then).
    pub stderr_is_tty: bool,
}

impl Ctx {
    /// Context from the global flags.
    pub fn new(force: bool, quiet: bool) -> Self {
        Self {
            force,
            quiet,
            stderr_is_tty: std::io::stderr().is_terminal(),
        }
    }

    /// A progress bar of `len` steps, hidden unless standard error is a terminal.
    pub fn progress(&self, len: u64, what: &str) -> indicatif::ProgressBar {
        if self.quiet || !self.stderr_is_tty {
            return indicatif::ProgressBar::hidden();
        }
        let pb = indicatif::ProgressBar::new(len);
        if let Ok(style) =
            indicatif::ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} ({eta})")
        {
            pb.set_style(style.progress_chars("=> "));
        }
        pb.set_message(what.to_string());
        pb
    }

    /// Print an informational message on standard error unless `--quiet`.
    pub fn info(&self, msg: impl AsRef<str>) {
        if !self.quiet {
            eprintln!("{}", msg.as_ref());
        }
    }

    /// Write a text output to `path` atomically, or to standard output when `path` is
    /// `None` or `-`. `inputs` are never overwritten. `write` gets the output's name for
    /// its messages (`<stdout>` for standard output).
    pub fn write_output(
        &self,
        path: Option<&Path>,
        inputs: &[&Path],
        write: impl FnOnce(&mut dyn Write, &Path) -> polarid_io::Result<()>,
    ) -> anyhow::Result<()> {
        match path.filter(|p| !polarid_io::limits::is_stdin(p)) {
            Some(p) => {
                polarid_io::atomic::check_output(p, self.force, inputs)?;
                polarid_io::atomic::write_atomic(p, self.force, |w| write(w, p))?;
            }
            None => {
                // Build the whole output first so that a failure prints nothing.
                let mut buf: Vec<u8> = Vec::new();
                write(&mut buf, Path::new("<stdout>"))?;
                print_stdout(&buf)?;
            }
        }
        Ok(())
    }
}

/// Write `bytes` to standard output and flush. A closed pipe (`polarid ... | head`) is not
/// a failure; any other error says `cannot write to standard output`.
pub fn print_stdout(bytes: &[u8]) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(bytes).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(anyhow::Error::new(e).context("cannot write to standard output")),
        Ok(()) => Ok(()),
    }
}

/// A usage or input error found by the CLI itself (exit status 2).
#[derive(Debug)]
pub struct BadInput(pub String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

/// Exit status for an error: 2 when the user's input or usage is at fault, 1 otherwise.
///
/// The first polarid error in the chain decides (a [`PipelineError`] is asked before the
/// error it wraps transparently, which its chain does not list).
pub fn exit_status(e: &anyhow::Error) -> u8 {
    let status = |bad_input: bool| if bad_input { 2 } else { 1 };
    for cause in e.chain() {
        if cause.is::<BadInput>() || cause.is::<CoreError>() {
            return 2;
        }
        if let Some(io) = cause.downcast_ref::<IoError>() {
            return status(io.is_bad_input());
        }
        if let Some(p) = cause.downcast_ref::<PipelineError>() {
            return status(p.is_bad_input());
        }
    }
    1
}
