use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

use super::*;
use crate::classify::hypothesis::{Nuisances, classify_rows, test_hypothesis};
use crate::classify::{BandPoint, NativeLayer, Status};

const WL: [f64; 3] = [650.0, 550.0, 450.0];

/// Materials at three bands: `(class, bulk per band, layer (index per band, min, max))`,
/// indices near the library's (metals under oxides, a semiconductor under its oxide,
/// dielectrics, a thick coating the tables cannot bound).
fn protos() -> Vec<MultiPrototype> {
    type L = Option<([(f64, f64); 3], f64, f64)>;
    let table: [(&str, [(f64, f64); 3], L); 9] = [
        (
            "aluminum",
            [(1.49, 7.82), (0.96, 6.69), (0.62, 5.47)],
            Some(([(1.77, 0.0), (1.77, 0.0), (1.78, 0.0)], 2.0, 5.0)),
        ),
        (
            "copper",
            [(0.21, 3.67), (1.02, 2.58), (1.24, 2.40)],
            Some(([(2.9, 0.1), (3.0, 0.2), (2.9, 0.6)], 1.0, 3.0)),
        ),
        ("gold", [(0.17, 3.15), (0.43, 2.46), (1.47, 1.95)], None),
        ("silver", [(0.05, 4.28), (0.06, 3.59), (0.04, 2.66)], None),
        (
            "silicon",
            [(3.84, 0.02), (4.08, 0.03), (4.68, 0.14)],
            Some(([(1.46, 0.0), (1.46, 0.0), (1.47, 0.0)], 1.0, 2.0)),
        ),
        ("glass", [(1.514, 0.0), (1.518, 0.0), (1.525, 0.0)], None),
        ("glass", [(1.57, 0.0), (1.58, 0.0), (1.59, 0.0)], None),
        ("PMMA", [(1.489, 0.0), (1.494, 0.0), (1.50, 0.0)], None),
        (
            "coated",
            [(1.2, 6.0), (1.0, 5.5), (0.8, 5.0)],
            Some(([(1.5, 0.0), (1.5, 0.0), (1.5, 0.0)], 20.0, 600.0)),
        ),
    ];
    table
        .iter()
        .map(|(class, bulk, layer)| MultiPrototype {
            class: (*class).into(),
            category: None,
            source: "test".into(),
            bands: (0..3)
                .map(|b| BandPoint {
                    wavelength_nm: Some(WL[b]),
                    n: bulk[b].0,
                    k: bulk[b].1,
                    cov: None,
                    film: None,
                    layer: layer.map(|l| l.0[b]),
                })
                .collect(),
            surface: layer.map(|l| NativeLayer {
                name: "layer".into(),
                min_nm: l.1,
                max_nm: l.2,
            }),
        })
        .collect()
}

/// A random pixel's rows at a random subset of the bands: from a random material of
/// `protos` (or a random index) as it is found, with noise a random factor off its
/// declared standard deviation (so some materials fall near the threshold).
fn pixel(rng: &mut StdRng, protos: &[MultiPrototype], nu: &Nuisances) -> (Vec<HypRow>, Vec<f64>) {
    let wl: Vec<f64> = match rng.random_range(0..4) {
        0 => vec![650.0],
        1 => vec![650.0, 450.0],
        _ => WL.to_vec(),
    };
    let truth = if rng.random::<f64>() < 0.8 {
        let p = &protos[rng.random_range(0..protos.len())];
        CandidateModel::from_prototype(p, &wl).unwrap()
    } else {
        let (n, k) = (rng.random_range(0.2..4.0), rng.random_range(0.0..6.0));
        CandidateModel {
            bulk: vec![(n, k); wl.len()],
            layer: None,
        }
    };
    let d = truth
        .layer
        .as_ref()
        .map_or(0.0, |l| rng.random_range(l.min_nm..=l.max_nm));
    let s = rng.random_range(nu.scale_min..=1.0);
    let o = rng.random_range(-1.0..=1.0) * nu.offset_max;
    let sd = [0.002, 0.005, 0.01, 0.03][rng.random_range(0..4)];
    let factor = rng.random_range(0.5..2.0);
    let t = rng.random_range(3..10);
    let (b0, b1) = (rng.random_range(15.0..50.0), rng.random_range(55.0..85.0));
    let noise = Normal::new(0.0, sd * factor).unwrap();
    let mut rows = Vec::new();
    for (band, &w) in wl.iter().enumerate() {
        for i in 0..t {
            let beta = (b0 + (b1 - b0) * i as f64 / (t - 1) as f64).to_radians();
            let bulk = truth.bulk[band];
            let p = match &truth.layer {
                Some(l) => layered_dolp(bulk, l.index[band], d / w, beta + o),
                None => dop(bulk.0, bulk.1, beta + o),
            };
            rows.push(HypRow {
                beta,
                dolp: s * p + noise.sample(rng),
                dolp_sd: sd,
                angle_sd: nu.offset_max * 2.0 / 3.0,
                band,
            });
        }
    }
    (rows, wl)
}

