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
