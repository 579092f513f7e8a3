//! A simulator of real-world imperfections, for measuring how the fit, its error model
//! and the model checks behave on data that the paper's single-interface model does not
//! describe exactly (docs/ERRORS.md "Measured").
//!
//! One target is seen in `T` in-plane captures (`φ = 180°`, source zenith `θi_t`, camera
//! zenith `θr`). Each capture's row is what `polarid measure` writes for a region: the
//! DoLP with its standard error, the AoLP from the (nominal) plane of incidence, and the
//! mean `S0` divided by the capture's exposure. Between the surface and the row:
//!
//! 1. **Geometry.** The true directions are off by uniform offsets in `±angle_offset_max`:
//!    the camera's once per target, the source's per capture, each with an in-plane
//!    component (it moves `θ`: `θi' = θi + δs∥`, `θr' = θr + δv∥`, so
//!    `β' = (θi' + θr')/2`, eq. 5 in the plane) and an out-of-plane one (the source's turns
//!    the true plane of incidence about the view ray by `ψ = δs⊥ / sin 2β`).
//! 2. **Surface** ([`Surface`]): the radiance `S0 = E cos θi' (f00 + ρd/π)` with the
//!    Priest–Meier lobe `f00 = m00 exp(−tan²θ/(2σ²)) / (8πσ² cos⁴θ cos θi' cos θr')` (paper
//!    eq. 3, facet tilt `θ = (θi' − θr')/2`, eq. 4) and a Lambertian part `ρd`, and the
//!    signed DoLP `P_s f00/(f00 + ρd/π)` where `P_s = (Rs − Rp)/(Rs + Rp)` of the
//!    reflecting stack ([`crate::film`]; for a bare interface, eq. 9); a diffuser has
//!    `S0 = E cos θi' ρ/π` and a weak DoLP of its own. Positive: perpendicular to the plane
//!    of incidence, negative: parallel.
//! 3. **Retardance** `δ` ahead of the analyzer, fast axis at a random angle `α` per target:
//!    linear polarization at `χ` from the axis leaves as `(S1, S2) = P (cos 2χ,
//!    sin 2χ cos δ)` in the axis frame (a linear retarder's Mueller matrix).
//! 4. **Extinction ratio** `ER` of the analyzer: every DoLP times `(ER − 1)/(ER + 1)`.
//! 5. **Noise**: Gaussian, standard deviation `dolp_se` on the normalised `S1/S0` and
//!    `S2/S0` (so a low DoLP is biased up, as measured); `S0` times
//!    `(1 + s0_rel_sd · N(0, 1))`. The exposure of each capture is the power of two that
//!    puts its `S0` nearest 0.5, and `s0` is the measured `S0` over it.
//!
//! The source's irradiance `E` is 1. Pure: no I/O; reproducible from `seed`.
//!
//! # Reference
//! Thilak, Creusere & Voelz, ICIP 2007: eq. (3)–(5), (9). Films: [`crate::film`].

use std::f64::consts::{FRAC_PI_2, PI};

use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;
use rand_distr::{Distribution, Normal, Uniform};

use crate::dop::dop;
use crate::error::{CoreError, Result};
use crate::film::{clear_coat, thin_film};
use crate::fresnel::Fresnel;

/// What reflects the light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Surface {
    /// A single interface of index `n + ik` (the paper's model).
    Bare {
        /// Real part of the index.
        n: f64,
        /// Imaginary part.
        k: f64,
    },
    /// A thin film (e.g. a native oxide) on a substrate: coherent single-layer
    /// interference ([`thin_film`]).
    Film {
        /// The substrate's `(n, k)`.
        substrate: (f64, f64),
        /// The film's `(n, k)`.
        film: (f64, f64),
        /// Film thickness, nanometres.
        thickness_nm: f64,
    },
    /// A thick, clear dielectric coat on a substrate: incoherent sum ([`clear_coat`]).
    ClearCoat {
        /// The substrate's `(n, k)`.
        substrate: (f64, f64),
        /// The coat's (real) index.
        coat_n: f64,
    },
    /// A diffuser: Lambertian brightness `albedo/π`, no specular lobe, and a weak DoLP
    /// `dolp_0 + (dolp_90 − dolp_0) sin²β` polarized parallel to the plane of incidence
    /// (`parallel`) or perpendicular to it.
    Diffuser {
        /// Albedo `ρ` (BRDF `ρ/π`).
        albedo: f64,
        /// DoLP at `β = 0`.
        dolp_0: f64,
        /// DoLP at `β = 90°`.
        dolp_90: f64,
        /// Polarized parallel to the plane of incidence (p) rather than perpendicular (s).
        parallel: bool,
    },
}

