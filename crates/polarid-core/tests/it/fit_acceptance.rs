//! Acceptance tests of the (n, k) inversion (issue 4), at the paper's geometry:
//! θr = 60°, θi = 35…80° in 5° steps, β = (θi + 60°)/2 (eq. 10).
//!
//! Run in release mode (`cargo test --release`): the large random sets take a few
//! seconds there.

use polarid_core::CoreError;
use polarid_core::dop::dop;
use polarid_core::fit::{
    FitBounds, FitOptions, FitPlan, FitStatus, NkFit, crb, crb_weighted, fit_batch, fit_nk,
};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

fn paper_betas() -> Vec<f64> {
    (0..10)
        .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
        .collect()
}

fn curve(n: f64, k: f64, betas: &[f64]) -> Vec<f64> {
    betas.iter().map(|&b| dop(n, k, b)).collect()
}

/// Random (n, k) in [0.2, 3] × [0, 8] and their DoLP curves, with optional noise
/// (clamped to [0, 1] as a measured DoLP is).
fn random_set(count: usize, sd: f64, seed: u64, betas: &[f64]) -> (Vec<(f64, f64)>, Vec<f64>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sd.max(1e-300)).unwrap();
    let mut truth = Vec::with_capacity(count);
    let mut y = Vec::with_capacity(count * betas.len());
    for _ in 0..count {
        let n: f64 = rng.random_range(0.2..3.0);
        let k: f64 = rng.random_range(0.0..8.0);
        truth.push((n, k));
        for &b in betas {
            let e = if sd > 0.0 {
                noise.sample(&mut rng)
            } else {
                0.0
            };
            y.push((dop(n, k, b) + e).clamp(0.0, 1.0));
        }
    }
    (truth, y)
}

fn inside(f: &NkFit, b: &FitBounds) -> bool {
    f.n >= b.n_min && f.n <= b.n_max && f.k >= b.k_min && f.k <= b.k_max
}

#[test]
fn noiseless_random_recovered_to_1e6() {
    let betas = paper_betas();
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let (truth, y) = random_set(100_000, 0.0, 11, &betas);
    let mut out = vec![NkFit::default(); truth.len()];
    fit_batch(&plan, &y, None, &mut out).unwrap();
    let mut bad = Vec::new();
    for (i, (f, &(n, k))) in out.iter().zip(&truth).enumerate() {
        if !((f.n - n).abs() <= 1e-6 && (f.k - k).abs() <= 1e-6) {
            bad.push((i, n, k, f.n, f.k, f.status));
        }
    }
    assert!(
        bad.is_empty(),
        "{} of {} not recovered to 1e-6, first: {:?}",
        bad.len(),
        truth.len(),
        &bad[..bad.len().min(5)]
    );
}

#[test]
fn noisy_random_reach_global_optimum_and_stay_in_box() {
    let betas = paper_betas();
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let bounds = plan.options().bounds;
    let (truth, y) = random_set(100_000, 0.005, 12, &betas);
    let mut out = vec![NkFit::default(); truth.len()];
    fit_batch(&plan, &y, None, &mut out).unwrap();
    let t = betas.len();
    let mut good = 0usize;
    let mut worst = Vec::new();
    for (i, (f, &(n, k))) in out.iter().zip(&truth).enumerate() {
        let yi = &y[i * t..(i + 1) * t];
        // Never outside the box; on its edge (other than k = 0) only with a status.
        assert!(inside(f, &bounds), "fit {i} left the box: {f:?}");
        let on_edge = f.n <= bounds.n_min || f.n >= bounds.n_max || f.k >= bounds.k_max;
        if on_edge {
            assert_eq!(
                f.status,
                FitStatus::AtBound,
                "fit {i} on the edge silently: {f:?}"
            );
        }
        let c_true = plan.cost(n, k, yi, None);
        let c_fit = plan.cost(f.n, f.k, yi, None);
        assert!((c_fit - f.cost).abs() <= 1e-9 * c_fit.max(1e-300) + 1e-15);
        if c_fit <= c_true * (1.0 + 1e-12) + 1e-18 {
            good += 1;
        } else if worst.len() < 5 {
            worst.push((n, k, *f, c_true));
        }
    }
    let rate = good as f64 / truth.len() as f64;
    assert!(
        rate >= 0.9999,
        "global-optimum rate {rate}, failures: {worst:?}"
    );
}

/// Noisy trials at one (n, k): RMSE of the estimates and RMS of the reported errors.
fn trials(n: f64, k: f64, sd: f64, count: usize, seed: u64, with_se: bool) -> (f64, f64, f64, f64) {
    let betas = paper_betas();
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let clean = curve(n, k, &betas);
    let mut rng = StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sd).unwrap();
    let se = vec![sd; betas.len()];
    let (mut e2n, mut e2k, mut s2n, mut s2k) = (0.0, 0.0, 0.0, 0.0);
    let mut ws = plan.workspace();
    for _ in 0..count {
        let y: Vec<f64> = clean
            .iter()
            .map(|&p| (p + noise.sample(&mut rng)).clamp(0.0, 1.0))
            .collect();
        let f = plan
            .fit_with(&y, with_se.then_some(&se[..]), &mut ws)
            .unwrap();
        assert_eq!(f.status, FitStatus::Ok, "({n}, {k}): {f:?}");
        e2n += (f.n - n).powi(2);
        e2k += (f.k - k).powi(2);
        s2n += f.n_se * f.n_se;
        s2k += f.k_se * f.k_se;
    }
    let c = count as f64;
    (
        (e2n / c).sqrt(),
        (e2k / c).sqrt(),
        (s2n / c).sqrt(),
        (s2k / c).sqrt(),
    )
}

