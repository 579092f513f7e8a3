//! The outcome of classifying one estimate: the [`Decision`] with its [`Status`], the
//! runner-up, the margin `runner_up_distance − distance` and every prototype ranked by
//! distance.

use super::UNKNOWN;
use crate::status::FitStatus;

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
    pub(super) fn unclassified(status: Status, reason: String) -> Self {
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
