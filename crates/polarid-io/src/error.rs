//! Errors of the I/O crate.

use std::path::PathBuf;

use polarid_core::CoreError;
use thiserror::Error;

/// Everything that can go wrong reading or writing polarid's files.
///
/// Variants name the file and, where there is one, the line, field and value at fault.
#[non_exhaustive]
#[derive(Debug, Error)]
pub enum IoError {
    /// The operating system refused to read or write a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error (shown in this error's message, so not chained as a
        /// source: `{:#}` would print it twice).
        source: std::io::Error,
    },
    /// An image file that cannot be used (format, colour, pages, size, corruption).
    #[error("{path}: {reason}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A bad value in a CSV file.
    #[error("{path}: line {line}, column `{column}`: {reason} (value {value:?})")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number (0 when unknown).
        line: u64,
        /// Column name.
        column: String,
        /// The offending text.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// A CSV file that lacks a required column or cannot be parsed at all.
    #[error("{path}: {reason}")]
    CsvStructure {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A bad field in a TOML manifest or scene file.
    #[error("{path}: line {line}, field `{field}`: {reason} (value {value})")]
    Manifest {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the field (0 when unknown).
        line: usize,
        /// Dotted field path, e.g. `capture[2].theta_i_deg`.
        field: String,
        /// The offending value as written.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// A model or library file (JSON, YAML) that cannot be used.
    #[error("{path}: {reason}")]
    Model {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// An output file exists and `--force` was not given.
    #[error("{path}: output exists (use --force to overwrite)")]
    OutputExists {
        /// The file.
        path: PathBuf,
    },
    /// An output path that would overwrite one of the inputs.
    #[error("{path}: refusing to overwrite an input file")]
    OverwritesInput {
        /// The file.
        path: PathBuf,
    },
    /// A core error, with the file it came from.
    #[error("{path}: {source}")]
    Core {
        /// The file whose data caused it.
        path: PathBuf,
        /// The core error (shown in this error's message).
        source: CoreError,
    },
}

impl IoError {
    /// True when the error is caused by the user's input (exit status 2), false for
    /// failures of the machine (disk full, permission denied on an output: status 1).
    pub fn is_bad_input(&self) -> bool {
        match self {
            IoError::Io { source, .. } => matches!(
                source.kind(),
                std::io::ErrorKind::NotFound
                    | std::io::ErrorKind::InvalidData
                    | std::io::ErrorKind::InvalidInput
                    | std::io::ErrorKind::UnexpectedEof
                    | std::io::ErrorKind::IsADirectory
            ),
            _ => true,
        }
    }

    /// Wrap an [`std::io::Error`] with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        IoError::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result alias of the I/O crate.
pub type Result<T> = std::result::Result<T, IoError>;
