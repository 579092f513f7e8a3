//! Portable strip kernels of the DoFP reconstructions: branch-free loops over blocks of
//! [`BLOCK`] columns, compiled as they are for the baseline target and, inlined into
//! `avx2.rs` / `avx512.rs`, for the vector instruction sets. Rust does not contract
//! `a·b + c` into a fused multiply-add and every kernel performs the same operations in
//! the same order, so all instruction sets give the same bits.
//!
//! Each output row is made in two steps over one block of columns at a time, with every
//! intermediate row in the per-thread [`Scratch`] (a few kilobytes: it stays in the L1
//! cache):
//!
//! 1. the four interpolation components (raw value, horizontal, vertical and diagonal
//!    mean, see the module documentation of [`crate::mosaic`]) and the per-column
//!    saturation / non-finite flags of the 3-row neighbourhood;
//! 2. per pixel: `S0`, `S1`, `S2`, the mask, its counts and (when asked) DoLP and AoLP,
//!    written straight into the caller's rows (or into scratch rows for outputs the
//!    caller did not ask for, which are never stored anywhere else).

use super::Pattern;
use crate::stokes::{PixelCounts, PixelRules, Sample, dolp_aolp_pixel, mask};

/// Columns per block: the scratch rows of one block stay in the L1 cache.
pub(super) const BLOCK: usize = 512;

/// Block lengths are multiples of this where possible (the widest vector: 16 `f32`).
const LANES: usize = 16;

/// The blocks of columns `start..end`: `(first column, length, skip)`. Blocks are
/// [`BLOCK`] long; the last one is extended backwards over `skip` columns of the
/// previous block to a multiple of [`LANES`] when the range allows, so that no pixel is
/// left to the scalar remainder of a vector loop (a recomputed pixel gets the same
/// values; only its count must not be taken twice).
#[inline(always)]
fn blocks(start: usize, end: usize) -> impl Iterator<Item = (usize, usize, usize)> {
    (start..end).step_by(BLOCK).map(move |c| {
        let len = BLOCK.min(end - c);
        let full = len.next_multiple_of(LANES);
        if full != len && end - start >= full {
            (end - full, full, full - len)
        } else {
            (c, len, 0)
        }
    })
}

/// An unsigned integer raw sample type (`u8`, `u16`) whose bilinear interpolation can be
/// rounded and stored in the type itself (OpenCV's integer arithmetic).
pub trait IntSample: Sample {
    /// The value as `u32`.
    fn to_u32(self) -> u32;
    /// `v` (at most the type's maximum) in the type.
    fn from_u32(v: u32) -> Self;
}

impl IntSample for u8 {
    #[inline(always)]
    fn to_u32(self) -> u32 {
        self as u32
    }
    #[inline(always)]
    fn from_u32(v: u32) -> Self {
        v as u8
    }
}

impl IntSample for u16 {
    #[inline(always)]
    fn to_u32(self) -> u32 {
        self as u32
    }
    #[inline(always)]
    fn from_u32(v: u32) -> Self {
        v as u16
    }
}

/// Per-thread scratch rows (one block of columns each).
pub(super) struct Scratch {
    /// The four components (bilinear) or the four cell values (super-pixel).
    comp: [Vec<f32>; 4],
    /// Largest raw value of each column of the 3-row neighbourhood (block + 2 columns).
    cmax: Vec<f32>,
    /// 1 where a raw value of the column's 3-row neighbourhood is not finite.
    cnf: Vec<u8>,
    /// S0, S1, S2 of the block when the caller did not ask for them.
    s: [Vec<f32>; 3],
    /// The mask of the block when the caller did not ask for it.
    m: Vec<u8>,
    /// DoLP / AoLP of the block when the caller asked for only one of them.
    polar: [Vec<f32>; 2],
}

impl Scratch {
    pub(super) fn new() -> Self {
        let f = || vec![0f32; BLOCK];
        Self {
            comp: [f(), f(), f(), f()],
            cmax: vec![0f32; BLOCK + 2],
            cnf: vec![0u8; BLOCK + 2],
            s: [f(), f(), f()],
            m: vec![0u8; BLOCK],
            polar: [f(), f()],
        }
    }
}

