//! Throughput of the image kernels on a 1024×1224 4-angle uint16 stack (a quarter of
//! the 2048×2448 frames of `scripts/bench/baselines.py stokes`; the full size is timed by
//! `examples/stokes_throughput.rs` and `scripts/bench_compare.sh`):
//! Stokes from 4 frames (exact 0/45/90/135 kernel, and the general least-squares
//! kernel on 0/60/120/150), fused Stokes + DoLP/AoLP, DoLP/AoLP from Stokes images,
//! bilinear demosaicing, super-pixel and bilinear DoFP Stokes, region statistics, and
//! the map's per-capture binned DoLP. Run: `cargo bench -p polarid-benches --bench kernels`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use polarid_core::map::frames_dolp;
use polarid_core::mosaic::{Pattern, bilinear_stokes, demosaic_bilinear, superpixel_stokes};
use polarid_core::region::{Rect, Sampling, region_stats};
use polarid_core::stokes::{PixelRules, StokesSolver, dolp_aolp};

const H: usize = 1024;
const W: usize = 1224;

#[allow(clippy::needless_range_loop)]
fn stack(angles: &[f64]) -> Vec<Vec<u16>> {
    let n = H * W;
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = vec![vec![0u16; n]; angles.len()];
    for i in 0..n {
        let s0 = 1000.0 + 59000.0 * next();
        let p = next();
        let t = std::f64::consts::PI * next();
        for (k, a) in angles.iter().enumerate() {
            let a = 2.0 * a.to_radians();
            let v = 0.5 * s0 * (1.0 + p * ((2.0 * t).cos() * a.cos() + (2.0 * t).sin() * a.sin()));
            out[k][i] = v.round().clamp(0.0, 65535.0) as u16;
        }
    }
    out
}

fn kernels(c: &mut Criterion) {
    let n = H * W;
    let mut g = c.benchmark_group("kernels");
    g.throughput(Throughput::Elements(n as u64));
    g.sample_size(20);
    let rules = PixelRules::default();
    let (mut s0, mut s1, mut s2, mut m) =
        (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0u8; n]);
    let (mut d, mut a) = (vec![0f32; n], vec![0f32; n]);

    let quad = [0.0, 45.0, 90.0, 135.0];
    let st = stack(&quad);
    let views: Vec<&[u16]> = st.iter().map(|v| v.as_slice()).collect();
    let solver = StokesSolver::from_degrees(&quad).unwrap();
    g.bench_function("stokes_4frames_u16", |b| {
        b.iter(|| {
            solver
                .compute(
                    black_box(&views),
                    W,
                    &rules,
                    &mut s0,
                    &mut s1,
                    &mut s2,
                    &mut m,
                )
                .unwrap()
        })
    });
    g.bench_function("stokes_dolp_aolp_fused_u16", |b| {
        b.iter(|| {
            solver
                .compute_with_polar(
                    black_box(&views),
                    W,
                    &rules,
                    &mut s0,
                    &mut s1,
                    &mut s2,
                    &mut m,
                    &mut d,
                    &mut a,
                )
                .unwrap()
        })
    });
    g.bench_function("dolp_aolp_from_stokes", |b| {
        b.iter(|| dolp_aolp(W, black_box(&s0), &s1, &s2, Some(&m), &mut d, &mut a).unwrap())
    });
    let gen_angles = [0.0, 60.0, 120.0, 150.0];
    let sg = stack(&gen_angles);
    let gviews: Vec<&[u16]> = sg.iter().map(|v| v.as_slice()).collect();
    let gsolver = StokesSolver::from_degrees(&gen_angles).unwrap();
    g.bench_function("stokes_4frames_general_lsq_u16", |b| {
        b.iter(|| {
            gsolver
                .compute(
                    black_box(&gviews),
                    W,
                    &rules,
                    &mut s0,
                    &mut s1,
                    &mut s2,
                    &mut m,
                )
                .unwrap()
        })
    });
    let mut fd = vec![0f32; n];
    let mut ff = vec![0u8; n];
    g.bench_function("map_capture_dolp_bin1_u16", |b| {
        b.iter(|| {
            ff.fill(0);
            frames_dolp(&solver, black_box(&views), W, &rules, 1, &mut fd, &mut ff).unwrap()
        })
    });

    // DoFP raw (pattern 90,45,135,0) from the stack.
    let mut raw = vec![0u16; n];
    for y in 0..H {
        for x in 0..W {
            let k = [2, 1, 3, 0][2 * (y % 2) + x % 2];
            raw[y * W + x] = st[k][y * W + x];
        }
    }
    let p = Pattern::imx250mzr();
    let mut ch: Vec<Vec<f32>> = vec![vec![0f32; n]; 4];
    g.bench_function("demosaic_bilinear_u16", |b| {
        b.iter(|| {
            let [c0, c1, c2, c3] = &mut ch[..] else {
                unreachable!()
            };
            demosaic_bilinear(black_box(&raw), W, &p, true, [c0, c1, c2, c3]).unwrap()
        })
    });
    g.bench_function("dofp_bilinear_stokes_u16", |b| {
        b.iter(|| {
            bilinear_stokes(
                black_box(&raw),
                W,
                &p,
                &rules,
                true,
                &mut s0,
                &mut s1,
                &mut s2,
                &mut m,
            )
            .unwrap()
        })
    });
    let q = n / 4;
    let (mut q0, mut q1, mut q2, mut qm) =
        (vec![0f32; q], vec![0f32; q], vec![0f32; q], vec![0u8; q]);
    g.bench_function("dofp_superpixel_stokes_u16", |b| {
        b.iter(|| {
            superpixel_stokes(
                black_box(&raw),
                W,
                &p,
                &rules,
                &mut q0,
                &mut q1,
                &mut q2,
                &mut qm,
            )
            .unwrap()
        })
    });
    solver
        .compute(&views, W, &rules, &mut s0, &mut s1, &mut s2, &mut m)
        .unwrap();
    let rect = Rect {
        x: 0,
        y: 0,
        width: W,
        height: H,
    };
    g.bench_function("region_stats_full_frame", |b| {
        b.iter(|| {
            region_stats(W, black_box(&s0), &s1, &s2, &m, rect, Sampling::Independent).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
