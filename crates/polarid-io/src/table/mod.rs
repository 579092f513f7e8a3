//! The CSV tables of `docs/FORMATS.md`.
//!
//! Readers find columns by name, ignore unknown columns and skip lines that start with
//! `#`; every parse error names the file, the line, the column and the value.
//! Writers emit the columns in the documented order.
//!
//! # Spreadsheet safety (CSV injection)
//!
//! A text cell that starts with `=`, `+`, `-`, `@`, a tab or a carriage return would be
//! run as a formula by a spreadsheet. Writers ([`write_rows`]) prefix such cells with a
//! single quote `'` (the OWASP rule), except numbers such as `-1.5`; a cell that starts
//! with `'` followed by such a character gets one more `'`. Readers remove exactly that
//! one quote again ([`unguard`]), so names round-trip unchanged.
//!
//! # Names
//!
//! Target and class names read through [`CsvTable::name`] are normalised to Unicode
//! NFC (so that `é` typed as one or two code points is one class), and names with
//! control, zero-width or bidirectional-override characters are refused.

pub mod classification;
pub mod fits;
pub mod measurements;
pub mod model_rows;

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use unicode_normalization::UnicodeNormalization;

use crate::error::{IoError, Result};
use crate::limits::{read_capped, short, text_cap};

/// A CSV file read into memory: header plus records with their line numbers.
#[derive(Debug, Clone)]
pub struct CsvTable {
    /// File the table was read from (used in error messages).
    pub path: PathBuf,
    /// Column names, trimmed.
    pub headers: Vec<String>,
    /// Records with their 1-based line numbers.
    pub rows: Vec<(u64, csv::StringRecord)>,
}

