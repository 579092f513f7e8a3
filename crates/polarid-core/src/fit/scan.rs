//! The coarse grid scan of a fit: the cost of every grid node for one pixel, fused
//! with the search for the best node.
//!
//! Weighted: `acc[c] = Σ_t w_t (curve_c(t) − y_t)²`. Unweighted: `acc[c] = ½‖curve_c‖²
//! − Σ_t curve_c(t) y_t = (cost_c − ‖y‖²)/2`, the same ranking for one multiply-add per
//! node and source position. `base` starts the sums (`½‖curve_c‖²`, or 0; +∞ on
//! padding nodes, whose curves are 0).
//!
//! The node curves are stored in blocks of [`SCAN_BLOCK`] nodes, block-major:
//! `curves[(c / SCAN_BLOCK · T + t) · SCAN_BLOCK + c % SCAN_BLOCK]`, so that one block
//! is one contiguous read; a block is accumulated over all `T` in eight vector
//! registers (AVX-512: the whole block; AVX2: half of it at a time) and stored once.
//! Every kernel adds in the same order, so all give the same `acc` (f32; the FMA
//! kernels round once per multiply-add).

/// Nodes per block of the scan's curve layout.
pub(crate) const SCAN_BLOCK: usize = 128;

/// Lanes of the running minimum (positions `≡ l (mod 16)`).
const L: usize = 16;

/// Scan with the portable kernel (`FMA`: `mul_add` is a hardware instruction).
#[inline(always)]
pub(crate) fn scan_portable<const FMA: bool>(
    curves: &[f32],
    base: &[f32],
    y: &[f32],
    w: Option<&[f32]>,
    acc: &mut [f32],
) -> (usize, f32) {
    const BL: usize = 32;
    let t_len = y.len();
    let mut m = [f32::INFINITY; L];
    let gp = base.len();
    let acc = &mut acc[..gp];
    for (b, out) in acc.chunks_exact_mut(SCAN_BLOCK).enumerate() {
        let blk = &curves[b * SCAN_BLOCK * t_len..(b + 1) * SCAN_BLOCK * t_len];
        for h in 0..SCAN_BLOCK / BL {
            let o = h * BL;
            let mut a = [0f32; BL];
            a.copy_from_slice(&base[b * SCAN_BLOCK + o..b * SCAN_BLOCK + o + BL]);
            for t in 0..t_len {
                let row = &blk[t * SCAN_BLOCK + o..t * SCAN_BLOCK + o + BL];
                let yt = y[t];
                match w {
                    Some(w) => {
                        let wt = w[t];
                        for l in 0..BL {
                            let d = row[l] - yt;
                            let wd = wt * d;
                            a[l] = if FMA { wd.mul_add(d, a[l]) } else { a[l] + wd * d };
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
            out[o..o + BL].copy_from_slice(&a);
            for q in a.chunks_exact(L) {
                for l in 0..L {
                    m[l] = if q[l] < m[l] { q[l] } else { m[l] };
                }
            }
        }
    }
    find(acc, &m)
}

/// Scan with AVX2 + FMA intrinsics.
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
    acc: &mut [f32],
) -> (usize, f32) {
    use std::arch::x86_64::*;
    let t_len = y.len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(
        acc.len() >= gp && curves.len() >= gp * t_len && w.is_none_or(|w| w.len() >= t_len)
    );
    // SAFETY: every pointer below stays inside `curves[..gp·T]`, `base[..gp]` and
    // `acc[..gp]` (asserted); the CPU has AVX2 + FMA (caller's contract).
    unsafe {
        let mut m_lo = _mm256_set1_ps(f32::INFINITY);
        let mut m_hi = m_lo;
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
                let op = acc.as_mut_ptr().add(o);
                for (i, ai) in a.iter().enumerate() {
                    _mm256_storeu_ps(op.add(8 * i), *ai);
                }
                // Positions o + 8i + l: i even → residues 0..7, i odd → 8..15.
                m_lo = _mm256_min_ps(
                    m_lo,
                    _mm256_min_ps(_mm256_min_ps(a[0], a[2]), _mm256_min_ps(a[4], a[6])),
                );
                m_hi = _mm256_min_ps(
                    m_hi,
                    _mm256_min_ps(_mm256_min_ps(a[1], a[3]), _mm256_min_ps(a[5], a[7])),
                );
            }
        }
        let mut m = [0f32; L];
        _mm256_storeu_ps(m.as_mut_ptr(), m_lo);
        _mm256_storeu_ps(m.as_mut_ptr().add(8), m_hi);
        find(&acc[..gp], &m)
    }
}

/// Scan with AVX-512F intrinsics.
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
    acc: &mut [f32],
) -> (usize, f32) {
    use std::arch::x86_64::*;
    let t_len = y.len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(
        acc.len() >= gp && curves.len() >= gp * t_len && w.is_none_or(|w| w.len() >= t_len)
    );
    // SAFETY: as in `scan_avx2`, with AVX-512F.
    unsafe {
        let mut mv = _mm512_set1_ps(f32::INFINITY);
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
            let op = acc.as_mut_ptr().add(o);
            for (i, ai) in a.iter().enumerate() {
                _mm512_storeu_ps(op.add(16 * i), *ai);
            }
            let m01 = _mm512_min_ps(a[0], a[1]);
            let m23 = _mm512_min_ps(a[2], a[3]);
            let m45 = _mm512_min_ps(a[4], a[5]);
            let m67 = _mm512_min_ps(a[6], a[7]);
            mv = _mm512_min_ps(
                mv,
                _mm512_min_ps(_mm512_min_ps(m01, m23), _mm512_min_ps(m45, m67)),
            );
        }
        let mut m = [0f32; L];
        _mm512_storeu_ps(m.as_mut_ptr(), mv);
        find(&acc[..gp], &m)
    }
}

