//! The column cache of the fit with a β per pixel: for a quantised angle
//! `β_q = q·Δ`, the DoLP and Jacobian of every grid node (a column of a [`FitPlan`]'s
//! node tables, at one angle), built once and shared by every pixel whose `β_t`
//! rounds to `β_q`.
//!
//! A column costs one evaluation of eq. (9) and its gradient per grid node (~30 µs at
//! the default 32 × 32 grid) and `16 · G` bytes (16 kB). The cache is bounded: after a
//! batch, when it holds more than [`MAX_BYTES`], the columns that batch did not use are
//! dropped. A batch holds its own references to its columns ([`ColumnView`]), so a
//! concurrent batch may evict them from the cache without affecting it.
//!
//! [`FitPlan`]: crate::fit::FitPlan

use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use super::super::grid::Grid;
use super::super::plan::node_values;
use crate::dop::BetaTerms;

/// Cache size above which unused columns are dropped after a batch, bytes.
pub(super) const MAX_BYTES: usize = 64 << 20;

/// The node tables of one quantised angle.
#[derive(Debug)]
pub(super) struct Column {
    /// DoLP of the coarse nodes in scan order, padded with 0 to the padded coarse node
    /// count: the row of the scan.
    coarse: Vec<f32>,
    /// DoLP, `∂P/∂n` and `∂P/∂k` (`∂P/∂u`, `u = k²`, below `k = 1`) of grid node
    /// `g = j · grid_n + i`, together: the refinement and the start of a pixel read one
    /// node of each of its columns.
    pub nodes: Vec<[f32; 3]>,
}

impl Column {
    /// The tables of `grid` at `beta` (radians).
    fn new(grid: &Grid, beta: f64) -> Self {
        let bt = BetaTerms::new(beta);
        let mut nodes = vec![[0f32; 3]; grid.nodes()];
        for (j, &k) in grid.node_k.iter().enumerate() {
            for (i, &n) in grid.node_n.iter().enumerate() {
                let (p, jn, j2) = node_values(n, k, &bt);
                nodes[j * grid.opts.grid_n + i] = [p, jn, j2];
            }
        }
        let mut coarse = vec![0f32; grid.gc_pad];
        for (c, v) in coarse.iter_mut().enumerate().take(grid.coarse_len()) {
            *v = nodes[grid.coarse_node(c)][0];
        }
        Self { coarse, nodes }
    }

    /// The coarse-node row of the scan (padded coarse node count, 0 on padding).
    #[inline(always)]
    pub fn coarse(&self) -> &[f32] {
        &self.coarse
    }

    fn bytes(&self) -> usize {
        4 * (self.coarse.len() + 3 * self.nodes.len())
    }
}

/// The columns one batch uses: `cols[q]` for every quantised angle `q` it needs.
pub(super) type ColumnView = Vec<Option<Arc<Column>>>;

/// The bounded cache of columns, indexed by the quantised angle.
#[derive(Debug, Default)]
pub(super) struct ColumnCache {
    cols: Mutex<Vec<Option<Arc<Column>>>>,
}

impl ColumnCache {
    /// The columns `needed[q]` of a batch, built (in parallel) where missing, with
    /// `beta(q)` the angle of column `q`.
    pub fn view(
        &self,
        grid: &Grid,
        needed: &[bool],
        beta: impl Fn(usize) -> f64 + Sync,
    ) -> ColumnView {
        let lock = || self.cols.lock().unwrap_or_else(|e| e.into_inner());
        let mut view: ColumnView = vec![None; needed.len()];
        let mut missing = Vec::new();
        {
            let cols = lock();
            for (q, &need) in needed.iter().enumerate() {
                if need {
                    match cols.get(q).and_then(Option::as_ref) {
                        Some(c) => view[q] = Some(Arc::clone(c)),
                        None => missing.push(q),
                    }
                }
            }
        }
        let built: Vec<(usize, Arc<Column>)> = missing
            .par_iter()
            .map(|&q| (q, Arc::new(Column::new(grid, beta(q)))))
            .collect();
        let mut cols = lock();
        if cols.len() < needed.len() {
            cols.resize(needed.len(), None);
        }
        for (q, c) in built {
            cols[q].get_or_insert_with(|| Arc::clone(&c));
            view[q] = Some(c);
        }
        let bytes: usize = cols.iter().flatten().map(|c| c.bytes()).sum();
        if bytes > MAX_BYTES {
            for (q, c) in cols.iter_mut().enumerate() {
                if !needed.get(q).copied().unwrap_or(false) {
                    *c = None;
                }
            }
        }
        view
    }

    /// Number of cached columns.
    pub fn len(&self) -> usize {
        self.cols
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .flatten()
            .count()
    }
}
