//! The `(n, k)` grid of a fit and its scan layout: everything about the global start
//! that depends only on the options, not on the β set. Shared by the [`FitPlan`] of
//! one β set (`plan.rs`) and by the per-pixel-β fit (`pixel/`), whose node curves come
//! from columns of a cache instead.
//!
//! [`FitPlan`]: super::FitPlan

use super::FitOptions;
use super::lanes;
use super::scan::{self, SCAN_BLOCK};
use crate::error::{CoreError, Result};

/// The validated options, the quadratically spaced `(n, k)` grid and the coarse-scan
/// layout (see the module documentation of [`crate::fit`]).
#[derive(Debug, Clone)]
pub(super) struct Grid {
    pub opts: FitOptions,
    /// `n` of the grid columns.
    pub node_n: Vec<f64>,
    /// `k` of the grid rows.
    pub node_k: Vec<f64>,
    /// Grid columns of the coarse scan (every `stride`-th, and the last).
    pub coarse_i: Vec<usize>,
    /// Grid rows of the coarse scan.
    pub coarse_j: Vec<usize>,
    /// Spacing of the coarse nodes in grid steps.
    pub stride: usize,
    /// Padded coarse node count (multiple of [`SCAN_BLOCK`]).
    pub gc_pad: usize,
    /// Nodes per band of the scan: [`scan::BAND`] when competing basins are searched
    /// (`max_candidates > 1`), else the whole grid.
    pub band: usize,
    /// 0 for coarse nodes, +∞ for padding: the start of the weighted scan's sums.
    pub coarse_base: Vec<f32>,
    /// `1 / (n_max − n_min)`, `1 / (k_max − k_min)` (grid cell lookup).
    pub inv_span: (f64, f64),
}

fn warp(lo: f64, hi: f64, m: usize) -> Vec<f64> {
    (0..m)
        .map(|i| {
            let u = i as f64 / (m - 1) as f64;
            lo + (hi - lo) * u * u
        })
        .collect()
}

impl Grid {
    /// Check the options and lay out the grid.
    ///
    /// Errors: an empty or non-finite box, a grid smaller than 4 × 4 or larger than
    /// 2²⁰ nodes, bounds above 1e100, `max_candidates = 0`.
    pub fn new(opts: FitOptions) -> Result<Self> {
        let b = &opts.bounds;
        for (name, v) in [
            ("n_min", b.n_min),
            ("n_max", b.n_max),
            ("k_min", b.k_min),
            ("k_max", b.k_max),
        ] {
            crate::error::ensure_finite(name, v)?;
        }
        if !(b.n_min >= 0.0 && b.n_max > b.n_min) {
            return Err(CoreError::OutOfRange {
                name: "n_max",
                value: b.n_max,
                expected: "n_max > n_min >= 0",
            });
        }
        if !(b.k_min >= 0.0 && b.k_max > b.k_min) {
            return Err(CoreError::OutOfRange {
                name: "k_max",
                value: b.k_max,
                expected: "k_max > k_min >= 0",
            });
        }
        if opts.grid_n < 4 || opts.grid_k < 4 || opts.grid_n * opts.grid_k > 1 << 20 {
            return Err(CoreError::OutOfRange {
                name: "grid size",
                value: (opts.grid_n * opts.grid_k) as f64,
                expected: "at least 4 x 4 and at most 2^20 nodes",
            });
        }
        if !(b.n_max <= lanes::MAX_BOUND && b.k_max <= lanes::MAX_BOUND) {
            return Err(CoreError::OutOfRange {
                name: "n_max/k_max",
                value: b.n_max.max(b.k_max),
                expected: "at most 1e100",
            });
        }
        if opts.max_candidates == 0 {
            return Err(CoreError::OutOfRange {
                name: "max_candidates",
                value: 0.0,
                expected: ">= 1",
            });
        }
        let node_n = warp(b.n_min, b.n_max, opts.grid_n);
        let node_k = warp(b.k_min, b.k_max, opts.grid_k);
        // Coarse scan: every `stride`-th node along each axis, and the last.
        let stride = (opts.grid_n.min(opts.grid_k) / 32).max(1);
        let sub = |m: usize| -> Vec<usize> {
            let mut v: Vec<usize> = (0..m).step_by(stride).collect();
            if v.last() != Some(&(m - 1)) {
                v.push(m - 1);
            }
            v
        };
        let coarse_i = sub(opts.grid_n);
        let coarse_j = sub(opts.grid_k);
        let gc = coarse_i.len() * coarse_j.len();
        let gc_pad = gc.div_ceil(SCAN_BLOCK) * SCAN_BLOCK;
        let mut coarse_base = vec![f32::INFINITY; gc_pad];
        coarse_base[..gc].fill(0.0);
        Ok(Self {
            opts,
            node_n,
            node_k,
            coarse_i,
            coarse_j,
            stride,
            gc_pad,
            band: if opts.max_candidates > 1 {
                scan::BAND
            } else {
                gc_pad
            },
            coarse_base,
            inv_span: (1.0 / (b.n_max - b.n_min), 1.0 / (b.k_max - b.k_min)),
        })
    }

