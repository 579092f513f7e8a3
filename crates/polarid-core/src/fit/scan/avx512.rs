//! The grid scan with AVX-512F intrinsics: a whole block of 128 nodes (eight f32x16
//! accumulators) per pass over the `T` source positions for one pixel, 64 nodes for
//! four pixels (sixteen accumulators: per source position four curve loads, four
//! broadcasts and sixteen fused multiply-adds); the lane minima are reduced with
//! masked AVX-512 reductions.
//!
//! # Safety
//! Every function takes the [`Avx512`] token, which exists only when
//! [`crate::cpu::cpu_features`] found AVX-512F (and AVX2, FMA) on this CPU; raw
//! pointers are formed only inside slices whose lengths the function asserts first.

use std::arch::x86_64::*;

use super::prune::{GROUP, Groups, MAX_GROUPS, NV, V16};
use super::{BandMin, SCAN_BLOCK, Scan};
use crate::cpu::Avx512;

impl Scan for Avx512 {
    const FOUR: bool = true;

    #[inline(always)]
    fn scan(
        self,
        curves: &[f32],
        base: &[f32],
        y: &[f32],
        w: Option<&[f32]>,
        band: usize,
        bands: &mut [BandMin],
    ) {
        scan_avx512(self, curves, base, y, w, band, bands)
    }

    #[inline(always)]
    fn scan4(
        self,
        curves: &[f32],
        base: &[f32],
        ny: [&[f32]; 4],
        band: usize,
        bands: [&mut [BandMin]; 4],
    ) {
        scan4_avx512(self, curves, base, ny, band, bands)
    }

    const PRUNED: bool = true;

    #[inline(always)]
    fn scan4_pruned(self, groups: &Groups, ny: [&[f32]; 4], bands: [&mut [BandMin]; 4]) {
        scan4_pruned_avx512(self, groups, ny, bands)
    }

    #[inline(always)]
    fn scan_rows(
        self,
        rows: &[&[f32]],
        base: &[f32],
        y: &[f32],
        w: Option<&[f32]>,
        band: usize,
        bands: &mut [BandMin],
    ) {
        scan_rows_avx512(self, rows, base, y, w, band, bands)
    }
}

/// [`Scan::scan_rows`] with AVX-512F intrinsics: a block of 128 nodes (eight f32x16
/// accumulators) per pass over the rows.
///
/// Safe: the `Avx512` token proves the CPU has AVX-512F; every pointer is checked against
/// the asserted slice lengths.
#[inline(always)]
fn scan_rows_avx512(
    tok: Avx512,
    rows: &[&[f32]],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    band: usize,
    bands: &mut [BandMin],
) {
    let t_len = rows.len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(
        rows.iter().all(|r| r.len() >= gp)
            && y.len() >= t_len
            && w.is_none_or(|w| w.len() >= t_len)
            && bands.len() >= gp.div_ceil(band)
            && band.is_multiple_of(SCAN_BLOCK)
    );
    // SAFETY: every pointer stays inside `rows[t][..gp]` and `base[..gp]`
    // (asserted); the CPU has AVX-512F (the token).
    unsafe {
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        let mut m = _mm512_set1_ps(f32::INFINITY);
        let mut ix = _mm512_set1_epi32(-1);
        for b in 0..nb {
            let o = b * SCAN_BLOCK;
            let bp = base.as_ptr().add(o);
            let mut a = [_mm512_setzero_ps(); 8];
            for (i, ai) in a.iter_mut().enumerate() {
                *ai = _mm512_loadu_ps(bp.add(16 * i));
            }
            for (t, row) in rows.iter().enumerate() {
                let r = row.as_ptr().add(o);
                let yt = _mm512_set1_ps(*y.get_unchecked(t));
                match w {
                    None => {
                        for (i, ai) in a.iter_mut().enumerate() {
                            let d = _mm512_sub_ps(_mm512_loadu_ps(r.add(16 * i)), yt);
                            *ai = _mm512_fmadd_ps(d, d, *ai);
                        }
                    }
                    Some(w) => {
                        let wt = _mm512_set1_ps(*w.get_unchecked(t));
                        for (i, ai) in a.iter_mut().enumerate() {
                            let d = _mm512_sub_ps(_mm512_loadu_ps(r.add(16 * i)), yt);
                            *ai = _mm512_fmadd_ps(_mm512_mul_ps(wt, d), d, *ai);
                        }
                    }
                }
            }
            for (i, ai) in a.iter().enumerate() {
                let lt = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(*ai, m);
                m = _mm512_mask_mov_ps(m, lt, *ai);
                let idx = _mm512_add_epi32(iota, _mm512_set1_epi32((o + 16 * i) as i32));
                ix = _mm512_mask_mov_epi32(ix, lt, idx);
            }
            if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == nb {
                bands[b * SCAN_BLOCK / band] = reduce512(tok, m, ix);
                m = _mm512_set1_ps(f32::INFINITY);
                ix = _mm512_set1_epi32(-1);
            }
        }
    }
}

