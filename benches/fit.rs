//! Fits per second of the (n, k) inversion at T = 10 (θr = 60°, θi = 35…80°), noise
//! sd 0.005, (n, k) uniform in [0.3, 3] × [0, 8] (the problem of
//! `scripts/bench/baselines.py fit-loop` / `fit-vec`): single fits on one thread, and
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
    let y = problem_sd(pixels, 0.005);
    (betas(), y)
}

fn betas() -> Vec<f64> {
    (0..T)
        .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
        .collect()
}

fn problem_sd(pixels: usize, sd: f64) -> Vec<f64> {
    let betas = betas();
    let mut rng = StdRng::seed_from_u64(1);
    let noise = Normal::new(0.0, sd).unwrap();
    let mut y = Vec::with_capacity(pixels * T);
    for _ in 0..pixels {
        let n: f64 = rng.random_range(0.3..3.0);
        let k: f64 = rng.random_range(0.0..8.0);
        for &b in &betas {
            y.push((dop(n, k, b) + noise.sample(&mut rng)).clamp(0.0, 1.0));
        }
    }
    y
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
    // The batch API on one thread: CPU cost per fit, free of the other core's load.
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    g.bench_function("batch_1_thread", |b| {
        b.iter(|| one.install(|| fit_batch(&plan, black_box(&y), None, &mut out).unwrap()))
    });
    // Weighted fits (standard errors given), single thread.
    let se = vec![0.005; y.len()];
    g.bench_function("batch_1_thread_weighted", |b| {
        b.iter(|| one.install(|| fit_batch(&plan, black_box(&y), Some(&se), &mut out).unwrap()))
    });
    // Noiseless curves (zero-residual problems converge quadratically).
    let clean = problem_sd(pixels, 0.0);
    g.bench_function("batch_1_thread_noiseless", |b| {
        b.iter(|| one.install(|| fit_batch(&plan, black_box(&clean), None, &mut out).unwrap()))
    });
    g.finish();
    c.bench_function("plan_build_T10", |b| {
        b.iter(|| FitPlan::with_defaults(black_box(&betas)).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