    /// Number of grid nodes.
    pub fn nodes(&self) -> usize {
        self.opts.grid_n * self.opts.grid_k
    }

    /// Number of coarse nodes (without padding).
    pub fn coarse_len(&self) -> usize {
        self.coarse_i.len() * self.coarse_j.len()
    }

    /// The grid node of coarse node `c`.
    #[inline]
    pub fn coarse_node(&self, c: usize) -> usize {
        let cn = self.coarse_i.len();
        self.coarse_j[c / cn] * self.opts.grid_n + self.coarse_i[c % cn]
    }

    /// Number of bands of the scan.
    pub fn bands(&self) -> usize {
        self.gc_pad.div_ceil(self.band)
    }

    /// Grid coordinates of node `g`.
    #[inline]
    pub fn node(&self, g: usize) -> (usize, usize, f64, f64) {
        let i = g % self.opts.grid_n;
        let j = g / self.opts.grid_n;
        (i, j, self.node_n[i], self.node_k[j])
    }

    /// Grid cell (column, row) nearest above `(n, k)`: the first node `≥` the value
    /// along each axis (the last node beyond the box).
    #[inline]
    pub fn cell(&self, n: f64, k: f64) -> (usize, usize) {
        let b = &self.opts.bounds;
        (
            axis_cell_inv(&self.node_n, b.n_min, self.inv_span.0, n),
            axis_cell_inv(&self.node_k, b.k_min, self.inv_span.1, k),
        )
    }
}

/// First index of the quadratically spaced `nodes` (see `warp`) holding a value `≥ x`,
/// at most the last: `nodes.partition_point(|&v| v < x).min(len − 1)`, from the
/// inverse of the spacing and at most a few corrections.
/// `[h00, h01, h11, n, k]` of every grid node: `JᵀJ` of its stored Jacobian (the sums
/// of [`Grid::node_step`] in the same order, so bit for bit the same values; `jac` as
/// `FitPlan` stores it, `2T` values per node) and its `(n, k)`.
pub(super) fn start_nodes(grid: &Grid, jac: &[f32], t_len: usize) -> Vec<[f64; 5]> {
    jac.chunks_exact(2 * t_len)
        .enumerate()
        .map(|(g, row)| {
            let (jn, jk) = row.split_at(t_len);
            let (_, _, n, k) = grid.node(g);
            let mut h = [0.0, 0.0, 0.0, n, k];
            for (&a, &b) in jn.iter().zip(jk) {
                let (a, b) = (a as f64, b as f64);
                h[0] += a * a;
                h[1] += a * b;
                h[2] += b * b;
            }
            h
        })
        .collect()
}

#[cfg(test)]
fn axis_cell(nodes: &[f64], lo: f64, hi: f64, x: f64) -> usize {
    axis_cell_inv(nodes, lo, 1.0 / (hi - lo), x)
}

/// `axis_cell` with the inverse span `1 / (hi − lo)` precomputed (a multiplication
/// instead of a division; the corrections make the result exact either way).
#[inline]
fn axis_cell_inv(nodes: &[f64], lo: f64, inv_span: f64, x: f64) -> usize {
    let m = nodes.len();
    let u = ((x - lo) * inv_span).clamp(0.0, 1.0).sqrt() * (m - 1) as f64;
    let mut i = (u.ceil() as usize).min(m - 1);
    while i > 0 && nodes[i - 1] >= x {
        i -= 1;
    }
    while i < m - 1 && nodes[i] < x {
        i += 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::{axis_cell, warp};

    /// The inverse-spacing lookup equals the binary search it replaces.
    #[test]
    fn axis_cell_matches_partition_point() {
        for &(lo, hi, m) in &[(0.01, 10.0, 32), (0.0, 15.0, 32), (0.5, 2.0, 7)] {
            let nodes = warp(lo, hi, m);
            let mut xs: Vec<f64> = (0..5000)
                .map(|i| lo - 0.1 + (hi - lo + 0.2) * i as f64 / 4999.0)
                .collect();
            xs.extend(nodes.iter().copied());
            xs.extend(nodes.iter().map(|v| v * (1.0 + 1e-15)));
            for x in xs {
                let want = nodes.partition_point(|&v| v < x).min(m - 1);
                assert_eq!(axis_cell(&nodes, lo, hi, x), want, "x = {x}");
            }
        }
    }
}
