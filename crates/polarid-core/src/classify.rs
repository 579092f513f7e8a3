//! Material classification from estimated complex indices (paper section 6), and Wolff's
//! metal/dielectric baseline (paper ref. \[1\]).
//!
//! # Nearest neighbour and beyond
//!
//! The paper classifies an estimate `(n̂, k̂)` by the nearest prototype in the training set
//! with the Euclidean distance in the `(n, k)` plane (section 6):
//!
//! ```text
//! d_E = √((n̂ − n_p)² + (k̂ − k_p)²)
//! ```
//!
//! [`Classifier`] implements that rule (the default, [`Metric::Euclidean`], `k = 1`) plus:
//!
//! - **k-NN**: the `k` nearest prototypes vote; a tie in votes goes to the tied class whose
//!   nearest member is closest.
//! - **Mahalanobis distance** ([`Metric::Mahalanobis`]): `d_M² = Δᵀ (Σ_est + Σ_proto)⁻¹ Δ`
//!   with `Δ = (n̂ − n_p, k̂ − k_p)`, `Σ_est` the estimate's covariance (from `n_se`,
//!   `k_se`, `nk_corr` of the fit) and `Σ_proto` the prototype's covariance when it has one
//!   (a prototype trained from a fit; literature values have none).
//! - **Reject option** ([`Reject`]): the answer is [`UNKNOWN`] when the predicted class's
//!   nearest prototype is too far: either a χ² gate on the Mahalanobis distance (2 degrees
//!   of freedom: `d_M² > χ²₂(p) = −2 ln(1 − p)`, so `p = 0.99` rejects beyond
//!   `d_M = 3.035`), or a plain distance threshold in the metric's own units.
//!
//! Every [`Decision`] carries the predicted class, its distance, the runner-up (the nearest
//! prototype of a *different* class) and its distance, the margin
//! `runner_up_distance − distance`, a [`Status`] and every prototype ranked by distance (so
//! a report can show *why*). An estimate whose fit status is not `ok` is never classified:
//! it gets [`UNKNOWN`] and a status naming the fit status.
//!
//! # Wolff's baseline
//!
//! Wolff (L. B. Wolff, "Polarization-based material classification from specular
//! reflection", IEEE PAMI 12(11), 1990) separates metals from dielectrics with the
//! polarization Fresnel ratio `FR = Rs/Rp`: near Brewster's angle a dielectric reflects
//! almost no p-polarized light (`FR ≫ 1`) while a metal's `Rs` and `Rp` stay close
//! (`FR` of order 1). For unpolarized incident light the measured degree of polarization
//! is `P = (Rs − Rp)/(Rs + Rp)`, hence
//!
//! ```text
//! FR = Rs/Rp = (1 + P)/(1 − P)
//! ```
//!
//! so the rule works directly from DoLP measurements, on the same data as the index fit:
//! see [`wolff_classify`] for the threshold rule and its default.
//!
//! # Leave-one-out evaluation
//!
//! [`leave_one_out`] classifies each labelled estimate against all the others and returns
//! a [`Confusion`] matrix and the accuracy.

use std::collections::BTreeMap;

use crate::error::{CoreError, Result};
use crate::status::FitStatus;

/// The label of an estimate that is not assigned to any class (rejected, unusable fit,
/// missing covariance). It cannot be used as a class name.
pub const UNKNOWN: &str = "unknown";

/// A symmetric 2×2 covariance of `(n, k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cov2 {
    /// Variance of `n`.
    pub nn: f64,
    /// Covariance of `n` and `k`.
    pub nk: f64,
    /// Variance of `k`.
    pub kk: f64,
}

impl Cov2 {
    /// Covariance from standard errors and their correlation:
    /// `[[n_se², ρ n_se k_se], [ρ n_se k_se, k_se²]]`.
    ///
    /// `None` when any input is not finite, a standard error is not positive, or
    /// `|ρ| > 1` (a fit without standard errors writes NaN).
    pub fn from_se(n_se: f64, k_se: f64, corr: f64) -> Option<Self> {
        if !(n_se.is_finite() && k_se.is_finite() && corr.is_finite()) {
            return None;
        }
        if n_se <= 0.0 || k_se <= 0.0 || corr.abs() > 1.0 {
            return None;
        }
        Some(Self {
            nn: n_se * n_se,
            nk: corr * n_se * k_se,
            kk: k_se * k_se,
        })
    }

