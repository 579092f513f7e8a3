//! The β terms of eq. (9) of a fit, structure-of-arrays and padded to whole
//! [`LANES`] (padding copies the first angle; the fit gives padding weight 0), read by
//! the grid refinement and by the lane evaluation of `engine.rs`.

use crate::dop::BetaTerms;

/// Positions evaluated together (one f64x4 vector).
pub(crate) const LANES: usize = 4;

/// Largest `n_max`, `k_max` for which the lane evaluation cannot overflow.
pub(crate) const MAX_BOUND: f64 = 1e100;

/// `2 sin²β cos β`, the numerator of eq. (9) without `A`.
#[inline(always)]
pub(crate) fn num(t: &BetaTerms) -> f64 {
    2.0 * t.s2 * t.c
}

/// The β terms of eq. (9), padded to a multiple of [`LANES`].
#[derive(Debug, Clone, Default)]
pub(crate) struct Lanes {
    /// Padded length.
    pub len: usize,
    s2: Vec<f64>,
    c: Vec<f64>,
    c2: Vec<f64>,
    s4: Vec<f64>,
    /// `2 sin²β cos β`.
    num: Vec<f64>,
}

impl Lanes {
    /// Terms of `terms`, padded with copies of the first (weight 0 in the fit).
    pub fn new(terms: &[BetaTerms]) -> Self {
        let len = terms.len().div_ceil(LANES) * LANES;
        let pad = |f: &dyn Fn(&BetaTerms) -> f64| -> Vec<f64> {
            (0..len)
                .map(|i| f(terms.get(i).unwrap_or(&terms[0])))
                .collect()
        };
        Self {
            len,
            s2: pad(&|t| t.s2),
            c: pad(&|t| t.c),
            c2: pad(&|t| t.c2),
            s4: pad(&|t| t.s4),
            num: pad(&|t| num(t)),
        }
    }

    /// The first `t_len` values of `sin²β`, `cos β`, `cos²β`, `sin⁴β` and
    /// `2 sin²β cos β`.
    #[inline(always)]
    pub fn terms(&self, t_len: usize) -> (&[f64], &[f64], &[f64], &[f64], &[f64]) {
        (
            &self.s2[..t_len],
            &self.c[..t_len],
            &self.c2[..t_len],
            &self.s4[..t_len],
            &self.num[..t_len],
        )
    }
}
