//! The fused kernels against the reference reconstructions (`reference.rs`), bit for
//! bit, on every instruction set of this CPU: all outputs and subsets of them, both
//! methods, rounding on and off, `u8` / `u16` / `f32` data with saturated, dark and
//! non-finite pixels on the edges and corners, sizes that leave partial vector lanes,
//! column blocks and row strips.

use super::*;
use crate::error::CoreError;
use crate::stokes::{dolp_aolp, mask};

/// A deterministic stream of pseudo-random numbers.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 33) as u32
    }
}

/// Set rows 3..8, columns 3..10 to `low` (when the mosaic is large enough), so that
/// some pixels are dark.
fn dark_patch<T: Copy>(v: &mut [T], w: usize, h: usize, low: T) {
    if w >= 12 && h >= 10 {
        for y in 3..8 {
            v[y * w + 3..y * w + 10].fill(low);
        }
    }
}

/// Raw test data of one sample type.
trait TestSample: Sample + PartialEq + std::fmt::Debug {
    /// A mosaic with values up to `max` and, where the type allows, non-finite values.
    fn mosaic(w: usize, h: usize, seed: u64) -> Vec<Self>;
}

impl TestSample for u16 {
    fn mosaic(w: usize, h: usize, seed: u64) -> Vec<Self> {
        let mut r = Lcg(seed);
        let mut v: Vec<u16> = (0..w * h).map(|_| (r.next() % 4096) as u16).collect();
        // saturated corners and an edge, and a dark patch
        for i in [0, w - 1, w * h - 1, w * (h - 1), w * (h / 2)] {
            v[i] = 4095;
        }
        dark_patch(&mut v, w, h, 1);
        v
    }
}

impl TestSample for u8 {
    fn mosaic(w: usize, h: usize, seed: u64) -> Vec<Self> {
        let mut r = Lcg(seed);
        let mut v: Vec<u8> = (0..w * h).map(|_| r.next() as u8).collect();
        v[w * h - 2] = 255;
        v[3] = 255;
        dark_patch(&mut v, w, h, 0);
        v
    }
}

impl TestSample for f32 {
    fn mosaic(w: usize, h: usize, seed: u64) -> Vec<Self> {
        let mut r = Lcg(seed);
        let mut v: Vec<f32> = (0..w * h)
            .map(|_| (r.next() % 380_000) as f32 / 97.0 - 3.0)
            .collect();
        v[0] = f32::NAN;
        v[w - 1] = f32::INFINITY;
        v[w * h - 1] = f32::NEG_INFINITY;
        v[w * (h / 2) + w / 2] = f32::NAN;
        v[w * (h - 1) + 1] = 3.0e38;
        v[2 * w + 2] = 4095.0;
        dark_patch(&mut v, w, h, 0.25);
        v
    }
}

/// Every output of a reconstruction, as bits.
#[derive(Debug, PartialEq)]
struct Bits {
    s: [Vec<u32>; 3],
    mask: Vec<u8>,
    dolp: Vec<u32>,
    aolp: Vec<u32>,
    counts: PixelCounts,
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|f| f.to_bits()).collect()
}

/// The unfused path: reference Stokes and mask, then DoLP / AoLP with the mask.
fn reference<T: Sample>(
    raw: &[T],
    w: usize,
    p: &Pattern,
    method: DofpMethod,
    rules: &PixelRules,
) -> Bits {
    let h = raw.len() / w;
    let (ow, oh) = method.output_size(w, h);
    let n = ow * oh;
    let mut s = [vec![0f32; n], vec![0f32; n], vec![0f32; n]];
    let mut m = vec![0u8; n];
    let [s0, s1, s2] = &mut s;
    let counts = match method {
        DofpMethod::Bilinear { round } => {
            reference::bilinear_stokes(raw, w, p, rules, round, s0, s1, s2, &mut m).unwrap()
        }
        DofpMethod::Superpixel => {
            reference::superpixel_stokes(raw, w, p, rules, s0, s1, s2, &mut m).unwrap()
        }
    };
    let (mut d, mut a) = (vec![0f32; n], vec![0f32; n]);
    dolp_aolp(ow, &s[0], &s[1], &s[2], Some(&m), &mut d, &mut a).unwrap();
    Bits {
        s: [bits(&s[0]), bits(&s[1]), bits(&s[2])],
        mask: m,
        dolp: bits(&d),
        aolp: bits(&a),
        counts,
    }
}

