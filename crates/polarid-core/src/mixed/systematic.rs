//! The total (noise + systematic) covariance of a radiometric fit's `(n, k)`, as the
//! specular fit reports it ([`crate::systematic`], docs/ERRORS.md): the systematic DoLP
//! covariance `Σ` of the captures is propagated through the weighted least-squares fit by
//! the sandwich
//!
//! ```text
//! Cov = s² (JᵀJ)⁻¹ + A W Aᵀ,   A = (JᵀJ)⁻¹ Jᵀ,   W = D Σ D ⊕ 0,   D = diag(1/se_t)
//! ```
//!
//! with `J` the Jacobian of the weighted residuals (DoLP rows then `ln S0` rows) in the
//! fit's free parameters; the systematic errors act on the DoLP rows only (the `S0` rows'
//! relative error `ε` is itself a systematic allowance). `Σ` is the specular fit's
//! ([`systematic_covariance`]) for the specular part of the light, diluted by the
//! specular shares `s_t` (the geometry, scale and film terms of row `t` are those of
//! `P(β_t)` times `s_t`), plus the DoLP floor `f²` on the diagonal. Near `k = 0` (when the fit's
//! `k_se` is one-sided) the covariance is formed in `(n, u = k²)` as the fit does.

use super::linalg::spd_inverse;
use super::problem::Problem;
use super::{
    K_FLOOR, MixedCapture, MixedFit, MixedOptions, NPAR, P_K, P_LN_E, P_N, P_RHO, P_SIGMA,
    P_THETA_R,
};
use crate::dop::dop;
use crate::systematic::{NkCov, Polarimetric, systematic_covariance};

/// The total covariance of `fit`'s `(n, k)` (module documentation), with the direction
/// uncertainty `angle_sd[t]` (radians) of each capture and the polarimetric error model
/// `pol`; `None` when the fit has no covariance or the lengths disagree.
pub fn total_nk_cov(
    caps: &[MixedCapture],
    opts: &MixedOptions,
    fit: &MixedFit,
    angle_sd: &[f64],
    pol: &Polarimetric,
) -> Option<NkCov> {
    let t_len = caps.len();
    if angle_sd.len() != t_len || !(fit.n_se.is_finite() && fit.k_se.is_finite()) {
        return None;
    }
    let pb = Problem::new(caps, opts, fit.model);
    let mut x = [0.0; NPAR];
    x[P_N] = fit.n;
    x[P_K] = fit.k.max(K_FLOOR);
    x[P_SIGMA] = fit.sigma;
    x[P_RHO] = fit.rho_d;
    x[P_LN_E] = fit.scale.ln();
    x[P_THETA_R] = fit.theta_r;
    let (mut r, mut j) = (Vec::new(), Vec::new());
    pb.eval(&x, &mut r, &mut j);
    let inv_se: Vec<f64> = pb.caps.iter().map(|p| p.inv_se).collect();
    let sys = diluted_sigma(caps, fit, &r, &inv_se, angle_sd, pol)?;
    let s2 = if fit.dof == 0 {
        return None;
    } else if caps.iter().all(|c| c.dolp_se.is_some()) {
        (fit.chi2 / fit.dof as f64).max(1.0)
    } else {
        fit.chi2 / fit.dof as f64
    };
    let idx: Vec<usize> = (0..NPAR).filter(|&a| pb.free[a]).collect();
    let (pn, pk) = (
        idx.iter().position(|&a| a == P_N)?,
        idx.iter().position(|&a| a == P_K)?,
    );
    let in_u = opts.bounds.k_min == 0.0 && fit.k < fit.k_se;
    let sw = Sandwich {
        j: &j,
        idx: &idx,
        pn,
        pk,
        k: x[P_K],
        inv_se: &inv_se,
        sys: &sys,
        s2,
    };
    let c = sw.nk(in_u)?;
    let n_se = c[0].max(0.0).sqrt();
    let se2 = c[2].max(0.0).sqrt();
    let k_se = if in_u {
        (fit.k * fit.k + se2).sqrt() - fit.k
    } else {
        se2
    };
    let den = (c[0] * c[2]).sqrt();
    Some(NkCov {
        n_se,
        k_se,
        nk_corr: if den > 0.0 { c[1] / den } else { f64::NAN },
        in_u,
    })
}

