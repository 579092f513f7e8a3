//! The least-squares problem of one model: input validation, the parameter box, and the
//! weighted residuals with their Jacobian (`2T` rows for `T` captures):
//!
//! ```text
//! r_t     = (DoLP_model − DoLP_t) / se_t        (se_t = dolp_se, or MixedOptions::dolp_sd)
//! r_{T+t} = (ln S0_model − ln S0_t) / ε         (ε = MixedOptions::s0_rel_sd)
//! ```
//!
//! `ln E` can be profiled out in closed form: the mean of `ln S0_t − ln(model_t/E)`.
//! With `θr` estimated, its box keeps `θi = 2β − θr` in `[0, 89.5°)` for every capture.

use std::f64::consts::PI;

use super::model::{Prepared, point, prepare_one};
use super::{
    K_FLOOR, MixedCapture, MixedModel, MixedOptions, ModelPoint, NPAR, P_LN_E, P_RHO, P_THETA_R,
};
use crate::error::{CoreError, Result, ensure_finite};

/// Grazing limit for the geometry (radians, 89.5°): `cos θ` stays away from 0.
const MAX_ZENITH: f64 = 89.5 * PI / 180.0;

pub(super) fn validate(caps: &[MixedCapture], o: &MixedOptions) -> Result<()> {
    if caps.len() < 3 {
        return Err(CoreError::TooFew {
            what: "captures (source positions) for the radiometric fit",
            needed: 3,
            got: caps.len(),
        });
    }
    for c in caps {
        ensure_finite("beta", c.beta)?;
        crate::error::ensure_range("dolp", c.dolp, 0.0, 1.0, "[0, 1]")?;
        ensure_finite("s0", c.s0)?;
        if !(c.s0 > 0.0) {
            return Err(CoreError::OutOfRange {
                name: "s0",
                value: c.s0,
                expected: "> 0 (mean S0 divided by the exposure)",
            });
        }
        if let Some(se) = c.dolp_se
            && !(se > 0.0 && se.is_finite())
        {
            return Err(CoreError::OutOfRange {
                name: "dolp_se",
                value: se,
                expected: "> 0",
            });
        }
        if !(c.beta > 0.0 && c.beta < std::f64::consts::FRAC_PI_2) {
            return Err(CoreError::OutOfRange {
                name: "beta",
                value: c.beta,
                expected: "(0, 90) degrees",
            });
        }
        if o.estimate_theta_r {
            if (c.phi - PI).abs() > 1e-6 {
                return Err(CoreError::OutOfRange {
                    name: "phi",
                    value: c.phi,
                    expected: "180 degrees (theta_r can be estimated in the plane of incidence only)",
                });
            }
        } else {
            for (name, v) in [("theta_i", c.theta_i), ("theta_r", c.theta_r)] {
                ensure_finite(name, v)?;
                if !(0.0..MAX_ZENITH).contains(&v) {
                    return Err(CoreError::OutOfRange {
                        name,
                        value: v,
                        expected: "[0, 89.5) degrees",
                    });
                }
            }
            ensure_finite("phi", c.phi)?;
        }
    }
    let b = &o.bounds;
    let ok = b.n_min >= 0.0
        && b.n_max > b.n_min
        && b.k_min >= 0.0
        && b.k_max > b.k_min
        && o.sigma_min > 0.0
        && o.sigma_max > o.sigma_min
        && o.rho_d_max > 0.0
        && o.s0_rel_sd > 0.0
        && o.dolp_sd > 0.0
        && o.theta_r_range.1 > o.theta_r_range.0
        && o.theta_r_range.0 >= 0.0
        && o.min_specular_share >= 0.0;
    if !ok {
        return Err(CoreError::OutOfRange {
            name: "mixed fit options",
            value: f64::NAN,
            expected: "non-empty boxes for n, k, sigma, rho_d, theta_r and positive error scales",
        });
    }
    Ok(())
}

