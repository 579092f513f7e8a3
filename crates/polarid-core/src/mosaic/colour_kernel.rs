//! Strip kernels of the colour polarization reconstructions ([`super::colour`]): portable,
//! branch-free loops over blocks of [`CBLOCK`] columns, compiled as they are and, inlined
//! into the token-gated entry points at the end of this file, for AVX2 + FMA and
//! AVX-512F. No `a·b + c` is contracted into a fused multiply-add, so every instruction
//! set gives the same bits.
//!
//! Bilinear, per output row and block of columns (every intermediate row in the
//! per-thread [`ColourScratch`], ~20 KB: it stays in the L1 cache):
//!
//! 1. for each row residue `ρ` the vertically interpolated raw row (and its vertical
//!    maxima, for the saturation test), padded by 4 columns on each side with the
//!    samples of the same column residue one period in (which is the clamping of the
//!    interpolation taps to the lattice's first and last samples);
//! 2. per band, each channel: at every column `x`, for each of its lattices `(ρ, χ)`,
//!    the horizontal interpolation between the padded row's values at `x − e` and
//!    `x − e + 4`, `e = (x − χ) mod 4`, chosen per vector lane by selects between
//!    shifted contiguous loads (no gathers, no deinterleaving), summed over the band's
//!    lattices; then Stokes, mask, DoLP and AoLP straight into the caller's rows.

use super::colour_pattern::ColourPattern;
use super::kernel::{count, mask_value, polar, row_counts};
use crate::stokes::{PixelCounts, PixelRules, Sample};

/// Columns per block (a multiple of 4).
pub(super) const CBLOCK: usize = 512;
/// Padding of the vertically interpolated rows on each side.
const PAD: usize = 4;
/// At most four bands (one per block).
pub(super) const MAX_BANDS: usize = 4;

/// A colour reconstruction: the raw mosaic, its size, the rules and, per band and
/// polarizer `k × 45°`, the lattices `4ρ + χ` averaged into the channel.
pub(super) struct ColourJob<'a, T> {
    pub raw: &'a [T],
    pub width: usize,
    pub height: usize,
    pub rules: PixelRules,
    pub nbands: usize,
    /// `lat[b][k][..n[b]]`: the lattices of band `b` under polarizer `k`.
    pub lat: [[[usize; 4]; 4]; MAX_BANDS],
    /// Blocks (lattices per channel) of each band.
    pub n: [usize; MAX_BANDS],
}

impl<'a, T> ColourJob<'a, T> {
    /// The job of `pattern` over `raw` (`width × height`, checked by the caller).
    pub(super) fn new(
        raw: &'a [T],
        width: usize,
        height: usize,
        pattern: &ColourPattern,
        rules: PixelRules,
    ) -> Self {
        let nbands = pattern.bands().len().min(MAX_BANDS);
        let mut lat = [[[0usize; 4]; 4]; MAX_BANDS];
        let mut n = [0usize; MAX_BANDS];
        for (b, (lb, nb)) in lat.iter_mut().zip(n.iter_mut()).enumerate().take(nbands) {
            for (k, lk) in lb.iter_mut().enumerate() {
                let l = pattern.lattices(b, k);
                *nb = l.len().min(4);
                for (i, v) in l.into_iter().take(4).enumerate() {
                    lk[i] = v;
                }
            }
        }
        Self {
            raw,
            width,
            height,
            rules,
            nbands,
            lat,
            n,
        }
    }
}

/// Per-thread scratch rows of the colour kernels.
pub(super) struct ColourScratch {
    /// Vertically interpolated rows per residue `ρ`, each `CBLOCK + 2·PAD`.
    v: [Vec<f32>; 4],
    /// The maxima of their samples (saturation test, for blocks that need it).
    vm: [Vec<f32>; 4],
    /// The four channels of one band, `CBLOCK` each.
    ik: [Vec<f32>; 4],
    /// Largest raw value with a non-zero weight of one band's pixels.
    mx: Vec<f32>,
    /// S0, S1, S2, DoLP, AoLP rows the caller did not ask for.
    tmp: [Vec<f32>; 5],
    /// The mask row when the caller did not ask for it.
    tm: Vec<u8>,
}

