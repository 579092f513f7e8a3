//! Systematic errors of a DoLP measurement and their propagation into the `(n, k)`
//! covariance of the specular fit (paper eq. 9 and 16), with the goodness-of-fit and
//! AoLP checks of the single-interface model. The reasoning and the defaults are in
//! `docs/ERRORS.md`.
//!
//! # Error model
//! Row `t` of a target (one capture) has DoLP `y_t`, noise standard error `se_t`, local
//! incidence angle `β_t` and an angle uncertainty `σ_t` (the standard uncertainty of the
//! directions of the source and of the camera). Besides the noise it carries
//!
//! - **geometry**: `β` is half the source–camera angle (eq. 5), so an error `δs` of the
//!   source direction and `δv` of the camera direction move it by
//!   `δβ = (δs∥ + δv∥)/2` (their components along the great circle through both; the
//!   surface normal does not enter β). The source part is independent from capture to
//!   capture, the camera part is common to every capture of a target (one camera pose):
//!   `Cov(δβ_t, δβ_s) = δ_ts σ_t²/4 + σ_t σ_s/4`, and `δP_t = P'(β_t) δβ_t`;
//! - **DoLP floor** `f`: an additive error, independent per row, `Var = f²`;
//! - **DoLP scale** `ε`: an analyzer with extinction ratio `ER` measures
//!   `P (ER − 1)/(ER + 1)`, a relative loss `2/(ER + 1)`; a retardance `δ` ahead of the
//!   analyzer turns part of the linear polarization into circular, a relative loss of at
//!   most `1 − cos δ`. Both are common to every row of a target (fully correlated):
//!   `δP_t = −ε P_t`, `Var ε = u²`, `u = 2/(ER + 1) + (1 − cos δ)`.
//!
//! - **surface layer** of standard thickness `σ_d` (in wavelengths): a native oxide or
//!   contamination film the single-interface model ignores. Its index is unknown between
//!   that of silica and of the high-index, possibly absorbing oxides: the DoLP change of
//!   a film of thickness `σ_d` and index `N_j ∈ FILM_INDICES` (1.5, 2.8, 2.8 + 0.3i) on
//!   the estimate,
//!   `g_jt = P_film(n_j, σ_d; β_t) − P(β_t)` (single-layer Airy sum, [`crate::film`]),
//!   each common to every row of a target (one film per surface):
//!   `Σ_film,ts = Σ_j g_jt g_js`. To first order in `d/λ` a film's change of `r_s`,
//!   `r_p` is linear in `N_f²` and `1/N_f²`, so films of intermediate index lie close to
//!   the span of the three.
//!
//! so that
//!
//! ```text
//! Σ_ts = δ_ts (f² + P'_t² σ_t²/4) + P'_t P'_s σ_t σ_s/4 + u² P_t P_s + Σ_j g_jt g_js.
//! ```
//!
//! # Propagation
//! The estimate is the noise-weighted least-squares fit (`W = diag(1/se²)`, or `I`);
//! linearised about it, `δθ = A δy` with `A = (JᵀWJ)⁻¹JᵀW`, `J = ∂P/∂(n, k)`, so
//!
//! ```text
//! Cov = Cov_noise + A Σ Aᵀ.
//! ```
//!
//! Near `k = 0`, where `∂P/∂k` vanishes, the covariance is formed in `(n, u = k²)`
//! (as the core fit does) and `k_se = √(k² + se_u) − k`.

use crate::CoreError;
use crate::dop::{dop, dop_beta_derivs, dop_grad};
use crate::error::check_len;
use crate::film::thin_film;
use crate::fit::inv2;

/// Indices `(n, k)` of the surface layers of the error model: silica-like, high-index
/// (TiO₂, NiO) and absorbing high-index oxides (Cu₂O, Fe₂O₃).
pub const FILM_INDICES: [(f64, f64); 3] = [(1.5, 0.0), (2.8, 0.0), (2.8, 0.3)];

/// Below this `k` the `(n, u = k²)` column `∂P/∂u` is taken by a secant.
const K_SECANT: f64 = 1e-4;

