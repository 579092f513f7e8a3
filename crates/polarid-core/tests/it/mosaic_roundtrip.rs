//! DoFP mosaics: exact noiseless round trips for all 24 patterns (super-pixel and
//! bilinear), OpenCV/polanalyser-identical bilinear interpolation, saturation handling,
//! and standard-error coverage with noise.

use polarid_core::mosaic::{Pattern, bilinear_stokes, demosaic_bilinear, superpixel_stokes};
use polarid_core::region::{Rect, Sampling, region_stats};
use polarid_core::stokes::{PixelRules, mask};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal, Poisson};

fn intensity(s: [f64; 3], a_deg: f64) -> f64 {
    let a = 2.0 * a_deg.to_radians();
    0.5 * (s[0] + s[1] * a.cos() + s[2] * a.sin())
}

fn all_patterns() -> Vec<[f64; 4]> {
    let base = [0.0, 45.0, 90.0, 135.0];
    let mut out = Vec::new();
    for a in 0..4 {
        for b in 0..4 {
            for c in 0..4 {
                for d in 0..4 {
                    let idx = [a, b, c, d];
                    let mut seen = [false; 4];
                    if idx.iter().all(|&i| !std::mem::replace(&mut seen[i], true)) {
                        out.push(idx.map(|i| base[i]));
                    }
                }
            }
        }
    }
    assert_eq!(out.len(), 24);
    out
}

/// Raw mosaic from a per-pixel Stokes function.
fn mosaic(w: usize, h: usize, pat: &[f64; 4], s: impl Fn(usize, usize) -> [f64; 3]) -> Vec<f32> {
    let mut raw = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let a = pat[2 * (y % 2) + x % 2];
            raw[y * w + x] = intensity(s(x, y), a) as f32;
        }
    }
    raw
}

#[test]
fn superpixel_round_trip_is_exact_for_all_24_patterns() {
    let (w, h) = (24, 18);
    let mut rng = StdRng::seed_from_u64(3);
    let cells: Vec<[f64; 3]> = (0..(w / 2) * (h / 2))
        .map(|_| {
            let s0 = 50.0 + 4000.0 * rng.random::<f64>();
            let p = rng.random::<f64>();
            let t = 6.3 * rng.random::<f64>();
            [s0, s0 * p * t.cos(), s0 * p * t.sin()]
        })
        .collect();
    let mut worst = 0.0f64;
    for pat in all_patterns() {
        let p = Pattern::new(&pat).unwrap();
        let raw = mosaic(w, h, &pat, |x, y| cells[(y / 2) * (w / 2) + x / 2]);
        let n = (w / 2) * (h / 2);
        let (mut s0, mut s1, mut s2, mut m) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0; n]);
        let c = superpixel_stokes(
            &raw,
            w,
            &p,
            &PixelRules::default(),
            &mut s0,
            &mut s1,
            &mut s2,
            &mut m,
        )
        .unwrap();
        assert_eq!(c.valid as usize, n);
        for (i, s) in cells.iter().enumerate() {
            for (k, got) in [s0[i], s1[i], s2[i]].into_iter().enumerate() {
                worst = worst.max((got as f64 - s[k]).abs() / s[0]);
            }
        }
    }
    eprintln!("super-pixel, 24 patterns: worst |S - S_true| / S0 = {worst:.2e}");
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn bilinear_round_trip_is_exact_for_all_24_patterns() {
    // Uniform field: exact everywhere (borders included). Affine field: exact at every
    // interior pixel (bilinear interpolation reproduces affine functions).
    let (w, h) = (20, 14);
    let uniform = [1234.0, -321.0, 456.0];
    let affine = |x: usize, y: usize| {
        let (x, y) = (x as f64, y as f64);
        [
            2000.0 + 13.0 * x - 7.0 * y,
            200.0 - 9.0 * x + 4.0 * y,
            -150.0 + 5.0 * x + 11.0 * y,
        ]
    };
    let mut worst = 0.0f64;
    for pat in all_patterns() {
        let p = Pattern::new(&pat).unwrap();
        let n = w * h;
        for (field, interior_only) in [(0, false), (1, true)] {
            let raw = if field == 0 {
                mosaic(w, h, &pat, |_, _| uniform)
            } else {
                mosaic(w, h, &pat, affine)
            };
            let (mut s0, mut s1, mut s2, mut m) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0; n]);
            bilinear_stokes(
                &raw,
                w,
                &p,
                &PixelRules::default(),
                false,
                &mut s0,
                &mut s1,
                &mut s2,
                &mut m,
            )
            .unwrap();
            for y in 0..h {
                for x in 0..w {
                    if interior_only && (x == 0 || y == 0 || x == w - 1 || y == h - 1) {
                        continue;
                    }
                    let s = if field == 0 { uniform } else { affine(x, y) };
                    let i = y * w + x;
                    for (k, got) in [s0[i], s1[i], s2[i]].into_iter().enumerate() {
                        let e = (got as f64 - s[k]).abs() / s[0];
                        assert!(
                            e < 1e-6,
                            "{pat:?} field {field} ({x},{y}) S{k}: {got} vs {}",
                            s[k]
                        );
                        worst = worst.max(e);
                    }
                }
            }
        }
    }
    eprintln!("bilinear, 24 patterns: worst |S - S_true| / S0 = {worst:.2e}");
}

