//! The coarse grid scan of a fit: the cost of every grid node for one pixel, reduced
//! on the fly to the best node of every band of [`BAND`] consecutive nodes.
//!
//! Weighted, a node's value is its cost `Σ_t w_t (curve_c(t) − y_t)²`. Unweighted it
//! is `½‖curve_c‖² − Σ_t curve_c(t) y_t = (cost_c − ‖y‖²)/2`, the same ranking for one
//! multiply-add per node and source position. `base` starts the sums (`½‖curve_c‖²`,
//! or 0; +∞ on padding nodes, whose curves are 0).
//!
//! The node curves are stored in blocks of [`SCAN_BLOCK`] nodes, block-major:
//! `curves[(c / SCAN_BLOCK · T + t) · SCAN_BLOCK + c % SCAN_BLOCK]`, so that a block is
//! one contiguous read, accumulated over all `T` in vector registers. No value is
//! stored: every vector lane keeps its running minimum and the node holding it (first
//! wins on ties), and at the end of a band the lanes are reduced to the band's best
//! node (smallest value, then smallest index). Bands are rows of the `(n, k)` grid
//! (eight rows of 32 nodes at the default size, `k` ranges), so the band minima are
//! the starting points of competing basins.
//!
//! Every kernel adds in the same order (one rounding per multiply-add with FMA) and
//! breaks ties the same way, so all give the same bands for the same data.

/// Nodes per block of the scan's curve layout.
pub(crate) const SCAN_BLOCK: usize = 128;

/// Nodes per band when competing basins are searched (a multiple of
/// [`SCAN_BLOCK`]); otherwise the whole grid is one band.
pub(crate) const BAND: usize = 256;

/// Lanes of the running minima in the reduction.
const L: usize = 16;

/// Best node of one band: its value and index (`u32::MAX` when every value in the band
/// is +∞ or NaN).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BandMin {
    pub value: f32,
    pub node: u32,
}

impl Default for BandMin {
    fn default() -> Self {
        Self {
            value: f32::INFINITY,
            node: u32::MAX,
        }
    }
}

/// The best of the lane minima `m` (nodes `ix`): smallest value, then smallest node.
#[inline(always)]
fn reduce(m: &[f32], ix: &[u32]) -> BandMin {
    let mut best = BandMin::default();
    for (&v, &i) in m.iter().zip(ix) {
        if v < best.value || (v == best.value && i < best.node) {
            best = BandMin { value: v, node: i };
        }
    }
    best
}

/// [`reduce`] of sixteen lanes with AVX-512F.
///
/// # Safety
/// The caller is compiled for (and runs on a CPU with) AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn reduce512(m: std::arch::x86_64::__m512, ix: std::arch::x86_64::__m512i) -> BandMin {
    use std::arch::x86_64::*;
    // SAFETY: AVX-512F (caller's contract).
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

/// The overall best of the bands (the first band on ties: bands hold ascending nodes).
#[inline(always)]
pub(crate) fn best_of(bands: &[BandMin]) -> BandMin {
    let mut best = BandMin::default();
    for b in bands {
        if b.value < best.value {
            best = *b;
        }
    }
    best
}

/// Scan of one pixel with the portable kernel (`FMA`: `mul_add` is a hardware
/// instruction). `bands` receives one [`BandMin`] per band.
#[inline(always)]
pub(crate) fn scan_portable<const FMA: bool>(
    curves: &[f32],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    band: usize,
    bands: &mut [BandMin],
) {
    const BL: usize = 32;
    let t_len = y.len();
    let gp = base.len();
    let mut m = [f32::INFINITY; L];
    let mut ix = [u32::MAX; L];
    for b in 0..gp / SCAN_BLOCK {
        let blk = &curves[b * SCAN_BLOCK * t_len..(b + 1) * SCAN_BLOCK * t_len];
        for h in 0..SCAN_BLOCK / BL {
            let o = h * BL;
            let g0 = b * SCAN_BLOCK + o;
            let mut a = [0f32; BL];
            a.copy_from_slice(&base[g0..g0 + BL]);
            for t in 0..t_len {
                let row = &blk[t * SCAN_BLOCK + o..t * SCAN_BLOCK + o + BL];
                let yt = y[t];
                match w {
                    Some(w) => {
                        let wt = w[t];
                        for l in 0..BL {
                            let d = row[l] - yt;
                            let wd = wt * d;
                            a[l] = if FMA {
                                wd.mul_add(d, a[l])
                            } else {
                                a[l] + wd * d
                            };
                        }
                    }
                    None => {
                        let ny = -yt;
                        for l in 0..BL {
                            a[l] = if FMA {
                                row[l].mul_add(ny, a[l])
                            } else {
                                a[l] + row[l] * ny
                            };
                        }
                    }
                }
            }
            for (l, &v) in a.iter().enumerate() {
                if v < m[l % L] {
                    m[l % L] = v;
                    ix[l % L] = (g0 + l) as u32;
                }
            }
        }
        if ((b + 1) * SCAN_BLOCK).is_multiple_of(band) || b + 1 == gp / SCAN_BLOCK {
            bands[b * SCAN_BLOCK / band] = reduce(&m, &ix);
            m = [f32::INFINITY; L];
            ix = [u32::MAX; L];
        }
    }
}

