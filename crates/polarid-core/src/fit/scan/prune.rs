//! The unweighted grid scan of one pixel with pruning: the same best node as the full
//! scan, bit for bit, for a fraction of the work.
//!
//! The coarse nodes are grouped in clusters of [`CLUSTER`] (tiles of 4 × 4 neighbouring
//! nodes of the `(n, k)` grid), each with a centroid curve `m` and a radius
//! `R ≥ max_c ‖c − m‖` over its node curves `c` (computed once per plan). For a pixel
//! with measurements `y`, a node's scan value is `V_c = ½‖c‖² − c·y = ½‖c − y‖² − ½‖y‖²`
//! (see the module documentation of `scan`), so by the triangle inequality every node
//! of a cluster has
//!
//! ```text
//! V_c ≥ ½ max(0, ‖y − m‖ − R)² − ½‖y‖²        (the cluster's lower bound)
//! ```
//!
//! with `‖y − m‖² = 2 V_m + ‖y‖²` from the centroid's own scan value `V_m`. The scan
//! computes the centroid values (one multiply-add per centroid and position), scores
//! the cluster with the nearest centroid node by node, then every other cluster whose bound
//! does not exceed the best value found so far by more than a rounding margin. A
//! skipped cluster cannot hold the best node: the margin covers the f32 rounding of
//! every value involved (`δ` below), so the nodes that are scored get exactly the
//! values of the full scan (the same multiply-adds in the same order, from the same
//! `½‖c‖²`) and the best of them — the smallest value, then the smallest node — is the
//! full scan's best node with its value.
//!
//! On the benchmark problem (`T = 10`, the default 32 × 32 grid) a pixel scores 64
//! centroids and about 11.5 of the 64 clusters instead of 1024 nodes.

use super::{BandMin, Scan};

/// Nodes per cluster (one f32x16 vector, two f32x8).
pub(crate) const CLUSTER: usize = 16;

/// Side of a cluster's tile of coarse nodes (`TILE × TILE = CLUSTER`).
const TILE: usize = 4;

/// The clusters of a plan's coarse nodes (see the module documentation).
#[derive(Debug, Clone, Default)]
pub(crate) struct Clusters {
    /// Number of clusters.
    q: usize,
    /// Measurements per pixel.
    t_len: usize,
    /// Centroid curves, in blocks of [`CLUSTER`] centroids:
    /// `cen[(q / CLUSTER · T + t) · CLUSTER + q % CLUSTER]` (padding: 0).
    cen: Vec<f32>,
    /// `½‖m‖²` of every centroid (padding: +∞).
    cen_half: Vec<f32>,
    /// Radius of every cluster, rounded up (padding: 0).
    radius: Vec<f32>,
    /// Node curves of cluster `q`: `curves[(q · T + t) · CLUSTER + i]` (padding: 0).
    curves: Vec<f32>,
    /// `½‖c‖²` of every node slot, the full scan's f32 value (padding: +∞).
    half: Vec<f32>,
    /// Coarse node of every slot (padding: `u32::MAX`).
    node: Vec<u32>,
    /// Bound on the f32 rounding error of one scan value, `δ`.
    delta: f32,
}

