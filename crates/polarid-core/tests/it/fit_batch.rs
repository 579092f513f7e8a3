//! The batch API gives exactly the single-fit results (same code path per pixel, in
//! parallel), weighted and unweighted, and reaches the global optimum on the problem
//! of `scripts/bench/baselines.py` (n ~ U[0.3, 3], k ~ U[0, 8], T = 10, sd 0.005).

use polarid_core::dop::dop;
use polarid_core::fit::{FitPlan, NkFit, fit_batch};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

const T: usize = 10;

fn betas() -> Vec<f64> {
    (0..T)
        .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
        .collect()
}

fn problem(pixels: usize, seed: u64) -> (Vec<(f64, f64)>, Vec<f64>) {
    let b = betas();
    let mut rng = StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.005).unwrap();
    let mut truth = Vec::new();
    let mut y = Vec::new();
    for _ in 0..pixels {
        let n: f64 = rng.random_range(0.3..3.0);
        let k: f64 = rng.random_range(0.0..8.0);
        truth.push((n, k));
        for &bt in &b {
            y.push((dop(n, k, bt) + noise.sample(&mut rng)).clamp(0.0, 1.0));
        }
    }
    (truth, y)
}

#[test]
fn batch_equals_single_fits_weighted_and_unweighted() {
    let plan = FitPlan::with_defaults(&betas()).unwrap();
    let (_, y) = problem(3000, 21);
    let se: Vec<f64> = (0..y.len())
        .map(|i| 0.004 + 0.002 * (i % 3) as f64)
        .collect();
    for weighted in [false, true] {
        let s = weighted.then_some(&se[..]);
        let mut out = vec![NkFit::default(); 3000];
        fit_batch(&plan, &y, s, &mut out).unwrap();
        let mut ws = plan.workspace();
        for (p, f) in out.iter().enumerate() {
            let g = plan
                .fit_with(
                    &y[p * T..(p + 1) * T],
                    s.map(|s| &s[p * T..(p + 1) * T]),
                    &mut ws,
                )
                .unwrap();
            assert_eq!(*f, g, "pixel {p} weighted {weighted}");
            // The reported cost and rms residual are those of the returned (n, k).
            let c = plan.cost(
                f.n,
                f.k,
                &y[p * T..(p + 1) * T],
                s.map(|s| &s[p * T..(p + 1) * T]),
            );
            assert!(
                (c - f.cost).abs() <= 1e-9 * c + 1e-15,
                "pixel {p}: {c} vs {f:?}"
            );
            let ss = plan.cost(f.n, f.k, &y[p * T..(p + 1) * T], None);
            assert!(
                ((ss / T as f64).sqrt() - f.rms_residual).abs() <= 1e-9 * f.rms_residual + 1e-15
            );
        }
    }
}

#[test]
fn baseline_problem_reaches_global_optimum() {
    let plan = FitPlan::with_defaults(&betas()).unwrap();
    let (truth, y) = problem(50_000, 22);
    let mut out = vec![NkFit::default(); truth.len()];
    fit_batch(&plan, &y, None, &mut out).unwrap();
    let mut good = 0;
    for (p, (f, &(n, k))) in out.iter().zip(&truth).enumerate() {
        let yp = &y[p * T..(p + 1) * T];
        let c_true = plan.cost(n, k, yp, None);
        good += usize::from(f.cost <= c_true * (1.0 + 1e-12) + 1e-18);
    }
    // The numpy batched LM of baselines.py reaches 99.89 %.
    let rate = good as f64 / truth.len() as f64;
    assert!(rate >= 0.9999, "global-optimum rate {rate}");
}