/// `Σ` of the module documentation (`T × T`, row-major): the specular part's systematic
/// DoLP covariance, diluted by the specular shares, plus the floor `f²` on the diagonal.
/// `r`: the weighted residuals at the fit; `inv_se`: the captures' `1/se_t`.
fn diluted_sigma(
    caps: &[MixedCapture],
    fit: &MixedFit,
    r: &[f64],
    inv_se: &[f64],
    angle_sd: &[f64],
    pol: &Polarimetric,
) -> Option<Vec<f64>> {
    let t_len = caps.len();
    let betas: Vec<f64> = caps.iter().map(|c| c.beta).collect();
    let bare = Polarimetric {
        dolp_floor: 0.0,
        ..*pol
    };
    let mut sys = vec![0.0; t_len * t_len];
    systematic_covariance(fit.n, fit.k, &betas, angle_sd, &bare, &mut sys).ok()?;
    let share: Vec<f64> = (0..t_len)
        .map(|t| {
            let model = caps[t].dolp + r[t] / inv_se[t];
            let p = dop(fit.n, fit.k, betas[t]);
            if p > 0.0 {
                (model / p).clamp(0.0, 1.0)
            } else {
                1.0
            }
        })
        .collect();
    for t in 0..t_len {
        for s in 0..t_len {
            sys[t * t_len + s] *= share[t] * share[s];
        }
        sys[t * t_len + t] += pol.dolp_floor * pol.dolp_floor;
    }
    Some(sys)
}

/// The terms of the sandwich `s² (JᵀJ)⁻¹ + A W Aᵀ` of the module documentation.
struct Sandwich<'a> {
    /// Jacobian rows of the weighted residuals (DoLP rows first).
    j: &'a [[f64; NPAR]],
    /// The free parameters.
    idx: &'a [usize],
    /// Positions of `n` and `k` among the free parameters.
    pn: usize,
    pk: usize,
    /// `k` at which `j` was evaluated.
    k: f64,
    /// `1/se_t` of the DoLP rows.
    inv_se: &'a [f64],
    /// `Σ`, `T × T` row-major.
    sys: &'a [f64],
    /// The error scale `s²`.
    s2: f64,
}

impl Sandwich<'_> {
    /// `[Cov_nn, Cov_nk, Cov_kk]` (in `u = k²` for `k` when `use_u`); `None` when `JᵀJ`
    /// is singular.
    fn nk(&self, use_u: bool) -> Option<[f64; 3]> {
        let (idx, pn, pk, s2) = (self.idx, self.pn, self.pk, self.s2);
        let (inv_se, sys) = (self.inv_se, self.sys);
        let d = idx.len();
        let t_len = inv_se.len();
        let rows: Vec<[f64; NPAR]> = self
            .j
            .iter()
            .map(|row| {
                let mut row = *row;
                if use_u {
                    row[P_K] /= 2.0 * self.k;
                }
                row
            })
            .collect();
        let mut h = [[0.0; NPAR]; NPAR];
        for row in &rows {
            for p in 0..d {
                for q in 0..d {
                    h[p][q] += row[idx[p]] * row[idx[q]];
                }
            }
        }
        let hi = spd_inverse(&h, d)?;
        // a_p(t) = Σ_q H⁻¹_pq J_t,q for the DoLP rows t < T, p ∈ {n, k}.
        let a = |p: usize, t: usize| (0..d).map(|q| hi[p][q] * rows[t][idx[q]]).sum::<f64>();
        let an: Vec<f64> = (0..t_len).map(|t| a(pn, t) * inv_se[t]).collect();
        let ak: Vec<f64> = (0..t_len).map(|t| a(pk, t) * inv_se[t]).collect();
        let (mut c00, mut c01, mut c11) = (0.0, 0.0, 0.0);
        for t in 0..t_len {
            for s in 0..t_len {
                let v = sys[t * t_len + s];
                c00 += an[t] * v * an[s];
                c01 += an[t] * v * ak[s];
                c11 += ak[t] * v * ak[s];
            }
        }
        Some([
            s2 * hi[pn][pn] + c00,
            s2 * hi[pn][pk] + c01,
            s2 * hi[pk][pk] + c11,
        ])
    }
}
