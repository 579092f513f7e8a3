//! Throughput of the Stokes kernels on the stack of `scripts/bench/baselines.py stokes`:
//! a 4-angle uint16 stack of 2048×2448 pixels. Prints Mpixel/s (best of 5) for
//! Stokes + DoLP + AoLP (fused), bilinear demosaicing (four channel images), and
//! DoFP bilinear Stokes. Run: `cargo run --release -p polarid-core --example stokes_throughput`.

use std::time::Instant;

use polarid_core::mosaic::{Pattern, bilinear_stokes, demosaic_bilinear};
use polarid_core::stokes::{PixelRules, StokesSolver};
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
    let (h, w) = (2048usize, 2448usize);
    let n = h * w;
    let mpix = n as f64 / 1e6;
    let mut rng = StdRng::seed_from_u64(0);
    let angles = [0.0, 45.0, 90.0, 135.0];
    let mut stack: Vec<Vec<u16>> = vec![vec![0; n]; 4];
    for i in 0..n {
        let s0 = 1000.0 + 59000.0 * rng.random::<f64>();
        let p = rng.random::<f64>();
        let t = std::f64::consts::PI * rng.random::<f64>();
        for (k, a) in angles.iter().enumerate() {
            let a = 2.0 * f64::to_radians(*a);
            let v = 0.5 * (s0 + s0 * p * ((2.0 * t).cos() * a.cos() + (2.0 * t).sin() * a.sin()));
            stack[k][i] = v.round().clamp(0.0, 65535.0) as u16;
        }
    }
    let solver = StokesSolver::from_degrees(&angles).unwrap();
    let views: Vec<&[u16]> = stack.iter().map(|v| v.as_slice()).collect();
    let rules = PixelRules::default();
    let (mut s0, mut s1, mut s2, mut m) =
        (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0u8; n]);
    let (mut d, mut a) = (vec![0f32; n], vec![0f32; n]);
    let t = best_of(5, || {
        solver
            .compute_with_polar(
                &views, w, &rules, &mut s0, &mut s1, &mut s2, &mut m, &mut d, &mut a,
            )
            .unwrap();
    });
    println!(
        "stokes+dolp+aolp (4 x uint16 {w}x{h}): {:.4} s, {:.1} Mpixel/s",
        t,
        mpix / t
    );
    // DoFP raw from the stack (pattern 90,45,135,0), as in baselines.py.
    let mut raw = vec![0u16; n];
    for y in 0..h {
        for x in 0..w {
            let k = [2, 1, 3, 0][2 * (y % 2) + x % 2];
            raw[y * w + x] = stack[k][y * w + x];
        }
    }
    let p = Pattern::imx250mzr();
    let mut ch: Vec<Vec<f32>> = vec![vec![0f32; n]; 4];
    let t = best_of(5, || {
        let [c0, c1, c2, c3] = &mut ch[..] else {
            unreachable!()
        };
        demosaic_bilinear(&raw, w, &p, true, [c0, c1, c2, c3]).unwrap();
    });
    println!(
        "bilinear demosaic (4 channel images, OpenCV rounding): {:.4} s, {:.1} Mpixel/s",
        t,
        mpix / t
    );
    let t = best_of(5, || {
        bilinear_stokes(&raw, w, &p, &rules, true, &mut s0, &mut s1, &mut s2, &mut m).unwrap();
    });
    println!(
        "DoFP bilinear Stokes (fused): {:.4} s, {:.1} Mpixel/s",
        t,
        mpix / t
    );
}
