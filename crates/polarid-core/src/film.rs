//! Reflection by layered surfaces: a thin film on a substrate (coherent, single-layer
//! interference) and a thick clear coat (incoherent multiple reflections). Used by the
//! simulator of real-world imperfections ([`crate::simulate::imperfect`]); the fit's
//! model remains the single interface of the paper (eq. 9).
//!
//! Conventions are those of [`crate::fresnel`]: ambient air (`N0 = 1`), `N = n + ik`
//! with `k ≥ 0`, fields `exp(i(kz − ωt))`, Born & Wolf sign of `r_p`. With the
//! tangential invariant `sin β` (Snell), each medium `j` has the normal component
//! `q_j = N_j cos θ_j = √(N_j² − sin²β)` (principal branch, `Im q ≥ 0`), and the
//! interface from medium `a` to medium `b` reflects
//!
//! ```text
//! r_s,ab = (q_a − q_b)/(q_a + q_b),     r_p,ab = (N_b² q_a − N_a² q_b)/(N_b² q_a + N_a² q_b)
//! ```
//!
//! (for `a` = air these are exactly [`Fresnel::new`](crate::fresnel::Fresnel::new)'s).
//!
//! # Thin film (coherent)
//! A film of index `N1` and thickness `d` on a substrate `N2`, at vacuum wavelength `λ`:
//! summing the multiply-reflected waves (Airy summation; Born & Wolf, *Principles of
//! Optics*, 7th ed., §1.6.4 eq. (58); Azzam & Bashara, *Ellipsometry and Polarized
//! Light*, eq. (4.37)),
//!
//! ```text
//! r = (r01 + r12 e^{2iδ}) / (1 + r01 r12 e^{2iδ}),     δ = 2π d q1 / λ
//! ```
//!
//! for s and p separately. `d = 0` gives the bare substrate (`(r01 + r12)/(1 + r01 r12)
//! = r02`), a quarter-wave film of index `√N2` at normal incidence reflects nothing.
//!
//! # Clear coat (incoherent)
//! A dielectric layer much thicker than the coherence length (a lacquer of tens of µm):
//! the phases average out and the reflectances add (Born & Wolf §1.6; the incoherent
//! limit of the Airy sum), for each polarization,
//!
//! ```text
//! R = R01 + T01² R12 τ² / (1 − R01 R12 τ²),    T01 = 1 − R01,    τ = exp(−α d / cos θ1)
//! ```
//!
//! with `R10 = R01` and `T10 = T01` (reciprocity; a non-absorbing top interface) and `τ`
//! the single-pass transmission of the layer (1 for a clear coat).
//!
//! For unpolarized incident light the reflected light is partially polarized along `s`
//! or `p` only (the Jones matrix is diagonal in the s/p basis):
//! `DoLP = (Rs − Rp)/(Rs + Rp)` signed — positive: perpendicular to the plane of
//! incidence (AoLP 90° from it, as a single interface always gives, eq. 9); negative:
//! parallel (AoLP 0°).

use num_complex::Complex64;

use crate::error::{CoreError, Result};

/// Reflection of an unpolarized beam by a layered surface at one angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerReflection {
    /// Amplitude reflection for s (NaN for incoherent stacks, which have none).
    pub rs: Complex64,
    /// Amplitude reflection for p, Born & Wolf sign (NaN for incoherent stacks).
    pub rp: Complex64,
    /// `Rs`.
    pub rs2: f64,
    /// `Rp`.
    pub rp2: f64,
}

impl LayerReflection {
    /// `m00 = (Rs + Rp)/2`: the reflectance of unpolarized light.
    pub fn m00(&self) -> f64 {
        0.5 * (self.rs2 + self.rp2)
    }

    /// Signed DoLP `(Rs − Rp)/(Rs + Rp)`: > 0 perpendicular to the plane of incidence,
    /// < 0 parallel (0 when nothing is reflected).
    pub fn signed_dolp(&self) -> f64 {
        let s = self.rs2 + self.rp2;
        if s > 0.0 {
            (self.rs2 - self.rp2) / s
        } else {
            0.0
        }
    }
}

