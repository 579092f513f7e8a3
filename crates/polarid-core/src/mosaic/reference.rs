//! The reconstructions as they were before the fused kernels (row by row, with
//! full-size channel images for [`demosaic_bilinear`]): the oracle the fused kernels
//! must match bit for bit. Test-only.

use rayon::prelude::*;

use super::Pattern;
use super::pattern::check_mosaic;
use crate::error::{Result, check_len};
use crate::stokes::{PixelCounts, PixelRules, Sample, finish_mask_row};

/// Super-pixel Stokes: one Stokes vector per 2×2 cell of `raw` (`width × height`, both
/// even). Outputs are `(width/2) × (height/2)`. A cell is saturated / invalid when any of
/// its four raw pixels is, dark when its `S0 <= rules.min_s0`.
#[allow(clippy::too_many_arguments)]
pub(super) fn superpixel_stokes<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    rules: &PixelRules,
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    mask: &mut [u8],
) -> Result<PixelCounts> {
    rules.validate()?;
    let height = check_mosaic(width, raw.len(), 2)?;
    let (ow, oh) = (width / 2, height / 2);
    for (name, l) in [("s0", s0.len()), ("s1", s1.len()), ("s2", s2.len())] {
        check_len(name, l, ow * oh)?;
    }
    check_len("mask", mask.len(), ow * oh)?;
    // Offsets within the cell (row-major 0..4) of the 0, 45, 90, 135 polarizers.
    let p = pattern.pos;
    let (dark, sat) = (rules.dark_level, rules.saturation);
    let counts = s0
        .par_chunks_mut(ow)
        .zip(s1.par_chunks_mut(ow))
        .zip(s2.par_chunks_mut(ow))
        .zip(mask.par_chunks_mut(ow))
        .enumerate()
        .map(|(cy, (((r0, r1), r2), rm))| {
            let top = &raw[2 * cy * width..(2 * cy + 1) * width];
            let bot = &raw[(2 * cy + 1) * width..(2 * cy + 2) * width];
            for (cx, (((a0, a1), a2), m)) in r0
                .iter_mut()
                .zip(r1.iter_mut())
                .zip(r2.iter_mut())
                .zip(rm.iter_mut())
                .enumerate()
            {
                let cell = [
                    top[2 * cx].to_f32(),
                    top[2 * cx + 1].to_f32(),
                    bot[2 * cx].to_f32(),
                    bot[2 * cx + 1].to_f32(),
                ];
                let mut flags = 0u8;
                for v in cell {
                    flags |= ((v >= sat) as u8) | ((!v.is_finite()) as u8) << 1;
                }
                let i0 = cell[p[0]] - dark;
                let i45 = cell[p[1]] - dark;
                let i90 = cell[p[2]] - dark;
                let i135 = cell[p[3]] - dark;
                *a0 = 0.5 * (i0 + i45 + i90 + i135);
                *a1 = i0 - i90;
                *a2 = i45 - i135;
                *m = flags;
            }
            finish_mask_row(r0, r1, r2, rm, rules.min_s0)
        })
        .reduce(PixelCounts::default, |a, b| PixelCounts {
            valid: a.valid + b.valid,
            saturated: a.saturated + b.saturated,
            dark: a.dark + b.dark,
            invalid: a.invalid + b.invalid,
        });
    Ok(counts)
}

/// The four interpolation components of output row `y` (module docs), computed from the
/// raw rows around the interior row `yi = clamp(y, 1, h − 2)`: `mid` (the raw value),
/// `hor` (mean of left and right), `ver` (mean of up and down) and `dia` (mean of the four
/// diagonals), each `width` long; only columns `1..width−1` are meaningful.
struct Components {
    up: Vec<f32>,
    mid: Vec<f32>,
    down: Vec<f32>,
    hor: Vec<f32>,
    ver: Vec<f32>,
    dia: Vec<f32>,
}

impl Components {
    fn new(width: usize) -> Self {
        Self {
            up: vec![0.0; width],
            mid: vec![0.0; width],
            down: vec![0.0; width],
            hor: vec![0.0; width],
            ver: vec![0.0; width],
            dia: vec![0.0; width],
        }
    }