/// Unweighted scans of four pixels at once: every curve vector loaded from memory
/// serves the four (the block of curves is read once per four pixels instead of once
/// per pixel). `y[p]`: the `T` measurements of pixel `p`; `acc[p]`: its `acc`. Gives
/// exactly the results of four calls of [`scan_avx512`] (same operations, same order).
///
/// # Safety
/// The caller is compiled for (and runs on a CPU with) AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn scan4_avx512(
    curves: &[f32],
    base: &[f32],
    y: [&[f32]; 4],
    acc: &mut [f32],
) -> [(usize, f32); 4] {
    use std::arch::x86_64::*;
    let t_len = y[0].len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(acc.len() >= 4 * gp && curves.len() >= gp * t_len && y.iter().all(|y| y.len() == t_len));
    // SAFETY: pointers stay inside `curves[..gp·T]`, `base[..gp]`, `acc[..4·gp]`
    // (asserted); the CPU has AVX-512F (caller's contract).
    unsafe {
        let mut mv = [_mm512_set1_ps(f32::INFINITY); 4];
        for b in 0..nb {
            let cb = curves.as_ptr().add(b * SCAN_BLOCK * t_len);
            for h in 0..SCAN_BLOCK / 64 {
                let o = b * SCAN_BLOCK + h * 64;
                let bp = base.as_ptr().add(o);
                let b4 = [
                    _mm512_loadu_ps(bp),
                    _mm512_loadu_ps(bp.add(16)),
                    _mm512_loadu_ps(bp.add(32)),
                    _mm512_loadu_ps(bp.add(48)),
                ];
                let mut a = [b4; 4];
                for t in 0..t_len {
                    let r = cb.add(t * SCAN_BLOCK + h * 64);
                    let c = [
                        _mm512_loadu_ps(r),
                        _mm512_loadu_ps(r.add(16)),
                        _mm512_loadu_ps(r.add(32)),
                        _mm512_loadu_ps(r.add(48)),
                    ];
                    for (p, ap) in a.iter_mut().enumerate() {
                        let ny = _mm512_set1_ps(-*y[p].get_unchecked(t));
                        for (i, ai) in ap.iter_mut().enumerate() {
                            *ai = _mm512_fmadd_ps(c[i], ny, *ai);
                        }
                    }
                }
                for (p, ap) in a.iter().enumerate() {
                    let op = acc.as_mut_ptr().add(p * gp + o);
                    for (i, ai) in ap.iter().enumerate() {
                        _mm512_storeu_ps(op.add(16 * i), *ai);
                    }
                    mv[p] = _mm512_min_ps(
                        mv[p],
                        _mm512_min_ps(_mm512_min_ps(ap[0], ap[1]), _mm512_min_ps(ap[2], ap[3])),
                    );
                }
            }
        }
        let mut out = [(0usize, 0f32); 4];
        for p in 0..4 {
            let mut m = [0f32; L];
            _mm512_storeu_ps(m.as_mut_ptr(), mv[p]);
            out[p] = find(&acc[p * gp..(p + 1) * gp], &m);
        }
        out
    }
}