fn settings(rng: &mut StdRng) -> HypothesisConfig {
    let scale_min = [1.0, 0.98, 0.9][rng.random_range(0..3)];
    let angle_sd = rng.random_range(0.0..0.5f64).to_radians();
    let mut nuisances = Nuisances::from_error_model(f64::INFINITY, 0.0, angle_sd);
    nuisances.scale_min = scale_min;
    HypothesisConfig {
        confidence: [0.9, 0.95, 0.99][rng.random_range(0..3)],
        nuisances,
        open_world: false,
    }
}

/// The lower bound of a material's `χ²_min` never exceeds the `χ²_min` its test reports,
/// over random pixels, materials, bands and settings (and the thick coating, which the
/// tables do not bound, is never rejected).
#[test]
fn the_lower_bound_is_below_every_reported_chi2() {
    let protos = protos();
    let mut rng = StdRng::seed_from_u64(5);
    let mut terms = Vec::new();
    let (mut tight, mut total) = (0usize, 0usize);
    for _ in 0..60 {
        let cfg = settings(&mut rng);
        let (rows, wl) = pixel(&mut rng, &protos, &cfg.nuisances);
        for p in &protos {
            let cand = CandidateModel::from_prototype(p, &wl).unwrap();
            let tables: Vec<Arc<Table>> = wl
                .iter()
                .enumerate()
                .map(|(b, &w)| Arc::new(Table::new(&cand, b, w)))
                .collect();
            let fit = test_hypothesis(&rows, &wl, &cand, &cfg).unwrap();
            fill_terms(&tables, &rows, cfg.nuisances.offset_max, &mut terms);
            let at = fit.chi2 * (1.0 + 1e-9) + 1e-9;
            assert!(
                !exceeds(&terms, cfg.nuisances.scale_min, at),
                "{}: bound above chi2 {} ({rows:?})",
                p.class,
                fit.chi2
            );
            // How tight: the bound exceeds half the χ².
            total += 1;
            if exceeds(&terms, cfg.nuisances.scale_min, 0.5 * fit.chi2) {
                tight += 1;
            }
        }
    }
    assert!(tight * 4 > total, "{tight} of {total}");
}

/// No material passes with a `χ²_min` above [`chi2_pass_bound`].
#[test]
fn no_passing_chi2_exceeds_the_pass_bound() {
    let protos = protos();
    let mut rng = StdRng::seed_from_u64(6);
    let mut passed = 0;
    for _ in 0..60 {
        let cfg = settings(&mut rng);
        let (rows, wl) = pixel(&mut rng, &protos, &cfg.nuisances);
        let bound = chi2_pass_bound(rows.len(), cfg.confidence);
        for p in &protos {
            let cand = CandidateModel::from_prototype(p, &wl).unwrap();
            let fit = test_hypothesis(&rows, &wl, &cand, &cfg).unwrap();
            if fit.consistent {
                passed += 1;
                assert!(fit.chi2 <= bound, "{}: {} > {bound}", p.class, fit.chi2);
            }
        }
    }
    assert!(passed > 30, "{passed}");
}

/// The per-pixel verdicts are `classify_rows`' consistent sets, over random pixels near
/// and far from the threshold (every kind of answer seen).
#[test]
fn verdicts_equal_classify_rows() {
    let protos = protos();
    let mut classes: Vec<String> = protos.iter().map(|p| p.class.clone()).collect();
    classes.sort();
    classes.dedup();
    let tests = PixelTests::new(&protos, &classes);
    let mut rng = StdRng::seed_from_u64(8);
    let mut seen = [0usize; 3];
    for _ in 0..120 {
        let cfg = settings(&mut rng);
        let (rows, wl) = pixel(&mut rng, &protos, &cfg.nuisances);
        let got = tests.decide(&rows, &wl, &cfg).unwrap();
        let out = classify_rows(&rows, &wl, &protos, None, &cfg).unwrap();
        let want = match out.decision.status {
            Status::Ok => Verdict::One(
                classes
                    .iter()
                    .position(|c| *c == out.decision.predicted)
                    .unwrap() as u16,
            ),
            Status::Ambiguous => Verdict::Several,
            Status::Rejected => Verdict::None,
            s => panic!("{s:?}"),
        };
        assert_eq!(got, want, "{rows:?} {wl:?} {cfg:?}");
        seen[match got {
            Verdict::One(_) => 0,
            Verdict::Several => 1,
            _ => 2,
        }] += 1;
    }
    assert!(seen.iter().all(|&s| s >= 5), "{seen:?}");
}