/// Scan of one pixel with AVX2 + FMA intrinsics (see [`scan_portable`]).
///
/// # Safety
/// The caller is compiled for (and runs on a CPU with) AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn scan_avx2(
    curves: &[f32],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    band: usize,
    bands: &mut [BandMin],
) {
    use std::arch::x86_64::*;
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
    // (asserted); the CPU has AVX2 + FMA (caller's contract).
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

/// Scan of one pixel with AVX-512F intrinsics (see [`scan_portable`]).
///
/// # Safety
/// The caller is compiled for (and runs on a CPU with) AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn scan_avx512(
    curves: &[f32],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    band: usize,
    bands: &mut [BandMin],
) {
    use std::arch::x86_64::*;
    let t_len = y.len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(
        curves.len() >= gp * t_len
            && w.is_none_or(|w| w.len() >= t_len)
            && bands.len() >= gp.div_ceil(band)
            && band.is_multiple_of(SCAN_BLOCK)
    );
    // SAFETY: as in `scan_avx2`, with AVX-512F.
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
                bands[b * SCAN_BLOCK / band] = reduce512(m, ix);
                m = _mm512_set1_ps(f32::INFINITY);
                ix = _mm512_set1_epi32(-1);
            }
        }
    }
}

/// Unweighted scans of four pixels at once: every curve vector loaded from memory
/// serves the four. `ny[p]`: the `T` measurements of pixel `p`, negated; `bands[p]`:
/// its band minima. The same results as four calls of [`scan_avx512`].
///
/// # Safety
/// The caller is compiled for (and runs on a CPU with) AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn scan4_avx512(
    curves: &[f32],
    base: &[f32],
    ny: [&[f32]; 4],
    band: usize,
    bands: [&mut [BandMin]; 4],
) {
    use std::arch::x86_64::*;
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
    // CPU has AVX-512F (caller's contract).
    unsafe {
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        let mut m = [_mm512_set1_ps(f32::INFINITY); 4];
        let mut ix = [_mm512_set1_epi32(-1); 4];

        for b in 0..nb {
            let cb = curves.as_ptr().add(b * SCAN_BLOCK * t_len);
            for h in 0..SCAN_BLOCK / 32 {
                let o = b * SCAN_BLOCK + h * 32;
                let bp = base.as_ptr().add(o);
                let b2 = [_mm512_loadu_ps(bp), _mm512_loadu_ps(bp.add(16))];
                let mut a = [b2; 4];
                for t in 0..t_len {
                    let r = cb.add(t * SCAN_BLOCK + h * 32);
                    let c = [_mm512_loadu_ps(r), _mm512_loadu_ps(r.add(16))];
                    for (p, ap) in a.iter_mut().enumerate() {
                        let nyt = _mm512_set1_ps(*ny[p].get_unchecked(t));
                        for (i, ai) in ap.iter_mut().enumerate() {
                            *ai = _mm512_fmadd_ps(c[i], nyt, *ai);
                        }
                    }
                }
                for i in 0..2 {
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
                    bands[p][b * SCAN_BLOCK / band] = reduce512(m[p], ix[p]);
                    m[p] = _mm512_set1_ps(f32::INFINITY);
                    ix[p] = _mm512_set1_epi32(-1);
                }
            }
        }
    }
}

/// [`scan4_avx512`] with AVX2 + FMA intrinsics (16 nodes at a time: eight
/// accumulators for the four pixels). The same results as four calls of
/// [`scan_avx2`].
///
/// # Safety
/// The caller is compiled for (and runs on a CPU with) AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn scan4_avx2(
    curves: &[f32],
    base: &[f32],
    ny: [&[f32]; 4],
    band: usize,
    bands: [&mut [BandMin]; 4],
) {
    use std::arch::x86_64::*;
    let t_len = ny[0].len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(
        curves.len() >= gp * t_len
            && ny.iter().all(|y| y.len() == t_len)
            && bands.iter().all(|b| b.len() >= gp.div_ceil(band))
            && band.is_multiple_of(SCAN_BLOCK)
    );
    // SAFETY: as in `scan4_avx512`, with AVX2 + FMA.
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The lane reduction picks the smallest value, then the smallest node.
    #[test]
    fn reduce_breaks_ties_by_node() {
        let m = [3.0, 1.0, 1.0, f32::INFINITY];
        let ix = [0, 9, 4, 2];
        assert_eq!(
            reduce(&m, &ix),
            BandMin {
                value: 1.0,
                node: 4
            }
        );
        // Lanes never updated hold +∞ and node u32::MAX: no node.
        let all_inf = [f32::INFINITY; 4];
        assert_eq!(reduce(&all_inf, &[u32::MAX; 4]).node, u32::MAX);
    }
}