/// A simulated target: its surface, and for the specular kinds the roughness of the
/// specular lobe and an unpolarized Lambertian part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImperfectTarget {
    /// The surface.
    pub surface: Surface,
    /// Roughness σ of the specular lobe (paper eq. 3), `> 0` (unused by a diffuser).
    pub sigma: f64,
    /// Albedo of an unpolarized Lambertian part, `[0, 1]` (unused by a diffuser).
    pub rho_d: f64,
}

/// The imperfections of the bench and the polarimeter, and the noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imperfections {
    /// Largest angle offset of each direction (uniform in `±`), radians.
    pub angle_offset_max: f64,
    /// Extinction ratio of the analyzer (`> 1`; infinite: ideal).
    pub extinction_ratio: f64,
    /// Retardance ahead of the analyzer, radians.
    pub retardance: f64,
    /// Standard deviation of the noise of `S1/S0` and `S2/S0` (`≥ 0`).
    pub dolp_se: f64,
    /// Relative standard deviation of `S0` (`≥ 0`).
    pub s0_rel_sd: f64,
    /// Vacuum wavelength, nanometres (for films).
    pub wavelength_nm: f64,
}

impl Default for Imperfections {
    /// None: exact angles, an ideal analyzer, no noise, 650 nm.
    fn default() -> Self {
        Self {
            angle_offset_max: 0.0,
            extinction_ratio: f64::INFINITY,
            retardance: 0.0,
            dolp_se: 0.0,
            s0_rel_sd: 0.0,
            wavelength_nm: 650.0,
        }
    }
}

/// One simulated row (one capture of one target), in the units of the measurements CSV.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImperfectRow {
    /// Nominal source zenith, degrees.
    pub theta_i_deg: f64,
    /// Nominal camera zenith, degrees.
    pub theta_r_deg: f64,
    /// Nominal `β = (θi + θr)/2`, degrees (eq. 5 in the plane).
    pub beta_deg: f64,
    /// Measured DoLP.
    pub dolp: f64,
    /// Its stated standard error (`Imperfections::dolp_se`).
    pub dolp_se: f64,
    /// Measured AoLP from the nominal plane of incidence, degrees, `[0, 180)`.
    pub aolp_poi_deg: f64,
    /// Measured mean `S0` divided by `exposure`.
    pub s0: f64,
    /// The capture's exposure.
    pub exposure: f64,
    /// The true `β` of the capture (with the angle offsets), degrees.
    pub beta_true_deg: f64,
    /// The DoLP leaving the surface at the true geometry, signed (< 0: parallel).
    pub dolp_true_signed: f64,
}

