//! The analytic Jacobian of the mixed radiometric model against central finite
//! differences (proptest), with and without Smith shadowing and θr estimation.

use polarid_core::mixed::{
    MixedCapture, NPAR, P_K, P_LN_E, P_N, P_RHO, P_SIGMA, P_THETA_R, Shadowing, m00_grad,
    model_point,
};
use proptest::prelude::*;
use std::f64::consts::PI;

fn check(
    cap: &MixedCapture,
    x: [f64; NPAR],
    est: bool,
    sh: Shadowing,
) -> Result<(), TestCaseError> {
    let mp = model_point(cap, &x, est, sh);
    let params = [P_N, P_K, P_SIGMA, P_RHO, P_LN_E, P_THETA_R];
    for &a in &params {
        if a == P_THETA_R && !est {
            continue;
        }
        let h = 1e-6 * x[a].abs().max(1e-3);
        let (mut xp, mut xm) = (x, x);
        xp[a] += h;
        xm[a] -= h;
        let (p, m) = (
            model_point(cap, &xp, est, sh),
            model_point(cap, &xm, est, sh),
        );
        let fd_d = (p.dolp - m.dolp) / (2.0 * h);
        let fd_s = (p.ln_s0 - m.ln_s0) / (2.0 * h);
        let tol_d = 1e-6 * (1.0 + fd_d.abs()) + 1e-7;
        let tol_s = 1e-6 * (1.0 + fd_s.abs()) + 1e-7;
        prop_assert!(
            (mp.d_dolp[a] - fd_d).abs() < tol_d,
            "dDoLP/dx[{a}]: analytic {} fd {} at {x:?} {cap:?}",
            mp.d_dolp[a],
            fd_d
        );
        prop_assert!(
            (mp.d_ln_s0[a] - fd_s).abs() < tol_s,
            "dlnS0/dx[{a}]: analytic {} fd {} at {x:?} {cap:?}",
            mp.d_ln_s0[a],
            fd_s
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn jacobian_matches_finite_differences(
        n in 0.2f64..4.0, k in 0.05f64..8.0, sigma in 0.05f64..0.8, rho in 0.0f64..1.0,
        ln_e in -3.0f64..8.0, ti_deg in 5.0f64..80.0, tr_deg in 20.0f64..75.0,
        smith in any::<bool>(), est in any::<bool>(),
    ) {
        let (ti, tr) = (ti_deg.to_radians(), tr_deg.to_radians());
        let cap = MixedCapture::new(ti, tr, PI, 0.5, None, 1.0);
        let sh = if smith { Shadowing::SmithBeckmann } else { Shadowing::None };
        // When estimating, x's θr is the parameter; keep θi = 2β − θr in range.
        let x = [n, k, sigma, rho, ln_e, tr];
        check(&cap, x, est, sh)?;
    }

    #[test]
    fn m00_gradient_matches_finite_differences(
        n in 0.05f64..6.0, k in 0.0f64..10.0, beta_deg in 1.0f64..89.0,
    ) {
        let (s, c) = beta_deg.to_radians().sin_cos();
        let (_, dn, dk) = m00_grad(n, k, s * s, c);
        let h = 1e-6;
        let f = |n: f64, k: f64| m00_grad(n, k, s * s, c).0;
        let fdn = (f(n + h, k) - f(n - h, k)) / (2.0 * h);
        let fdk = if k > h {
            (f(n, k + h) - f(n, k - h)) / (2.0 * h)
        } else {
            (f(n, k + h) - f(n, k)) / h
        };
        prop_assert!((dn - fdn).abs() < 1e-6 * (1.0 + fdn.abs()), "dn {dn} {fdn}");
        prop_assert!((dk - fdk).abs() < 2e-6 * (1.0 + fdk.abs()), "dk {dk} {fdk}");
    }
}

#[test]
fn out_of_plane_geometry_dolp_is_diluted_eq9() {
    // DoLP of the specular part is frame-invariant: the model equals the pBRDF's.
    let (ti, tr, phi) = (0.6, 0.9, 2.5);
    let cap = MixedCapture::new(ti, tr, phi, 0.5, None, 1.0);
    let x = [1.5, 0.3, 0.25, 0.4, 0.0, 0.0];
    let mp = model_point(&cap, &x, false, Shadowing::None);
    let f = polarid_core::pbrdf::pbrdf(1.5, 0.3, 0.25, ti, tr, phi).unwrap();
    let g = f.global;
    let s0 = g[0][0] + 0.4 / PI;
    let dolp = g[1][0].hypot(g[2][0]) / s0;
    assert!((mp.dolp - dolp).abs() < 1e-12, "{} {dolp}", mp.dolp);
    assert!((mp.ln_s0 - (ti.cos() * s0).ln()).abs() < 1e-12);
    // And against the simulator's radiometry.
    let optics = polarid_core::simulate::PlateOptics {
        n: 1.5,
        k: 0.3,
        sigma: 0.25,
        rho_d: 0.4,
    };
    let l = polarid_core::simulate::plate_radiance(&optics, ti, tr, phi).unwrap();
    assert!((mp.ln_s0 - l[0].ln()).abs() < 1e-12);
}
