//! Strip kernels of the colour polarization reconstructions ([`super::colour`]): portable,
//! branch-free loops over blocks of [`CBLOCK`] columns, compiled as they are and, inlined
//! into the token-gated entry points at the end of this file, for AVX2 + FMA and
//! AVX-512F. No `a·b + c` is contracted into a fused multiply-add, so every instruction
//! set gives the same bits.
//!
//! Bilinear, per output row and block of columns (all intermediate rows in the
//! per-thread [`ColourScratch`], ~40 KB):
//!
//! 1. for each of the 16 lattices (`ρ = y mod 4`, `χ = x mod 4`) the vertically
//!    interpolated raw row at the lattice's columns, deinterleaved into one short row
//!    per lattice, padded by one (clamped) group on each side (and the vertical maxima
//!    for the saturation test);
//! 2. for each phase `j = x mod 4` of the output columns: each lattice's horizontal
//!    interpolation at the columns `4m + j` (a two-tap blend of neighbouring groups with
//!    the phase's weight), then per band the channel means, Stokes, mask, DoLP and AoLP;
//! 3. the four phases interleaved into the caller's rows.

use super::colour_pattern::ColourPattern;
use super::kernel::{StripOut, count, mask_value, polar, row_counts};
use crate::stokes::{PixelCounts, PixelRules, Sample};