impl CsvTable {
    /// Read a CSV file, or standard input when `path` is `-`
    /// ([`crate::limits::STDIN`]; messages then name `<stdin>`).
    ///
    /// The input must be a regular file or a stream (a FIFO, standard input) of at most
    /// [`text_cap`] bytes ([`read_capped`]).
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = read_capped(path, text_cap(), "CSV")?;
        Self::from_reader(&input_label(path), bytes.as_slice())
    }

    /// Read CSV text from `reader`; `path` labels error messages.
    ///
    /// Lines starting with `#` are comments; reported line numbers are those of the
    /// original file, comments included. A leading byte-order mark is ignored, and at
    /// most [`text_cap`] bytes are read.
    pub fn from_reader<R: Read>(path: &Path, reader: R) -> Result<Self> {
        let structure = |reason: String| IoError::CsvStructure {
            path: path.to_path_buf(),
            reason,
        };
        let cap = text_cap();
        let mut bytes = Vec::new();
        reader
            .take(cap.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(|e| IoError::io(path, e))?;
        if bytes.len() as u64 > cap {
            return Err(IoError::TooLarge {
                path: path.to_path_buf(),
                what: format!("CSV text of more than {}", crate::limits::human(cap)),
                limit: crate::limits::memory_limit(),
            });
        }
        let text =
            String::from_utf8(bytes).map_err(|e| structure(format!("not UTF-8 text: {e}")))?;
        let text = crate::limits::strip_bom(text);
        // Drop comment lines, remembering the original number of each kept line.
        let mut kept = String::with_capacity(text.len());
        let mut line_of: Vec<u64> = Vec::new();
        for (i, line) in text.lines().enumerate() {
            if line.trim_start().starts_with('#') {
                continue;
            }
            kept.push_str(line);
            kept.push('\n');
            line_of.push(i as u64 + 1);
        }
        let orig = |l: u64| -> u64 {
            l.checked_sub(1)
                .and_then(|i| line_of.get(i as usize).copied())
                .unwrap_or(l)
        };
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .flexible(false)
            .from_reader(kept.as_bytes());
        let headers: Vec<String> = rdr
            .headers()
            .map_err(|e| structure(format!("cannot read the header line: {e}")))?
            .iter()
            .map(|h| h.trim().to_string())
            .collect();
        if headers.iter().all(|h| h.is_empty()) {
            return Err(structure("no header line (the file is empty)".into()));
        }
        let mut rows = Vec::new();
        for rec in rdr.records() {
            let rec = rec.map_err(|e| {
                let line = e.position().map(|p| orig(p.line())).unwrap_or(0);
                structure(format!("line {line}: {e}"))
            })?;
            let line = rec.position().map(|p| orig(p.line())).unwrap_or(0);
            let rec = if rec.iter().any(|c| c.starts_with('\'')) {
                rec.iter().map(unguard).collect()
            } else {
                rec
            };
            rows.push((line, rec));
        }
        Ok(Self {
            path: path.to_path_buf(),
            headers,
            rows,
        })
    }

    /// Index of column `name`, if present.
    pub fn col(&self, name: &str) -> Option<usize> {
        self.headers.iter().position(|h| h == name)
    }

    /// Index of column `name`, or an error naming the file and the missing column.
    pub fn require(&self, name: &str) -> Result<usize> {
        self.col(name).ok_or_else(|| IoError::CsvStructure {
            path: self.path.clone(),
            reason: format!(
                "missing required column `{name}` (columns are: {})",
                self.headers.join(",")
            ),
        })
    }

    /// Text of row `row`, column `col` (empty when either is out of range).
    pub fn text(&self, row: usize, col: usize) -> &str {
        self.rows.get(row).and_then(|r| r.1.get(col)).unwrap_or("")
    }

    /// An error about the value of row `row`, column `col` (the value shortened to 60
    /// characters).
    pub fn err(&self, row: usize, col: usize, reason: impl Into<String>) -> IoError {
        IoError::Csv {
            path: self.path.clone(),
            line: self.rows.get(row).map_or(0, |r| r.0),
            column: self.headers.get(col).cloned().unwrap_or_default(),
            value: short(self.text(row, col)),
            reason: reason.into(),
        }
    }

    /// A name (target, class): [`clean_name`] of the cell, or an error naming the cell.
    /// Empty cells give an empty string.
    pub fn name(&self, row: usize, col: usize) -> Result<String> {
        clean_name(self.text(row, col)).map_err(|reason| self.err(row, col, reason))
    }

    /// An optional name: `None` when the column is absent or the cell empty.
    pub fn opt_name(&self, row: usize, col: Option<usize>) -> Result<Option<String>> {
        match col {
            None => Ok(None),
            Some(c) => Ok(Some(self.name(row, c)?).filter(|s| !s.is_empty())),
        }
    }

    /// An optional standard error: an empty cell (or no column) for unknown, else a
    /// finite number `>= 0`. The literal `nan` is accepted only when `nan_ok` (a failed
    /// fit's row, whose `n` and `k` may be `nan` too); elsewhere it is refused, so that
    /// a usable estimate never loses its uncertainty silently.
    pub fn se(&self, row: usize, col: Option<usize>, nan_ok: bool) -> Result<f64> {
        let Some(c) = col else { return Ok(f64::NAN) };
        let t = self.text(row, c);
        if t.is_empty() {
            return Ok(f64::NAN);
        }
        if t.eq_ignore_ascii_case("nan") {
            if nan_ok {
                return Ok(f64::NAN);
            }
            return Err(self.err(
                row,
                c,
                "a standard error must be a number >= 0 (leave the cell empty when unknown)",
            ));
        }
        let v = self.f64(row, c)?;
        if v < 0.0 {
            return Err(self.err(
                row,
                c,
                "a standard error must be >= 0 (leave the cell empty when unknown)",
            ));
        }
        Ok(v)
    }

    /// An optional correlation: an empty cell (or no column) for unknown, else a number
    /// in `[-1, 1]`; the literal `nan` only when `nan_ok`, as for [`CsvTable::se`].
    pub fn corr(&self, row: usize, col: Option<usize>, nan_ok: bool) -> Result<f64> {
        let Some(c) = col else { return Ok(f64::NAN) };
        let t = self.text(row, c);
        if t.is_empty() || (nan_ok && t.eq_ignore_ascii_case("nan")) {
            return Ok(f64::NAN);
        }
        let why = "a correlation must be in [-1, 1] (leave the cell empty when unknown)";
        if t.eq_ignore_ascii_case("nan") {
            return Err(self.err(row, c, why));
        }
        let v = self.f64(row, c)?;
        if !(-1.0..=1.0).contains(&v) {
            return Err(self.err(row, c, why));
        }
        Ok(v)
    }

    /// A required finite number.
    pub fn f64(&self, row: usize, col: usize) -> Result<f64> {
        let t = self.text(row, col);
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(self.err(row, col, "not a finite number")),
            Err(_) if t.is_empty() => Err(self.err(row, col, "missing value")),
            Err(_) => Err(self.err(row, col, "not a number")),
        }
    }

    /// An optional finite number: `None` when the column is absent or the cell empty.
    pub fn opt_f64(&self, row: usize, col: Option<usize>) -> Result<Option<f64>> {
        match col {
            None => Ok(None),
            Some(c) if self.text(row, c).is_empty() => Ok(None),
            Some(c) => self.f64(row, c).map(Some),
        }
    }

    /// An optional non-negative integer.
    pub fn opt_u64(&self, row: usize, col: Option<usize>) -> Result<Option<u64>> {
        match col {
            None => Ok(None),
            Some(c) if self.text(row, c).is_empty() => Ok(None),
            Some(c) => self
                .text(row, c)
                .parse::<u64>()
                .map(Some)
                .map_err(|_| self.err(row, c, "not a non-negative integer")),
        }
    }

    /// An optional text cell: `None` when the column is absent or the cell empty.
    pub fn opt_text(&self, row: usize, col: Option<usize>) -> Option<String> {
        col.map(|c| self.text(row, c).to_string())
            .filter(|s| !s.is_empty())
    }
}