/// [`reduce`](super::reduce) of sixteen lanes with AVX-512F.
///
/// Safe: the `Avx512` token proves the CPU has AVX-512F.
#[inline(always)]
fn reduce512(_: Avx512, m: __m512, ix: __m512i) -> BandMin {
    // SAFETY: AVX-512F (the token).
    unsafe {
        let v = _mm512_reduce_min_ps(m);
        let eq = _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(m, _mm512_set1_ps(v));
        let node = _mm512_mask_reduce_min_epu32(eq, ix);
        if eq == 0 {
            BandMin::default()
        } else {
            BandMin { value: v, node }
        }
    }
}

/// Scan of one pixel with AVX-512F intrinsics (see the module documentation of `scan`).
///
/// Safe: the `Avx512` token proves the CPU has AVX-512F; every pointer is checked against
/// the asserted slice lengths.
#[inline(always)]
fn scan_avx512(
    tok: Avx512,
    curves: &[f32],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    band: usize,
    bands: &mut [BandMin],
) {
    let t_len = y.len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(
        curves.len() >= gp * t_len
            && w.is_none_or(|w| w.len() >= t_len)
            && bands.len() >= gp.div_ceil(band)
            && band.is_multiple_of(SCAN_BLOCK)
    );
    // SAFETY: every pointer stays inside `curves[..gp·T]` and `base[..gp]`
    // (asserted); the CPU has AVX-512F (the token).
    unsafe {
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        let mut m = _mm512_set1_ps(f32::INFINITY);
        let mut ix = _mm512_set1_epi32(-1);
        for b in 0..nb {
            let cb = curves.as_ptr().add(b * SCAN_BLOCK * t_len);
            let o = b * SCAN_BLOCK;
            let bp = base.as_ptr().add(o);
            let mut a = [_mm512_setzero_ps(); 8];
            for (i, ai) in a.iter_mut().enumerate() {
                *ai = _mm512_loadu_ps(bp.add(16 * i));
            }
            for t in 0..t_len {
                let r = cb.add(t * SCAN_BLOCK);
                match w {
                    None => {
                        let ny = _mm512_set1_ps(-*y.get_unchecked(t));
                        for (i, ai) in a.iter_mut().enumerate() {
                            *ai = _mm512_fmadd_ps(_mm512_loadu_ps(r.add(16 * i)), ny, *ai);
                        }
                    }
                    Some(w) => {
                        let yt = _mm512_set1_ps(*y.get_unchecked(t));
                        let wt = _mm512_set1_ps(*w.get_unchecked(t));
                        for (i, ai) in a.iter_mut().enumerate() {
                            let d = _mm512_sub_ps(_mm512_loadu_ps(r.add(16 * i)), yt);
                            *ai = _mm512_fmadd_ps(_mm512_mul_ps(wt, d), d, *ai);
                        }
                    }
                }
            }
            for (i, ai) in a.iter().enumerate() {
                let lt = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(*ai, m);
                m = _mm512_mask_mov_ps(m, lt, *ai);
                let idx = _mm512_add_epi32(iota, _mm512_set1_epi32((o + 16 * i) as i32));
                ix = _mm512_mask_mov_epi32(ix, lt, idx);
            }
            if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == nb {
                bands[b * SCAN_BLOCK / band] = reduce512(tok, m, ix);
                m = _mm512_set1_ps(f32::INFINITY);
                ix = _mm512_set1_epi32(-1);
            }
        }
    }
}

/// f32x16 vectors of nodes per pass of the four-pixel scan: 64 nodes, sixteen
/// accumulators, so that each broadcast measurement serves four vectors and each loaded
/// curve vector four pixels.
const V4: usize = 4;

