//! The one status type of an `(n, k)` estimate: how far a fit can be trusted.
//!
//! Every fit (specular eq. 16, the mixed radiometric fit, the per-pixel map) reports a
//! [`FitStatus`]; the classifier only classifies [`FitStatus::Ok`]. The word form
//! ([`FitStatus::as_str`], [`FitStatus::parse`]) is used only where a CSV file or the
//! Python package meets the type; [`FitStatus::code`] is the small integer of the
//! Python package's status arrays (an index into [`FitStatus::ALL`]).

/// How far an `(n, k)` estimate can be trusted.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
pub enum FitStatus {
    /// Converged to the global least-squares minimum inside the box.
    #[default]
    Ok,
    /// The polish did not converge within the iteration limit.
    NotConverged,
    /// The data do not determine the parameters: fewer than 3 distinct β, too narrow a
    /// β range, a flat DoLP curve, a singular `JᵀWJ`, or (mixed fit) `θr` not pinned.
    IllConditioned,
    /// The minimum lies on the edge of the box (other than `k = 0`, `ρd = 0`).
    AtBound,
    /// The data are unusable (non-finite, DoLP outside `[0, 1]`); only from batch fits,
    /// single fits return an error instead.
    InvalidInput,
    /// The light is (nearly) unpolarized at every capture: `(n, k)` would rest on a tiny
    /// polarized part (specular fit: DoLP below a threshold everywhere; mixed fit: the
    /// diffuse term dominates).
    Depolarized,
    /// The data contradict the single-interface model beyond their total (noise plus
    /// systematic) uncertainty: the residuals fail the χ² goodness-of-fit test, or the
    /// AoLP is not perpendicular to the plane of incidence (a coating, a film,
    /// birefringence or a wrong geometry; docs/ERRORS.md). The estimate is reported but
    /// must not be classified.
    ModelMismatch,
}

impl FitStatus {
    /// Every status, in the order of their [`FitStatus::code`].
    pub const ALL: [FitStatus; 7] = [
        FitStatus::Ok,
        FitStatus::NotConverged,
        FitStatus::IllConditioned,
        FitStatus::AtBound,
        FitStatus::InvalidInput,
        FitStatus::Depolarized,
        FitStatus::ModelMismatch,
    ];

    /// One word: `ok`, `not_converged`, `ill_conditioned`, `at_bound`, `invalid_input`,
    /// `depolarized`, `model_mismatch` (the `status` column of the fits CSV).
    pub fn as_str(self) -> &'static str {
        match self {
            FitStatus::Ok => "ok",
            FitStatus::NotConverged => "not_converged",
            FitStatus::IllConditioned => "ill_conditioned",
            FitStatus::AtBound => "at_bound",
            FitStatus::InvalidInput => "invalid_input",
            FitStatus::Depolarized => "depolarized",
            FitStatus::ModelMismatch => "model_mismatch",
        }
    }

    /// The status of a word written by [`FitStatus::as_str`] (exact, lower case);
    /// `None` for any other text.
    pub fn parse(word: &str) -> Option<FitStatus> {
        FitStatus::ALL.into_iter().find(|s| s.as_str() == word)
    }

    /// Small integer code: the index of the status in [`FitStatus::ALL`].
    pub fn code(self) -> u8 {
        match self {
            FitStatus::Ok => 0,
            FitStatus::NotConverged => 1,
            FitStatus::IllConditioned => 2,
            FitStatus::AtBound => 3,
            FitStatus::InvalidInput => 4,
            FitStatus::Depolarized => 5,
            FitStatus::ModelMismatch => 6,
        }
    }

    /// True for [`FitStatus::Ok`]: the estimate may be classified.
    pub fn is_ok(self) -> bool {
        self == FitStatus::Ok
    }
}

impl std::fmt::Display for FitStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_and_codes_round_trip() {
        for (i, s) in FitStatus::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(s.code()), i);
            assert_eq!(FitStatus::parse(s.as_str()), Some(s));
            assert_eq!(s.to_string(), s.as_str());
        }
        assert_eq!(FitStatus::parse("OK"), None);
        assert_eq!(FitStatus::parse(""), None);
        assert_eq!(FitStatus::parse("fit_ok"), None);
        assert_eq!(
            FitStatus::parse("model_mismatch"),
            Some(FitStatus::ModelMismatch)
        );
        assert_eq!(FitStatus::ModelMismatch.code(), 6);
    }
}
