//! The starts of the polishes of one pixel, from the band minima of its grid scan:
//! refinement of a coarse node among its fine-grid neighbours, one Gauss–Newton step
//! with the node's stored Jacobian (no model evaluation), and the competing-basin
//! starts (step 4 of the method in the module documentation of [`crate::fit`]).

use super::FitPlan;
use super::engine;
use super::grid::Grid;
use super::lanes;
use super::lm::{self, Eval};
use super::scan;

/// The node curves and Jacobians of the β set of one fit: a [`FitPlan`]'s, or those of
/// one pixel's β gathered from the columns of the per-pixel fit (`pixel/`).
pub(super) trait Nodes {
    /// Number of measurements `T`.
    fn t_len(&self) -> usize;
    /// `T` padded to whole [`lanes::LANES`].
    fn t_pad(&self) -> usize;
    /// DoLP of grid node `g` at position `t < t_pad()` (0 on padding).
    fn curve(&self, g: usize, t: usize) -> f32;
    /// Jacobian of grid node `g` at position `t < t_len()`: `∂P/∂n` and `∂P/∂k` (or
    /// `∂P/∂u` below [`lm::K_U`]).
    fn jac(&self, g: usize, t: usize) -> (f32, f32);
    /// Node `g`'s curve (`t_pad()` values, 0 on padding) and Jacobian rows (`∂P/∂n`,
    /// `∂P/∂k` or `∂P/∂u`, `t_len()` values each) as contiguous slices, when stored
    /// so (the same values as [`Nodes::curve`] and [`Nodes::jac`]).
    #[inline(always)]
    fn rows(&self, _g: usize) -> Option<(&[f32], &[f32], &[f32])> {
        None
    }
}

impl Nodes for FitPlan {
    #[inline(always)]
    fn t_len(&self) -> usize {
        self.betas.len()
    }
    #[inline(always)]
    fn t_pad(&self) -> usize {
        self.lanes.len
    }
    #[inline(always)]
    fn curve(&self, g: usize, t: usize) -> f32 {
        self.node_curves[g * self.lanes.len + t]
    }
    #[inline(always)]
    fn jac(&self, g: usize, t: usize) -> (f32, f32) {
        let t_len = self.betas.len();
        (
            self.jac[g * 2 * t_len + t],
            self.jac[g * 2 * t_len + t_len + t],
        )
    }
    #[inline(always)]
    fn rows(&self, g: usize) -> Option<(&[f32], &[f32], &[f32])> {
        let (t_len, tp) = (self.betas.len(), self.lanes.len);
        let curve = self.node_curves.get(g * tp..(g + 1) * tp)?;
        let jac = self.jac.get(g * 2 * t_len..(g + 1) * 2 * t_len)?;
        let (jn, jk) = jac.split_at(t_len);
        Some((curve, jn, jk))
    }
}