/// The name of an input in messages: `<stdin>` for `-` (standard input), else the path.
pub fn input_label(path: &Path) -> PathBuf {
    if crate::limits::is_stdin(path) {
        PathBuf::from("<stdin>")
    } else {
        path.to_path_buf()
    }
}

/// Characters that make a spreadsheet run a cell as a formula when they start it.
const FORMULA_START: [char; 6] = ['=', '+', '-', '@', '\t', '\r'];

/// True when `cell` must be written with a leading `'` so that a spreadsheet shows it
/// as text: it starts with a formula character and is not a number (`-1.5`, `+2e3`),
/// or it starts with `'` and the rest needs the quote (so that [`unguard`] inverts
/// [`guard`] exactly).
fn needs_guard(cell: &str) -> bool {
    match cell.chars().next() {
        Some('\'') => needs_guard(&cell[1..]),
        Some(c) if FORMULA_START.contains(&c) => cell.trim().parse::<f64>().is_err(),
        _ => false,
    }
}

/// A cell as written to a CSV file: prefixed with `'` when a spreadsheet would run it
/// as a formula (module docs).
pub fn guard(cell: &str) -> std::borrow::Cow<'_, str> {
    if needs_guard(cell) {
        format!("'{cell}").into()
    } else {
        cell.into()
    }
}

/// A cell as read back: the `'` that [`guard`] added removed, anything else unchanged.
pub fn unguard(cell: &str) -> &str {
    match cell.strip_prefix('\'') {
        Some(rest) if needs_guard(rest) => rest,
        _ => cell,
    }
}

/// A name as polarid uses it: trimmed, in Unicode NFC, or why it cannot be used (a
/// control, zero-width or bidirectional-formatting character, shown by its code
/// point).
pub fn clean_name(raw: &str) -> std::result::Result<String, String> {
    for c in raw.chars() {
        let invisible = matches!(
            c,
            '\u{200B}'..='\u{200F}'
                | '\u{202A}'..='\u{202E}'
                | '\u{2060}'..='\u{2064}'
                | '\u{2066}'..='\u{2069}'
                | '\u{061C}'
                | '\u{FEFF}'
                | '\u{00AD}'
        );
        if c.is_control() || invisible {
            return Err(format!(
                "a name cannot hold the invisible or control character U+{:04X}",
                c as u32
            ));
        }
    }
    Ok(raw.trim().nfc().collect())
}

