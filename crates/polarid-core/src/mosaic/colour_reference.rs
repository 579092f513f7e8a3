//! The colour reconstructions written the obvious way, one output pixel at a time from
//! the definitions of [`super::colour`]: the oracle the fused kernels must match bit for
//! bit. Test-only.

use super::colour::{ColourMethod, ColourPattern};
use crate::stokes::{PixelCounts, PixelRules, Sample, dolp_aolp_pixel, mask};

/// The outputs of one band.
#[derive(Debug, Clone)]
pub(super) struct RefBand {
    pub s0: Vec<f32>,
    pub s1: Vec<f32>,
    pub s2: Vec<f32>,
    pub mask: Vec<u8>,
    pub dolp: Vec<f32>,
    pub aolp: Vec<f32>,
    pub counts: PixelCounts,
}

/// The two taps and phase along one axis (`p`: position, `r`: lattice residue, `n`:
/// axis length): `e = (p − r) mod 4`, taps `p − e` and `p − e + 4` clamped to the
/// lattice's samples `r ..= r + n − 4`.
fn axis(p: usize, r: usize, n: usize) -> (usize, usize, usize) {
    let e = (p as i64 - r as i64).rem_euclid(4) as usize;
    let lo = p as i64 - e as i64;
    let (first, last) = (r as i64, (r + n - 4) as i64);
    (
        lo.clamp(first, last) as usize,
        (lo + 4).clamp(first, last) as usize,
        e,
    )
}

/// `(value, samples with a non-zero weight)` of lattice `(rho, chi)` at `(y, x)`.
fn interpolate<T: Sample>(
    raw: &[T],
    w: usize,
    h: usize,
    rho: usize,
    chi: usize,
    y: usize,
    x: usize,
) -> (f32, Vec<f32>) {
    let (ya, yb, ey) = axis(y, rho, h);
    let (xa, xb, ex) = axis(x, chi, w);
    let at = |yy: usize, xx: usize| raw[yy * w + xx].to_f32();
    let blend = |e: usize, a: f32, b: f32| {
        if e == 0 {
            a
        } else {
            let wb = e as f32 / 4.0;
            (1.0 - wb) * a + wb * b
        }
    };
    let vert = |xx: usize| blend(ey, at(ya, xx), at(yb, xx));
    let v = blend(ex, vert(xa), vert(xb));
    let rows: Vec<usize> = if ey == 0 { vec![ya] } else { vec![ya, yb] };
    let cols: Vec<usize> = if ex == 0 { vec![xa] } else { vec![xa, xb] };
    let used = rows
        .iter()
        .flat_map(|&yy| cols.iter().map(move |&xx| (yy, xx)))
        .map(|(yy, xx)| at(yy, xx))
        .collect();
    (v, used)
}

/// Stokes, mask, DoLP and AoLP from the four channel values and the band's used raw
/// values.
fn finish(i: [f32; 4], used: &[f32], rules: &PixelRules, dark2: f32) -> ([f32; 3], u8, f32, f32) {
    let [i0, i45, i90, i135] = i;
    let s0 = 0.5 * ((i0 + i90) + (i45 + i135)) - dark2;
    let s1 = i0 - i90;
    let s2 = i45 - i135;
    let m = if !(s0 + s1 + s2).is_finite() {
        mask::INVALID
    } else if used.iter().any(|&v| v >= rules.saturation) {
        mask::SATURATED
    } else if s0 <= rules.min_s0 {
        mask::DARK
    } else {
        mask::VALID
    };
    let (d, a) = if m == mask::VALID {
        dolp_aolp_pixel(s0, s1, s2)
    } else {
        (f32::NAN, f32::NAN)
    };
    ([s0, s1, s2], m, d, a)
}

/// Every band's outputs of `raw` (`width` wide) by `method`.
pub(super) fn colour_reference<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &ColourPattern,
    method: ColourMethod,
    rules: &PixelRules,
) -> Vec<RefBand> {
    let (w, h) = (width, raw.len() / width);
    let (ow, oh) = method.output_size(w, h);
    let lattices = |b: usize, k: usize| -> Vec<(usize, usize)> {
        let mut v = Vec::new();
        for rho in 0..4 {
            for chi in 0..4 {
                if pattern.channel_at(rho, chi) == (b, k) {
                    v.push((rho, chi));
                }
            }
        }
        v
    };
    (0..pattern.bands().len())
        .map(|b| {
            let mut o = RefBand {
                s0: vec![0.0; ow * oh],
                s1: vec![0.0; ow * oh],
                s2: vec![0.0; ow * oh],
                mask: vec![0; ow * oh],
                dolp: vec![0.0; ow * oh],
                aolp: vec![0.0; ow * oh],
                counts: PixelCounts::default(),
            };
            let lats: Vec<Vec<(usize, usize)>> = (0..4).map(|k| lattices(b, k)).collect();
            let n = lats[0].len();
            let inv = 1.0 / n as f32;
            for y in 0..oh {
                for x in 0..ow {
                    let mut used = Vec::new();
                    let mut iv = [0f32; 4];
                    let dark2;
                    match method {
                        ColourMethod::Bilinear => {
                            for (k, lk) in lats.iter().enumerate() {
                                let mut sum = 0f32;
                                for (j, &(rho, chi)) in lk.iter().enumerate() {
                                    let (v, u) = interpolate(raw, w, h, rho, chi, y, x);
                                    sum = if j == 0 { v } else { sum + v };
                                    used.extend(u);
                                }
                                iv[k] = if n == 1 { sum } else { sum * inv };
                            }
                            dark2 = 2.0 * rules.dark_level;
                        }
                        ColourMethod::Superpixel => {
                            for (k, lk) in lats.iter().enumerate() {
                                let mut sum = 0f32;
                                for &(rho, chi) in lk {
                                    let v = raw[(4 * y + rho) * w + 4 * x + chi].to_f32();
                                    sum += v;
                                    used.push(v);
                                }
                                iv[k] = sum * inv - rules.dark_level;
                            }
                            dark2 = 0.0;
                        }
                    }
                    let (s, m, d, a) = finish(iv, &used, rules, dark2);
                    let p = y * ow + x;
                    (o.s0[p], o.s1[p], o.s2[p]) = (s[0], s[1], s[2]);
                    (o.mask[p], o.dolp[p], o.aolp[p]) = (m, d, a);
                }
            }
            o.counts = PixelCounts::from_mask(&o.mask);
            o
        })
        .collect()
}
