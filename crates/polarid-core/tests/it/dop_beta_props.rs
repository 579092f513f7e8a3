//! The analytic β-derivatives of eq. (9) (`dop::dop_beta_derivs`) agree with central
//! finite differences of `dop::dop`, and `dop_spread` approximates the mean of `P` over
//! a spread of β to second order.

use polarid_core::dop::{dop, dop_beta_derivs, dop_spread};
use proptest::prelude::*;

/// Central differences of `P` in β with step `h`: (first, second derivative).
fn central(n: f64, k: f64, b: f64, h: f64) -> (f64, f64) {
    let (pm, p0, pp) = (dop(n, k, b - h), dop(n, k, b), dop(n, k, b + h));
    ((pp - pm) / (2.0 * h), (pp - 2.0 * p0 + pm) / (h * h))
}

/// Central differences with one Richardson step (error O(h⁴)).
fn finite_differences(n: f64, k: f64, b: f64, h: f64) -> (f64, f64) {
    let (a1, a2) = central(n, k, b, h);
    let (b1, b2) = central(n, k, b, h / 2.0);
    ((4.0 * b1 - a1) / 3.0, (4.0 * b2 - a2) / 3.0)
}

/// `√C` of eq. (14): the derivatives are unbounded where it vanishes (critical angle).
fn root_c(n: f64, k: f64, b: f64) -> f64 {
    let d = n * n - k * k - b.sin().powi(2);
    (4.0 * n * n * k * k + d * d).sqrt()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn beta_derivatives_match_finite_differences(
        n in 0.05f64..8.0,
        k in prop_oneof![Just(0.0), 0.0f64..8.0],
        bd in 2.0f64..88.0,
    ) {
        let b = bd.to_radians();
        // Stay away from the critical angle of a transparent medium, where the
        // derivatives are unbounded (√C → 0) and finite differences meaningless.
        prop_assume!(root_c(n, k, b) > 0.05);
        prop_assume!(root_c(n, k, b - 2e-3) > 0.04 && root_c(n, k, b + 2e-3) > 0.04);
        let g = dop_beta_derivs(n, k, b);
        prop_assert!((g.p - dop(n, k, b)).abs() < 1e-15);
        let h = 4e-4;
        let (d1, d2) = finite_differences(n, k, b, h);
        let tol1 = 1e-6 * (1.0 + g.dp_dbeta.abs());
        prop_assert!((g.dp_dbeta - d1).abs() < tol1, "P' {} vs {}", g.dp_dbeta, d1);
        let tol2 = 2e-4 * (1.0 + g.d2p_dbeta2.abs());
        prop_assert!((g.d2p_dbeta2 - d2).abs() < tol2, "P'' {} vs {}", g.d2p_dbeta2, d2);
    }

    #[test]
    fn spread_correction_is_second_order(
        n in 0.1f64..4.0,
        k in 0.0f64..6.0,
        bd in 15.0f64..75.0,
        sd_deg in 0.5f64..3.0,
    ) {
        let b = bd.to_radians();
        prop_assume!(root_c(n, k, b) > 0.2);
        // A symmetric three-point distribution with SD `sd`: the mean of P exactly.
        let exact = |sd: f64| {
            let h = sd * 1.5f64.sqrt();
            (dop(n, k, b - h) + dop(n, k, b) + dop(n, k, b + h)) / 3.0
        };
        let err = |sd: f64| (exact(sd) - dop_spread(n, k, b, sd)).abs();
        let plain = |sd: f64| (exact(sd) - dop(n, k, b)).abs();
        let sd = sd_deg.to_radians();
        // Without the correction the error is O(s²); with it O(s⁴): halving the spread
        // divides it by ~16 (by ~4 without the correction).
        prop_assert!(err(sd / 2.0) <= err(sd) / 8.0 + 1e-4 * plain(sd) + 1e-12,
            "err {} -> {} (uncorrected {} -> {})", err(sd), err(sd / 2.0), plain(sd), plain(sd / 2.0));
    }
}