/// `(S0/E, signed DoLP)` leaving `target` at true zeniths `ti`, `tr` (radians, in the
/// plane), wavelength `lambda` nm.
pub fn surface_response(
    target: &ImperfectTarget,
    ti: f64,
    tr: f64,
    lambda: f64,
) -> Result<(f64, f64)> {
    let beta = 0.5 * (ti + tr);
    let (m00, p) = match target.surface {
        Surface::Diffuser {
            albedo,
            dolp_0,
            dolp_90,
            parallel,
        } => {
            let d = dolp_0 + (dolp_90 - dolp_0) * beta.sin().powi(2);
            let d = if parallel { -d } else { d };
            return Ok((ti.cos() * albedo / PI, d));
        }
        Surface::Bare { n, k } => {
            let f = Fresnel::new(n, k, beta);
            (0.5 * (f.rs2 + f.rp2), dop(n, k, beta))
        }
        Surface::Film {
            substrate,
            film,
            thickness_nm,
        } => {
            let r = thin_film(film, thickness_nm, substrate, beta, lambda)?;
            (r.m00(), r.signed_dolp())
        }
        Surface::ClearCoat { substrate, coat_n } => {
            let r = clear_coat(coat_n, substrate, beta)?;
            (r.m00(), r.signed_dolp())
        }
    };
    let s = target.sigma;
    let th = 0.5 * (ti - tr);
    let f00 = m00 * (-th.tan().powi(2) / (2.0 * s * s)).exp()
        / (8.0 * PI * s * s * th.cos().powi(4) * ti.cos() * tr.cos());
    let dif = target.rho_d / PI;
    Ok((ti.cos() * (f00 + dif), p * f00 / (f00 + dif)))
}

fn check(name: &'static str, v: f64, ok: bool, expected: &'static str) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(CoreError::OutOfRange {
            name,
            value: v,
            expected,
        })
    }
}

/// The checks of [`simulate_target`] on its inputs.
fn check_inputs(
    target: &ImperfectTarget,
    theta_i: &[f64],
    theta_r: f64,
    imp: &Imperfections,
) -> Result<()> {
    let ang_ok = |a: f64| a.is_finite() && (0.0..FRAC_PI_2).contains(&a);
    check("theta_r", theta_r, ang_ok(theta_r), "[0, pi/2) radians")?;
    for &t in theta_i {
        check("theta_i", t, ang_ok(t), "[0, pi/2) radians")?;
    }
    let specular = !matches!(target.surface, Surface::Diffuser { .. });
    if specular {
        check(
            "sigma",
            target.sigma,
            target.sigma > 0.0 && target.sigma.is_finite(),
            "> 0",
        )?;
        check(
            "rho_d",
            target.rho_d,
            (0.0..=1.0).contains(&target.rho_d),
            "[0, 1]",
        )?;
    }
    let off = imp.angle_offset_max;
    check(
        "angle_offset_max",
        off,
        off.is_finite() && (0.0..0.2).contains(&off),
        "[0, 0.2) radians",
    )?;
    check(
        "extinction_ratio",
        imp.extinction_ratio,
        imp.extinction_ratio > 1.0,
        "> 1",
    )?;
    for (name, v) in [
        ("retardance", imp.retardance),
        ("dolp_se", imp.dolp_se),
        ("s0_rel_sd", imp.s0_rel_sd),
    ] {
        check(name, v, v.is_finite() && v >= 0.0, ">= 0")?;
    }
    check(
        "wavelength_nm",
        imp.wavelength_nm,
        imp.wavelength_nm.is_finite() && imp.wavelength_nm > 0.0,
        "> 0",
    )?;
    Ok(())
}