impl ColourScratch {
    pub(super) fn new() -> Self {
        let f = || vec![0f32; CBLOCK + 2 * PAD];
        Self {
            v: [f(), f(), f(), f()],
            vm: [f(), f(), f(), f()],
            ik: [f(), f(), f(), f()],
            mx: f(),
            tmp: [f(), f(), f(), f(), f()],
            tm: vec![0u8; CBLOCK + 2 * PAD],
        }
    }
}

/// The two taps and the phase `e` of the interpolation at position `p` along an axis
/// of `n` pixels of the lattice at residue `r` (mod 4): `lo = p − e` with
/// `e = (p − r) mod 4`, `hi = lo + 4`, each clamped to the lattice's first and last
/// sample `[r, r + n − 4]`. The value is `raw(lo)` when `e = 0`, else
/// `(1 − e/4)·raw(lo) + (e/4)·raw(hi)`.
#[inline(always)]
pub(super) fn taps(p: usize, r: usize, n: usize) -> (usize, usize, usize) {
    let e = (p + 4 - r) % 4;
    let lo = (p + 4 - e) as isize - 4;
    let last = (r + n - 4) as isize;
    let cl = |v: isize| v.clamp(r as isize, last) as usize;
    (cl(lo), cl(lo + 4), e)
}

/// The weights `(1 − e/4, e/4)` of phase `e` (exact in `f32`).
#[inline(always)]
pub(super) fn weights(e: usize) -> (f32, f32) {
    let wb = e as f32 * 0.25;
    (1.0 - wb, wb)
}

/// The row `r` of a `width`-wide image.
#[inline(always)]
fn row<T>(img: &[T], width: usize, r: usize) -> &[T] {
    &img[r * width..(r + 1) * width]
}

/// The vertical interpolation of phase `e` of raw rows `a`, `b` over columns
/// `x0..x0 + v.len()` into `v` (`MAX`: the largest of the samples with a non-zero
/// weight instead).
#[inline(always)]
fn vertical<T: Sample, const MAX: bool>(a: &[T], b: &[T], e: usize, x0: usize, v: &mut [f32]) {
    let n = v.len();
    let (a, b) = (&a[x0..x0 + n], &b[x0..x0 + n]);
    if e == 0 {
        for i in 0..n {
            v[i] = a[i].to_f32();
        }
    } else if MAX {
        for i in 0..n {
            v[i] = a[i].to_f32().max(b[i].to_f32());
        }
    } else {
        let (wa, wb) = weights(e);
        for i in 0..n {
            v[i] = wa * a[i].to_f32() + wb * b[i].to_f32();
        }
    }
}

/// The largest value of `a[x0..x1]` and `b[x0..x1]` (NaN ignored).
#[inline(always)]
fn raw_max<T: Sample>(a: &[T], b: &[T], x0: usize, x1: usize) -> f32 {
    let mut m = [f32::NEG_INFINITY; 16];
    for (ca, cb) in a[x0..x1].chunks(16).zip(b[x0..x1].chunks(16)) {
        for (k, (&va, &vb)) in ca.iter().zip(cb).enumerate() {
            m[k] = m[k].max(va.to_f32().max(vb.to_f32()));
        }
    }
    m.iter().fold(f32::NEG_INFINITY, |x, &y| x.max(y))
}

/// One vertically interpolated, padded row (module docs) for output columns
/// `c0..c0 + len`: `v[PAD + i]` is column `c0 + i`; columns before 0 or from `w` on
/// take the column one period in. `MAX`: the maxima of the samples instead.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn padded_row<T: Sample, const MAX: bool>(
    a: &[T],
    b: &[T],
    e: usize,
    w: usize,
    c0: usize,
    len: usize,
    v: &mut [f32],
) {
    // columns c0 − PAD .. c0 + len + PAD, inside the image
    let lo = c0.saturating_sub(PAD);
    let hi = (c0 + len + PAD).min(w);
    let off = lo + PAD - c0;
    vertical::<T, MAX>(a, b, e, lo, &mut v[off..off + hi - lo]);
    // outside: the same residue one period in
    for k in 0..off {
        v[k] = v[k + 4];
    }
    for k in off + hi - lo..len + 2 * PAD {
        v[k] = v[k - 4];
    }
}

