//! Locating values of a TOML document for error messages (manifest and scene files):
//! the 1-based line of a byte offset, a short snippet of the value, and the
//! [`IoError::Manifest`] that names file, line, field and value.

use std::ops::Range;
use std::path::Path;

use crate::error::IoError;

/// A TOML document being parsed: its file (for messages) and its text.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TomlText<'a> {
    /// The file the text came from.
    pub path: &'a Path,
    /// The whole text.
    pub text: &'a str,
}

impl TomlText<'_> {
    /// 1-based line number of byte offset `pos`.
    pub fn line(&self, pos: usize) -> usize {
        let end = pos.min(self.text.len());
        self.text.as_bytes()[..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1
    }

    /// The text of `span` on one line, shortened to 60 characters.
    pub fn snippet(&self, span: &Range<usize>) -> String {
        let s = self
            .text
            .get(span.clone())
            .unwrap_or("")
            .trim()
            .replace('\n', " ");
        if s.chars().count() > 60 {
            let t: String = s.chars().take(57).collect();
            format!("{t}...")
        } else {
            s
        }
    }

    /// An error about the value at `span` of the dotted `field`.
    pub fn err(&self, span: &Range<usize>, field: &str, reason: impl Into<String>) -> IoError {
        IoError::Manifest {
            path: self.path.to_path_buf(),
            line: self.line(span.start),
            field: field.to_string(),
            value: self.snippet(span),
            reason: reason.into(),
        }
    }
}
