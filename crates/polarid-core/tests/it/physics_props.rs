//! Properties of the physics: eq. (9) and its analytic gradient, the complex Fresnel
//! equations, and the pBRDF of eq. (3).

use std::f64::consts::{FRAC_PI_2, PI};

use polarid_core::dop::{dop, dop_grad};
use polarid_core::fresnel::{self, Fresnel};
use polarid_core::pbrdf::pbrdf;
use proptest::prelude::*;

/// Central finite differences of eq. (9) in n and k.
fn fd(n: f64, k: f64, beta: f64) -> (f64, f64) {
    let hn = 1e-6 * n.max(1.0);
    let hk = 1e-6 * k.max(1.0);
    let dn = (dop(n + hn, k, beta) - dop(n - hn, k, beta)) / (2.0 * hn);
    let dk = (dop(n, k + hk, beta) - dop(n, k - hk, beta)) / (2.0 * hk);
    (dn, dk)
}

/// Distance (in N² − sin²β) from the critical-angle singularity `N² = sin²β`, where
/// `∂P/∂n` is unbounded: `√C` of eq. (14).
fn sqrt_c(n: f64, k: f64, beta: f64) -> f64 {
    let d = n * n - k * k - beta.sin().powi(2);
    (2.0 * n * k).hypot(d)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Analytic ∂P/∂n, ∂P/∂k against central differences (h = 1e-6), away from the
    /// critical angle of weakly absorbing media (√C ≥ 0.05). Tolerance 1e-6 absolute
    /// plus 1e-6 relative: the truncation error h²P'''/6 and the rounding error
    /// ~ε/h are both below it there.
    #[test]
    fn gradient_matches_finite_differences(
        n in 0.05f64..6.0,
        k in 0.0f64..50.0,
        beta in 0.0f64..FRAC_PI_2,
        kzero in proptest::bool::weighted(0.15),
    ) {
        let k = if kzero { 0.0 } else { k.max(2e-6) };
        prop_assume!(sqrt_c(n, k, beta) >= 0.05);
        let g = dop_grad(n, k, beta);
        prop_assert!((g.p - dop(n, k, beta)).abs() <= 1e-15);
        let (dn, dk) = if k == 0.0 {
            // Above the critical angle P ∝ k (one-sided difference); below, P is even
            // in k and ∂P/∂k = 0.
            let total = n < beta.sin();
            let h = 1e-7;
            let dk = if total { (dop(n, h, beta) - dop(n, 0.0, beta)) / h } else { 0.0 };
            if !total {
                prop_assert!(g.dp_dk.abs() <= 1e-12, "dp_dk at k = 0: {}", g.dp_dk);
            }
            let hn = 1e-6 * n.max(1.0);
            ((dop(n + hn, 0.0, beta) - dop(n - hn, 0.0, beta)) / (2.0 * hn), dk)
        } else {
            fd(n, k, beta)
        };
        prop_assert!((g.dp_dn - dn).abs() <= 1e-6 * (1.0 + dn.abs()),
            "n={n} k={k} beta={beta}: dP/dn {} vs {}", g.dp_dn, dn);
        prop_assert!((g.dp_dk - dk).abs() <= 1e-6 * (1.0 + dk.abs()),
            "n={n} k={k} beta={beta}: dP/dk {} vs {}", g.dp_dk, dk);
    }

    /// 0 ≤ Rs, Rp ≤ 1 and 0 ≤ P ≤ 1, for every index and angle (incl. total reflection
    /// and grazing incidence).
    #[test]
    fn reflectances_and_dolp_in_unit_interval(
        n in 0.01f64..10.0,
        k in 0.0f64..50.0,
        beta in 0.0f64..=FRAC_PI_2,
    ) {
        let f = Fresnel::new(n, k, beta);
        prop_assert!((0.0..=1.0).contains(&f.rs2), "Rs {}", f.rs2);
        prop_assert!((0.0..=1.0).contains(&f.rp2), "Rp {}", f.rp2);
        let p = dop(n, k, beta);
        prop_assert!((0.0..=1.0).contains(&p), "P {p}");
        let g = dop_grad(n, k, beta);
        prop_assert!(g.p.is_finite() && g.dp_dn.is_finite() && g.dp_dk.is_finite());
    }

    /// Eq. (9) equals (Rs − Rp)/(Rs + Rp) from the complex amplitudes (the direct form
    /// loses digits only near index matching, excluded here).
    #[test]
    fn eq9_equals_fresnel_ratio(
        n in 0.05f64..6.0,
        k in 0.0f64..50.0,
        beta in 0.0f64..FRAC_PI_2,
    ) {
        prop_assume!((n - 1.0).hypot(k) > 0.02);
        let (rs, rp) = fresnel::reflectances(n, k, beta);
        let direct = (rs - rp) / (rs + rp);
        let p = dop(n, k, beta);
        prop_assert!((p - direct).abs() <= 1e-12, "n={n} k={k} beta={beta}: {p} vs {direct}");
        // and +m10/m00 of the Fresnel Mueller matrix (SCATMECH sign)
        let m = fresnel::mueller3(n, k, beta);
        prop_assert!((m[1][0] / m[0][0] - p).abs() <= 1e-12);
    }

    /// The Fresnel Mueller matrix is non-depolarizing: m22² + m23² = Rs·Rp, and its
    /// 3×3 block is the linear part of the 4×4.
    #[test]
    fn fresnel_mueller_consistent(
        n in 0.05f64..6.0,
        k in 0.0f64..20.0,
        beta in 0.0f64..FRAC_PI_2,
    ) {
        let f = Fresnel::new(n, k, beta);
        let m4 = f.mueller4();
        let m3 = f.mueller3();
        for i in 0..3 { for j in 0..3 { prop_assert_eq!(m3[i][j], m4[i][j]); } }
        let lhs = m4[2][2] * m4[2][2] + m4[2][3] * m4[2][3];
        prop_assert!((lhs - f.rs2 * f.rp2).abs() <= 1e-14, "{lhs} vs {}", f.rs2 * f.rp2);
        prop_assert_eq!(m4[3][2], -m4[2][3]);
        prop_assert_eq!(m4[3][3], m4[2][2]);
    }

    /// Swapping source and camera leaves m00 unchanged (reciprocity, Helmholtz), and the
    /// DoLP too. Also: m00 and DoLP are the same in both frames, and the global
    /// rotation preserves √(m10² + m20²).
    #[test]
    fn reciprocity_and_frames(
        n in 0.2f64..3.0,
        k in 0.0f64..8.0,
        sigma in 0.05f64..0.5,
        ti in 0.0f64..1.45,
        tr in 0.0f64..1.45,
        phi in 0.0f64..(2.0 * PI),
    ) {
        let a = pbrdf(n, k, sigma, ti, tr, phi).unwrap();
        let b = pbrdf(n, k, sigma, tr, ti, phi).unwrap();
        let m00 = a.local[0][0];
        prop_assert!(m00 >= 0.0 && m00.is_finite());
        prop_assert!((b.local[0][0] - m00).abs() <= 1e-12 * m00, "{} vs {m00}", b.local[0][0]);
        prop_assert!((b.global[0][0] - a.global[0][0]).abs() <= 1e-12 * m00);
        prop_assert!((a.dolp - b.dolp).abs() <= 1e-14);
        prop_assert!((0.0..=1.0).contains(&a.dolp));
        prop_assert_eq!(a.global[0][0], m00);
        if m00 > 1e-250 {
            let dl = a.local[1][0].hypot(a.local[2][0]) / m00;
            let dg = a.global[1][0].hypot(a.global[2][0]) / m00;
            prop_assert!((dl - a.dolp).abs() <= 1e-12 && (dg - a.dolp).abs() <= 1e-12,
                "{dl} {dg} {}", a.dolp);
        }
        for v in a.local.iter().chain(a.global.iter()).flatten() {
            prop_assert!(v.is_finite());
        }
    }
}