/// Oracle: polanalyser 3.0.0 `demosaicing(raw, COLOR_PolarMono)` (OpenCV 5.0.0
/// bilinear Bayer demosaicing) of this 8×10 uint16 mosaic, computed once in Python
/// (numpy default_rng(1).integers(0, 60000)). Channels 0° and 135°.
const RAW: [[u16; 10]; 8] = [
    [
        28391, 30709, 45310, 57027, 2091, 8649, 49376, 56918, 14953, 18709,
    ],
    [
        52141, 25399, 16390, 49662, 15419, 24551, 38629, 32975, 5144, 1653,
    ],
    [
        51935, 45210, 50273, 32288, 49052, 19783, 27160, 47305, 7435, 18191,
    ],
    [
        7465, 27209, 58614, 8042, 22998, 24186, 54232, 12207, 30135, 15738,
    ],
    [
        1189, 45021, 3721, 16824, 29894, 29111, 7016, 58844, 44946, 57699,
    ],
    [
        5526, 43487, 17588, 32473, 55495, 16613, 43552, 9639, 19354, 58195,
    ],
    [
        25267, 30964, 17578, 6951, 25475, 37409, 27335, 46600, 21771, 36780,
    ],
    [
        46367, 55037, 25638, 2375, 43111, 31715, 52325, 27560, 22084, 3740,
    ],
];
const PA_000: [[u16; 10]; 8] = [
    [
        25399, 25399, 37531, 49662, 37107, 24551, 28763, 32975, 17314, 17314,
    ],
    [
        25399, 25399, 37531, 49662, 37107, 24551, 28763, 32975, 17314, 17314,
    ],
    [
        26304, 26304, 27578, 28852, 26610, 24369, 23480, 22591, 15643, 15643,
    ],
    [
        27209, 27209, 17626, 8042, 16114, 24186, 18197, 12207, 13973, 13973,
    ],
    [
        35348, 35348, 27803, 20258, 20329, 20400, 15661, 10923, 23945, 23945,
    ],
    [
        43487, 43487, 37980, 32473, 24543, 16613, 13126, 9639, 33917, 33917,
    ],
    [
        49262, 49262, 33343, 17424, 20794, 24164, 21382, 18600, 24784, 24784,
    ],
    [
        49262, 49262, 33343, 17424, 20794, 24164, 21382, 18600, 24784, 24784,
    ],
];
const PA_135: [[u16; 10]; 8] = [
    [
        34266, 34266, 16390, 15905, 15419, 27024, 38629, 21887, 5144, 5144,
    ],
    [
        34266, 34266, 16390, 15905, 15419, 27024, 38629, 21887, 5144, 5144,
    ],
    [
        33653, 33653, 37502, 28355, 19209, 32820, 46431, 32035, 17640, 17640,
    ],
    [
        33040, 33040, 58614, 40806, 22998, 38615, 54232, 42184, 30135, 30135,
    ],
    [
        22298, 22298, 38101, 38674, 39247, 44069, 48892, 36818, 24745, 24745,
    ],
    [
        11557, 11557, 17588, 36542, 55495, 49524, 43552, 31453, 19354, 19354,
    ],
    [
        23780, 23780, 21613, 35458, 49303, 48621, 47939, 34329, 20719, 20719,
    ],
    [
        23780, 23780, 21613, 35458, 49303, 48621, 47939, 34329, 20719, 20719,
    ],
];

#[test]
fn bilinear_demosaicing_matches_polanalyser_exactly() {
    let raw: Vec<u16> = RAW.iter().flatten().copied().collect();
    let n = raw.len();
    let mut ch: Vec<Vec<f32>> = vec![vec![0.0; n]; 4];
    let [c0, c45, c90, c135] = &mut ch[..] else {
        unreachable!()
    };
    demosaic_bilinear(&raw, 10, &Pattern::imx250mzr(), true, [c0, c45, c90, c135]).unwrap();
    let want0: Vec<f32> = PA_000.iter().flatten().map(|&v| v as f32).collect();
    let want135: Vec<f32> = PA_135.iter().flatten().map(|&v| v as f32).collect();
    assert_eq!(ch[0], want0);
    assert_eq!(ch[3], want135);
    // The fused Stokes path uses the same interpolation.
    let (mut s0, mut s1, mut s2, mut m) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0; n]);
    bilinear_stokes(
        &raw,
        10,
        &Pattern::imx250mzr(),
        &PixelRules::default(),
        true,
        &mut s0,
        &mut s1,
        &mut s2,
        &mut m,
    )
    .unwrap();
    for i in 0..n {
        assert_eq!(s1[i], ch[0][i] - ch[2][i]);
        assert_eq!(s2[i], ch[1][i] - ch[3][i]);
    }
}

