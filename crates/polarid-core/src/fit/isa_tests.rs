//! The instruction sets of the fit agree: every kernel the CPU has against the
//! portable one, and the detected path (what `fit_batch` runs) against the forced
//! portable path, in process ([`Isa::Portable`]) and through `POLARID_NO_SIMD`.

use super::*;
use crate::cpu::{Isa, cpu_features};
use crate::dop::dop;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

fn data(pixels: usize, t_len: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let betas: Vec<f64> = (0..t_len)
        .map(|i| (40.0 + 30.0 * i as f64 / (t_len - 1) as f64).to_radians())
        .collect();
    let mut rng = StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.005).unwrap();
    let mut y = Vec::new();
    let mut se = Vec::new();
    for p in 0..pixels {
        let (n, k) = (rng.random_range(0.2..4.0), rng.random_range(0.0..10.0));
        for (t, &b) in betas.iter().enumerate() {
            y.push((dop(n, k, b) + noise.sample(&mut rng)).clamp(0.0, 1.0));
            se.push(0.004 + 0.001 * ((p + t) % 3) as f64);
        }
    }
    (betas, y, se)
}

/// The fits of one chunk with instruction set `isa`.
fn run(plan: &FitPlan, isa: Isa, y: &[f64], se: Option<&[f64]>) -> Vec<NkFit> {
    let mut o = vec![NkFit::default(); y.len() / plan.len()];
    let mut ws = plan.workspace();
    plan.fit_chunk_isa(isa, y, se, &mut o, &mut ws);
    o
}

/// `a` and `b` (portable) are the same minima: equal statuses, costs equal to
/// rounding.
fn assert_same_minima(plan: &FitPlan, y: &[f64], s: Option<&[f64]>, a: &[NkFit], b: &[NkFit]) {
    let t_len = plan.len();
    for (p, (a, b)) in a.iter().zip(b).enumerate() {
        assert_eq!(a.status, b.status, "pixel {p}: {a:?} vs {b:?}");
        let yp = &y[p * t_len..(p + 1) * t_len];
        let sp = s.map(|s| &s[p * t_len..(p + 1) * t_len]);
        let (ca, cb) = (plan.cost(a.n, a.k, yp, sp), plan.cost(b.n, b.k, yp, sp));
        assert!(
            (ca - cb).abs() <= 1e-9 * ca.max(cb) + 1e-15,
            "pixel {p}: cost {ca} vs {cb}"
        );
    }
}

/// Every kernel the CPU has gives the same fits: AVX2 and AVX-512 bit for bit (the
/// same fused operations in the same order), the portable kernel (separate
/// multiply and add) to rounding. Weighted and unweighted, with and without
/// competing-basin starts, for a pixel count that leaves a remainder after the
/// four-pixel scans, and for a grid whose bands do not divide it evenly.
#[test]
fn kernels_agree() {
    for (opts, t_len) in [
        (FitOptions::default(), 10),
        (
            FitOptions {
                max_candidates: 3,
                ..Default::default()
            },
            7,
        ),
        (
            FitOptions {
                grid_n: 20,
                grid_k: 22,
                max_candidates: 2,
                ..Default::default()
            },
            5,
        ),
    ] {
        let (betas, y, se) = data(203, t_len, 4);
        let plan = FitPlan::new(&betas, opts).unwrap();
        for s in [None, Some(&se[..])] {
            let portable = run(&plan, Isa::Portable, &y, s);
            let runs: Vec<Vec<NkFit>> = cpu_features().all()[1..]
                .iter()
                .map(|&isa| run(&plan, isa, &y, s))
                .collect();
            if runs.len() == 2 {
                assert_eq!(runs[0], runs[1], "AVX2 and AVX-512 differ");
            }
            for r in &runs {
                assert_same_minima(&plan, &y, s, r, &portable);
            }
        }
    }
}