impl Clusters {
    /// The clusters of a coarse grid of `cn × ck` nodes (coarse node `c` at column
    /// `c % cn`, row `c / cn`) whose curves are `curve(c, t)` (DoLP in [0, 1]) and
    /// whose scan base is `half[c] = ½‖c‖²` (f32, as the full scan uses it).
    pub fn new(
        cn: usize,
        ck: usize,
        t_len: usize,
        curve: impl Fn(usize, usize) -> f32,
        half: &[f32],
    ) -> Self {
        let (qi, qj) = (cn.div_ceil(TILE), ck.div_ceil(TILE));
        let q = qi * qj;
        let q_pad = q.div_ceil(CLUSTER) * CLUSTER;
        let mut cl = Self {
            q,
            t_len,
            cen: vec![0.0; q_pad * t_len],
            cen_half: vec![f32::INFINITY; q_pad],
            radius: vec![0.0; q_pad],
            curves: vec![0.0; q * t_len * CLUSTER],
            half: vec![f32::INFINITY; q * CLUSTER],
            node: vec![u32::MAX; q * CLUSTER],
            // Each value is at most (T + 1) roundings of sums bounded by ½T + T (curves
            // and measurements in [0, 1]): (T + 1)·1.5T·2⁻²⁴, here with a factor 4 to
            // spare and the rounding of ½‖c‖² to f32 included.
            delta: ((t_len as f64 + 2.0) * 1.5 * t_len as f64 * 2f64.powi(-22)) as f32,
        };
        let mut members = Vec::with_capacity(CLUSTER);
        for bj in 0..qj {
            for bi in 0..qi {
                let qq = bj * qi + bi;
                members.clear();
                for j in bj * TILE..((bj + 1) * TILE).min(ck) {
                    for i in bi * TILE..((bi + 1) * TILE).min(cn) {
                        members.push(j * cn + i);
                    }
                }
                let mut mean = vec![0f64; t_len];
                for (s, &c) in members.iter().enumerate() {
                    cl.node[qq * CLUSTER + s] = c as u32;
                    cl.half[qq * CLUSTER + s] = half[c];
                    for (t, m) in mean.iter_mut().enumerate() {
                        let v = curve(c, t);
                        cl.curves[(qq * t_len + t) * CLUSTER + s] = v;
                        *m += f64::from(v);
                    }
                }
                let m32: Vec<f32> = mean
                    .iter()
                    .map(|&m| (m / members.len() as f64) as f32)
                    .collect();
                let mut r2 = 0f64;
                for &c in &members {
                    let d2: f64 = (0..t_len)
                        .map(|t| (f64::from(curve(c, t)) - f64::from(m32[t])).powi(2))
                        .sum();
                    r2 = r2.max(d2);
                }
                let r = r2.sqrt() * (1.0 + 1e-6) + 1e-7;
                cl.radius[qq] = next_up(r as f32);
                let mut hn = 0f64;
                for (t, &m) in m32.iter().enumerate() {
                    cl.cen[(qq / CLUSTER * t_len + t) * CLUSTER + qq % CLUSTER] = m;
                    hn += f64::from(m).powi(2);
                }
                cl.cen_half[qq] = (0.5 * hn) as f32;
            }
        }
        cl
    }
}

/// The smallest f32 above `x` (finite, `x ≥ 0`).
fn next_up(x: f32) -> f32 {
    f32::from_bits(x.to_bits() + 1)
}

/// The best node of the unweighted scan of one pixel (`ny`: its `T` measurements as
/// f32, negated), the same [`BandMin`] as the full scan of the whole grid as one band.
/// `lb`: scratch memory.
#[inline(always)]
pub(crate) fn pruned_scan<K: Scan>(k: K, cl: &Clusters, ny: &[f32], lb: &mut Vec<f32>) -> BandMin {
    let t_len = cl.t_len;
    let ny = &ny[..t_len];
    let mut yy = 0f32;
    for &v in ny {
        yy += v * v;
    }
    let delta = cl.delta;
    let margin = 4.0 * delta + 1e-4;
    let s0 = yy - 3.0 * delta;
    // Lower bounds of every cluster from its centroid's scan value; the cluster with
    // the nearest centroid is scored first (its best node sets the limit).
    let q_pad = cl.cen_half.len();
    lb.resize(q_pad, 0.0);
    let mut q0 = 0usize;
    let mut w0 = f32::INFINITY;
    for (b, out) in lb.chunks_exact_mut(CLUSTER).enumerate() {
        let (w, i) = k.bounds16(
            &cl.cen[b * t_len * CLUSTER..(b + 1) * t_len * CLUSTER],
            &cl.cen_half[b * CLUSTER..(b + 1) * CLUSTER],
            ny,
            &cl.radius[b * CLUSTER..(b + 1) * CLUSTER],
            s0,
            0.5 * yy,
            out,
        );
        if w < w0 {
            w0 = w;
            q0 = b * CLUSTER + i;
        }
    }
    // Lane minima and their nodes (ties: the smaller node).
    let mut m = [f32::INFINITY; CLUSTER];
    let mut ix = [u32::MAX; CLUSTER];
    score(k, cl, ny, [q0; 4], &mut m, &mut ix);
    let limit = super::reduce(&m, &ix).value + margin;
    // The other clusters whose bound does not exceed the limit, four at a time (the
    // last group padded with q0, which scoring again leaves as it is).
    let mut group = [q0; 4];
    let mut g = 0;
    for b in 0..q_pad / CLUSTER {
        // Padding clusters have bound +∞ and are never scored.
        let mut bits = k.not_above16(&lb[b * CLUSTER..(b + 1) * CLUSTER], limit);
        while bits != 0 {
            let q = b * CLUSTER + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if q != q0 && q < cl.q {
                group[g] = q;
                g += 1;
                if g == 4 {
                    score(k, cl, ny, group, &mut m, &mut ix);
                    g = 0;
                }
            }
        }
    }
    if g > 0 {
        group[g..].fill(q0);
        score(k, cl, ny, group, &mut m, &mut ix);
    }
    super::reduce(&m, &ix)
}