/// Unweighted scans of four pixels at once: every curve vector loaded from memory
/// serves the four. `ny[p]`: the `T` measurements of pixel `p`, negated; `bands[p]`:
/// its band minima. The same results as four calls of [`scan_avx512`].
///
/// Safe: the `Avx512` token proves the CPU has AVX-512F; every pointer is checked against
/// the asserted slice lengths.
#[inline(always)]
fn scan4_avx512(
    tok: Avx512,
    curves: &[f32],
    base: &[f32],
    ny: [&[f32]; 4],
    band: usize,
    bands: [&mut [BandMin]; 4],
) {
    let t_len = ny[0].len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(
        curves.len() >= gp * t_len
            && ny.iter().all(|y| y.len() == t_len)
            && bands.iter().all(|b| b.len() >= gp.div_ceil(band))
            && band.is_multiple_of(SCAN_BLOCK)
    );
    // SAFETY: pointers stay inside `curves[..gp·T]` and `base[..gp]` (asserted); the
    // CPU has AVX-512F (the token).
    unsafe {
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        let mut m = [_mm512_set1_ps(f32::INFINITY); 4];
        let mut ix = [_mm512_set1_epi32(-1); 4];

        for b in 0..nb {
            let cb = curves.as_ptr().add(b * SCAN_BLOCK * t_len);
            for h in 0..SCAN_BLOCK / (16 * V4) {
                let o = b * SCAN_BLOCK + h * 16 * V4;
                let bp = base.as_ptr().add(o);
                // Explicit arrays, not `array::from_fn`: a closure would not inherit the
                // caller's target features, and its intrinsics might not inline.
                let bv: [__m512; V4] = [
                    _mm512_loadu_ps(bp),
                    _mm512_loadu_ps(bp.add(16)),
                    _mm512_loadu_ps(bp.add(32)),
                    _mm512_loadu_ps(bp.add(48)),
                ];
                let mut a = [bv; 4];
                for t in 0..t_len {
                    let r = cb.add(t * SCAN_BLOCK + h * 16 * V4);
                    let c: [__m512; V4] = [
                        _mm512_loadu_ps(r),
                        _mm512_loadu_ps(r.add(16)),
                        _mm512_loadu_ps(r.add(32)),
                        _mm512_loadu_ps(r.add(48)),
                    ];
                    for (p, ap) in a.iter_mut().enumerate() {
                        let nyt = _mm512_set1_ps(*ny[p].get_unchecked(t));
                        for (i, ai) in ap.iter_mut().enumerate() {
                            *ai = _mm512_fmadd_ps(c[i], nyt, *ai);
                        }
                    }
                }
                for i in 0..V4 {
                    let idx = _mm512_add_epi32(iota, _mm512_set1_epi32((o + 16 * i) as i32));
                    for p in 0..4 {
                        let lt = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a[p][i], m[p]);
                        m[p] = _mm512_mask_mov_ps(m[p], lt, a[p][i]);
                        ix[p] = _mm512_mask_mov_epi32(ix[p], lt, idx);
                    }
                }
            }
            if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == nb {
                for p in 0..4 {
                    bands[p][b * SCAN_BLOCK / band] = reduce512(tok, m[p], ix[p]);
                    m[p] = _mm512_set1_ps(f32::INFINITY);
                    ix[p] = _mm512_set1_epi32(-1);
                }
            }
        }
    }
}

/// The aligned load of one [`V16`] (not a closure: closures do not inherit the
/// caller's target features).
///
/// # Safety
/// The CPU has AVX-512F.
#[inline(always)]
unsafe fn ld(x: &V16) -> __m512 {
    // SAFETY: `V16` is 64 bytes, aligned to 64; AVX-512F (the caller's contract).
    unsafe { _mm512_load_ps(x.0.as_ptr()) }
}