    /// Covariance from a matrix `[[nn, nk], [kn, kk]]`; `None` unless it is finite,
    /// symmetric and positive definite.
    pub fn from_matrix(m: [[f64; 2]; 2]) -> Option<Self> {
        let c = Self {
            nn: m[0][0],
            nk: m[0][1],
            kk: m[1][1],
        };
        let ok = m.iter().flatten().all(|v| v.is_finite())
            && m[0][1] == m[1][0]
            && c.nn > 0.0
            && c.nn * c.kk - c.nk * c.nk > 0.0;
        ok.then_some(c)
    }

    /// Standard errors and correlation `(n_se, k_se, nk_corr)`.
    pub fn to_se(&self) -> (f64, f64, f64) {
        let (sn, sk) = (self.nn.sqrt(), self.kk.sqrt());
        (sn, sk, self.nk / (sn * sk))
    }

    /// Squared Mahalanobis length of `(dn, dk)`: `Δᵀ Σ⁻¹ Δ`, or `None` when the matrix is
    /// not positive definite.
    #[inline]
    pub fn mahalanobis2(&self, dn: f64, dk: f64) -> Option<f64> {
        let det = self.nn * self.kk - self.nk * self.nk;
        if !(det > 0.0 && self.nn > 0.0 && det.is_finite()) {
            return None;
        }
        // Σ⁻¹ = [[kk, −nk], [−nk, nn]] / det
        let q = (self.kk * dn * dn - 2.0 * self.nk * dn * dk + self.nn * dk * dk) / det;
        (q.is_finite() && q >= 0.0).then_some(q)
    }
}

impl std::ops::Add for Cov2 {
    type Output = Self;

    /// Sum of two covariances (of independent estimates).
    fn add(self, other: Self) -> Self {
        Self {
            nn: self.nn + other.nn,
            nk: self.nk + other.nk,
            kk: self.kk + other.kk,
        }
    }
}

/// A labelled point of the `(n, k)` plane that estimates are compared with: a training
/// estimate or a literature value.
#[derive(Debug, Clone, PartialEq)]
pub struct Prototype {
    /// Class (material) name.
    pub class: String,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index (`k >= 0`).
    pub k: f64,
    /// Covariance of `(n, k)` when the prototype is itself an estimate.
    pub cov: Option<Cov2>,
    /// Broad category (`metal`, `dielectric`, `semiconductor`, `other`) when known.
    pub category: Option<String>,
    /// Where the prototype came from (e.g. `fits.csv:3 target A`, `library builtin`).
    pub source: String,
}

/// An estimate to classify.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Estimated real part of the index.
    pub n: f64,
    /// Estimated imaginary part of the index.
    pub k: f64,
    /// Covariance of the estimate (`None` when the fit gave no standard errors).
    pub cov: Option<Cov2>,
    /// Status of the fit: [`FitStatus::Ok`], or why it should not be trusted.
    pub fit_status: FitStatus,
}

impl Estimate {
    /// An estimate with status `ok` and no covariance.
    pub fn point(n: f64, k: f64) -> Self {
        Self {
            n,
            k,
            cov: None,
            fit_status: FitStatus::Ok,
        }
    }
}

/// Distance used to compare an estimate with the prototypes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Metric {
    /// Euclidean distance in `(n, k)` (the paper's rule).
    #[default]
    Euclidean,
    /// Mahalanobis distance with the estimate's (plus the prototype's) covariance.
    Mahalanobis,
}

impl Metric {
    /// Name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Euclidean => "euclidean",
            Metric::Mahalanobis => "mahalanobis",
        }
    }
}

/// When to answer [`UNKNOWN`] instead of the nearest class.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Reject {
    /// Never reject.
    #[default]
    Never,
    /// χ² gate with 2 degrees of freedom on the Mahalanobis distance to the predicted
    /// class's nearest prototype: reject when `d_M² > −2 ln(1 − p)`. Applies whatever
    /// the ranking metric; needs a covariance.
    Chi2 {
        /// Probability of the gate, in `(0, 1)` (e.g. 0.99).
        p: f64,
    },
    /// Reject when the distance (in the ranking metric's units) exceeds this value.
    MaxDistance(f64),
}

/// The χ² quantile with 2 degrees of freedom: `−2 ln(1 − p)` (the χ²₂ CDF is
/// `1 − exp(−x/2)`).
pub fn chi2_2dof_quantile(p: f64) -> f64 {
    -2.0 * (-p).ln_1p()
}

/// Settings of a [`Classifier`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClassifierConfig {
    /// Distance metric.
    pub metric: Metric,
    /// Number of neighbours that vote (1 = the paper's nearest neighbour).
    pub k: usize,
    /// Reject option.
    pub reject: Reject,
}

