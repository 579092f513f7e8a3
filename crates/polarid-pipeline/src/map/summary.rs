//! The map's summary: pixel counts per class and per reason, and per labelled region of
//! the manifest the share of its pixels given each class (`map_summary.json`).

use polarid_core::classify::UNKNOWN;
use polarid_io::manifest::Manifest;
use serde_json::{Value, json};

use super::MapResult;
use super::capture::Dims;

/// What a labelled region of the manifest became in the map.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionSummary {
    /// Region name.
    pub name: String,
    /// The region's rectangle `[x, y, width, height]`, frame pixels.
    pub rect: [usize; 4],
    /// Map pixels (blocks) entirely inside the rectangle.
    pub pixels: u64,
    /// Pixels per answer (a material, `ambiguous`, or `unknown` for no material), answers
    /// with pixels only, in class-index order.
    pub classes: Vec<(String, u64)>,
    /// The region's labelled class, if any.
    pub class: Option<String>,
    /// Pixels given the labelled class (0 without a label).
    pub correct: u64,
}

impl RegionSummary {
    /// `correct / pixels`, `None` without a label or pixels.
    pub fn correct_fraction(&self) -> Option<f64> {
        (self.class.is_some() && self.pixels > 0).then(|| self.correct as f64 / self.pixels as f64)
    }

    fn to_json(&self) -> Value {
        let per: serde_json::Map<String, Value> = self
            .classes
            .iter()
            .map(|(n, c)| (n.clone(), json!(c)))
            .collect();
        let mut v = json!({
            "name": self.name,
            "rect": self.rect,
            "pixels": self.pixels,
            "classes": per,
        });
        if let Some(cls) = &self.class {
            v["class"] = json!(cls);
            v["correct"] = json!(self.correct);
            v["correct_fraction"] = self.correct_fraction().map_or(Value::Null, |f| json!(f));
        }
        v
    }
}

/// `x`, or null when it is not finite (JSON has no NaN).
fn finite(x: f64) -> Value {
    if x.is_finite() { json!(x) } else { Value::Null }
}

/// Per labelled region: the share of its (binned) pixels given each class.
pub(crate) fn region_summary(
    m: &Manifest,
    d: Dims,
    bin: usize,
    class: &[u16],
    names: &[String],
) -> Vec<RegionSummary> {
    let label = |i: usize| {
        if i == 0 {
            UNKNOWN.to_string()
        } else {
            names.get(i - 1).cloned().unwrap_or_default()
        }
    };
    m.regions
        .iter()
        .map(|r| {
            // Blocks entirely inside the rectangle.
            let x0 = r.rect.x.div_ceil(bin);
            let y0 = r.rect.y.div_ceil(bin);
            let x1 = ((r.rect.x + r.rect.width) / bin).min(d.out_w);
            let y1 = ((r.rect.y + r.rect.height) / bin).min(d.out_h);
            let mut counts = vec![0u64; names.len() + 1];
            for y in y0..y1.max(y0) {
                for x in x0..x1.max(x0) {
                    if let Some(c) = class.get(y * d.out_w + x)
                        && let Some(n) = counts.get_mut(*c as usize)
                    {
                        *n += 1;
                    }
                }
            }
            let correct = r.class.as_ref().map_or(0, |cls| {
                names
                    .iter()
                    .position(|n| n == cls)
                    .map_or(0, |i| counts[i + 1])
            });
            RegionSummary {
                name: r.name.clone(),
                rect: [r.rect.x, r.rect.y, r.rect.width, r.rect.height],
                pixels: counts.iter().sum(),
                classes: counts
                    .iter()
                    .enumerate()
                    .filter(|(_, n)| **n > 0)
                    .map(|(i, n)| (label(i), *n))
                    .collect(),
                class: r.class.clone(),
                correct,
            }
        })
        .collect()
}