/// `q = √(N² − sin²β)` with `Im q ≥ 0` (and `Re q ≥ 0` when `Im q = 0`).
fn q_of(nn: Complex64, sin2: f64) -> Complex64 {
    let q = (nn * nn - sin2).sqrt();
    if q.im < 0.0 || (q.im == 0.0 && q.re < 0.0) {
        -q
    } else {
        q
    }
}

/// `(r_s, r_p)` of the interface from `(na, qa)` to `(nb, qb)` (module documentation).
fn interface(na: Complex64, qa: Complex64, nb: Complex64, qb: Complex64) -> (Complex64, Complex64) {
    let rs = (qa - qb) / (qa + qb);
    let (a2, b2) = (na * na, nb * nb);
    let rp = (b2 * qa - a2 * qb) / (b2 * qa + a2 * qb);
    (rs, rp)
}

fn check_index(name: &'static str, n: f64, k: f64) -> Result<()> {
    if !(n.is_finite() && n > 0.0) {
        return Err(CoreError::OutOfRange {
            name,
            value: n,
            expected: "a finite real part > 0",
        });
    }
    if !(k.is_finite() && k >= 0.0) {
        return Err(CoreError::OutOfRange {
            name,
            value: k,
            expected: "a finite imaginary part >= 0",
        });
    }
    Ok(())
}

fn check_beta(beta: f64) -> Result<()> {
    if !(beta.is_finite() && (0.0..std::f64::consts::FRAC_PI_2).contains(&beta)) {
        return Err(CoreError::OutOfRange {
            name: "beta",
            value: beta,
            expected: "[0, pi/2) radians",
        });
    }
    Ok(())
}

/// A thin film of index `film = (n1, k1)` and thickness `thickness` on a substrate
/// `substrate = (n2, k2)`, at incidence `beta` (radians) from air and vacuum wavelength
/// `wavelength` (same unit as `thickness`): the Airy sum of the module documentation.
///
/// Errors: [`CoreError::OutOfRange`] for a non-finite or negative index part, thickness
/// or wavelength, or `beta` outside `[0, π/2)`.
pub fn thin_film(
    film: (f64, f64),
    thickness: f64,
    substrate: (f64, f64),
    beta: f64,
    wavelength: f64,
) -> Result<LayerReflection> {
    check_index("film index", film.0, film.1)?;
    check_index("substrate index", substrate.0, substrate.1)?;
    check_beta(beta)?;
    if !(thickness.is_finite() && thickness >= 0.0) {
        return Err(CoreError::OutOfRange {
            name: "thickness",
            value: thickness,
            expected: "finite and >= 0",
        });
    }
    if !(wavelength.is_finite() && wavelength > 0.0) {
        return Err(CoreError::OutOfRange {
            name: "wavelength",
            value: wavelength,
            expected: "finite and > 0",
        });
    }
    let sin2 = beta.sin().powi(2);
    let n0 = Complex64::new(1.0, 0.0);
    let n1 = Complex64::new(film.0, film.1);
    let n2 = Complex64::new(substrate.0, substrate.1);
    let (q0, q1, q2) = (q_of(n0, sin2), q_of(n1, sin2), q_of(n2, sin2));
    let (rs01, rp01) = interface(n0, q0, n1, q1);
    let (rs12, rp12) = interface(n1, q1, n2, q2);
    // e^{2iδ}, δ = 2π d q1/λ (eq. 58 of Born & Wolf §1.6.4).
    let two_delta = q1 * (4.0 * std::f64::consts::PI * thickness / wavelength);
    let ph = (Complex64::new(0.0, 1.0) * two_delta).exp();
    let airy = |r01: Complex64, r12: Complex64| (r01 + r12 * ph) / (1.0 + r01 * r12 * ph);
    let rs = airy(rs01, rs12);
    let rp = airy(rp01, rp12);
    Ok(LayerReflection {
        rs,
        rp,
        rs2: rs.norm_sqr().min(1.0),
        rp2: rp.norm_sqr().min(1.0),
    })
}