/// The polarimetric part of the systematic error model (per target).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Polarimetric {
    /// Additive DoLP error, standard deviation, independent per row (≥ 0).
    pub dolp_floor: f64,
    /// The lowest extinction ratio the analyzer may have (> 1; `f64::INFINITY`: ideal).
    pub extinction_ratio: f64,
    /// Largest retardance ahead of the analyzer, radians (≥ 0).
    pub retardance: f64,
    /// Standard thickness of an unmodelled surface layer, in wavelengths (≥ 0; 0: none).
    pub film_sd_waves: f64,
}

impl Polarimetric {
    /// Standard uncertainty of the relative DoLP scale:
    /// `u = 2/(ER + 1) + (1 − cos δ)`.
    pub fn scale_sd(&self) -> f64 {
        let ext = if self.extinction_ratio.is_finite() {
            2.0 / (self.extinction_ratio + 1.0)
        } else {
            0.0
        };
        ext + (1.0 - self.retardance.cos())
    }
}

/// Fill `out` (row-major `T × T`) with the systematic DoLP covariance `Σ` of the module
/// documentation at the estimate `(n, k)`: `betas` and `angle_sd` in radians, one per row.
///
/// Errors: [`CoreError::LengthMismatch`] when the lengths disagree.
pub fn systematic_covariance(
    n: f64,
    k: f64,
    betas: &[f64],
    angle_sd: &[f64],
    pol: &Polarimetric,
    out: &mut [f64],
) -> Result<(), CoreError> {
    let t_len = betas.len();
    check_len("angle_sd", angle_sd.len(), t_len)?;
    check_len("out", out.len(), t_len * t_len)?;
    let u = pol.scale_sd();
    let f2 = pol.dolp_floor * pol.dolp_floor;
    // a_t = P'_t σ_t / 2: the β-error of row t is half its direction errors.
    let (p, a): (Vec<f64>, Vec<f64>) = betas
        .iter()
        .zip(angle_sd)
        .map(|(&b, &s)| {
            let d = dop_beta_derivs(n, k, b);
            (d.p, 0.5 * d.dp_dbeta * s)
        })
        .unzip();
    // g_jt: the DoLP change of a film of thickness σ_d and index n_j.
    let films: Vec<Vec<f64>> = if pol.film_sd_waves > 0.0 {
        FILM_INDICES
            .iter()
            .map(|&film| {
                betas
                    .iter()
                    .zip(&p)
                    .map(|(&b, &pb)| {
                        thin_film(film, pol.film_sd_waves, (n, k), b, 1.0)
                            .map_or(0.0, |r| r.signed_dolp() - pb)
                    })
                    .collect()
            })
            .collect()
    } else {
        Vec::new()
    };
    for t in 0..t_len {
        for s in t..t_len {
            let mut v = a[t] * a[s] + u * u * (p[t] * p[s]);
            for g in &films {
                v += g[t] * g[s];
            }
            if t == s {
                v += f2 + a[t] * a[t];
            }
            out[t * t_len + s] = v;
            out[s * t_len + t] = v;
        }
    }
    Ok(())
}

/// The fit's sensitivity to a surface layer of the error model: for each
/// [`FILM_INDICES`] index `N_j`, the `(n, k)` shift `h_j = A g_j` that a layer of one
/// standard thickness `σ_d` makes in the fit (`g_j`: its DoLP change at the rows' β, as in
/// [`systematic_covariance`]; `A = (JᵀWJ)⁻¹JᵀW` the linearised fit, paper eq. 9),
/// `self.0[j] = [δn_j, δk_j]`.
///
/// The surface-layer part of the propagated covariance is `Σ_j h_j h_jᵀ`
/// ([`FilmShifts::block`]). A layer's thickness in nanometres is the same at every
/// wavelength, so the shifts of one target's bands (each at its own `σ_d = film_sd_nm/λ`)
/// are those of ONE layer: stacked over the bands they give the cross-band covariance
/// `Σ_j H_j H_jᵀ` that multi-band classification uses (docs/BANDS.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilmShifts(pub [[f64; 2]; 3]);

