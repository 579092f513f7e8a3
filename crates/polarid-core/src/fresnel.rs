//! Fresnel reflection at the interface between air and a medium of complex index
//! `N = n + ik` (`k >= 0`), at the local incidence angle `β` — the `M` of the paper's
//! eq. (3) and (6).
//!
//! Conventions (those of NIST SCATMECH, used by `data/oracles/`):
//!
//! - `w = √(N² − sin²β)`, principal branch with `Im w >= 0` (`w = A + iB`, with `A`,
//!   `B` of eq. (12), (13)).
//! - `r_s = (cos β − w)/(cos β + w)` and `r_p = (N² cos β − w)/(N² cos β + w)` (Born &
//!   Wolf sign: each beam has a right-handed `{s, p, k}` basis, `p = k × s`, so that
//!   `r_p = −r_s` at normal incidence).
//! - Stokes vectors use `S1 = I_s − I_p`, `S2 = I(s+p) − I(s−p)` and `S3` such that
//!   the Mueller matrix of the Jones matrix `diag(r_s, r_p)` is
//!
//! ```text
//!       ⎡ (Rs+Rp)/2  (Rs−Rp)/2      0          0      ⎤
//!   M = ⎢ (Rs−Rp)/2  (Rs+Rp)/2      0          0      ⎥
//!       ⎢     0          0      Re(r_s r_p*)  Im(r_s r_p*) ⎥
//!       ⎣     0          0     −Im(r_s r_p*)  Re(r_s r_p*) ⎦
//! ```
//!
//! (SCATMECH's `MuellerMatrix(JonesMatrix)`). The paper neglects circular polarization
//! and uses the upper-left 3×3 block ([`Fresnel::mueller3`]).

use num_complex::Complex64;

/// Complex Fresnel reflection coefficients and reflectances at one angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fresnel {
    /// Amplitude reflection coefficient for s (TE) polarization.
    pub rs: Complex64,
    /// Amplitude reflection coefficient for p (TM) polarization, Born & Wolf sign.
    pub rp: Complex64,
    /// `Rs = |r_s|²`, in `[0, 1]`.
    pub rs2: f64,
    /// `Rp = |r_p|²`, in `[0, 1]`.
    pub rp2: f64,
}

/// `w = √(N² − sin²β) = A + iB` with `A, B >= 0`, computed without cancellation
/// (eq. 12–15): `D = n² − k² − sin²β`, `√C = |(D, 2nk)|`, and the smaller of `A`, `B`
/// from `A·B = nk`.
#[inline]
pub fn w_root(n: f64, k: f64, sin2_beta: f64) -> Complex64 {
    let d = n * n - k * k - sin2_beta; // eq. (15)
    let nk = n * k;
    let r = (2.0 * nk).hypot(d); // √C, eq. (14)
    if d >= 0.0 {
        let a = ((r + d) * 0.5).sqrt(); // eq. (12)
        let b = if a > 0.0 { nk / a } else { 0.0 };
        Complex64::new(a, b.abs())
    } else {
        let b = ((r - d) * 0.5).sqrt(); // eq. (13)
        let a = if b > 0.0 { nk / b } else { 0.0 };
        Complex64::new(a.abs(), b)
    }
}

impl Fresnel {
    /// Fresnel coefficients for `N = n + ik` (`k >= 0`) at incidence angle `beta`
    /// (radians, `[0, π/2]`).
    #[inline]
    pub fn new(n: f64, k: f64, beta: f64) -> Self {
        let (s, c) = beta.sin_cos();
        Self::from_sin_cos(n, k, s * s, c)
    }

    /// Same as [`Fresnel::new`] from `sin²β` and `cos β` (no trigonometry).
    #[inline]
    pub fn from_sin_cos(n: f64, k: f64, sin2_beta: f64, cos_beta: f64) -> Self {
        let w = w_root(n, k, sin2_beta);
        let cb = Complex64::new(cos_beta, 0.0);
        let n2 = Complex64::new(n * n - k * k, 2.0 * n * k);
        let n2c = n2 * cos_beta;
        let rs = ratio(cb - w, cb + w);
        let rp = ratio(n2c - w, n2c + w);
        Self {
            rs,
            rp,
            rs2: rs.norm_sqr().min(1.0),
            rp2: rp.norm_sqr().min(1.0),
        }
    }

    /// `(Rs + Rp)/2`: reflectance for unpolarized light (`m00`).
    #[inline]
    pub fn m00(&self) -> f64 {
        0.5 * (self.rs2 + self.rp2)
    }

