//! The outcome of classifying one estimate: the [`Decision`] with its [`Status`], the
//! runner-up, the margin `runner_up_distance − distance` and every prototype ranked by
//! distance, and the consistent set: the [`Candidate`]s within the χ²₂ quantile of the
//! confidence, ranked, with their common category.

use super::bands::MultiPrototype;
use super::{AMBIGUOUS, UNKNOWN};
use crate::status::FitStatus;

/// Why a decision is what it is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Status {
    /// Classified.
    Ok,
    /// The predicted class's nearest prototype is beyond the reject threshold, or (set
    /// rule) no material is consistent with the estimate.
    Rejected,
    /// Set rule: several materials are consistent with the estimate.
    Ambiguous,
    /// The fit's status is not `ok` (the fit status is carried): not classified.
    FitNotOk(FitStatus),
    /// The Mahalanobis distance (metric or χ² gate) needs a covariance and there is none.
    NoCovariance,
    /// `n` or `k` is not a finite number although the fit says `ok`.
    InvalidEstimate,
    /// No prototype has a band (wavelength) of the estimate.
    NoCommonBand,
}

impl Status {
    /// The word written in the `status` column: `ok`, `rejected`, `ambiguous`,
    /// `fit_<fit status>`,
    /// `no_covariance`, `invalid_estimate`, `no_common_band`.
    pub fn label(&self) -> String {
        match self {
            Status::Ok => "ok".into(),
            Status::Rejected => "rejected".into(),
            Status::Ambiguous => "ambiguous".into(),
            Status::FitNotOk(s) => format!("fit_{s}"),
            Status::NoCovariance => "no_covariance".into(),
            Status::InvalidEstimate => "invalid_estimate".into(),
            Status::NoCommonBand => "no_common_band".into(),
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

/// A material consistent with an estimate: its class, its nearest prototype and the
/// Mahalanobis distance to it (in `(n, u = k²)` near `k = 0`, see [`Cov2`](super::Cov2)),
/// or, tested against the measured rows ([`hypothesis`](super::hypothesis)), its `χ²`,
/// probability and nuisances.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Class (material) name.
    pub class: String,
    /// Index of the class's nearest prototype in the classifier's prototypes.
    pub index: usize,
    /// Mahalanobis distance to that prototype.
    pub distance: f64,
    /// The class's category, when known.
    pub category: Option<String>,
    /// The material's probability given the rows (hypothesis tests against the measured
    /// DoLP, [`classify_rows`](super::hypothesis::classify_rows)); `None` for the
    /// `(n, k)` set rule.
    pub probability: Option<f64>,
    /// What the hypothesis test found (`χ²`, p-value, the nuisances it needed); `None`
    /// for the `(n, k)` set rule. [`Candidate::distance`] is then its `χ²`.
    pub fit: Option<NuisanceFit>,
}

/// What one hypothesis test found: the statistic and the nuisances it needed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NuisanceFit {
    /// `χ²_min` over the nuisance box.
    pub chi2: f64,
    /// The effective degrees of freedom: the mean of `χ²_min` under the hypothesis,
    /// `T − m + E[D]` (the [`hypothesis`](super::hypothesis) module documentation; `T − m` when every
    /// nuisance is interior).
    pub dof: f64,
    /// `P(χ²_min ≥ observed)` under the hypothesis (the [`hypothesis`](super::hypothesis) module documentation).
    pub p_value: f64,
    /// Whether `p_value ≥ 1 − p`.
    pub consistent: bool,
    /// The layer thickness at the minimum, nm (0 without a layer).
    pub thickness_nm: f64,
    /// The polarimeter scale at the minimum.
    pub scale: f64,
    /// The common angle offset at the minimum, radians.
    pub offset: f64,
    /// `ln Z`: the log of the likelihood averaged over the nuisance box (up to a
    /// constant common to every hypothesis of the same rows).
    pub log_evidence: f64,
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
    /// The materials consistent with the estimate at the configured confidence, best
    /// first (ties in the prototypes' order); empty when none is, or when no covariance
    /// allows the test (see [`Decision::set_tested`]). Computed under both rules.
    pub candidates: Vec<Candidate>,
    /// Whether the consistent set was computed (a covariance was available).
    pub set_tested: bool,
    /// The common category of [`Decision::candidates`] when they all have the same one.
    pub set_category: Option<String>,
    /// The wavelengths (nm; `None`: not given) of the estimate's bands compared with the
    /// nearest prototype, in the estimate's band order (empty when nothing was compared).
    /// Fewer than the estimate's bands when a band's fit was not `ok` or the prototype
    /// lacks it.
    pub bands_used: Vec<Option<f64>>,
}

impl Decision {
    /// The candidates' classes joined with `;` (the `candidates` column).
    pub fn candidates_text(&self) -> String {
        self.candidates
            .iter()
            .map(|c| c.class.as_str())
            .collect::<Vec<_>>()
            .join(";")
    }

    /// Against a catalogue (an open world): a single answer that is a transparent material
    /// (every prototype of its class transparent at `wavelengths`,
    /// [`MultiPrototype::transparent_at`]) becomes [`AMBIGUOUS`], with it the only
    /// candidate and its category kept, because DoLP tells a transparent surface by its
    /// index alone and a material of the same index outside the library fits as well
    /// (`hypothesis`, "Transparent materials and the open world"). Other decisions are
    /// left as they are. `confidence`: the test's, for the reason.
    pub fn open_world(&mut self, protos: &[MultiPrototype], wavelengths: &[f64], confidence: f64) {
        if self.status != Status::Ok || self.candidates.len() != 1 {
            return;
        }
        let class = &self.candidates[0].class;
        let own: Vec<&MultiPrototype> = protos.iter().filter(|p| &p.class == class).collect();
        if own.is_empty() || !own.iter().all(|p| p.transparent_at(wavelengths)) {
            return;
        }
        let index: Vec<String> = own
            .iter()
            .flat_map(|p| p.bands_at(wavelengths))
            .map(|b| match b.wavelength_nm {
                Some(w) => format!("n {:.3} at {w} nm", b.n),
                None => format!("n {:.3}", b.n),
            })
            .collect();
        self.reason = format!(
            "a transparent material of {class}'s index ({}) explains the data at {}% \
             confidence; DoLP tells a transparent surface by its index alone, and a material \
             of the same index outside the library explains them as well",
            index.join(", "),
            confidence * 100.0
        );
        self.predicted = AMBIGUOUS.to_string();
        self.status = Status::Ambiguous;
    }
}

impl Decision {
    /// A decision that classifies nothing: `unknown` with `status` and `reason`, nothing
    /// compared.
    pub fn unclassified(status: Status, reason: String) -> Self {
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
            candidates: Vec::new(),
            set_tested: false,
            set_category: None,
            bands_used: Vec::new(),
        }
    }

    /// [`Decision::bands_used`] as text: wavelengths joined with `;` (e.g. `450;550;650`),
    /// empty when no band has a wavelength.
    pub fn bands_used_text(&self) -> String {
        if self.bands_used.iter().all(Option::is_none) {
            return String::new();
        }
        self.bands_used
            .iter()
            .map(|w| w.map_or("?".to_string(), |w| format!("{w}")))
            .collect::<Vec<_>>()
            .join(";")
    }
}
