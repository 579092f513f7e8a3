//! Settings of a [`Classifier`](super::Classifier): the distance [`Metric`], the number of
//! voting neighbours and the [`Reject`] option with its χ² gate.
//!
//! ```text
//! d_E = √((n̂ − n_p)² + (k̂ − k_p)²)                    (paper section 6)
//! d_M² = Δᵀ (Σ_est + Σ_proto)⁻¹ Δ
//! reject when d_M² > χ²₂(p) = −2 ln(1 − p)           (χ²₂ CDF: 1 − exp(−x/2))
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
