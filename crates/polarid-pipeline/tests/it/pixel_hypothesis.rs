//! The per-pixel hypothesis tests of `polarid map` (`HypothesisDecider`, which tests only
//! the materials that can pass) answer exactly as `classify_rows`' consistent set, against
//! the built-in libraries as `map` loads them: `builtin-rgb` at 650/550/450 nm (pixels with
//! all three bands or two) and `builtin` at 550 nm, over random pixels of random library
//! materials as they are found (and of indices outside the library), noise levels from
//! 0.002 to 0.03 a random factor off the declared one (so materials fall on both sides of
//! the threshold), 3–9 positions per band, and `map`'s default error model.
//!
//! Cheap by default (60 pixels per library); `POLARID_FULL=1` runs 2000.

use polarid_core::classify::pixel_decision::{HypothesisDecider, PixelAnswer};
use polarid_core::classify::{
    CandidateModel, HypRow, HypothesisConfig, MultiPrototype, Nuisances, Status, classify_rows,
    layered_dolp,
};
use polarid_core::dop::dop;
use polarid_io::library::Library;
use polarid_pipeline::fit::{DEFAULT_ANGLE_SD_DEG, DEFAULT_EXTINCTION_RATIO};

/// SplitMix64 with uniforms and Box–Muller normals.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    fn index(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn normal(&mut self, sd: f64) -> f64 {
        let u = 1.0 - self.uniform();
        let v = self.uniform();
        sd * (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// A random pixel's rows at `wl` (module documentation).
fn pixel(
    rng: &mut Rng,
    protos: &[MultiPrototype],
    wl: &[f64],
    cfg: &HypothesisConfig,
) -> Vec<HypRow> {
    let nu = cfg.nuisances;
    let truth = loop {
        if rng.uniform() < 0.2 {
            let (n, k) = (rng.range(0.2, 4.0), rng.range(0.0, 6.0));
            break CandidateModel {
                bulk: vec![(n, k); wl.len()],
                layer: None,
            };
        }
        if let Some(c) = CandidateModel::from_prototype(&protos[rng.index(protos.len())], wl) {
            break c;
        }
    };
    let d = truth
        .layer
        .as_ref()
        .map_or(0.0, |l| rng.range(l.min_nm, l.max_nm));
    let s = rng.range(nu.scale_min, 1.0);
    let o = rng.range(-1.0, 1.0) * nu.offset_max;
    let sd = [0.002, 0.005, 0.01, 0.03][rng.index(4)];
    let noise = sd * rng.range(0.5, 2.0);
    let t = 3 + rng.index(7);
    let (b0, b1) = (rng.range(15.0, 50.0), rng.range(55.0, 85.0));
    let angle_sd = DEFAULT_ANGLE_SD_DEG.to_radians();
    let mut rows = Vec::new();
    for (band, &w) in wl.iter().enumerate() {
        for i in 0..t {
            let beta = (b0 + (b1 - b0) * i as f64 / (t - 1) as f64).to_radians();
            let b = beta + o + rng.normal(angle_sd / 2.0);
            let bulk = truth.bulk[band];
            let p = match &truth.layer {
                Some(l) => layered_dolp(bulk, l.index[band], d / w, b),
                None => dop(bulk.0, bulk.1, b),
            };
            rows.push(HypRow {
                beta,
                dolp: s * p + rng.normal(noise),
                dolp_sd: sd,
                angle_sd,
                band,
            });
        }
    }
    rows
}

#[test]
fn map_decisions_equal_classify_rows_against_the_builtin_libraries() {
    let n = polarid_testkit::seeds(60, 2000) as usize;
    let scale_min = Nuisances::from_error_model(DEFAULT_EXTINCTION_RATIO, 0.0, 0.0).scale_min;
    let rgb = Library::builtin_rgb().unwrap().multi_prototypes();
    let (one, _) = Library::builtin()
        .unwrap()
        .at_wavelengths(&[550.0])
        .unwrap();
    let cases: [(&str, Vec<MultiPrototype>, Vec<Vec<f64>>); 2] = [
        (
            "builtin-rgb",
            rgb,
            vec![vec![650.0, 550.0, 450.0], vec![650.0, 450.0]],
        ),
        ("builtin", one.multi_prototypes(), vec![vec![550.0]]),
    ];
    let mut rng = Rng(41);
    for (name, protos, band_sets) in &cases {
        let mut seen = [0usize; 3];
        for confidence in [0.95, 0.99] {
            let decider = HypothesisDecider::new(protos, confidence, scale_min, true).unwrap();
            for i in 0..n / 2 {
                let wl = &band_sets[i % band_sets.len()];
                let cfg = HypothesisConfig {
                    confidence,
                    nuisances: Nuisances {
                        scale_min,
                        ..Nuisances::from_error_model(
                            f64::INFINITY,
                            0.0,
                            DEFAULT_ANGLE_SD_DEG.to_radians(),
                        )
                    },
                    open_world: true,
                };
                let rows = pixel(&mut rng, protos, wl, &cfg);
                let got = decider.decide(&rows, wl).unwrap();
                let out = classify_rows(&rows, wl, protos, None, &cfg).unwrap();
                let d = &out.decision;
                let want = match &d.status {
                    Status::Ok => PixelAnswer::One(
                        decider
                            .classes()
                            .iter()
                            .position(|c| *c == d.predicted)
                            .unwrap() as u16,
                    ),
                    Status::Ambiguous => PixelAnswer::Ambiguous,
                    Status::Rejected => PixelAnswer::Unknown,
                    s => panic!("{s:?}"),
                };
                assert_eq!(got, want, "{name} {wl:?} p {confidence}: {rows:?}");
                seen[match got {
                    PixelAnswer::One(_) => 0,
                    PixelAnswer::Ambiguous => 1,
                    _ => 2,
                }] += 1;
            }
        }
        eprintln!("{name}: one / ambiguous / unknown {seen:?}");
        assert!(seen.iter().all(|&s| s * 20 >= n), "{name}: {seen:?}");
    }
}
