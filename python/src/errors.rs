//! The one place where polarid's Rust errors become Python exceptions.
//!
//! Every binding converts with [`PyResultExt::py_err`] (`result.py_err()?`), so that
//! Python users see exactly the message the CLI prints: the error and its causes joined
//! by `: `, built by the same function ([`polarid_io::error::chain_message`]):
//!
//! | Rust error | Python exception |
//! | --- | --- |
//! | any [`CoreError`] (bad argument or unusable data) | `ValueError` |
//! | [`IoError::Io`], file not found | `FileNotFoundError` |
//! | [`IoError::Io`], permission denied | `PermissionError` |
//! | [`IoError::Io`], is a directory | `IsADirectoryError` |
//! | [`IoError::Io`], other bad-input kinds ([`IoError::is_bad_input`]) | `ValueError` |
//! | [`IoError::Io`], anything else (disk full ...) | `OSError` |
//! | [`IoError::OutputExists`] | `FileExistsError` |
//! | every other [`IoError`] (bad file content: CSV, manifest, image, model) | `ValueError` |
//! | [`PipelineError::Io`], [`PipelineError::Core`] | as the error it wraps |
//! | every other [`PipelineError`] (configuration, data) | `ValueError` |

use std::io::ErrorKind;

use polarid_core::CoreError;
use polarid_io::IoError;
use polarid_io::error::chain_message;
use polarid_pipeline::PipelineError;
use pyo3::PyErr;
use pyo3::exceptions::{
    PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyOSError, PyPermissionError,
    PyValueError,
};

/// Conversion of a polarid error into the Python exception documented in this module.
pub trait IntoPyErr {
    /// The Python exception, with the error's full message (its `Display`, then its
    /// causes) as its message.
    fn into_py_err(self) -> PyErr;
}

impl IntoPyErr for CoreError {
    fn into_py_err(self) -> PyErr {
        PyValueError::new_err(chain_message(&self))
    }
}

impl IntoPyErr for IoError {
    fn into_py_err(self) -> PyErr {
        let msg = chain_message(&self);
        match &self {
            IoError::Io { source, .. } => match source.kind() {
                ErrorKind::NotFound => PyFileNotFoundError::new_err(msg),
                ErrorKind::PermissionDenied => PyPermissionError::new_err(msg),
                ErrorKind::IsADirectory => PyIsADirectoryError::new_err(msg),
                _ if self.is_bad_input() => PyValueError::new_err(msg),
                _ => PyOSError::new_err(msg),
            },
            IoError::OutputExists { .. } => PyFileExistsError::new_err(msg),
            _ => PyValueError::new_err(msg),
        }
    }
}

impl IntoPyErr for PipelineError {
    fn into_py_err(self) -> PyErr {
        match self {
            PipelineError::Io(e) => e.into_py_err(),
            PipelineError::Core(e) => e.into_py_err(),
            // The option as the Python keyword (`--min-s0` -> `min_s0`).
            PipelineError::Config {
                option,
                value,
                reason,
            } => {
                let name = option.trim_start_matches("--").replace('-', "_");
                PyValueError::new_err(format!("{name} {reason}, got {value}"))
            }
            other => PyValueError::new_err(chain_message(&other)),
        }
    }
}

/// `result.py_err()?` turns a `Result<T, CoreError>`, `Result<T, IoError>` or
/// `Result<T, PipelineError>` into a `PyResult<T>`.
pub trait PyResultExt<T> {
    /// Map the error with [`IntoPyErr`].
    fn py_err(self) -> pyo3::PyResult<T>;
}

impl<T, E: IntoPyErr> PyResultExt<T> for Result<T, E> {
    #[inline]
    fn py_err(self) -> pyo3::PyResult<T> {
        self.map_err(IntoPyErr::into_py_err)
    }
}

/// A `ValueError` for a Python-level usage error that has no Rust counterpart (array
/// shapes that do not broadcast, wrong dimensionality ...).
pub fn value_error(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}
