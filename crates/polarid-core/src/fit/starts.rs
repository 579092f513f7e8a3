//! The starts of the polishes of one pixel, from the band minima of its grid scan:
//! refinement of a coarse node among its fine-grid neighbours, one Gauss–Newton step
//! with the node's stored Jacobian (no model evaluation), and the competing-basin
//! starts (step 4 of the method in the module documentation of [`crate::fit`]).

use super::engine;
use super::grid::Grid;
use super::lanes;
use super::lm::{self, Eval};
use super::scan;
use super::simd::{Simd, W};
use super::{FitBounds, FitPlan};

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
        gn_step(&ev, n, k, &self.opts.bounds)
    }
}

/// The Gauss–Newton step of [`Grid::node_step`] from `(n, k)` with the normal
/// equations `ev` (`ev.cost`: the cost there): the start point and the cost the
/// step's quadratic model predicts there.
#[inline(always)]
fn gn_step(ev: &Eval, n: f64, k: f64, b: &FitBounds) -> (f64, f64, f64) {
    let cost = ev.cost;
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

/// What the lane starts ([`FitPlan::push_starts`]) need of one pixel: its best node,
/// the node's f32 grid cost and the gradient `Σ_t J_t (curve_t − y_t)` there.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StartSums {
    pixel: usize,
    node: usize,
    cost: f32,
    g0: f64,
    g1: f64,
}

impl FitPlan {
    /// Whether the starts of unweighted pixels are taken in lanes
    /// ([`FitPlan::start_sums`], [`FitPlan::push_starts`]): one start per pixel
    /// (`max_candidates = 1`) from the best node itself (coarse stride 1, nothing to
    /// refine). The same starts as [`Grid::queue`], bit for bit.
    #[inline(always)]
    pub(super) fn lane_starts(&self) -> bool {
        self.grid.stride == 1 && self.grid.opts.max_candidates == 1
    }

    /// The best node of pixel `p` (band minima `bands` of its unweighted scan), its f32
    /// cost `Σ_t (curve_t − y_t)²` (the sums of [`Grid::refine`] in the same order) and
    /// the gradient of [`Grid::node_step`]. `yf`: the pixel's measurements in f32,
    /// negated when `NEG` (the layout of the four-pixel scan); `y`: in f64.
    #[inline(always)]
    pub(super) fn start_sums<const NEG: bool>(
        &self,
        p: usize,
        bands: &[scan::BandMin],
        yf: &[f32],
        y: &[f64],
    ) -> StartSums {
        const L: usize = lanes::LANES;
        let t_len = self.betas.len();
        let best = scan::best_of(bands);
        // Every value +∞ or NaN cannot happen for validated data; node 0 then.
        let c0 = if best.node == u32::MAX {
            0
        } else {
            best.node as usize
        };
        // Coarse stride 1 (`lane_starts`): coarse node `c` is grid node `c`.
        let g = c0;
        let mut sums = StartSums {
            pixel: p,
            node: g,
            ..Default::default()
        };
        let Some((curve, jn, jk)) = self.rows(g) else {
            return sums;
        };
        let (curve, yf, y) = (&curve[..t_len], &yf[..t_len], &y[..t_len]);
        // Lane `l` sums the terms `t ≡ l (mod L)` in order, as the row loop of
        // `refine` does (its padding terms are +0 and change nothing).
        let mut a = [0f32; L];
        let d = |c: f32, v: f32| if NEG { c + v } else { c - v };
        let (cc, cr) = (curve.chunks_exact(L), curve.chunks_exact(L).remainder());
        for (c, v) in cc.zip(yf.chunks_exact(L)) {
            for ((al, &c), &v) in a.iter_mut().zip(c).zip(v) {
                let d = d(c, v);
                *al += d * d;
            }
        }
        for ((al, &c), &v) in a.iter_mut().zip(cr).zip(yf.chunks_exact(L).remainder()) {
            let d = d(c, v);
            *al += d * d;
        }
        sums.cost = (a[0] + a[2]) + (a[1] + a[3]);
        for (((&c, &yt), &jn), &jk) in curve.iter().zip(y).zip(&jn[..t_len]).zip(&jk[..t_len]) {
            let r = c as f64 - yt;
            sums.g0 += jn as f64 * r;
            sums.g1 += jk as f64 * r;
        }
        sums
    }