impl FilmShifts {
    /// `Σ_j h_j h_jᵀ` as `[nn, nk, kk]`: the layer's part of the fit's `(n, k)` covariance.
    pub fn block(&self) -> [f64; 3] {
        let mut c = [0.0; 3];
        for h in &self.0 {
            c[0] += h[0] * h[0];
            c[1] += h[0] * h[1];
            c[2] += h[1] * h[1];
        }
        c
    }

    /// Whether every shift is a finite number.
    pub fn is_finite(&self) -> bool {
        self.0.iter().flatten().all(|v| v.is_finite())
    }
}

/// The [`FilmShifts`] of a fit at `(n, k)` in the `(n, k)` parameterisation: `betas`
/// radians; `noise_se` the rows' standard errors when the fit was weighted by them
/// (`None`: unweighted, `W = I`). `None` when `pol.film_sd_waves` is 0 or `JᵀWJ` is
/// singular.
///
/// Errors: [`CoreError::LengthMismatch`].
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn film_shifts(
    n: f64,
    k: f64,
    betas: &[f64],
    noise_se: Option<&[f64]>,
    pol: &Polarimetric,
) -> Result<Option<FilmShifts>, CoreError> {
    let t_len = betas.len();
    if let Some(se) = noise_se {
        check_len("noise_se", se.len(), t_len)?;
    }
    if !(pol.film_sd_waves > 0.0) {
        return Ok(None);
    }
    let w: Vec<f64> = match noise_se {
        Some(se) => se.iter().map(|s| 1.0 / (s * s)).collect(),
        None => vec![1.0; t_len],
    };
    let grads: Vec<_> = betas.iter().map(|&b| dop_grad(n, k, b)).collect();
    let (mut h00, mut h01, mut h11) = (0.0, 0.0, 0.0);
    for (g, wt) in grads.iter().zip(&w) {
        h00 += wt * g.dp_dn * g.dp_dn;
        h01 += wt * g.dp_dn * g.dp_dk;
        h11 += wt * g.dp_dk * g.dp_dk;
    }
    let Some((i00, i01, i11)) = inv2(h00, h01, h11) else {
        return Ok(None);
    };
    let mut out = [[0.0; 2]; 3];
    for (j, &film) in FILM_INDICES.iter().enumerate() {
        let (mut bn, mut bk) = (0.0, 0.0);
        for ((&b, g), wt) in betas.iter().zip(&grads).zip(&w) {
            let gj = thin_film(film, pol.film_sd_waves, (n, k), b, 1.0)
                .map_or(0.0, |r| r.signed_dolp() - g.p);
            bn += wt * g.dp_dn * gj;
            bk += wt * g.dp_dk * gj;
        }
        out[j] = [i00 * bn + i01 * bk, i01 * bn + i11 * bk];
    }
    let f = FilmShifts(out);
    Ok(f.is_finite().then_some(f))
}

/// Standard errors and correlation of `(n, k)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NkCov {
    /// Standard error of `n`.
    pub n_se: f64,
    /// Standard error of `k` (one-sigma upper deviation when formed in `(n, k²)`).
    pub k_se: f64,
    /// Correlation of `n` and `k`.
    pub nk_corr: f64,
    /// True when the covariance was formed in `(n, u = k²)`.
    pub in_u: bool,
}

impl NkCov {
    fn nan() -> Self {
        Self {
            n_se: f64::NAN,
            k_se: f64::NAN,
            nk_corr: f64::NAN,
            in_u: false,
        }
    }
}

/// The result of [`propagate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Propagated {
    /// Noise plus systematic: `Cov_noise + A Σ Aᵀ`.
    pub total: NkCov,
    /// The systematic part alone, `A Σ Aᵀ` (same parameterisation as `total`).
    pub systematic: NkCov,
    /// The goodness of fit against the total variance (weighted fits only).
    pub gof: Option<Gof>,
}