/// The fused kernel with the outputs selected by `want` (s0, s1, s2, mask, dolp, aolp);
/// outputs not asked for are left as a sentinel in the result.
fn fused<T: Sample>(
    isa: Isa,
    raw: &[T],
    w: usize,
    p: &Pattern,
    method: DofpMethod,
    rules: &PixelRules,
    want: [bool; 6],
) -> Bits {
    let h = raw.len() / w;
    let (ow, oh) = method.output_size(w, h);
    let n = ow * oh;
    let sentinel = -7.25f32;
    let mut f: Vec<Vec<f32>> = (0..5).map(|_| vec![sentinel; n]).collect();
    let mut m = vec![9u8; n];
    let [s0, s1, s2, d, a] = &mut f[..] else {
        unreachable!()
    };
    let out = DofpOutputs {
        s0: want[0].then_some(&mut s0[..]),
        s1: want[1].then_some(&mut s1[..]),
        s2: want[2].then_some(&mut s2[..]),
        mask: want[3].then_some(&mut m[..]),
        dolp: want[4].then_some(&mut d[..]),
        aolp: want[5].then_some(&mut a[..]),
    };
    let counts = dofp_polar_isa(isa, raw, w, p, method, rules, out).unwrap();
    Bits {
        s: [bits(&f[0]), bits(&f[1]), bits(&f[2])],
        mask: m,
        dolp: bits(&f[3]),
        aolp: bits(&f[4]),
        counts,
    }
}

/// `got` equals `want` on the outputs selected by `sel`, and the counts agree.
fn assert_selected(got: &Bits, want: &Bits, sel: [bool; 6], ctx: &str) {
    assert_eq!(got.counts, want.counts, "{ctx}: counts");
    for (k, (g, w)) in got.s.iter().zip(&want.s).enumerate() {
        if sel[k] {
            assert_eq!(g, w, "{ctx}: s{k}");
        } else {
            assert!(
                g.iter().all(|&b| b == (-7.25f32).to_bits()),
                "{ctx}: s{k} written"
            );
        }
    }
    if sel[3] {
        assert_eq!(got.mask, want.mask, "{ctx}: mask");
    }
    if sel[4] {
        assert_eq!(got.dolp, want.dolp, "{ctx}: dolp");
    }
    if sel[5] {
        assert_eq!(got.aolp, want.aolp, "{ctx}: aolp");
    }
}

/// Sizes: the smallest, partial vectors, several column blocks (interior widths over
/// 512 and 1024) and several row strips.
const SIZES: [(usize, usize); 7] = [
    (4, 4),
    (6, 4),
    (4, 6),
    (18, 10),
    (1030, 6),
    (70, 36),
    (2 * kernel::BLOCK + 10, 4),
];

fn patterns() -> Vec<Pattern> {
    [
        [90.0, 45.0, 135.0, 0.0],
        [0.0, 45.0, 135.0, 90.0],
        [0.0, 90.0, 45.0, 135.0],
        [45.0, 0.0, 90.0, 135.0],
        [135.0, 90.0, 0.0, 45.0],
    ]
    .iter()
    .map(|a| Pattern::new(a).unwrap())
    .collect()
}

fn check_type<T: TestSample>(rules: &PixelRules) {
    let selections = [
        [true; 6],
        [false, false, false, false, true, true],
        [false, false, false, false, true, false],
        [false, true, false, true, false, false],
        [true, true, true, true, false, false],
    ];
    for (si, &(w, h)) in SIZES.iter().enumerate() {
        let raw = T::mosaic(w, h, 17 + si as u64);
        for (pi, p) in patterns().iter().enumerate() {
            for method in [
                DofpMethod::Superpixel,
                DofpMethod::Bilinear { round: false },
                DofpMethod::Bilinear { round: true },
            ] {
                let want = reference(&raw, w, p, method, rules);
                if w * h > 100 {
                    assert!(want.counts.valid > 0, "{w}x{h}: no valid pixel");
                }
                for isa in cpu_features().all() {
                    for sel in selections {
                        let got = fused(isa, &raw, w, p, method, rules, sel);
                        let ctx = format!(
                            "{} {w}x{h} pattern {pi} {method:?} {isa:?} {sel:?}",
                            std::any::type_name::<T>()
                        );
                        assert_selected(&got, &want, sel, &ctx);
                    }
                }
            }
        }
    }
}