    /// Queue one polish per pixel of `sums`, [`W`] pixels at a time: the
    /// stored-Jacobian Gauss–Newton step of [`Grid::node_step`] (with the node's `JᵀJ`
    /// precomputed in the plan) in vector lanes, without branches, with the same
    /// arithmetic, so the same starts bit for bit. `spans[p]` receives the job of
    /// pixel `p`.
    #[inline(always)]
    pub(super) fn push_starts<S: Simd>(
        &self,
        s: S,
        sums: &[StartSums],
        jobs: &mut Vec<engine::Job>,
        spans: &mut [(usize, usize)],
    ) {
        let b = &self.grid.opts.bounds;
        let k_floor = if b.k_min == 0.0 { lm::K_FLOOR } else { b.k_min };
        for group in sums.chunks(W) {
            let mut v = [[0.0f64; W]; 7];
            for l in 0..W {
                // Spare lanes repeat the first pixel (results not used).
                let q = group.get(l).unwrap_or(&group[0]);
                let h = self.start_nodes.get(q.node).copied().unwrap_or_default();
                for (dst, x) in v.iter_mut().zip([h[0], h[1], h[2], q.g0, q.g1, h[3], h[4]]) {
                    dst[l] = x;
                }
            }
            let [h00, h01, h11, g0, g1, n, k] = v.map(|x| s.load(&x));
            let (n1, k1) = gn_step_lanes(s, b, [h00, h01, h11], [g0, g1], n, k);
            let (mut n1s, mut k1s) = ([0.0; W], [0.0; W]);
            s.store(n1, &mut n1s);
            s.store(s.max(k1, s.splat(k_floor)), &mut k1s);
            for (l, q) in group.iter().enumerate() {
                let h = self.start_nodes.get(q.node).copied().unwrap_or_default();
                let (nn, kk) = (h[3], h[4]);
                spans[q.pixel] = (jobs.len(), 1);
                jobs.push(engine::Job {
                    pixel: q.pixel,
                    start: (n1s[l], k1s[l]),
                    node: (nn, kk.max(k_floor)),
                    grid_cost: q.cost as f64,
                });
            }
        }
    }
}

/// `x.clamp(lo, hi)` of every lane (`lo ≤ hi`), the same value as `f64::clamp`.
#[inline(always)]
fn clamp_lanes<S: Simd>(s: S, x: S::V, lo: S::V, hi: S::V) -> S::V {
    s.select(s.lt(x, lo), lo, s.select(s.lt(hi, x), hi, x))
}

