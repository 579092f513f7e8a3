//! Answers as sets for map pixels: the covariance of a pixel's `(n, k)` with the
//! systematic error model of `docs/ERRORS.md` ([`crate::systematic`]) added to the noise,
//! and the materials consistent with it.
//!
//! # Covariance
//! A pixel's fit is linearised as in [`crate::systematic::propagate`]:
//! `A = (JᵀWJ)⁻¹JᵀW` (`W = diag(1/se²)` for a noise-weighted fit, else `I`), and
//!
//! ```text
//! Cov = s² (JᵀWJ)⁻¹ + A Σ Aᵀ,
//! Σ_ts = δ_ts (f² + a_t²) + a_t a_s + u² P_t P_s,    a_t = P'(β_t) σ_t / 2
//! ```
//!
//! (`s² = 1` when weighted, `Σr²/(T − 2)` when not). `Σ` is diagonal plus rank two, so
//! `AΣAᵀ = Σ_t (f² + a_t²) A_t A_tᵀ + (Aa)(Aa)ᵀ + u² (AP)(AP)ᵀ` costs `O(T)`: one
//! evaluation of eq. (9) with its `(n, k)` and `β` derivatives per row, no `T × T` matrix.
//! Near `k = 0` (when the total interval on `k` reaches 0) the covariance is formed in
//! `(n, u = k²)` and `k_se = √(k² + se_u) − k`, as the fit and `propagate` do.
//!
//! The systematic part is common to many pixels (one camera, one analyzer, one bench),
//! so it is **not** written into `n_se.tif`/`k_se.tif` (the pixels' own, noise-only
//! standard errors); it enters only the consistency test of the set rule, where it
//! keeps a pixel whose DoLP is off by a calibration error from being called a wrong
//! material with confidence.
//!
//! # Set
//! The set rule of `polarid_pipeline::map` tests the materials against a pixel's
//! estimate with this covariance: one consistent → that material; several →
//! `ambiguous`; none → `unknown` (reason `rejected`). An estimate whose total
//! `n_se ≥ n` (its one-sigma interval reaches `n = 0`: the data leave the pixel free to
//! slide along a valley of the DoLP curves, typically to the box's edge) is `ambiguous`
//! without the test: a linearised distance means nothing that far from the estimate (on
//! the rough aluminum of the Mitsuba renders, such pixels at `(5, 13) ± (7, 8)` were
//! otherwise found consistent with green paint only).

use crate::classify::Cov2;
use crate::dop::{dop, dop_beta_derivs, dop_grad};
use crate::systematic::Polarimetric;

/// The systematic error model of a map: the polarimetric part (one analyzer) and the
/// angle uncertainty of every capture.
#[derive(Debug, Clone, PartialEq)]
pub struct MapErrorModel {
    /// DoLP floor, extinction ratio and retardance.
    pub polarimetric: Polarimetric,
    /// Standard uncertainty of the source and camera directions of each capture,
    /// radians (in the order of the DoLP images).
    pub angle_sd: Vec<f64>,
}

impl MapErrorModel {
    /// No systematic error (noise only).
    pub fn none(captures: usize) -> Self {
        Self {
            polarimetric: Polarimetric {
                dolp_floor: 0.0,
                extinction_ratio: f64::INFINITY,
                retardance: 0.0,
                film_sd_waves: 0.0,
            },
            angle_sd: vec![0.0; captures],
        }
    }
}

/// One row of a pixel's fit: the capture's index, its β (radians), the measured DoLP
/// and the noise standard error (1 when unweighted).
#[derive(Debug, Clone, Copy)]
pub struct PixelRow {
    /// Index of the capture (into [`MapErrorModel::angle_sd`]).
    pub capture: usize,
    /// β of the pixel in that capture, radians (eq. 5).
    pub beta: f64,
    /// Measured DoLP.
    pub y: f64,
    /// Noise standard error of the DoLP (1 when the fit is unweighted).
    pub se: f64,
}

