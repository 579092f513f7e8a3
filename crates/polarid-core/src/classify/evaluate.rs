//! Evaluation of a classifier on labelled estimates: [`leave_one_out`] (each estimate
//! against all the others) and [`evaluate`] (against a trained classifier), with the
//! [`Confusion`] matrix and the accuracy `correct / total` ([`UNKNOWN`] and
//! [`AMBIGUOUS`](super::AMBIGUOUS) count as wrong), and the consistent sets' [`SetStats`]:
//! coverage (truth in the set) and set sizes.

use super::{
    Classifier, ClassifierConfig, Decision, Estimate, Metric, MultiEstimate, MultiPrototype,
    Prototype, Rule, UNKNOWN, check_class_name,
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

/// Most prototypes a leave-one-out decision keeps in [`Decision::ranked`](super::Decision).
pub const LOO_RANKED_KEPT: usize = 64;

/// Leave-one-out evaluation: each labelled estimate whose fit status is `ok` is classified
/// with the others (fit status `ok`) as prototypes. Items whose fit is not `ok` are neither
/// prototypes nor evaluated; they are listed in [`Evaluation::skipped`].
///
/// Memory is linear in the number of items: no classifier over all the others is built
/// per item. For each item the decision depends only on, per class, its `k` nearest
/// other prototypes by the rule's distance and its nearest by the set distance (plus
/// the first prototype without a usable distance, which decides a `no_covariance`
/// answer); these are found in one pass over the others and classified exactly as
/// against all of them (same distances, votes, runner-up, candidates and tie-breaking:
/// ties go to the earlier item). Indices in a decision refer to the others in input
/// order, as if item `i` were removed; its `ranked` holds at most the `k` nearest
/// (capped at `LOO_RANKED_KEPT`).
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
    // Single-band items (no wavelength): the linear-memory selection below. Several
    // bands: a classifier over the others per item (memory linear too, time n²).
    let singles: Option<Vec<Estimate>> = usable.iter().map(|o| single_band(&o.estimate)).collect();
    let Some(singles) = singles else {
        return leave_one_out_multi(&usable, skipped, config);
    };
    let protos: Vec<Prototype> = usable
        .iter()
        .zip(&singles)
        .map(|(o, e)| Prototype {
            class: o.class.clone(),
            n: e.n,
            k: e.k,
            cov: e.cov,
            category: None,
            source: o.source.clone(),
        })
        .collect();
    // Checks every prototype once (the same checks as per item before).
    let all = Classifier::new(protos, config)?;
    let protos = all.prototypes();
    // Class of each prototype as a small integer.
    let mut names: Vec<&str> = protos.iter().map(|p| p.class.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    let class_of: Vec<usize> = protos
        .iter()
        .map(|p| names.binary_search(&p.class.as_str()).unwrap_or(0))
        .collect();
    let mut counts = vec![0usize; names.len()];
    for &c in &class_of {
        counts[c] += 1;
    }
    let mut sel = Selector::new(names.len(), config.k);
    let mut out = Vec::with_capacity(usable.len());
    let mut unrep = Vec::new();
    for (i, it) in usable.iter().enumerate() {
        if counts[class_of[i]] < 2 {
            unrep.push(it.class.clone());
        }
        let chosen = sel.select(&singles[i], protos, &class_of, i, config);
        let reduced: Vec<Prototype> = chosen.iter().map(|&j| protos[j].clone()).collect();
        let clf = Classifier::new(reduced, config)?;
        let mut decision = clf.classify(&singles[i]);
        // Indices: reduced → all usable → the others (item i removed).
        let map = |r: usize| {
            let j = chosen.get(r).copied().unwrap_or(r);
            if j > i { j - 1 } else { j }
        };
        if let Some(nb) = decision.nearest.as_mut() {
            nb.index = map(nb.index);
        }
        for nb in &mut decision.ranked {
            nb.index = map(nb.index);
        }
        for c in &mut decision.candidates {
            c.index = map(c.index);
        }
        decision.ranked.truncate(config.k.clamp(1, LOO_RANKED_KEPT));
        decision.ranked.shrink_to_fit();
        out.push(EvalItem {
            target: it.target.clone(),
            class: it.class.clone(),
            decision,
        });
    }
    Ok(finish(out, skipped, unrep, config.confidence))
}

/// The estimate of a single-band item without a wavelength (the paper's case).
fn single_band(e: &MultiEstimate) -> Option<Estimate> {
    match e.bands.as_slice() {
        [b] if b.wavelength_nm.is_none() => Some(b.estimate.clone()),
        _ => None,
    }
}

/// Leave-one-out over multi-band items: a classifier over all the others per item
/// (memory linear in the items; `ranked` capped at [`LOO_RANKED_KEPT`]).
fn leave_one_out_multi(
    usable: &[&Labelled],
    skipped: Vec<(String, crate::status::FitStatus)>,
    config: ClassifierConfig,
) -> Result<Evaluation> {
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
            decision: {
                let mut d = clf.classify_multi(&it.estimate);
                d.ranked.truncate(config.k.clamp(1, LOO_RANKED_KEPT));
                d.ranked.shrink_to_fit();
                d
            },
        });
    }
    Ok(finish(out, skipped, unrep, config.confidence))
}

