//! Trained classification models (JSON), written by `polarid train`, read by
//! `polarid classify --model` and `polarid map --model`.
//!
//! ```json
//! {
//!   "format": "polarid-model",
//!   "format_version": 1,
//!   "created_by": "polarid 0.1.0",
//!   "prototypes": [
//!     { "class": "aluminum", "n": 1.64, "k": 4.56,
//!       "covariance": [[0.0004, 0.0001], [0.0001, 0.0009]],
//!       "category": null,
//!       "source": { "file": "fits.csv", "line": 3, "target": "A" } }
//!   ]
//! }
//! ```
//!
//! `covariance` is the `(n, k)` covariance of the training estimate (`null` when the fit
//! gave no standard errors): the fit's total, noise plus systematic error.
//! `sample_covariance` (written when the fit gave the sample columns `n_se_sample`,
//! `k_se_sample`, `nk_corr_sample`; absent otherwise and optional on input, so older
//! models load) is the noise plus the surface layer's variation from plate to plate: what
//! an estimate from the same bench is compared with ([`Model::multi_prototypes_on`],
//! docs/CLASSIFY.md "Trained models: the same bench"). A prototype trained on a multi-band fit with the surface-layer
//! shifts (fits columns `film1_dn` … `film3_dk`) has them as `"film_shifts"`
//! (`[[δn, δk], ...]`, three pairs; absent otherwise and optional on input), so that
//! classification correlates the layer across the prototype's bands (docs/BANDS.md).
//!
//! A model trained on multi-band fits has one prototype per target per band, each with
//! `"wavelength_nm"` (after `class`; absent from single-band models, whose JSON is
//! unchanged). The bands of one training target — the prototypes with the same `class`,
//! `source.file` and `source.target` — form one multi-band prototype
//! ([`Model::multi_prototypes`]). `source.file` is relative to the model file's folder when the
//! fits file lies under it, else absolute. A model whose `format_version` is not
//! [`FORMAT_VERSION`] is refused with an error naming both versions.

use std::io::Write;
use std::path::Path;

use polarid_core::classify::{
    BandPoint, Bench, Cov2, FilmShifts, MultiPrototype, Prototype, check_class_name, same_band,
};
use serde::{Deserialize, Serialize};

use crate::error::{IoError, Result};

/// Value of the `format` field.
pub const FORMAT: &str = "polarid-model";
/// The model format version this polarid writes and reads.
pub const FORMAT_VERSION: u64 = 1;

/// Where a prototype came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PrototypeSource {
    /// The fits CSV.
    pub file: String,
    /// Line of the fits CSV.
    pub line: u64,
    /// Target name in that file.
    pub target: String,
}

/// One prototype of a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelPrototype {
    /// Class name.
    pub class: String,
    /// Centre wavelength of the band, nm (multi-band models only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wavelength_nm: Option<f64>,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index.
    pub k: f64,
    /// Covariance `[[var n, cov nk], [cov nk, var k]]` of the training estimate.
    pub covariance: Option<[[f64; 2]; 2]>,
    /// Covariance of the training estimate from its noise and the surface layer's
    /// variation between plates of one material (the same-bench comparison); `None` in
    /// models trained on fits without the sample columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_covariance: Option<[[f64; 2]; 2]>,
    /// The training fit's surface-layer shifts `[[δn, δk]; 3]` (part of `covariance`;
    /// multi-band fits with a layer allowance only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub film_shifts: Option<[[f64; 2]; 3]>,
    /// Category, when known.
    #[serde(default)]
    pub category: Option<String>,
    /// Provenance.
    pub source: PrototypeSource,
}

/// A trained model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`FORMAT_VERSION`].
    pub format_version: u64,
    /// Program that wrote the model.
    pub created_by: String,
    /// The prototypes.
    pub prototypes: Vec<ModelPrototype>,
}

impl Model {
    /// A model of the current format version.
    pub fn new(prototypes: Vec<ModelPrototype>) -> Self {
        Self {
            format: FORMAT.into(),
            format_version: FORMAT_VERSION,
            created_by: format!("polarid {}", env!("CARGO_PKG_VERSION")),
            prototypes,
        }
    }

