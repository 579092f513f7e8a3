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