/// The public entry points run the detected path: `fit_batch` (parallel chunks) and
/// `FitPlan::fit` (a chunk of one) give bit for bit the fits of the chunk driver with
/// `cpu_features().best()`, and the same minima as the forced portable path.
#[test]
fn detected_path_matches_forced_portable() {
    let (betas, y, se) = data(1500, 8, 11);
    let plan = FitPlan::with_defaults(&betas).unwrap();
    let t_len = plan.len();
    for s in [None, Some(&se[..])] {
        let mut batch = vec![NkFit::default(); 1500];
        fit_batch(&plan, &y, s, &mut batch).unwrap();
        let detected = run(&plan, cpu_features().best(), &y, s);
        assert_eq!(batch, detected);
        for p in [0, 1, 2, 3, 4, 777, 1499] {
            let rows = p * t_len..(p + 1) * t_len;
            let one = plan.fit(&y[rows.clone()], s.map(|s| &s[rows])).unwrap();
            assert_eq!(one, batch[p], "pixel {p}");
        }
        let portable = run(&plan, Isa::Portable, &y, s);
        assert_same_minima(&plan, &y, s, &batch, &portable);
    }
}

/// The data and plan of the `POLARID_NO_SIMD` test.
fn env_case() -> (FitPlan, Vec<f64>) {
    let (betas, y, _) = data(64, 6, 5);
    (FitPlan::with_defaults(&betas).unwrap(), y)
}

/// One line per fit: `n`, `k` and cost as bits.
fn fingerprint(fits: &[NkFit]) -> String {
    fits.iter()
        .map(|f| {
            format!(
                "FIT {:016x} {:016x} {:016x}\n",
                f.n.to_bits(),
                f.k.to_bits(),
                f.cost.to_bits()
            )
        })
        .collect()
}

/// Child of [`no_simd_env_forces_portable`] (does nothing unless that test runs it):
/// prints the fingerprint of `fit_batch` on [`env_case`].
#[test]
fn no_simd_env_child() {
    if std::env::var_os("POLARID_ISA_TEST_CHILD").is_none() {
        return;
    }
    let (plan, y) = env_case();
    let mut out = vec![NkFit::default(); y.len() / plan.len()];
    fit_batch(&plan, &y, None, &mut out).unwrap();
    // (A new line first: the test harness prints the test name without one.)
    print!("\n{}", fingerprint(&out));
}

/// `POLARID_NO_SIMD=1` makes the process run the portable kernels: the fits of a
/// child process (this test binary, running [`no_simd_env_child`]) with it set are bit
/// for bit the forced portable fits of this process, and without it the detected ones.
#[test]
fn no_simd_env_forces_portable() {
    let (plan, y) = env_case();
    let child = |no_simd: Option<&str>| -> String {
        let mut cmd = std::process::Command::new(std::env::current_exe().unwrap());
        cmd.args([
            "fit::isa_tests::no_simd_env_child",
            "--exact",
            "--nocapture",
            "--test-threads=1",
        ])
        .env("POLARID_ISA_TEST_CHILD", "1")
        .env_remove("POLARID_NO_SIMD");
        if let Some(v) = no_simd {
            cmd.env("POLARID_NO_SIMD", v);
        }
        let out = cmd.output().unwrap();
        assert!(out.status.success(), "{out:?}");
        String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("FIT "))
            .map(|l| format!("{l}\n"))
            .collect()
    };
    let portable = fingerprint(&run(&plan, Isa::Portable, &y, None));
    let detected = fingerprint(&run(&plan, cpu_features().best(), &y, None));
    assert_eq!(portable.lines().count(), 64);
    assert_eq!(child(Some("1")), portable);
    // (When this process itself runs with POLARID_NO_SIMD, "detected" is portable.)
    if std::env::var_os("POLARID_NO_SIMD").is_none() {
        assert_eq!(child(Some("0")), detected);
        assert_eq!(child(None), detected);
    }
}