/// The outputs of one strip of rows (each `rows × width` of the output image, or
/// absent). `polar` is true when DoLP or AoLP is asked for.
pub(super) struct StripOut<'a> {
    /// First output row.
    pub y0: usize,
    /// Rows in the strip.
    pub rows: usize,
    pub s: [Option<&'a mut [f32]>; 3],
    pub mask: Option<&'a mut [u8]>,
    pub dolp: Option<&'a mut [f32]>,
    pub aolp: Option<&'a mut [f32]>,
}

/// The rows of one output row `r` of a strip (see [`StripOut::row`]).
struct RowOut<'a> {
    s: [Option<&'a mut [f32]>; 3],
    rm: Option<&'a mut [u8]>,
    rd: Option<&'a mut [f32]>,
    ra: Option<&'a mut [f32]>,
}

impl StripOut<'_> {
    /// Row `r` (of `w` pixels) of each output asked for.
    #[inline(always)]
    fn row(&mut self, r: usize, w: usize) -> RowOut<'_> {
        let span = r * w..(r + 1) * w;
        let [s0, s1, s2] = &mut self.s;
        RowOut {
            s: [
                s0.as_deref_mut().map(|b| &mut b[span.clone()]),
                s1.as_deref_mut().map(|b| &mut b[span.clone()]),
                s2.as_deref_mut().map(|b| &mut b[span.clone()]),
            ],
            rm: self.mask.as_deref_mut().map(|b| &mut b[span.clone()]),
            rd: self.dolp.as_deref_mut().map(|b| &mut b[span.clone()]),
            ra: self.aolp.as_deref_mut().map(|b| &mut b[span]),
        }
    }
}

/// A bilinear reconstruction: the raw mosaic, its size, the rules and the cell
/// position `(row, column)` of the 0, 45, 90 and 135° polarizers.
pub(super) struct Bilinear<'a, T> {
    pub raw: &'a [T],
    pub width: usize,
    pub height: usize,
    pub rules: PixelRules,
    pub pos: [(usize, usize); 4],
}

/// The cell positions of [`Bilinear`] for a pattern.
pub(super) fn positions(pattern: &Pattern) -> [(usize, usize); 4] {
    std::array::from_fn(|k| pattern.position(k))
}

/// The row `r` of a `width`-wide image.
#[inline(always)]
fn row<T>(img: &[T], width: usize, r: usize) -> &[T] {
    &img[r * width..(r + 1) * width]
}

/// OpenCV's rounding of an interpolated value `v` of samples of type `T` when `ROUND`:
/// `⌊v + ½⌋` for the non-negative values of unsigned integer data. Bit for bit
/// `((v + 0.5) as i32) as f32` for every `v` (truncation, saturation at ±2³¹, NaN to +0,
/// −0 to +0), in operations that vectorise on every instruction set (the saturating
/// `as` does not); for integer samples (`v` in `[0, 2¹⁶)`) a plain conversion.
#[inline(always)]
fn rnd<T: Sample, const ROUND: bool>(v: f32) -> f32 {
    const LIM: f32 = 2_147_483_648.0; // 2³¹: i32::MIN and i32::MAX as f32
    const BELOW: f32 = 2_147_483_520.0; // the largest f32 below 2³¹
    if !ROUND {
        return v;
    }
    let t = v + 0.5;
    if T::INTEGER {
        // SAFETY: a mean of integer samples is in [0, 2¹⁶), so `t` is finite and its
        // truncation fits in an i32.
        return unsafe { t.to_int_unchecked::<i32>() } as f32;
    }
    let c = if t.is_nan() {
        0.0
    } else {
        t.clamp(-LIM, BELOW)
    };
    // SAFETY: `c` is finite and in [−2³¹, 2³¹), so its truncation fits in an i32.
    let r = unsafe { c.to_int_unchecked::<i32>() } as f32;
    if t >= LIM { LIM } else { r }
}

/// Where each channel (0, 45, 90, 135°) of a row block comes from: `same[k]` when its
/// polarizer is in the cell row of the image row (raw value or horizontal mean), else
/// vertical or diagonal mean; `own[k]`: true when the polarizer's own column (raw
/// value or vertical mean there, horizontal or diagonal mean at the other parity) is at
/// odd block indices.
#[derive(Clone, Copy)]
pub(super) struct ChannelSel {
    same: [bool; 4],
    own: [bool; 4],
}

