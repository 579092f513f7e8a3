//! The refractiveindex.info database's YAML files: [`RiiData`] reads one file and
//! evaluates `n(λ)`, `k(λ)` from its tabulated data or dispersion formulas (the formulas
//! and the rules are in the [`crate::library`] documentation, "refractiveindex.info YAML").

use std::path::{Path, PathBuf};

use saphyr::{LoadableYamlNode, Yaml};

use crate::error::{IoError, Result};

/// Embedded data files parsed once per process ([`parsed_once`]): the parsed values, or
/// the first error's text.
pub(crate) type ParsedOnce<T> = std::sync::OnceLock<std::result::Result<Vec<T>, String>>;

/// The values `parse` gives, parsed on the first call into `cell`; an error is an
/// [`IoError::Model`] naming `label` (the same one on every call).
pub(crate) fn parsed_once<T>(
    cell: &'static ParsedOnce<T>,
    label: &str,
    parse: impl FnOnce() -> Result<Vec<T>>,
) -> Result<&'static [T]> {
    match cell.get_or_init(|| parse().map_err(|e| e.to_string())) {
        Ok(v) => Ok(v),
        Err(e) => Err(IoError::model(label, e.clone())),
    }
}

/// How a refractiveindex.info file gives `n` or `k` as a function of wavelength.
#[derive(Debug, Clone, PartialEq)]
pub enum Dispersion {
    /// A dispersion formula (`formula 1` … `formula 9`), giving `n`.
    Formula {
        /// Formula number, 1 to 9.
        kind: u8,
        /// Coefficients `C1, C2, …`.
        coefficients: Vec<f64>,
        /// Validity range in µm, when the file gives one.
        range_um: Option<(f64, f64)>,
    },
    /// Tabulated values, linearly interpolated.
    Table {
        /// Wavelengths in µm, sorted (the database repeats a node now and then and lists a
        /// few rows out of order; a repeated wavelength takes its first value).
        wavelength_um: Vec<f64>,
        /// Values at those wavelengths.
        values: Vec<f64>,
    },
}

impl Dispersion {
    /// Wavelength range (µm) over which the data may be evaluated.
    pub fn range_um(&self) -> (f64, f64) {
        match self {
            Dispersion::Formula { range_um, .. } => {
                range_um.unwrap_or((f64::NEG_INFINITY, f64::INFINITY))
            }
            Dispersion::Table { wavelength_um, .. } => (
                wavelength_um.first().copied().unwrap_or(f64::NAN),
                wavelength_um.last().copied().unwrap_or(f64::NAN),
            ),
        }
    }

    /// Value at `wl` µm (NaN outside the range or where a formula has no real value).
    pub fn eval(&self, wl: f64) -> f64 {
        let (lo, hi) = self.range_um();
        if !(wl >= lo && wl <= hi) {
            return f64::NAN;
        }
        match self {
            Dispersion::Table {
                wavelength_um: w,
                values: v,
            } => {
                // First node >= wl.
                let j = w.partition_point(|&x| x < wl);
                match (j, w.get(j), v.get(j)) {
                    (_, Some(&wj), Some(&vj)) if wj == wl => vj,
                    (j, Some(&wj), Some(&vj)) if j > 0 => {
                        // ok: 0 < j < len (w.get(j) matched) and v has w's length.
                        let (wi, vi) = (w[j - 1], v[j - 1]);
                        vi + (vj - vi) * (wl - wi) / (wj - wi)
                    }
                    _ => f64::NAN,
                }
            }
            Dispersion::Formula {
                kind, coefficients, ..
            } => formula(*kind, coefficients, wl),
        }
    }
}