impl MapResult {
    /// The summary as JSON (the content of `map_summary.json` without the input paths
    /// and timings, which the caller adds): size, binning, thresholds, metric, pixel
    /// counts per reason and per class, and the regions. With calibrated geometry also
    /// `"geometry": "calibrated"`, each capture's β range (`beta_range_deg`) and the
    /// reason `no_geometry` (far-field summaries list only the reasons they can have,
    /// as before it existed).
    pub fn summary_json(&self) -> Value {
        let names = self.reason_names();
        let reasons: serde_json::Map<String, Value> = names
            .iter()
            .zip(self.counts.reasons)
            .map(|(n, c)| (n.to_string(), json!(c)))
            .collect();
        let class_counts: Vec<Value> = self
            .counts
            .classes
            .iter()
            .enumerate()
            .map(|(i, c)| {
                json!({
                    "index": i,
                    "name": self.class_name(i),
                    "pixels": c,
                })
            })
            .collect();
        let mut v = json!({
            "frame_width": self.frame_width,
            "frame_height": self.frame_height,
            "bin": self.bin,
            "width": self.width,
            "height": self.height,
            "captures": self.beta_deg.len(),
            "beta_deg": self.beta_deg,
            "min_s0_dn": self.min_s0_dn,
            "max_distance": self.max_distance,
            "metric": self.metric.name(),
            "pixels": self.width * self.height,
            "classified": self.classified(),
            "reasons": reasons,
            "reason_codes": names,
            "classes": class_counts,
            "regions": self.regions.iter().map(RegionSummary::to_json).collect::<Vec<_>>(),
        });
        v["rule"] = json!(self.rule.name());
        if self.rule == super::Rule::Set {
            let e = &self.errors;
            v["confidence"] = json!(self.confidence);
            v["error_model"] = json!({
                "angle_sd_deg": e.angle_sd_deg,
                "dolp_floor": e.dolp_floor,
                "extinction_ratio": finite(e.extinction_ratio),
                "retardance_deg": e.retardance_deg,
            });
        }
        v["answers"] = json!(self.answers());
        v["weights"] = json!(if self.weighted { "noise" } else { "none" });
        v["noise"] = match &self.noise {
            Some(n) => json!({
                "read_noise_dn": n.model.read_var_dn2.sqrt(),
                "gain_e_per_dn": finite(1.0 / n.model.inv_gain),
                "pixels": n.pixels,
                "outliers": n.outliers,
                "reduced_chi2": finite(n.reduced_chi2),
            }),
            None => Value::Null,
        };
        if self.is_colour() {
            v["bands"] = json!(
                self.bands
                    .iter()
                    .map(|b| {
                        let files: Vec<String> =
                            super::bands::image_files(Some(super::band_tag(b.wavelength_nm)))
                                .collect();
                        let reasons: serde_json::Map<String, Value> = names
                            .iter()
                            .zip(b.reasons)
                            .filter(|(_, c)| *c > 0)
                            .map(|(n, c)| (n.to_string(), json!(c)))
                            .collect();
                        let captures: Vec<usize> = b.captures.iter().map(|&i| i + 1).collect();
                        json!({
                            "wavelength_nm": b.wavelength_nm,
                            "captures": captures,
                            "fitted": b.reasons[polarid_core::map::reason::CLASSIFIED as usize],
                            "reasons": reasons,
                            "weights": if b.noise.is_some() { "noise" } else { "none" },
                            "files": files,
                        })
                    })
                    .collect::<Vec<_>>()
            );
        }
        if self.calibrated {
            v["geometry"] = json!("calibrated");
            v["beta_range_deg"] = json!(
                self.beta_range_deg
                    .iter()
                    .map(|r| r.iter().map(|&x| finite(x)).collect::<Vec<_>>())
                    .collect::<Vec<_>>()
            );
            v["beta_deg"] = json!(self.beta_deg.iter().map(|&x| finite(x)).collect::<Vec<_>>());
        }
        v
    }

    /// `classes.json`: class index (as a string) → answer, `"0": "unknown"` (no
    /// material; `reason.tif` says why), `"ambiguous"` last under the set rule.
    pub fn classes_json(&self) -> Value {
        let mut m = serde_json::Map::new();
        m.insert("0".into(), json!(UNKNOWN));
        for (i, n) in self.class_names.iter().enumerate() {
            m.insert((i + 1).to_string(), json!(n));
        }
        Value::Object(m)
    }
}

/// The pixels of a map by answer (docs/FORMATS.md, "Answers"): one material, several
/// (`ambiguous`) or none (`unknown`); the three add up to the map's pixels. Why a pixel
/// is `unknown` is in its reason (`rejected`: fitted `ok` but no material consistent;
/// the other reasons: no usable fit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct Answers {
    /// Pixels given one material.
    pub material: u64,
    /// Pixels consistent with several materials (set rule).
    pub ambiguous: u64,
    /// Pixels given no material (class 0, `unknown`): [`Answers::rejected`] plus the
    /// pixels without a usable fit.
    pub unknown: u64,
    /// The `unknown` pixels fitted with status `ok` but placed nowhere (reason
    /// `rejected`: no consistent material, or the nearest one beyond the maximum
    /// distance). Not serialized: the summary's `reasons` carry it.
    #[serde(skip)]
    pub rejected: u64,
}

impl Answers {
    /// The `unknown` pixels without a usable fit (signal, geometry, or a fit that is not
    /// `ok`).
    pub fn not_fitted(&self) -> u64 {
        self.unknown - self.rejected
    }
}

impl MapResult {
    /// The pixels by answer.
    pub fn answers(&self) -> Answers {
        let r = &self.counts.reasons;
        let material = r[polarid_core::map::reason::CLASSIFIED as usize];
        let ambiguous = r[polarid_core::map::reason::AMBIGUOUS as usize];
        let rejected = r[polarid_core::map::reason::REJECTED as usize];
        let total: u64 = r.iter().sum();
        Answers {
            material,
            ambiguous,
            unknown: total - material - ambiguous,
            rejected,
        }
    }
}