/// The eight rows `s[t][i] = v[i + t + 1]` (column `c0 + i + t − 3`) from which
/// [`lane_taps`] picks the taps of `n` output columns of the padded row `v`.
#[inline(always)]
fn shifted(v: &[f32], n: usize) -> [&[f32]; 8] {
    std::array::from_fn(|t| &v[t + 1..t + 1 + n])
}

/// The taps `(lo, hi)` and phase `e` of output column `c0 + i` (`c0` a multiple of 4)
/// of lattice column residue `chi` from the [`shifted`] rows `s` (`hi` is meaningless
/// when `e = 0`). Every value is loaded and the lane's taps selected: conditional loads
/// would not vectorise.
#[inline(always)]
fn lane_taps(s: [&[f32]; 8], i: usize, chi: usize) -> (f32, f32, usize) {
    let e = (i + 4 - chi) & 3;
    let [v0, v1, v2, v3, v4, v5, v6, _] = s.map(|r| r[i]);
    let lo = if e == 0 { v3 } else { v2 };
    let lo = if e == 2 { v1 } else { lo };
    let lo = if e == 3 { v0 } else { lo };
    let hi = if e == 1 { v6 } else { v4 };
    let hi = if e == 2 { v5 } else { hi };
    (lo, hi, e)
}

/// The horizontal interpolation of lattice column residue `chi` at columns
/// `c0 + i` (`c0` a multiple of 4) from the padded row `v`, written into `dst`
/// (`ADD`: added to it).
#[inline(always)]
fn horizontal<const ADD: bool>(dst: &mut [f32], v: &[f32], chi: usize) {
    let s = shifted(v, dst.len());
    for (i, d) in dst.iter_mut().enumerate() {
        let (lo, hi, e) = lane_taps(s, i, chi);
        let (wa, wb) = weights(e);
        let val = if e == 0 { lo } else { wa * lo + wb * hi };
        *d = if ADD { *d + val } else { val };
    }
}

/// The largest sample with a non-zero weight of [`horizontal`], folded into `mx`.
#[inline(always)]
fn horizontal_max(mx: &mut [f32], vm: &[f32], chi: usize) {
    let s = shifted(vm, mx.len());
    for (i, m) in mx.iter_mut().enumerate() {
        let (lo, hi, e) = lane_taps(s, i, chi);
        let hi = if e == 0 { lo } else { hi };
        *m = m.max(lo.max(hi));
    }
}

/// The outputs of one band for one strip of rows (each `rows × width`, or absent).
pub(super) struct BandStrip<'a> {
    pub s: [Option<&'a mut [f32]>; 3],
    pub mask: Option<&'a mut [u8]>,
    pub dolp: Option<&'a mut [f32]>,
    pub aolp: Option<&'a mut [f32]>,
}

