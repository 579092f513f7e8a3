//! The grid scan with AVX2 + FMA intrinsics: 64 nodes (eight f32x8 accumulators) per
//! pass over the `T` source positions for one pixel, 16 nodes for four pixels.
//!
//! # Safety
//! Every function takes the [`Avx2Fma`] token, which exists only when
//! [`crate::cpu::cpu_features`] found AVX2 and FMA on this CPU; raw pointers are
//! formed only inside slices whose lengths the function asserts first.

use std::arch::x86_64::*;

use super::{BandMin, SCAN_BLOCK, Scan, reduce};
use crate::cpu::Avx2Fma;

impl Scan for Avx2Fma {
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
        scan_avx2(self, curves, base, y, w, band, bands)
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
        scan4_avx2(self, curves, base, ny, band, bands)
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
        scan_rows_avx2(self, rows, base, y, w, band, bands)
    }
}

/// [`Scan::scan_rows`] with AVX2 + FMA intrinsics: 64 nodes (eight f32x8
/// accumulators) per pass over the rows.
///
/// Safe: the `Avx2Fma` token proves the CPU has AVX2 and FMA; every pointer is checked
/// against the asserted slice lengths.
#[inline(always)]
fn scan_rows_avx2(
    _: Avx2Fma,
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
    // (asserted); the CPU has AVX2 + FMA (the token).
    unsafe {
        let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let mut m = _mm256_set1_ps(f32::INFINITY);
        let mut ix = _mm256_set1_epi32(-1);
        for b in 0..nb {
            for h in 0..2 {
                let o = b * SCAN_BLOCK + h * 64;
                let bp = base.as_ptr().add(o);
                let mut a = [_mm256_setzero_ps(); 8];
                for (i, ai) in a.iter_mut().enumerate() {
                    *ai = _mm256_loadu_ps(bp.add(8 * i));
                }
                for (t, row) in rows.iter().enumerate() {
                    let r = row.as_ptr().add(o);
                    let yt = _mm256_set1_ps(*y.get_unchecked(t));
                    match w {
                        None => {
                            for (i, ai) in a.iter_mut().enumerate() {
                                let d = _mm256_sub_ps(_mm256_loadu_ps(r.add(8 * i)), yt);
                                *ai = _mm256_fmadd_ps(d, d, *ai);
                            }
                        }
                        Some(w) => {
                            let wt = _mm256_set1_ps(*w.get_unchecked(t));
                            for (i, ai) in a.iter_mut().enumerate() {
                                let d = _mm256_sub_ps(_mm256_loadu_ps(r.add(8 * i)), yt);
                                *ai = _mm256_fmadd_ps(_mm256_mul_ps(wt, d), d, *ai);
                            }
                        }
                    }
                }
                for (i, ai) in a.iter().enumerate() {
                    let lt = _mm256_cmp_ps::<_CMP_LT_OQ>(*ai, m);
                    m = _mm256_blendv_ps(m, *ai, lt);
                    let idx = _mm256_add_epi32(iota, _mm256_set1_epi32((o + 8 * i) as i32));
                    ix = _mm256_castps_si256(_mm256_blendv_ps(
                        _mm256_castsi256_ps(ix),
                        _mm256_castsi256_ps(idx),
                        lt,
                    ));
                }
            }
            if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == nb {
                let mut mv = [0f32; 8];
                let mut iv = [0u32; 8];
                _mm256_storeu_ps(mv.as_mut_ptr(), m);
                _mm256_storeu_si256(iv.as_mut_ptr().cast(), ix);
                bands[b * SCAN_BLOCK / band] = reduce(&mv, &iv);
                m = _mm256_set1_ps(f32::INFINITY);
                ix = _mm256_set1_epi32(-1);
            }
        }
    }
}

