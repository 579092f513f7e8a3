//! Fits per second of the (n, k) inversion at T = 10 (θr = 60°, θi = 35…80°), noise
//! sd 0.005, (n, k) uniform in [0.3, 3] × [0, 8] (the problem of
//! `shared/bench/baselines.py fit-loop` / `fit-vec`): single fits on one thread, and
//! the rayon batch API on all cores. Throughput is reported in elements = fits.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use polarid_core::dop::dop;
use polarid_core::fit::{FitPlan, NkFit, fit_batch};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::hint::black_box;

const T: usize = 10;

fn problem(pixels: usize) -> (Vec<f64>, Vec<f64>) {
    let betas: Vec<f64> = (0..T)
        .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
        .collect();
    let mut rng = StdRng::seed_from_u64(1);
    let noise = Normal::new(0.0, 0.005).unwrap();
    let mut y = Vec::with_capacity(pixels * T);
    for _ in 0..pixels {
        let n: f64 = rng.random_range(0.3..3.0);
        let k: f64 = rng.random_range(0.0..8.0);
        for &b in &betas {
            y.push((dop(n, k, b) + noise.sample(&mut rng)).clamp(0.0, 1.0));
        }
    }
    (betas, y)
}

fn bench(c: &mut Criterion) {
    let (betas, y) = problem(20_000);
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let pixels = y.len() / T;
    let mut g = c.benchmark_group("fit_T10_sd0.005");
    g.sample_size(10);
    g.throughput(Throughput::Elements(pixels as u64));
    g.bench_function("single_thread", |b| {
        let mut ws = plan.workspace();
        b.iter(|| {
            let mut acc = 0.0;
            for px in y.chunks_exact(T) {
                acc += plan.fit_with(black_box(px), None, &mut ws).unwrap().n;
            }
            acc
        })
    });
    let mut out = vec![NkFit::default(); pixels];
    g.bench_function("batch_rayon", |b| {
        b.iter(|| fit_batch(&plan, black_box(&y), None, &mut out).unwrap())
    });
    g.finish();
    c.bench_function("plan_build_T10", |b| {
        b.iter(|| FitPlan::with_defaults(black_box(&betas)).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
