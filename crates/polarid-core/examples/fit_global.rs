//! How often the (n, k) fit misses the global optimum, on six kinds of problems: a fit
//! "misses" when its cost is above the cost at the true (n, k) (the criterion of
//! `scripts/bench/baselines.py`, `c_fit <= c_true (1 + 1e-9) + 1e-14`; `strict` uses
//! `1e-12`, `1e-18`). Prints one line per problem: misses, worst cost ratio of a miss,
//! mean model evaluations and wall time per fit (all cores).
//!
//! ```text
//! cargo run --release -p polarid-core --example fit_global -- --pixels 100000 --candidates 1
//! ```
//!
//! Problems: `bench` (the benchmark: n ~ U[0.3, 3], k ~ U[0, 8], T = 10, θr = 60°,
//! θi = 35…80°, sd 0.005), `wide` (the whole default box), `noisy` (sd 0.03), `t4`
//! (four angles), `narrow` (six angles over 15°), `low` (eight low angles).
//! `--candidates C` sets `FitOptions::max_candidates` (competing-basin starts).

use polarid_core::dop::dop;
use polarid_core::fit::{FitOptions, FitPlan, NkFit, fit_batch};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

fn usage(msg: &str) -> ! {
    eprintln!("fit_global: {msg}\nusage: fit_global [--pixels N] [--candidates C] [--seed S]");
    std::process::exit(2)
}

fn paper(t: usize, first: f64, step: f64, theta_r: f64) -> Vec<f64> {
    (0..t)
        .map(|i| ((first + step * i as f64 + theta_r) / 2.0f64).to_radians())
        .collect()
}

fn main() {
    let (mut pixels, mut candidates, mut seed) = (100_000usize, 1usize, 7u64);
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let val = it.next().unwrap_or_else(|| usage("missing value"));
        fn num<V: std::str::FromStr>(flag: &str, val: &str) -> V {
            val.parse()
                .unwrap_or_else(|_| usage(&format!("bad value for {flag}: {val}")))
        }
        match flag.as_str() {
            "--pixels" => pixels = num(&flag, &val),
            "--candidates" => candidates = num(&flag, &val),
            "--seed" => seed = num(&flag, &val),
            _ => usage(&format!("unknown option {flag}")),
        }
    }
    if pixels == 0 || candidates == 0 {
        usage("--pixels and --candidates must be positive");
    }
    let deg = |d: f64| d.to_radians();
    // (name, n range, k range, noise sd, betas)
    let cases: Vec<(&str, (f64, f64), (f64, f64), f64, Vec<f64>)> = vec![
        (
            "bench",
            (0.3, 3.0),
            (0.0, 8.0),
            0.005,
            paper(10, 35.0, 5.0, 60.0),
        ),
        (
            "wide",
            (0.01, 10.0),
            (0.0, 15.0),
            0.005,
            paper(10, 35.0, 5.0, 60.0),
        ),
        (
            "noisy",
            (0.3, 3.0),
            (0.0, 8.0),
            0.03,
            paper(10, 35.0, 5.0, 60.0),
        ),
        (
            "t4",
            (0.3, 3.0),
            (0.0, 8.0),
            0.005,
            vec![deg(30.0), deg(45.0), deg(55.0), deg(70.0)],
        ),
        (
            "narrow",
            (0.3, 3.0),
            (0.0, 8.0),
            0.005,
            paper(6, 40.0, 3.0, 50.0),
        ),
        (
            "low",
            (0.3, 3.0),
            (0.0, 8.0),
            0.005,
            paper(8, 10.0, 5.0, 20.0),
        ),
    ];
    let opts = FitOptions {
        max_candidates: candidates,
        ..Default::default()
    };
    for (name, (n0, n1), (k0, k1), sd, betas) in cases {
        let t = betas.len();
        let plan = FitPlan::new(&betas, opts).unwrap_or_else(|e| usage(&e.to_string()));
        let mut rng = StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, sd).unwrap_or_else(|_| usage("bad noise"));
        let mut truth = Vec::with_capacity(pixels);
        let mut y = Vec::with_capacity(pixels * t);
        for _ in 0..pixels {
            let n: f64 = rng.random_range(n0..n1);
            let k: f64 = rng.random_range(k0..k1);
            truth.push((n, k));
            for &b in &betas {
                y.push((dop(n, k, b) + noise.sample(&mut rng)).clamp(0.0, 1.0));
            }
        }
        let mut out = vec![NkFit::default(); pixels];
        let t0 = std::time::Instant::now();
        fit_batch(&plan, &y, None, &mut out).unwrap_or_else(|e| usage(&e.to_string()));
        let dt = t0.elapsed().as_secs_f64();
        let (mut miss, mut miss_strict, mut worst, mut evals) = (0usize, 0usize, 1.0f64, 0u64);
        for (p, f) in out.iter().enumerate() {
            let yp = &y[p * t..(p + 1) * t];
            let ct = plan.cost(truth[p].0, truth[p].1, yp, None);
            let cf = plan.cost(f.n, f.k, yp, None);
            if !(cf <= ct * (1.0 + 1e-9) + 1e-14) {
                miss += 1;
                worst = worst.max(cf / ct);
            }
            miss_strict += usize::from(!(cf <= ct * (1.0 + 1e-12) + 1e-18));
            evals += u64::from(f.evaluations);
        }
        println!(
            "{name:8} T={t:2} misses {miss:5} (strict {miss_strict:5}) of {pixels}, worst cost ratio {worst:8.3}, evaluations {:.3}, {:.3} us/fit",
            evals as f64 / pixels as f64,
            dt * 1e6 / pixels as f64
        );
    }
}
