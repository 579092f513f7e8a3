//! The nearest-neighbour classifier: the paper's rule (`k = 1`, Euclidean distance), k-NN
//! voting, the Mahalanobis distance and the reject option.
//!
//! ```text
//! d_E = √((n̂ − n_p)² + (k̂ − k_p)²)
//! d_M = √(Δᵀ (Σ_est + Σ_proto)⁻¹ Δ),   Δ = (n̂ − n_p, k̂ − k_p)
//! ```
//!
//! Votes among the `k` nearest prototypes; a tie goes to the tied class whose nearest member
//! is closest. The χ² gate rejects when `d_M² > −2 ln(1 − p)` (2 degrees of freedom).
//!
//! The consistent set: every class whose nearest prototype (by the set distance, the
//! Mahalanobis distance in `(n, k)`, or in `(n, u = k²)` when the estimate's `k_se` is
//! one-sided or either point is within `NEAR_ZERO_SIGMAS` k_se of `k = 0`) has
//! `d_M² ≤ −2 ln(1 − confidence)`, ranked by distance, ties in the
//! prototypes' order.
//!
//! # Reference
//! Thilak, Creusere & Voelz, ICIP 2007, section 6 (Tables 1 and 2 in the tests).

use super::{
    AMBIGUOUS, Candidate, ClassifierConfig, Decision, Estimate, Metric, Neighbour, Prototype,
    Reject, Rule, Status, UNKNOWN, check_class_name, chi2_2dof_quantile,
};
use crate::error::{CoreError, Result};