/// The [`ChannelSel`] of a block starting at column `c` of interior row `yi`.
#[inline(always)]
fn channel_sel(pos: &[(usize, usize); 4], yi: usize, c: usize) -> ChannelSel {
    ChannelSel {
        same: std::array::from_fn(|k| (yi & 1) == pos[k].0),
        own: std::array::from_fn(|k| (c ^ pos[k].1) & 1 == 1),
    }
}

/// The value of a channel at a pixel from its four components (module docs of
/// [`crate::mosaic`]), with selects between values (vector blends).
#[inline(always)]
fn channel<V: Copy>(same: bool, own: bool, mid: V, hor: V, ver: V, dia: V) -> V {
    let (a, b) = if same { (mid, hor) } else { (ver, dia) };
    if own { a } else { b }
}

/// The raw values around interior columns `c..c + len` of the raw rows up, mid and
/// down: for each row its columns shifted left (`l`), centred (`c`) and right (`r`),
/// each exactly `len` long (so that the pixel loops need no bounds checks).
#[derive(Clone, Copy)]
struct Neighbours<'a, T> {
    ul: &'a [T],
    uc: &'a [T],
    ur: &'a [T],
    ml: &'a [T],
    mc: &'a [T],
    mr: &'a [T],
    dl: &'a [T],
    dc: &'a [T],
    dr: &'a [T],
}

/// The [`Neighbours`] of columns `c..c + len` (`1 <= c`, `c + len < width`).
#[inline(always)]
fn neighbours<T>(rows: [&[T]; 3], c: usize, len: usize) -> Neighbours<'_, T> {
    let [u, m, d] = rows;
    Neighbours {
        ul: &u[c - 1..][..len],
        uc: &u[c..][..len],
        ur: &u[c + 1..][..len],
        ml: &m[c - 1..][..len],
        mc: &m[c..][..len],
        mr: &m[c + 1..][..len],
        dl: &d[c - 1..][..len],
        dc: &d[c..][..len],
        dr: &d[c + 1..][..len],
    }
}

impl<T: Sample> Neighbours<'_, T> {
    /// The first `n` columns (lengths the compiler then knows to be `n`).
    #[inline(always)]
    fn trim(self, n: usize) -> Self {
        Neighbours {
            ul: &self.ul[..n],
            uc: &self.uc[..n],
            ur: &self.ur[..n],
            ml: &self.ml[..n],
            mc: &self.mc[..n],
            mr: &self.mr[..n],
            dl: &self.dl[..n],
            dc: &self.dc[..n],
            dr: &self.dr[..n],
        }
    }

    /// The four components at block index `i` (module documentation of
    /// [`crate::mosaic`]): raw value, horizontal, vertical and diagonal mean, the means
    /// rounded when `ROUND`.
    #[inline(always)]
    fn components<const ROUND: bool>(&self, i: usize) -> [f32; 4] {
        let f = |s: &[T]| s[i].to_f32();
        let hor = 0.5 * (f(self.ml) + f(self.mr));
        let ver = 0.5 * (f(self.uc) + f(self.dc));
        let dia = 0.25 * ((f(self.ul) + f(self.ur)) + (f(self.dl) + f(self.dr)));
        [
            f(self.mc),
            rnd::<T, ROUND>(hor),
            rnd::<T, ROUND>(ver),
            rnd::<T, ROUND>(dia),
        ]
    }
}

/// The column maxima and non-finite flags of the 3-row neighbourhood of columns
/// `c − 1..c + len + 1` into `cmax[..len + 2]`, `cnf[..len + 2]`.
#[inline(always)]
fn column_flags<T: Sample>(
    rows: [&[T]; 3],
    c: usize,
    len: usize,
    cmax: &mut [f32],
    cnf: &mut [u8],
) {
    let n = len + 2;
    let [u, m, d] = rows.map(|r| &r[c - 1..c - 1 + n]);
    let (cmax, cnf) = (&mut cmax[..n], &mut cnf[..n]);
    for j in 0..n {
        let (a, b, e) = (u[j].to_f32(), m[j].to_f32(), d[j].to_f32());
        cmax[j] = a.max(b).max(e);
        cnf[j] = (!T::INTEGER && !(a.is_finite() & b.is_finite() & e.is_finite())) as u8;
    }
}

