//! The grid scan with AVX2 + FMA intrinsics: 64 nodes (eight f32x8 accumulators) per
//! pass over the `T` source positions for one pixel, 16 nodes for four pixels.
//!
//! # Safety
//! Every function takes the [`Avx2Fma`] token, which exists only when
//! [`crate::cpu::cpu_features`] found AVX2 and FMA on this CPU; raw pointers are
//! formed only inside slices whose lengths the function asserts first.

use std::arch::x86_64::*;

use super::prune::CLUSTER;
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
    fn score16(
        self,
        curves: [&[f32]; 4],
        base: [&[f32]; 4],
        ny: &[f32],
        nodes: [&[u32]; 4],
        m: &mut [f32; CLUSTER],
        ix: &mut [u32; CLUSTER],
    ) {
        let t_len = ny.len();
        for j in 0..4 {
            assert!(
                curves[j].len() >= t_len * CLUSTER
                    && base[j].len() >= CLUSTER
                    && nodes[j].len() >= CLUSTER
            );
        }
        // SAFETY: reads inside `curves[j][..T·16]`, `base[j][..16]`, `nodes[j][..16]`
        // (asserted) and the arrays `m`, `ix`; the token proves the CPU has AVX2 + FMA.
        unsafe {
            let mut a = [[_mm256_setzero_ps(); 2]; 4];
            for (j, aj) in a.iter_mut().enumerate() {
                aj[0] = _mm256_loadu_ps(base[j].as_ptr());
                aj[1] = _mm256_loadu_ps(base[j].as_ptr().add(8));
            }
            for (t, &nyt) in ny.iter().enumerate() {
                let n = _mm256_set1_ps(nyt);
                for (j, aj) in a.iter_mut().enumerate() {
                    let r = curves[j].as_ptr().add(t * CLUSTER);
                    aj[0] = _mm256_fmadd_ps(_mm256_loadu_ps(r), n, aj[0]);
                    aj[1] = _mm256_fmadd_ps(_mm256_loadu_ps(r.add(8)), n, aj[1]);
                }
            }
            let sign = _mm256_set1_epi32(i32::MIN);
            for h in 0..2 {
                let mut mv = _mm256_loadu_ps(m.as_ptr().add(8 * h));
                let mut iv = _mm256_loadu_si256(ix.as_ptr().add(8 * h).cast());
                for (j, aj) in a.iter().enumerate() {
                    let ah = aj[h];
                    let nv = _mm256_loadu_si256(nodes[j].as_ptr().add(8 * h).cast());
                    let lt = _mm256_cmp_ps::<_CMP_LT_OQ>(ah, mv);
                    let eq = _mm256_cmp_ps::<_CMP_EQ_OQ>(ah, mv);
                    // nodes < ix, unsigned: compare with the sign bits flipped.
                    let nlt =
                        _mm256_cmpgt_epi32(_mm256_xor_si256(iv, sign), _mm256_xor_si256(nv, sign));
                    let take = _mm256_or_ps(lt, _mm256_and_ps(eq, _mm256_castsi256_ps(nlt)));
                    mv = _mm256_blendv_ps(mv, ah, take);
                    iv = _mm256_blendv_epi8(iv, nv, _mm256_castps_si256(take));
                }
                _mm256_storeu_ps(m.as_mut_ptr().add(8 * h), mv);
                _mm256_storeu_si256(ix.as_mut_ptr().add(8 * h).cast(), iv);
            }
        }
    }

    #[inline(always)]
    fn bounds16(
        self,
        curves: &[f32],
        base: &[f32],
        ny: &[f32],
        r: &[f32],
        s0: f32,
        half_yy: f32,
        out: &mut [f32],
    ) -> (f32, usize) {
        assert!(r.len() >= CLUSTER && out.len() >= CLUSTER);
        let w = values16_avx2(self, curves, base, ny);
        let mut wa = [0f32; CLUSTER];
        // SAFETY: 8-value reads and writes inside `r`, `out` (asserted) and `wa`; the
        // token proves the CPU has AVX2 and FMA.
        unsafe {
            let zero = _mm256_setzero_ps();
            for (h, &wh) in w.iter().enumerate() {
                let s = _mm256_max_ps(
                    _mm256_fmadd_ps(_mm256_set1_ps(2.0), wh, _mm256_set1_ps(s0)),
                    zero,
                );
                let e = _mm256_max_ps(
                    _mm256_sub_ps(_mm256_sqrt_ps(s), _mm256_loadu_ps(r.as_ptr().add(8 * h))),
                    zero,
                );
                let lb = _mm256_fmsub_ps(
                    _mm256_mul_ps(_mm256_set1_ps(0.5), e),
                    e,
                    _mm256_set1_ps(half_yy),
                );
                _mm256_storeu_ps(out.as_mut_ptr().add(8 * h), lb);
                _mm256_storeu_ps(wa.as_mut_ptr().add(8 * h), wh);
            }
        }
        let mut best = (f32::INFINITY, 0);
        for (i, &v) in wa.iter().enumerate() {
            if v < best.0 {
                best = (v, i);
            }
        }
        best
    }

    #[inline(always)]
    fn not_above16(self, v: &[f32], limit: f32) -> u32 {
        assert!(v.len() >= CLUSTER);
        // SAFETY: 8-value reads inside `v` (asserted); the token proves the CPU has AVX.
        unsafe {
            let l = _mm256_set1_ps(limit);
            let lo =
                _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NGT_UQ>(_mm256_loadu_ps(v.as_ptr()), l));
            let hi = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NGT_UQ>(
                _mm256_loadu_ps(v.as_ptr().add(8)),
                l,
            ));
            (lo as u32 & 0xff) | ((hi as u32 & 0xff) << 8)
        }
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

/// The unweighted scan values of 16 nodes (see [`Scan::score16`]): one fused
/// multiply-add per position, in two f32x8 halves.
///
/// Safe: the `Avx2Fma` token proves the CPU has AVX2 and FMA; reads stay inside the
/// asserted slice lengths.
#[inline(always)]
fn values16_avx2(_tok: Avx2Fma, curves: &[f32], base: &[f32], ny: &[f32]) -> [__m256; 2] {
    let t_len = ny.len();
    assert!(curves.len() >= t_len * CLUSTER && base.len() >= CLUSTER);
    // SAFETY: reads inside `curves[..T·16]` and `base[..16]` (asserted); the token
    // proves the CPU has AVX2 and FMA.
    unsafe {
        let mut a0 = _mm256_loadu_ps(base.as_ptr());
        let mut a1 = _mm256_loadu_ps(base.as_ptr().add(8));
        for (t, &nyt) in ny.iter().enumerate() {
            let r = curves.as_ptr().add(t * CLUSTER);
            let n = _mm256_set1_ps(nyt);
            a0 = _mm256_fmadd_ps(_mm256_loadu_ps(r), n, a0);
            a1 = _mm256_fmadd_ps(_mm256_loadu_ps(r.add(8)), n, a1);
        }
        [a0, a1]
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
