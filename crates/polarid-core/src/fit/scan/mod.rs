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
//!
//! # Kernels
//! [`Scan`] is implemented once per instruction set, each in its own file:
//! `portable.rs` ([`Portable`](crate::fit::simd::Portable), any CPU), `avx2.rs`
//! ([`crate::cpu::Avx2Fma`]) and `avx512.rs` ([`crate::cpu::Avx512`]). The vector
//! kernels are safe functions taking the token that proves the CPU has their
//! instructions (see [`crate::cpu`]); they are `#[inline(always)]`, so that they
//! compile to vector code inside the chunk driver's `#[target_feature]` entry points.

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod portable;
pub(crate) mod prune;

pub(crate) use prune::Groups;

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

/// Unweighted scans of four pixels ([`Scan::scan4`]): pruned ([`Scan::scan4_pruned`])
/// when the plan has `groups` (the whole grid is one band) and the backend a pruned
/// kernel; the same band minima either way.
#[inline(always)]
pub(crate) fn scan4_grid<K: Scan>(
    k: K,
    groups: Option<&Groups>,
    curves: &[f32],
    base: &[f32],
    ny: [&[f32]; 4],
    band: usize,
    bands: [&mut [BandMin]; 4],
) {
    match groups {
        Some(g) if K::PRUNED && band >= base.len() => k.scan4_pruned(g, ny, bands),
        _ => k.scan4(curves, base, ny, band, bands),
    }
}

/// The grid-scan kernels of one instruction set (the backend value is the token of
/// [`crate::cpu`] for the vector ones).
pub(crate) trait Scan: Copy {
    /// Whether the chunk driver should scan unweighted pixels four at a time with
    /// [`Scan::scan4`] (each curve vector loaded once for four pixels).
    const FOUR: bool;

    /// Scan of one pixel: `y` its `T` measurements, `w` its weights (weighted scan) or
    /// `None` (unweighted; `base` must then be `½‖curve‖²`). `bands` receives one
    /// [`BandMin`] per band of `band` nodes.
    fn scan(
        self,
        curves: &[f32],
        base: &[f32],
        y: &[f32],
        w: Option<&[f32]>,
        band: usize,
        bands: &mut [BandMin],
    );

    /// Unweighted scans of four pixels: `ny[p]` the `T` measurements of pixel `p`,
    /// negated; `bands[p]` its band minima. The same results as four calls of
    /// [`Scan::scan`].
    fn scan4(
        self,
        curves: &[f32],
        base: &[f32],
        ny: [&[f32]; 4],
        band: usize,
        bands: [&mut [BandMin]; 4],
    );

    /// Whether [`Scan::scan4_pruned`] is this backend's own kernel (worth running
    /// instead of [`Scan::scan4`]).
    const PRUNED: bool = false;

    /// Pruned unweighted scans of four pixels over the whole grid as one band (see
    /// `prune.rs`): `ny[p]` the `T` measurements of pixel `p`, negated; `bands[p][0]`
    /// receives its best node, the same as [`Scan::scan4`] with one band gives.
    /// Default: the plain-Rust reference with fused multiply-adds, a pixel at a time.
    fn scan4_pruned(self, groups: &Groups, ny: [&[f32]; 4], bands: [&mut [BandMin]; 4]) {
        for (y, b) in ny.into_iter().zip(bands) {
            b[0] = prune::pruned_reference(groups, y);
        }
    }

    /// Scan of one pixel whose node curves are not stored together but come one source
    /// position at a time from separate rows (the fit with a β per pixel, `pixel/`:
    /// row `t` is the column of the pixel's quantised `β_t`): `rows[t]` holds the
    /// DoLP of every coarse node in scan order (at least `base.len()` values, 0 on
    /// padding), `base` is 0 for a node and +∞ for padding. The value of a node is
    /// `Σ_t w_t (c_t − y_t)²`, or `Σ_t (c_t − y_t)²` with `w = None` (the ranking of
    /// the unweighted scans), summed in `t` order with one fused multiply-add per term
    /// (a separate multiply and add in the portable kernel).
    fn scan_rows(
        self,
        rows: &[&[f32]],
        base: &[f32],
        y: &[f32],
        w: Option<&[f32]>,
        band: usize,
        bands: &mut [BandMin],
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::{Isa, cpu_features};
    use crate::fit::simd::Portable;

    /// [`Scan::scan_rows`] with instruction set `isa`.
    fn scan_rows_isa(
        isa: Isa,
        rows: &[&[f32]],
        base: &[f32],
        y: &[f32],
        w: Option<&[f32]>,
        band: usize,
        bands: &mut [BandMin],
    ) {
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => t.scan_rows(rows, base, y, w, band, bands),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma(t) => t.scan_rows(rows, base, y, w, band, bands),
            Isa::Portable => Portable.scan_rows(rows, base, y, w, band, bands),
        }
    }

    /// Every kernel's row scan finds the band minima of a direct computation in the
    /// same arithmetic (fused multiply-adds for the vector kernels, separate for the
    /// portable one), bit for bit, ties to the first node, weighted and unweighted.
    #[test]
    fn row_scans_find_the_band_minima() {
        let gp = 3 * SCAN_BLOCK;
        let gc = gp - 50;
        let t_len = 5;
        let cols: Vec<Vec<f32>> = (0..t_len)
            .map(|t| {
                (0..gp)
                    .map(|c| {
                        if c < gc {
                            // Repeating values: ties between nodes.
                            ((c * 37 + t * 11) % 101) as f32 / 101.0
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        let rows: Vec<&[f32]> = cols.iter().map(|c| c.as_slice()).collect();
        let mut base = vec![f32::INFINITY; gp];
        base[..gc].fill(0.0);
        let y: Vec<f32> = (0..t_len).map(|t| 0.1 + 0.15 * t as f32).collect();
        let wv: Vec<f32> = (0..t_len).map(|t| 1.0 + t as f32).collect();
        for isa in cpu_features().all() {
            let fused = !matches!(isa, Isa::Portable);
            for w in [None, Some(&wv[..])] {
                for band in [SCAN_BLOCK, 2 * SCAN_BLOCK, gp] {
                    let mut bands = vec![BandMin::default(); gp.div_ceil(band)];
                    scan_rows_isa(isa, &rows, &base, &y, w, band, &mut bands);
                    for (bi, got) in bands.iter().enumerate() {
                        let mut want = BandMin::default();
                        for c in bi * band..((bi + 1) * band).min(gc) {
                            let mut v = 0f32;
                            for (t, col) in cols.iter().enumerate() {
                                let d = col[c] - y[t];
                                let wd = w.map_or(d, |w| w[t] * d);
                                v = if fused { wd.mul_add(d, v) } else { v + wd * d };
                            }
                            if v < want.value {
                                want = BandMin {
                                    value: v,
                                    node: c as u32,
                                };
                            }
                        }
                        assert_eq!(*got, want, "{isa:?} band {bi} of {band}");
                    }
                }
            }
        }
    }

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