/// Format a number for CSV output: shortest round-trip decimal, exponent notation for
/// very small or large magnitudes, `nan` for NaN.
pub fn fmt_f64(x: f64) -> String {
    if x.is_nan() {
        "nan".to_string()
    } else if x == 0.0 || (1e-5..1e16).contains(&x.abs()) || x.is_infinite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Format an optional number (empty cell for `None`).
pub fn fmt_opt(x: Option<f64>) -> String {
    x.map(fmt_f64).unwrap_or_default()
}

/// A row of [`write_banded`]: its cells, its wavelength and its optional trailing cells.
pub struct BandedRow {
    /// The cells of the table's fixed columns.
    pub cells: Vec<String>,
    /// The row's wavelength, nm, if any.
    pub wavelength_nm: Option<f64>,
    /// The cells of the optional trailing columns, if the row has them.
    pub extra: Option<Vec<String>>,
}

/// Write `rows` under `columns` ([`write_rows`]), with a `wavelength_nm` column third when
/// some row has a wavelength, and the columns `extra` last when some row has their cells
/// (empty cells in the rows without).
pub fn write_banded<W: Write + ?Sized>(
    w: &mut W,
    path: &Path,
    columns: &[&str],
    extra: &[&str],
    rows: Vec<BandedRow>,
) -> Result<()> {
    let banded = rows.iter().any(|r| r.wavelength_nm.is_some());
    let extended = rows.iter().any(|r| r.extra.is_some());
    let mut headers = columns.to_vec();
    if banded {
        headers.insert(2, "wavelength_nm");
    }
    if extended {
        headers.extend(extra);
    }
    let rows = rows.into_iter().map(|r| {
        let mut cells = r.cells;
        if banded {
            cells.insert(2, fmt_opt(r.wavelength_nm));
        }
        if extended {
            cells.extend(r.extra.unwrap_or_else(|| vec![String::new(); extra.len()]));
        }
        cells
    });
    write_rows(w, path, &headers, rows)
}

/// A `Write` shared by the two CSV writers of [`write_rows`].
struct Shared<'a, W: Write + ?Sized>(&'a std::cell::RefCell<&'a mut W>);

impl<W: Write + ?Sized> Write for Shared<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.borrow_mut().flush()
    }
}

/// Write a header and rows of already formatted cells.
///
/// A row whose first cell starts with `#` would read back as a comment line, so its
/// cells are quoted. Cells a spreadsheet would run as formulas are prefixed with `'`
/// ([`guard`]).
pub fn write_rows<W: Write + ?Sized>(
    w: &mut W,
    path: &Path,
    headers: &[&str],
    rows: impl IntoIterator<Item = Vec<String>>,
) -> Result<()> {
    let sink = std::cell::RefCell::new(w);
    let mut plain = csv::Writer::from_writer(Shared(&sink));
    let mut quoted = csv::WriterBuilder::new()
        .quote_style(csv::QuoteStyle::Always)
        .from_writer(Shared(&sink));
    let io = |e: csv::Error| IoError::io(path, std::io::Error::other(e.to_string()));
    let flush = |e: std::io::Error| IoError::io(path, e);
    plain.write_record(headers).map_err(io)?;
    for r in rows {
        let r: Vec<std::borrow::Cow<'_, str>> = r.iter().map(|c| guard(c)).collect();
        let r: Vec<&str> = r.iter().map(|c| c.as_ref()).collect();
        if r.first().is_some_and(|c| c.trim_start().starts_with('#')) {
            plain.flush().map_err(flush)?;
            quoted.write_record(&r).map_err(io)?;
            quoted.flush().map_err(flush)?;
        } else {
            plain.write_record(&r).map_err(io)?;
        }
    }
    plain.flush().map_err(flush)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_with_comments_and_names_bad_cells() {
        let text = "# comment\na,b\n1,2\n# another\n3,x\n";
        let t = CsvTable::from_reader(Path::new("t.csv"), text.as_bytes()).unwrap();
        assert_eq!(t.rows.len(), 2);
        let b = t.require("b").unwrap();
        assert_eq!(t.f64(0, b).unwrap(), 2.0);
        let e = t.f64(1, b).unwrap_err().to_string();
        assert!(
            e.contains("t.csv") && e.contains("line 5") && e.contains("`b`") && e.contains("\"x\""),
            "{e}"
        );
        let e = t.require("zz").unwrap_err().to_string();
        assert!(e.contains("zz"), "{e}");
    }

    #[test]
    fn formats_numbers() {
        assert_eq!(fmt_f64(0.5), "0.5");
        assert_eq!(fmt_f64(1.5e-87), "1.5e-87");
        assert_eq!(fmt_f64(f64::NAN), "nan");
        assert_eq!(fmt_f64(0.0), "0");
    }
}