/// Evaluate refractiveindex.info dispersion formula `kind` (1–9) at `l` µm (see the
/// module documentation). NaN for an unknown formula or no real index.
pub fn formula(kind: u8, c: &[f64], l: f64) -> f64 {
    let cf = |i: usize| c.get(i).copied().unwrap_or(0.0);
    let l2 = l * l;
    // Σ over pairs (C(2i), C(2i+1)) from 0-based index `from`, skipping zero multipliers.
    let pairs = |from: usize, term: &dyn Fn(f64, f64) -> f64| -> f64 {
        let mut s = 0.0;
        let mut i = from;
        while i < c.len() {
            let a = cf(i);
            if a != 0.0 {
                s += term(a, cf(i + 1));
            }
            i += 2;
        }
        s
    };
    match kind {
        1 => (1.0 + cf(0) + pairs(1, &|a, b| a * l2 / (l2 - b * b))).sqrt(),
        2 => (1.0 + cf(0) + pairs(1, &|a, b| a * l2 / (l2 - b))).sqrt(),
        3 => (cf(0) + pairs(1, &|a, b| a * l.powf(b))).sqrt(),
        4 => {
            let mut n2 = cf(0);
            if cf(1) != 0.0 {
                n2 += cf(1) * l.powf(cf(2)) / (l2 - cf(3).powf(cf(4)));
            }
            if cf(5) != 0.0 {
                n2 += cf(5) * l.powf(cf(6)) / (l2 - cf(7).powf(cf(8)));
            }
            (n2 + pairs(9, &|a, b| a * l.powf(b))).sqrt()
        }
        5 => cf(0) + pairs(1, &|a, b| a * l.powf(b)),
        6 => 1.0 + cf(0) + pairs(1, &|a, b| a / (b - 1.0 / l2)),
        7 => {
            let m = 1.0 / (l2 - 0.028);
            cf(0) + cf(1) * m + cf(2) * m * m + cf(3) * l2 + cf(4) * l2 * l2 + cf(5) * l2 * l2 * l2
        }
        8 => {
            let b = cf(0) + cf(1) * l2 / (l2 - cf(2)) + cf(3) * l2;
            ((1.0 + 2.0 * b) / (1.0 - b)).sqrt()
        }
        9 => {
            let d = l - cf(4);
            (cf(0) + cf(1) / (l2 - cf(2)) + cf(3) * d / (d * d + cf(5))).sqrt()
        }
        _ => f64::NAN,
    }
}

/// The optical constants of one refractiveindex.info YAML file.
#[derive(Debug, Clone, PartialEq)]
pub struct RiiData {
    /// The file (for messages).
    pub path: PathBuf,
    /// How `n` is given.
    pub n: Dispersion,
    /// How `k` is given (`None`: the file gives only `n`; `k` is taken as 0).
    pub k: Option<Dispersion>,
}

fn scalar_text(y: &Yaml) -> Option<String> {
    if let Some(s) = y.as_str() {
        return Some(s.to_string());
    }
    if let Some(f) = y.as_floating_point() {
        return Some(f.to_string());
    }
    y.as_integer().map(|i| i.to_string())
}

/// Entry `i` of a file's `DATA` list, of type `ty` (for the messages).
struct DataEntry<'a, 'y> {
    path: &'a Path,
    i: usize,
    ty: &'a str,
    yaml: &'a Yaml<'y>,
}

impl DataEntry<'_, '_> {
    fn bad(&self, reason: String) -> IoError {
        IoError::model(self.path, reason)
    }

    fn field(&self, name: &str) -> Result<String> {
        self.yaml
            .as_mapping_get(name)
            .and_then(scalar_text)
            .ok_or_else(|| self.bad(format!("DATA[{}]: missing field `{name}`", self.i)))
    }

