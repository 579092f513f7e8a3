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
//! - **Answers as sets** ([`Rule::Set`], see `docs/CLASSIFY.md`): every material whose
//!   Mahalanobis distance (estimate's plus prototype's covariance; in `(n, u = k²)` when the
//!   fit's `k_se` is one-sided near `k = 0`, see [`Cov2::to_nu`]) satisfies
//!   `d_M² ≤ χ²₂(confidence) = −2 ln(1 − confidence)` is a [`Candidate`]: one → that
//!   material, several → [`AMBIGUOUS`] with their common category, none → [`UNKNOWN`].
//!   The set is computed under both rules when a covariance is available.
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
//! # Several bands
//!
//! A target measured in several spectral bands (a colour polarization camera) is a
//! [`MultiEstimate`]; prototypes with several bands are [`MultiPrototype`]s
//! ([`Classifier::multi`], [`Classifier::classify_multi`]). Distances add in squares over
//! the bands an estimate and a prototype have in common (block-diagonal covariance), and
//! the χ² tests use `2 × bands` degrees of freedom ([`chi2_quantile`]); see [`bands`].
//!
//! # Hypothesis tests against the measured rows
//!
//! [`hypothesis`] tests each material, as it is found (bulk under its native layer, a
//! polarimeter that only loses DoLP, a bounded common angle offset), directly against a
//! target's DoLP rows: a `χ²` test per material and a probability per material
//! ([`classify_rows`]).
//!
//! # Leave-one-out evaluation
//!
//! [`leave_one_out`] classifies each labelled estimate against all the others and returns
//! a [`Confusion`] matrix and the accuracy.
//!
//! # Layout
//!
//! `cov` ([`Cov2`]), `points` ([`Prototype`], [`Estimate`]), `config` ([`Metric`],
//! [`Reject`], [`ClassifierConfig`]), `decision` ([`Decision`], [`Status`]), `classifier`
//! ([`Classifier`]: distances, k-NN vote, reject gate), `evaluate` (leave-one-out,
//! confusion matrix), `wolff` (Wolff's baseline).
//!
//! # Reference
//!
//! - Thilak, Creusere & Voelz, "Material classification using passive polarimetric
//!   imagery", ICIP 2007: section 6 (nearest neighbour), Tables 1 and 2.
//! - L. B. Wolff, "Polarization-based material classification from specular reflection",
//!   IEEE PAMI 12(11), 1990 (the paper's ref. \[1\]).

pub mod bands;
mod classifier;
mod config;
mod cov;
mod decision;
mod evaluate;
pub mod hypothesis;
pub mod pixel_decision;
mod points;
pub mod reference;
pub mod separability;
mod wolff;

pub use bands::{
    BAND_TOLERANCE_NM, BandPoint, EstimateBand, FilmShifts, MultiEstimate, MultiPrototype,
    NativeLayer, TRANSPARENT_K, chi2_quantile, same_band,
};
pub use classifier::{Classifier, NEAR_ZERO_SIGMAS};
pub use config::{
    Bench, ClassifierConfig, DEFAULT_CONFIDENCE, Metric, Reject, Rule, chi2_2dof_quantile,
};
pub use cov::{Cov2, ONE_SIDED_RATIO};
pub use decision::{Candidate, Decision, Neighbour, Status};
pub use evaluate::{Confusion, EvalItem, Evaluation, Labelled, SetStats, evaluate, leave_one_out};
pub use hypothesis::{
    CandidateModel, HypRow, HypothesisConfig, HypothesisOutcome, LayerModel, NuisanceFit,
    Nuisances, OFFSET_SIGMAS, classify_rows, layered_dolp, test_hypothesis,
};
pub use points::{Estimate, Prototype, class_categories};
pub use wolff::{
    WolffClass, WolffConfig, WolffDecision, WolffObservation, fresnel_ratio, wolff_classify,
};

use crate::error::{CoreError, Result};

/// The label of an estimate that is not assigned to any class (rejected, unusable fit,
/// missing covariance). It cannot be used as a class name.
pub const UNKNOWN: &str = "unknown";

/// The label of an estimate consistent with several materials (set rule). It cannot be
/// used as a class name.
pub const AMBIGUOUS: &str = "ambiguous";

/// Check a class name: not empty, not [`UNKNOWN`] or [`AMBIGUOUS`].
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
    if name.trim().eq_ignore_ascii_case(AMBIGUOUS) {
        return Err(CoreError::InvalidName {
            what: "class",
            name: name.into(),
            reason: format!("`{AMBIGUOUS}` is reserved for estimates several materials fit"),
        });
    }
    Ok(())
}
