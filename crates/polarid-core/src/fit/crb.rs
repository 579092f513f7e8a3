//! Cramér–Rao bound on `(n, k)` from DoLP measurements with Gaussian noise.
//!
//! For measurements `y_t = P(n, k, β_t) + ε_t`, `ε_t ~ N(0, σ_t²)` (eq. 16), the
//! Fisher information is `F = Σ_t ∇P_t ∇P_tᵀ / σ_t²` (a 2×2 matrix) and every unbiased
//! estimator has covariance `≥ F⁻¹`.

use crate::dop::{BetaTerms, dop_grad_terms};
use crate::error::{CoreError, Result, check_len, ensure_finite};

/// The Cramér–Rao bound (the inverse Fisher information) on `(n, k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crb {
    /// Bound on the variance of `n`.
    pub var_n: f64,
    /// Bound on the variance of `k`.
    pub var_k: f64,
    /// Covariance of `n` and `k` in `F⁻¹`.
    pub cov_nk: f64,
    /// `√var_n`: the smallest achievable standard deviation of `n`.
    pub sd_n: f64,
    /// `√var_k`: the smallest achievable standard deviation of `k`.
    pub sd_k: f64,
    /// Correlation of `n` and `k` in `F⁻¹`.
    pub corr: f64,
}

impl Crb {
    /// The inverse of a 2×2 information matrix `[[f00, f01], [f01, f11]]`; infinite
    /// variances (and NaN correlation) when it is singular.
    pub fn from_information(f00: f64, f01: f64, f11: f64) -> Self {
        let det = f00 * f11 - f01 * f01;
        if !(det > 1e-300) || !(det > 1e-15 * f00 * f11) {
            return Self {
                var_n: f64::INFINITY,
                var_k: f64::INFINITY,
                cov_nk: f64::NAN,
                sd_n: f64::INFINITY,
                sd_k: f64::INFINITY,
                corr: f64::NAN,
            };
        }
        let var_n = f11 / det;
        let var_k = f00 / det;
        let cov_nk = -f01 / det;
        Self {
            var_n,
            var_k,
            cov_nk,
            sd_n: var_n.sqrt(),
            sd_k: var_k.sqrt(),
            corr: -f01 / (f00 * f11).sqrt(),
        }
    }
}

/// Cramér–Rao bound for the index `(n, k)` measured at local incidence angles `betas`
/// (radians) with the same DoLP noise standard deviation `noise_sd` for every
/// measurement.
///
/// `F = Σ_t ∇P(n, k, β_t) ∇P(n, k, β_t)ᵀ / σ²`, `CRB = F⁻¹` (eq. 9 / 16 with the
/// analytic gradient of [`crate::dop::dop_grad`]).
pub fn crb(n: f64, k: f64, betas: &[f64], noise_sd: f64) -> Result<Crb> {
    check_nk(n, k)?;
    if !(noise_sd > 0.0) || !noise_sd.is_finite() {
        return Err(CoreError::OutOfRange {
            name: "noise_sd",
            value: noise_sd,
            expected: "a finite value > 0",
        });
    }
    let terms = beta_terms(betas)?;
    Ok(crb_terms(n, k, &terms, |_| noise_sd))
}

/// Cramér–Rao bound with one noise standard deviation per measurement (`sds[t]` for
/// `betas[t]`).
pub fn crb_weighted(n: f64, k: f64, betas: &[f64], sds: &[f64]) -> Result<Crb> {
    check_nk(n, k)?;
    check_len("sds", sds.len(), betas.len())?;
    for &s in sds {
        if !(s > 0.0) || !s.is_finite() {
            return Err(CoreError::OutOfRange {
                name: "noise_sd",
                value: s,
                expected: "a finite value > 0",
            });
        }
    }
    let terms = beta_terms(betas)?;
    Ok(crb_terms(n, k, &terms, |t| sds[t]))
}

pub(crate) fn crb_terms(n: f64, k: f64, terms: &[BetaTerms], sd: impl Fn(usize) -> f64) -> Crb {
    let (mut f00, mut f01, mut f11) = (0.0, 0.0, 0.0);
    for (i, t) in terms.iter().enumerate() {
        let g = dop_grad_terms(n, k, t);
        let w = 1.0 / (sd(i) * sd(i));
        f00 += w * g.dp_dn * g.dp_dn;
        f01 += w * g.dp_dn * g.dp_dk;
        f11 += w * g.dp_dk * g.dp_dk;
    }
    Crb::from_information(f00, f01, f11)
}

fn check_nk(n: f64, k: f64) -> Result<()> {
    ensure_finite("n", n)?;
    ensure_finite("k", k)?;
    if !(n > 0.0) {
        return Err(CoreError::OutOfRange {
            name: "n",
            value: n,
            expected: "n > 0",
        });
    }
    if k < 0.0 {
        return Err(CoreError::OutOfRange {
            name: "k",
            value: k,
            expected: "k >= 0",
        });
    }
    Ok(())
}

fn beta_terms(betas: &[f64]) -> Result<Vec<BetaTerms>> {
    betas
        .iter()
        .map(|&b| {
            crate::error::ensure_range(
                "beta",
                b,
                0.0,
                std::f64::consts::FRAC_PI_2,
                "[0, pi/2] radians",
            )
            .map(BetaTerms::new)
        })
        .collect()
}