/// The pruned unweighted scans of four pixels (see `prune.rs`), each stage over the four
/// pixels side by side. `ny[p]`: the `T` measurements of pixel `p`, negated;
/// `bands[p][0]`: its best node, the same as [`scan4_avx512`] with one band gives (and
/// as `prune::pruned_reference`).
///
/// Safe: the `Avx512` token proves the CPU has AVX-512F (and FMA); every index is
/// checked against the asserted lengths of the group arrays (group indices come from
/// masks limited to the `q` groups).
#[inline(always)]
fn scan4_pruned_avx512(tok: Avx512, g: &Groups, ny: [&[f32]; 4], bands: [&mut [BandMin]; 4]) {
    // A copy per `T` up to 16, so that the loops over the source positions unroll and
    // each pixel's broadcast measurements stay in registers; `T` at run time beyond.
    macro_rules! by_len {
        ($($n:literal)*) => {
            match g.t_len {
                $($n => pruned4::<$n>(tok, g, ny, bands),)*
                _ => pruned4::<0>(tok, g, ny, bands),
            }
        };
    }
    by_len!(3 4 5 6 7 8 9 10 11 12 13 14 15 16)
}

/// [`scan4_pruned_avx512`] for `T = TC` (`TC = 0`: `T` at run time, at most 16
/// broadcast measurements kept in registers).
///
/// Safe: as [`scan4_pruned_avx512`].
#[inline(always)]
fn pruned4<const TC: usize>(tok: Avx512, g: &Groups, ny: [&[f32]; 4], bands: [&mut [BandMin]; 4]) {
    let t_len = if TC == 0 { g.t_len } else { TC };
    let q = g.q;
    assert!(
        ny.iter().all(|y| y.len() == t_len)
            && bands.iter().all(|b| !b.is_empty())
            && (1..=MAX_GROUPS).contains(&q)
            && g.cen.len() == NV * t_len
            && g.cen_half.len() == NV
            && g.radius.len() == NV
            && g.curves.len() == q * t_len
            && g.half.len() == q
            && g.node.len() == q
    );
    let qmask = u64::MAX >> (MAX_GROUPS - q);
    let mut yy = [0f32; 4];
    for (s, y) in yy.iter_mut().zip(&ny) {
        for &v in y.iter() {
            *s = v.mul_add(v, *s);
        }
    }
    // SAFETY: every vector read is of an element of the asserted arrays (`v < NV`,
    // groups `< q`, `t < T`) or of the local `cv`; the CPU has AVX-512F and FMA (the
    // token).
    unsafe {
        // Stage 1: the centre values (sixteen accumulators: four vectors of centres
        // for four pixels), and the nearest centre of each pixel (the first on ties).
        let mut a = [[_mm512_setzero_ps(); NV]; 4];
        for v in 0..NV {
            let b = ld(g.cen_half.get_unchecked(v));
            for ap in a.iter_mut() {
                ap[v] = b;
            }
        }
        for t in 0..t_len {
            let c = [
                ld(g.cen.get_unchecked(t * NV)),
                ld(g.cen.get_unchecked(t * NV + 1)),
                ld(g.cen.get_unchecked(t * NV + 2)),
                ld(g.cen.get_unchecked(t * NV + 3)),
            ];
            for (p, ap) in a.iter_mut().enumerate() {
                let n = _mm512_set1_ps(*ny[p].get_unchecked(t));
                for (v, av) in ap.iter_mut().enumerate() {
                    *av = _mm512_fmadd_ps(c[v], n, *av);
                }
            }
        }
        let mut cv = [[V16([0.0; GROUP]); NV]; 4];
        let mut all = [false; 4];
        let mut g0 = [0usize; 4];
        for p in 0..4 {
            let ap = &a[p];
            for (c, &av) in cv[p].iter_mut().zip(ap) {
                _mm512_store_ps(c.0.as_mut_ptr(), av);
            }
            let mn = _mm512_min_ps(_mm512_min_ps(ap[0], ap[1]), _mm512_min_ps(ap[2], ap[3]));
            let b = _mm512_set1_ps(_mm512_reduce_min_ps(mn));
            let mut at = 0u64;
            for (v, &av) in ap.iter().enumerate() {
                at |= u64::from(_mm512_cmp_ps_mask::<_CMP_EQ_OQ>(av, b)) << (GROUP * v);
            }
            // (No finite centre value cannot happen for data in [0, 1]: then group 0
            // and every group.)
            let n = at.trailing_zeros() as usize;
            all[p] = n >= q;
            g0[p] = if n < q { n } else { 0 };
        }
        // Stage 2: the best value of the nearest group bounds each pixel's best value.
        let mut a = [
            ld(g.half.get_unchecked(g0[0])),
            ld(g.half.get_unchecked(g0[1])),
            ld(g.half.get_unchecked(g0[2])),
            ld(g.half.get_unchecked(g0[3])),
        ];
        for t in 0..t_len {
            for (p, ap) in a.iter_mut().enumerate() {
                let c = ld(g.curves.get_unchecked(g0[p] * t_len + t));
                *ap = _mm512_fmadd_ps(c, _mm512_set1_ps(*ny[p].get_unchecked(t)), *ap);
            }
        }
        // Stage 3: the candidate groups of each pixel.
        let two = _mm512_set1_ps(2.0);
        let dv = _mm512_set1_ps(g.delta);
        let mut masks = [0u64; 4];
        for p in 0..4 {
            let v0 = _mm512_reduce_min_ps(a[p]);
            let lim = (2f32.mul_add(v0, yy[p]).max(0.0) + g.delta).sqrt();
            let (lv, yv) = (_mm512_set1_ps(lim), _mm512_set1_ps(yy[p]));
            let mut mask = 1u64 << g0[p];
            for (v, c) in cv[p].iter().enumerate() {
                let lhs = _mm512_fmadd_ps(ld(c), two, yv);
                let s = _mm512_add_ps(ld(g.radius.get_unchecked(v)), lv);
                let rhs = _mm512_fmadd_ps(s, s, dv);
                let k = _mm512_cmp_ps_mask::<_CMP_NGT_UQ>(lhs, rhs);
                mask |= u64::from(k) << (GROUP * v);
            }
            if all[p] {
                mask = u64::MAX;
            }
            masks[p] = mask & qmask;
        }
        // Stage 4: their nodes, in group order, into lane minima; two pixels side by
        // side (two independent chains of multiply-adds per step, each pixel's
        // broadcast measurements in registers). When one pixel has no candidate left it
        // scores its last group again, which leaves its minima as they are (equal
        // values do not replace).
        let held = if TC == 0 { t_len.min(8) } else { TC };
        let [b0, b1, b2, b3] = bands;
        for (pa, pb, ba, bb) in [(0, 1, b0, b1), (2, 3, b2, b3)] {
            let (mut ma, mut mb) = (masks[pa], masks[pb]);
            let mut na = [_mm512_setzero_ps(); 16];
            let mut nb = [_mm512_setzero_ps(); 16];
            for t in 0..held {
                na[t] = _mm512_set1_ps(*ny[pa].get_unchecked(t));
                nb[t] = _mm512_set1_ps(*ny[pb].get_unchecked(t));
            }
            let mut m = [_mm512_set1_ps(f32::INFINITY); 2];
            let mut ix = [_mm512_set1_epi32(-1); 2];
            let (mut ga, mut gb) = (g0[pa], g0[pb]);
            while (ma | mb) != 0 {
                if ma != 0 {
                    ga = ma.trailing_zeros() as usize;
                }
                if mb != 0 {
                    gb = mb.trailing_zeros() as usize;
                }
                ma &= ma.wrapping_sub(1);
                mb &= mb.wrapping_sub(1);
                let mut acc = [ld(g.half.get_unchecked(ga)), ld(g.half.get_unchecked(gb))];
                for t in 0..t_len {
                    let (xa, xb) = if t < held {
                        (na[t], nb[t])
                    } else {
                        (
                            _mm512_set1_ps(*ny[pa].get_unchecked(t)),
                            _mm512_set1_ps(*ny[pb].get_unchecked(t)),
                        )
                    };
                    acc[0] =
                        _mm512_fmadd_ps(ld(g.curves.get_unchecked(ga * t_len + t)), xa, acc[0]);
                    acc[1] =
                        _mm512_fmadd_ps(ld(g.curves.get_unchecked(gb * t_len + t)), xb, acc[1]);
                }
                for (i, gi) in [ga, gb].into_iter().enumerate() {
                    let lt = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(acc[i], m[i]);
                    m[i] = _mm512_mask_mov_ps(m[i], lt, acc[i]);
                    let nodes = _mm512_load_si512(g.node.get_unchecked(gi).0.as_ptr().cast());
                    ix[i] = _mm512_mask_mov_epi32(ix[i], lt, nodes);
                }
            }
            *ba.get_unchecked_mut(0) = reduce512(tok, m[0], ix[0]);
            *bb.get_unchecked_mut(0) = reduce512(tok, m[1], ix[1]);
        }
    }
}
