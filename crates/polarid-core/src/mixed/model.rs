//! The radiometric model at one capture and its analytic gradients ([`model_point`]):
//!
//! ```text
//! S0 = E cos θi (a + ρd/π),          a = f00(n, k, σ, θi, θr, φ) · G
//! DoLP = P(n, k, β) · a/(a + ρd/π)
//! f00 = m00(β) exp(−tan²θ/(2σ²)) / (8π σ² cos⁴θ cos θi cos θr),   m00 = (Rs + Rp)/2
//! ```
//!
//! `G` is 1 or the Smith factor of `shadowing`; with `θr` estimated, `θi = 2β − θr` and the
//! facet tilt `θ = β − θr` (in-plane geometry). The gradients of `ln S0` and `DoLP` in
//! `x = (n, k, σ, ρd, ln E, θr)` are checked against finite differences in
//! `tests/mixed_props.rs`.
//!
//! # Reference
//! Thilak, Creusere & Voelz, ICIP 2007: eq. (3) (`f00`), (4) (`θ`), (5) (`β`), (8), (9)
//! (`P = m10/m00`); the Lambertian term is an addition (see `docs/MIXED.md`).

use std::f64::consts::PI;

use num_complex::Complex64;

use super::shadowing::smith_ln_g1;
use super::{MixedCapture, NPAR, P_K, P_LN_E, P_N, P_RHO, P_SIGMA, P_THETA_R, Shadowing};
use crate::dop::{BetaTerms, dop_grad_terms};
use crate::fresnel::w_root;
use crate::geometry::ScatterGeometry;

/// Values and gradients of the model at one capture.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModelPoint {
    /// Model DoLP.
    pub dolp: f64,
    /// `ln S0` of the model (including `ln E`).
    pub ln_s0: f64,
    /// Specular share `a/(a + ρd/π)`.
    pub specular_share: f64,
    /// `∂DoLP/∂x` (`x` indexed by [`P_N`] … [`P_THETA_R`]; the `θr` entry is 0 unless
    /// `θr` is estimated).
    pub d_dolp: [f64; NPAR],
    /// `∂ ln S0/∂x`.
    pub d_ln_s0: [f64; NPAR],
}

/// `m00 = (Rs + Rp)/2` and its derivatives in `n` and `k` at `sin²β`, `cos β`.
///
/// `rs = (c − w)/(c + w)`, `rp = (N²c − w)/(N²c + w)`, `w = √(N² − sin²β)`;
/// `drs/dN = −2cN/(w (c + w)²)`, `drp/dN = 2Nc (2w² − N²)/(w (N²c + w)²)`,
/// `∂|r|²/∂n = 2 Re(r̄ dr/dN)`, `∂|r|²/∂k = −2 Im(r̄ dr/dN)`.
pub fn m00_grad(n: f64, k: f64, sin2_beta: f64, cos_beta: f64) -> (f64, f64, f64) {
    let w = w_root(n, k, sin2_beta);
    let nn = Complex64::new(n, k);
    let n2 = nn * nn;
    let c = Complex64::new(cos_beta, 0.0);
    let ds = c + w;
    let dp = n2 * c + w;
    if ds.norm_sqr() == 0.0 || dp.norm_sqr() == 0.0 {
        return (1.0, 0.0, 0.0);
    }
    let rs = (c - w) / ds;
    let rp = (n2 * c - w) / dp;
    let m00 = 0.5 * (rs.norm_sqr() + rp.norm_sqr());
    if w.norm_sqr() < 1e-300 {
        return (m00, 0.0, 0.0);
    }
    let drs = -2.0 * c * nn / (w * ds * ds);
    let drp = 2.0 * nn * c * (2.0 * w * w - n2) / (w * dp * dp);
    let gs = rs.conj() * drs;
    let gp = rp.conj() * drp;
    (m00, gs.re + gp.re, -(gs.im + gp.im))
}

/// Per-capture data prepared for the fit.
#[derive(Debug, Clone, Copy)]
pub(super) struct Prepared {
    pub(super) bt: BetaTerms,
    beta: f64,
    /// Known geometry (unused when θr is estimated).
    geo: ScatterGeometry,
    pub(super) y_dolp: f64,
    /// 1/se.
    pub(super) inv_se: f64,
    pub(super) ln_s0: f64,
}

/// Geometry terms that depend on θr and σ.
pub(super) struct LobeTerms {
    /// ln of the facet factor of eq. (3) times the shadowing factor.
    pub(super) ln_g: f64,
    d_sigma: f64,
    d_theta_r: f64,
    pub(super) ln_cos_i: f64,
    dln_cos_i_dtr: f64,
}