    /// Read and check a model file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = crate::limits::read_text(path)?;
        Self::parse(path, &text)
    }

    /// Parse and check model JSON; `path` labels errors.
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        let bad = |reason: String| IoError::model(path, reason);
        let v: serde_json::Value =
            serde_json::from_str(text).map_err(|e| bad(format!("not valid JSON: {e}")))?;
        match v.get("format").and_then(|f| f.as_str()) {
            Some(FORMAT) => {}
            other => {
                return Err(bad(format!(
                    "not a polarid model (field `format` is {}, expected \"{FORMAT}\")",
                    other.map_or("missing".to_string(), |s| format!("{s:?}"))
                )));
            }
        }
        match v.get("format_version") {
            Some(x) if x.as_u64() == Some(FORMAT_VERSION) => {}
            Some(x) => {
                return Err(bad(format!(
                    "model format version {x} is not supported (this polarid reads version \
                     {FORMAT_VERSION}); retrain the model with `polarid train`"
                )));
            }
            None => return Err(bad("missing field `format_version`".into())),
        }
        let m: Model = serde_json::from_value(v).map_err(|e| bad(format!("bad model: {e}")))?;
        for (i, p) in m.prototypes.iter().enumerate() {
            let at = format!("prototypes[{i}] (class {:?})", p.class);
            check_class_name(&p.class).map_err(|e| bad(format!("{at}: {e}")))?;
            if !(p.n.is_finite() && p.k.is_finite() && p.k >= 0.0) {
                return Err(bad(format!(
                    "{at}: n = {}, k = {} (need finite values, k >= 0)",
                    p.n, p.k
                )));
            }
            if let Some(w) = p.wavelength_nm
                && !(w.is_finite() && w > 0.0)
            {
                return Err(bad(format!(
                    "{at}: wavelength_nm = {w} (need a finite wavelength > 0 nm)"
                )));
            }
            if let Some(f) = p.film_shifts
                && !f.iter().flatten().all(|v| v.is_finite())
            {
                return Err(bad(format!(
                    "{at}: film_shifts {f:?} (need finite numbers)"
                )));
            }
            for (field, c) in [
                ("covariance", p.covariance),
                ("sample_covariance", p.sample_covariance),
            ] {
                if let Some(c) = c
                    && Cov2::from_matrix(c).is_none()
                {
                    return Err(bad(format!(
                        "{at}: {field} {c:?} is not a symmetric positive definite matrix"
                    )));
                }
            }
        }
        if m.prototypes.is_empty() {
            return Err(bad("the model has no prototypes".into()));
        }
        let multi = m.multi_prototypes();
        if let Some(p) = multi.iter().find(|p| {
            p.bands.len() > 1
                && p.bands.iter().enumerate().any(|(i, b)| {
                    b.wavelength_nm.is_none()
                        || p.bands[..i]
                            .iter()
                            .any(|o| same_band(o.wavelength_nm, b.wavelength_nm))
                })
        }) {
            return Err(bad(format!(
                "prototype of class {:?} ({}): a band is repeated or has no wavelength_nm",
                p.class, p.source
            )));
        }
        Ok(m)
    }

    /// Write the model as pretty JSON.
    pub fn write<W: Write + ?Sized>(&self, w: &mut W, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| IoError::io(path, std::io::Error::other(e.to_string())))?;
        w.write_all(text.as_bytes())
            .and_then(|_| w.write_all(b"\n"))
            .map_err(|e| IoError::io(path, e))
    }

    /// The prototypes for a classifier (source `FILE:LINE target T`).
    pub fn prototypes(&self) -> Vec<Prototype> {
        self.prototypes
            .iter()
            .map(|p| Prototype {
                class: p.class.clone(),
                n: p.n,
                k: p.k,
                cov: p.covariance.and_then(Cov2::from_matrix),
                category: p.category.clone(),
                source: format!(
                    "{}:{} target {}",
                    p.source.file, p.source.line, p.source.target
                ),
            })
            .collect()
    }
}

impl Model {
    /// The prototypes with all their bands: those with the same `class`, `source.file` and
    /// `source.target` are the bands of one prototype (first-appearance order; source
    /// `FILE target T`, or `FILE:LINE target T` for a single band). Single-band models give
    /// the prototypes of [`Model::prototypes`] one for one.
    pub fn multi_prototypes(&self) -> Vec<MultiPrototype> {
        self.multi_prototypes_on(Bench::Other)
    }

    /// Whether every prototype has a sample covariance (the model can be compared with
    /// estimates from its own bench, [`Bench::Same`]).
    pub fn has_sample_covariances(&self) -> bool {
        self.prototypes
            .iter()
            .all(|p| p.sample_covariance.is_some() || p.covariance.is_none())
    }