/// Score the nodes of clusters `q` into the lane minima `m` and their nodes `ix`.
/// A function, not a closure: closures do not inherit the `#[target_feature]`s of the
/// function they are written in, and the kernels must inline into their caller.
#[inline(always)]
fn score<K: Scan>(
    k: K,
    cl: &Clusters,
    ny: &[f32],
    q: [usize; 4],
    m: &mut [f32; CLUSTER],
    ix: &mut [u32; CLUSTER],
) {
    let t_len = cl.t_len;
    let tc = t_len * CLUSTER;
    k.score16(
        q.map(|q| &cl.curves[q * tc..(q + 1) * tc]),
        q.map(|q| &cl.half[q * CLUSTER..(q + 1) * CLUSTER]),
        ny,
        q.map(|q| &cl.node[q * CLUSTER..(q + 1) * CLUSTER]),
        m,
        ix,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::{Isa, cpu_features};
    use crate::fit::simd::Portable;
    use crate::fit::{FitBounds, FitOptions, FitPlan};
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    fn full_isa(isa: Isa, plan: &FitPlan, y: &[f32]) -> BandMin {
        let mut bands = vec![BandMin::default(); 1];
        let (c, b) = (&plan.coarse_curves[..], &plan.coarse_half_norm[..]);
        let band = plan.grid.gc_pad;
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => t.scan(c, b, y, None, band, &mut bands),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma(t) => t.scan(c, b, y, None, band, &mut bands),
            Isa::Portable => Portable.scan(c, b, y, None, band, &mut bands),
        }
        bands[0]
    }

    fn pruned_isa(isa: Isa, plan: &FitPlan, ny: &[f32]) -> BandMin {
        let mut lb = Vec::new();
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => pruned_scan(t, &plan.clusters, ny, &mut lb),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma(t) => pruned_scan(t, &plan.clusters, ny, &mut lb),
            Isa::Portable => pruned_scan(Portable, &plan.clusters, ny, &mut lb),
        }
    }

    /// The pruned scan finds the full scan's best node and value, bit for bit, with
    /// every instruction set: measurements on a node curve plus noise of several sizes
    /// (near-ties between neighbouring nodes), uniform ones, 0 and 1, for several
    /// angle sets, boxes and grid sizes (grids with partial tiles and a coarse stride).
    #[test]
    fn pruned_scan_equals_full_scan() {
        let mut rng = StdRng::seed_from_u64(11);
        let cases: Vec<(Vec<f64>, FitOptions)> = vec![
            (
                (0..10)
                    .map(|i| (47.5 + 2.5 * i as f64).to_radians())
                    .collect(),
                FitOptions::default(),
            ),
            (
                vec![0.3, 0.7, 1.1],
                FitOptions {
                    grid_n: 21,
                    grid_k: 13,
                    ..Default::default()
                },
            ),
            (
                (0..13).map(|i| 0.2 + 0.1 * i as f64).collect(),
                FitOptions {
                    bounds: FitBounds {
                        n_min: 0.0,
                        n_max: 4.0,
                        k_min: 0.5,
                        k_max: 3.0,
                    },
                    grid_n: 64,
                    grid_k: 70,
                    ..Default::default()
                },
            ),
            (
                vec![0.9, 1.0, 1.1, 1.2],
                FitOptions {
                    grid_n: 4,
                    grid_k: 4,
                    ..Default::default()
                },
            ),
        ];
        let mut scored = 0usize;
        for (betas, opts) in cases {
            let plan = FitPlan::new(&betas, opts).unwrap();
            let t_len = betas.len();
            let gc = plan.grid.coarse_len();
            for trial in 0..3000 {
                let y: Vec<f32> = match trial % 4 {
                    0 => (0..t_len).map(|_| rng.random_range(0.0..1.0)).collect(),
                    1 => vec![if trial % 8 == 1 { 0.0 } else { 1.0 }; t_len],
                    _ => {
                        let c = rng.random_range(0..gc);
                        let sd = [1e-6f32, 1e-3, 0.01, 0.05][rng.random_range(0..4)];
                        (0..t_len)
                            .map(|t| {
                                let b = c / crate::fit::scan::SCAN_BLOCK;
                                let v = plan.coarse_curves[(b * t_len + t)
                                    * crate::fit::scan::SCAN_BLOCK
                                    + c % crate::fit::scan::SCAN_BLOCK];
                                (v + sd * rng.random_range(-1.0f32..1.0)).clamp(0.0, 1.0)
                            })
                            .collect()
                    }
                };
                let ny: Vec<f32> = y.iter().map(|v| -v).collect();
                for isa in cpu_features().all() {
                    let want = full_isa(isa, &plan, &y);
                    let got = pruned_isa(isa, &plan, &ny);
                    assert_eq!(got, want, "{isa:?} trial {trial} y {y:?}");
                    scored += 1;
                }
            }
        }
        assert!(scored > 0);
    }
}
