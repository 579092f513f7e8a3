//! Evaluation of a classifier on labelled estimates: [`leave_one_out`] (each estimate
//! against all the others) and [`evaluate`] (against a trained classifier), with the
//! [`Confusion`] matrix and the accuracy `correct / total` ([`UNKNOWN`] and
//! [`AMBIGUOUS`](super::AMBIGUOUS) count as wrong), and the consistent sets' [`SetStats`]:
//! coverage (truth in the set) and set sizes.

use super::{
    Classifier, ClassifierConfig, Decision, MultiEstimate, MultiPrototype, UNKNOWN,
    check_class_name,
};
use crate::error::{CoreError, Result};
use crate::status::FitStatus;

/// A labelled estimate for evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Labelled {
    /// Target name.
    pub target: String,
    /// True class.
    pub class: String,
    /// The estimate, in one band or several (`MultiEstimate::from(estimate)` for one).
    pub estimate: MultiEstimate,
    /// Where it came from (becomes the prototype's source).
    pub source: String,
}

impl Labelled {
    /// This estimate as a prototype of its class (its bands whose fit is `ok`).
    pub fn to_prototype(&self) -> MultiPrototype {
        self.estimate.to_prototype(&self.class, &self.source)
    }
}

/// A confusion matrix: rows are true classes, columns predicted classes (the true classes
/// in the same order, then any other predicted class, then [`UNKNOWN`] if it occurs).
#[derive(Debug, Clone, PartialEq)]
pub struct Confusion {
    /// Row labels (true classes, sorted).
    pub truth: Vec<String>,
    /// Column labels.
    pub predicted: Vec<String>,
    /// `counts[row][column]`.
    pub counts: Vec<Vec<u64>>,
}

impl Confusion {
    /// Build from `(truth, predicted)` pairs.
    pub fn from_pairs<'a>(pairs: impl IntoIterator<Item = (&'a str, &'a str)> + Clone) -> Self {
        let mut truth: Vec<String> = pairs.clone().into_iter().map(|p| p.0.into()).collect();
        truth.sort();
        truth.dedup();
        let mut predicted = truth.clone();
        let mut extra: Vec<String> = pairs
            .clone()
            .into_iter()
            .map(|p| p.1.to_string())
            .filter(|p| !truth.contains(p) && p != UNKNOWN)
            .collect();
        extra.sort();
        extra.dedup();
        predicted.extend(extra);
        if pairs.clone().into_iter().any(|p| p.1 == UNKNOWN) {
            predicted.push(UNKNOWN.into());
        }
        let mut counts = vec![vec![0u64; predicted.len()]; truth.len()];
        for (t, p) in pairs {
            let r = truth.iter().position(|x| x == t);
            let c = predicted.iter().position(|x| x == p);
            if let (Some(r), Some(c)) = (r, c) {
                counts[r][c] += 1;
            }
        }
        Self {
            truth,
            predicted,
            counts,
        }
    }

    /// Count of items of true class `truth` predicted as `predicted`.
    pub fn get(&self, truth: &str, predicted: &str) -> u64 {
        match (
            self.truth.iter().position(|x| x == truth),
            self.predicted.iter().position(|x| x == predicted),
        ) {
            (Some(r), Some(c)) => self.counts[r][c],
            _ => 0,
        }
    }

    /// Items on the diagonal (predicted = true class).
    pub fn correct(&self) -> u64 {
        self.truth.iter().map(|t| self.get(t, t)).sum()
    }

    /// All items.
    pub fn total(&self) -> u64 {
        self.counts.iter().flatten().sum()
    }

    /// `correct / total` (NaN for an empty matrix). [`UNKNOWN`] counts as wrong.
    pub fn accuracy(&self) -> f64 {
        let t = self.total();
        if t == 0 {
            f64::NAN
        } else {
            self.correct() as f64 / t as f64
        }
    }
}

/// One evaluated item.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalItem {
    /// Target name.
    pub target: String,
    /// True class.
    pub class: String,
    /// The decision.
    pub decision: Decision,
}