#[test]
fn efficient_where_crb_on_k_is_small() {
    let betas = paper_betas();
    let sd = 0.005;
    // (n, k) points whose CRB on k is below 0.05 at this geometry and noise.
    let points = [(1.5, 0.3), (1.39, 0.34), (2.0, 1.0), (1.0, 1.0), (0.8, 2.0)];
    for (idx, &(n, k)) in points.iter().enumerate() {
        let bound = crb(n, k, &betas, sd).unwrap();
        assert!(bound.sd_k < 0.05, "({n}, {k}): CRB on k {}", bound.sd_k);
        for with_se in [false, true] {
            let (rmse_n, rmse_k, se_n, se_k) = trials(n, k, sd, 1000, 100 + idx as u64, with_se);
            let eff_k = rmse_k / bound.sd_k;
            assert!(
                (eff_k - 1.0).abs() <= 0.15,
                "({n}, {k}) se given {with_se}: RMSE k {rmse_k} vs CRB {} (ratio {eff_k})",
                bound.sd_k
            );
            // Reported standard errors against the observed scatter.
            let ratio_k = se_k / rmse_k;
            let ratio_n = se_n / rmse_n;
            assert!(
                (ratio_k - 1.0).abs() <= 0.2 && (ratio_n - 1.0).abs() <= 0.2,
                "({n}, {k}) se given {with_se}: reported se n {se_n} k {se_k}, observed {rmse_n} {rmse_k}"
            );
        }
    }
}

#[test]
fn copper_converges_to_global_optimum() {
    let betas = paper_betas();
    let (n, k) = (0.4, 2.95);
    let f = fit_nk(&betas, &curve(n, k, &betas), None).unwrap();
    assert_eq!(f.status, FitStatus::Ok, "{f:?}");
    assert!((f.n - n).abs() < 1e-8 && (f.k - k).abs() < 1e-8, "{f:?}");
    // With noise: at or below the cost of the truth in every trial.
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let clean = curve(n, k, &betas);
    let mut rng = StdRng::seed_from_u64(5);
    let noise = Normal::new(0.0, 0.005).unwrap();
    for _ in 0..2000 {
        let y: Vec<f64> = clean.iter().map(|&p| p + noise.sample(&mut rng)).collect();
        let f = plan.fit(&y, None).unwrap();
        let c_true = plan.cost(n, k, &y, None);
        assert!(
            f.cost <= c_true * (1.0 + 1e-12),
            "{f:?} vs truth cost {c_true}"
        );
    }
    // The paper's narrower range (θi 35…70°) too.
    let narrow: Vec<f64> = betas[..8].to_vec();
    let f = fit_nk(&narrow, &curve(n, k, &narrow), None).unwrap();
    assert!((f.n - n).abs() < 1e-8 && (f.k - k).abs() < 1e-8, "{f:?}");
}

#[test]
fn weighted_fit_uses_standard_errors() {
    let betas = paper_betas();
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let (n, k) = (1.24, 0.9);
    let mut y = curve(n, k, &betas);
    // One wild measurement with a huge standard error is ignored by the weighted fit.
    y[3] = (y[3] + 0.3).min(1.0);
    let mut se = vec![1e-4; betas.len()];
    se[3] = 1e3;
    let f = plan.fit(&y, Some(&se)).unwrap();
    assert!((f.n - n).abs() < 1e-5 && (f.k - k).abs() < 1e-5, "{f:?}");
    let g = plan.fit(&y, None).unwrap();
    assert!((g.n - n).abs() > 1e-3 || (g.k - k).abs() > 1e-3, "{g:?}");
}

