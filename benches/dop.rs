//! Cost of one eq. (9) evaluation with its gradient (the per-pixel fit's inner loop),
//! and of the pBRDF. Run: `cargo bench -p polarid-benches --bench dop`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use polarid_core::dop::{BetaTerms, dop_grad_terms, dop_terms};
use polarid_core::geometry::ScatterGeometry;
use polarid_core::pbrdf::{Pbrdf, pbrdf_geometry};

/// A deterministic spread of (n, k, β) over the physical range, including k = 0 and
/// total reflection, so that every branch is exercised.
fn cases(len: usize) -> Vec<(f64, f64, BetaTerms)> {
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..len)
        .map(|i| {
            let n = 0.2 + 2.8 * next();
            let k = if i % 4 == 0 { 0.0 } else { 8.0 * next() };
            let beta = (1.0 + 88.0 * next()).to_radians();
            (n, k, BetaTerms::new(beta))
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    const LEN: usize = 1024;
    let data = cases(LEN);
    let mut g = c.benchmark_group("eq9");
    g.throughput(Throughput::Elements(LEN as u64));
    g.bench_function("dop_grad_terms", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (n, k, t) in &data {
                let r = dop_grad_terms(black_box(*n), black_box(*k), t);
                acc += r.p + r.dp_dn + r.dp_dk;
            }
            black_box(acc)
        })
    });
    g.bench_function("dop_terms", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (n, k, t) in &data {
                acc += dop_terms(black_box(*n), black_box(*k), t);
            }
            black_box(acc)
        })
    });
    g.finish();

    let geoms: Vec<ScatterGeometry> = (0..LEN)
        .map(|i| {
            let f = i as f64 / LEN as f64;
            ScatterGeometry::new(1.3 * f, 1.2 * (1.0 - f), 6.0 * f)
        })
        .collect();
    let mut g = c.benchmark_group("pbrdf");
    g.throughput(Throughput::Elements(LEN as u64));
    g.bench_function("pbrdf_geometry", |b| {
        let mut out = Pbrdf::default();
        b.iter(|| {
            let mut acc = 0.0;
            for (geo, (n, k, _)) in geoms.iter().zip(&data) {
                pbrdf_geometry(black_box(*n), black_box(*k), 0.2, geo, &mut out);
                acc += out.global[1][0];
            }
            black_box(acc)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
