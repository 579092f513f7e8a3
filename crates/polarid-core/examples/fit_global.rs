//! scratch: global-optimum rate under several distributions (MODE env decides variant)
use polarid_core::dop::dop;
use polarid_core::fit::{FitBounds, FitOptions, FitPlan, NkFit, fit_batch};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

fn main() {
    let mode: u8 = std::env::var("MODE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let pixels: usize = std::env::var("PIX")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200000);
    let cases: Vec<(&str, f64, f64, f64, f64, f64, Vec<f64>)> = vec![
        (
            "bench",
            0.3,
            3.0,
            0.0,
            8.0,
            0.005,
            (0..10)
                .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
                .collect(),
        ),
        (
            "wide",
            0.01,
            10.0,
            0.0,
            15.0,
            0.005,
            (0..10)
                .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
                .collect(),
        ),
        (
            "noisy",
            0.3,
            3.0,
            0.0,
            8.0,
            0.03,
            (0..10)
                .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
                .collect(),
        ),
        (
            "t4",
            0.3,
            3.0,
            0.0,
            8.0,
            0.005,
            vec![
                30f64.to_radians(),
                45f64.to_radians(),
                55f64.to_radians(),
                70f64.to_radians(),
            ],
        ),
        (
            "narrow",
            0.3,
            3.0,
            0.0,
            8.0,
            0.005,
            (0..6)
                .map(|i| ((40.0 + 3.0 * i as f64 + 50.0) / 2.0f64).to_radians())
                .collect(),
        ),
        (
            "low",
            0.3,
            3.0,
            0.0,
            8.0,
            0.005,
            (0..8)
                .map(|i| ((10.0 + 5.0 * i as f64 + 20.0) / 2.0f64).to_radians())
                .collect(),
        ),
    ];
    for (name, n0, n1, k0, k1, sd, betas) in cases {
        let t = betas.len();
        let plan = FitPlan::new(
            &betas,
            FitOptions {
                bounds: FitBounds::default(),
                ..Default::default()
            },
        )
        .unwrap();
        let mut rng = StdRng::seed_from_u64(7);
        let noise = Normal::new(0.0, sd).unwrap();
        let mut truth = vec![];
        let mut y = vec![];
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
        fit_batch(&plan, &y, None, &mut out).unwrap();
        let dt = t0.elapsed().as_secs_f64();
        let mut fail = 0;
        let mut fail_strict = 0;
        let mut ev = 0u64;
        let mut worst: f64 = 0.0;
        for (p, f) in out.iter().enumerate() {
            let yp = &y[p * t..(p + 1) * t];
            let ct = plan.cost(truth[p].0, truth[p].1, yp, None);
            let cf = plan.cost(f.n, f.k, yp, None);
            if !(cf <= ct * (1.0 + 1e-9) + 1e-14) {
                fail += 1;
                worst = worst.max(cf / ct);
                if fail <= 4 {
                    eprintln!(
                        "  {name}: truth {:?} fit {} {} cost {:.3e} vs {:.3e} status {} ev {} starts {} y {:?}",
                        truth[p], f.n, f.k, cf, ct, f.status, f.evaluations, f.starts, yp
                    );
                }
            }
            if !(cf <= ct * (1.0 + 1e-12) + 1e-18) {
                fail_strict += 1;
            }
            ev += f.evaluations as u64;
        }
        if std::env::var_os("HIST").is_some() {
            let mut h = [0usize; 40];
            for f in &out {
                h[(f.evaluations as usize).min(39)] += 1;
            }
            eprintln!("{name} evals hist {:?}", &h[..25]);
            let mut hi = [0usize; 40];
            for f in &out {
                hi[(f.iterations as usize).min(39)] += 1;
            }
            eprintln!("{name} iters hist {:?}", &hi[..25]);
        }
        if std::env::var_os("SLOW").is_some() {
            let mut bins = std::collections::BTreeMap::new();
            for (p, f) in out.iter().enumerate() {
                let key = (
                    f.evaluations >= 8,
                    (truth[p].0 * 2.0) as i32,
                    (truth[p].1) as i32,
                );
                *bins.entry(key).or_insert(0usize) += 1;
            }
            let mut tab = String::new();
            for ((slow, nb, kb), c) in &bins {
                if *slow {
                    let tot = bins.get(&(false, *nb, *kb)).copied().unwrap_or(0) + c;
                    tab += &format!("n~{:.1} k~{} slow {}/{}\n", *nb as f64 / 2.0, kb, c, tot);
                }
            }
            eprintln!("{tab}");
            let st: usize = out
                .iter()
                .filter(|f| f.evaluations >= 8 && f.status != polarid_core::fit::FitStatus::Ok)
                .count();
            eprintln!("slow non-ok {st}");
        }
        println!(
            "{name:8} mode {mode} fail {fail:6} strict {fail_strict:6} worst {worst:.4} evals {:.3} us/fit {:.3}",
            ev as f64 / pixels as f64,
            dt * 1e6 / pixels as f64 * 2.0
        );
    }
}