#[test]
fn errors_for_bad_input() {
    let betas = paper_betas();
    // Fewer than 3 measurements.
    let e = fit_nk(&betas[..2], &[0.5, 0.6], None).unwrap_err();
    assert!(
        matches!(
            e,
            CoreError::TooFew {
                needed: 3,
                got: 2,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("at least 3"), "{e}");
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let mut y = curve(1.5, 0.5, &betas);
    y[4] = f64::NAN;
    let e = plan.fit(&y, None).unwrap_err();
    assert!(
        matches!(e, CoreError::NonFinite { name: "dolp", .. }),
        "{e}"
    );
    y[4] = 1.2;
    let e = plan.fit(&y, None).unwrap_err();
    assert!(
        matches!(e, CoreError::OutOfRange { name: "dolp", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("1.2"), "{e}");
    y[4] = -0.01;
    assert!(plan.fit(&y, None).is_err());
    y[4] = 0.3;
    assert!(matches!(
        plan.fit(&y[..9], None).unwrap_err(),
        CoreError::LengthMismatch { .. }
    ));
    let mut se = vec![0.01; betas.len()];
    se[0] = 0.0;
    assert!(plan.fit(&y, Some(&se)).is_err());
    se[0] = f64::INFINITY;
    assert!(plan.fit(&y, Some(&se)).is_err());
    // Non-finite angle.
    assert!(FitPlan::with_defaults(&[0.5, f64::NAN, 0.7]).is_err());
    // In a batch a bad pixel is flagged, the others are fitted.
    let mut batch = curve(1.5, 0.5, &betas);
    batch.extend(curve(2.0, 1.0, &betas));
    batch[12] = f64::NAN;
    let mut out = vec![NkFit::default(); 2];
    fit_batch(&plan, &batch, None, &mut out).unwrap();
    assert_eq!(out[0].status, FitStatus::Ok);
    assert_eq!(out[1].status, FitStatus::InvalidInput);
    assert!(out[1].n.is_nan());
    assert!(fit_batch(&plan, &batch[..15], None, &mut out).is_err());
}

#[test]
fn ill_conditioned_cases_are_flagged() {
    // Fewer than 3 distinct β.
    let b = [1.0, 1.0, 1.2, 1.2];
    let f = fit_nk(&b, &curve(1.5, 0.5, &b), None).unwrap();
    assert_eq!(f.status, FitStatus::IllConditioned, "{f:?}");
    assert!(f.reason.contains("distinct"), "{}", f.reason);
    // Too narrow a β range.
    let b = [1.0, 1.01, 1.02, 1.03];
    let f = fit_nk(&b, &curve(1.5, 0.5, &b), None).unwrap();
    assert_eq!(f.status, FitStatus::IllConditioned, "{f:?}");
    // A flat (fully depolarized) DoLP curve.
    let betas = paper_betas();
    let f = fit_nk(&betas, &vec![0.0; betas.len()], None).unwrap();
    assert_eq!(f.status, FitStatus::IllConditioned, "{f:?}");
    assert_eq!(f.status.as_str(), "ill_conditioned");
    assert!(!f.reason.is_empty());
}

#[test]
fn solution_on_the_box_edge_is_reported() {
    let betas = paper_betas();
    let opts = FitOptions {
        bounds: FitBounds {
            n_min: 0.01,
            n_max: 10.0,
            k_min: 0.0,
            k_max: 2.0,
        },
        ..Default::default()
    };
    let plan = FitPlan::new(&betas, opts).unwrap();
    let f = plan.fit(&curve(0.4, 2.95, &betas), None).unwrap();
    assert_eq!(f.status, FitStatus::AtBound, "{f:?}");
    assert_eq!(f.status.as_str(), "at_bound");
    assert_eq!(f.k, 2.0);
    // A dielectric (k = 0) is not "at bound": k = 0 is where the model is symmetric.
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let f = plan.fit(&curve(1.5, 0.0, &betas), None).unwrap();
    assert_eq!(f.status, FitStatus::Ok, "{f:?}");
    assert!((f.n - 1.5).abs() < 1e-8 && f.k < 1e-6, "{f:?}");
    assert!(f.k_se.is_finite());
}

#[test]
fn crb_matches_finite_difference_fisher_information() {
    let betas = paper_betas();
    for &(n, k) in &[(1.5, 0.3), (0.4, 2.95), (2.0, 1.0)] {
        let sd = 0.01;
        let (mut f00, mut f01, mut f11) = (0.0, 0.0, 0.0);
        let h = 1e-6;
        for &b in &betas {
            let dn = (dop(n + h, k, b) - dop(n - h, k, b)) / (2.0 * h);
            let dk = (dop(n, k + h, b) - dop(n, k - h, b)) / (2.0 * h);
            f00 += dn * dn / (sd * sd);
            f01 += dn * dk / (sd * sd);
            f11 += dk * dk / (sd * sd);
        }
        let det = f00 * f11 - f01 * f01;
        let c = crb(n, k, &betas, sd).unwrap();
        assert!((c.var_n / (f11 / det) - 1.0).abs() < 1e-5, "{c:?}");
        assert!((c.var_k / (f00 / det) - 1.0).abs() < 1e-5, "{c:?}");
        assert!((c.cov_nk / (-f01 / det) - 1.0).abs() < 1e-5, "{c:?}");
        // Scales with the noise variance; per-measurement sds agree.
        let c2 = crb(n, k, &betas, 2.0 * sd).unwrap();
        assert!((c2.sd_k / c.sd_k - 2.0).abs() < 1e-12);
        let cw = crb_weighted(n, k, &betas, &vec![sd; betas.len()]).unwrap();
        assert!((cw.var_k / c.var_k - 1.0).abs() < 1e-12);
    }
    assert!(crb(1.5, 0.3, &betas, 0.0).is_err());
    assert!(crb(1.5, -0.3, &betas, 0.01).is_err());
}