/// The mask value of a pixel: invalid (a non-finite raw value or Stokes component),
/// else saturated, else dark (`S0 <= min_s0`), else valid — the order of
/// [`crate::stokes`]' row kernels.
#[inline(always)]
pub(super) fn mask_value(nonfinite: bool, saturated: bool, s0: f32, min_s0: f32) -> u8 {
    if nonfinite {
        mask::INVALID
    } else if saturated {
        mask::SATURATED
    } else if s0 <= min_s0 {
        mask::DARK
    } else {
        mask::VALID
    }
}

/// Add a pixel's mask value `m` to the rejection counts `[saturated, dark, invalid]`
/// when `live` (branch-free: the pixel loops vectorise with these reductions; without
/// any, LLVM has been seen to leave the bilinear loop scalar).
#[inline(always)]
pub(super) fn count(m: u8, live: bool, c: &mut [u32; 3]) {
    c[0] += (live & (m == mask::SATURATED)) as u32;
    c[1] += (live & (m == mask::DARK)) as u32;
    c[2] += (live & (m == mask::INVALID)) as u32;
}

/// DoLP / AoLP of a pixel, NaN where the mask rejects it (as [`crate::stokes::dolp_aolp`]
/// with a mask).
#[inline(always)]
pub(super) fn polar(s0: f32, s1: f32, s2: f32, m: u8) -> (f32, f32) {
    let (pd, pa) = dolp_aolp_pixel(s0, s1, s2);
    let ok = m == mask::VALID;
    (
        if ok { pd } else { f32::NAN },
        if ok { pa } else { f32::NAN },
    )
}

/// Destination rows of one block: the caller's rows `c..c + len` where asked for, else
/// the scratch rows.
macro_rules! dest {
    ($out:expr, $scratch:expr, $c:expr, $len:expr) => {
        match $out {
            Some(r) => &mut r[$c..$c + $len],
            None => &mut $scratch[..$len],
        }
    };
}

/// One block of a bilinear row: per pixel the components, `S0 = ½ ((raw + hor) + (ver
/// + dia)) − 2·dark`, `S1 = I0 − I90`, `S2 = I45 − I135`, the mask from the 3×3
/// neighbourhood flags (`cmax`, `cnf` from [`column_flags`]), its counts (from block
/// index `skip` on) and DoLP / AoLP when `POLAR`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn bilinear_pixels<T: Sample, const ROUND: bool, const POLAR: bool>(
    nb: Neighbours<'_, T>,
    sel: ChannelSel,
    cmax: &[f32],
    cnf: &[u8],
    rules: &PixelRules,
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    m: &mut [u8],
    d: &mut [f32],
    a: &mut [f32],
    skip: usize,
    counts: &mut [u32; 3],
) {
    let n = s0.len();
    let nb = nb.trim(n);
    let (s1, s2, m) = (&mut s1[..n], &mut s2[..n], &mut m[..n]);
    let (d, a) = if POLAR {
        (&mut d[..n], &mut a[..n])
    } else {
        (&mut d[..0], &mut a[..0])
    };
    // The three columns around each pixel as slices of exactly `n` (indexing `[i + 2]`
    // would leave a bounds check in the loop, which then needs a scalar remainder).
    let (cm0, cm1, cm2) = (&cmax[..n], &cmax[1..][..n], &cmax[2..][..n]);
    let (cf0, cf1, cf2) = (&cnf[..n], &cnf[1..][..n], &cnf[2..][..n]);
    let dark2 = 2.0 * rules.dark_level;
    let (sat, min_s0) = (rules.saturation, rules.min_s0);
    let [same0, same45, same90, same135] = sel.same;
    let [own0, own45, own90, own135] = sel.own;
    let skip = skip as u32; // n <= BLOCK: block indices fit in u32 (32-bit vector lanes)
    for i in 0..n {
        let [mid, hor, ver, dia] = nb.components::<ROUND>(i);
        let v0 = 0.5 * ((mid + hor) + (ver + dia)) - dark2;
        let odd = (i as u32) & 1 == 1;
        let i0 = channel(same0, odd == own0, mid, hor, ver, dia);
        let i45 = channel(same45, odd == own45, mid, hor, ver, dia);
        let i90 = channel(same90, odd == own90, mid, hor, ver, dia);
        let i135 = channel(same135, odd == own135, mid, hor, ver, dia);
        let v1 = i0 - i90;
        let v2 = i45 - i135;
        let mx = cm0[i].max(cm1[i]).max(cm2[i]);
        // Integer samples are finite and their Stokes values too (|S| < 2¹⁹).
        let nf = !T::INTEGER && ((cf0[i] | cf1[i] | cf2[i]) != 0 || !(v0 + v1 + v2).is_finite());
        let mk = mask_value(nf, mx >= sat, v0, min_s0);
        s0[i] = v0;
        s1[i] = v1;
        s2[i] = v2;
        m[i] = mk;
        count(mk, i as u32 >= skip, counts);
        if POLAR {
            (d[i], a[i]) = polar(v0, v1, v2, mk);
        }
    }
}