    /// Fill the components for output row `y`; returns `yi`.
    fn fill<T: Sample>(
        &mut self,
        raw: &[T],
        width: usize,
        height: usize,
        y: usize,
        round: bool,
    ) -> usize {
        let yi = y.clamp(1, height - 2);
        let row = |r: usize| &raw[r * width..(r + 1) * width];
        for (dst, r) in [
            (&mut self.up, yi - 1),
            (&mut self.mid, yi),
            (&mut self.down, yi + 1),
        ] {
            for (d, &v) in dst.iter_mut().zip(row(r)) {
                *d = v.to_f32();
            }
        }
        let (up, mid, down) = (&self.up, &self.mid, &self.down);
        let n = width - 2;
        // hor[x] = (mid[x-1] + mid[x+1]) / 2, ver[x] = (up[x] + down[x]) / 2,
        // dia[x] = (up[x-1] + up[x+1] + down[x-1] + down[x+1]) / 4, for x in 1..w-1.
        for (((h, &l), &r), ((v, &u), &d)) in self.hor[1..=n]
            .iter_mut()
            .zip(&mid[..n])
            .zip(&mid[2..])
            .zip(self.ver[1..=n].iter_mut().zip(&up[1..=n]).zip(&down[1..=n]))
        {
            *h = 0.5 * (l + r);
            *v = 0.5 * (u + d);
        }
        for ((((o, &ul), &ur), &dl), &dr) in self.dia[1..=n]
            .iter_mut()
            .zip(&up[..n])
            .zip(&up[2..])
            .zip(&down[..n])
            .zip(&down[2..])
        {
            *o = 0.25 * ((ul + ur) + (dl + dr));
        }
        if round {
            // OpenCV's integer arithmetic: round half up (rounding is only used for
            // unsigned integer raw data, for which truncating v + ½ is ⌊v + ½⌋ and
            // vectorises without SSE4.1).
            for v in self
                .hor
                .iter_mut()
                .chain(self.ver.iter_mut())
                .chain(self.dia.iter_mut())
            {
                *v = ((*v + 0.5) as i32) as f32; // ⌊v + ½⌋ for non-negative integer data
            }
        }
        yi
    }

    /// The component row that channel `(pr, pc)` uses at columns of parity `q` in row
    /// parity `yi & 1`.
    fn pick(&self, yi: usize, pr: usize, pc: usize, q: usize) -> &[f32] {
        match (((yi ^ pr) & 1) == 1, ((q ^ pc) & 1) == 1) {
            (false, false) => &self.mid,
            (false, true) => &self.hor,
            (true, false) => &self.ver,
            (true, true) => &self.dia,
        }
    }
}

/// Write one output row of a channel from the components: even columns from `even`,
/// odd columns from `odd`; border columns copy their interior neighbour.
#[inline]
fn select_row(even: &[f32], odd: &[f32], out: &mut [f32]) {
    for ((o, e), d) in out
        .chunks_exact_mut(2)
        .zip(even.chunks_exact(2))
        .zip(odd.chunks_exact(2))
    {
        o[0] = e[0];
        o[1] = d[1];
    }
    let w = out.len();
    out[0] = out[1];
    out[w - 1] = out[w - 2];
}

/// Saturation / non-finite flags of output row `y`: bit 0 when any raw pixel of the
/// 3×3 neighbourhood (border-replicated) is saturated, bit 1 when one is not finite.
fn flag_row<T: Sample>(
    raw: &[T],
    width: usize,
    height: usize,
    y: usize,
    sat: f32,
    col: &mut [u8],
    out: &mut [u8],
) {
    let yi = y.clamp(1, height - 2);
    col.fill(0);
    for r in yi - 1..=yi + 1 {
        for (c, &v) in col.iter_mut().zip(&raw[r * width..(r + 1) * width]) {
            let v = v.to_f32();
            *c |= ((v >= sat) as u8) | ((!v.is_finite()) as u8) << 1;
        }
    }
    for (x, o) in out[..width].iter_mut().enumerate() {
        let xi = x.clamp(1, width - 2);
        *o = col[xi - 1] | col[xi] | col[xi + 1];
    }
}