    fn numbers(&self, name: &str, s: &str) -> Result<Vec<f64>> {
        let (i, ty) = (self.i, self.ty);
        s.split_whitespace()
            .map(|t| {
                t.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        self.bad(format!("DATA[{i}] ({ty}): `{name}` has a bad number {t:?}"))
                    })
            })
            .collect()
    }

    /// Put `d` in `slot` (`what`: `n` or `k`), which must be empty.
    fn set(&self, slot: &mut Option<Dispersion>, what: &str, d: Dispersion) -> Result<()> {
        if slot.is_some() {
            return Err(self.bad(format!(
                "DATA[{}] ({}): {what} is given more than once",
                self.i, self.ty
            )));
        }
        *slot = Some(d);
        Ok(())
    }

    /// A `formula N` entry (`num`: what follows `formula`).
    fn formula(&self, num: &str) -> Result<Dispersion> {
        let (i, ty) = (self.i, self.ty);
        let kind: u8 = num
            .trim()
            .parse()
            .ok()
            .filter(|k| (1..=9).contains(k))
            .ok_or_else(|| {
                self.bad(format!(
                    "DATA[{i}]: unsupported type {ty:?} (formula 1 to 9 are supported)"
                ))
            })?;
        let coefficients = self.numbers("coefficients", &self.field("coefficients")?)?;
        let range_um = match self
            .yaml
            .as_mapping_get("wavelength_range")
            .and_then(scalar_text)
        {
            None => None,
            Some(s) => match self.numbers("wavelength_range", &s)?.as_slice() {
                [a, b] if a < b => Some((*a, *b)),
                _ => {
                    return Err(self.bad(format!(
                        "DATA[{i}] ({ty}): `wavelength_range` must be two increasing \
                         numbers, got {s:?}"
                    )));
                }
            },
        };
        Ok(Dispersion::Formula {
            kind,
            coefficients,
            range_um,
        })
    }

    /// A `tabulated nk`, `n` or `k` entry (`cols`): the wavelengths and the one or two
    /// columns of values (the second is zeros for `n` or `k`), sorted by wavelength.
    fn tabulated(&self, cols: &str) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let (i, ty) = (self.i, self.ty);
        let width = match cols {
            "nk" => 3,
            "n" | "k" => 2,
            _ => {
                return Err(self.bad(format!(
                    "DATA[{i}]: unsupported type {ty:?} (tabulated nk, n or k)"
                )));
            }
        };
        let text = self.field("data")?;
        let mut rows: Vec<(f64, f64, f64)> = Vec::new();
        for (ln, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let v = self.numbers("data", line)?;
            if v.len() != width {
                return Err(self.bad(format!(
                    "DATA[{i}] ({ty}): data line {} has {} numbers, expected {width}: {line:?}",
                    ln + 1,
                    v.len()
                )));
            }
            // ok: v.len() == width >= 2.
            rows.push((v[0], v[1], v.get(2).copied().unwrap_or(0.0)));
        }
        // A few database files list some rows out of order: sort by wavelength
        // (stable, so a repeated wavelength keeps its first value first).
        rows.sort_by(|x, y| x.0.total_cmp(&y.0));
        let w: Vec<f64> = rows.iter().map(|r| r.0).collect();
        let a: Vec<f64> = rows.iter().map(|r| r.1).collect();
        let b: Vec<f64> = rows.iter().map(|r| r.2).collect();
        if w.is_empty() {
            return Err(self.bad(format!("DATA[{i}] ({ty}): no data")));
        }
        Ok((w, a, b))
    }
}

