//! Wolff's baseline scored on the evaluated targets.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use polarid_core::classify::{Confusion, Evaluation, Prototype, UNKNOWN, WolffDecision};
use polarid_io::library::Library;

use super::WolffEvalRequest;
use crate::Result;
use crate::classify::WolffData;

/// Categories accepted as a class's true category.
pub const CATEGORIES: [&str; 4] = ["metal", "dielectric", "semiconductor", "other"];

/// A class name as matched against categories: lower case, spaces as underscores.
fn name_key(class: &str) -> String {
    class.trim().to_lowercase().replace(' ', "_")
}

/// Where the true categories of the classes come from, in order of precedence.
struct Categories {
    /// `(source label, class key → category)`, first match wins.
    sources: Vec<(String, BTreeMap<String, String>)>,
}

impl Categories {
    fn new(req: &WolffEvalRequest, model: Option<(&Path, &[Prototype])>) -> Result<Self> {
        let mut sources = Vec::new();
        if !req.categories.is_empty() {
            let given = req.categories.iter();
            let m = given.map(|(class, cat)| (name_key(class), cat.trim().to_string()));
            sources.push(("--wolff-category".to_string(), m.collect()));
        }
        let keyed = |protos: &[Prototype]| {
            let mut m = BTreeMap::new();
            for p in protos {
                if let Some(c) = &p.category {
                    m.entry(name_key(&p.class)).or_insert_with(|| c.clone());
                }
            }
            m
        };
        if let Some((path, protos)) = model {
            sources.push((format!("model {}", path.display()), keyed(protos)));
        }
        let lib = Library::load(&req.library)?;
        sources.push((format!("library {}", req.library), keyed(&lib.prototypes())));
        Ok(Self { sources })
    }

    /// The category of `class` and where it came from.
    fn of(&self, class: &str) -> Option<(&str, &str)> {
        let key = name_key(class);
        self.sources
            .iter()
            .find_map(|(src, m)| m.get(&key).map(|c| (c.as_str(), src.as_str())))
    }

    /// The sources, for messages: `--wolff-category, library builtin`.
    fn describe(&self) -> String {
        self.sources
            .iter()
            .map(|(s, _)| s.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Wolff's decision on one evaluated target.
#[derive(Debug, Clone)]
pub struct WolffItem {
    /// Target name.
    pub target: String,
    /// True class.
    pub class: String,
    /// True category (`metal` or `dielectric`).
    pub category: String,
    /// Where `category` came from.
    pub category_source: String,
    /// Wolff's decision.
    pub decision: WolffDecision,
    /// The (n, k) classifier's prediction.
    pub predicted: String,
    /// Category of the classifier's prediction (`unknown` when it has none).
    pub predicted_category: String,
}

/// Wolff's baseline on the evaluated targets.
#[derive(Debug, Clone)]
pub struct WolffEval {
    /// Settings, e.g. `Fresnel ratio threshold 6, beta in [40, 70] deg`.
    pub settings: String,
    /// The measurements file.
    pub measurements: PathBuf,
    /// Where the categories came from, e.g. `--wolff-category, library builtin`.
    pub categories: String,
    /// Scored targets.
    pub items: Vec<WolffItem>,
    /// Targets not scored: `(target, class, category)`.
    pub not_scored: Vec<(String, String, Option<String>)>,
    /// Scored targets without any row in the measurements file.
    pub no_rows: Vec<String>,
    /// Rows: true category; columns: Wolff's class.
    pub confusion: Confusion,
    /// Wolff's metal/dielectric accuracy.
    pub accuracy: f64,
    /// The classifier's `(correct, total)` on the scored targets, by material.
    pub nn_material: (u64, u64),
    /// The classifier's `(correct, total)` on the scored targets, by metal/dielectric.
    pub nn_binary: (u64, u64),
}

/// `correct / total` of a `(correct, total)` pair (NaN when `total` is 0).
pub fn ratio((c, t): (u64, u64)) -> f64 {
    if t == 0 {
        f64::NAN
    } else {
        c as f64 / t as f64
    }
}

/// Run Wolff's rule on the evaluated targets of `ev`.
pub(super) fn score(
    req: &WolffEvalRequest,
    ev: &Evaluation,
    model: Option<(&Path, &[Prototype])>,
) -> Result<WolffEval> {
    let data = WolffData::load(&req.measurements, req.settings)?;
    let cats = Categories::new(req, model)?;
    let mut items = Vec::new();
    let mut not_scored = Vec::new();
    let mut no_rows = Vec::new();
    for it in &ev.items {
        let (category, source) = match cats.of(&it.class) {
            Some((c @ ("metal" | "dielectric"), src)) => (c.to_string(), src.to_string()),
            other => {
                not_scored.push((
                    it.target.clone(),
                    it.class.clone(),
                    other.map(|(c, _)| c.to_string()),
                ));
                continue;
            }
        };
        if data.of(&it.target).is_empty() {
            no_rows.push(it.target.clone());
        }
        let decision = data.decide(&it.target, &format!("target {}", it.target))?;
        let predicted = it.decision.predicted.clone();
        let predicted_category = cats.of(&predicted).map_or(UNKNOWN, |(c, _)| c).to_string();
        items.push(WolffItem {
            target: it.target.clone(),
            class: it.class.clone(),
            category,
            category_source: source,
            decision,
            predicted,
            predicted_category,
        });
    }
    let confusion = Confusion::from_pairs(
        items
            .iter()
            .map(|i| (i.category.as_str(), i.decision.class.name())),
    );
    let accuracy = confusion.accuracy();
    let right = |f: fn(&WolffItem) -> bool| {
        let n = items.iter().filter(|i| f(i)).count() as u64;
        (n, items.len() as u64)
    };
    let nn_material = right(|i| i.predicted == i.class);
    let nn_binary = right(|i| i.predicted_category == i.category);
    Ok(WolffEval {
        settings: req.settings.describe(),
        measurements: req.measurements.clone(),
        categories: cats.describe(),
        items,
        not_scored,
        no_rows,
        confusion,
        accuracy,
        nn_material,
        nn_binary,
    })
}
