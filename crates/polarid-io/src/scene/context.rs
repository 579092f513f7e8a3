//! The parsing context: the file's path and text, the errors it builds
//! ([`IoError::Manifest`] with file, 1-based line, dotted field and value) and the checks
//! of single values (finite numbers, ranges, zenith angles, rectangles, names).

use std::ops::Range;
use std::path::Path;

use polarid_core::region::Rect;
use toml::Spanned;

use crate::error::{IoError, Result};
use crate::toml_span::TomlText;

pub(super) struct Ctx<'a> {
    pub(super) path: &'a Path,
    pub(super) text: &'a str,
}

impl Ctx<'_> {
    fn toml(&self) -> TomlText<'_> {
        TomlText {
            path: self.path,
            text: self.text,
        }
    }

    pub(super) fn line(&self, pos: usize) -> usize {
        self.toml().line(pos)
    }

    pub(super) fn snippet(&self, span: &Range<usize>) -> String {
        self.toml().snippet(span)
    }

    pub(super) fn err(
        &self,
        span: &Range<usize>,
        field: &str,
        reason: impl Into<String>,
    ) -> IoError {
        self.toml().err(span, field, reason)
    }

    /// An error at the first of `keys` (name, span when given) that is given: field
    /// `field(name)`, `reason`.
    pub(super) fn refuse<const N: usize>(
        &self,
        keys: [(&str, Option<Range<usize>>); N],
        field: &dyn Fn(&str) -> String,
        reason: &str,
    ) -> Result<()> {
        match keys.into_iter().find_map(|(k, s)| Some((k, s?))) {
            Some((k, span)) => Err(self.err(&span, &field(k), reason)),
            None => Ok(()),
        }
    }

    /// An error about a missing key (no span: line 0 unless `near` is given).
    pub(super) fn missing(&self, near: Option<&Range<usize>>, field: &str, what: &str) -> IoError {
        IoError::Manifest {
            path: self.path.to_path_buf(),
            line: near.map_or(0, |s| self.line(s.start)),
            field: field.to_string(),
            value: "(missing)".into(),
            reason: format!("missing {what}"),
        }
    }

    /// The key written on the line holding `pos` (for TOML syntax and type errors).
    pub(super) fn key_at(&self, pos: usize, message: &str) -> String {
        // serde names the key in "unknown field `x`" and "missing field `x`".
        for pat in ["unknown field `", "missing field `"] {
            if let Some(i) = message.find(pat) {
                let rest = &message[i + pat.len()..];
                if let Some(j) = rest.find('`') {
                    return rest[..j].to_string();
                }
            }
        }
        let end = pos.min(self.text.len());
        let start = self.text[..end].rfind('\n').map_or(0, |i| i + 1);
        let line = self.text[start..].lines().next().unwrap_or("");
        let key = line.split('=').next().unwrap_or("").trim();
        if key.is_empty() || line.trim_start().starts_with('[') && !line.contains('=') {
            line.trim().trim_matches(['[', ']']).to_string()
        } else {
            key.to_string()
        }
    }

    pub(super) fn num(&self, v: &Spanned<f64>, field: &str) -> Result<f64> {
        let x = *v.get_ref();
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(&v.span(), field, "expected a finite number"))
        }
    }

    pub(super) fn num_in(
        &self,
        v: &Spanned<f64>,
        field: &str,
        ok: impl Fn(f64) -> bool,
        expected: &str,
    ) -> Result<f64> {
        let x = self.num(v, field)?;
        if ok(x) {
            Ok(x)
        } else {
            Err(self.err(&v.span(), field, format!("must be {expected}")))
        }
    }

    pub(super) fn zenith(&self, v: &Spanned<f64>, field: &str) -> Result<f64> {
        self.num_in(
            v,
            field,
            |x| (0.0..90.0).contains(&x),
            "a zenith angle in [0, 90) degrees",
        )
    }

    pub(super) fn rect(&self, v: &Spanned<Vec<i64>>, field: &str) -> Result<Rect> {
        let r = v.get_ref();
        if r.len() != 4 || r.iter().any(|&x| x < 0) || r[2] == 0 || r[3] == 0 {
            return Err(self.err(
                &v.span(),
                field,
                "rect must be [x, y, width, height]: four non-negative integers, width and \
                 height > 0",
            ));
        }
        Ok(Rect {
            x: r[0] as usize,
            y: r[1] as usize,
            width: r[2] as usize,
            height: r[3] as usize,
        })
    }

    pub(super) fn name(&self, v: &Spanned<String>, field: &str) -> Result<String> {
        let s = v.get_ref();
        if s.trim().is_empty() || s.contains([',', '"', '/', '\\', '\n']) {
            return Err(self.err(
                &v.span(),
                field,
                "names must be non-empty and contain no comma, quote, slash or newline",
            ));
        }
        // Unicode NFC, no control, zero-width or bidirectional-formatting character
        // (docs/RELIABILITY.md "Names and values"), as names read from CSV files.
        crate::table::clean_name(s).map_err(|why| self.err(&v.span(), field, why))
    }
}