/// The bilinear colour reconstruction of output rows `y0 .. y0 + rows` into `out` (one
/// [`BandStrip`] per band): returns the counts of each band.
#[inline(always)]
pub(super) fn bilinear_strip<T: Sample, const SAT: bool, const POLAR: bool>(
    job: &ColourJob<'_, T>,
    y0: usize,
    rows: usize,
    out: &mut [BandStrip<'_>],
    sc: &mut ColourScratch,
) -> [PixelCounts; MAX_BANDS] {
    let (w, hgt) = (job.width, job.height);
    let dark2 = 2.0 * job.rules.dark_level;
    let nb = job.nbands.min(out.len());
    let mut total = [PixelCounts::default(); MAX_BANDS];
    for r in 0..rows {
        let y = y0 + r;
        let mut counts = [[0u32; 3]; MAX_BANDS];
        for c0 in (0..w).step_by(CBLOCK) {
            let len = CBLOCK.min(w - c0);
            // the raw rows and phase of the vertical interpolation of residue `ρ`
            let vtaps = |rho| {
                let (ya, yb, e) = taps(y, rho, hgt);
                (row(job.raw, w, ya), row(job.raw, w, yb), e)
            };
            // any saturated sample in reach of the block? (else the test is skipped)
            let mut any_sat = false;
            for rho in 0..4 {
                let (a, b, e) = vtaps(rho);
                padded_row::<T, false>(a, b, e, w, c0, len, &mut sc.v[rho]);
                if SAT {
                    let (lo, hi) = (c0.saturating_sub(PAD), (c0 + len + PAD).min(w));
                    any_sat |= raw_max(a, b, lo, hi) >= job.rules.saturation;
                }
            }
            if SAT && any_sat {
                for rho in 0..4 {
                    let (a, b, e) = vtaps(rho);
                    padded_row::<T, true>(a, b, e, w, c0, len, &mut sc.vm[rho]);
                }
            }
            for (band, o) in out.iter_mut().enumerate().take(nb) {
                let n = job.n[band];
                let lat = &job.lat[band];
                for (k, lk) in lat.iter().enumerate() {
                    let ik = &mut sc.ik[k][..len];
                    for (j, &l) in lk[..n].iter().enumerate() {
                        let v = &sc.v[l / 4][..len + 2 * PAD];
                        if j == 0 {
                            horizontal::<false>(ik, v, l % 4);
                        } else {
                            horizontal::<true>(ik, v, l % 4);
                        }
                    }
                    if n > 1 {
                        let inv = 1.0 / n as f32;
                        for x in ik.iter_mut() {
                            *x *= inv;
                        }
                    }
                }
                if SAT && any_sat {
                    let mx = &mut sc.mx[..len];
                    mx.fill(f32::NEG_INFINITY);
                    for lk in lat {
                        for &l in &lk[..n] {
                            horizontal_max(mx, &sc.vm[l / 4][..len + 2 * PAD], l % 4);
                        }
                    }
                }
                let rows = PixelRows::of(o, &mut sc.tmp, &mut sc.tm, r * w + c0, len);
                let ch: [&[f32]; 4] = std::array::from_fn(|k| &sc.ik[k][..len]);
                let (mx, cnt) = (&sc.mx[..len], &mut counts[band]);
                if SAT && any_sat {
                    stokes_pixels::<T, true, POLAR>(ch, mx, &job.rules, dark2, rows, cnt);
                } else {
                    stokes_pixels::<T, false, POLAR>(ch, mx, &job.rules, dark2, rows, cnt);
                }
            }
        }
        for b in 0..nb {
            total[b] = total[b].add(row_counts(counts[b], w));
        }
    }
    total
}

/// The super-pixel colour reconstruction of output rows `y0 .. y0 + rows` (one output
/// per 4×4 period): per band and polarizer `I_k = (Σ raw)/n − dark` over the band's `n`
/// blocks, `S0 = ½ ((I0 + I90) + (I45 + I135))`, `S1 = I0 − I90`, `S2 = I45 − I135`;
/// saturated when one of the band's `4n` raw values is.
#[inline(always)]
pub(super) fn superpixel_strip<T: Sample, const POLAR: bool>(
    job: &ColourJob<'_, T>,
    y0: usize,
    rows: usize,
    out: &mut [BandStrip<'_>],
    sc: &mut ColourScratch,
) -> [PixelCounts; MAX_BANDS] {
    let w = job.width;
    let ow = w / 4;
    let dark = job.rules.dark_level;
    let nb = job.nbands.min(out.len());
    let mut total = [PixelCounts::default(); MAX_BANDS];
    for r in 0..rows {
        let cy = y0 + r;
        let raw_rows: [&[T]; 4] = std::array::from_fn(|rho| row(job.raw, w, 4 * cy + rho));
        let mut counts = [[0u32; 3]; MAX_BANDS];
        for c0 in (0..ow).step_by(CBLOCK) {
            let len = CBLOCK.min(ow - c0);
            for (band, o) in out.iter_mut().enumerate().take(nb) {
                let n = job.n[band];
                let inv = 1.0 / n as f32;
                let mx = &mut sc.mx[..len];
                mx.fill(f32::NEG_INFINITY);
                for (k, lk) in job.lat[band].iter().enumerate() {
                    let ik = &mut sc.ik[k][..len];
                    ik.fill(0.0);
                    for &l in &lk[..n] {
                        let src = &raw_rows[l / 4][4 * c0..4 * (c0 + len)];
                        for ((d, m), s) in ik.iter_mut().zip(mx.iter_mut()).zip(src.chunks_exact(4))
                        {
                            let v = s[l % 4].to_f32();
                            *d += v;
                            *m = m.max(v);
                        }
                    }
                    for x in ik.iter_mut() {
                        *x = *x * inv - dark;
                    }
                }
                let rows = PixelRows::of(o, &mut sc.tmp, &mut sc.tm, r * ow + c0, len);
                let ch: [&[f32]; 4] = std::array::from_fn(|k| &sc.ik[k][..len]);
                stokes_pixels::<T, true, POLAR>(
                    ch,
                    &sc.mx[..len],
                    &job.rules,
                    0.0,
                    rows,
                    &mut counts[band],
                );
            }
        }
        for b in 0..nb {
            total[b] = total[b].add(row_counts(counts[b], ow));
        }
    }
    total
}

/// The output rows of [`stokes_pixels`] (all of one length).
struct PixelRows<'a> {
    s0: &'a mut [f32],
    s1: &'a mut [f32],
    s2: &'a mut [f32],
    m: &'a mut [u8],
    d: &'a mut [f32],
    a: &'a mut [f32],
}

impl<'a> PixelRows<'a> {
    /// The rows `start..start + len` of the outputs of `o` the caller asked for, the
    /// scratch rows `tmp`, `tm` for the others.
    #[inline(always)]
    fn of(
        o: &'a mut BandStrip<'_>,
        tmp: &'a mut [Vec<f32>; 5],
        tm: &'a mut [u8],
        start: usize,
        len: usize,
    ) -> Self {
        fn dest<'a, U>(
            out: Option<&'a mut [U]>,
            scratch: &'a mut [U],
            start: usize,
            len: usize,
        ) -> &'a mut [U] {
            match out {
                Some(r) => &mut r[start..start + len],
                None => &mut scratch[..len],
            }
        }
        let [t0, t1, t2, td, ta] = tmp;
        let [s0, s1, s2] = &mut o.s;
        Self {
            s0: dest(s0.as_deref_mut(), t0, start, len),
            s1: dest(s1.as_deref_mut(), t1, start, len),
            s2: dest(s2.as_deref_mut(), t2, start, len),
            m: dest(o.mask.as_deref_mut(), tm, start, len),
            d: dest(o.dolp.as_deref_mut(), td, start, len),
            a: dest(o.aolp.as_deref_mut(), ta, start, len),
        }
    }
}