impl Default for ClassifierConfig {
    fn default() -> Self {
        Self {
            metric: Metric::Euclidean,
            k: 1,
            reject: Reject::Never,
        }
    }
}

impl ClassifierConfig {
    /// Check the settings.
    pub fn validate(&self) -> Result<()> {
        if self.k == 0 {
            return Err(CoreError::OutOfRange {
                name: "k (neighbours)",
                value: 0.0,
                expected: ">= 1",
            });
        }
        match self.reject {
            Reject::Never => {}
            Reject::Chi2 { p } => {
                if !(p > 0.0 && p < 1.0) {
                    return Err(CoreError::OutOfRange {
                        name: "chi-square gate probability",
                        value: p,
                        expected: "in (0, 1)",
                    });
                }
            }
            Reject::MaxDistance(d) => {
                if !(d > 0.0 && d.is_finite()) {
                    return Err(CoreError::OutOfRange {
                        name: "maximum distance",
                        value: d,
                        expected: "finite and > 0",
                    });
                }
            }
        }
        Ok(())
    }
}

/// Why a decision is what it is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Status {
    /// Classified.
    Ok,
    /// The predicted class's nearest prototype is beyond the reject threshold.
    Rejected,
    /// The fit's status is not `ok` (the fit status is carried): not classified.
    FitNotOk(FitStatus),
    /// The Mahalanobis distance (metric or χ² gate) needs a covariance and there is none.
    NoCovariance,
    /// `n` or `k` is not a finite number although the fit says `ok`.
    InvalidEstimate,
}

impl Status {
    /// The word written in the `status` column: `ok`, `rejected`, `fit_<fit status>`,
    /// `no_covariance`, `invalid_estimate`.
    pub fn label(&self) -> String {
        match self {
            Status::Ok => "ok".into(),
            Status::Rejected => "rejected".into(),
            Status::FitNotOk(s) => format!("fit_{s}"),
            Status::NoCovariance => "no_covariance".into(),
            Status::InvalidEstimate => "invalid_estimate".into(),
        }
    }
}

/// A prototype and its distance to an estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neighbour {
    /// Index into the classifier's prototypes.
    pub index: usize,
    /// Distance in the classifier's metric.
    pub distance: f64,
}

/// The outcome of classifying one estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    /// Predicted class, or [`UNKNOWN`].
    pub predicted: String,
    /// Class of the winning prototype even when rejected (`None` when nothing was
    /// compared).
    pub nearest_class: Option<String>,
    /// Nearest prototype of `nearest_class`.
    pub nearest: Option<Neighbour>,
    /// Distance to `nearest` (NaN when none).
    pub distance: f64,
    /// Nearest class other than `nearest_class`.
    pub runner_up: Option<String>,
    /// Distance to the runner-up's nearest prototype (NaN when none).
    pub runner_up_distance: f64,
    /// `runner_up_distance − distance` (NaN when either is missing).
    pub margin: f64,
    /// The statistic compared with the reject threshold (Mahalanobis distance for the χ²
    /// gate, the metric's distance for a maximum distance), when a reject option is set.
    pub gate: Option<f64>,
    /// Votes for `nearest_class` among the `k` nearest prototypes.
    pub votes: usize,
    /// Why the decision is what it is.
    pub status: Status,
    /// A sentence explaining a status other than `ok` (empty otherwise).
    pub reason: String,
    /// All prototypes ranked by distance (empty when nothing was compared).
    pub ranked: Vec<Neighbour>,
}

impl Decision {
    fn unclassified(status: Status, reason: String) -> Self {
        Self {
            predicted: UNKNOWN.into(),
            nearest_class: None,
            nearest: None,
            distance: f64::NAN,
            runner_up: None,
            runner_up_distance: f64::NAN,
            margin: f64::NAN,
            gate: None,
            votes: 0,
            status,
            reason,
            ranked: Vec::new(),
        }
    }
}

/// Check a class name: not empty, not [`UNKNOWN`].
pub fn check_class_name(name: &str) -> Result<()> {
    if name.trim().is_empty() {
        return Err(CoreError::InvalidName {
            what: "class",
            name: name.into(),
            reason: "a class name cannot be empty".into(),
        });
    }
    if name.trim().eq_ignore_ascii_case(UNKNOWN) {
        return Err(CoreError::InvalidName {
            what: "class",
            name: name.into(),
            reason: format!("`{UNKNOWN}` is reserved for unclassified estimates"),
        });
    }
    Ok(())
}

