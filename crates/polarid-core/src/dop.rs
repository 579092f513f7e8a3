//! Degree of linear polarization of specular Fresnel reflection, paper eq. (9)–(15),
//! with analytic derivatives with respect to `n` and `k`.
//!
//! For unpolarized light specularly reflected by a medium of complex index
//! `N = n + ik` (`k >= 0`) at local incidence angle `β`,
//!
//! ```text
//!            2 A sin²β cos β
//! P = ─────────────────────────────────────      (eq. 9)
//!      A² cos²β + sin⁴β + B² cos²β
//!
//! A = √((√C + D)/2)   (eq. 12)      B = √((√C − D)/2)   (eq. 13)
//! C = 4n²k² + D²      (eq. 14)      D = n² − k² − sin²β (eq. 15)
//! ```
//!
//! `A + iB = √(N² − sin²β)`, so `A² + B² = √C` and `A·B = nk`. This module evaluates
//! eq. (9) as `P = 2A s²c / (c²√C + s⁴)` (`s = sin β`, `c = cos β`), taking `A`
//! from whichever of eq. (12) or `A = nk/B` (with eq. 13) has no cancellation, and the
//! derivatives from forms free of `0/0`, so the value and gradient are accurate near
//! index matching (`N ≈ 1`), at Brewster's angle, at `β → 0` and `β → 90°`, for
//! `n < 1` (total reflection, `P = 0`) and for large `k`.
//!
//! `P` equals `(Rs − Rp)/(Rs + Rp)` from the Fresnel amplitudes of
//! [`crate::fresnel`], and `+m10/m00` of the Fresnel Mueller matrix (SCATMECH sign,
//! `S1 = I_s − I_p`).

/// The β-dependent terms of eq. (9), precomputed once per source position so that
/// repeated evaluations (the fit's inner loop) cost no trigonometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BetaTerms {
    /// `sin²β`.
    pub s2: f64,
    /// `cos β`.
    pub c: f64,
    /// `cos²β`.
    pub c2: f64,
    /// `sin⁴β`.
    pub s4: f64,
}

impl BetaTerms {
    /// Terms for the local incidence angle `beta` (radians, in `[0, π/2]`).
    #[inline]
    pub fn new(beta: f64) -> Self {
        let (s, c) = beta.sin_cos();
        let s2 = s * s;
        Self {
            s2,
            c,
            c2: c * c,
            s4: s2 * s2,
        }
    }
}

/// Value and gradient of the degree of polarization.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DopGrad {
    /// `P(n, k, β)`, eq. (9), in `[0, 1]`.
    pub p: f64,
    /// `∂P/∂n`.
    pub dp_dn: f64,
    /// `∂P/∂k`.
    pub dp_dk: f64,
}

/// `√(x² + y²)`: the plain form where no intermediate can overflow or underflow
/// (every physical input), `hypot` otherwise. The plain form is ~3× cheaper and
/// accurate to 1 ulp.
#[inline(always)]
fn norm2(x: f64, y: f64) -> f64 {
    let s = x * x + y * y;
    if s > 1e-290 && s < 1e290 {
        s.sqrt()
    } else {
        x.hypot(y)
    }
}

/// Intermediate quantities shared by the value and the gradient.
struct Parts {
    /// `A = Re √(N² − sin²β)` (eq. 12).
    a: f64,
    /// `B = Im √(N² − sin²β)` (eq. 13).
    b: f64,
    /// `R = √C` (eq. 14) `= A² + B²`.
    r: f64,
    /// `c²R + s⁴`, the denominator of eq. (9).
    q: f64,
}

/// `A`, `B`, `√C` and the denominator of eq. (9) without cancellation and without
/// data-dependent branches: the larger of `A`, `B` is `ρ = √((√C + |D|)/2)` (eq. 12 or
/// 13, whichever adds two non-negative terms) and the smaller is `nk/ρ` (`AB = nk`).
#[inline(always)]
fn parts(n: f64, k: f64, t: &BetaTerms) -> Parts {
    let d = n * n - k * k - t.s2; // eq. (15)
    let nk = n * k;
    let r = norm2(2.0 * nk, d); // √C, eq. (14)
    let rho = ((r + d.abs()) * 0.5).sqrt();
    let small = if rho > 0.0 { nk / rho } else { 0.0 };
    let (a, b) = if d >= 0.0 { (rho, small) } else { (small, rho) };
    let q = t.c2 * r + t.s4;
    Parts { a, b, r, q }
}

/// `P = 2xy/Q` with `x = cA`, `y = s²`, `Q = c²√C + s⁴ = x² + y² + (cB)²`, evaluated
/// as `1 − ((x − y)² + (cB)²)/Q` where `P > 1/2`, so that `P = 1` exactly at
/// Brewster's angle for `k = 0` (instead of `1 − ulp`). Clamped to `[0, 1]`.
#[inline(always)]
fn p_value(a: f64, b: f64, t: &BetaTerms, inv_q: f64) -> f64 {
    let x = t.c * a;
    let p = 2.0 * x * t.s2 * inv_q;
    let e = x - t.s2;
    let cb = t.c * b;
    let p_hi = 1.0 - (e * e + cb * cb) * inv_q;
    // Branch-free select (P > 1/2 is unpredictable in a fit); exact: for m = 1,
    // p_hi − p is exact (Sterbenz) and p + (p_hi − p) = p_hi.
    let m = f64::from(u8::from(p > 0.5));
    (p + m * (p_hi - p)).clamp(0.0, 1.0)
}