/// χ² goodness of fit of the residuals against the total (noise + systematic)
/// covariance `V = diag(se²) + Σ`, after removing the fitted directions (generalised
/// least squares about the estimate):
/// `χ² = rᵀV⁻¹r − bᵀ(JᵀV⁻¹J)⁻¹b`, `b = JᵀV⁻¹r`, with `T − 2` degrees of freedom.
#[derive(Debug, Clone, PartialEq)]
pub struct Gof {
    /// The statistic.
    pub chi2: f64,
    /// Degrees of freedom (`T − 2`, or `T − 1` when `k` is not determined).
    pub dof: usize,
    /// `P(χ²_dof ≥ chi2)`.
    pub p_value: f64,
    /// Standardised residual of each row: its generalised-least-squares residual over
    /// that residual's standard deviation.
    pub z: Vec<f64>,
}

/// Propagate the systematic covariance `sys` (row-major `T × T`, from
/// [`systematic_covariance`]) through the fit at `(n, k)`.
///
/// `betas` radians; `residual` = measured (spread-corrected) DoLP − `P(n, k, β)`;
/// `noise_se`: the rows' standard errors when the fit was weighted by them (then the
/// noise covariance is `(JᵀWJ)⁻¹` and a [`Gof`] is computed), `None` for an unweighted
/// fit (noise covariance `s²(JᵀJ)⁻¹` with `s² = Σr²/(T − 2)`; no `Gof`). `k_can_be_zero`:
/// the search box reaches `k = 0` (then near it the covariance is formed in `(n, k²)`).
///
/// Errors: [`CoreError::LengthMismatch`], [`CoreError::TooFew`] (fewer than 3 rows).
pub fn propagate(
    n: f64,
    k: f64,
    betas: &[f64],
    residual: &[f64],
    noise_se: Option<&[f64]>,
    sys: &[f64],
    k_can_be_zero: bool,
) -> Result<Propagated, CoreError> {
    let t_len = betas.len();
    if t_len < 3 {
        return Err(CoreError::TooFew {
            what: "measurements",
            needed: 3,
            got: t_len,
        });
    }
    check_len("residual", residual.len(), t_len)?;
    check_len("sys", sys.len(), t_len * t_len)?;
    if let Some(se) = noise_se {
        check_len("noise_se", se.len(), t_len)?;
    }
    let w: Vec<f64> = match noise_se {
        Some(se) => se.iter().map(|s| 1.0 / (s * s)).collect(),
        None => vec![1.0; t_len],
    };
    let s2 = match noise_se {
        Some(_) => 1.0,
        None => residual.iter().map(|r| r * r).sum::<f64>() / (t_len as f64 - 2.0),
    };
    let grads: Vec<_> = betas.iter().map(|&b| dop_grad(n, k, b)).collect();
    let jn: Vec<f64> = grads.iter().map(|g| g.dp_dn).collect();
    let jk: Vec<f64> = grads.iter().map(|g| g.dp_dk).collect();
    let lin = sandwich(&jn, &jk, &w, s2, sys);
    let use_u = k_can_be_zero
        && match &lin {
            None => true,
            Some((tot, _, _)) => k < tot[2].sqrt(),
        };
    let (total, systematic, j2) = if use_u {
        let ju: Vec<f64> = if k >= K_SECANT {
            jk.iter().map(|d| d / (2.0 * k)).collect()
        } else {
            let du = 1e-6;
            let k1 = (k * k + du).sqrt();
            betas
                .iter()
                .zip(&grads)
                .map(|(&b, g)| (dop(n, k1, b) - g.p) / (k1 * k1 - k * k))
                .collect()
        };
        match sandwich(&jn, &ju, &w, s2, sys) {
            Some((tot, sy, _)) => (to_nk(&tot, k, true), to_nk(&sy, k, true), ju),
            None => (NkCov::nan(), NkCov::nan(), ju),
        }
    } else {
        match &lin {
            Some((tot, sy, _)) => (to_nk(tot, k, false), to_nk(sy, k, false), jk),
            None => (NkCov::nan(), NkCov::nan(), jk),
        }
    };
    let gof = noise_se.and_then(|se| {
        let mut v = sys.to_vec();
        for t in 0..t_len {
            v[t * t_len + t] += se[t] * se[t];
        }
        gls_gof(&v, &jn, &j2, residual)
    });
    Ok(Propagated {
        total,
        systematic,
        gof,
    })
}