/// Nearest-neighbour classifier over a set of prototypes.
#[derive(Debug, Clone)]
pub struct Classifier {
    prototypes: Vec<Prototype>,
    config: ClassifierConfig,
}

impl Classifier {
    /// A classifier; fails when there are no prototypes, a prototype has a non-finite or
    /// negative index or a reserved/empty class name, or the settings are invalid.
    pub fn new(prototypes: Vec<Prototype>, config: ClassifierConfig) -> Result<Self> {
        config.validate()?;
        if prototypes.is_empty() {
            return Err(CoreError::TooFew {
                what: "prototypes",
                needed: 1,
                got: 0,
            });
        }
        for p in &prototypes {
            check_class_name(&p.class)?;
            crate::error::ensure_finite("prototype n", p.n)?;
            crate::error::ensure_range("prototype k", p.k, 0.0, f64::INFINITY, ">= 0")?;
        }
        Ok(Self { prototypes, config })
    }

    /// The prototypes.
    pub fn prototypes(&self) -> &[Prototype] {
        &self.prototypes
    }

    /// The settings.
    pub fn config(&self) -> &ClassifierConfig {
        &self.config
    }

    /// Index and Euclidean distance of the nearest prototype to `(n, k)` — the paper's
    /// rule without allocation, for per-pixel use. `None` when `n` or `k` is not finite.
    #[inline]
    pub fn nearest_euclidean(&self, n: f64, k: f64) -> Option<(usize, f64)> {
        if !(n.is_finite() && k.is_finite()) {
            return None;
        }
        let mut best = (usize::MAX, f64::INFINITY);
        for (i, p) in self.prototypes.iter().enumerate() {
            let (dn, dk) = (n - p.n, k - p.k);
            let d2 = dn * dn + dk * dk;
            if d2 < best.1 {
                best = (i, d2);
            }
        }
        (best.0 != usize::MAX).then(|| (best.0, best.1.sqrt()))
    }

    /// Mahalanobis distance between the estimate and prototype `p`, when a covariance is
    /// available (the estimate's plus the prototype's).
    fn mahalanobis(est: &Estimate, p: &Prototype) -> Option<f64> {
        let cov = match (est.cov, p.cov) {
            (Some(a), Some(b)) => a + b,
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => return None,
        };
        cov.mahalanobis2(est.n - p.n, est.k - p.k).map(f64::sqrt)
    }