/// The consistency test is done in `(n, u = k²)` when the estimate or the prototype is
/// within this many of the estimate's `k_se` of `k = 0` (or the `k_se` is one-sided):
/// there the DoLP is linear in `u`, not in `k` (paper eq. 14–15).
pub const NEAR_ZERO_SIGMAS: f64 = 3.0;

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

    /// Distance of the consistency test between the estimate and prototype `p`: the
    /// Mahalanobis distance with `Σ_est + Σ_proto` in `(n, k)`, or in `(n, u = k²)` (both
    /// covariances through [`Cov2::to_nu`](super::Cov2::to_nu),
    /// `Δ = (n̂ − n_p, k̂² − k_p²)`) near `k = 0`: when the estimate's `k_se` is one-sided,
    /// or the estimate or the prototype is within [`NEAR_ZERO_SIGMAS`]` · k_se` of `k = 0`.
    /// The choice does not depend on the confidence, so a higher confidence never shrinks
    /// the set. `None` without a usable covariance.
    pub fn set_distance(est: &Estimate, p: &Prototype) -> Option<f64> {
        let near_zero = est.cov.is_some_and(|c| {
            let k_se = c.kk.sqrt();
            c.k_is_one_sided(est.k)
                || est.k <= NEAR_ZERO_SIGMAS * k_se
                || p.k <= NEAR_ZERO_SIGMAS * k_se
        });
        if !near_zero {
            return Self::mahalanobis(est, p);
        }
        let ce = est.cov.map(|c| c.to_nu(est.k));
        let cp = p.cov.map(|c| c.to_nu(p.k));
        let cov = match (ce, cp) {
            (Some(a), Some(b)) => a + b,
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => return None,
        };
        cov.mahalanobis2(est.n - p.n, est.k * est.k - p.k * p.k)
            .map(f64::sqrt)
    }

    /// Set distances to every prototype, ranked (ties in the prototypes' order); `Err`
    /// with the first prototype lacking a usable covariance.
    fn set_ranked(&self, est: &Estimate) -> std::result::Result<Vec<Neighbour>, usize> {
        let mut ranked = Vec::with_capacity(self.prototypes.len());
        for (index, p) in self.prototypes.iter().enumerate() {
            let distance = Self::set_distance(est, p).ok_or(index)?;
            ranked.push(Neighbour { index, distance });
        }
        ranked.sort_by(|a, b| {
            a.distance
                .total_cmp(&b.distance)
                .then(a.index.cmp(&b.index))
        });
        Ok(ranked)
    }

    /// The consistent classes among `ranked` (set distances): each class once, at its
    /// nearest prototype, kept when `d² ≤ −2 ln(1 − confidence)`; and their common
    /// category.
    fn candidates(&self, ranked: &[Neighbour]) -> (Vec<Candidate>, Option<String>) {
        let q = chi2_2dof_quantile(self.config.confidence);
        let mut out: Vec<Candidate> = Vec::new();
        for nb in ranked {
            if nb.distance * nb.distance > q {
                break;
            }
            let p = &self.prototypes[nb.index];
            if out.iter().any(|c| c.class == p.class) {
                continue;
            }
            let category = self
                .prototypes
                .iter()
                .filter(|o| o.class == p.class)
                .find_map(|o| o.category.clone());
            out.push(Candidate {
                class: p.class.clone(),
                index: nb.index,
                distance: nb.distance,
                category,
            });
        }
        let common = match out.first().and_then(|c| c.category.clone()) {
            Some(cat) if out.iter().all(|c| c.category.as_ref() == Some(&cat)) => Some(cat),
            _ => None,
        };
        (out, common)
    }

    /// Classify one estimate with the configured [`Rule`].
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
        match self.config.rule {
            Rule::Nearest => {
                let mut d = self.classify_nearest(est);
                if d.status != Status::NoCovariance
                    && let Ok(ranked) = self.set_ranked(est)
                {
                    let (c, cat) = self.candidates(&ranked);
                    d.candidates = c;
                    d.set_category = cat;
                    d.set_tested = true;
                }
                d
            }
            Rule::Set => self.classify_set(est),
        }
    }

    /// The set rule (estimate already checked).
    fn classify_set(&self, est: &Estimate) -> Decision {
        let ranked = match self.set_ranked(est) {
            Ok(r) => r,
            Err(i) => {
                let p = &self.prototypes[i];
                return Decision::unclassified(
                    Status::NoCovariance,
                    format!(
                        "not classified: the consistency test needs a covariance and neither \
                         the estimate nor prototype `{}` ({}) has a usable one",
                        p.class, p.source
                    ),
                );
            }
        };
        let (candidates, set_category) = self.candidates(&ranked);
        // ok: there is at least one prototype (checked in `new`), so `ranked` is not empty.
        let nearest = ranked[0];
        let class = self.prototypes[nearest.index].class.clone();
        let runner = ranked
            .iter()
            .find(|nb| self.prototypes[nb.index].class != class)
            .copied();
        let runner_up_distance = runner.map_or(f64::NAN, |n| n.distance);
        let pct = self.config.confidence * 100.0;
        let (predicted, status, reason) = match candidates.len() {
            0 => (
                UNKNOWN.to_string(),
                Status::Rejected,
                format!(
                    "rejected: no material is consistent at {pct}% confidence (Mahalanobis \
                     distance <= {:.3}); nearest `{class}` at {:.3}",
                    chi2_2dof_quantile(self.config.confidence).sqrt(),
                    nearest.distance
                ),
            ),
            1 => (class.clone(), Status::Ok, String::new()),
            n => (
                AMBIGUOUS.to_string(),
                Status::Ambiguous,
                format!(
                    "ambiguous: {n} materials are consistent at {pct}% confidence: {}",
                    candidates
                        .iter()
                        .map(|c| format!("{} ({:.3})", c.class, c.distance))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ),
        };
        Decision {
            predicted,
            nearest_class: Some(class),
            nearest: Some(nearest),
            distance: nearest.distance,
            runner_up: runner.map(|r| self.prototypes[r.index].class.clone()),
            runner_up_distance,
            margin: runner_up_distance - nearest.distance,
            gate: Some(nearest.distance),
            votes: 1,
            status,
            reason,
            ranked,
            candidates,
            set_tested: true,
            set_category,
        }
    }

    /// The paper's nearest-neighbour rule with k-NN votes and the reject option
    /// (estimate already checked).
    fn classify_nearest(&self, est: &Estimate) -> Decision {
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
            candidates: Vec::new(),
            set_tested: false,
            set_category: None,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::Cov2;
    use crate::status::FitStatus;

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
}