/// Per pixel from the four channels `ch` (0, 45, 90, 135°, dark included) and the
/// largest raw value `mx` (used when `SAT`): `S0 = ½ ((I0 + I90) + (I45 + I135)) − dark2`,
/// `S1 = I0 − I90`, `S2 = I45 − I135`, the mask, its counts, DoLP and AoLP when `POLAR`.
#[inline(always)]
fn stokes_pixels<T: Sample, const SAT: bool, const POLAR: bool>(
    ch: [&[f32]; 4],
    mx: &[f32],
    rules: &PixelRules,
    dark2: f32,
    out: PixelRows<'_>,
    counts: &mut [u32; 3],
) {
    let PixelRows {
        s0,
        s1,
        s2,
        m,
        d,
        a,
    } = out;
    let n = s0.len();
    let (s1, s2, m) = (&mut s1[..n], &mut s2[..n], &mut m[..n]);
    let (d, a) = if POLAR {
        (&mut d[..n], &mut a[..n])
    } else {
        (&mut d[..0], &mut a[..0])
    };
    let mx = if SAT { &mx[..n] } else { &mx[..0] };
    let [c0, c45, c90, c135] = ch.map(|c| &c[..n]);
    let (sat, min_s0) = (rules.saturation, rules.min_s0);
    let mut cnt = *counts;
    for i in 0..n {
        let (a0, a45, a90, a135) = (c0[i], c45[i], c90[i], c135[i]);
        let v0 = 0.5 * ((a0 + a90) + (a45 + a135)) - dark2;
        let v1 = a0 - a90;
        let v2 = a45 - a135;
        let nf = !T::INTEGER && !(v0 + v1 + v2).is_finite();
        let satd = SAT && mx[i] >= sat;
        let mk = mask_value(nf, satd, v0, min_s0);
        s0[i] = v0;
        s1[i] = v1;
        s2[i] = v2;
        m[i] = mk;
        count(mk, true, &mut cnt);
        if POLAR {
            (d[i], a[i]) = polar(v0, v1, v2, mk);
        }
    }
    *counts = cnt;
}