/// Scratch memory of [`total_covariance`].
#[derive(Debug, Default)]
pub struct CovScratch {
    jn: Vec<f64>,
    jk: Vec<f64>,
    w: Vec<f64>,
    p: Vec<f64>,
    a: Vec<f64>,
}

/// The noise-plus-systematic covariance of a pixel's fit `(n, k)` (module docs);
/// `weighted`: the fit used the rows' `se`; `k_can_be_zero`: the fit's bounds allow
/// `k = 0` (the covariance is then taken in `u = k²` near 0). `None` when `JᵀWJ` is
/// singular or there are fewer than 3 rows. Public for the per-band maps of colour
/// captures, which classify a pixel on all its bands at once.
pub fn total_covariance(
    n: f64,
    k: f64,
    rows: &[PixelRow],
    weighted: bool,
    model: &MapErrorModel,
    k_can_be_zero: bool,
    s: &mut CovScratch,
) -> Option<Cov2> {
    let t_len = rows.len();
    if t_len < 3 {
        return None;
    }
    s.jn.clear();
    s.jk.clear();
    s.w.clear();
    s.p.clear();
    s.a.clear();
    let mut ss = 0.0;
    for r in rows {
        let g = dop_grad(n, k, r.beta);
        let sd = model.angle_sd.get(r.capture).copied().unwrap_or(0.0);
        let a = if sd > 0.0 {
            0.5 * dop_beta_derivs(n, k, r.beta).dp_dbeta * sd
        } else {
            0.0
        };
        s.jn.push(g.dp_dn);
        s.jk.push(g.dp_dk);
        s.w.push(if weighted { 1.0 / (r.se * r.se) } else { 1.0 });
        s.p.push(g.p);
        s.a.push(a);
        let e = r.y - g.p;
        ss += e * e;
    }
    let s2 = if weighted {
        1.0
    } else {
        ss / (t_len as f64 - 2.0)
    };
    let lin = sandwich(&s.jn, &s.jk, s, s2, &model.polarimetric);
    let use_u = k_can_be_zero
        && match lin {
            None => true,
            Some(c) => k < c[2].max(0.0).sqrt(),
        };
    let (c, in_u) = if use_u {
        let ju: Vec<f64> = if k >= 1e-4 {
            s.jk.iter().map(|d| d / (2.0 * k)).collect()
        } else {
            let du = 1e-6;
            let k1 = (k * k + du).sqrt();
            rows.iter()
                .zip(&s.p)
                .map(|(r, p)| (dop(n, k1, r.beta) - p) / (k1 * k1 - k * k))
                .collect()
        };
        (sandwich(&s.jn, &ju, s, s2, &model.polarimetric)?, true)
    } else {
        (lin?, false)
    };
    let n_se = c[0].max(0.0).sqrt();
    let se2 = c[2].max(0.0).sqrt();
    let k_se = if in_u { (k * k + se2).sqrt() - k } else { se2 };
    let den = (c[0] * c[2]).sqrt();
    let corr = if den > 0.0 { c[1] / den } else { 0.0 };
    Cov2::from_se(n_se, k_se, corr.clamp(-1.0, 1.0))
}

