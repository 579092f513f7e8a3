//! Monte-Carlo accuracy study of the (n, k) inversion (paper section 5) against the
//! Cramér–Rao bound, at the paper's geometry: camera at θr = 60°, source positions θi
//! spread evenly over 35…80° (β = (θi + 60°)/2, eq. 10), Gaussian DoLP noise.
//!
//! For each material, number of source positions T and noise sd, it fits `trials`
//! noisy curves and prints the RMSE of n and k, the CRB (√ of the diagonal of F⁻¹),
//! their ratio (1 = efficient), the RMS of the reported standard errors, and the
//! fraction of fits that reached a cost at or below the cost at the true (n, k).
//!
//! ```text
//! cargo run --release -p polarid-core --example montecarlo [-- TRIALS [SEED]]
//! ```

use polarid_core::dop::dop;
use polarid_core::fit::{FitPlan, FitStatus, crb};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

fn main() {
    let mut args = std::env::args().skip(1);
    let trials: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(1000);
    let seed: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1);
    let materials = [
        ("green paint", 1.39, 0.34),
        ("copper", 0.4, 2.95),
        ("aluminum", 1.24, 6.6),
        ("n=2, k=1", 2.0, 1.0),
    ];
    let ts = [3usize, 5, 10, 19];
    let sds = [0.001, 0.002, 0.005, 0.01, 0.02];
    println!(
        "# Monte-Carlo study: theta_r = 60 deg, theta_i evenly over 35..80 deg, {trials} trials per row, seed {seed}"
    );
    println!(
        "# eff = RMSE / CRB (1 = efficient); se = RMS of the reported standard errors; glob = fraction with cost <= cost at truth; ok = fraction with status ok"
    );
    println!(
        "{:<12} {:>3} {:>6} | {:>9} {:>9} {:>9} {:>5} | {:>9} {:>9} {:>9} {:>5} | {:>6} {:>6}",
        "material",
        "T",
        "sd",
        "rmse_n",
        "crb_n",
        "se_n",
        "eff",
        "rmse_k",
        "crb_k",
        "se_k",
        "eff",
        "glob",
        "ok"
    );
    let mut rng = StdRng::seed_from_u64(seed);
    for &(name, n, k) in &materials {
        for &t in &ts {
            let betas: Vec<f64> = (0..t)
                .map(|i| {
                    let ti = 35.0 + 45.0 * i as f64 / (t - 1) as f64;
                    ((ti + 60.0) / 2.0f64).to_radians()
                })
                .collect();
            let plan = FitPlan::with_defaults(&betas).expect("valid plan");
            let mut ws = plan.workspace();
            let clean: Vec<f64> = betas.iter().map(|&b| dop(n, k, b)).collect();
            for &sd in &sds {
                let bound = crb(n, k, &betas, sd).expect("valid CRB");
                let noise = Normal::new(0.0, sd).expect("valid sd");
                let (mut e2n, mut e2k, mut s2n, mut s2k) = (0.0, 0.0, 0.0, 0.0);
                let (mut glob, mut ok, mut used) = (0usize, 0usize, 0usize);
                let mut y = vec![0.0; t];
                for _ in 0..trials {
                    for (yi, &p) in y.iter_mut().zip(&clean) {
                        *yi = (p + noise.sample(&mut rng)).clamp(0.0, 1.0);
                    }
                    let Ok(f) = plan.fit_with(&y, None, &mut ws) else {
                        continue;
                    };
                    used += 1;
                    e2n += (f.n - n).powi(2);
                    e2k += (f.k - k).powi(2);
                    if f.n_se.is_finite() && f.k_se.is_finite() {
                        s2n += f.n_se * f.n_se;
                        s2k += f.k_se * f.k_se;
                    }
                    if f.cost <= plan.cost(n, k, &y, None) * (1.0 + 1e-12) + 1e-18 {
                        glob += 1;
                    }
                    if f.status == FitStatus::Ok {
                        ok += 1;
                    }
                }
                let m = used.max(1) as f64;
                let (rn, rk) = ((e2n / m).sqrt(), (e2k / m).sqrt());
                println!(
                    "{:<12} {:>3} {:>6} | {:>9.4} {:>9.4} {:>9.4} {:>5.2} | {:>9.4} {:>9.4} {:>9.4} {:>5.2} | {:>6.4} {:>6.4}",
                    name,
                    t,
                    sd,
                    rn,
                    bound.sd_n,
                    (s2n / m).sqrt(),
                    rn / bound.sd_n,
                    rk,
                    bound.sd_k,
                    (s2k / m).sqrt(),
                    rk / bound.sd_k,
                    glob as f64 / m,
                    ok as f64 / m
                );
            }
        }
    }
}