    /// Classify one estimate.
    pub fn classify(&self, est: &Estimate) -> Decision {
        if !est.fit_status.is_ok() {
            return Decision::unclassified(
                Status::FitNotOk(est.fit_status),
                format!(
                    "not classified: the fit's status is `{}`, not `ok`",
                    est.fit_status
                ),
            );
        }
        if !(est.n.is_finite() && est.k.is_finite()) {
            return Decision::unclassified(
                Status::InvalidEstimate,
                format!(
                    "not classified: the estimate n = {}, k = {} is not finite",
                    est.n, est.k
                ),
            );
        }
        // Distances to every prototype.
        let mut ranked: Vec<Neighbour> = Vec::with_capacity(self.prototypes.len());
        for (index, p) in self.prototypes.iter().enumerate() {
            let distance = match self.config.metric {
                Metric::Euclidean => (est.n - p.n).hypot(est.k - p.k),
                Metric::Mahalanobis => match Self::mahalanobis(est, p) {
                    Some(d) => d,
                    None => {
                        return Decision::unclassified(
                            Status::NoCovariance,
                            format!(
                                "not classified: the Mahalanobis distance needs a covariance \
                                 and neither the estimate nor prototype `{}` ({}) has a usable one",
                                p.class, p.source
                            ),
                        );
                    }
                },
            };
            ranked.push(Neighbour { index, distance });
        }
        ranked.sort_by(|a, b| {
            a.distance
                .total_cmp(&b.distance)
                .then(a.index.cmp(&b.index))
        });

        // Vote among the k nearest; ties go to the class whose nearest member is closest
        // (classes are visited in order of their nearest member, so the first class to
        // reach the maximum vote wins).
        let kk = self.config.k.min(ranked.len());
        let mut votes: Vec<(&str, usize, f64)> = Vec::new();
        for nb in &ranked[..kk] {
            let class = self.prototypes[nb.index].class.as_str();
            match votes.iter_mut().find(|v| v.0 == class) {
                Some(v) => v.1 += 1,
                None => votes.push((class, 1, nb.distance)),
            }
        }
        let mut winner = votes[0];
        for v in &votes[1..] {
            if v.1 > winner.1 {
                winner = *v;
            }
        }
        let class = winner.0.to_string();
        let nearest = ranked
            .iter()
            .find(|nb| self.prototypes[nb.index].class == class)
            .copied();
        let runner = ranked
            .iter()
            .find(|nb| self.prototypes[nb.index].class != class)
            .copied();
        let distance = nearest.map_or(f64::NAN, |n| n.distance);
        let runner_up_distance = runner.map_or(f64::NAN, |n| n.distance);
        let mut decision = Decision {
            predicted: class.clone(),
            nearest_class: Some(class.clone()),
            nearest,
            distance,
            runner_up: runner.map(|r| self.prototypes[r.index].class.clone()),
            runner_up_distance,
            margin: runner_up_distance - distance,
            gate: None,
            votes: winner.1,
            status: Status::Ok,
            reason: String::new(),
            ranked,
        };

        // Reject option.
        let Some(near) = nearest else {
            return decision;
        };
        match self.config.reject {
            Reject::Never => {}
            Reject::MaxDistance(dmax) => {
                decision.gate = Some(distance);
                if distance > dmax {
                    decision.predicted = UNKNOWN.into();
                    decision.status = Status::Rejected;
                    decision.reason = format!(
                        "rejected: nearest class `{class}` is at distance {distance:.4} > {dmax}"
                    );
                }
            }
            Reject::Chi2 { p } => {
                let proto = &self.prototypes[near.index];
                let dm = match self.config.metric {
                    Metric::Mahalanobis => Some(distance),
                    Metric::Euclidean => Self::mahalanobis(est, proto),
                };
                match dm {
                    None => {
                        decision.predicted = UNKNOWN.into();
                        decision.status = Status::NoCovariance;
                        decision.reason = format!(
                            "not classified: the chi-square gate needs a covariance and neither \
                             the estimate nor prototype `{class}` has a usable one"
                        );
                    }
                    Some(dm) => {
                        decision.gate = Some(dm);
                        let q = chi2_2dof_quantile(p);
                        if dm * dm > q {
                            decision.predicted = UNKNOWN.into();
                            decision.status = Status::Rejected;
                            decision.reason = format!(
                                "rejected: nearest class `{class}` has Mahalanobis distance \
                                 {dm:.3} > {:.3} (chi-square gate, 2 dof, p = {p})",
                                q.sqrt()
                            );
                        }
                    }
                }
            }
        }
        decision
    }
}

/// A labelled estimate for evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Labelled {
    /// Target name.
    pub target: String,
    /// True class.
    pub class: String,
    /// The estimate.
    pub estimate: Estimate,
    /// Where it came from (becomes the prototype's source).
    pub source: String,
}

impl Labelled {
    /// This estimate as a prototype of its class.
    pub fn to_prototype(&self) -> Prototype {
        Prototype {
            class: self.class.clone(),
            n: self.estimate.n,
            k: self.estimate.k,
            cov: self.estimate.cov,
            category: None,
            source: self.source.clone(),
        }
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
) -> Evaluation {
    unrep.sort();
    unrep.dedup();
    let confusion = Confusion::from_pairs(
        items
            .iter()
            .map(|i| (i.class.as_str(), i.decision.predicted.as_str())),
    );
    let accuracy = confusion.accuracy();
    Evaluation {
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
        .filter(|i| i.estimate.fit_status.is_ok())
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
        .filter(|i| !i.estimate.fit_status.is_ok())
        .map(|i| (i.target.clone(), i.estimate.fit_status))
        .collect();
    let mut out = Vec::with_capacity(usable.len());
    let mut unrep = Vec::new();
    for (i, it) in usable.iter().enumerate() {
        let protos: Vec<Prototype> = usable
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, o)| o.to_prototype())
            .collect();
        if !protos.iter().any(|p| p.class == it.class) {
            unrep.push(it.class.clone());
        }
        let clf = Classifier::new(protos, config)?;
        out.push(EvalItem {
            target: it.target.clone(),
            class: it.class.clone(),
            decision: clf.classify(&it.estimate),
        });
    }
    Ok(finish(out, skipped, unrep))
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
        if !it.estimate.fit_status.is_ok() {
            skipped.push((it.target.clone(), it.estimate.fit_status));
            continue;
        }
        if !classifier.prototypes.iter().any(|p| p.class == it.class) {
            unrep.push(it.class.clone());
        }
        out.push(EvalItem {
            target: it.target.clone(),
            class: it.class.clone(),
            decision: classifier.classify(&it.estimate),
        });
    }
    Ok(finish(out, skipped, unrep))
}