/// [`Grid::node_step`]'s step (without the predicted cost) for every lane, branch-free
/// and with the same operations in the same order: `h` = `[h00, h01, h11]`, `g` =
/// `[g0, g1]` at the node `(n, k)`; returns the start `(n1, k1)`.
#[inline(always)]
fn gn_step_lanes<S: Simd>(
    s: S,
    b: &FitBounds,
    h: [S::V; 3],
    g: [S::V; 2],
    n: S::V,
    k: S::V,
) -> (S::V, S::V) {
    let [h00, h01, h11] = h;
    let [g0, g1] = g;
    let (zero, neg, two) = (s.splat(0.0), s.splat(-1.0), s.splat(2.0));
    let det = s.sub(s.mul(h00, h11), s.mul(h01, h01));
    let both = s.and(
        s.lt(s.mul(s.mul(s.splat(1e-12), h00), h11), det),
        s.lt(zero, det),
    );
    let dn2 = s.div(s.mul(neg, s.sub(s.mul(h11, g0), s.mul(h01, g1))), det);
    let dk2 = s.div(s.mul(neg, s.sub(s.mul(h00, g1), s.mul(h01, g0))), det);
    let dn1 = s.select(s.lt(zero, h00), s.div(s.mul(neg, g0), h00), zero);
    let dn = s.select(both, dn2, dn1);
    let dk = s.select(both, dk2, zero);
    let (n_min, n_max, k_max) = (s.splat(b.n_min), s.splat(b.n_max), s.splat(b.k_max));
    let k_lo = s.splat(if b.k_min > 0.0 { b.k_min } else { lm::K_FLOOR });
    let in_u = s.lt(k, s.splat(lm::K_U));
    let u = clamp_lanes(s, s.add(s.mul(k, k), dk), zero, s.splat(b.k_max * b.k_max));
    let k_new = s.select(in_u, s.sqrt(u), s.add(k, dk));
    // lm::project(n + dn, k_new)
    let n_p = s.add(n, dn);
    let n_p = if b.n_min == 0.0 { s.abs(n_p) } else { n_p };
    let k_p = if b.k_min == 0.0 { s.abs(k_new) } else { k_new };
    let n_s = clamp_lanes(s, n_p, n_min, n_max);
    let k_s = clamp_lanes(s, k_p, k_lo, k_max);
    // lm::arc_step(n, k, dn, dk, b, both) for k ≥ K_U.
    let ar = s.sub(s.mul(n, n), s.mul(k, k));
    let ai = s.mul(s.mul(two, n), k);
    let (br, bi) = (s.sub(n, dn), s.sub(k, dk));
    let inv = s.div(s.splat(1.0), s.add(s.mul(br, br), s.mul(bi, bi)));
    let na = s.mul(s.add(s.mul(ar, br), s.mul(ai, bi)), inv);
    let ka = s.mul(s.sub(s.mul(ai, br), s.mul(ar, bi)), inv);
    let small = s.lt(
        s.add(s.mul(dn, dn), s.mul(dk, dk)),
        s.mul(
            s.splat(lm::ARC_MAX * lm::ARC_MAX),
            s.add(s.mul(n, n), s.mul(k, k)),
        ),
    );
    let arc = s.and(
        s.and(
            s.and(s.not(in_u), both),
            s.and(s.and(s.lt(n_min, n), s.lt(n, n_max)), s.lt(k, k_max)),
        ),
        s.and(
            small,
            s.and(
                s.and(s.lt(n_min, na), s.lt(na, n_max)),
                s.and(s.lt(k_lo, ka), s.lt(ka, k_max)),
            ),
        ),
    );
    (s.select(arc, na, n_s), s.select(arc, ka, k_s))
}

#[cfg(test)]
mod tests {
    use super::super::simd::{Portable, Simd, W};
    use super::super::{FitBounds, FitOptions, FitPlan};
    use super::engine::Job;
    use super::scan::BandMin;
    use super::{Eval, gn_step, gn_step_lanes, lm};
    use crate::cpu::{Isa, cpu_features};
    use crate::dop::dop;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    fn bits(j: &Job) -> [u64; 5] {
        [
            j.start.0.to_bits(),
            j.start.1.to_bits(),
            j.node.0.to_bits(),
            j.node.1.to_bits(),
            j.grid_cost.to_bits(),
        ]
    }

    /// The lane starts of backend `s` from coarse node `c` (`None`: no node found) of
    /// every pixel of `y`, through both data layouts of `start_sums`.
    fn lane_jobs<S: Simd>(s: S, plan: &FitPlan, y: &[f64], c: Option<u32>) -> Vec<Job> {
        let t_len = plan.len();
        let bands = [BandMin {
            value: 0.0,
            node: c.unwrap_or(u32::MAX),
        }];
        let mut sums = Vec::new();
        for (p, yp) in y.chunks_exact(t_len).enumerate() {
            let yf: Vec<f32> = yp.iter().map(|&v| v as f32).collect();
            let neg: Vec<f32> = yp.iter().map(|&v| -(v as f32)).collect();
            sums.push(if p % 2 == 0 {
                plan.start_sums::<false>(p, &bands, &yf, yp)
            } else {
                plan.start_sums::<true>(p, &bands, &neg, yp)
            });
        }
        let mut jobs = Vec::new();
        let mut spans = vec![(0, 0); sums.len()];
        plan.push_starts(s, &sums, &mut jobs, &mut spans);
        for (p, &(first, count)) in spans.iter().enumerate() {
            assert_eq!((jobs[first].pixel, count), (p, 1));
        }
        jobs
    }