/// Safe, token-gated entry points to the strip kernels for one instruction set (see
/// `isa.rs` for the safety argument: the token is handed out only when the CPU has the
/// features).
#[cfg(target_arch = "x86_64")]
macro_rules! colour_entry {
    ($modname:ident, $token:ty, $features:literal) => {
        pub(super) mod $modname {
            use super::{BandStrip, ColourJob, ColourScratch, MAX_BANDS};
            use crate::stokes::{PixelCounts, Sample};

            /// [`super::bilinear_strip`] for this instruction set.
            #[inline]
            pub(in crate::mosaic) fn bilinear<T: Sample, const SAT: bool, const POLAR: bool>(
                _t: $token,
                job: &ColourJob<'_, T>,
                y0: usize,
                rows: usize,
                out: &mut [BandStrip<'_>],
                sc: &mut ColourScratch,
            ) -> [PixelCounts; MAX_BANDS] {
                // SAFETY: the token proves the CPU has the enabled features.
                unsafe { bilinear_tf::<T, SAT, POLAR>(job, y0, rows, out, sc) }
            }

            /// # Safety
            /// The CPU has the enabled features.
            #[target_feature(enable = $features)]
            unsafe fn bilinear_tf<T: Sample, const SAT: bool, const POLAR: bool>(
                job: &ColourJob<'_, T>,
                y0: usize,
                rows: usize,
                out: &mut [BandStrip<'_>],
                sc: &mut ColourScratch,
            ) -> [PixelCounts; MAX_BANDS] {
                super::bilinear_strip::<T, SAT, POLAR>(job, y0, rows, out, sc)
            }

            /// [`super::superpixel_strip`] for this instruction set.
            #[inline]
            pub(in crate::mosaic) fn superpixel<T: Sample, const POLAR: bool>(
                _t: $token,
                job: &ColourJob<'_, T>,
                y0: usize,
                rows: usize,
                out: &mut [BandStrip<'_>],
                sc: &mut ColourScratch,
            ) -> [PixelCounts; MAX_BANDS] {
                // SAFETY: the token proves the CPU has the enabled features.
                unsafe { superpixel_tf::<T, POLAR>(job, y0, rows, out, sc) }
            }

            /// # Safety
            /// The CPU has the enabled features.
            #[target_feature(enable = $features)]
            unsafe fn superpixel_tf<T: Sample, const POLAR: bool>(
                job: &ColourJob<'_, T>,
                y0: usize,
                rows: usize,
                out: &mut [BandStrip<'_>],
                sc: &mut ColourScratch,
            ) -> [PixelCounts; MAX_BANDS] {
                super::superpixel_strip::<T, POLAR>(job, y0, rows, out, sc)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
colour_entry!(avx2, crate::cpu::Avx2Fma, "avx2,fma");
#[cfg(target_arch = "x86_64")]
colour_entry!(avx512, crate::cpu::Avx512, "avx512f,avx2,fma");