#[test]
fn zero_spread_is_eq_9() {
    for &(n, k, bd) in &[(1.5, 0.0, 56.3), (0.27, 2.8, 70.0), (1.2, 6.9, 40.0)] {
        let b = f64::to_radians(bd);
        assert_eq!(dop_spread(n, k, b, 0.0), dop(n, k, b));
    }
}

#[test]
fn critical_angle_and_total_reflection_are_zero() {
    // k = 0, n = sin β: √C = 0.
    let b = 0.5f64.asin();
    assert_eq!(dop_beta_derivs(0.5, 0.0, b).d2p_dbeta2, 0.0);
    // Beyond it: P = 0 with zero derivatives.
    let g = dop_beta_derivs(0.5, 0.0, 60f64.to_radians());
    assert_eq!((g.p, g.dp_dbeta, g.d2p_dbeta2), (0.0, 0.0, 0.0));
    // Brewster's angle of glass: a maximum, P' = 0 and P'' < 0.
    let g = dop_beta_derivs(1.5, 0.0, 1.5f64.atan());
    assert!(g.dp_dbeta.abs() < 1e-9 && g.d2p_dbeta2 < -1.0, "{g:?}");
}

/// The residual error of the second-order spread model over plates whose β is spread
/// uniformly (weights 1) or under a lobe (weights `e^{4u}` across the plate, `u` in
/// [−½, ½]: 7× brighter at one edge), for β spreads (SD) of 1°, 2°, 3°, over
/// β̄ = 20°…80°; printed for docs/GEOMETRY.md and bounded here.
#[test]
fn spread_truncation_table() {
    let materials = [
        ("aluminium 650", 1.2, 7.0),
        ("gold 450", 1.38, 1.92),
        ("copper 450", 1.01, 2.58),
        ("glass", 1.52, 0.0),
    ];
    for (name, n, k) in materials {
        for sd_deg in [1.0f64, 2.0, 3.0] {
            let mut worst = [0.0f64; 4]; // uniform plain, uniform corrected, lobe plain, lobe corrected
            for lobe in [false, true] {
                for bd in (20..=80).map(f64::from) {
                    // 2001 pixels across the plate, u in [−½, ½], β linear in u.
                    let m = 2001;
                    let us: Vec<f64> = (0..m).map(|i| i as f64 / (m - 1) as f64 - 0.5).collect();
                    let w: Vec<f64> = us
                        .iter()
                        .map(|&u| if lobe { (4.0 * u).exp() } else { 1.0 })
                        .collect();
                    let sw: f64 = w.iter().sum();
                    let mu: f64 = us.iter().zip(&w).map(|(u, w)| u * w).sum::<f64>() / sw;
                    let var: f64 = us
                        .iter()
                        .zip(&w)
                        .map(|(u, w)| w * (u - mu).powi(2))
                        .sum::<f64>()
                        / sw;
                    // Scale so that the weighted SD is sd_deg and the weighted mean is bd.
                    let scale = sd_deg.to_radians() / var.sqrt();
                    let beta = |u: f64| bd.to_radians() + (u - mu) * scale;
                    let exact: f64 = us
                        .iter()
                        .zip(&w)
                        .map(|(&u, w)| w * dop(n, k, beta(u)))
                        .sum::<f64>()
                        / sw;
                    let b = bd.to_radians();
                    let plain = (exact - dop(n, k, b)).abs();
                    let corr = (exact - dop_spread(n, k, b, sd_deg.to_radians())).abs();
                    let o = if lobe { 2 } else { 0 };
                    worst[o] = worst[o].max(plain);
                    worst[o + 1] = worst[o + 1].max(corr);
                }
            }
            println!(
                "{name:14} sd {sd_deg}°: uniform {:.1e} -> {:.1e}, lobe {:.1e} -> {:.1e}",
                worst[0], worst[1], worst[2], worst[3]
            );
            // The correction removes most of the error wherever it matters.
            assert!(
                worst[1] < 0.25 * worst[0] + 1e-5,
                "{name} {sd_deg}: {worst:?}"
            );
            assert!(
                worst[3] < 0.5 * worst[2] + 1e-5,
                "{name} {sd_deg}: {worst:?}"
            );
        }
    }
}