    /// `gn_step_lanes` of backend `s` on [`W`] inputs `(h00, h01, h11, g0, g1, n, k)`.
    fn step_lanes<S: Simd>(s: S, b: &FitBounds, x: &[[f64; 7]]) -> Vec<(f64, f64)> {
        let mut v = [[0.0; W]; 7];
        for (l, x) in x.iter().enumerate() {
            for (d, &x) in v.iter_mut().zip(x) {
                d[l] = x;
            }
        }
        let [h00, h01, h11, g0, g1, n, k] = v.map(|x| s.load(&x));
        let (n1, k1) = gn_step_lanes(s, b, [h00, h01, h11], [g0, g1], n, k);
        let (mut a, mut c) = ([0.0; W], [0.0; W]);
        s.store(n1, &mut a);
        s.store(k1, &mut c);
        a.into_iter().zip(c).collect()
    }

    /// The lane step is the scalar `gn_step` bit for bit on random normal equations:
    /// well conditioned, nearly and exactly singular, `h00 = 0`, at points inside the
    /// box, on its bounds and outside, with steps leaving it, in `k` and in `u = k²`.
    #[test]
    fn lane_step_equals_scalar_step() {
        let mut rng = StdRng::seed_from_u64(3);
        let boxes = [
            FitBounds::default(),
            FitBounds {
                n_min: 0.0,
                n_max: 3.0,
                k_min: 0.0,
                k_max: 4.0,
            },
            FitBounds {
                n_min: 0.5,
                n_max: 2.5,
                k_min: 0.3,
                k_max: 6.0,
            },
        ];
        let mut kinds = [0usize; 4];
        for b in &boxes {
            for _ in 0..400 {
                let x: Vec<[f64; 7]> = (0..W)
                    .map(|l| {
                        let h00: f64 = if l == 0 {
                            0.0
                        } else {
                            rng.random_range(0.0..2.0)
                        };
                        let h11: f64 = rng.random_range(0.0..2.0);
                        let r: f64 = match l % 4 {
                            0 => 1.0,
                            1 => 1.0 - 1e-14,
                            _ => rng.random_range(-1.0..1.0),
                        };
                        let h01 = r * (h00 * h11).sqrt();
                        let sc = 10f64.powi(rng.random_range(-3..2));
                        let (g0, g1) = (
                            sc * rng.random_range(-1.0..1.0),
                            sc * rng.random_range(-1.0..1.0),
                        );
                        let n = match l % 5 {
                            0 => b.n_min,
                            1 => b.n_max,
                            _ => rng.random_range(b.n_min - 0.2..b.n_max + 0.2),
                        };
                        let k = match l % 7 {
                            0 => b.k_min,
                            1 => b.k_max,
                            2 => rng.random_range(0.0..1.0),
                            _ => rng.random_range(b.k_min..b.k_max + 0.2),
                        };
                        [h00, h01, h11, g0, g1, n, k]
                    })
                    .collect();
                let want: Vec<(u64, u64)> = x
                    .iter()
                    .map(|&[h00, h01, h11, g0, g1, n, k]| {
                        let ev = Eval {
                            h00,
                            h01,
                            h11,
                            g0,
                            g1,
                            ..Default::default()
                        };
                        let det = h00 * h11 - h01 * h01;
                        let both = det > 1e-12 * h00 * h11 && det > 0.0;
                        let arc = k >= lm::K_U && lm::arc_step(n, k, 1.0, 1.0, b, true).is_some();
                        kinds[usize::from(both) + 2 * usize::from(arc)] += 1;
                        let (n1, k1, _) = gn_step(&ev, n, k, b);
                        (n1.to_bits(), k1.to_bits())
                    })
                    .collect();
                for isa in cpu_features().all() {
                    let got = match isa {
                        Isa::Portable => step_lanes(Portable, b, &x),
                        #[cfg(target_arch = "x86_64")]
                        Isa::Avx2Fma(t) => step_lanes(t, b, &x),
                        #[cfg(target_arch = "x86_64")]
                        Isa::Avx512(t) => step_lanes(t, b, &x),
                    };
                    let got: Vec<(u64, u64)> =
                        got.iter().map(|p| (p.0.to_bits(), p.1.to_bits())).collect();
                    assert_eq!(got, want, "{b:?} {x:?} {isa:?}");
                }
            }
        }
        assert!(kinds.iter().all(|&c| c > 100), "{kinds:?}");
    }