#[test]
fn saturated_raw_pixels_reject_their_neighbourhood() {
    let (w, h) = (8, 8);
    let mut raw = vec![100u16; w * h];
    raw[3 * w + 4] = 4095;
    let rules = PixelRules {
        saturation: 4095.0,
        ..PixelRules::default()
    };
    let n = w * h;
    let (mut s0, mut s1, mut s2, mut m) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0; n]);
    let c = bilinear_stokes(
        &raw,
        w,
        &Pattern::default(),
        &rules,
        false,
        &mut s0,
        &mut s1,
        &mut s2,
        &mut m,
    )
    .unwrap();
    assert_eq!(c.saturated, 9);
    for y in 0..h {
        for x in 0..w {
            let near = y.abs_diff(3) <= 1 && x.abs_diff(4) <= 1;
            assert_eq!(m[y * w + x] == mask::SATURATED, near, "({x},{y})");
        }
    }
    let q = n / 4;
    let (mut s0, mut s1, mut s2, mut m) = (vec![0.0; q], vec![0.0; q], vec![0.0; q], vec![0; q]);
    let c = superpixel_stokes(
        &raw,
        w,
        &Pattern::default(),
        &rules,
        &mut s0,
        &mut s1,
        &mut s2,
        &mut m,
    )
    .unwrap();
    assert_eq!((c.saturated, c.valid), (1, 15));
    assert_eq!(m[4 + 2], mask::SATURATED);
}

fn noisy_mosaic(w: usize, h: usize, pat: &[f64; 4], s: [f64; 3], rng: &mut StdRng) -> Vec<u16> {
    let read = Normal::new(0.0, 3.0).unwrap();
    let pois: Vec<Poisson<f64>> = pat
        .iter()
        .map(|&a| Poisson::new(intensity(s, a)).unwrap())
        .collect();
    let mut raw = vec![0u16; w * h];
    for y in 0..h {
        for x in 0..w {
            let e: f64 = pois[2 * (y % 2) + x % 2].sample(rng);
            raw[y * w + x] = (e + 64.0 + read.sample(rng)).round().clamp(0.0, 4095.0) as u16;
        }
    }
    raw
}

#[test]
fn dofp_region_dolp_is_within_three_standard_errors_in_99_percent_of_trials() {
    // 24×24 mosaic, 16×16 region away from the border; bilinear (variance inflation
    // 64/9) and super-pixel (independent cells, region of 8×8 cells).
    let (w, h) = (24, 24);
    let n = w * h;
    let rules = PixelRules {
        dark_level: 64.0,
        saturation: 4095.0,
        min_s0: 0.0,
    };
    let mut rng = StdRng::seed_from_u64(99);
    let pats = all_patterns();
    let trials = 1000;
    let (mut inside_bl, mut inside_sp) = (0, 0);
    let (mut se_bl, mut se_sp) = (0.0, 0.0);
    for t in 0..trials {
        let pat = pats[t % 24];
        let p = Pattern::new(&pat).unwrap();
        let dolp = 0.05 + 0.5 * (t as f64 / trials as f64);
        let psi = 0.3 + 0.013 * t as f64;
        let s = [
            1500.0,
            1500.0 * dolp * (2.0 * psi).cos(),
            1500.0 * dolp * (2.0 * psi).sin(),
        ];
        let raw = noisy_mosaic(w, h, &pat, s, &mut rng);
        let (mut s0, mut s1, mut s2, mut m) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0; n]);
        bilinear_stokes(
            &raw, w, &p, &rules, false, &mut s0, &mut s1, &mut s2, &mut m,
        )
        .unwrap();
        let r = Rect {
            x: 4,
            y: 4,
            width: 16,
            height: 16,
        };
        let st = region_stats(w, &s0, &s1, &s2, &m, r, Sampling::BilinearDofp).unwrap();
        se_bl += st.dolp_se.unwrap();
        if (st.dolp - dolp).abs() <= 3.0 * st.dolp_se.unwrap() {
            inside_bl += 1;
        }
        let q = n / 4;
        let (mut s0, mut s1, mut s2, mut m) =
            (vec![0.0; q], vec![0.0; q], vec![0.0; q], vec![0; q]);
        superpixel_stokes(&raw, w, &p, &rules, &mut s0, &mut s1, &mut s2, &mut m).unwrap();
        let r = Rect {
            x: 2,
            y: 2,
            width: 8,
            height: 8,
        };
        let st = region_stats(w / 2, &s0, &s1, &s2, &m, r, Sampling::Independent).unwrap();
        se_sp += st.dolp_se.unwrap();
        if (st.dolp - dolp).abs() <= 3.0 * st.dolp_se.unwrap() {
            inside_sp += 1;
        }
    }
    eprintln!(
        "DoFP coverage within 3 SE: bilinear {inside_bl}/{trials} (mean SE {:.5}), super-pixel {inside_sp}/{trials} (mean SE {:.5})",
        se_bl / trials as f64,
        se_sp / trials as f64
    );
    assert!(
        inside_bl as f64 >= 0.99 * trials as f64,
        "bilinear coverage {inside_bl}"
    );
    assert!(
        inside_sp as f64 >= 0.99 * trials as f64,
        "super-pixel coverage {inside_sp}"
    );
}