    /// The 3×3 linear-polarization block of the Fresnel reflection Mueller matrix
    /// (SCATMECH convention, `S1 = I_s − I_p`), in the local facet (s, p) frame.
    #[inline]
    pub fn mueller3(&self) -> [[f64; 3]; 3] {
        let a = 0.5 * (self.rs2 + self.rp2);
        let b = 0.5 * (self.rs2 - self.rp2);
        let c = (self.rs * self.rp.conj()).re;
        [[a, b, 0.0], [b, a, 0.0], [0.0, 0.0, c]]
    }

    /// The full 4×4 Fresnel reflection Mueller matrix (SCATMECH convention:
    /// `m23 = Im(r_s r_p*) = −m32`).
    #[inline]
    pub fn mueller4(&self) -> [[f64; 4]; 4] {
        let a = 0.5 * (self.rs2 + self.rp2);
        let b = 0.5 * (self.rs2 - self.rp2);
        let z = self.rs * self.rp.conj();
        [
            [a, b, 0.0, 0.0],
            [b, a, 0.0, 0.0],
            [0.0, 0.0, z.re, z.im],
            [0.0, 0.0, -z.im, z.re],
        ]
    }
}

/// `num / den`, or `0` when both vanish (`N = 1` at normal incidence has no reflection;
/// a vanishing denominator cannot occur otherwise since `Re w >= 0`, `Re(N² cos β)`
/// and `cos β` are not both zero with the numerator non-zero).
#[inline]
fn ratio(num: Complex64, den: Complex64) -> Complex64 {
    if den.norm_sqr() > 0.0 {
        num / den
    } else {
        Complex64::new(0.0, 0.0)
    }
}

/// Fresnel amplitude coefficients `(r_s, r_p)` for `N = n + ik` at `beta` (radians).
#[inline]
pub fn amplitudes(n: f64, k: f64, beta: f64) -> (Complex64, Complex64) {
    let f = Fresnel::new(n, k, beta);
    (f.rs, f.rp)
}

/// Reflectances `(Rs, Rp)` for `N = n + ik` at `beta` (radians).
#[inline]
pub fn reflectances(n: f64, k: f64, beta: f64) -> (f64, f64) {
    let f = Fresnel::new(n, k, beta);
    (f.rs2, f.rp2)
}

/// The 3×3 linear block of the Fresnel reflection Mueller matrix at `beta` (radians).
#[inline]
pub fn mueller3(n: f64, k: f64, beta: f64) -> [[f64; 3]; 3] {
    Fresnel::new(n, k, beta).mueller3()
}

/// The full 4×4 Fresnel reflection Mueller matrix at `beta` (radians).
#[inline]
pub fn mueller4(n: f64, k: f64, beta: f64) -> [[f64; 4]; 4] {
    Fresnel::new(n, k, beta).mueller4()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_signs() {
        let f = Fresnel::new(1.5, 0.0, 0.0);
        assert!((f.rs.re + 0.2).abs() < 1e-15, "{:?}", f.rs);
        assert!((f.rp.re - 0.2).abs() < 1e-15, "{:?}", f.rp);
        let m = f.mueller3();
        assert!((m[2][2] + 0.04).abs() < 1e-15);
        assert!(m[0][1].abs() < 1e-16);
    }

    #[test]
    fn brewster_rp_vanishes() {
        let n: f64 = 1.5;
        let f = Fresnel::new(n, 0.0, n.atan());
        assert!(f.rp2 < 1e-30, "{}", f.rp2);
    }

    #[test]
    fn total_reflection() {
        let f = Fresnel::new(0.5, 0.0, 60f64.to_radians());
        assert!((f.rs2 - 1.0).abs() < 1e-14 && (f.rp2 - 1.0).abs() < 1e-14);
        let w = w_root(0.5, 0.0, 0.75);
        assert!(w.im > 0.0 && w.re == 0.0);
    }

    #[test]
    fn grazing_is_total() {
        let f = Fresnel::new(2.0, 3.0, std::f64::consts::FRAC_PI_2);
        assert!((f.rs2 - 1.0).abs() < 1e-12 && (f.rp2 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn root_matches_complex_sqrt() {
        for &(n, k, s2) in &[
            (1.5, 0.3, 0.2),
            (0.2, 4.0, 0.9),
            (0.5, 0.0, 0.3),
            (3.0, 0.0, 0.5),
        ] {
            let w = w_root(n, k, s2);
            let z = (Complex64::new(n, k) * Complex64::new(n, k) - s2).sqrt();
            assert!((w - z).norm() < 1e-14, "{w} {z}");
        }
    }
}