/// Copy column 1 into column 0 and column `w − 2` into `w − 1` (OpenCV's border).
#[inline(always)]
fn borders<V: Copy>(r: &mut [V]) {
    let w = r.len();
    r[0] = r[1];
    r[w - 1] = r[w - 2];
}

/// Counts of a row from its rejection counts, its length and the border pixels' masks.
#[inline(always)]
pub(super) fn row_counts(c: [u32; 3], n: usize) -> PixelCounts {
    let rejected = (c[0] + c[1] + c[2]) as u64;
    PixelCounts {
        valid: n as u64 - rejected,
        saturated: c[0] as u64,
        dark: c[1] as u64,
        invalid: c[2] as u64,
    }
}

/// The bilinear reconstruction of one strip of rows (module documentation).
#[inline(always)]
pub(super) fn bilinear_strip<T: Sample, const ROUND: bool, const POLAR: bool>(
    job: &Bilinear<'_, T>,
    out: &mut StripOut<'_>,
    sc: &mut Scratch,
) -> PixelCounts {
    let w = job.width;
    let mut total = PixelCounts::default();
    for r in 0..out.rows {
        let y = out.y0 + r;
        let yi = y.clamp(1, job.height - 2);
        let (up, mid, down) = (
            row(job.raw, w, yi - 1),
            row(job.raw, w, yi),
            row(job.raw, w, yi + 1),
        );
        let RowOut {
            s: [mut r0, mut r1, mut r2],
            mut rm,
            mut rd,
            mut ra,
        } = out.row(r, w);
        let mut counts = [0u32; 3];
        let (mut m_first, mut m_last) = (0u8, 0u8);
        for (c, len, skip) in blocks(1, w - 1) {
            let rows = [up, mid, down];
            column_flags(rows, c, len, &mut sc.cmax, &mut sc.cnf);
            let nb = neighbours(rows, c, len);
            let sel = channel_sel(&job.pos, yi, c);
            let [t0, t1, t2] = &mut sc.s;
            let [td, ta] = &mut sc.polar;
            let s0 = dest!(r0.as_deref_mut(), t0, c, len);
            let s1 = dest!(r1.as_deref_mut(), t1, c, len);
            let s2 = dest!(r2.as_deref_mut(), t2, c, len);
            let m = dest!(rm.as_deref_mut(), sc.m, c, len);
            let d = dest!(rd.as_deref_mut(), td, c, len);
            let a = dest!(ra.as_deref_mut(), ta, c, len);
            bilinear_pixels::<T, ROUND, POLAR>(
                nb,
                sel,
                &sc.cmax,
                &sc.cnf,
                &job.rules,
                s0,
                s1,
                s2,
                m,
                d,
                a,
                skip,
                &mut counts,
            );
            if c == 1 {
                m_first = m[0];
            }
            if c + len == w - 1 {
                m_last = m[len - 1];
            }
        }
        for r in [r0, r1, r2, rd, ra].into_iter().flatten() {
            borders(r);
        }
        if let Some(r) = rm {
            borders(r);
        }
        count(m_first, true, &mut counts);
        count(m_last, true, &mut counts);
        total = total.add(row_counts(counts, w));
    }
    total
}