/// Degree of linear polarization `P(n, k, β)` of eq. (9), using precomputed β terms.
///
/// Returns a value in `[0, 1]` (`P = 1` at Brewster's angle for `k = 0`, `P = 0` at
/// `β = 0`, `β = 90°` and under total reflection). `N = 1` exactly is a removable
/// singularity of `(Rs − Rp)/(Rs + Rp)`; eq. (9) returns its limit along `k = 0`.
#[inline]
pub fn dop_terms(n: f64, k: f64, t: &BetaTerms) -> f64 {
    let Parts { a, b, q, .. } = parts(n, k, t);
    if q > 0.0 {
        p_value(a, b, t, 1.0 / q)
    } else {
        0.0
    }
}

/// Degree of linear polarization `P(n, k, β)` of eq. (9); `beta` in radians.
#[inline]
pub fn dop(n: f64, k: f64, beta: f64) -> f64 {
    dop_terms(n, k, &BetaTerms::new(beta))
}

/// `P` of eq. (9) and its analytic partial derivatives `∂P/∂n`, `∂P/∂k`.
///
/// With `R = √C = A² + B²`, `u = n² + k² − s²`, `v = n² + k² + s²`, differentiating
/// `A² − B² = D`, `AB = nk` gives
///
/// ```text
/// ∂A/∂n = (nA + kB) / R          ∂A/∂k = (nB − kA) / R = 2n s² B / (R (v + R))
/// ∂R/∂n = 2n u / R               ∂R/∂k = 2k v / R
/// ∂P/∂x = 2s²c (∂A/∂x · Q − A c² ∂R/∂x) / Q²,   Q = c²R + s⁴
/// ```
///
/// Every form used adds non-negative terms (`(v − R)(v + R) = 4n²s²`), so nothing
/// cancels near index matching, at `β → 0`, for large `k` or under total reflection,
/// and there is no data-dependent branch. At the critical angle of a transparent
/// medium (`k = 0`, `n = sin β` exactly, `R = 0`) the derivative in `n` is unbounded;
/// `P = 0` and zero derivatives are returned there.
#[inline]
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn dop_grad_terms(n: f64, k: f64, t: &BetaTerms) -> DopGrad {
    let Parts { a, b, r, q } = parts(n, k, t);
    if !(r > 0.0) || !(q > 0.0) {
        // N² = sin²β exactly (critical angle of a transparent medium): P = 0 and the
        // gradient is unbounded.
        return DopGrad {
            p: 0.0,
            dp_dn: 0.0,
            dp_dk: 0.0,
        };
    }
    let nn_kk = n * n + k * k;
    let u = nn_kk - t.s2;
    let v = nn_kk + t.s2;
    let inv_r = 1.0 / r;
    let da_dn = (n * a + k * b) * inv_r;
    let da_dk = 2.0 * n * t.s2 * b * inv_r / (v + r);
    let dr_dn = 2.0 * n * u * inv_r;
    let dr_dk = 2.0 * k * v * inv_r;
    let num = 2.0 * t.s2 * t.c;
    let inv_q = 1.0 / q;
    let p = p_value(a, b, t, inv_q);
    let ac2 = a * t.c2;
    let f = num * inv_q * inv_q;
    DopGrad {
        p,
        dp_dn: f * (da_dn * q - ac2 * dr_dn),
        dp_dk: f * (da_dk * q - ac2 * dr_dk),
    }
}

/// `P(n, k, β)` of eq. (9) and its gradient; `beta` in radians.
#[inline]
pub fn dop_grad(n: f64, k: f64, beta: f64) -> DopGrad {
    dop_grad_terms(n, k, &BetaTerms::new(beta))
}

/// `P(β)` of eq. (9) and its first two derivatives with respect to the incidence angle
/// `β` (radians), at fixed `n`, `k`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DopBetaDerivs {
    /// `P(n, k, β)`, eq. (9).
    pub p: f64,
    /// `∂P/∂β`, per radian.
    pub dp_dbeta: f64,
    /// `∂²P/∂β²`, per radian².
    pub d2p_dbeta2: f64,
}