/// The distance a classifier with `config` ranks prototypes by (`None`: not usable,
/// which makes the classifier answer `no_covariance`): the set distance under the set
/// rule; the Euclidean or Mahalanobis distance under the nearest rule (as in
/// `Classifier::classify`).
fn rule_distance(config: &ClassifierConfig, est: &Estimate, p: &Prototype) -> Option<f64> {
    match (config.rule, config.metric) {
        (Rule::Set, _) => Classifier::set_distance(est, p),
        (_, Metric::Euclidean) => Some((est.n - p.n).hypot(est.k - p.k)),
        (_, _) => {
            let cov = match (est.cov, p.cov) {
                (Some(a), Some(b)) => a + b,
                (Some(a), None) | (None, Some(a)) => a,
                (None, None) => return None,
            };
            cov.mahalanobis2(est.n - p.n, est.k - p.k).map(f64::sqrt)
        }
    }
}

/// Finds, for one item, the prototypes its leave-one-out decision depends on; its
/// buffers are reused from item to item.
struct Selector {
    k: usize,
    /// Per class, the `k` nearest by the rule's distance: `(distance, index)`, sorted.
    near: Vec<Vec<(f64, usize)>>,
    /// Per class, the nearest by the set distance.
    near_set: Vec<Option<(f64, usize)>>,
}

/// `(d, i)` before `(e, j)` in the classifier's order (distance, then index).
fn before(a: (f64, usize), b: (f64, usize)) -> bool {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).is_lt()
}

impl Selector {
    fn new(classes: usize, k: usize) -> Self {
        Self {
            k,
            near: vec![Vec::with_capacity(k.min(64)); classes],
            near_set: vec![None; classes],
        }
    }

    /// Indices (into `protos`, ascending, `skip` excluded) of the prototypes the
    /// decision for `est` depends on.
    fn select(
        &mut self,
        est: &Estimate,
        protos: &[Prototype],
        class_of: &[usize],
        skip: usize,
        config: ClassifierConfig,
    ) -> Vec<usize> {
        for v in &mut self.near {
            v.clear();
        }
        self.near_set.iter_mut().for_each(|s| *s = None);
        let set_too = config.rule == Rule::Nearest;
        let (mut first_none, mut first_set_none) = (None, None);
        for (j, p) in protos.iter().enumerate() {
            if j == skip {
                continue;
            }
            let c = class_of[j];
            match rule_distance(&config, est, p) {
                Some(d) => {
                    let v = &mut self.near[c];
                    if v.len() < self.k || v.last().is_some_and(|&w| before((d, j), w)) {
                        let at = v.partition_point(|&w| before(w, (d, j)));
                        v.insert(at, (d, j));
                        v.truncate(self.k);
                    }
                }
                None => {
                    first_none.get_or_insert(j);
                }
            }
            if set_too {
                match Classifier::set_distance(est, p) {
                    Some(d) => {
                        let s = &mut self.near_set[c];
                        if s.is_none_or(|w| before((d, j), w)) {
                            *s = Some((d, j));
                        }
                    }
                    None => {
                        first_set_none.get_or_insert(j);
                    }
                }
            }
        }
        let mut chosen: Vec<usize> = self
            .near
            .iter()
            .flatten()
            .map(|&(_, j)| j)
            .chain(self.near_set.iter().flatten().map(|&(_, j)| j))
            .chain(first_none)
            .chain(first_set_none)
            .collect();
        chosen.sort_unstable();
        chosen.dedup();
        chosen
    }
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