/// Simulate one target seen from camera zenith `theta_r` with the source at each of
/// `theta_i` (radians, in the plane), with the imperfections `imp`, reproducibly from
/// `seed` (module documentation).
///
/// Errors: [`CoreError::OutOfRange`] for an angle outside `[0, π/2)`, a bad roughness,
/// albedo, extinction ratio, noise or wavelength, or a bad index or thickness.
pub fn simulate_target(
    target: &ImperfectTarget,
    theta_i: &[f64],
    theta_r: f64,
    imp: &Imperfections,
    seed: u64,
) -> Result<Vec<ImperfectRow>> {
    check_inputs(target, theta_i, theta_r, imp)?;
    let ang_ok = |a: f64| a.is_finite() && (0.0..FRAC_PI_2).contains(&a);
    let off = imp.angle_offset_max;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let unit = Uniform::new_inclusive(-1.0, 1.0).map_err(|_| CoreError::OutOfRange {
        name: "uniform",
        value: 1.0,
        expected: "a valid range",
    })?;
    let normal = Normal::new(0.0, 1.0).map_err(|_| CoreError::OutOfRange {
        name: "normal",
        value: 1.0,
        expected: "a valid sd",
    })?;
    let cam = off * unit.sample(&mut rng);
    let axis = PI * 0.5 * (unit.sample(&mut rng) + 1.0);
    let scale = if imp.extinction_ratio.is_finite() {
        (imp.extinction_ratio - 1.0) / (imp.extinction_ratio + 1.0)
    } else {
        1.0
    };
    let mut rows = Vec::with_capacity(theta_i.len());
    for &ti in theta_i {
        let (par, perp) = (off * unit.sample(&mut rng), off * unit.sample(&mut rng));
        let (ti_t, tr_t) = (ti + par, theta_r + cam);
        check("theta_i + offset", ti_t, ang_ok(ti_t), "[0, pi/2) radians")?;
        let beta_t = 0.5 * (ti_t + tr_t);
        let (s0, p) = surface_response(target, ti_t, tr_t, imp.wavelength_nm)?;
        // Polarization angle from the nominal plane of incidence.
        let psi = perp / (2.0 * beta_t).sin().max(1e-3);
        let chi0 = if p >= 0.0 { FRAC_PI_2 } else { 0.0 } + psi;
        // Retarder (fast axis at `axis`), then the analyzer's extinction.
        let chi = chi0 - axis;
        let (c, s) = ((2.0 * chi).cos(), (2.0 * chi).sin() * imp.retardance.cos());
        let (ca, sa) = ((2.0 * axis).cos(), (2.0 * axis).sin());
        let mag = p.abs() * scale;
        let s1 = mag * (c * ca - s * sa) + imp.dolp_se * normal.sample(&mut rng);
        let s2 = mag * (c * sa + s * ca) + imp.dolp_se * normal.sample(&mut rng);
        let dolp = s1.hypot(s2).min(1.0);
        let aolp = (0.5 * s2.atan2(s1)).rem_euclid(PI);
        let s0_meas = s0 * (1.0 + imp.s0_rel_sd * normal.sample(&mut rng)).max(1e-6);
        let exposure = (0.5 / s0.max(1e-300))
            .log2()
            .round()
            .clamp(-60.0, 60.0)
            .exp2();
        rows.push(ImperfectRow {
            theta_i_deg: ti.to_degrees(),
            theta_r_deg: theta_r.to_degrees(),
            beta_deg: (0.5 * (ti + theta_r)).to_degrees(),
            dolp,
            dolp_se: imp.dolp_se,
            aolp_poi_deg: aolp.to_degrees().rem_euclid(180.0),
            s0: (s0_meas * exposure).min(1.0) / exposure,
            exposure,
            beta_true_deg: beta_t.to_degrees(),
            dolp_true_signed: p,
        });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn deg(v: &[f64]) -> Vec<f64> {
        v.iter().map(|d| d.to_radians()).collect()
    }

    #[test]
    fn without_imperfections_a_bare_surface_is_the_paper_model() {
        let t = ImperfectTarget {
            surface: Surface::Bare { n: 1.38, k: 1.92 },
            sigma: 0.2,
            rho_d: 0.0,
        };
        let rows = simulate_target(
            &t,
            &deg(&[30.0, 50.0, 70.0]),
            0.8,
            &Imperfections::default(),
            1,
        )
        .unwrap();
        for r in &rows {
            let b = r.beta_deg.to_radians();
            assert!((r.dolp - dop(1.38, 1.92, b)).abs() < 1e-12);
            assert!((r.aolp_poi_deg - 90.0).abs() < 1e-9);
            assert!(r.s0 > 0.0 && r.exposure > 0.0);
        }
        // A zero-thickness film is the bare substrate.
        let f = ImperfectTarget {
            surface: Surface::Film {
                substrate: (1.38, 1.92),
                film: (1.46, 0.0),
                thickness_nm: 0.0,
            },
            ..t
        };
        let rf = simulate_target(
            &f,
            &deg(&[30.0, 50.0, 70.0]),
            0.8,
            &Imperfections::default(),
            1,
        )
        .unwrap();
        for (a, b) in rows.iter().zip(&rf) {
            assert!((a.dolp - b.dolp).abs() < 1e-12 && (a.s0 - b.s0).abs() < 1e-12 * a.s0);
        }
    }

    #[test]
    fn extinction_retardance_and_offsets_do_what_they_say() {
        let t = ImperfectTarget {
            surface: Surface::Bare { n: 1.5, k: 0.0 },
            sigma: 0.3,
            rho_d: 0.0,
        };
        let caps = deg(&[40.0, 56.0]);
        let imp = Imperfections {
            extinction_ratio: 99.0,
            ..Imperfections::default()
        };
        let rows = simulate_target(&t, &caps, 0.8, &imp, 3).unwrap();
        for r in &rows {
            let p = dop(1.5, 0.0, r.beta_deg.to_radians());
            assert!((r.dolp - 0.98 * p).abs() < 1e-12);
        }
        // Retardance: DoLP between P cos δ and P, AoLP within a few degrees of 90.
        let imp = Imperfections {
            retardance: 0.5,
            ..Imperfections::default()
        };
        for seed in 0..20 {
            let rows = simulate_target(&t, &caps, 0.8, &imp, seed).unwrap();
            for r in &rows {
                let p = dop(1.5, 0.0, r.beta_deg.to_radians());
                assert!(r.dolp <= p + 1e-12 && r.dolp >= p * 0.5f64.cos() - 1e-12);
            }
        }
        // Offsets: the true β is within the bound of the nominal one.
        let imp = Imperfections {
            angle_offset_max: 0.3f64.to_radians(),
            ..Imperfections::default()
        };
        let mut moved = 0.0f64;
        for seed in 0..50 {
            for r in simulate_target(&t, &caps, 0.8, &imp, seed).unwrap() {
                let d = (r.beta_true_deg - r.beta_deg).abs();
                assert!(d <= 0.3 + 1e-12);
                moved = moved.max(d);
                assert!((r.aolp_poi_deg - 90.0).abs() < 1.0);
            }
        }
        assert!(moved > 0.2);
    }

    #[test]
    fn a_diffuser_is_lambertian_and_weakly_polarized() {
        let t = ImperfectTarget {
            surface: Surface::Diffuser {
                albedo: 0.95,
                dolp_0: 0.01,
                dolp_90: 0.06,
                parallel: true,
            },
            sigma: 0.0,
            rho_d: 0.0,
        };
        let rows = simulate_target(
            &t,
            &deg(&[20.0, 40.0, 60.0]),
            0.7,
            &Imperfections::default(),
            5,
        )
        .unwrap();
        for r in &rows {
            let ti = r.theta_i_deg.to_radians();
            assert!((r.s0 - ti.cos() * 0.95 / PI).abs() < 1e-12);
            assert!(r.dolp > 0.01 && r.dolp < 0.06);
            assert!(r.aolp_poi_deg.abs() < 1e-9 || (r.aolp_poi_deg - 180.0).abs() < 1e-9);
        }
    }

    #[test]
    fn bad_inputs_are_refused() {
        let t = ImperfectTarget {
            surface: Surface::Bare { n: 1.5, k: 0.0 },
            sigma: 0.0,
            rho_d: 0.0,
        };
        assert!(simulate_target(&t, &[0.5], 0.8, &Imperfections::default(), 1).is_err());
        let t = ImperfectTarget { sigma: 0.2, ..t };
        assert!(simulate_target(&t, &[2.0], 0.8, &Imperfections::default(), 1).is_err());
        let imp = Imperfections {
            extinction_ratio: 0.5,
            ..Imperfections::default()
        };
        assert!(simulate_target(&t, &[0.5], 0.8, &imp, 1).is_err());
    }
}