/// `(total, systematic, (JᵀWJ)⁻¹)` as `[c00, c01, c11]` for the columns `j0`, `j1`.
#[allow(clippy::type_complexity)]
fn sandwich(
    j0: &[f64],
    j1: &[f64],
    w: &[f64],
    s2: f64,
    sys: &[f64],
) -> Option<([f64; 3], [f64; 3], [f64; 3])> {
    let t_len = j0.len();
    let (mut h00, mut h01, mut h11) = (0.0, 0.0, 0.0);
    for t in 0..t_len {
        h00 += w[t] * j0[t] * j0[t];
        h01 += w[t] * j0[t] * j1[t];
        h11 += w[t] * j1[t] * j1[t];
    }
    let (i00, i01, i11) = inv2(h00, h01, h11)?;
    // A = (JᵀWJ)⁻¹ JᵀW, rows a0, a1.
    let a0: Vec<f64> = (0..t_len)
        .map(|t| w[t] * (i00 * j0[t] + i01 * j1[t]))
        .collect();
    let a1: Vec<f64> = (0..t_len)
        .map(|t| w[t] * (i01 * j0[t] + i11 * j1[t]))
        .collect();
    let (mut c00, mut c01, mut c11) = (0.0, 0.0, 0.0);
    for t in 0..t_len {
        let row = &sys[t * t_len..(t + 1) * t_len];
        let (mut s0, mut s1) = (0.0, 0.0);
        for (s, &v) in row.iter().enumerate() {
            s0 += v * a0[s];
            s1 += v * a1[s];
        }
        c00 += a0[t] * s0;
        c01 += a0[t] * s1;
        c11 += a1[t] * s1;
    }
    let sy = [c00, c01, c11];
    let noise = [i00 * s2, i01 * s2, i11 * s2];
    Some((
        [noise[0] + sy[0], noise[1] + sy[1], noise[2] + sy[2]],
        sy,
        [i00, i01, i11],
    ))
}

/// Standard errors of a covariance `[c00, c01, c11]` in `(n, k)` or `(n, u = k²)`.
fn to_nk(c: &[f64; 3], k: f64, in_u: bool) -> NkCov {
    let n_se = c[0].max(0.0).sqrt();
    let se2 = c[2].max(0.0).sqrt();
    let k_se = if in_u { (k * k + se2).sqrt() - k } else { se2 };
    let den = (c[0] * c[2]).sqrt();
    NkCov {
        n_se,
        k_se,
        nk_corr: if den > 0.0 { c[1] / den } else { f64::NAN },
        in_u,
    }
}