/// A super-pixel reconstruction: the raw mosaic, its width, the rules and the cell
/// position (0..4, row-major) of the 0, 45, 90 and 135° polarizers.
pub(super) struct Superpixel<'a, T> {
    pub raw: &'a [T],
    pub width: usize,
    pub rules: PixelRules,
    pub pos: [usize; 4],
}

/// The super-pixel reconstruction of one strip of output rows: per cell
/// `I_k = raw_k − dark`, `S0 = ½ (I0 + I45 + I90 + I135)`, `S1 = I0 − I90`,
/// `S2 = I45 − I135`, saturated / invalid when one of its four raw values is.
#[inline(always)]
pub(super) fn superpixel_strip<T: Sample, const POLAR: bool>(
    job: &Superpixel<'_, T>,
    out: &mut StripOut<'_>,
    sc: &mut Scratch,
) -> PixelCounts {
    let w = job.width;
    let ow = w / 2;
    let dark = job.rules.dark_level;
    let (sat, min_s0) = (job.rules.saturation, job.rules.min_s0);
    let mut total = PixelCounts::default();
    for r in 0..out.rows {
        let cy = out.y0 + r;
        let (top, bot) = (row(job.raw, w, 2 * cy), row(job.raw, w, 2 * cy + 1));
        let RowOut {
            s: [mut r0, mut r1, mut r2],
            mut rm,
            mut rd,
            mut ra,
        } = out.row(r, ow);
        let mut counts = [0u32; 3];
        for (c, len, skip) in blocks(0, ow) {
            // Deinterleave the block's cells: comp[p][i] = raw value at cell position p.
            {
                let [k0, k1, k2, k3] = &mut sc.comp;
                let (k0, k1, k2, k3) = (
                    &mut k0[..len],
                    &mut k1[..len],
                    &mut k2[..len],
                    &mut k3[..len],
                );
                let (t, b) = (&top[2 * c..2 * (c + len)], &bot[2 * c..2 * (c + len)]);
                for i in 0..len {
                    k0[i] = t[2 * i].to_f32();
                    k1[i] = t[2 * i + 1].to_f32();
                    k2[i] = b[2 * i].to_f32();
                    k3[i] = b[2 * i + 1].to_f32();
                }
            }
            let [t0, t1, t2] = &mut sc.s;
            let [td, ta] = &mut sc.polar;
            let s0 = dest!(r0.as_deref_mut(), t0, c, len);
            let s1 = dest!(r1.as_deref_mut(), t1, c, len);
            let s2 = dest!(r2.as_deref_mut(), t2, c, len);
            let m = dest!(rm.as_deref_mut(), sc.m, c, len);
            let (d, a) = if POLAR {
                (
                    dest!(rd.as_deref_mut(), td, c, len),
                    dest!(ra.as_deref_mut(), ta, c, len),
                )
            } else {
                (&mut td[..0], &mut ta[..0])
            };
            let k = &sc.comp;
            let (q0, q1, q2, q3) = (&k[0][..len], &k[1][..len], &k[2][..len], &k[3][..len]);
            let p = job.pos;
            let (c0, c45, c90, c135) = (
                &k[p[0]][..len],
                &k[p[1]][..len],
                &k[p[2]][..len],
                &k[p[3]][..len],
            );
            for i in 0..len {
                let (a0, a1, a2, a3) = (q0[i], q1[i], q2[i], q3[i]);
                let satd = (a0 >= sat) | (a1 >= sat) | (a2 >= sat) | (a3 >= sat);
                let nfr = !(a0.is_finite() & a1.is_finite() & a2.is_finite() & a3.is_finite());
                let i0 = c0[i] - dark;
                let i45 = c45[i] - dark;
                let i90 = c90[i] - dark;
                let i135 = c135[i] - dark;
                let v0 = 0.5 * (i0 + i45 + i90 + i135);
                let v1 = i0 - i90;
                let v2 = i45 - i135;
                let nf = nfr || !(v0 + v1 + v2).is_finite();
                let mk = mask_value(nf, satd, v0, min_s0);
                s0[i] = v0;
                s1[i] = v1;
                s2[i] = v2;
                m[i] = mk;
                count(mk, i as u32 >= skip as u32, &mut counts);
                if POLAR {
                    (d[i], a[i]) = polar(v0, v1, v2, mk);
                }
            }
        }
        total = total.add(row_counts(counts, ow));
    }
    total
}