/// Statistics of the consistent sets over the evaluated items whose set was tested.
#[derive(Debug, Clone, PartialEq)]
pub struct SetStats {
    /// Confidence of the sets.
    pub confidence: f64,
    /// Items whose set was tested (a covariance was available).
    pub tested: u64,
    /// Items whose true class is among the candidates.
    pub covered: u64,
    /// `covered / tested`: the coverage, to compare with the confidence.
    pub coverage: f64,
    /// Mean number of candidates.
    pub mean_size: f64,
    /// Items with exactly one candidate / several / none.
    pub single: u64,
    /// Items with several candidates.
    pub several: u64,
    /// Items with no candidate.
    pub empty: u64,
    /// Items with exactly one candidate, the true class.
    pub single_correct: u64,
}

impl SetStats {
    /// Statistics of `items` (only those whose set was tested); `None` when none was.
    pub fn of(items: &[EvalItem], confidence: f64) -> Option<Self> {
        let tested: Vec<&EvalItem> = items.iter().filter(|i| i.decision.set_tested).collect();
        if tested.is_empty() {
            return None;
        }
        let count = |f: &dyn Fn(&EvalItem) -> bool| tested.iter().filter(|i| f(i)).count() as u64;
        let covered = count(&|i| i.decision.candidates.iter().any(|c| c.class == i.class));
        let sizes: usize = tested.iter().map(|i| i.decision.candidates.len()).sum();
        let t = tested.len() as f64;
        Some(Self {
            confidence,
            tested: tested.len() as u64,
            covered,
            coverage: covered as f64 / t,
            mean_size: sizes as f64 / t,
            single: count(&|i| i.decision.candidates.len() == 1),
            several: count(&|i| i.decision.candidates.len() > 1),
            empty: count(&|i| i.decision.candidates.is_empty()),
            single_correct: count(&|i| {
                i.decision.candidates.len() == 1 && i.decision.candidates[0].class == i.class
            }),
        })
    }
}

/// Result of an evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Items evaluated (fit status `ok`).
    pub items: Vec<EvalItem>,
    /// Items not evaluated because their fit status is not `ok`: `(target, status)`.
    pub skipped: Vec<(String, FitStatus)>,
    /// True classes that no prototype represents when their items are classified (a
    /// class with a single sample in leave-one-out, or absent from a model): these items
    /// cannot be classified correctly.
    pub unrepresented: Vec<String>,
    /// Confusion matrix of the evaluated items.
    pub confusion: Confusion,
    /// Fraction of evaluated items predicted as their true class.
    pub accuracy: f64,
    /// Coverage and sizes of the consistent sets (`None` when no set was tested).
    pub sets: Option<SetStats>,
}

fn check_labels(items: &[Labelled]) -> Result<()> {
    for it in items {
        check_class_name(&it.class)?;
    }
    Ok(())
}

fn finish(
    items: Vec<EvalItem>,
    skipped: Vec<(String, FitStatus)>,
    mut unrep: Vec<String>,
    confidence: f64,
) -> Evaluation {
    unrep.sort();
    unrep.dedup();
    let confusion = Confusion::from_pairs(
        items
            .iter()
            .map(|i| (i.class.as_str(), i.decision.predicted.as_str())),
    );
    let accuracy = confusion.accuracy();
    let sets = SetStats::of(&items, confidence);
    Evaluation {
        sets,
        items,
        skipped,
        unrepresented: unrep,
        confusion,
        accuracy,
    }
}

/// Leave-one-out evaluation: each labelled estimate whose fit status is `ok` is classified
/// with the others (fit status `ok`) as prototypes. Items whose fit is not `ok` are neither
/// prototypes nor evaluated; they are listed in [`Evaluation::skipped`].
///
/// Fails when a class name is empty or [`UNKNOWN`], fewer than two items are usable, or
/// the settings are invalid.
pub fn leave_one_out(items: &[Labelled], config: ClassifierConfig) -> Result<Evaluation> {
    config.validate()?;
    check_labels(items)?;
    let usable: Vec<&Labelled> = items
        .iter()
        .filter(|i| i.estimate.fit_status().is_ok())
        .collect();
    if usable.len() < 2 {
        return Err(CoreError::TooFew {
            what: "labelled estimates with fit status ok (leave-one-out)",
            needed: 2,
            got: usable.len(),
        });
    }
    let skipped = items
        .iter()
        .filter(|i| !i.estimate.fit_status().is_ok())
        .map(|i| (i.target.clone(), i.estimate.fit_status()))
        .collect();
    let mut out = Vec::with_capacity(usable.len());
    let mut unrep = Vec::new();
    for (i, it) in usable.iter().enumerate() {
        let protos: Vec<MultiPrototype> = usable
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, o)| o.to_prototype())
            .collect();
        if !protos.iter().any(|p| p.class == it.class) {
            unrep.push(it.class.clone());
        }
        let clf = Classifier::multi(protos, config)?;
        out.push(EvalItem {
            target: it.target.clone(),
            class: it.class.clone(),
            decision: clf.classify_multi(&it.estimate),
        });
    }
    Ok(finish(out, skipped, unrep, config.confidence))
}