    /// The lane starts are the scalar starts of `Grid::queue` bit for bit, from every
    /// node of the grid (steps in `k` and in `u = k²`, arc steps, projections onto
    /// every bound, reflections at lower bounds of 0), in every instruction set.
    #[test]
    fn lane_starts_equal_scalar_starts() {
        let boxes = [
            FitBounds::default(),
            FitBounds {
                n_min: 0.0,
                n_max: 3.0,
                k_min: 0.0,
                k_max: 4.0,
            },
            FitBounds {
                n_min: 0.5,
                n_max: 2.5,
                k_min: 0.3,
                k_max: 6.0,
            },
        ];
        let mut rng = StdRng::seed_from_u64(7);
        for (case, bounds) in boxes.into_iter().enumerate() {
            let t_len = 5 + 2 * case;
            let betas: Vec<f64> = (0..t_len)
                .map(|i| (35.0 + 40.0 * i as f64 / (t_len - 1) as f64).to_radians())
                .collect();
            let opts = FitOptions {
                bounds,
                grid_n: 12 + case,
                grid_k: 16,
                ..Default::default()
            };
            let plan = FitPlan::new(&betas, opts).unwrap();
            assert!(plan.lane_starts());
            // 19 pixels: a whole group of lanes and a partial one.
            let y: Vec<f64> = (0..19)
                .flat_map(|_| {
                    let (n, k) = (rng.random_range(0.1..5.0), rng.random_range(0.0..12.0));
                    let e = rng.random_range(-0.05..0.05);
                    betas
                        .iter()
                        .map(move |&b| (dop(n, k, b) + e).clamp(0.0, 1.0))
                        .collect::<Vec<_>>()
                })
                .collect();
            let nodes = (0..plan.grid.coarse_len() as u32).map(Some);
            for c in nodes.chain([None]) {
                let bands = [BandMin {
                    value: 0.0,
                    node: c.unwrap_or(u32::MAX),
                }];
                let (mut yf, mut wf) = (vec![0.0; plan.lanes.len], vec![0.0; plan.lanes.len]);
                let mut want = Vec::new();
                for (p, yp) in y.chunks_exact(t_len).enumerate() {
                    for t in 0..yf.len() {
                        yf[t] = yp.get(t).map_or(0.0, |&v| v as f32);
                        wf[t] = if t < t_len { 1.0 } else { 0.0 };
                    }
                    plan.grid
                        .queue(&plan, p, &bands, yp, None, &yf, &wf, &mut want);
                }
                let want: Vec<_> = want.iter().map(bits).collect();
                for isa in cpu_features().all() {
                    let got = match isa {
                        Isa::Portable => lane_jobs(Portable, &plan, &y, c),
                        #[cfg(target_arch = "x86_64")]
                        Isa::Avx2Fma(t) => lane_jobs(t, &plan, &y, c),
                        #[cfg(target_arch = "x86_64")]
                        Isa::Avx512(t) => lane_jobs(t, &plan, &y, c),
                    };
                    let got: Vec<_> = got.iter().map(bits).collect();
                    assert_eq!(got, want, "box {case}, node {c:?}, {isa:?}");
                }
            }
        }
    }
}