#[test]
fn fused_matches_unfused_u16() {
    let rules = PixelRules {
        dark_level: 12.5,
        saturation: 4095.0,
        min_s0: 40.0,
    };
    check_type::<u16>(&rules);
    check_type::<u16>(&PixelRules::default());
}

#[test]
fn fused_matches_unfused_u8() {
    let rules = PixelRules {
        dark_level: 3.0,
        saturation: 255.0,
        min_s0: 8.0,
    };
    check_type::<u8>(&rules);
}

#[test]
fn fused_matches_unfused_f32() {
    let rules = PixelRules {
        dark_level: 1.37,
        saturation: 4000.0,
        min_s0: 2.0,
    };
    check_type::<f32>(&rules);
    check_type::<f32>(&PixelRules::default());
}

/// The rejection classes all occur in the test data (so that the comparisons above
/// cover them).
#[test]
fn test_data_has_every_mask_value() {
    let rules = PixelRules {
        dark_level: 1.37,
        saturation: 4000.0,
        min_s0: 2.0,
    };
    let (w, h) = (70, 36);
    let raw = f32::mosaic(w, h, 3);
    let b = fused(
        cpu_features().best(),
        &raw,
        w,
        &Pattern::default(),
        DofpMethod::Bilinear { round: false },
        &rules,
        [true; 6],
    );
    let c = b.counts;
    assert!(
        c.valid > 0 && c.saturated > 0 && c.dark > 0 && c.invalid > 0,
        "{c:?}"
    );
    assert_eq!(c, PixelCounts::from_mask(&b.mask));
    assert!(b.mask.contains(&mask::DARK));
}