    /// The leave-one-out of before: a classifier over all the others per item.
    fn brute_force(items: &[Labelled], config: ClassifierConfig) -> Vec<Decision> {
        let usable: Vec<&Labelled> = items
            .iter()
            .filter(|i| i.estimate.fit_status().is_ok())
            .collect();
        let single = |e: &MultiEstimate| single_band(e).unwrap();
        (0..usable.len())
            .map(|i| {
                let protos: Vec<Prototype> = usable
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, o)| {
                        let e = single(&o.estimate);
                        Prototype {
                            class: o.class.clone(),
                            n: e.n,
                            k: e.k,
                            cov: e.cov,
                            category: None,
                            source: o.source.clone(),
                        }
                    })
                    .collect();
                Classifier::new(protos, config)
                    .unwrap()
                    .classify(&single(&usable[i].estimate))
            })
            .collect()
    }

    /// Random labelled estimates: a few classes around centres, some without covariance,
    /// some near k = 0, some duplicated points (ties).
    fn random_items(seed: u64, n: usize, classes: usize, cov_every: u64) -> Vec<Labelled> {
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut next = move || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut out: Vec<Labelled> = Vec::new();
        for t in 0..n {
            let c = (next() * classes as f64) as usize;
            let (cn, ck) = (0.5 + c as f64 * 0.4, (c as f64 * 0.9) % 3.0);
            let (mut n_, mut k_) = (cn + 0.3 * (next() - 0.5), (ck + 0.3 * (next() - 0.5)).abs());
            if t % 7 == 3
                && let Some(prev) = out.last()
            {
                let e = single_band(&prev.estimate).unwrap();
                (n_, k_) = (e.n, e.k);
            }
            let cov = if cov_every == 1 || (cov_every > 1 && !(t as u64).is_multiple_of(cov_every))
            {
                super::super::Cov2::from_se(0.02 + 0.1 * next(), 0.02 + 0.1 * next(), next() - 0.5)
            } else {
                None
            };
            out.push(Labelled {
                target: format!("t{t}"),
                class: format!("c{c}"),
                estimate: Estimate {
                    n: n_,
                    k: k_,
                    cov,
                    fit_status: if t % 11 == 5 {
                        FitStatus::NotConverged
                    } else {
                        FitStatus::Ok
                    },
                }
                .into(),
                source: format!("s{t}"),
            });
        }
        out
    }

    #[test]
    fn loo_equals_the_classifier_over_all_others() {
        let configs = [
            ClassifierConfig::default(),
            ClassifierConfig {
                k: 3,
                ..Default::default()
            },
            ClassifierConfig {
                k: 4,
                metric: Metric::Mahalanobis,
                ..Default::default()
            },
            ClassifierConfig {
                reject: super::super::Reject::Chi2 { p: 0.9 },
                ..Default::default()
            },
            ClassifierConfig {
                reject: super::super::Reject::MaxDistance(0.05),
                k: 2,
                ..Default::default()
            },
            ClassifierConfig::set(0.95),
            ClassifierConfig::set(0.5),
        ];
        let mut compared = 0;
        for seed in 0..12u64 {
            let cov_every = [0, 1, 5][seed as usize % 3];
            let items = random_items(
                seed,
                30 + seed as usize * 7,
                2 + seed as usize % 4,
                cov_every,
            );
            for cfg in configs {
                let ev = leave_one_out(&items, cfg).unwrap();
                let want = brute_force(&items, cfg);
                assert_eq!(ev.items.len(), want.len());
                for (got, want) in ev.items.iter().zip(&want) {
                    let mut w = want.clone();
                    w.ranked.truncate(cfg.k.clamp(1, LOO_RANKED_KEPT));
                    // Debug text: NaN distances compare equal.
                    assert_eq!(
                        format!("{:?}", got.decision),
                        format!("{w:?}"),
                        "seed {seed} {cfg:?} {}",
                        got.target
                    );
                    compared += 1;
                }
            }
        }
        assert!(compared > 3000, "{compared}");
    }

    #[test]
    fn loo_keeps_per_item_memory_independent_of_the_number_of_items() {
        // Each decision keeps a bounded number of neighbours, whatever the number of
        // items (it held all n - 1 before: n² in all).
        for n in [50, 400] {
            let items = random_items(7, n, 3, 1);
            for cfg in [ClassifierConfig::default(), ClassifierConfig::set(0.95)] {
                let ev = leave_one_out(&items, cfg).unwrap();
                let most = ev.items.iter().map(|i| i.decision.ranked.len()).max();
                assert_eq!(most, Some(1), "n = {n}");
                assert!(ev.items.iter().all(|i| i.decision.candidates.len() <= 3));
            }
        }
    }
}