/// Wolff's two classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WolffClass {
    /// Small Fresnel ratio at every measured angle.
    Metal,
    /// Large Fresnel ratio near Brewster's angle.
    Dielectric,
    /// No measurement in the angle window.
    Unknown,
}

impl WolffClass {
    /// `metal`, `dielectric` or `unknown`.
    pub fn name(self) -> &'static str {
        match self {
            WolffClass::Metal => "metal",
            WolffClass::Dielectric => "dielectric",
            WolffClass::Unknown => UNKNOWN,
        }
    }
}

/// Settings of Wolff's rule (angles in radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WolffConfig {
    /// Fresnel-ratio threshold: `FR_max > threshold` → dielectric.
    pub threshold: f64,
    /// Smallest specular angle β used.
    pub beta_min: f64,
    /// Largest specular angle β used.
    pub beta_max: f64,
}

impl Default for WolffConfig {
    /// Threshold 6, β window 40°–70°.
    ///
    /// Why: over β ∈ [40°, 70°] the Fresnel ratio of every metal of the built-in library
    /// stays below 4.8 (tungsten reaches 4.76 at 70°, iron 3.9, aluminum 1.26, copper
    /// 1.13), while every dielectric of the library (n from 1.31 to 2.58) has its Brewster
    /// angle (52°–69°) inside the window, where its ratio exceeds 20 for measurements
    /// within a few degrees of it. 6 (`P = 5/7 ≈ 0.714`) sits between the two with room
    /// for depolarization, which lowers a dielectric's ratio.
    fn default() -> Self {
        Self {
            threshold: 6.0,
            beta_min: 40f64.to_radians(),
            beta_max: 70f64.to_radians(),
        }
    }
}

/// One DoLP measurement for Wolff's rule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WolffObservation {
    /// Specular (half-) angle β, radians (eq. 5).
    pub beta: f64,
    /// Measured degree of linear polarization, in `[0, 1]`.
    pub dolp: f64,
}

/// Wolff's decision for one target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WolffDecision {
    /// Metal, dielectric or unknown.
    pub class: WolffClass,
    /// Largest Fresnel ratio over the measurements in the window (NaN when none;
    /// infinite for `P = 1`).
    pub fr_max: f64,
    /// β (radians) of that measurement (NaN when none).
    pub beta_at_max: f64,
    /// Measurements in the window.
    pub used: usize,
}

/// The polarization Fresnel ratio `FR = Rs/Rp = (1 + P)/(1 − P)` from the degree of
/// polarization of unpolarized light specularly reflected (`P = (Rs − Rp)/(Rs + Rp)`).
/// Infinite for `P = 1`.
#[inline]
pub fn fresnel_ratio(dolp: f64) -> f64 {
    (1.0 + dolp) / (1.0 - dolp)
}

/// Wolff's threshold rule: among the measurements whose β lies in
/// `[beta_min, beta_max]`, take the largest Fresnel ratio `FR_max`; the target is a
/// dielectric when `FR_max > threshold`, a metal otherwise, and unknown when no
/// measurement falls in the window.
///
/// Fails when a DoLP is outside `[0, 1]` or an angle is not finite, or the settings are
/// invalid (threshold ≤ 1, empty window).
pub fn wolff_classify(obs: &[WolffObservation], cfg: &WolffConfig) -> Result<WolffDecision> {
    if !(cfg.threshold > 1.0 && cfg.threshold.is_finite()) {
        return Err(CoreError::OutOfRange {
            name: "Fresnel-ratio threshold",
            value: cfg.threshold,
            expected: "finite and > 1",
        });
    }
    if !(cfg.beta_min <= cfg.beta_max && cfg.beta_min.is_finite() && cfg.beta_max.is_finite()) {
        return Err(CoreError::OutOfRange {
            name: "Wolff beta window minimum (radians)",
            value: cfg.beta_min,
            expected: "<= the window maximum",
        });
    }
    let mut fr_max = f64::NAN;
    let mut beta_at_max = f64::NAN;
    let mut used = 0;
    for o in obs {
        crate::error::ensure_finite("beta", o.beta)?;
        crate::error::ensure_range("dolp", o.dolp, 0.0, 1.0, "in [0, 1]")?;
        if o.beta < cfg.beta_min || o.beta > cfg.beta_max {
            continue;
        }
        used += 1;
        let fr = fresnel_ratio(o.dolp);
        if fr_max.is_nan() || fr > fr_max {
            fr_max = fr;
            beta_at_max = o.beta;
        }
    }
    let class = if used == 0 {
        WolffClass::Unknown
    } else if fr_max > cfg.threshold {
        WolffClass::Dielectric
    } else {
        WolffClass::Metal
    };
    Ok(WolffDecision {
        class,
        fr_max,
        beta_at_max,
        used,
    })
}