/// The GLS goodness of fit of [`Gof`] with the total covariance `v` (row-major).
fn gls_gof(v: &[f64], j0: &[f64], j1: &[f64], r: &[f64]) -> Option<Gof> {
    let t_len = r.len();
    let l = cholesky(v, t_len)?;
    let rt = forward(&l, r, t_len);
    let a = forward(&l, j0, t_len);
    let b = forward(&l, j1, t_len);
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
    // Two fitted directions, or one when the second is not determined.
    let (h00, h01, h11) = (dot(&a, &a), dot(&a, &b), dot(&b, &b));
    let (g0, g1) = (dot(&a, &rt), dot(&b, &rt));
    let (delta, ginv, dof) = match inv2(h00, h01, h11) {
        Some((i00, i01, i11)) => (
            [i00 * g0 + i01 * g1, i01 * g0 + i11 * g1],
            [i00, i01, i11],
            t_len - 2,
        ),
        None if h00 > 0.0 => ([g0 / h00, 0.0], [1.0 / h00, 0.0, 0.0], t_len - 1),
        None => ([0.0, 0.0], [0.0; 3], t_len),
    };
    if dof == 0 {
        return None;
    }
    let chi2 = (dot(&rt, &rt) - (delta[0] * g0 + delta[1] * g1)).max(0.0);
    // Residual e = r − Jδ; Cov e = V − J G Jᵀ.
    let z = (0..t_len)
        .map(|t| {
            let e = r[t] - delta[0] * j0[t] - delta[1] * j1[t];
            let var = v[t * t_len + t]
                - (ginv[0] * j0[t] * j0[t]
                    + 2.0 * ginv[1] * j0[t] * j1[t]
                    + ginv[2] * j1[t] * j1[t]);
            if var > 1e-12 * v[t * t_len + t] {
                e / var.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    Some(Gof {
        chi2,
        dof,
        p_value: chi2_sf(chi2, dof as f64),
        z,
    })
}

/// Lower Cholesky factor of the symmetric `m × m` matrix `v` (row-major), or `None`
/// when it is not positive definite.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
#[inline]
pub(crate) fn cholesky(v: &[f64], m: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..=i {
            let mut s = v[i * m + j];
            for p in 0..j {
                s -= l[i * m + p] * l[j * m + p];
            }
            if i == j {
                if !(s > 0.0) || !s.is_finite() {
                    return None;
                }
                l[i * m + i] = s.sqrt();
            } else {
                l[i * m + j] = s / l[j * m + j];
            }
        }
    }
    Some(l)
}

/// Solve `L x = y` for lower-triangular `L`.
#[inline]
pub(crate) fn forward(l: &[f64], y: &[f64], m: usize) -> Vec<f64> {
    let mut x = vec![0.0; m];
    for i in 0..m {
        let mut s = y[i];
        for p in 0..i {
            s -= l[i * m + p] * x[p];
        }
        x[i] = s / l[i * m + i];
    }
    x
}

/// The survival function of the χ² distribution with `dof` degrees of freedom,
/// `P(X ≥ x) = Q(dof/2, x/2)` (regularised upper incomplete gamma function: series for
/// `x < a + 1`, Lentz's continued fraction otherwise; relative accuracy ~1e-12).
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    if x.is_nan() || dof.is_nan() || dof <= 0.0 {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    let a = 0.5 * dof;
    let x = 0.5 * x;
    let ln_pre = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        (1.0 - sum * ln_pre.exp()).clamp(0.0, 1.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (ln_pre.exp() * h).clamp(0.0, 1.0)
    }
}

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, 9 terms; ~1e-15 relative).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = G[0];
    let t = x + 7.5;
    for (i, g) in G.iter().enumerate().skip(1) {
        a += g / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The AoLP check of one row: the AoLP measured from the plane of incidence,
/// `aolp_poi` (radians, `[0, π)`), against the single interface's `π/2`.
///
/// Returns the deviation `d` wrapped into `(−π/2, π/2]` and its standard uncertainty
///
/// ```text
/// sd² = (se² + f²)/(2P)² + (σ / sin β)²
/// ```
///
/// (AoLP noise of a DoLP `P` with standard error `se` plus the floor `f` as a spurious
/// polarization, and the turn of the plane of incidence about the view ray for a
/// direction error `σ`), or `None` when `P ≤ 0` or `β ≤ 0`.
pub fn aolp_deviation(
    aolp_poi: f64,
    dolp: f64,
    dolp_se: f64,
    floor: f64,
    angle_sd: f64,
    beta: f64,
) -> Option<(f64, f64)> {
    if !(dolp > 0.0 && beta > 0.0 && aolp_poi.is_finite()) {
        return None;
    }
    let half = std::f64::consts::FRAC_PI_2;
    let pi = std::f64::consts::PI;
    let mut d = (aolp_poi - half).rem_euclid(pi);
    if d > half {
        d -= pi;
    }
    let pol = (dolp_se * dolp_se + floor * floor) / (4.0 * dolp * dolp);
    let geo = (angle_sd / beta.sin()).powi(2);
    Some((d, (pol + geo).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_sf_known_values() {
        // dof 2: exp(−x/2).
        for x in [0.1, 1.0, 5.0, 20.0] {
            assert!((chi2_sf(x, 2.0) - (-x / 2.0f64).exp()).abs() < 1e-13);
        }
        // dof 1: 3.841459 is the 95% quantile; dof 10: 18.307038.
        assert!((chi2_sf(3.841_458_820_694_124, 1.0) - 0.05).abs() < 1e-10);
        assert!((chi2_sf(18.307_038_053_275_146, 10.0) - 0.05).abs() < 1e-10);
        assert!((chi2_sf(29.588_298_445_074_43, 10.0) - 0.001).abs() < 1e-11);
        assert_eq!(chi2_sf(0.0, 3.0), 1.0);
    }

    #[test]
    fn aolp_deviation_wraps() {
        let (d, _) = aolp_deviation(0.0, 0.5, 0.01, 0.0, 0.0, 0.7).unwrap();
        assert!((d - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        let (d, sd) = aolp_deviation(1.6, 0.5, 0.01, 0.0, 0.0, 0.7).unwrap();
        assert!((d - (1.6 - std::f64::consts::FRAC_PI_2)).abs() < 1e-15);
        assert!((sd - 0.01).abs() < 1e-15);
        assert!(aolp_deviation(1.6, 0.0, 0.01, 0.0, 0.0, 0.7).is_none());
    }

    #[test]
    fn film_shifts_are_the_layer_part_of_the_propagated_covariance() {
        // Gold at 550 nm, the demo's eight β, only a 3 nm layer in the error model: the
        // propagated systematic covariance is Σ_j h_j h_jᵀ of the shifts.
        let betas: Vec<f64> = (0..8)
            .map(|i| (0.5 * (90.0 + 7.0 * i as f64)).to_radians())
            .collect();
        let se = vec![0.004; 8];
        let pol = Polarimetric {
            dolp_floor: 0.0,
            extinction_ratio: f64::INFINITY,
            retardance: 0.0,
            film_sd_waves: 3.0 / 550.0,
        };
        let (n, k) = (0.458, 2.462);
        let h = film_shifts(n, k, &betas, Some(&se), &pol).unwrap().unwrap();
        let mut sys = vec![0.0; 64];
        let zero = vec![0.0; 8];
        systematic_covariance(n, k, &betas, &zero, &pol, &mut sys).unwrap();
        let p = propagate(n, k, &betas, &zero, Some(&se), &sys, false).unwrap();
        let b = h.block();
        let s = p.systematic;
        assert!((b[0] - s.n_se * s.n_se).abs() < 1e-12 * b[0].max(1e-9));
        assert!((b[2] - s.k_se * s.k_se).abs() < 1e-10 * b[2]);
        assert!((b[1] - s.nk_corr * s.n_se * s.k_se).abs() < 1e-10 * (b[0] * b[2]).sqrt());
        // A layer lowers the fitted k of gold (every index) by 0.1-0.5 at 550 nm.
        for sh in h.0 {
            assert!(sh[1] < -0.1 && sh[1] > -0.5, "{sh:?}");
        }
        let none = Polarimetric {
            film_sd_waves: 0.0,
            ..pol
        };
        assert!(
            film_shifts(n, k, &betas, Some(&se), &none)
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn covariance_is_symmetric_and_has_its_parts() {
        let betas = [0.5, 0.7, 0.9];
        let sd = [1e-3, 2e-3, 3e-3];
        let pol = Polarimetric {
            dolp_floor: 0.002,
            extinction_ratio: 199.0,
            retardance: 0.0,
            film_sd_waves: 0.0,
        };
        let mut s = vec![0.0; 9];
        systematic_covariance(1.4, 2.0, &betas, &sd, &pol, &mut s).unwrap();
        let d: Vec<_> = betas
            .iter()
            .map(|&b| dop_beta_derivs(1.4, 2.0, b))
            .collect();
        for t in 0..3 {
            for u in 0..3 {
                assert_eq!(s[t * 3 + u], s[u * 3 + t]);
            }
        }
        let a = |t: usize| 0.5 * d[t].dp_dbeta * sd[t];
        let want01 = a(0) * a(1) + 0.01f64.powi(2) * (d[0].p * d[1].p);
        assert!((s[1] - want01).abs() < 1e-15);
        let want00 = 2.0 * a(0) * a(0) + 0.01f64.powi(2) * d[0].p * d[0].p + 4e-6;
        assert!((s[0] - want00).abs() < 1e-15);
        assert!(systematic_covariance(1.4, 2.0, &betas, &sd[..2], &pol, &mut s).is_err());
    }
}
