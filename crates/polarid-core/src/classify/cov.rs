//! The covariance of an `(n, k)` estimate and the squared Mahalanobis length it defines.
//!
//! ```text
//! Σ = [[n_se², ρ n_se k_se], [ρ n_se k_se, k_se²]]
//! d_M² = Δᵀ Σ⁻¹ Δ = (Σ_kk Δn² − 2 Σ_nk Δn Δk + Σ_nn Δk²) / det Σ
//! ```
//!
//! The covariances of independent estimates add (`Σ_est + Σ_proto`).

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
