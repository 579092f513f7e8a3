//! The result of one fit ([`NkFit`]); its trust status is [`FitStatus`].

use super::FitStatus;

/// The result of one fit.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NkFit {
    /// Fitted `n`.
    pub n: f64,
    /// Fitted `k`.
    pub k: f64,
    /// Standard error of `n`.
    pub n_se: f64,
    /// Standard error of `k` (one-sigma upper deviation near `k = 0`, see the module
    /// documentation of [`crate::fit`]).
    pub k_se: f64,
    /// Correlation of the `n` and `k` estimates.
    pub nk_corr: f64,
    /// Root-mean-square (unweighted) DoLP residual.
    pub rms_residual: f64,
    /// The minimised cost `Σ w_t r_t²` (χ² when standard errors were given).
    pub cost: f64,
    /// Levenberg–Marquardt iterations, summed over the polished starts.
    pub iterations: u32,
    /// Model evaluations (each: `T` values and gradients), summed over the starts.
    pub evaluations: u32,
    /// Number of starts polished.
    pub starts: u32,
    /// Trust status.
    pub status: FitStatus,
    /// Why the status is not [`FitStatus::Ok`] (empty when it is).
    pub reason: &'static str,
}

impl NkFit {
    pub(super) fn invalid(reason: &'static str) -> Self {
        Self {
            n: f64::NAN,
            k: f64::NAN,
            n_se: f64::NAN,
            k_se: f64::NAN,
            nk_corr: f64::NAN,
            rms_residual: f64::NAN,
            cost: f64::NAN,
            status: FitStatus::InvalidInput,
            reason,
            ..Default::default()
        }
    }
}