/// Bilinear demosaicing of one strip of rows into four `f32` channel images (0, 45, 90,
/// 135°), each value minus `dark`.
#[inline(always)]
pub(super) fn demosaic_strip<T: Sample, const ROUND: bool>(
    job: &Bilinear<'_, T>,
    dark: f32,
    y0: usize,
    out: [&mut [f32]; 4],
) {
    let w = job.width;
    let rows = out[0].len() / w;
    let mut out = out;
    for r in 0..rows {
        let yi = (y0 + r).clamp(1, job.height - 2);
        let raw_rows = [yi - 1, yi, yi + 1].map(|y| row(job.raw, w, y));
        let [o0, o45, o90, o135] = out.each_mut().map(|o| &mut o[r * w..(r + 1) * w]);
        for (c, len, _) in blocks(1, w - 1) {
            let nb = neighbours(raw_rows, c, len);
            let ChannelSel { same, own } = channel_sel(&job.pos, yi, c);
            let (d0, d45, d90, d135) = (
                &mut o0[c..c + len],
                &mut o45[c..c + len],
                &mut o90[c..c + len],
                &mut o135[c..c + len],
            );
            for i in 0..len {
                let [mid, hor, ver, dia] = nb.components::<ROUND>(i);
                let odd = (i as u32) & 1 == 1;
                d0[i] = channel(same[0], odd == own[0], mid, hor, ver, dia) - dark;
                d45[i] = channel(same[1], odd == own[1], mid, hor, ver, dia) - dark;
                d90[i] = channel(same[2], odd == own[2], mid, hor, ver, dia) - dark;
                d135[i] = channel(same[3], odd == own[3], mid, hor, ver, dia) - dark;
            }
        }
        for o in [o0, o45, o90, o135] {
            borders(o);
        }
    }
}

/// Bilinear demosaicing of one strip of rows of unsigned integer data into four channel
/// images of the same type, rounded as OpenCV does: `(a + b + 1) >> 1` for two-pixel
/// means and `(a + b + c + d + 2) >> 2` for four-pixel means.
#[inline(always)]
pub(super) fn demosaic_int_strip<T: IntSample>(
    job: &Bilinear<'_, T>,
    y0: usize,
    out: [&mut [T]; 4],
) {
    let w = job.width;
    let rows = out[0].len() / w;
    let mut out = out;
    for r in 0..rows {
        let yi = (y0 + r).clamp(1, job.height - 2);
        let raw_rows = [yi - 1, yi, yi + 1].map(|y| row(job.raw, w, y));
        let [o0, o45, o90, o135] = out.each_mut().map(|o| &mut o[r * w..(r + 1) * w]);
        for (c, len, _) in blocks(1, w - 1) {
            let Neighbours {
                ul,
                uc,
                ur,
                ml,
                mc,
                mr,
                dl,
                dc,
                dr,
            } = neighbours(raw_rows, c, len);
            let ChannelSel { same, own } = channel_sel(&job.pos, yi, c);
            let (d0, d45, d90, d135) = (
                &mut o0[c..c + len],
                &mut o45[c..c + len],
                &mut o90[c..c + len],
                &mut o135[c..c + len],
            );
            for i in 0..len {
                let mid = mc[i].to_u32();
                let hor = (ml[i].to_u32() + mr[i].to_u32() + 1) >> 1;
                let ver = (uc[i].to_u32() + dc[i].to_u32() + 1) >> 1;
                let dia =
                    (ul[i].to_u32() + ur[i].to_u32() + dl[i].to_u32() + dr[i].to_u32() + 2) >> 2;
                let odd = (i as u32) & 1 == 1;
                d0[i] = T::from_u32(channel(same[0], odd == own[0], mid, hor, ver, dia));
                d45[i] = T::from_u32(channel(same[1], odd == own[1], mid, hor, ver, dia));
                d90[i] = T::from_u32(channel(same[2], odd == own[2], mid, hor, ver, dia));
                d135[i] = T::from_u32(channel(same[3], odd == own[3], mid, hor, ver, dia));
            }
        }
        for o in [o0, o45, o90, o135] {
            borders(o);
        }
    }
}
