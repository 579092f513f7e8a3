use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

use super::*;
use crate::classify::{BandPoint, NativeLayer, chi2_quantile};
use crate::dop::dop;
use crate::film::thin_film;

const AL: (f64, f64) = (1.558, 7.712);
const AL2O3: (f64, f64) = (1.65, 0.0);
const CU: (f64, f64) = (0.238, 3.626);
const CU2O: (f64, f64) = (2.9, 0.1);
const AU: (f64, f64) = (0.156, 3.602);
const NI: (f64, f64) = (1.99, 4.209);
const GLASS: (f64, f64) = (1.514, 0.0);

fn cfg(p: f64) -> HypothesisConfig {
    HypothesisConfig {
        confidence: p,
        nuisances: Nuisances::from_error_model(100.0, 0.0, 0.2f64.to_radians()),
        open_world: false,
    }
}

fn model(bulk: (f64, f64), layer: Option<((f64, f64), f64, f64)>) -> CandidateModel {
    CandidateModel {
        bulk: vec![bulk],
        layer: layer.map(|(index, min_nm, max_nm)| LayerModel {
            index: vec![index],
            min_nm,
            max_nm,
        }),
    }
}

fn proto(class: &str, bulk: (f64, f64), layer: Option<((f64, f64), f64, f64)>) -> MultiPrototype {
    MultiPrototype {
        class: class.into(),
        category: Some("metal".into()),
        source: "test".into(),
        bands: vec![BandPoint {
            wavelength_nm: Some(650.0),
            n: bulk.0,
            k: bulk.1,
            cov: None,
            film: None,
            layer: layer.map(|l| l.0),
        }],
        surface: layer.map(|l| NativeLayer {
            name: "oxide".into(),
            min_nm: l.1,
            max_nm: l.2,
        }),
    }
}

