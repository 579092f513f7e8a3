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

/// Intermediate quantities shared by the value and the gradient.
struct Parts {
    /// `A = Re √(N² − sin²β)`.
    a: f64,
    /// `c²√C + s⁴`, the denominator of eq. (9).
    q: f64,
}

#[inline(always)]
fn parts(n: f64, k: f64, t: &BetaTerms) -> Parts {
    let d = n * n - k * k - t.s2; // eq. (15)
    let two_nk = 2.0 * n * k;
    let r = two_nk.hypot(d); // √C, eq. (14)
    let a = if d >= 0.0 {
        ((r + d) * 0.5).sqrt() // eq. (12)
    } else {
        // (√C + D)/2 = n²k² / ((√C − D)/2): no cancellation when D < 0.
        let b = ((r - d) * 0.5).sqrt(); // eq. (13)
        if b > 0.0 { n * k / b } else { 0.0 }
    };
    let q = t.c2 * r + t.s4;
    Parts { a, q }
}

/// Degree of linear polarization `P(n, k, β)` of eq. (9), using precomputed β terms.
///
/// Returns a value in `[0, 1]` (`P = 1` at Brewster's angle for `k = 0`, `P = 0` at
/// `β = 0`, `β = 90°` and under total reflection). `N = 1` exactly is a removable
/// singularity of `(Rs − Rp)/(Rs + Rp)`; eq. (9) returns its limit along `k = 0`.
#[inline]
pub fn dop_terms(n: f64, k: f64, t: &BetaTerms) -> f64 {
    let Parts { a, q, .. } = parts(n, k, t);
    if q > 0.0 {
        (2.0 * a * t.s2 * t.c / q).clamp(0.0, 1.0)
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
/// With `u = n² + k² − s²`, `v = n² + k² + s²`, `R = √C`:
///
/// ```text
/// ∂R/∂n = 2n u / R            ∂R/∂k = 2k v / R
/// ∂A/∂n = n (R + u) / (2AR)   ∂A/∂k = k (v − R) / (2AR)
/// ∂P/∂x = 2s²c (∂A/∂x · Q − A c² ∂R/∂x) / Q²,   Q = c²R + s⁴
/// ```
///
/// where `R + u` and `v − R` are evaluated as `4k²s²/(R − u)` (when `u < 0`) and
/// `4n²s²/(v + R)`, and the `A` derivatives through `A = nk/B` when `D < 0`, so that
/// nothing cancels. At the critical angle of a transparent medium (`k = 0`,
/// `n = sin β` exactly) the derivative in `n` is unbounded; zeros are returned there.
#[inline]
pub fn dop_grad_terms(n: f64, k: f64, t: &BetaTerms) -> DopGrad {
    let d = n * n - k * k - t.s2;
    let nn_kk = n * n + k * k;
    let u = nn_kk - t.s2;
    let v = nn_kk + t.s2;
    let r = (2.0 * n * k).hypot(d);
    let q = t.c2 * r + t.s4;
    if !(r > 0.0) || !(q > 0.0) {
        // N² = sin²β exactly (critical angle of a transparent medium): P = 0 and the
        // gradient is unbounded.
        return DopGrad {
            p: 0.0,
            dp_dn: 0.0,
            dp_dk: 0.0,
        };
    }
    // R + u without cancellation.
    let r_plus_u = if u >= 0.0 {
        r + u
    } else {
        4.0 * k * k * t.s2 / (r - u)
    };
    // v − R without cancellation.
    let v_minus_r = 4.0 * n * n * t.s2 / (v + r);
    let (a, da_dn, da_dk) = if d >= 0.0 {
        let a = ((r + d) * 0.5).sqrt();
        let inv = 1.0 / (2.0 * a * r);
        (a, n * r_plus_u * inv, k * v_minus_r * inv)
    } else {
        let b = ((r - d) * 0.5).sqrt();
        let a = n * k / b;
        // ∂A/∂n = n(R+u)/(2AR) with A = nk/B:
        let da_dn = if u >= 0.0 {
            // here k² ≥ |D|/2 > 0
            r_plus_u * b / (2.0 * k * r)
        } else {
            2.0 * k * t.s2 * b / ((r - u) * r)
        };
        // ∂A/∂k = k(v−R)/(2AR) = (v−R)B/(2nR) = 2n s² B / ((v+R) R)
        let da_dk = 2.0 * n * t.s2 * b / ((v + r) * r);
        (a, da_dn, da_dk)
    };
    let dr_dn = 2.0 * n * u / r;
    let dr_dk = 2.0 * k * v / r;
    let num = 2.0 * t.s2 * t.c;
    let inv_q = 1.0 / q;
    let p = num * a * inv_q;
    let ac2 = a * t.c2;
    let dp_dn = num * (da_dn * q - ac2 * dr_dn) * inv_q * inv_q;
    let dp_dk = num * (da_dk * q - ac2 * dr_dk) * inv_q * inv_q;
    DopGrad {
        p: p.clamp(0.0, 1.0),
        dp_dn,
        dp_dk,
    }
}

/// `P(n, k, β)` of eq. (9) and its gradient; `beta` in radians.
#[inline]
pub fn dop_grad(n: f64, k: f64, beta: f64) -> DopGrad {
    dop_grad_terms(n, k, &BetaTerms::new(beta))
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