/// `s² (JᵀWJ)⁻¹ + AΣAᵀ` for the columns `j0`, `j1` as `[c00, c01, c11]`.
fn sandwich(
    j0: &[f64],
    j1: &[f64],
    s: &CovScratch,
    s2: f64,
    pol: &Polarimetric,
) -> Option<[f64; 3]> {
    let (mut h00, mut h01, mut h11) = (0.0, 0.0, 0.0);
    for t in 0..j0.len() {
        h00 += s.w[t] * j0[t] * j0[t];
        h01 += s.w[t] * j0[t] * j1[t];
        h11 += s.w[t] * j1[t] * j1[t];
    }
    let det = h00 * h11 - h01 * h01;
    if !(h00 > 0.0 && h11 > 0.0 && det > 1e-12 * h00 * h11 && det.is_finite()) {
        return None;
    }
    let (i00, i01, i11) = (h11 / det, -h01 / det, h00 / det);
    let f2 = pol.dolp_floor * pol.dolp_floor;
    let u2 = {
        let u = pol.scale_sd();
        u * u
    };
    let (mut c00, mut c01, mut c11) = (0.0, 0.0, 0.0);
    let (mut aa0, mut aa1, mut ap0, mut ap1) = (0.0, 0.0, 0.0, 0.0);
    for t in 0..j0.len() {
        let a0 = s.w[t] * (i00 * j0[t] + i01 * j1[t]);
        let a1 = s.w[t] * (i01 * j0[t] + i11 * j1[t]);
        let d = f2 + s.a[t] * s.a[t];
        c00 += d * a0 * a0;
        c01 += d * a0 * a1;
        c11 += d * a1 * a1;
        aa0 += a0 * s.a[t];
        aa1 += a1 * s.a[t];
        ap0 += a0 * s.p[t];
        ap1 += a1 * s.p[t];
    }
    c00 += aa0 * aa0 + u2 * ap0 * ap0 + s2 * i00;
    c01 += aa0 * aa1 + u2 * ap0 * ap1 + s2 * i01;
    c11 += aa1 * aa1 + u2 * ap1 * ap1 + s2 * i11;
    Some([c00, c01, c11])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::systematic::{propagate, systematic_covariance};

    /// The O(T) covariance equals `systematic::propagate`'s total, weighted and not, in
    /// `(n, k)` and near `k = 0`.
    #[test]
    fn total_covariance_matches_propagate() {
        let pol = Polarimetric {
            dolp_floor: 0.002,
            extinction_ratio: 100.0,
            retardance: 0.05,
            film_sd_waves: 0.0,
        };
        let betas: Vec<f64> = (0..8)
            .map(|i| (30.0 + 6.0 * i as f64).to_radians())
            .collect();
        let sd: Vec<f64> = (0..8)
            .map(|i| (0.1 + 0.02 * i as f64).to_radians())
            .collect();
        let model = MapErrorModel {
            polarimetric: pol,
            angle_sd: sd.clone(),
        };
        for &(n, k) in &[(1.2, 6.6), (0.4, 2.9), (1.5, 0.0), (1.5, 0.01)] {
            for weighted in [true, false] {
                let rows: Vec<PixelRow> = betas
                    .iter()
                    .enumerate()
                    .map(|(t, &b)| PixelRow {
                        capture: t,
                        beta: b,
                        y: dop(n, k, b) + 0.003 * ((t as f64) * 1.7).sin(),
                        se: 0.002 + 0.0005 * t as f64,
                    })
                    .collect();
                let mut s = CovScratch::default();
                let c = total_covariance(n, k, &rows, weighted, &model, true, &mut s).unwrap();
                let mut sys = vec![0.0; 64];
                systematic_covariance(n, k, &betas, &sd, &pol, &mut sys).unwrap();
                let resid: Vec<f64> = rows.iter().map(|r| r.y - dop(n, k, r.beta)).collect();
                let se: Vec<f64> = rows.iter().map(|r| r.se).collect();
                let want = propagate(
                    n,
                    k,
                    &betas,
                    &resid,
                    weighted.then_some(&se[..]),
                    &sys,
                    true,
                )
                .unwrap()
                .total;
                let (n_se, k_se, corr) = c.to_se();
                for (a, b, what) in [
                    (n_se, want.n_se, "n_se"),
                    (k_se, want.k_se, "k_se"),
                    (corr, want.nk_corr, "corr"),
                ] {
                    assert!(
                        (a - b).abs() <= 1e-6 * b.abs().max(1e-3),
                        "({n}, {k}) weighted {weighted} {what}: {a} vs {b}"
                    );
                }
            }
        }
    }
}