/// Columns per block of the bilinear kernel (a multiple of 4).
pub(super) const CBLOCK: usize = 256;
/// Groups (4-column periods) per block.
const G: usize = CBLOCK / 4;
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
        for b in 0..nbands {
            for k in 0..4 {
                let l = pattern.lattices(b, k);
                n[b] = l.len().min(4);
                for (i, v) in l.into_iter().take(4).enumerate() {
                    lat[b][k][i] = v;
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
    /// Vertically interpolated lattice rows, 16 × (G + 2) (padded).
    d: Vec<f32>,
    /// Their vertical maxima (saturation), 16 × (G + 2).
    dm: Vec<f32>,
    /// Horizontally interpolated lattice rows of one phase, 16 × G.
    h: Vec<f32>,
    /// Their maxima, 16 × G.
    hm: Vec<f32>,
    /// Channel means of one band (bands with several blocks), 4 × G.
    ik: Vec<f32>,
    /// Largest raw value of one band's samples, G.
    mx: Vec<f32>,
    /// Per band, output (s0, s1, s2, dolp, aolp) and phase: MAX_BANDS × 5 × 4 × G.
    ph: Vec<f32>,
    /// Per band and phase the mask: MAX_BANDS × 4 × G.
    pm: Vec<u8>,
}

impl ColourScratch {
    pub(super) fn new() -> Self {
        Self {
            d: vec![0.0; 16 * (G + 2)],
            dm: vec![0.0; 16 * (G + 2)],
            h: vec![0.0; 16 * G],
            hm: vec![0.0; 16 * G],
            ik: vec![0.0; 4 * G],
            mx: vec![0.0; G],
            ph: vec![0.0; MAX_BANDS * 5 * 4 * G],
            pm: vec![0; MAX_BANDS * 4 * G],
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

/// Fill one padded lattice row `d` (G + 2 long, first `g + 2` used) of residue `chi`
/// for the groups `m0 − 1 ..= m0 + g` (clamped to `0..w4`) from the raw rows `a`, `b`
/// blended with phase `e` (vertical), and its maxima `dm` when `SAT`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn fill_lattice<T: Sample, const SAT: bool>(
    a: &[T],
    b: &[T],
    e: usize,
    chi: usize,
    m0: usize,
    g: usize,
    w4: usize,
    d: &mut [f32],
    dm: &mut [f32],
) {
    let (wa, wb) = weights(e);
    let val = |gm: usize| {
        let x = 4 * gm + chi;
        let (va, vb) = (a[x].to_f32(), b[x].to_f32());
        let v = if e == 0 { va } else { wa * va + wb * vb };
        let m = if e == 0 { va } else { va.max(vb) };
        (v, m)
    };
    let first = m0.saturating_sub(1);
    let last = (m0 + g).min(w4 - 1);
    (d[0], dm[0]) = val(first);
    (d[g + 1], dm[g + 1]) = val(last);
    let (sa, sb) = (&a[4 * m0..4 * (m0 + g)], &b[4 * m0..4 * (m0 + g)]);
    let (di, dmi) = (&mut d[1..g + 1], &mut dm[1..g + 1]);
    if e == 0 {
        for (o, s) in di.iter_mut().zip(sa.chunks_exact(4)) {
            *o = s[chi].to_f32();
        }
        if SAT {
            for (o, s) in dmi.iter_mut().zip(sa.chunks_exact(4)) {
                *o = s[chi].to_f32();
            }
        }
    } else {
        for ((o, s), t) in di
            .iter_mut()
            .zip(sa.chunks_exact(4))
            .zip(sb.chunks_exact(4))
        {
            *o = wa * s[chi].to_f32() + wb * t[chi].to_f32();
        }
        if SAT {
            for ((o, s), t) in dmi
                .iter_mut()
                .zip(sa.chunks_exact(4))
                .zip(sb.chunks_exact(4))
            {
                *o = s[chi].to_f32().max(t[chi].to_f32());
            }
        }
    }
}

/// The bilinear colour reconstruction of one strip of output rows `y0 .. y0 + rows`
/// into `out` (one [`StripOut`] per band, each `rows × width`): returns the counts of
/// each band.
#[inline(always)]
pub(super) fn bilinear_strip<T: Sample, const SAT: bool, const POLAR: bool>(
    job: &ColourJob<'_, T>,
    out: &mut [StripOut<'_>],
    sc: &mut ColourScratch,
) -> [PixelCounts; MAX_BANDS] {
    let (w, hgt) = (job.width, job.height);
    let w4 = w / 4;
    let dark2 = 2.0 * job.rules.dark_level;
    let (sat, min_s0) = (job.rules.saturation, job.rules.min_s0);
    let nb = job.nbands.min(out.len());
    let (y0, rows) = match out.first() {
        Some(o) => (o.y0, o.rows),
        None => return [PixelCounts::default(); MAX_BANDS],
    };
    let mut total = [PixelCounts::default(); MAX_BANDS];
    const GP: usize = G + 2;
    for r in 0..rows {
        let y = y0 + r;
        let vt: [(usize, usize, usize); 4] = std::array::from_fn(|rho| taps(y, rho, hgt));
        let mut counts = [[0u32; 3]; MAX_BANDS];
        for c0 in (0..w).step_by(CBLOCK) {
            let len = CBLOCK.min(w - c0);
            let (g, m0) = (len / 4, c0 / 4);
            // 1. vertically interpolated lattice rows
            for (rho, &(ya, yb, e)) in vt.iter().enumerate() {
                let (a, b) = (row(job.raw, w, ya), row(job.raw, w, yb));
                for chi in 0..4 {
                    let l = 4 * rho + chi;
                    fill_lattice::<T, SAT>(
                        a,
                        b,
                        e,
                        chi,
                        m0,
                        g,
                        w4,
                        &mut sc.d[l * GP..(l + 1) * GP],
                        &mut sc.dm[l * GP..(l + 1) * GP],
                    );
                }
            }
            // 2. per phase: horizontal interpolation, channels, Stokes
            for j in 0..4 {
                for l in 0..16 {
                    let chi = l % 4;
                    let e = (j + 4 - chi) % 4;
                    let base = usize::from(chi <= j);
                    let d = &sc.d[l * GP + base..][..g + 1];
                    let h = &mut sc.h[l * G..][..g];
                    if e == 0 {
                        h.copy_from_slice(&d[..g]);
                    } else {
                        let (wa, wb) = weights(e);
                        let (d0, d1) = (&d[..g], &d[1..g + 1]);
                        for i in 0..g {
                            h[i] = wa * d0[i] + wb * d1[i];
                        }
                    }
                    if SAT {
                        let dm = &sc.dm[l * GP + base..][..g + 1];
                        let hm = &mut sc.hm[l * G..][..g];
                        if e == 0 {
                            hm.copy_from_slice(&dm[..g]);
                        } else {
                            let (d0, d1) = (&dm[..g], &dm[1..g + 1]);
                            for i in 0..g {
                                hm[i] = d0[i].max(d1[i]);
                            }
                        }
                    }
                }
                for b in 0..nb {
                    let n = job.n[b];
                    let lat = &job.lat[b];
                    // channel means
                    if n > 1 {
                        let inv = 1.0 / n as f32;
                        for (k, lk) in lat.iter().enumerate() {
                            let ik = &mut sc.ik[k * G..][..g];
                            ik.copy_from_slice(&sc.h[lk[0] * G..][..g]);
                            for &l in &lk[1..n] {
                                let hl = &sc.h[l * G..][..g];
                                for i in 0..g {
                                    ik[i] += hl[i];
                                }
                            }
                            for v in ik.iter_mut() {
                                *v *= inv;
                            }
                        }
                    }
                    if SAT {
                        let mx = &mut sc.mx[..g];
                        mx.fill(f32::NEG_INFINITY);
                        for lk in lat {
                            for &l in &lk[..n] {
                                let hm = &sc.hm[l * G..][..g];
                                for i in 0..g {
                                    mx[i] = mx[i].max(hm[i]);
                                }
                            }
                        }
                    }
                    let ch: [&[f32]; 4] = std::array::from_fn(|k| {
                        if n > 1 {
                            &sc.ik[k * G..][..g]
                        } else {
                            &sc.h[lat[k][0] * G..][..g]
                        }
                    });
                    let mx = &sc.mx[..g];
                    let base = b * 5 * 4 * G;
                    let ph = &mut sc.ph[base..base + 20 * G];
                    let (p0, rest) = ph.split_at_mut(4 * G);
                    let (p1, rest) = rest.split_at_mut(4 * G);
                    let (p2, rest) = rest.split_at_mut(4 * G);
                    let (pd, pa) = rest.split_at_mut(4 * G);
                    let s0 = &mut p0[j * G..][..g];
                    let s1 = &mut p1[j * G..][..g];
                    let s2 = &mut p2[j * G..][..g];
                    let dl = &mut pd[j * G..][..g];
                    let al = &mut pa[j * G..][..g];
                    let m = &mut sc.pm[(b * 4 + j) * G..][..g];
                    let [c0s, c45, c90, c135] = ch;
                    let cnt = &mut counts[b];
                    for i in 0..g {
                        let (a0, a45, a90, a135) = (c0s[i], c45[i], c90[i], c135[i]);
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
                        count(mk, true, cnt);
                        if POLAR {
                            (dl[i], al[i]) = polar(v0, v1, v2, mk);
                        }
                    }
                }
            }
            // 3. interleave the phases into the caller's rows
            for (b, o) in out.iter_mut().enumerate().take(nb) {
                let span = r * w + c0..r * w + c0 + len;
                let base = b * 5 * 4 * G;
                let [s0, s1, s2] = &mut o.s;
                let dests = [
                    s0.as_deref_mut(),
                    s1.as_deref_mut(),
                    s2.as_deref_mut(),
                    o.dolp.as_deref_mut(),
                    o.aolp.as_deref_mut(),
                ];
                for (q, dst) in dests.into_iter().enumerate() {
                    if let Some(dst) = dst
                        && (q < 3 || POLAR)
                    {
                        let p = &sc.ph[base + q * 4 * G..][..4 * G];
                        interleave(&mut dst[span.clone()], p, g);
                    }
                }
                if let Some(dst) = o.mask.as_deref_mut() {
                    let p = &sc.pm[b * 4 * G..][..4 * G];
                    interleave(&mut dst[span], p, g);
                }
            }
        }
        for b in 0..nb {
            total[b] = total[b].add(row_counts(counts[b], w));
        }
    }
    total
}

/// `dst[4i + j] = p[j·G + i]` for `i < g`, `j < 4`.
#[inline(always)]
fn interleave<V: Copy>(dst: &mut [V], p: &[V], g: usize) {
    let (p0, p1, p2, p3) = (
        &p[..g],
        &p[G..G + g],
        &p[2 * G..2 * G + g],
        &p[3 * G..3 * G + g],
    );
    for (i, o) in dst.chunks_exact_mut(4).take(g).enumerate() {
        o[0] = p0[i];
        o[1] = p1[i];
        o[2] = p2[i];
        o[3] = p3[i];
    }
}

/// The super-pixel colour reconstruction of one strip of output rows (one output per
/// 4×4 period): per band and polarizer `I_k = (Σ raw)/n − dark` over the band's `n`
/// blocks, `S0 = ½ ((I0 + I90) + (I45 + I135))`, `S1 = I0 − I90`, `S2 = I45 − I135`;
/// saturated when one of the band's `4n` raw values is.
#[inline(always)]
pub(super) fn superpixel_strip<T: Sample, const POLAR: bool>(
    job: &ColourJob<'_, T>,
    out: &mut [StripOut<'_>],
) -> [PixelCounts; MAX_BANDS] {
    let w = job.width;
    let ow = w / 4;
    let dark = job.rules.dark_level;
    let (sat, min_s0) = (job.rules.saturation, job.rules.min_s0);
    let nb = job.nbands.min(out.len());
    let (y0, rows) = match out.first() {
        Some(o) => (o.y0, o.rows),
        None => return [PixelCounts::default(); MAX_BANDS],
    };
    let mut total = [PixelCounts::default(); MAX_BANDS];
    for r in 0..rows {
        let cy = y0 + r;
        let raw_rows: [&[T]; 4] = std::array::from_fn(|rho| row(job.raw, w, 4 * cy + rho));
        for (b, o) in out.iter_mut().enumerate().take(nb) {
            let n = job.n[b];
            let inv = 1.0 / n as f32;
            let lat = &job.lat[b];
            let span = r * ow..(r + 1) * ow;
            let mut cnt = [0u32; 3];
            for x in 0..ow {
                let mut iv = [0f32; 4];
                let mut mx = f32::NEG_INFINITY;
                for (k, lk) in lat.iter().enumerate() {
                    let mut s = 0f32;
                    for &l in &lk[..n] {
                        let v = raw_rows[l / 4][4 * x + l % 4].to_f32();
                        s += v;
                        mx = mx.max(v);
                    }
                    iv[k] = s * inv - dark;
                }
                let [i0, i45, i90, i135] = iv;
                let v0 = 0.5 * ((i0 + i90) + (i45 + i135));
                let v1 = i0 - i90;
                let v2 = i45 - i135;
                let nf = !T::INTEGER && !(v0 + v1 + v2).is_finite();
                let mk = mask_value(nf, mx >= sat, v0, min_s0);
                count(mk, true, &mut cnt);
                let at = span.start + x;
                let [s0, s1, s2] = &mut o.s;
                for (dst, v) in [(s0, v0), (s1, v1), (s2, v2)] {
                    if let Some(d) = dst.as_deref_mut() {
                        d[at] = v;
                    }
                }
                if let Some(d) = o.mask.as_deref_mut() {
                    d[at] = mk;
                }
                if POLAR {
                    let (pd, pa) = polar(v0, v1, v2, mk);
                    if let Some(d) = o.dolp.as_deref_mut() {
                        d[at] = pd;
                    }
                    if let Some(d) = o.aolp.as_deref_mut() {
                        d[at] = pa;
                    }
                }
            }
            total[b] = total[b].add(row_counts(cnt, ow));
        }
    }
    total
}

/// Safe, token-gated entry points to [`bilinear_strip`] for one instruction set (see
/// `isa.rs` for the safety argument: the token is handed out only when the CPU has the
/// features).
#[cfg(target_arch = "x86_64")]
macro_rules! colour_entry {
    ($modname:ident, $token:ty, $features:literal) => {
        pub(super) mod $modname {
            use super::{ColourJob, ColourScratch, MAX_BANDS, bilinear_strip};
            use crate::mosaic::kernel::StripOut;
            use crate::stokes::{PixelCounts, Sample};

            /// [`bilinear_strip`] for this instruction set.
            #[inline]
            pub(in crate::mosaic) fn strip<T: Sample, const SAT: bool, const POLAR: bool>(
                _t: $token,
                job: &ColourJob<'_, T>,
                out: &mut [StripOut<'_>],
                sc: &mut ColourScratch,
            ) -> [PixelCounts; MAX_BANDS] {
                // SAFETY: the token proves the CPU has the enabled features.
                unsafe { strip_tf::<T, SAT, POLAR>(job, out, sc) }
            }

            /// # Safety
            /// The CPU has the enabled features.
            #[target_feature(enable = $features)]
            unsafe fn strip_tf<T: Sample, const SAT: bool, const POLAR: bool>(
                job: &ColourJob<'_, T>,
                out: &mut [StripOut<'_>],
                sc: &mut ColourScratch,
            ) -> [PixelCounts; MAX_BANDS] {
                bilinear_strip::<T, SAT, POLAR>(job, out, sc)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
colour_entry!(avx2, crate::cpu::Avx2Fma, "avx2,fma");
#[cfg(target_arch = "x86_64")]
colour_entry!(avx512, crate::cpu::Avx512, "avx512f,avx2,fma");