impl Grid {
    /// Queue the polishes of pixel `p` from the band minima of its scan: the best
    /// node's, then (with
    /// [`FitOptions::max_candidates`](super::FitOptions::max_candidates) > 1) those of
    /// competing basins: the best nodes of other bands (other `k` ranges) that are not
    /// next to the best node, whose stored-Jacobian Gauss–Newton step stays near them
    /// (a minimum, not a slope into another basin), does not land in the best node's
    /// basin, and predicts a cost within 10% of the best node's prediction.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn queue<N: Nodes>(
        &self,
        nodes: &N,
        p: usize,
        bands: &[scan::BandMin],
        y: &[f64],
        w: Option<&[f64]>,
        yf: &[f32],
        wf: &[f32],
        jobs: &mut Vec<engine::Job>,
    ) {
        let best = scan::best_of(bands);
        // Every value +∞ or NaN cannot happen for validated data; node 0 then.
        let c0 = if best.node == u32::MAX {
            0
        } else {
            best.node as usize
        };
        let (g0, cost0) = self.refine(nodes, c0, yf, wf);
        let (job0, pred0) = self.job(nodes, p, g0, cost0, y, w);
        jobs.push(job0);
        if self.opts.max_candidates < 2 {
            return;
        }
        let land0 = self.cell(job0.start.0, job0.start.1);
        let cn = self.coarse_i.len();
        let (i0, j0) = (c0 % cn, c0 / cn);
        let mut extra = 0;
        for bm in bands {
            if bm.node == u32::MAX || bm.node == best.node {
                continue;
            }
            let c = bm.node as usize;
            if (c % cn).abs_diff(i0) <= 2 && (c / cn).abs_diff(j0) <= 2 {
                continue;
            }
            let (g, cost) = self.refine(nodes, c, yf, wf);
            let (job, pred) = self.job(nodes, p, g, cost, y, w);
            if pred > pred0 * 1.1 + 1e-12 {
                continue;
            }
            let (i, j, _, _) = self.node(g);
            let (i1, j1) = self.cell(job.start.0, job.start.1);
            if i1.abs_diff(i) > 2 || j1.abs_diff(j) > 2 {
                continue;
            }
            if i1.abs_diff(land0.0) <= 2 && j1.abs_diff(land0.1) <= 2 {
                continue;
            }
            jobs.push(job);
            extra += 1;
            if extra + 1 >= self.opts.max_candidates {
                break;
            }
        }
    }

    /// The polish job of pixel `p` from grid node `g` (grid cost `cost`): one
    /// stored-Jacobian Gauss–Newton step gives the start; also the cost that step's
    /// quadratic model predicts.
    #[inline(always)]
    fn job<N: Nodes>(
        &self,
        nodes: &N,
        p: usize,
        g: usize,
        cost: f32,
        y: &[f64],
        w: Option<&[f64]>,
    ) -> (engine::Job, f64) {
        let b = &self.opts.bounds;
        let k_floor = if b.k_min == 0.0 { lm::K_FLOOR } else { b.k_min };
        let (n1, k1, pred) = self.node_step(nodes, g, cost as f64, y, w);
        let (_, _, nn, kk) = self.node(g);
        (
            engine::Job {
                pixel: p,
                start: (n1, k1.max(k_floor)),
                node: (nn, kk.max(k_floor)),
                grid_cost: cost as f64,
            },
            pred,
        )
    }

    /// The best grid node within `stride − 1` grid steps of coarse node `c` (at least
    /// the coarse node itself), and its cost `Σ_t w_t (curve_g(t) − y_t)²` in f32.
    #[inline(always)]
    fn refine<N: Nodes>(&self, nodes: &N, c: usize, yf: &[f32], wf: &[f32]) -> (usize, f32) {
        const L: usize = lanes::LANES;
        let tp = nodes.t_pad();
        let cn = self.coarse_i.len();
        let (ic, jc) = (self.coarse_i[c % cn], self.coarse_j[c / cn]);
        let h = self.stride.saturating_sub(1);
        let (gn, gk) = (self.opts.grid_n, self.opts.grid_k);
        let (yf, wf) = (&yf[..tp], &wf[..tp]);
        let mut best = (jc * gn + ic, f32::INFINITY);
        for j in jc.saturating_sub(h)..(jc + h + 1).min(gk) {
            for i in ic.saturating_sub(h)..(ic + h + 1).min(gn) {
                let g = j * gn + i;
                let mut a = [0f32; L];
                match nodes.rows(g) {
                    // The same sums from the contiguous row.
                    Some((curve, _, _)) => {
                        for ((c, y), w) in curve[..tp]
                            .chunks_exact(L)
                            .zip(yf.chunks_exact(L))
                            .zip(wf.chunks_exact(L))
                        {
                            for (((al, &c), &y), &w) in a.iter_mut().zip(c).zip(y).zip(w) {
                                let d = c - y;
                                *al += w * d * d;
                            }
                        }
                    }
                    None => {
                        for ch in 0..tp / L {
                            for l in 0..L {
                                let t = ch * L + l;
                                let d = nodes.curve(g, t) - yf[t];
                                a[l] += wf[t] * d * d;
                            }
                        }
                    }
                }
                let v = (a[0] + a[2]) + (a[1] + a[3]);
                if v < best.1 {
                    best = (g, v);
                }
            }
        }
        best
    }

    /// One Gauss–Newton step from node `g` with its stored Jacobian: the start point
    /// and the cost its quadratic model predicts there.
    #[inline(always)]
    fn node_step<N: Nodes>(
        &self,
        nodes: &N,
        g: usize,
        cost: f64,
        y: &[f64],
        w: Option<&[f64]>,
    ) -> (f64, f64, f64) {
        let t_len = nodes.t_len();
        let (_, _, n, k) = self.node(g);
        let mut ev = Eval {
            cost,
            ..Default::default()
        };
        match w {
            // The same sums with w_t = 1 (bitwise: 1·x = x).
            None if nodes.rows(g).is_some() => {
                // The same sums from the contiguous rows.
                if let Some((curve, jn, jk)) = nodes.rows(g) {
                    for (((&c, &yt), &jn), &jk) in curve[..t_len]
                        .iter()
                        .zip(&y[..t_len])
                        .zip(&jn[..t_len])
                        .zip(&jk[..t_len])
                    {
                        let r = c as f64 - yt;
                        let (a, b) = (jn as f64, jk as f64);
                        ev.h00 += a * a;
                        ev.h01 += a * b;
                        ev.h11 += b * b;
                        ev.g0 += a * r;
                        ev.g1 += b * r;
                    }
                }
            }
            None => {
                for (t, &yt) in y[..t_len].iter().enumerate() {
                    let r = nodes.curve(g, t) as f64 - yt;
                    let (jn, jk) = nodes.jac(g, t);
                    let (a, b) = (jn as f64, jk as f64);
                    ev.h00 += a * a;
                    ev.h01 += a * b;
                    ev.h11 += b * b;
                    ev.g0 += a * r;
                    ev.g1 += b * r;
                }
            }
            Some(w) => {
                for t in 0..t_len {
                    let r = nodes.curve(g, t) as f64 - y[t];
                    let wt = w[t];
                    let (jn, jk) = nodes.jac(g, t);
                    let (a, b) = (jn as f64, jk as f64);
                    ev.h00 += wt * a * a;
                    ev.h01 += wt * a * b;
                    ev.h11 += wt * b * b;
                    ev.g0 += wt * a * r;
                    ev.g1 += wt * b * r;
                }
            }
        }
        let det = ev.h00 * ev.h11 - ev.h01 * ev.h01;
        let (dn, dk) = if det > 1e-12 * ev.h00 * ev.h11 && det > 0.0 {
            (
                -(ev.h11 * ev.g0 - ev.h01 * ev.g1) / det,
                -(ev.h00 * ev.g1 - ev.h01 * ev.g0) / det,
            )
        } else if ev.h00 > 0.0 {
            (-ev.g0 / ev.h00, 0.0)
        } else {
            (0.0, 0.0)
        };
        let pred = (cost + dn * ev.g0 + dk * ev.g1).max(0.0);
        let b = &self.opts.bounds;
        let k_new = if k < lm::K_U {
            (k * k + dk).clamp(0.0, b.k_max * b.k_max).sqrt()
        } else {
            k + dk
        };
        let both = det > 1e-12 * ev.h00 * ev.h11 && det > 0.0;
        let arc = if k < lm::K_U {
            None
        } else {
            lm::arc_step(n, k, dn, dk, b, both)
        };
        let (n1, k1) = arc.unwrap_or_else(|| lm::project(n + dn, k_new, b));
        (n1, k1, pred)
    }
}