#[test]
fn brewster_is_exactly_one() {
    for &n in &[0.3, 0.5, 0.9, 1.2, 1.5, 2.0, 3.0, 4.5] {
        let b = f64::atan(n);
        let p = dop(n, 0.0, b);
        assert_eq!(p, 1.0, "n={n}");
        let g = dop_grad(n, 0.0, b);
        assert_eq!(g.p, 1.0, "n={n}");
        // P has its maximum there: the gradient in n is ~0 along... no: at fixed β the
        // maximum over n is at n = tan β.
        assert!(g.dp_dn.abs() <= 1e-7, "n={n}: dP/dn {}", g.dp_dn);
        assert_eq!(g.dp_dk, 0.0);
    }
}

#[test]
fn normal_and_grazing_incidence() {
    for &(n, k) in &[
        (1.5, 0.0),
        (0.4, 2.95),
        (1.2, 50.0),
        (0.05, 4.0),
        (1.0001, 0.0),
    ] {
        assert_eq!(dop(n, k, 0.0), 0.0);
        let g = dop_grad(n, k, 0.0);
        assert_eq!((g.p, g.dp_dn, g.dp_dk), (0.0, 0.0, 0.0));
        let p = dop(n, k, FRAC_PI_2);
        assert!(p <= 1e-15, "{p}");
        // Small β: P ≈ β² scale, smooth.
        let p = dop(n, k, 1e-4);
        assert!((0.0..1e-6).contains(&p), "{p}");
    }
}