/// Evaluate a trained classifier on a labelled test set (no leave-one-out). Items whose
/// fit is not `ok` are skipped; true classes the classifier does not know are listed in
/// [`Evaluation::unrepresented`].
pub fn evaluate(classifier: &Classifier, items: &[Labelled]) -> Result<Evaluation> {
    check_labels(items)?;
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    let mut unrep = Vec::new();
    for it in items {
        if !it.estimate.fit_status().is_ok() {
            skipped.push((it.target.clone(), it.estimate.fit_status()));
            continue;
        }
        if !classifier.prototypes().iter().any(|p| p.class == it.class) {
            unrep.push(it.class.clone());
        }
        out.push(EvalItem {
            target: it.target.clone(),
            class: it.class.clone(),
            decision: classifier.classify_multi(&it.estimate),
        });
    }
    Ok(finish(out, skipped, unrep, classifier.config().confidence))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::Estimate;

    #[test]
    fn loo_confusion_and_accuracy() {
        let mk = |t: &str, c: &str, n: f64, k: f64| Labelled {
            target: t.into(),
            class: c.into(),
            estimate: Estimate::point(n, k).into(),
            source: t.into(),
        };
        let items = vec![
            mk("a1", "al", 1.6, 4.5),
            mk("a2", "al", 1.5, 4.4),
            mk("c1", "cu", 0.5, 3.2),
            mk("c2", "cu", 0.6, 3.1),
            mk("p1", "paint", 1.4, 0.4),
            Labelled {
                estimate: Estimate {
                    fit_status: FitStatus::Depolarized,
                    ..Estimate::point(9.0, 9.0)
                }
                .into(),
                ..mk("bad", "al", 0.0, 0.0)
            },
        ];
        let ev = leave_one_out(&items, ClassifierConfig::default()).unwrap();
        assert_eq!(ev.items.len(), 5);
        assert_eq!(
            ev.skipped,
            vec![("bad".to_string(), FitStatus::Depolarized)]
        );
        assert_eq!(ev.unrepresented, vec!["paint".to_string()]);
        assert_eq!(ev.confusion.get("al", "al"), 2);
        assert_eq!(ev.confusion.get("cu", "cu"), 2);
        assert_eq!(ev.confusion.get("paint", "paint"), 0);
        assert_eq!(ev.confusion.total(), 5);
        assert!((ev.accuracy - 0.8).abs() < 1e-12);
        assert!(ev.sets.is_none(), "no covariance, no set");
    }

    #[test]
    fn set_stats_count_coverage_and_sizes() {
        let mk = |t: &str, c: &str, n: f64, k: f64| Labelled {
            target: t.into(),
            class: c.into(),
            estimate: Estimate {
                cov: super::super::Cov2::from_se(0.1, 0.1, 0.0),
                ..Estimate::point(n, k)
            }
            .into(),
            source: t.into(),
        };
        let items = vec![
            mk("a1", "al", 1.6, 4.5),
            mk("a2", "al", 1.55, 4.45),
            mk("c1", "cu", 0.5, 3.2),
            mk("c2", "cu", 0.55, 3.15),
            mk("x1", "x", 0.52, 3.18),
            mk("x2", "x", 9.0, 9.0),
        ];
        let ev = leave_one_out(&items, ClassifierConfig::set(0.95)).unwrap();
        let s = ev.sets.unwrap();
        assert_eq!(s.tested, 6);
        // a1, a2: {al}; c1, c2: {x, cu} or {cu, x}; x1: {cu}; x2: {}.
        assert_eq!((s.single, s.several, s.empty), (3, 2, 1));
        assert_eq!(s.covered, 4);
        assert_eq!(s.single_correct, 2);
        assert!((s.mean_size - 7.0 / 6.0).abs() < 1e-12);
        assert!((s.coverage - 4.0 / 6.0).abs() < 1e-12);
        assert_eq!(ev.confusion.get("cu", "ambiguous"), 2);
        assert_eq!(ev.confusion.get("x", "unknown"), 1);
    }
}
