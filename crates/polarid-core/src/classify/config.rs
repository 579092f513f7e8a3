//! Settings of a [`Classifier`](super::Classifier): the decision [`Rule`] (the paper's
//! nearest neighbour or the consistent set), the set's confidence, the distance [`Metric`],
//! the number of voting neighbours and the [`Reject`] option with its χ² gate.
//!
//! ```text
//! d_E = √((n̂ − n_p)² + (k̂ − k_p)²)                    (paper section 6)
//! d_M² = Δᵀ (Σ_est + Σ_proto)⁻¹ Δ
//! reject when d_M² > χ²₂(p) = −2 ln(1 − p)           (χ²₂ CDF: 1 − exp(−x/2))
//! consistent (set rule) when d_M² ≤ χ²₂(confidence)
//! ```
//!
//! # Reference
//! Thilak, Creusere & Voelz, ICIP 2007, section 6 (nearest neighbour with the Euclidean
//! distance).

use crate::error::{CoreError, Result};

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

/// How a [`Decision`](super::Decision)'s answer is chosen.
///
/// The consistent set (the materials whose Mahalanobis distance is within the χ²₂
/// quantile of the confidence) is computed under both rules whenever a covariance is
/// available; the rule decides only what `predicted` and `status` say.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Rule {
    /// The paper's rule: the nearest prototype's class (with the metric, `k` votes and the
    /// reject option). The default of the library type, so that a bare [`ClassifierConfig`]
    /// is the paper's classifier; the command line and Python default to [`Rule::Set`].
    #[default]
    Nearest,
    /// Answers as sets: one consistent material → that material (`ok`); several →
    /// [`AMBIGUOUS`](super::AMBIGUOUS) (`ambiguous`); none → [`UNKNOWN`](super::UNKNOWN)
    /// (`rejected`). Always uses the Mahalanobis distance, `k = 1` and no reject option.
    Set,
}

impl Rule {
    /// Name used in files and on the command line: `nearest` or `set`.
    pub fn name(self) -> &'static str {
        match self {
            Rule::Nearest => "nearest",
            Rule::Set => "set",
        }
    }
}

/// Where a trained model's prototypes were measured, relative to the estimates compared
/// with them: which covariances the set distance adds (`docs/CLASSIFY.md`, "Trained
/// models: the same bench").
///
/// ```text
/// Same:   d_M² = Δᵀ (Σ_est,noise + Σ_proto,sample)⁻¹ Δ
/// Other:  d_M² = Δᵀ (Σ_est,total + Σ_proto,total)⁻¹ Δ
/// ```
///
/// `Σ_total` is noise plus every systematic error of the fit's error model (angles,
/// DoLP floor, extinction, a surface layer of unknown thickness); `Σ_sample` is noise plus
/// the surface layer's variation from plate to plate of one material. On one bench a
/// training plate and a test plate share the camera (its extinction, its calibration),
/// the rig's lamp positions and the camera's pose: those errors move both estimates
/// alike and cancel in `Δ`, so adding them on both sides widens every answer for
/// nothing. What differs between the two plates is their noise and their surface layer;
/// the layer's variation is the prototype's, evaluated at its material (the hypothesis
/// tested is "the test plate is this prototype's material").
///
/// Library materials (literature values) are always compared with the estimate's total
/// covariance: a library has no bench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Bench {
    /// The model was trained on the bench the estimates come from (the default).
    #[default]
    Same,
    /// The model was trained on another bench: the systematic errors on both sides.
    Other,
}

impl Bench {
    /// Name used in files and on the command line: `same` or `other`.
    pub fn name(self) -> &'static str {
        match self {
            Bench::Same => "same",
            Bench::Other => "other",
        }
    }
}

/// Default confidence of the consistent set (95%).
pub const DEFAULT_CONFIDENCE: f64 = 0.95;

/// When to answer [`UNKNOWN`](super::UNKNOWN) instead of the nearest class.
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

/// Settings of a [`Classifier`](super::Classifier).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClassifierConfig {
    /// Distance metric.
    pub metric: Metric,
    /// Number of neighbours that vote (1 = the paper's nearest neighbour).
    pub k: usize,
    /// Reject option (nearest rule only).
    pub reject: Reject,
    /// Decision rule.
    pub rule: Rule,
    /// Confidence of the consistent set, in `(0, 1)`: a material is consistent when
    /// `d_M² ≤ −2 ln(1 − confidence)`.
    pub confidence: f64,
}

impl Default for ClassifierConfig {
    fn default() -> Self {
        Self {
            metric: Metric::Euclidean,
            k: 1,
            reject: Reject::Never,
            rule: Rule::Nearest,
            confidence: DEFAULT_CONFIDENCE,
        }
    }
}

impl ClassifierConfig {
    /// The set rule at `confidence` (Mahalanobis distance, `k = 1`, no reject option).
    pub fn set(confidence: f64) -> Self {
        Self {
            metric: Metric::Mahalanobis,
            rule: Rule::Set,
            confidence,
            ..Self::default()
        }
    }

    /// The metric distances are reported in: [`Metric::Mahalanobis`] under the set rule,
    /// else [`ClassifierConfig::metric`].
    pub fn distance_metric(&self) -> Metric {
        match self.rule {
            Rule::Set => Metric::Mahalanobis,
            Rule::Nearest => self.metric,
        }
    }

    /// Check the settings: `k >= 1`, the confidence in `(0, 1)`, a reject probability in
    /// `(0, 1)` or a positive maximum distance; the set rule with `k = 1` and no reject
    /// option.
    pub fn validate(&self) -> Result<()> {
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return Err(CoreError::OutOfRange {
                name: "confidence",
                value: self.confidence,
                expected: "in (0, 1)",
            });
        }
        if self.rule == Rule::Set {
            if self.k != 1 {
                return Err(CoreError::OutOfRange {
                    name: "k (neighbours) with the set rule",
                    value: self.k as f64,
                    expected: "1 (the set rule does not vote)",
                });
            }
            match self.reject {
                Reject::Never => {}
                Reject::Chi2 { p: v } | Reject::MaxDistance(v) => {
                    return Err(CoreError::OutOfRange {
                        name: "reject option with the set rule",
                        value: v,
                        expected: "none (the set rule rejects by its confidence)",
                    });
                }
            }
        }
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