    /// [`Model::multi_prototypes`] with the covariances for estimates from `bench`:
    /// [`Bench::Other`] the training fits' total covariance (and layer shifts);
    /// [`Bench::Same`] their sample covariance where a prototype has one (no layer
    /// shifts: the layer's variation is per band), else the total.
    pub fn multi_prototypes_on(&self, bench: Bench) -> Vec<MultiPrototype> {
        let mut out: Vec<MultiPrototype> = Vec::new();
        let mut keys: Vec<(&str, &str, &str)> = Vec::new();
        for p in &self.prototypes {
            let sample = match bench {
                Bench::Same => p.sample_covariance.and_then(Cov2::from_matrix),
                Bench::Other => None,
            };
            let band = match sample {
                Some(c) => BandPoint {
                    wavelength_nm: p.wavelength_nm,
                    n: p.n,
                    k: p.k,
                    cov: Some(c),
                    film: None,
                    layer: None,
                },
                None => BandPoint {
                    wavelength_nm: p.wavelength_nm,
                    n: p.n,
                    k: p.k,
                    cov: p.covariance.and_then(Cov2::from_matrix),
                    film: p.film_shifts.map(FilmShifts),
                    layer: None,
                },
            };
            let key = (
                p.class.as_str(),
                p.source.file.as_str(),
                p.source.target.as_str(),
            );
            match keys.iter().position(|k| *k == key) {
                Some(i) if p.wavelength_nm.is_some() => {
                    out[i].bands.push(band);
                    out[i].source = format!("{} target {}", p.source.file, p.source.target);
                }
                _ => {
                    keys.push(key);
                    out.push(MultiPrototype {
                        class: p.class.clone(),
                        category: p.category.clone(),
                        source: format!(
                            "{}:{} target {}",
                            p.source.file, p.source.line, p.source.target
                        ),
                        bands: vec![band],
                        surface: None,
                    });
                }
            }
        }
        out
    }
}

/// `[[nn, nk], [nk, kk]]` of a covariance.
pub fn cov_matrix(c: &Cov2) -> [[f64; 2]; 2] {
    [[c.nn, c.nk], [c.nk, c.kk]]
}

/// A path to record in a file written at `out`: relative to `out`'s folder when `path`
/// lies under it, else absolute (or as given when it cannot be resolved).
pub fn path_relative_to_output(path: &Path, out: &Path) -> String {
    let abs = std::fs::canonicalize(path).ok();
    let dir = out
        .parent()
        .map(|p| {
            if p.as_os_str().is_empty() {
                Path::new(".")
            } else {
                p
            }
        })
        .and_then(|p| std::fs::canonicalize(p).ok());
    match (abs, dir) {
        (Some(a), Some(d)) => match a.strip_prefix(&d) {
            Ok(rel) => rel.display().to_string(),
            Err(_) => a.display().to_string(),
        },
        (Some(a), None) => a.display().to_string(),
        _ => path.display().to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OLD: &str = r#"{"format": "polarid-model", "format_version": 1, "created_by": "x",
      "prototypes": [{"class": "aluminum", "n": 1.0, "k": 6.0,
        "covariance": [[0.25, 0.9], [0.9, 4.0]], "source": {"file": "f", "line": 2, "target": "A"}}]}"#;

    #[test]
    fn sample_covariance_is_optional_and_used_on_the_same_bench() {
        // A model written before the field loads; on the same bench it falls back to the
        // total covariance, and it says it cannot give the same-bench comparison.
        let m = Model::parse(Path::new("m.json"), OLD).unwrap();
        assert!(!m.has_sample_covariances());
        let total = m.multi_prototypes_on(Bench::Same)[0].bands[0].cov.unwrap();
        assert_eq!(total.nn, 0.25);
        // With the field: the same bench uses it (and no layer shifts), another bench
        // the total; the field round-trips.
        let with = OLD.replace(
            r#""covariance": [[0.25, 0.9], [0.9, 4.0]],"#,
            r#""covariance": [[0.25, 0.9], [0.9, 4.0]], "sample_covariance": [[0.04, 0.1], [0.1, 0.9]],"#,
        );
        let m = Model::parse(Path::new("m.json"), &with).unwrap();
        assert!(m.has_sample_covariances());
        assert_eq!(
            m.multi_prototypes_on(Bench::Same)[0].bands[0]
                .cov
                .unwrap()
                .nn,
            0.04
        );
        assert_eq!(m.multi_prototypes()[0].bands[0].cov.unwrap().nn, 0.25);
        let mut buf = Vec::new();
        m.write(&mut buf, Path::new("m.json")).unwrap();
        let back = Model::parse(Path::new("m.json"), std::str::from_utf8(&buf).unwrap()).unwrap();
        assert_eq!(back, m);
        // Not positive definite: refused, naming the field.
        let bad = with.replace("[[0.04, 0.1], [0.1, 0.9]]", "[[0.04, 0.9], [0.9, 0.9]]");
        let e = Model::parse(Path::new("m.json"), &bad)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("sample_covariance") && e.contains("prototypes[0]"),
            "{e}"
        );
    }
}