/// Demosaicing into `f32` planes (with and without a dark level) and into integer
/// planes equals the reference interpolation on every instruction set.
#[test]
fn demosaic_matches_reference() {
    for (si, &(w, h)) in SIZES.iter().enumerate() {
        let r16 = u16::mosaic(w, h, 5 + si as u64);
        let r8 = u8::mosaic(w, h, 9 + si as u64);
        let rf = f32::mosaic(w, h, 11 + si as u64);
        let n = w * h;
        for p in patterns() {
            for round in [false, true] {
                let mut want = vec![vec![0f32; n]; 4];
                let [a, b, c, d] = &mut want[..] else {
                    unreachable!()
                };
                reference::demosaic_bilinear(&r16, w, &p, round, [a, b, c, d]).unwrap();
                let mut wantf = vec![vec![0f32; n]; 4];
                let [a, b, c, d] = &mut wantf[..] else {
                    unreachable!()
                };
                reference::demosaic_bilinear(&rf, w, &p, round, [a, b, c, d]).unwrap();
                for isa in cpu_features().all() {
                    for dark in [0.0f32, 2.75] {
                        let mut got = vec![vec![0f32; n]; 4];
                        let [a, b, c, d] = &mut got[..] else {
                            unreachable!()
                        };
                        demosaic_bilinear_isa(isa, &r16, w, &p, round, dark, [a, b, c, d]).unwrap();
                        for k in 0..4 {
                            let wk: Vec<u32> =
                                want[k].iter().map(|v| (v - dark).to_bits()).collect();
                            assert_eq!(bits(&got[k]), wk, "{w}x{h} {p:?} {round} {isa:?} {k}");
                        }
                        let [a, b, c, d] = &mut got[..] else {
                            unreachable!()
                        };
                        demosaic_bilinear_isa(isa, &rf, w, &p, round, dark, [a, b, c, d]).unwrap();
                        for k in 0..4 {
                            let wk: Vec<u32> =
                                wantf[k].iter().map(|v| (v - dark).to_bits()).collect();
                            assert_eq!(bits(&got[k]), wk, "f32 {w}x{h} {p:?} {round} {isa:?} {k}");
                        }
                    }
                    if round {
                        let mut got = vec![vec![0u16; n]; 4];
                        let [a, b, c, d] = &mut got[..] else {
                            unreachable!()
                        };
                        demosaic_bilinear_int_isa(isa, &r16, w, &p, [a, b, c, d]).unwrap();
                        for k in 0..4 {
                            let wk: Vec<u16> = want[k].iter().map(|&v| v as u16).collect();
                            assert_eq!(got[k], wk, "u16 {w}x{h} {p:?} {isa:?} {k}");
                        }
                        let mut want8 = vec![vec![0f32; n]; 4];
                        let [a, b, c, d] = &mut want8[..] else {
                            unreachable!()
                        };
                        reference::demosaic_bilinear(&r8, w, &p, true, [a, b, c, d]).unwrap();
                        let mut got = vec![vec![0u8; n]; 4];
                        let [a, b, c, d] = &mut got[..] else {
                            unreachable!()
                        };
                        demosaic_bilinear_int_isa(isa, &r8, w, &p, [a, b, c, d]).unwrap();
                        for k in 0..4 {
                            let wk: Vec<u8> = want8[k].iter().map(|&v| v as u8).collect();
                            assert_eq!(got[k], wk, "u8 {w}x{h} {p:?} {isa:?} {k}");
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn pattern_validation() {
    assert!(Pattern::new(&[90.0, 45.0, 135.0, 0.0]).is_ok());
    assert_eq!(
        Pattern::new(&[90.0, 45.0, 135.0, 0.0]).unwrap(),
        Pattern::imx250mzr()
    );
    for bad in [
        vec![0.0, 45.0, 90.0],
        vec![0.0, 45.0, 90.0, 90.0],
        vec![0.0, 45.0, 90.0, 120.0],
        vec![0.0, 45.0, 90.0, 180.0],
        vec![0.0, 45.0, 90.0, f64::NAN],
    ] {
        assert!(
            matches!(Pattern::new(&bad), Err(CoreError::InvalidPattern { .. })),
            "{bad:?}"
        );
    }
    let p = Pattern::imx250mzr();
    assert_eq!(p.position(0), (1, 1));
    assert_eq!(p.position(2), (0, 0));
}

#[test]
fn odd_sizes_rejected() {
    let raw = vec![0u16; 6 * 5];
    let mut o = vec![0f32; 30];
    let mut m = vec![0u8; 30];
    let e = bilinear_stokes(
        &raw,
        6,
        &Pattern::default(),
        &PixelRules::default(),
        false,
        &mut o.clone(),
        &mut o.clone(),
        &mut o,
        &mut m,
    );
    assert!(matches!(e, Err(CoreError::InvalidDimensions { .. })));
}

/// Bad sizes and buffers are refused naming what is wrong, before anything is written.
#[test]
fn fused_refuses_bad_sizes() {
    let raw = vec![0u16; 8 * 6];
    let p = Pattern::default();
    let rules = PixelRules::default();
    let mut d = vec![1f32; 8 * 6 - 1];
    let e = dofp_polar(
        &raw,
        8,
        &p,
        DofpMethod::Bilinear { round: true },
        &rules,
        DofpOutputs {
            dolp: Some(&mut d),
            ..Default::default()
        },
    );
    assert!(
        matches!(e, Err(CoreError::LengthMismatch { name: "dolp", .. })),
        "{e:?}"
    );
    assert!(d.iter().all(|&v| v == 1.0));
    let mut a = vec![0f32; 12];
    let e = dofp_polar(
        &raw,
        8,
        &p,
        DofpMethod::Superpixel,
        &rules,
        DofpOutputs {
            aolp: Some(&mut a),
            ..Default::default()
        },
    );
    assert!(e.is_ok(), "{e:?}");
    let small = vec![0u16; 2 * 2];
    let e = dofp_polar(
        &small,
        2,
        &p,
        DofpMethod::Bilinear { round: false },
        &rules,
        DofpOutputs::default(),
    );
    assert!(
        matches!(e, Err(CoreError::InvalidDimensions { .. })),
        "{e:?}"
    );
    let bad = PixelRules {
        dark_level: f32::NAN,
        ..rules
    };
    let e = dofp_polar(
        &raw,
        8,
        &p,
        DofpMethod::Superpixel,
        &bad,
        DofpOutputs::default(),
    );
    assert!(matches!(e, Err(CoreError::NonFinite { .. })), "{e:?}");
}