/// Bounds of every parameter for this data set.
pub(super) fn param_box(caps: &[MixedCapture], o: &MixedOptions) -> ([f64; NPAR], [f64; NPAR]) {
    let b = &o.bounds;
    let k_lo = if b.k_min > 0.0 { b.k_min } else { K_FLOOR };
    let mut lo = [b.n_min.max(1e-6), k_lo, o.sigma_min, 0.0, -1e300, 0.0];
    let mut hi = [b.n_max, b.k_max, o.sigma_max, o.rho_d_max, 1e300, 0.0];
    if o.estimate_theta_r {
        // θi = 2β − θr must stay in [0, MAX_ZENITH) for every capture.
        let bmin = caps.iter().map(|c| c.beta).fold(f64::INFINITY, f64::min);
        let bmax = caps
            .iter()
            .map(|c| c.beta)
            .fold(f64::NEG_INFINITY, f64::max);
        lo[P_THETA_R] = o.theta_r_range.0.max(2.0 * bmax - MAX_ZENITH + 1e-6);
        hi[P_THETA_R] = o.theta_r_range.1.min(2.0 * bmin).min(MAX_ZENITH - 1e-6);
    }
    (lo, hi)
}

pub(super) struct Problem<'a> {
    pub(super) caps: Vec<Prepared>,
    pub(super) opts: &'a MixedOptions,
    pub(super) free: [bool; NPAR],
    pub(super) lo: [f64; NPAR],
    pub(super) hi: [f64; NPAR],
    pub(super) inv_eps: f64,
}

impl<'a> Problem<'a> {
    /// The problem of `model` for these captures: every parameter free but `ρd` for the
    /// specular model and `θr` unless estimated, in the [`param_box`].
    pub(super) fn new(caps: &[MixedCapture], opts: &'a MixedOptions, model: MixedModel) -> Self {
        let (lo, hi) = param_box(caps, opts);
        let mut free = [true; NPAR];
        free[P_RHO] = model == MixedModel::Mixed;
        free[P_THETA_R] = opts.estimate_theta_r;
        Problem {
            caps: caps.iter().map(|c| prepare_one(c, opts.dolp_sd)).collect(),
            opts,
            free,
            lo,
            hi,
            inv_eps: 1.0 / opts.s0_rel_sd,
        }
    }

    pub(super) fn m(&self) -> usize {
        2 * self.caps.len()
    }

    /// Weighted residuals and Jacobian rows (columns for all NPAR parameters).
    pub(super) fn eval(&self, x: &[f64; NPAR], r: &mut Vec<f64>, j: &mut Vec<[f64; NPAR]>) -> f64 {
        r.clear();
        j.clear();
        let est = self.opts.estimate_theta_r;
        let mut cost = 0.0;
        let pts: Vec<ModelPoint> = self
            .caps
            .iter()
            .map(|p| point(p, x, est, self.opts.shadowing))
            .collect();
        for (p, mp) in self.caps.iter().zip(&pts) {
            let v = (mp.dolp - p.y_dolp) * p.inv_se;
            r.push(v);
            cost += v * v;
            let mut row = mp.d_dolp;
            row.iter_mut().for_each(|e| *e *= p.inv_se);
            j.push(row);
        }
        for (p, mp) in self.caps.iter().zip(&pts) {
            let v = (mp.ln_s0 - p.ln_s0) * self.inv_eps;
            r.push(v);
            cost += v * v;
            let mut row = mp.d_ln_s0;
            row.iter_mut().for_each(|e| *e *= self.inv_eps);
            j.push(row);
        }
        if cost.is_finite() {
            cost
        } else {
            f64::INFINITY
        }
    }

    /// Profile `ln E` out: the value minimising the S0 residuals for the other params.
    pub(super) fn profile_ln_e(&self, x: &mut [f64; NPAR]) {
        x[P_LN_E] = 0.0;
        let est = self.opts.estimate_theta_r;
        let mut s = 0.0;
        for p in &self.caps {
            s += p.ln_s0 - point(p, x, est, self.opts.shadowing).ln_s0;
        }
        x[P_LN_E] = s / self.caps.len() as f64;
    }
}
