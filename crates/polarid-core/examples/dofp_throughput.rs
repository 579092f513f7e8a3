//! Throughput of the DoFP kernels on a 2048×2448 uint16 IMX250MZR-style mosaic (pattern
//! 90,45,135,0; the raw frame of `scripts/bench/baselines.py stokes`): the fused raw →
//! DoLP + AoLP (both methods), the unfused path (Stokes images, then DoLP / AoLP), and
//! bilinear demosaicing into four `f32` or `u16` channel images. Output buffers are
//! allocated once (caller-owned). Prints one line per figure (best of `--repeats`,
//! default 7) and a JSON line. Run:
//! `cargo run --release -p polarid-core --example dofp_throughput [-- --repeats N]`.

use std::time::Instant;

use polarid_core::mosaic::{
    DofpMethod, DofpOutputs, Pattern, bilinear_stokes, demosaic_bilinear, demosaic_bilinear_int,
    dofp_polar,
};
use polarid_core::stokes::{PixelRules, dolp_aolp};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

fn best_of<F: FnMut()>(n: usize, mut f: F) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..n {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let opt = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let repeats: usize = opt("--repeats").map_or(7, |v| v.parse().expect("--repeats N"));
    // --only KEY: run only the figure whose JSON key starts with KEY (for profiling).
    let only = opt("--only").unwrap_or_default();
    let run = |key: &str| key.starts_with(&only);
    let (h, w) = (2048usize, 2448usize);
    let n = h * w;
    let mpix = n as f64 / 1e6;
    let mut rng = StdRng::seed_from_u64(0);
    let raw: Vec<u16> = (0..n).map(|_| rng.random_range(1000..60000u16)).collect();
    let p = Pattern::imx250mzr();
    let rules = PixelRules {
        saturation: 65535.0,
        ..PixelRules::default()
    };
    let (mut d, mut a) = (vec![0f32; n], vec![0f32; n]);
    let mut figures = Vec::new();
    let mut report = |name: &str, key: &str, t: f64| {
        if !t.is_finite() {
            return;
        }
        println!("{name}: {:.2} ms, {:.1} Mpixel/s", t * 1e3, mpix / t);
        figures.push(format!("\"{key}\": {:.1}", mpix / t));
    };
    for (name, key, method) in [
        (
            "fused raw -> DoLP+AoLP, bilinear (rounded)",
            "fused_bilinear_mpix_s",
            DofpMethod::Bilinear { round: true },
        ),
        (
            "fused raw -> DoLP+AoLP, super-pixel",
            "fused_superpixel_mpix_s",
            DofpMethod::Superpixel,
        ),
    ] {
        if !run(key) {
            continue;
        }
        let m = match method {
            DofpMethod::Superpixel => n / 4,
            _ => n,
        };
        let t = best_of(repeats, || {
            let out = DofpOutputs {
                dolp: Some(&mut d[..m]),
                aolp: Some(&mut a[..m]),
                ..Default::default()
            };
            dofp_polar(&raw, w, &p, method, &rules, out).unwrap();
        });
        report(name, key, t);
    }
    let (mut s0, mut s1, mut s2, mut m) =
        (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0u8; n]);
    for (key, round) in [
        ("stokes_bilinear_round", true),
        ("stokes_bilinear_exact", false),
    ] {
        let t = best_of(if run(key) { repeats } else { 0 }, || {
            bilinear_stokes(
                &raw, w, &p, &rules, round, &mut s0, &mut s1, &mut s2, &mut m,
            )
            .unwrap();
        });
        report("bilinear Stokes images + mask (no DoLP/AoLP)", key, t);
    }
    let t = best_of(if run("unfused") { repeats } else { 0 }, || {
        bilinear_stokes(&raw, w, &p, &rules, true, &mut s0, &mut s1, &mut s2, &mut m).unwrap();
        dolp_aolp(w, &s0, &s1, &s2, Some(&m), &mut d, &mut a).unwrap();
    });
    report(
        "unfused: bilinear Stokes images, then DoLP+AoLP",
        "unfused_bilinear_mpix_s",
        t,
    );
    let mut ch: Vec<Vec<f32>> = vec![vec![0f32; n]; 4];
    let t = best_of(if run("demosaic_f32") { repeats } else { 0 }, || {
        let [c0, c1, c2, c3] = &mut ch[..] else {
            unreachable!()
        };
        demosaic_bilinear(&raw, w, &p, true, [c0, c1, c2, c3]).unwrap();
    });
    report(
        "bilinear demosaic, 4 x f32 (OpenCV rounding)",
        "demosaic_f32_mpix_s",
        t,
    );
    drop(ch);
    let mut ci: Vec<Vec<u16>> = vec![vec![0u16; n]; 4];
    let t = best_of(if run("demosaic_u16") { repeats } else { 0 }, || {
        let [c0, c1, c2, c3] = &mut ci[..] else {
            unreachable!()
        };
        demosaic_bilinear_int(&raw, w, &p, [c0, c1, c2, c3]).unwrap();
    });
    report(
        "bilinear demosaic, 4 x u16 (OpenCV's values)",
        "demosaic_u16_mpix_s",
        t,
    );
    println!(
        "{{\"bench\": \"dofp_throughput\", \"width\": {w}, \"height\": {h}, \"repeats\": {repeats}, {}}}",
        figures.join(", ")
    );
}