#[test]
fn total_reflection_is_unpolarized() {
    for &n in &[0.2, 0.5, 0.9] {
        let crit = f64::asin(n);
        for &b in &[
            crit + 1e-6,
            crit + 1e-3,
            0.5 * (crit + FRAC_PI_2),
            FRAC_PI_2 - 1e-6,
        ] {
            assert_eq!(dop(n, 0.0, b), 0.0, "n={n} beta={b}");
            let g = dop_grad(n, 0.0, b);
            assert_eq!(g.p, 0.0);
            assert_eq!(g.dp_dn, 0.0);
            // Any absorption polarizes: ∂P/∂k > 0 (one-sided difference).
            assert!(g.dp_dk > 0.0 && g.dp_dk.is_finite());
            if b > crit + 1e-4 {
                let h = 1e-9;
                let fd = dop(n, h, b) / h;
                assert!(
                    (g.dp_dk - fd).abs() <= 1e-5 * (1.0 + fd),
                    "{} vs {fd}",
                    g.dp_dk
                );
            }
        }
        // Exactly at the critical angle the gradient is unbounded: finite zeros.
        let g = dop_grad(n, 0.0, crit);
        assert!(g.p.is_finite() && g.dp_dn.is_finite() && g.dp_dk.is_finite());
    }
}

#[test]
fn large_k_is_finite_and_accurate() {
    for &k in &[10.0, 25.0, 50.0] {
        for &bd in &[5.0f64, 45.0, 80.0, 89.9] {
            let b = bd.to_radians();
            let (rs, rp) = fresnel::reflectances(0.3, k, b);
            let direct = (rs - rp) / (rs + rp);
            let g = dop_grad(0.3, k, b);
            assert!(
                (g.p - direct).abs() <= 1e-13,
                "k={k} β={bd}: {} vs {direct}",
                g.p
            );
            let (dn, dk) = fd(0.3, k, b);
            assert!((g.dp_dn - dn).abs() <= 1e-7 * (1.0 + dn.abs()));
            assert!((g.dp_dk - dk).abs() <= 1e-7 * (1.0 + dk.abs()));
        }
    }
}

#[test]
fn near_index_matching_is_smooth() {
    // |N − 1| from 1e-3 down to 1e-9: P tends to its k = 0 limit at N = 1 smoothly,
    // and the gradient stays finite and matches finite differences.
    let b = 50f64.to_radians();
    let (s, c) = b.sin_cos();
    let limit = 2.0 * c * c * s * s / (c.powi(4) + s.powi(4));
    for &e in &[1e-3, 1e-5, 1e-7, 1e-9] {
        let p = dop(1.0 + e, 0.0, b);
        assert!((p - limit).abs() <= 10.0 * e, "e={e}: {p} vs {limit}");
        let g = dop_grad(1.0 + e, e, b);
        assert!(g.dp_dn.is_finite() && g.dp_dk.is_finite());
    }
    let g = dop_grad(1.001, 0.001, b);
    let (dn, dk) = fd(1.001, 0.001, b);
    assert!((g.dp_dn - dn).abs() <= 1e-6 * (1.0 + dn.abs()));
    assert!(
        (g.dp_dk - dk).abs() <= 1e-6 * (1.0 + dk.abs()),
        "{} vs {dk}",
        g.dp_dk
    );
}
