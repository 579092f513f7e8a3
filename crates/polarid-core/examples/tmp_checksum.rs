use polarid_core::dop::dop;
use polarid_core::fit::{FitOptions, FitPlan, NkFit, fit_batch};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
fn main() {
    for (t_len, opts, weighted) in [
        (10, FitOptions::default(), false),
        (10, FitOptions::default(), true),
        (
            7,
            FitOptions {
                max_candidates: 3,
                ..Default::default()
            },
            false,
        ),
        (
            5,
            FitOptions {
                grid_n: 64,
                grid_k: 70,
                max_candidates: 2,
                ..Default::default()
            },
            true,
        ),
        (
            4,
            FitOptions {
                bounds: polarid_core::fit::FitBounds {
                    n_min: 0.0,
                    n_max: 4.0,
                    k_min: 0.1,
                    k_max: 9.0,
                },
                ..Default::default()
            },
            false,
        ),
    ] {
        let betas: Vec<f64> = (0..t_len)
            .map(|i| (38.0 + 33.0 * i as f64 / (t_len - 1) as f64).to_radians())
            .collect();
        let mut rng = StdRng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.01).unwrap();
        let np = 20000;
        let mut y = vec![];
        let mut se = vec![];
        for p in 0..np {
            let (n, k) = (rng.random_range(0.2..4.0), rng.random_range(0.0..10.0));
            for (t, &b) in betas.iter().enumerate() {
                y.push((dop(n, k, b) + noise.sample(&mut rng)).clamp(0.0, 1.0));
                se.push(0.004 + 0.001 * ((p + t) % 3) as f64);
            }
        }
        let plan = FitPlan::new(&betas, opts).unwrap();
        let mut out = vec![NkFit::default(); np];
        fit_batch(&plan, &y, weighted.then_some(&se[..]), &mut out).unwrap();
        let mut h = 0xcbf29ce484222325u64;
        for f in &out {
            for v in [f.n, f.k, f.n_se, f.k_se, f.nk_corr, f.rms_residual, f.cost] {
                h = (h ^ v.to_bits()).wrapping_mul(0x100000001b3);
            }
            h = (h
                ^ (f.evaluations as u64)
                ^ ((f.iterations as u64) << 32)
                ^ ((f.starts as u64) << 48))
                .wrapping_mul(0x100000001b3);
            h = (h ^ f.status.code() as u64).wrapping_mul(0x100000001b3);
        }
        println!("{t_len} {weighted} {h:016x}");
    }
}
