//! Errors of the I/O crate, and [`chain_message`], the one way an error and its causes
//! are shown to users (CLI and Python).
//!
//! Each error's `Display` says only its own level (the file, line, field and value at
//! fault); an underlying error is its `source()`, never repeated in the message.

use std::error::Error as StdError;
use std::path::PathBuf;

use polarid_core::CoreError;
use thiserror::Error;

/// Everything that can go wrong reading or writing polarid's files.
///
/// Variants name the file and, where there is one, the line, field and value at fault.
#[non_exhaustive]
#[derive(Debug, Error)]
pub enum IoError {
    /// The operating system refused to read or write a file. The message names the
    /// file; the operating system's reason is the [`source`](StdError::source).
    #[error("{path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error (chained as this error's source).
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
    /// Another run published the same output directory while this one was writing it:
    /// exactly one of them wins.
    #[error(
        "{path}: another polarid run wrote this output directory at the same time; \
             this run's output was not published"
    )]
    Concurrent {
        /// The output directory.
        path: PathBuf,
    },
    /// An input or a piece of work over the memory budget
    /// ([`crate::limits::memory_limit`]), or a decompression bomb: refused before
    /// anything is allocated.
    #[error(
        "{path}: {what}, more than the memory limit of {} (raise it with --memory-limit \
         or POLARID_MEMORY_LIMIT)",
        human(*limit)
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// What would need the memory, and how much.
        what: String,
        /// The budget in force, in bytes.
        limit: u64,
    },
    /// An input that is not a regular file (a device such as `/dev/zero`, a FIFO, a
    /// socket or a directory).
    #[error("{path}: is {kind}, not a regular file")]
    NotRegular {
        /// The file.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// A core error, with the file it came from. The message names the file; the core
    /// error is the [`source`](StdError::source).
    #[error("{path}")]
    Core {
        /// The file whose data caused it.
        path: PathBuf,
        /// The core error (chained as this error's source).
        source: CoreError,
    },
}

impl IoError {
    /// True when the error is caused by the user's input (exit status 2), false for
    /// failures of the machine (disk full, permission denied on an output: status 1).
    pub fn is_bad_input(&self) -> bool {
        match self {
            IoError::Io { source, .. } => is_bad_path(source),
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

    /// An [`IoError::Model`]: file `path` is not a valid model or optical-data file, or
    /// its data cannot give what was asked, for `reason`.
    pub fn model(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        IoError::Model {
            path: path.into(),
            reason: reason.into(),
        }
    }

    /// Wrap a [`CoreError`] with the file whose data caused it.
    pub fn core(path: impl Into<PathBuf>, source: CoreError) -> Self {
        IoError::Core {
            path: path.into(),
            source,
        }
    }
}

/// True when an operating-system error is the fault of the path or data the user gave
/// (exit status 2): a missing file or directory, a path through a file (`ENOTDIR`), a
/// directory where a file is needed (`EISDIR`) or the reverse, a symbolic-link loop
/// (`ELOOP`), a name too long, bad data. Permission, disk-full and device errors are
/// the machine's (status 1).
pub fn is_bad_path(e: &std::io::Error) -> bool {
    use std::io::ErrorKind as K;
    if matches!(
        e.kind(),
        K::NotFound
            | K::InvalidData
            | K::InvalidInput
            | K::UnexpectedEof
            | K::IsADirectory
            | K::NotADirectory
            | K::AlreadyExists
            | K::DirectoryNotEmpty
            | K::InvalidFilename
    ) {
        return true;
    }
    // ELOOP (symbolic-link loop) has no stable kind to match; errors wrapped by other
    // crates (tempfile) keep the kind but lose the OS code.
    if matches!(
        format!("{:?}", e.kind()).as_str(),
        "FilesystemLoop" | "NotADirectory" | "InvalidFilename"
    ) {
        return true;
    }
    // ELOOP and ENAMETOOLONG by their OS codes.
    #[cfg(target_os = "linux")]
    const BAD: [i32; 3] = [40, 36, 20]; // ELOOP, ENAMETOOLONG, ENOTDIR
    #[cfg(all(unix, not(target_os = "linux")))]
    const BAD: [i32; 3] = [62, 63, 20];
    #[cfg(not(unix))]
    const BAD: [i32; 0] = [];
    e.raw_os_error().is_some_and(|c| BAD.contains(&c))
}

/// `err` and its chain of causes ([`source`](StdError::source)), joined by `": "`: the
/// full message users see, e.g. `"scene.toml: No such file or directory (os error 2)"`.
///
/// Every error is shown once: each level's `Display` carries only its own part, so
/// nothing is left out or de-duplicated here.
pub fn chain_message(err: &dyn StdError) -> String {
    let mut msg = err.to_string();
    let mut cause = err.source();
    while let Some(c) = cause {
        msg.push_str(": ");
        msg.push_str(&c.to_string());
        cause = c.source();
    }
    msg
}

/// Result alias of the I/O crate.
pub type Result<T> = std::result::Result<T, IoError>;

/// A byte count for messages: `3.0 GiB`, `12.5 MiB`, `800 bytes`.
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if bytes >= 1 << 30 {
        format!("{:.1} GiB", b / (1u64 << 30) as f64)
    } else if bytes >= 1 << 20 {
        format!("{:.1} MiB", b / (1u64 << 20) as f64)
    } else if bytes >= 1 << 10 {
        format!("{:.1} KiB", b / 1024.0)
    } else {
        format!("{bytes} bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn io_error_is_chained_and_printed_once() {
        let os = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file (test)");
        let e = IoError::io("scene.toml", os);
        assert_eq!(e.to_string(), "scene.toml");
        let source = e.source().map(ToString::to_string);
        assert_eq!(source.as_deref(), Some("no such file (test)"));
        let msg = chain_message(&e);
        assert_eq!(msg, "scene.toml: no such file (test)");
        assert_eq!(msg.matches("no such file (test)").count(), 1, "{msg}");
    }

    #[test]
    fn core_error_is_chained_and_printed_once() {
        let e = IoError::Core {
            path: "raw.png".into(),
            source: CoreError::TooFew {
                what: "frames",
                needed: 3,
                got: 0,
            },
        };
        assert_eq!(e.to_string(), "raw.png");
        let msg = chain_message(&e);
        assert_eq!(msg, "raw.png: need at least 3 frames, got 0");
        assert_eq!(msg.matches("need at least").count(), 1, "{msg}");
    }

    #[test]
    fn every_level_of_a_longer_chain_is_shown_once_in_order() {
        #[derive(Debug, Error)]
        #[error("reading the model")]
        struct Outer(#[source] IoError);
        let inner = IoError::io("m.json", std::io::Error::other("disk on fire"));
        let msg = chain_message(&Outer(inner));
        assert_eq!(msg, "reading the model: m.json: disk on fire");
        // A message that happens to contain its cause's text is not shortened.
        #[derive(Debug, Error)]
        #[error("m.json")]
        struct Same(#[source] IoError);
        let msg = chain_message(&Same(IoError::io("m.json", std::io::Error::other("x"))));
        assert_eq!(msg, "m.json: m.json: x");
    }
}
