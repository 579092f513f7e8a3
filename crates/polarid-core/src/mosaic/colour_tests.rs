//! The colour kernels against the per-pixel oracle (`colour_reference.rs`), bit for bit,
//! on every instruction set of this CPU; the documented bias of the bilinear method on
//! ramps and step edges, and of the super-pixel method on ramps.

use super::colour::colour_polar_isa;
use super::colour_reference::{RefBand, colour_reference};
use super::*;
use crate::error::CoreError;
use crate::stokes::mask;

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

/// Outputs of one band as owned buffers.
#[derive(Debug)]
struct Bufs {
    s: [Vec<f32>; 3],
    mask: Vec<u8>,
    dolp: Vec<f32>,
    aolp: Vec<f32>,
}

impl Bufs {
    fn new(n: usize) -> Self {
        Self {
            s: [vec![7.0; n], vec![7.0; n], vec![7.0; n]],
            mask: vec![9; n],
            dolp: vec![7.0; n],
            aolp: vec![7.0; n],
        }
    }
}

/// Which outputs to ask for: s0, s1, s2, mask, dolp, aolp.
type Ask = [bool; 6];

fn run<T: Sample>(
    isa: Isa,
    raw: &[T],
    w: usize,
    p: &ColourPattern,
    method: ColourMethod,
    rules: &PixelRules,
    ask: Ask,
) -> (Vec<Bufs>, Vec<PixelCounts>) {
    let h = raw.len() / w;
    let (ow, oh) = method.output_size(w, h);
    let mut bufs: Vec<Bufs> = p.bands().iter().map(|_| Bufs::new(ow * oh)).collect();
    let outs: Vec<DofpOutputs<'_>> = bufs
        .iter_mut()
        .map(|b| {
            let [s0, s1, s2] = &mut b.s;
            DofpOutputs {
                s0: ask[0].then_some(&mut s0[..]),
                s1: ask[1].then_some(&mut s1[..]),
                s2: ask[2].then_some(&mut s2[..]),
                mask: ask[3].then_some(&mut b.mask[..]),
                dolp: ask[4].then_some(&mut b.dolp[..]),
                aolp: ask[5].then_some(&mut b.aolp[..]),
            }
        })
        .collect();
    let counts = colour_polar_isa(isa, raw, w, p, method, rules, outs).unwrap();
    (bufs, counts)
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

fn check_against<T: Sample>(
    raw: &[T],
    w: usize,
    p: &ColourPattern,
    method: ColourMethod,
    rules: &PixelRules,
    what: &str,
) {
    let want: Vec<RefBand> = colour_reference(raw, w, p, method, rules);
    for isa in cpu_features().all() {
        for ask in [
            [true; 6],
            [false, false, false, false, true, true],
            [true, false, true, false, false, false],
            [false, false, false, true, false, true],
        ] {
            let (got, counts) = run(isa, raw, w, p, method, rules, ask);
            for (b, (g, r)) in got.iter().zip(&want).enumerate() {
                let ctx = format!("{what} {method:?} {isa:?} ask {ask:?} band {b}");
                assert_eq!(counts[b], r.counts, "{ctx}: counts");
                let refs = [&r.s0, &r.s1, &r.s2];
                for q in 0..3 {
                    if ask[q] {
                        assert!(same_bits(&g.s[q], refs[q]), "{ctx}: s{q}");
                    }
                }
                if ask[3] {
                    assert_eq!(g.mask, r.mask, "{ctx}: mask");
                }
                if ask[4] {
                    assert!(same_bits(&g.dolp, &r.dolp), "{ctx}: dolp");
                }
                if ask[5] {
                    assert!(same_bits(&g.aolp, &r.aolp), "{ctx}: aolp");
                }
            }
        }
    }
}

fn patterns() -> Vec<(ColourPattern, &'static str)> {
    vec![
        (ColourPattern::imx250myr(), "imx"),
        (
            ColourPattern::new(Pattern::new(&[0.0, 45.0, 135.0, 90.0]).unwrap(), "gbrg").unwrap(),
            "gbrg",
        ),
        (
            ColourPattern::new(Pattern::default(), "RGBW").unwrap(),
            "rgbw",
        ),
        (
            ColourPattern::new(Pattern::default(), "GGGB").unwrap(),
            "gggb",
        ),
    ]
}

#[test]
fn fused_matches_reference_u16() {
    // sizes: one period, columns across a block boundary (256), odd numbers of groups
    for (w, h) in [(4, 4), (8, 12), (20, 8), (264, 20), (532, 36)] {
        let mut r = Lcg(w as u64 * 31 + h as u64);
        let mut raw: Vec<u16> = (0..w * h).map(|_| (r.next() % 4096) as u16).collect();
        for i in [0, w - 1, w * h - 1, w * (h / 2) + 5] {
            raw[i] = 4095;
        }
        if w >= 20 {
            for y in 2..6 {
                raw[y * w + 8..y * w + 16].fill(1);
            }
        }
        let rules = PixelRules {
            dark_level: 3.0,
            saturation: 4095.0,
            min_s0: 4.0,
        };
        for (p, name) in patterns() {
            for method in [ColourMethod::Bilinear, ColourMethod::Superpixel] {
                check_against(&raw, w, &p, method, &rules, &format!("u16 {w}x{h} {name}"));
            }
        }
    }
}

#[test]
fn fused_matches_reference_u8_f32() {
    let (w, h) = (268, 16);
    let mut r = Lcg(5);
    let raw8: Vec<u8> = (0..w * h).map(|_| r.next() as u8).collect();
    let mut rawf: Vec<f32> = (0..w * h)
        .map(|_| (r.next() % 10000) as f32 * 0.37)
        .collect();
    rawf[w * 3 + 7] = f32::NAN;
    rawf[w * 9 + 200] = f32::INFINITY;
    rawf[0] = f32::NEG_INFINITY;
    rawf[w * 12 + 100] = 5000.0;
    for (p, name) in patterns() {
        for method in [ColourMethod::Bilinear, ColourMethod::Superpixel] {
            let rules = PixelRules {
                dark_level: 1.0,
                saturation: 255.0,
                min_s0: 0.0,
            };
            check_against(&raw8, w, &p, method, &rules, &format!("u8 {name}"));
            for sat in [f32::INFINITY, 3500.0] {
                let rules = PixelRules {
                    dark_level: 0.5,
                    saturation: sat,
                    min_s0: 1.0,
                };
                check_against(
                    &rawf,
                    w,
                    &p,
                    method,
                    &rules,
                    &format!("f32 {name} sat {sat}"),
                );
            }
        }
    }
}

#[test]
fn rejects_bad_sizes_and_outputs() {
    let p = ColourPattern::imx250myr();
    let raw = vec![0u16; 6 * 8];
    let rules = PixelRules::default();
    let e = colour_polar(&raw, 6, &p, ColourMethod::Bilinear, &rules, vec![]).unwrap_err();
    assert!(
        matches!(e, CoreError::InvalidDimensions { width: 6, .. }),
        "{e}"
    );
    let raw = vec![0u16; 8 * 8];
    let e = colour_polar(&raw, 8, &p, ColourMethod::Bilinear, &rules, vec![]).unwrap_err();
    assert!(
        matches!(
            e,
            CoreError::LengthMismatch {
                name: "band outputs",
                expected: 3,
                got: 0
            }
        ),
        "{e}"
    );
    let mut short = vec![0f32; 10];
    let outs = vec![
        DofpOutputs {
            s0: Some(&mut short),
            ..Default::default()
        },
        DofpOutputs::default(),
        DofpOutputs::default(),
    ];
    let e = colour_polar(&raw, 8, &p, ColourMethod::Superpixel, &rules, outs).unwrap_err();
    assert!(
        matches!(e, CoreError::LengthMismatch { name: "s0", .. }),
        "{e}"
    );
    for bad in ["RGB", "RGGBR", "RG1B", ""] {
        let e = ColourPattern::new(Pattern::default(), bad).unwrap_err();
        assert!(matches!(e, CoreError::InvalidName { .. }), "{bad}: {e}");
    }
    let p = ColourPattern::new(Pattern::default(), "rggb").unwrap();
    assert_eq!(p, ColourPattern::imx250myr());
    assert_eq!(p.color(), "RGGB");
    assert_eq!((0..4).filter(|&b| p.block_band(b) == 1).count(), 2);
    // IMX250MYR: pixel (0,0) is R at 90°, (3,2) is B at 135°, (1,3) is G at 0°
    assert_eq!(p.channel_at(0, 0), (0, 2));
    assert_eq!(p.channel_at(3, 2), (2, 3));
    assert_eq!(p.channel_at(1, 3), (1, 0));
}

/// All bands of a bilinear reconstruction with every output (default ISA).
fn bilinear_all(raw: &[u16], w: usize, p: &ColourPattern) -> Vec<Bufs> {
    let rules = PixelRules::default();
    run(
        cpu_features().best(),
        raw,
        w,
        p,
        ColourMethod::Bilinear,
        &rules,
        [true; 6],
    )
    .0
}

#[test]
fn bilinear_reproduces_linear_ramps_exactly() {
    let (w, h) = (48, 40);
    for (gx, gy) in [(3u16, 5u16), (17, 0), (0, 11)] {
        let ramp = |y: usize, x: usize| 100 + gx as usize * x + gy as usize * y;
        let raw: Vec<u16> = (0..w * h).map(|i| ramp(i / w, i % w) as u16).collect();
        for (p, name) in patterns() {
            for (b, o) in bilinear_all(&raw, w, &p).iter().enumerate() {
                for y in 3..h - 3 {
                    for x in 3..w - 3 {
                        let i = y * w + x;
                        let ctx = format!("{name} band {b} ({y},{x}) g=({gx},{gy})");
                        assert_eq!(o.s[0][i], 2.0 * ramp(y, x) as f32, "{ctx}: S0");
                        assert_eq!((o.s[1][i], o.s[2][i], o.dolp[i]), (0.0, 0.0, 0.0), "{ctx}");
                        assert_eq!(o.mask[i], mask::VALID, "{ctx}");
                    }
                }
            }
        }
    }
}

#[test]
fn superpixel_ramp_bias_is_the_documented_one() {
    let (w, h) = (32, 24);
    let (gx, gy) = (6.0f32, 2.0f32);
    let raw: Vec<f32> = (0..w * h)
        .map(|i| 1000.0 + gx * (i % w) as f32 + gy * (i / w) as f32)
        .collect();
    let p = ColourPattern::imx250myr();
    let rules = PixelRules::default();
    let (bufs, _) = run(
        Isa::Portable,
        &raw,
        w,
        &p,
        ColourMethod::Superpixel,
        &rules,
        [true; 6],
    );
    for o in &bufs {
        for i in 0..o.s[0].len() {
            assert_eq!((o.s[1][i], o.s[2][i]), (gx + gy, gx - gy));
            let want = (2.0f32).sqrt() * (gx * gx + gy * gy).sqrt() / o.s[0][i];
            assert!((o.dolp[i] - want).abs() < 1e-6, "{} vs {want}", o.dolp[i]);
        }
    }
}

/// The bound of the documented false DoLP of a step from `a` to `b`.
fn step_bound(a: f32, b: f32) -> f32 {
    let d = b - a;
    (3.0 * 2f32.sqrt() * d / (8.0 * a + 3.0 * d)).min(1.0)
}

#[test]
fn bilinear_step_edge_false_dolp_is_confined_and_bounded() {
    let (w, h) = (40, 32);
    let p = ColourPattern::imx250myr();
    for (a, b) in [(500u16, 1000u16), (1000, 1100), (100, 1000)] {
        let bound = step_bound(a as f32, b as f32);
        for vertical in [true, false] {
            let mut worst = 0f32;
            for xe in 16..20 {
                let raw: Vec<u16> = (0..w * h)
                    .map(|i| {
                        let c = if vertical { i % w } else { i / w };
                        if c >= xe { b } else { a }
                    })
                    .collect();
                for (band, o) in bilinear_all(&raw, w, &p).iter().enumerate() {
                    for i in 0..w * h {
                        let c = if vertical { i % w } else { i / w };
                        let ctx = format!("step {a}->{b} at {xe} vertical {vertical} band {band}");
                        if c + 3 < xe || c > xe + 2 {
                            assert_eq!(o.dolp[i], 0.0, "{ctx}: pixel {i} outside the band");
                        } else {
                            assert!(o.dolp[i] <= bound + 1e-6, "{ctx}: {} > {bound}", o.dolp[i]);
                            worst = worst.max(o.dolp[i]);
                        }
                    }
                }
            }
            assert!(
                worst >= bound - 1e-6,
                "step {a}->{b}: bound {bound} not reached ({worst})"
            );
        }
    }
    assert!((step_bound(500.0, 1000.0) - 0.386).abs() < 1e-3);
    assert!((step_bound(1000.0, 1100.0) - 0.0511).abs() < 1e-3);
}
