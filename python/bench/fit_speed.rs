//! Rust side of the `fit_nk` speed comparison (python/bench/fit_speed.py runs it).
//!
//! `fit_speed DATA.f64 T REPS`: reads `P × T` little-endian f64 DoLP values (pixel-major)
//! and `T` β values in degrees from `DATA.f64.beta`, builds the plan once (not timed),
//! then times `fit_batch` over all pixels `REPS` times and prints the median time per
//! pixel in nanoseconds, the fastest repetition's, and a checksum of the fitted n and k.

use std::time::Instant;

use polarid_core::fit::{FitOptions, FitPlan, NkFit, fit_batch};

fn read_f64(path: &str) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, data, t, reps] = &args[..] else {
        eprintln!("usage: fit_speed DATA.f64 T REPS");
        std::process::exit(2);
    };
    let t: usize = t.parse().expect("T");
    let reps: usize = reps.parse().expect("REPS");
    let y = read_f64(data);
    let betas: Vec<f64> = read_f64(&format!("{data}.beta"))
        .iter()
        .map(|b| b.to_radians())
        .collect();
    assert_eq!(betas.len(), t);
    let p = y.len() / t;
    let plan = FitPlan::new(&betas, FitOptions::default()).expect("plan");
    let mut out = vec![NkFit::default(); p];
    let mut times = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = Instant::now();
        fit_batch(&plan, &y, None, &mut out).expect("fit");
        times.push(t0.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let med = times[times.len() / 2];
    let min = times[0];
    let sum: f64 = out
        .iter()
        .map(|f| f.n + f.k)
        .filter(|v| v.is_finite())
        .sum();
    println!(
        "{:.3} {:.3} {sum:.12e}",
        med * 1e9 / p as f64,
        min * 1e9 / p as f64
    );
}