pub(super) fn lobe(
    p: &Prepared,
    sigma: f64,
    theta_r: f64,
    estimate: bool,
    sh: Shadowing,
) -> LobeTerms {
    let s2 = sigma * sigma;
    if estimate {
        let ti = 2.0 * p.beta - theta_r;
        let tilt = p.beta - theta_r;
        let (tt, ct) = (tilt.tan(), tilt.cos());
        let tan2 = tt * tt;
        let (ci, cr) = (ti.cos(), theta_r.cos());
        let mut ln_g =
            -tan2 / (2.0 * s2) - (8.0 * PI * s2).ln() - 4.0 * ct.ln() - ci.ln() - cr.ln();
        let mut d_sigma = tan2 / (s2 * sigma) - 2.0 / sigma;
        let mut d_tr = tt / (ct * ct * s2) - 4.0 * tt - ti.tan() + theta_r.tan();
        if sh == Shadowing::SmithBeckmann {
            let (gi, gi_t, gi_s) = smith_ln_g1(ti, sigma);
            let (gr, gr_t, gr_s) = smith_ln_g1(theta_r, sigma);
            ln_g += gi + gr;
            d_sigma += gi_s + gr_s;
            d_tr += -gi_t + gr_t;
        }
        LobeTerms {
            ln_g,
            d_sigma,
            d_theta_r: d_tr,
            ln_cos_i: ci.ln(),
            dln_cos_i_dtr: ti.tan(),
        }
    } else {
        let g = &p.geo;
        let mut ln_g = -g.tan2_tilt / (2.0 * s2)
            - (8.0 * PI * s2).ln()
            - 2.0 * g.cos2_tilt.ln()
            - g.cos_i.ln()
            - g.cos_r.ln();
        let mut d_sigma = g.tan2_tilt / (s2 * sigma) - 2.0 / sigma;
        if sh == Shadowing::SmithBeckmann {
            let (gi, _, gi_s) = smith_ln_g1(g.theta_i, sigma);
            let (gr, _, gr_s) = smith_ln_g1(g.theta_r, sigma);
            ln_g += gi + gr;
            d_sigma += gi_s + gr_s;
        }
        LobeTerms {
            ln_g,
            d_sigma,
            d_theta_r: 0.0,
            ln_cos_i: g.cos_i.ln(),
            dln_cos_i_dtr: 0.0,
        }
    }
}

pub(super) fn point(p: &Prepared, x: &[f64; NPAR], estimate: bool, sh: Shadowing) -> ModelPoint {
    let (n, k, sigma, rho) = (x[P_N], x[P_K], x[P_SIGMA], x[P_RHO]);
    let d = dop_grad_terms(n, k, &p.bt);
    let (m00, m_n, m_k) = m00_grad(n, k, p.bt.s2, p.bt.c);
    let lt = lobe(p, sigma, x[P_THETA_R], estimate, sh);
    let g = lt.ln_g.exp();
    let a = m00 * g;
    let b = rho / PI;
    let ab = a + b;
    let (s, ds_da, ds_db) = if ab > 0.0 {
        (a / ab, b / (ab * ab), -a / (ab * ab))
    } else {
        (1.0, 0.0, 0.0)
    };
    let a_n = m_n * g;
    let a_k = m_k * g;
    let a_s = a * lt.d_sigma;
    let a_t = a * lt.d_theta_r;
    let mut out = ModelPoint {
        dolp: d.p * s,
        ln_s0: x[P_LN_E] + lt.ln_cos_i + ab.ln(),
        specular_share: s,
        ..Default::default()
    };
    out.d_dolp[P_N] = d.dp_dn * s + d.p * ds_da * a_n;
    out.d_dolp[P_K] = d.dp_dk * s + d.p * ds_da * a_k;
    out.d_dolp[P_SIGMA] = d.p * ds_da * a_s;
    out.d_dolp[P_RHO] = d.p * ds_db / PI;
    out.d_dolp[P_THETA_R] = d.p * ds_da * a_t;
    let inv = if ab > 0.0 { 1.0 / ab } else { 0.0 };
    out.d_ln_s0[P_N] = a_n * inv;
    out.d_ln_s0[P_K] = a_k * inv;
    out.d_ln_s0[P_SIGMA] = a_s * inv;
    out.d_ln_s0[P_RHO] = inv / PI;
    out.d_ln_s0[P_LN_E] = 1.0;
    out.d_ln_s0[P_THETA_R] = lt.dln_cos_i_dtr + a_t * inv;
    out
}

/// The model at one capture for parameters `x = (n, k, σ, ρd, ln E, θr)` with
/// analytic gradients. With `estimate_theta_r`, `θi = 2β − θr` (in-plane, `β` of the
/// capture known) and `x[P_THETA_R]` is used; otherwise the capture's own angles are
/// used and `x[P_THETA_R]` is ignored.
pub fn model_point(
    cap: &MixedCapture,
    x: &[f64; NPAR],
    estimate_theta_r: bool,
    shadowing: Shadowing,
) -> ModelPoint {
    let p = prepare_one(cap, 0.01);
    point(&p, x, estimate_theta_r, shadowing)
}

pub(super) fn prepare_one(c: &MixedCapture, dolp_sd: f64) -> Prepared {
    Prepared {
        bt: BetaTerms::new(c.beta),
        beta: c.beta,
        geo: ScatterGeometry::new(c.theta_i, c.theta_r, c.phi),
        y_dolp: c.dolp,
        inv_se: 1.0 / c.dolp_se.unwrap_or(dolp_sd),
        ln_s0: c.s0.ln(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn m00_matches_fresnel() {
        let f = crate::fresnel::Fresnel::new(1.5, 0.7, 0.9);
        let (s, c) = 0.9f64.sin_cos();
        let (m, _, _) = m00_grad(1.5, 0.7, s * s, c);
        assert!((m - f.m00()).abs() < 1e-14);
    }
}