/// Bilinear demosaicing of `raw` (`width × height`, even, at least 4×4) into four
/// full-resolution channel images `out[k]` for the polarizer at `k × 45°` (0, 45, 90,
/// 135). Exactly polanalyser's / OpenCV's interpolation when `round` (module docs).
pub(super) fn demosaic_bilinear<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    round: bool,
    out: [&mut [f32]; 4],
) -> Result<()> {
    let height = check_mosaic(width, raw.len(), 4)?;
    for o in &out {
        check_len("demosaiced channel", o.len(), raw.len())?;
    }
    let pos: [(usize, usize); 4] = std::array::from_fn(|k| pattern.position(k));
    let [o0, o1, o2, o3] = out;
    o0.par_chunks_mut(width)
        .zip(o1.par_chunks_mut(width))
        .zip(o2.par_chunks_mut(width))
        .zip(o3.par_chunks_mut(width))
        .enumerate()
        .for_each_init(
            || Components::new(width),
            |c, (y, (((r0, r1), r2), r3))| {
                let yi = c.fill(raw, width, height, y, round);
                for (k, r) in [r0, r1, r2, r3].into_iter().enumerate() {
                    let (pr, pc) = pos[k];
                    select_row(c.pick(yi, pr, pc, 0), c.pick(yi, pr, pc, 1), r);
                }
            },
        );
    Ok(())
}

/// Full-resolution Stokes images of a DoFP frame by bilinear demosaicing (module docs),
/// fused row by row (no full-size channel images are stored). Outputs and `mask` are
/// `width × height`.
///
/// At every pixel the four channels use the four components (raw, horizontal, vertical,
/// diagonal mean) once each, so `S0 = ½ (mid + hor + ver + dia)` whatever the pattern,
/// and `S1`, `S2` are differences of two components chosen by the pixel's parity.
#[allow(clippy::too_many_arguments)]
pub(super) fn bilinear_stokes<T: Sample>(
    raw: &[T],
    width: usize,
    pattern: &Pattern,
    rules: &PixelRules,
    round: bool,
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    mask: &mut [u8],
) -> Result<PixelCounts> {
    rules.validate()?;
    let height = check_mosaic(width, raw.len(), 4)?;
    let n = raw.len();
    for (name, l) in [("s0", s0.len()), ("s1", s1.len()), ("s2", s2.len())] {
        check_len(name, l, n)?;
    }
    check_len("mask", mask.len(), n)?;
    let pos: [(usize, usize); 4] = std::array::from_fn(|k| pattern.position(k));
    let dark2 = 2.0 * rules.dark_level;
    let counts = s0
        .par_chunks_mut(width)
        .zip(s1.par_chunks_mut(width))
        .zip(s2.par_chunks_mut(width))
        .zip(mask.par_chunks_mut(width))
        .enumerate()
        .map_init(
            || (Components::new(width), vec![0u8; width]),
            |(c, cols), (y, (((r0, r1), r2), rm))| {
                let yi = c.fill(raw, width, height, y, round);
                // S0 = (mid + hor + ver + dia) / 2 − 2 dark (the dark level cancels in S1, S2).
                for ((((o, &a), &b), &v), &d) in r0
                    .iter_mut()
                    .zip(&c.mid)
                    .zip(&c.hor)
                    .zip(&c.ver)
                    .zip(&c.dia)
                {
                    *o = 0.5 * ((a + b) + (v + d)) - dark2;
                }
                let w = width;
                r0[0] = r0[1];
                r0[w - 1] = r0[w - 2];
                // S1 = I0 − I90, S2 = I45 − I135, per column parity.
                for (out, (kp, km)) in [(&mut *r1, (0usize, 2usize)), (&mut *r2, (1, 3))] {
                    let (p, m) = (pos[kp], pos[km]);
                    for q in 0..2 {
                        let plus = c.pick(yi, p.0, p.1, q);
                        let minus = c.pick(yi, m.0, m.1, q);
                        for x in (q..w).step_by(2) {
                            out[x] = plus[x] - minus[x];
                        }
                    }
                    out[0] = out[1];
                    out[w - 1] = out[w - 2];
                }
                flag_row(raw, width, height, y, rules.saturation, cols, rm);
                finish_mask_row(r0, r1, r2, rm, rules.min_s0)
            },
        )
        .reduce(PixelCounts::default, |a, b| PixelCounts {
            valid: a.valid + b.valid,
            saturated: a.saturated + b.saturated,
            dark: a.dark + b.dark,
            invalid: a.invalid + b.invalid,
        });
    Ok(counts)
}