impl RiiData {
    /// Read a refractiveindex.info YAML file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = crate::limits::read_text(path)?;
        Self::parse(path, &text)
    }

    /// Parse refractiveindex.info YAML text; `path` labels errors.
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        let bad = |reason: String| IoError::model(path, reason);
        let docs = Yaml::load_from_str(text).map_err(|e| bad(format!("not valid YAML: {e}")))?;
        let doc = docs
            .first()
            .ok_or_else(|| bad("empty YAML document".into()))?;
        let data = doc
            .as_mapping_get("DATA")
            .and_then(|d| d.as_sequence())
            .ok_or_else(|| bad("no `DATA` list".into()))?;
        let mut n: Option<Dispersion> = None;
        let mut k: Option<Dispersion> = None;
        for (i, yaml) in data.iter().enumerate() {
            let untyped = DataEntry {
                path,
                i,
                ty: "",
                yaml,
            };
            let ty = untyped.field("type")?;
            let e = DataEntry {
                ty: ty.trim(),
                ..untyped
            };
            if let Some(num) = e.ty.strip_prefix("formula") {
                e.set(&mut n, "n", e.formula(num)?)?;
            } else if let Some(cols) = e.ty.strip_prefix("tabulated") {
                let cols = cols.trim();
                let (w, a, b) = e.tabulated(cols)?;
                let table = |values| Dispersion::Table {
                    wavelength_um: w.clone(),
                    values,
                };
                match cols {
                    "nk" => {
                        e.set(&mut n, "n", table(a))?;
                        e.set(&mut k, "k", table(b))?;
                    }
                    "n" => e.set(&mut n, "n", table(a))?,
                    _ => e.set(&mut k, "k", table(a))?,
                }
            } else {
                return Err(e.bad(format!("DATA[{i}]: unsupported type {:?}", e.ty)));
            }
        }
        let n = n.ok_or_else(|| bad("the file gives no refractive index n".into()))?;
        Ok(Self {
            path: path.to_path_buf(),
            n,
            k,
        })
    }

    /// Wavelength range (µm) covered by both `n` and `k`.
    pub fn range_um(&self) -> (f64, f64) {
        let (a, b) = self.n.range_um();
        match &self.k {
            Some(k) => {
                let (c, d) = k.range_um();
                (a.max(c), b.min(d))
            }
            None => (a, b),
        }
    }

    /// `(n, k)` at `wl` µm; `k = 0` when the file gives only `n`. Fails outside the data's
    /// range (no extrapolation) or where a formula has no real value.
    pub fn nk(&self, wl: f64) -> Result<(f64, f64)> {
        let (lo, hi) = self.range_um();
        if !(wl >= lo && wl <= hi) {
            return Err(IoError::model(
                &self.path,
                format!(
                    "wavelength {:.1} nm is outside the data's range {:.1}–{:.1} nm \
                     (no extrapolation)",
                    wl * 1e3,
                    lo * 1e3,
                    hi * 1e3
                ),
            ));
        }
        let n = self.n.eval(wl);
        let k = self.k.as_ref().map_or(0.0, |k| k.eval(wl));
        if !(n.is_finite() && k.is_finite()) {
            return Err(IoError::model(
                &self.path,
                format!(
                    "no real optical constants at {:.1} nm (n = {n}, k = {k})",
                    wl * 1e3
                ),
            ));
        }
        Ok((n, k))
    }

    /// Arithmetic means of `n` and of `k` over `lo_nm ..= hi_nm` sampled every `step_nm`
    /// (`library_650nm.csv`: 610, 690, 1 → 81 samples). `lo_nm = hi_nm` gives the value
    /// at that wavelength.
    pub fn band_mean(&self, lo_nm: f64, hi_nm: f64, step_nm: f64) -> Result<(f64, f64)> {
        if !(lo_nm > 0.0 && hi_nm >= lo_nm && step_nm > 0.0 && hi_nm.is_finite()) {
            return Err(IoError::model(
                &self.path,
                format!(
                    "bad band {lo_nm}–{hi_nm} nm, step {step_nm} nm (need 0 < low <= high, step > 0)"
                ),
            ));
        }
        let count = ((hi_nm - lo_nm) / step_nm + 1e-9).floor() as usize + 1;
        let (mut sn, mut sk) = (0.0, 0.0);
        for j in 0..count {
            let wl_nm = lo_nm + j as f64 * step_nm;
            let (n, k) = self.nk(wl_nm / 1e3)?;
            sn += n;
            sk += k;
        }
        Ok((sn / count as f64, sk / count as f64))
    }
}