/// A thick, non-absorbing clear coat of real index `coat` on a substrate `(n2, k2)` at
/// incidence `beta` (radians) from air: the incoherent sum of the module documentation
/// (`τ = 1`). `rs`, `rp` are NaN (no phase survives).
///
/// Errors: [`CoreError::OutOfRange`] for a bad index or `beta`.
pub fn clear_coat(coat: f64, substrate: (f64, f64), beta: f64) -> Result<LayerReflection> {
    check_index("coat index", coat, 0.0)?;
    check_index("substrate index", substrate.0, substrate.1)?;
    check_beta(beta)?;
    let sin2 = beta.sin().powi(2);
    let n0 = Complex64::new(1.0, 0.0);
    let n1 = Complex64::new(coat, 0.0);
    let n2 = Complex64::new(substrate.0, substrate.1);
    let (q0, q1, q2) = (q_of(n0, sin2), q_of(n1, sin2), q_of(n2, sin2));
    let (rs01, rp01) = interface(n0, q0, n1, q1);
    let (rs12, rp12) = interface(n1, q1, n2, q2);
    let sum = |r01: Complex64, r12: Complex64| {
        let (a, b) = (r01.norm_sqr(), r12.norm_sqr());
        let t = 1.0 - a;
        a + t * t * b / (1.0 - a * b)
    };
    let nan = Complex64::new(f64::NAN, f64::NAN);
    Ok(LayerReflection {
        rs: nan,
        rp: nan,
        rs2: sum(rs01, rs12).min(1.0),
        rp2: sum(rp01, rp12).min(1.0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dop::dop;
    use crate::fresnel::Fresnel;

    /// Independent check: Born & Wolf's characteristic matrix of a homogeneous layer
    /// (§1.6.2 eq. (29)–(35)), with `p_j = q_j` (s) or `q_j/N_j²` (p).
    fn char_matrix(
        film: Complex64,
        d: f64,
        sub: Complex64,
        beta: f64,
        lam: f64,
    ) -> (Complex64, Complex64) {
        let sin2 = beta.sin().powi(2);
        let n0 = Complex64::new(1.0, 0.0);
        let (q0, q1, q2) = (q_of(n0, sin2), q_of(film, sin2), q_of(sub, sin2));
        let delta = q1 * (2.0 * std::f64::consts::PI * d / lam);
        let i = Complex64::new(0.0, 1.0);
        let r = |p0: Complex64, p1: Complex64, p2: Complex64| {
            let (c, s) = (delta.cos(), delta.sin());
            let (m11, m12, m21, m22) = (c, -i * s / p1, -i * p1 * s, c);
            let a = (m11 + m12 * p2) * p0;
            let b = m21 + m22 * p2;
            (a - b) / (a + b)
        };
        let rs = r(q0, q1, q2);
        // TM: p_j = q_j / N_j² (at d = 0: (N2² q0 − q2)/(N2² q0 + q2), Born & Wolf's r_p).
        let rp = r(q0 / (n0 * n0), q1 / (film * film), q2 / (sub * sub));
        (rs, rp)
    }

    #[test]
    fn zero_thickness_is_the_bare_substrate() {
        for &(n, k) in &[(3.85, 0.016), (1.56, 7.71), (0.24, 3.63), (1.5, 0.0)] {
            for deg in [0.0, 20.0, 45.0, 70.0, 85.0] {
                let b = f64::to_radians(deg);
                let f = thin_film((1.46, 0.0), 0.0, (n, k), b, 650.0).unwrap();
                let bare = Fresnel::new(n, k, b);
                assert!((f.rs - bare.rs).norm() < 1e-12, "{n} {k} {deg}");
                assert!((f.rp - bare.rp).norm() < 1e-12, "{n} {k} {deg}");
                if deg > 0.0 {
                    assert!((f.signed_dolp() - dop(n, k, b)).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn quarter_wave_antireflection_and_half_wave_absence() {
        // n1 = √n2, d = λ/(4 n1): R = 0 at normal incidence.
        let n2: f64 = 2.25;
        let n1 = n2.sqrt();
        let f = thin_film((n1, 0.0), 550.0 / (4.0 * n1), (n2, 0.0), 0.0, 550.0).unwrap();
        assert!(f.m00() < 1e-28, "{}", f.m00());
        // Half-wave: the layer is absent at normal incidence.
        let f = thin_film((1.38, 0.0), 550.0 / (2.0 * 1.38), (n2, 0.0), 0.0, 550.0).unwrap();
        let bare = ((n2 - 1.0) / (n2 + 1.0)).powi(2);
        assert!((f.m00() - bare).abs() < 1e-14);
        // Single-layer formula: R = ((n0 n2 − n1²)/(n0 n2 + n1²))² at a quarter wave.
        let n1 = 1.38;
        let f = thin_film((n1, 0.0), 550.0 / (4.0 * n1), (1.52, 0.0), 0.0, 550.0).unwrap();
        let want = ((1.52 - n1 * n1) / (1.52 + n1 * n1)).powi(2);
        assert!((f.m00() - want).abs() < 1e-14, "{} {want}", f.m00());
    }

    #[test]
    fn airy_sum_matches_the_characteristic_matrix() {
        let cases = [
            ((1.46, 0.0), 3.0, (3.85, 0.016)),
            ((1.46, 0.0), 250.0, (3.85, 0.016)),
            ((1.65, 0.0), 4.0, (1.56, 7.71)),
            ((2.0, 0.3), 80.0, (0.24, 3.63)),
            ((1.5, 0.0), 1234.0, (1.0, 0.0)),
        ];
        for (film, d, sub) in cases {
            for deg in [5.0, 30.0, 55.0, 75.0, 88.0] {
                let b = f64::to_radians(deg);
                let f = thin_film(film, d, sub, b, 633.0).unwrap();
                let (rs, rp) = char_matrix(
                    Complex64::new(film.0, film.1),
                    d,
                    Complex64::new(sub.0, sub.1),
                    b,
                    633.0,
                );
                assert!(
                    (f.rs - rs).norm() < 1e-12,
                    "{film:?} {d} {deg}: {} {rs}",
                    f.rs
                );
                assert!(
                    (f.rp - rp).norm() < 1e-12,
                    "{film:?} {d} {deg}: {} {rp}",
                    f.rp
                );
            }
        }
    }

    #[test]
    fn a_thick_oxide_turns_the_polarization_parallel_somewhere() {
        // SiO2 on Si at β = 60°: some thickness makes Rp > Rs (an oxidised wafer).
        let flips = (0..400).map(|i| f64::from(i) * 2.5).any(|d| {
            thin_film((1.46, 0.0), d, (3.85, 0.016), 1.05, 500.0)
                .unwrap()
                .signed_dolp()
                < -0.05
        });
        assert!(flips);
    }

    #[test]
    fn clear_coat_limits() {
        for deg in [10.0, 40.0, 70.0] {
            let b = f64::to_radians(deg);
            // A coat matched to a dielectric substrate is just the substrate.
            let c = clear_coat(1.5, (1.5, 0.0), b).unwrap();
            let f = Fresnel::new(1.5, 0.0, b);
            assert!((c.rs2 - f.rs2).abs() < 1e-14 && (c.rp2 - f.rp2).abs() < 1e-14);
            // On a perfect mirror-like substrate nearly everything comes back.
            let c = clear_coat(1.5, (0.05, 40.0), b).unwrap();
            assert!(c.m00() > 0.99, "{}", c.m00());
        }
        // The incoherent sum is the average of the coherent one over thickness.
        let b = 0.8;
        let (mut s, mut p) = (0.0, 0.0);
        let m = 4000;
        for i in 0..m {
            let d = 20_000.0 + 600.0 * f64::from(i) / f64::from(m);
            let f = thin_film((1.5, 0.0), d, (0.24, 3.63), b, 600.0).unwrap();
            s += f.rs2;
            p += f.rp2;
        }
        let c = clear_coat(1.5, (0.24, 3.63), b).unwrap();
        assert!(
            (s / f64::from(m) - c.rs2).abs() < 2e-3,
            "{} {}",
            s / f64::from(m),
            c.rs2
        );
        assert!(
            (p / f64::from(m) - c.rp2).abs() < 2e-3,
            "{} {}",
            p / f64::from(m),
            c.rp2
        );
        assert!(clear_coat(1.5, (0.24, -1.0), b).is_err());
        assert!(thin_film((1.5, 0.0), -1.0, (0.24, 3.63), b, 600.0).is_err());
    }
}