/// Group the classes of a set of prototypes with their categories (first category seen
/// per class), e.g. to report "classified as a metal".
pub fn class_categories(prototypes: &[Prototype]) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    for p in prototypes {
        if let Some(c) = &p.category {
            m.entry(p.class.clone()).or_insert_with(|| c.clone());
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn proto(class: &str, n: f64, k: f64) -> Prototype {
        Prototype {
            class: class.into(),
            n,
            k,
            cov: None,
            category: None,
            source: "test".into(),
        }
    }

    /// Paper, Table 1 (estimated training values) and Table 2 (test estimates).
    fn paper_training() -> Vec<Prototype> {
        vec![
            proto("green paint", 1.47, 0.47),
            proto("aluminum", 1.64, 4.56),
            proto("copper", 0.54, 3.19),
        ]
    }

    #[test]
    fn paper_table2_is_aluminum() {
        let clf = Classifier::new(paper_training(), ClassifierConfig::default()).unwrap();
        for (n, k) in [(1.37, 3.97), (1.60, 4.34)] {
            let d = clf.classify(&Estimate::point(n, k));
            assert_eq!(d.predicted, "aluminum", "{n}+{k}i");
            assert_eq!(d.status, Status::Ok);
            let expect = (n - 1.64f64).hypot(k - 4.56);
            assert!((d.distance - expect).abs() < 1e-12);
            assert_eq!(d.runner_up.as_deref(), Some("copper"));
            let ru = (n - 0.54f64).hypot(k - 3.19);
            assert!((d.runner_up_distance - ru).abs() < 1e-12);
            assert!((d.margin - (ru - expect)).abs() < 1e-12);
        }
    }

    #[test]
    fn knn_majority_and_tie_by_distance() {
        let protos = vec![
            proto("a", 0.0, 0.0),
            proto("b", 1.0, 0.0),
            proto("b", 1.1, 0.0),
            proto("a", 5.0, 0.0),
        ];
        let cfg = ClassifierConfig {
            k: 3,
            ..Default::default()
        };
        let clf = Classifier::new(protos.clone(), cfg).unwrap();
        // Nearest is `a` at 0.4 but `b` has two of the three votes.
        let d = clf.classify(&Estimate::point(0.4, 0.0));
        assert_eq!(d.predicted, "b");
        assert_eq!(d.votes, 2);
        assert!((d.distance - 0.6).abs() < 1e-12);
        assert_eq!(d.runner_up.as_deref(), Some("a"));
        // k = 2: one vote each; the tie goes to the nearer class.
        let clf = Classifier::new(protos, ClassifierConfig { k: 2, ..cfg }).unwrap();
        let d = clf.classify(&Estimate::point(0.4, 0.0));
        assert_eq!(d.predicted, "a");
        let d = clf.classify(&Estimate::point(0.6, 0.0));
        assert_eq!(d.predicted, "b");
    }

    #[test]
    fn mahalanobis_uses_both_covariances() {
        let cov = Cov2::from_se(0.1, 0.2, 0.5).unwrap();
        let mut p = proto("x", 1.0, 2.0);
        p.cov = Some(Cov2::from_se(0.1, 0.1, 0.0).unwrap());
        let est = Estimate {
            n: 1.2,
            k: 2.3,
            cov: Some(cov),
            fit_status: FitStatus::Ok,
        };
        let clf = Classifier::new(
            vec![p],
            ClassifierConfig {
                metric: Metric::Mahalanobis,
                ..Default::default()
            },
        )
        .unwrap();
        let d = clf.classify(&est);
        // Σ = [[0.02, 0.01], [0.01, 0.05]], Δ = (0.2, 0.3)
        let (a, b, c) = (0.02, 0.01, 0.05);
        let det: f64 = a * c - b * b;
        let q = (c * 0.04 - 2.0 * b * 0.06 + a * 0.09) / det;
        assert!((d.distance - q.sqrt()).abs() < 1e-12, "{}", d.distance);
        // No covariance anywhere: not classified.
        let clf2 = Classifier::new(
            vec![proto("x", 1.0, 2.0)],
            ClassifierConfig {
                metric: Metric::Mahalanobis,
                ..Default::default()
            },
        )
        .unwrap();
        let d = clf2.classify(&Estimate::point(1.0, 2.0));
        assert_eq!(d.predicted, UNKNOWN);
        assert_eq!(d.status, Status::NoCovariance);
    }

    #[test]
    fn chi2_gate_rejects_far_estimates() {
        assert!((chi2_2dof_quantile(0.99) - 9.210340371976182).abs() < 1e-12);
        let cfg = ClassifierConfig {
            reject: Reject::Chi2 { p: 0.99 },
            ..Default::default()
        };
        let clf = Classifier::new(paper_training(), cfg).unwrap();
        let mut est = Estimate {
            n: 1.60,
            k: 4.34,
            cov: Cov2::from_se(0.05, 0.05, 0.0),
            fit_status: FitStatus::Ok,
        };
        // d_M = |(0.04, 0.22)| / 0.05 = 4.47 > 3.035: rejected.
        let d = clf.classify(&est);
        assert_eq!(d.predicted, UNKNOWN);
        assert_eq!(d.status, Status::Rejected);
        assert_eq!(d.nearest_class.as_deref(), Some("aluminum"));
        assert!((d.gate.unwrap() - 0.04f64.hypot(0.22) / 0.05).abs() < 1e-9);
        // Larger uncertainty: accepted.
        est.cov = Cov2::from_se(0.2, 0.2, 0.0);
        let d = clf.classify(&est);
        assert_eq!(d.predicted, "aluminum");
        assert_eq!(d.status, Status::Ok);
        // Euclidean threshold.
        let clf = Classifier::new(
            paper_training(),
            ClassifierConfig {
                reject: Reject::MaxDistance(0.2),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(
            clf.classify(&Estimate::point(1.60, 4.34)).predicted,
            UNKNOWN
        );
        assert_eq!(
            clf.classify(&Estimate::point(1.60, 4.50)).predicted,
            "aluminum"
        );
    }

    #[test]
    fn non_ok_fits_are_never_classified() {
        let clf = Classifier::new(paper_training(), ClassifierConfig::default()).unwrap();
        let mut est = Estimate::point(1.64, 4.56);
        est.fit_status = FitStatus::NotConverged;
        let d = clf.classify(&est);
        assert_eq!(d.predicted, UNKNOWN);
        assert_eq!(d.status.label(), "fit_not_converged");
        assert!(d.ranked.is_empty());
        let d = clf.classify(&Estimate::point(f64::NAN, 1.0));
        assert_eq!(d.status, Status::InvalidEstimate);
    }

    #[test]
    fn reserved_class_names_are_refused() {
        let e = Classifier::new(
            vec![proto("Unknown", 1.0, 1.0)],
            ClassifierConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("Unknown") && e.contains("reserved"), "{e}");
    }

    #[test]
    fn loo_confusion_and_accuracy() {
        let mk = |t: &str, c: &str, n: f64, k: f64| Labelled {
            target: t.into(),
            class: c.into(),
            estimate: Estimate::point(n, k),
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
                },
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
    }

    #[test]
    fn wolff_fresnel_ratio_rule() {
        use crate::dop::dop;
        let cfg = WolffConfig::default();
        let betas: Vec<f64> = (0..=9)
            .map(|i| (47.5 + 2.5 * i as f64).to_radians())
            .collect();
        let obs = |n: f64, k: f64| -> Vec<WolffObservation> {
            betas
                .iter()
                .map(|&b| WolffObservation {
                    beta: b,
                    dolp: dop(n, k, b),
                })
                .collect()
        };
        // Paper's estimates: aluminum, copper are metals, green paint a dielectric.
        assert_eq!(
            wolff_classify(&obs(1.64, 4.56), &cfg).unwrap().class,
            WolffClass::Metal
        );
        assert_eq!(
            wolff_classify(&obs(0.54, 3.19), &cfg).unwrap().class,
            WolffClass::Metal
        );
        let g = wolff_classify(&obs(1.47, 0.47), &cfg).unwrap();
        assert_eq!(g.class, WolffClass::Dielectric);
        assert!(g.fr_max > 15.0, "{}", g.fr_max);
        // FR = Rs/Rp.
        assert!((fresnel_ratio(0.5) - 3.0).abs() < 1e-15);
        // Nothing in the window.
        let none = wolff_classify(
            &[WolffObservation {
                beta: 0.1,
                dolp: 0.1,
            }],
            &cfg,
        )
        .unwrap();
        assert_eq!(none.class, WolffClass::Unknown);
        assert!(
            wolff_classify(
                &[WolffObservation {
                    beta: 1.0,
                    dolp: 1.5
                }],
                &cfg
            )
            .is_err()
        );
    }
}
