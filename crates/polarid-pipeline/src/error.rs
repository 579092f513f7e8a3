//! Errors of the workflows.

use polarid_core::CoreError;
use polarid_io::IoError;
use thiserror::Error;

/// Everything that can stop a workflow.
///
/// Bad input (a file, a field or an option with an unusable value) is distinguished from
/// failures of the machine by [`PipelineError::is_bad_input`] (exit status 2 vs 1).
///
/// The wrappers are transparent (message and source are the wrapped error's), so the
/// full message users see, [`polarid_io::error::chain_message`], names each level once.
#[non_exhaustive]
#[derive(Debug, Error)]
pub enum PipelineError {
    /// Reading or writing a file failed, or a file holds a bad value.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The physics or numerics refused the data.
    #[error(transparent)]
    Core(#[from] CoreError),
    /// A configuration value that cannot be used; reads `OPTION REASON, got VALUE`
    /// (e.g. `--bin must be in 1..=64, got 0`).
    #[error("{option} {reason}, got {value}")]
    Config {
        /// The option or field, as the user wrote it (e.g. `--bin`, `max_distance`).
        option: String,
        /// The offending value.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// A `MIN,MAX` search range that cannot be used; reads `OPTION: REASON` (e.g.
    /// `n_range: need 0 <= MIN < MAX, got 2,1`: the reason quotes the range).
    #[error("{option}: {reason}")]
    Range {
        /// The option or field (`--n-range`, `n_range`).
        option: String,
        /// What is wrong, with the range as given.
        reason: String,
    },
    /// The data of a file cannot support the workflow (e.g. a target with too few
    /// measurements, a class the model does not know).
    #[error("{path}: {reason}")]
    Data {
        /// The file (or a description of the data's origin).
        path: String,
        /// What is wrong, naming the target, line or field.
        reason: String,
    },
}

impl PipelineError {
    /// True when the user's input or configuration is at fault (exit status 2).
    pub fn is_bad_input(&self) -> bool {
        match self {
            PipelineError::Io(e) => e.is_bad_input(),
            _ => true,
        }
    }

    /// A [`PipelineError::Config`] error.
    pub fn config(
        option: impl Into<String>,
        value: impl ToString,
        reason: impl Into<String>,
    ) -> Self {
        PipelineError::Config {
            option: option.into(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }
}

/// `Ok(())` when `ok`, else the [`PipelineError::Config`] error of `option`, `value` and
/// `reason` (a check of a configuration value: write the condition that must hold).
pub fn ensure(
    ok: bool,
    option: impl Into<String>,
    value: impl ToString,
    reason: impl Into<String>,
) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(PipelineError::config(option, value, reason))
    }
}

/// Result alias of the pipeline crate.
pub type Result<T> = std::result::Result<T, PipelineError>;

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_io::error::chain_message;

    #[test]
    fn transparent_wrappers_add_nothing_to_the_message() {
        let io = IoError::io("a.csv", std::io::Error::other("disk on fire"));
        let e = PipelineError::from(io);
        assert_eq!(chain_message(&e), "a.csv: disk on fire");
        assert!(!e.is_bad_input());
        let core = CoreError::TooFew {
            what: "frames",
            needed: 3,
            got: 1,
        };
        assert_eq!(
            chain_message(&PipelineError::from(core)),
            "need at least 3 frames, got 1"
        );
        let c = PipelineError::config("--bin", 0, "must be at least 1");
        assert_eq!(chain_message(&c), "--bin must be at least 1, got 0");
    }
}