/// `P(n, k, β)` of eq. (9) with its analytic first and second derivatives in `β`
/// (radians).
///
/// Used for the region forward model `E_w[P(β)] ≈ P(β̄) + ½ P''(β̄) s_β²` of a region
/// whose pixels see different `β` (docs/GEOMETRY.md). With `s = sin β`, `c = cos β`,
/// `t = s²` (so `t' = 2sc`, `t'' = 2(c² − s²)`), eq. (12)–(15) give, writing
/// `R = √C = A² + B²`,
///
/// ```text
/// dR/dt = −D/R            d²R/dt² = 4n²k²/R³
/// dA/dt = −A/(2R)         d²A/dt² = A (R − 2D)/(4R³)
/// ```
///
/// and eq. (9) is `P = 2 f A / Q` with `f = s²c` (`f' = s(2c² − s²)`,
/// `f'' = c(2c² − 7s²)`) and `Q = c²R + s⁴`; the quotient rule then gives
/// `P' = (N' − P Q')/Q` and `P'' = (N'' − 2P'Q' − P Q'')/Q` with `N = 2fA`.
///
/// Where `R = 0` (the critical angle of a transparent medium, `k = 0`, `n = sin β`,
/// at which the derivatives are unbounded) `P = 0` and zero derivatives are returned,
/// as [`dop_grad`] does. Under total reflection (`k = 0`, `sin β > n`) `P = 0` and its
/// derivatives are 0.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn dop_beta_derivs(n: f64, k: f64, beta: f64) -> DopBetaDerivs {
    let t = BetaTerms::new(beta);
    let Parts { a, b, r, q } = parts(n, k, &t);
    if !(r > 0.0) || !(q > 0.0) {
        return DopBetaDerivs::default();
    }
    let p = p_value(a, b, &t, 1.0 / q);
    let (s, c) = beta.sin_cos();
    let (s2, c2) = (t.s2, t.c2);
    let d = n * n - k * k - s2; // eq. (15)
    let nk2 = 4.0 * (n * k) * (n * k);
    let sc = s * c;
    let cos2 = c2 - s2;
    let r3 = r * r * r;
    // A(β) and R(β) by the chain rule through t = sin²β.
    let da = -a * sc / r;
    let d2a = a * (r - 2.0 * d) * s2 * c2 / r3 - a * cos2 / r;
    let dr = -2.0 * sc * d / r;
    let d2r = 16.0 * nk2 * s2 * c2 / (4.0 * r3) - 2.0 * d * cos2 / r;
    // Q = c²R + s⁴.
    let dq = -2.0 * sc * r + c2 * dr + 4.0 * s2 * sc;
    let d2q = -2.0 * cos2 * r - 4.0 * sc * dr + c2 * d2r + 12.0 * s2 * c2 - 4.0 * s2 * s2;
    // N = 2 f A, f = s²c.
    let f = s2 * c;
    let df = s * (2.0 * c2 - s2);
    let d2f = c * (2.0 * c2 - 7.0 * s2);
    let dn = 2.0 * (df * a + f * da);
    let d2n = 2.0 * (d2f * a + 2.0 * df * da + f * d2a);
    let dp = (dn - p * dq) / q;
    let d2p = (d2n - 2.0 * dp * dq - p * d2q) / q;
    DopBetaDerivs {
        p,
        dp_dbeta: dp,
        d2p_dbeta2: d2p,
    }
}

/// The mean of `P` over pixels whose `β` has weighted mean `beta` and weighted standard
/// deviation `beta_sd` (radians), to second order:
/// `E_w[P(β)] ≈ P(β̄) + ½ P''(β̄) s_β²` (the first-order term vanishes because `β̄` is
/// the weighted mean). `beta_sd = 0` gives `P(β̄)` of eq. (9) exactly. The truncation
/// error is of order `P⁽³⁾ m₃/6 + P⁽⁴⁾ m₄/24` (third and fourth central moments of β;
/// docs/GEOMETRY.md quantifies it).
pub fn dop_spread(n: f64, k: f64, beta: f64, beta_sd: f64) -> f64 {
    if beta_sd == 0.0 {
        return dop(n, k, beta);
    }
    let d = dop_beta_derivs(n, k, beta);
    d.p + 0.5 * d.d2p_dbeta2 * beta_sd * beta_sd
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn brewster_is_one() {
        for &n in &[1.2, 1.5, 2.0, 3.0] {
            let p = dop(n, 0.0, f64::atan(n));
            assert!((p - 1.0).abs() < 1e-14, "n={n} p={p}");
        }
    }

    #[test]
    fn grad_matches_finite_differences_spot() {
        for &(n, k, bd) in &[
            (1.5, 0.0, 40.0),
            (0.4, 2.95, 60.0),
            (1.24, 6.6, 70.0),
            (0.3, 0.1, 50.0),
        ] {
            let b = f64::to_radians(bd);
            let g = dop_grad(n, k, b);
            let h = 1e-6;
            let fdn = (dop(n + h, k, b) - dop(n - h, k, b)) / (2.0 * h);
            let fdk = (dop(n, k + h, b) - dop(n, (k - h).max(0.0), b)) / (h + h.min(k));
            assert!(
                (g.dp_dn - fdn).abs() < 1e-6,
                "{n} {k} {bd}: {} vs {}",
                g.dp_dn,
                fdn
            );
            assert!(
                (g.dp_dk - fdk).abs() < 1e-6,
                "{n} {k} {bd}: {} vs {}",
                g.dp_dk,
                fdk
            );
            assert!((g.p - dop(n, k, b)).abs() < 1e-15);
        }
    }
}