/// [`scan4_avx512`] with AVX2 + FMA intrinsics (16 nodes at a time: 8 accumulators
/// for the four pixels). Exactly the results of four calls of [`scan_avx2`].
///
/// # Safety
/// The caller is compiled for (and runs on a CPU with) AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn scan4_avx2(
    curves: &[f32],
    base: &[f32],
    y: [&[f32]; 4],
    acc: &mut [f32],
) -> [(usize, f32); 4] {
    use std::arch::x86_64::*;
    let t_len = y[0].len();
    let gp = base.len();
    let nb = gp / SCAN_BLOCK;
    assert!(acc.len() >= 4 * gp && curves.len() >= gp * t_len && y.iter().all(|y| y.len() == t_len));
    // SAFETY: as in `scan4_avx512`, with AVX2 + FMA.
    unsafe {
        let mut m_lo = [_mm256_set1_ps(f32::INFINITY); 4];
        let mut m_hi = m_lo;
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
                        let ny = _mm256_set1_ps(-*y[p].get_unchecked(t));
                        ap[0] = _mm256_fmadd_ps(c[0], ny, ap[0]);
                        ap[1] = _mm256_fmadd_ps(c[1], ny, ap[1]);
                    }
                }
                for (p, ap) in a.iter().enumerate() {
                    let op = acc.as_mut_ptr().add(p * gp + o);
                    _mm256_storeu_ps(op, ap[0]);
                    _mm256_storeu_ps(op.add(8), ap[1]);
                    m_lo[p] = _mm256_min_ps(m_lo[p], ap[0]);
                    m_hi[p] = _mm256_min_ps(m_hi[p], ap[1]);
                }
            }
        }
        let mut out = [(0usize, 0f32); 4];
        for p in 0..4 {
            let mut m = [0f32; L];
            _mm256_storeu_ps(m.as_mut_ptr(), m_lo[p]);
            _mm256_storeu_ps(m.as_mut_ptr().add(8), m_hi[p]);
            out[p] = find(&acc[p * gp..(p + 1) * gp], &m);
        }
        out
    }
}

/// Position of the smallest of the lane minima `m` in `acc` (`m[l]` is the minimum
/// over the positions `≡ l (mod 16)`): only that residue class is searched. Returns
/// `(0, +∞)` when every value is +∞ (or NaN).
#[inline(always)]
pub(crate) fn find(acc: &[f32], m: &[f32; L]) -> (usize, f32) {
    let (mut lb, mut mv) = (0, f32::INFINITY);
    for (l, &v) in m.iter().enumerate() {
        if v < mv {
            (lb, mv) = (l, v);
        }
    }
    if !mv.is_finite() {
        return (0, f32::INFINITY);
    }
    // A plain counted loop over the residue class (`step_by` costs several times as
    // many instructions per element here).
    let col = &acc[lb..];
    let mut i = 0;
    while i < col.len() {
        if col[i] == mv {
            return (lb + i, mv);
        }
        i += L;
    }
    (0, f32::INFINITY)
}