/// Rows of the paper's geometry (β 47.5–70°, `t` positions) simulated from `bulk` under
/// `layer` of thickness `d` nm at 650 nm, scale `s`, common offset `o` (rad), independent
/// source-angle errors (sd `angle_sd/2`), DoLP noise `se` and floor `f`.
#[allow(clippy::too_many_arguments)]
fn simulate(
    rng: &mut StdRng,
    bulk: (f64, f64),
    layer: (f64, f64),
    d: f64,
    s: f64,
    o: f64,
    t: usize,
    se: f64,
) -> Vec<HypRow> {
    let angle_sd = 0.2f64.to_radians();
    let f = 0.002;
    let noise = Normal::new(0.0, (se * se + f * f).sqrt()).unwrap();
    let ang = Normal::new(0.0, angle_sd / 2.0).unwrap();
    (0..t)
        .map(|i| {
            let beta = (47.5 + 22.5 * i as f64 / (t - 1) as f64).to_radians();
            let b = beta + o + ang.sample(rng);
            let y = s * layered_dolp(bulk, layer, d / 650.0, b) + noise.sample(rng);
            HypRow {
                beta,
                dolp: y,
                dolp_sd: (se * se + f * f).sqrt(),
                angle_sd,
                band: 0,
            }
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    /// Without a layer the stack is the paper's eq. (9), and with one it is
    /// `film::thin_film`'s signed DoLP in magnitude.
    #[test]
    fn layered_dolp_is_eq9_and_thin_film(
        n in 0.05f64..5.0, k in 0.0f64..8.0, nl in 1.2f64..3.0, kl in 0.0f64..0.5,
        d in 0.0f64..0.05, bdeg in 1.0f64..85.0,
    ) {
        let b = bdeg.to_radians();
        let bare = layered_dolp((n, k), (nl, kl), 0.0, b);
        prop_assert!((bare - dop(n, k, b)).abs() < 1e-10, "{bare} vs {}", dop(n, k, b));
        let film = thin_film((nl, kl), d, (n, k), b, 1.0).unwrap().signed_dolp().abs();
        let ours = layered_dolp((n, k), (nl, kl), d, b);
        prop_assert!((ours - film).abs() < 1e-10, "{ours} vs {film}");
    }

    /// The reported χ² is the minimum over the box: no point of the box does better
    /// (up to the interpolation's error, far below a row's σ²).
    #[test]
    fn chi2_is_the_box_minimum(
        seed in 0u64..1000, dt in 2.0f64..5.0, st in 0.98f64..1.0, ot in -0.3f64..0.3,
        dq in 2.0f64..5.0, sq in 0.98f64..1.0, oq in -0.3f64..0.3,
    ) {
        let mut rng = StdRng::seed_from_u64(seed);
        let rows = simulate(&mut rng, AL, AL2O3, dt, st, ot.to_radians(), 8, 0.003);
        let cand = model(AL, Some((AL2O3, 2.0, 5.0)));
        let fit = test_hypothesis(&rows, &[650.0], &cand, &cfg(0.95)).unwrap();
        let chi2_at = |d: f64, s: f64, o: f64| -> f64 {
            rows.iter().map(|r| {
                let m = s * exact(&cand, &[650.0], r, d, o);
                let a = 0.5 * angle_slope(&cand, &[650.0], 0, r.beta) * r.angle_sd;
                (r.dolp - m).powi(2) / (r.dolp_sd.powi(2) + a * a)
            }).sum()
        };
        let other = chi2_at(dq, sq, oq.to_radians());
        prop_assert!(fit.chi2 <= other + 1e-3, "{} > {other}", fit.chi2);
        // And it is the χ² at the reported nuisances.
        let at = chi2_at(fit.thickness_nm, fit.scale, fit.offset);
        prop_assert!((at - fit.chi2).abs() < 1e-9 * (1.0 + at), "{at} vs {}", fit.chi2);
        prop_assert!((2.0..=5.0).contains(&fit.thickness_nm));
        prop_assert!((0.98..=1.0).contains(&fit.scale));
        prop_assert!(fit.offset.abs() <= 0.3f64.to_radians() + 1e-12);
    }
}

/// The row variance's slope is the hypothesis' own model's: eq. 9's analytic slope
/// without a layer (or a layer of zero range at 0 nm), the layered curve's at mid range
/// with one, which for aluminium under 2–5 nm of Al₂O₃ differs from the bulk's.
#[test]
fn angle_slope_is_the_layered_models() {
    for bdeg in [30.0, 47.5, 60.0, 70.0, 80.0] {
        let b = f64::to_radians(bdeg);
        let bare = dop_beta_derivs(AL.0, AL.1, b).dp_dbeta;
        assert_eq!(angle_slope(&model(AL, None), &[650.0], 0, b), bare);
        let zero = model(AL, Some((AL2O3, 0.0, 0.0)));
        assert_eq!(angle_slope(&zero, &[650.0], 0, b), bare);
        let h = 1e-4;
        let fd = (layered_dolp(AL, AL2O3, 3.5 / 650.0, b + h)
            - layered_dolp(AL, AL2O3, 3.5 / 650.0, b - h))
            / (2.0 * h);
        let got = angle_slope(&model(AL, Some((AL2O3, 2.0, 5.0))), &[650.0], 0, b);
        assert!(
            (got - fd).abs() < 1e-6 * (1.0 + fd.abs()),
            "{bdeg}: {got} vs {fd}"
        );
        assert!(
            (got - bare).abs() > 1e-3 * bare.abs(),
            "{bdeg}: {got} vs {bare}"
        );
    }
}

#[test]
fn quantiles_match_the_even_table() {
    for dof in [2, 4, 6, 10] {
        for p in [0.5, 0.8, 0.95, 0.99] {
            let a = chi2_quantile_any(p, dof as f64);
            let b = chi2_quantile(p, dof);
            assert!((a - b).abs() < 1e-8 * b, "{dof} {p}: {a} vs {b}");
        }
    }
    // χ²₁(0.95) = 3.841459, χ²₅(0.95) = 11.0705 (tables).
    assert!((chi2_quantile_any(0.95, 1.0) - 3.841_459).abs() < 1e-5);
    assert!((chi2_quantile_any(0.95, 5.0) - 11.070_498).abs() < 1e-5);
    assert!(chi2_quantile_any(1.0, 3.0).is_nan() && chi2_quantile_any(0.5, 0.0).is_nan());
}

#[test]
fn normal_mass_matches_direct_values() {
    // Φ(1) − Φ(−1) = 0.682689, Φ(3) − Φ(2) = 0.0214002, deep tail Φ(−9) − Φ(−10).
    assert!((ln_normal_mass(-1.0, 1.0).exp() - 0.682_689_49).abs() < 1e-6);
    assert!((ln_normal_mass(2.0, 3.0).exp() / 0.021_400_23 - 1.0).abs() < 1e-5);
    assert!((ln_normal_mass(-3.0, -2.0).exp() / 0.021_400_23 - 1.0).abs() < 1e-5);
    let tail = ln_normal_mass(-10.0, -9.0);
    // Q(9) = 1.1285884e-19, Q(10) = 7.619853e-24.
    assert!(
        (tail - (1.128_588_4e-19f64 - 7.619_853e-24).ln()).abs() < 1e-5,
        "{tail}"
    );
}

#[test]
fn nuisance_bounds_from_the_error_model() {
    let n = Nuisances::from_error_model(100.0, 0.0, 0.2f64.to_radians());
    assert!((n.scale_min - 99.0 / 101.0).abs() < 1e-15);
    assert!((n.offset_max - 0.3f64.to_radians()).abs() < 1e-15);
    let ideal = Nuisances::from_error_model(f64::INFINITY, 0.0, 0.0);
    assert_eq!((ideal.scale_min, ideal.offset_max), (1.0, 0.0));
    let ret = Nuisances::from_error_model(f64::INFINITY, 0.1, 0.0);
    assert!((ret.scale_min - 0.1f64.cos()).abs() < 1e-15);
}

#[test]
fn noiseless_rows_recover_the_nuisances() {
    let rows: Vec<HypRow> = (0..8)
        .map(|i| {
            let beta = (47.5 + 22.5 * i as f64 / 7.0).to_radians();
            let o = 0.1f64.to_radians();
            HypRow {
                beta,
                dolp: 0.99 * layered_dolp(AL, AL2O3, 3.5 / 650.0, beta + o),
                dolp_sd: 0.003,
                angle_sd: 0.2f64.to_radians(),
                band: 0,
            }
        })
        .collect();
    let fit = test_hypothesis(
        &rows,
        &[650.0],
        &model(AL, Some((AL2O3, 2.0, 5.0))),
        &cfg(0.95),
    )
    .unwrap();
    assert!(fit.chi2 < 1e-4, "{fit:?}");
    assert!((fit.thickness_nm - 3.5).abs() < 0.05, "{fit:?}");
    assert!((fit.scale - 0.99).abs() < 1e-3, "{fit:?}");
    assert!((fit.offset.to_degrees() - 0.1).abs() < 0.01, "{fit:?}");
    assert!(fit.consistent && fit.p_value > 0.999);
}

#[test]
fn bad_input_is_an_error_naming_the_value() {
    let row = HypRow {
        beta: 1.0,
        dolp: 0.1,
        dolp_sd: 0.0,
        angle_sd: 0.0,
        band: 0,
    };
    let e = test_hypothesis(&[row], &[650.0], &model(AL, None), &cfg(0.95)).unwrap_err();
    assert!(e.to_string().contains("dolp_sd"), "{e}");
    let row = HypRow {
        dolp_sd: 0.01,
        band: 1,
        ..row
    };
    assert!(test_hypothesis(&[row], &[650.0], &model(AL, None), &cfg(0.95)).is_err());
    let row = HypRow { band: 0, ..row };
    let e = test_hypothesis(&[row], &[650.0], &model(AL, None), &cfg(1.5)).unwrap_err();
    assert!(e.to_string().contains("confidence"), "{e}");
    let e = classify_rows(
        &[row],
        &[650.0],
        &[proto("a", AL, None)],
        Some(&[-1.0]),
        &cfg(0.9),
    )
    .unwrap_err();
    assert!(e.to_string().contains("prior"), "{e}");
}

/// Coverage of the true material with interior nuisances, at two confidences, in both
/// directions (over-coverage is as wrong as under-coverage).
#[test]
fn true_material_passes_at_the_confidence() {
    let full = std::env::var("POLARID_FULL").is_ok_and(|v| v == "1");
    let n = if full { 6000 } else { 1200 };
    let cases: [(&str, (f64, f64), Option<((f64, f64), f64, f64)>); 3] = [
        ("aluminum", AL, Some((AL2O3, 2.0, 5.0))),
        ("copper", CU, Some((CU2O, 0.5, 3.0))),
        ("glass", GLASS, None),
    ];
    for (name, bulk, layer) in cases {
        let cand = model(bulk, layer);
        // Measured (1200 targets): 0.960/0.793 (aluminium), 0.962/0.802 (copper),
        // 0.954/0.796 (glass) at 95%/80%; bounds of the cheap run: the stated level plus
        // the binomial margin in both directions.
        for (p, lo, hi) in [(0.95, 0.925, 0.97), (0.8, 0.74, 0.84)] {
            let mut rng = StdRng::seed_from_u64(7);
            let mut pass = 0;
            for _ in 0..n {
                // Truths uniform over the nuisance box (the prior); the scale from an
                // extinction ratio of 100–500.
                let (li, d) = match layer {
                    Some((li, a, b)) => (li, rng.random_range(a..=b)),
                    None => ((1.5, 0.0), 0.0),
                };
                let er = rng.random_range(100.0..500.0);
                let s = (er - 1.0) / (er + 1.0);
                let o = rng.random_range(-0.3f64..0.3).to_radians();
                let t = rng.random_range(6..=10);
                let se = rng.random_range(0.002..0.005);
                let rows = simulate(&mut rng, bulk, li, d, s, o, t, se);
                let fit = test_hypothesis(&rows, &[650.0], &cand, &cfg(p)).unwrap();
                pass += usize::from(fit.consistent);
            }
            let cov = pass as f64 / n as f64;
            eprintln!("coverage {name} p={p}: {cov:.4} ({pass}/{n})");
            assert!((lo..=hi).contains(&cov), "{name} p={p}: coverage {cov}");
        }
    }
}

#[test]
fn decision_names_the_truth_and_probabilities_add_up() {
    let protos = vec![
        proto("aluminum", AL, Some((AL2O3, 2.0, 5.0))),
        proto("copper", CU, Some((CU2O, 0.5, 3.0))),
        proto("gold", AU, Some(((1.5, 0.0), 0.5, 1.5))),
        proto("nickel", NI, Some(((2.25, 0.0), 1.0, 2.0))),
    ];
    let mut rng = StdRng::seed_from_u64(3);
    let rows = simulate(&mut rng, AL, AL2O3, 3.0, 0.99, 0.001, 8, 0.003);
    let out = classify_rows(&rows, &[650.0], &protos, None, &cfg(0.95)).unwrap();
    let d = &out.decision;
    assert_eq!(d.predicted, "aluminum", "{d:?}");
    assert_eq!(d.status, Status::Ok);
    assert_eq!(out.tested.len(), 4);
    let sum: f64 = out.tested.iter().map(|c| c.probability.unwrap()).sum();
    assert!((sum - 1.0).abs() < 1e-12);
    assert_eq!(out.tested[0].class, "aluminum");
    assert!(out.tested[0].probability.unwrap() > 0.99);
    assert_eq!(d.candidates.len(), 1);
    let f = d.candidates[0].fit.unwrap();
    assert!((2.0..=5.0).contains(&f.thickness_nm));
    // A prior of 0 removes a material from the probabilities (its test still runs).
    let out = classify_rows(
        &rows,
        &[650.0],
        &protos,
        Some(&[0.0, 1.0, 1.0, 1.0]),
        &cfg(0.95),
    )
    .unwrap();
    let al = out.tested.iter().find(|c| c.class == "aluminum").unwrap();
    assert_eq!(al.probability, Some(0.0));
    // Copper and gold under their layers are one hypothesis apart at 650 nm: a copper
    // target's answer holds copper.
    let rows = simulate(&mut rng, CU, CU2O, 1.5, 0.99, 0.0, 8, 0.003);
    let out = classify_rows(&rows, &[650.0], &protos, None, &cfg(0.95)).unwrap();
    assert!(
        out.decision.candidates.iter().any(|c| c.class == "copper"),
        "{:?}",
        out.decision
    );
    // Nickel data without nickel in the list: nothing explains them.
    let rows = simulate(&mut rng, NI, (2.25, 0.0), 1.5, 0.99, 0.0, 8, 0.003);
    let out = classify_rows(&rows, &[650.0], &protos[..3], None, &cfg(0.95)).unwrap();
    assert_eq!(out.decision.predicted, UNKNOWN, "{:?}", out.decision);
    assert_eq!(out.decision.status, Status::Rejected);
    // No prototype with the rows' band.
    let out = classify_rows(&rows, &[450.0], &protos, None, &cfg(0.95)).unwrap();
    assert_eq!(out.decision.status, Status::NoCommonBand);
}

/// Several bands share one thickness and one offset: the model takes each row's band.
#[test]
fn bands_share_one_layer() {
    let wl = [450.0, 650.0];
    let bulk = [(1.383, 1.916), AU];
    let mut rows = Vec::new();
    for (b, &w) in wl.iter().enumerate() {
        for i in 0..6 {
            let beta = (47.5 + 4.5 * i as f64).to_radians();
            rows.push(HypRow {
                beta,
                dolp: 0.995 * layered_dolp(bulk[b], (1.5, 0.0), 1.0 / w, beta),
                dolp_sd: 0.003,
                angle_sd: 0.0,
                band: b,
            });
        }
    }
    let cand = CandidateModel {
        bulk: bulk.to_vec(),
        layer: Some(LayerModel {
            index: vec![(1.5, 0.0); 2],
            min_nm: 0.5,
            max_nm: 1.5,
        }),
    };
    let fit = test_hypothesis(&rows, &wl, &cand, &cfg(0.95)).unwrap();
    assert!(
        fit.chi2 < 1e-3 && (fit.thickness_nm - 1.0).abs() < 0.05,
        "{fit:?}"
    );
}

/// `|Rs − Rp|/(Rs + Rp)` of one layer from the characteristic matrix (Born & Wolf,
/// *Principles of Optics*, 7th ed., §1.6.2 eqs. 33–35 and §1.6.4 eq. 57; time factor
/// `e^{−iωt}`, `N = n + ik`): written independently of the Airy sum of [`layered_dolp`],
/// with `δ = 2π d q₁/λ` and the admittances `q` (s) and `N²/q` (p). `sign` = −1 flips the
/// layer's phase (the convention error the tests below rule out).
fn matrix_dolp(bulk: (f64, f64), layer: (f64, f64), d_waves: f64, beta: f64, sign: f64) -> f64 {
    let s2 = beta.sin().powi(2);
    let nl = Complex64::new(layer.0, layer.1);
    let nb = Complex64::new(bulk.0, bulk.1);
    let q = |n: Complex64| {
        let v = (n * n - s2).sqrt();
        if v.im < 0.0 { -v } else { v }
    };
    let (q0, q1, q2) = (Complex64::new(beta.cos(), 0.0), q(nl), q(nb));
    let delta = sign * 2.0 * PI * d_waves * q1;
    let i = Complex64::new(0.0, 1.0);
    let r2 = |y0: Complex64, y1: Complex64, y2: Complex64| {
        let (m11, m12) = (delta.cos(), -i * delta.sin() / y1);
        let (m21, m22) = (-i * y1 * delta.sin(), delta.cos());
        let r = (y0 * m11 + y0 * y2 * m12 - m21 - y2 * m22)
            / (y0 * m11 + y0 * y2 * m12 + m21 + y2 * m22);
        r.norm_sqr()
    };
    let rs = r2(q0, q1, q2);
    let rp = r2(1.0 / q0, nl * nl / q1, nb * nb / q2);
    ((rs - rp) / (rs + rp)).abs()
}

/// The layer's phase convention, checked against the characteristic matrix: equal for
/// metals, semiconductors and glasses under thin and thick layers; and the flipped phase
/// is unphysical (an absorbing layer on glass then reflects more than it receives), so
/// the agreement is with the right convention.
#[test]
fn layered_dolp_matches_the_characteristic_matrix() {
    let cases = [
        (AL, AL2O3),
        (CU, CU2O),
        (NI, (2.3, 0.0)),
        (GLASS, (1.5, 0.0)),
        ((3.85, 0.016), (1.46, 0.0)),
    ];
    for (bulk, layer) in cases {
        for d_nm in [0.5, 3.0, 15.0, 120.0] {
            for bdeg in [10.0, 47.5, 56.0, 62.0, 70.0, 85.0] {
                let b = f64::to_radians(bdeg);
                let ours = layered_dolp(bulk, layer, d_nm / 650.0, b);
                let other = matrix_dolp(bulk, layer, d_nm / 650.0, b, 1.0);
                assert!(
                    (ours - other).abs() < 1e-9,
                    "{bulk:?} under {d_nm} nm of {layer:?} at {bdeg}°: {ours} vs {other}"
                );
            }
        }
    }
    // Passivity: R_s of an absorbing layer (1.5 + 1i) on glass at 17°, over thickness.
    let rs = |d_waves: f64, sign: f64| {
        let b = 0.3f64;
        let q = |n: Complex64| {
            let v = (n * n - b.sin().powi(2)).sqrt();
            if v.im < 0.0 { -v } else { v }
        };
        let (q0, q1, q2) = (
            Complex64::new(b.cos(), 0.0),
            q(Complex64::new(1.5, 1.0)),
            q(Complex64::new(1.5, 0.0)),
        );
        let delta = sign * 2.0 * PI * d_waves * q1;
        let i = Complex64::new(0.0, 1.0);
        let (m11, m12, m21, m22) = (
            delta.cos(),
            -i * delta.sin() / q1,
            -i * q1 * delta.sin(),
            delta.cos(),
        );
        ((q0 * m11 + q0 * q2 * m12 - m21 - q2 * m22) / (q0 * m11 + q0 * q2 * m12 + m21 + q2 * m22))
            .norm_sqr()
    };
    let max = |sign: f64| {
        (0..400)
            .map(|j| rs(j as f64 * 0.0077, sign))
            .fold(0.0, f64::max)
    };
    assert!(max(1.0) < 1.0, "passive: {}", max(1.0));
    assert!(
        max(-1.0) > 1.0,
        "the flipped phase is a gain medium: {}",
        max(-1.0)
    );
}

#[test]
#[allow(clippy::excessive_precision)] // reference quantiles to 16 digits
fn halton_and_normal_quantile() {
    assert_eq!(halton(1, 2), 0.5);
    assert_eq!(halton(6, 2), 0.375);
    assert!((halton(5, 3) - 7.0 / 9.0).abs() < 1e-15);
    for (p, z) in [
        (0.5, 0.0),
        (0.975, 1.959_963_984_540_054),
        (0.9, 1.281_551_565_544_601),
        (1e-6, -4.753_424_308_822_899),
        (0.01, -2.326_347_874_040_841),
    ] {
        let got = normal_quantile(p);
        assert!(
            (got - z).abs() < 1e-8 * (1.0 + z.abs()),
            "{p}: {got} vs {z}"
        );
    }
}

/// A transparent material passing alone is an index, not a name, in an open world (a
/// library): LSAT-like rows (n 2.02) against a list holding a material of n 2.0 are
/// `ambiguous`, with that material the only candidate and its category; the same list
/// as a closed world (a trained model) names it. An absorbing material alone stands.
#[test]
fn a_lone_transparent_answer_is_an_index_in_an_open_world() {
    let mut zno = proto("ZnO", (2.0, 0.0), Some(((1.5, 0.0), 0.0, 2.0)));
    zno.category = Some("dielectric".into());
    let protos = vec![
        proto("aluminum", AL, Some((AL2O3, 2.0, 5.0))),
        proto("copper", CU, Some((CU2O, 0.5, 3.0))),
        zno,
    ];
    let open = HypothesisConfig {
        open_world: true,
        ..cfg(0.95)
    };
    let mut rng = StdRng::seed_from_u64(11);
    let rows = simulate(&mut rng, (2.02, 0.0), (1.5, 0.0), 1.0, 0.99, 0.0, 8, 0.003);
    let closed = classify_rows(&rows, &[650.0], &protos, None, &cfg(0.95)).unwrap();
    assert_eq!(closed.decision.predicted, "ZnO", "{:?}", closed.decision);
    assert_eq!(closed.decision.status, Status::Ok);
    let out = classify_rows(&rows, &[650.0], &protos, None, &open).unwrap();
    let d = &out.decision;
    assert_eq!(
        (d.predicted.as_str(), &d.status),
        (AMBIGUOUS, &Status::Ambiguous)
    );
    assert_eq!(d.candidates.len(), 1);
    assert_eq!(d.candidates[0].class, "ZnO");
    assert_eq!(d.set_category.as_deref(), Some("dielectric"));
    assert!(d.reason.contains("n 2.000 at 650 nm"), "{}", d.reason);
    // Aluminium passing alone is named in the open world too.
    let rows = simulate(&mut rng, AL, AL2O3, 3.0, 0.99, 0.001, 8, 0.003);
    let out = classify_rows(&rows, &[650.0], &protos, None, &open).unwrap();
    assert_eq!(
        (out.decision.predicted.as_str(), &out.decision.status),
        ("aluminum", &Status::Ok)
    );
}