/// Scan of one pixel with AVX2 + FMA intrinsics (see the module documentation of `scan`).
///
/// Safe: the `Avx2Fma` token proves the CPU has AVX2 and FMA; every pointer is checked against
/// the asserted slice lengths.
#[inline(always)]
fn scan_avx2(
    _: Avx2Fma,
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
    // (asserted); the CPU has AVX2 + FMA (the token).
    unsafe {
        let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let mut m = _mm256_set1_ps(f32::INFINITY);
        let mut ix = _mm256_set1_epi32(-1);
        for b in 0..nb {
            let cb = curves.as_ptr().add(b * SCAN_BLOCK * t_len);
            for h in 0..2 {
                let o = b * SCAN_BLOCK + h * 64;
                let bp = base.as_ptr().add(o);
                let mut a = [_mm256_setzero_ps(); 8];
                for (i, ai) in a.iter_mut().enumerate() {
                    *ai = _mm256_loadu_ps(bp.add(8 * i));
                }
                for t in 0..t_len {
                    let r = cb.add(t * SCAN_BLOCK + h * 64);
                    match w {
                        None => {
                            let ny = _mm256_set1_ps(-*y.get_unchecked(t));
                            for (i, ai) in a.iter_mut().enumerate() {
                                *ai = _mm256_fmadd_ps(_mm256_loadu_ps(r.add(8 * i)), ny, *ai);
                            }
                        }
                        Some(w) => {
                            let yt = _mm256_set1_ps(*y.get_unchecked(t));
                            let wt = _mm256_set1_ps(*w.get_unchecked(t));
                            for (i, ai) in a.iter_mut().enumerate() {
                                let d = _mm256_sub_ps(_mm256_loadu_ps(r.add(8 * i)), yt);
                                *ai = _mm256_fmadd_ps(_mm256_mul_ps(wt, d), d, *ai);
                            }
                        }
                    }
                }
                for (i, ai) in a.iter().enumerate() {
                    let lt = _mm256_cmp_ps::<_CMP_LT_OQ>(*ai, m);
                    m = _mm256_blendv_ps(m, *ai, lt);
                    let idx = _mm256_add_epi32(iota, _mm256_set1_epi32((o + 8 * i) as i32));
                    ix = _mm256_castps_si256(_mm256_blendv_ps(
                        _mm256_castsi256_ps(ix),
                        _mm256_castsi256_ps(idx),
                        lt,
                    ));
                }
            }
            if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == nb {
                let mut mv = [0f32; 8];
                let mut iv = [0u32; 8];
                _mm256_storeu_ps(mv.as_mut_ptr(), m);
                _mm256_storeu_si256(iv.as_mut_ptr().cast(), ix);
                bands[b * SCAN_BLOCK / band] = reduce(&mv, &iv);
                m = _mm256_set1_ps(f32::INFINITY);
                ix = _mm256_set1_epi32(-1);
            }
        }
    }
}

/// The four-pixel scan (`Scan::scan4`) with AVX2 + FMA intrinsics (16 nodes at a time: eight
/// accumulators for the four pixels). The same results as four calls of
/// [`scan_avx2`].
///
/// Safe: the `Avx2Fma` token proves the CPU has AVX2 and FMA; every pointer is checked against
/// the asserted slice lengths.
#[inline(always)]
fn scan4_avx2(
    _: Avx2Fma,
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
    // CPU has AVX2 + FMA (the token).
    unsafe {
        let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let mut m = [_mm256_set1_ps(f32::INFINITY); 4];
        let mut ix = [_mm256_set1_epi32(-1); 4];

        for b in 0..nb {
            let cb = curves.as_ptr().add(b * SCAN_BLOCK * t_len);
            for h in 0..SCAN_BLOCK / 16 {
                let o = b * SCAN_BLOCK + h * 16;
                let bp = base.as_ptr().add(o);
                let b2 = [_mm256_loadu_ps(bp), _mm256_loadu_ps(bp.add(8))];
                let mut a = [b2; 4];
                for t in 0..t_len {
                    let r = cb.add(t * SCAN_BLOCK + h * 16);
                    let c = [_mm256_loadu_ps(r), _mm256_loadu_ps(r.add(8))];
                    for (p, ap) in a.iter_mut().enumerate() {
                        let nyt = _mm256_set1_ps(*ny[p].get_unchecked(t));
                        ap[0] = _mm256_fmadd_ps(c[0], nyt, ap[0]);
                        ap[1] = _mm256_fmadd_ps(c[1], nyt, ap[1]);
                    }
                }
                for i in 0..2 {
                    let idx = _mm256_add_epi32(iota, _mm256_set1_epi32((o + 8 * i) as i32));
                    for p in 0..4 {
                        let lt = _mm256_cmp_ps::<_CMP_LT_OQ>(a[p][i], m[p]);
                        m[p] = _mm256_blendv_ps(m[p], a[p][i], lt);
                        ix[p] = _mm256_castps_si256(_mm256_blendv_ps(
                            _mm256_castsi256_ps(ix[p]),
                            _mm256_castsi256_ps(idx),
                            lt,
                        ));
                    }
                }
            }
            if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == nb {
                for p in 0..4 {
                    let mut mv = [0f32; 8];
                    let mut iv = [0u32; 8];
                    _mm256_storeu_ps(mv.as_mut_ptr(), m[p]);
                    _mm256_storeu_si256(iv.as_mut_ptr().cast(), ix[p]);
                    bands[p][b * SCAN_BLOCK / band] = reduce(&mv, &iv);
                    m[p] = _mm256_set1_ps(f32::INFINITY);
                    ix[p] = _mm256_set1_epi32(-1);
                }
            }
        }
    }
}
