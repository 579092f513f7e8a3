//! The settings of a fit: the box of admissible `(n, k)` ([`FitBounds`]) and the grid
//! and solver options ([`FitOptions`]).

/// The box of admissible `(n, k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitBounds {
    /// Smallest `n` (> 0 or = 0).
    pub n_min: f64,
    /// Largest `n`.
    pub n_max: f64,
    /// Smallest `k` (≥ 0).
    pub k_min: f64,
    /// Largest `k`.
    pub k_max: f64,
}

impl Default for FitBounds {
    fn default() -> Self {
        Self {
            n_min: 0.01,
            n_max: 10.0,
            k_min: 0.0,
            k_max: 15.0,
        }
    }
}

/// Settings of a [`FitPlan`](super::FitPlan).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// The box of admissible `(n, k)`.
    pub bounds: FitBounds,
    /// Grid nodes along `n` for the global start (≥ 4).
    pub grid_n: usize,
    /// Grid nodes along `k` for the global start (≥ 4).
    pub grid_k: usize,
    /// At most this many starts are polished per fit (≥ 1).
    pub max_candidates: usize,
    /// Iteration limit of one Levenberg–Marquardt polish.
    pub max_iter: u32,
    /// Relative step tolerance.
    pub xtol: f64,
    /// Relative cost-decrease tolerance.
    pub ftol: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            bounds: FitBounds::default(),
            grid_n: 32,
            grid_k: 32,
            max_candidates: 1,
            max_iter: 1000,
            xtol: 1e-10,
            ftol: 1e-12,
        }
    }
}
