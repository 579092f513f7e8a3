//! The pruned unweighted scan of one band (the whole grid): the full scan's best node,
//! bit for bit, from a fraction of the nodes.
//!
//! The coarse nodes are cut into groups of [`GROUP`] = 4 × 4 neighbours of the
//! `(n, k)` grid (tiles of the coarse grid; partial tiles at the edges are padded),
//! each with a centre curve `m` (the mean of its node curves, f32) and a radius
//! `r ≥ max ‖c − m‖` over its node curves `c` (rounded up), computed once per plan.
//! For a pixel with measurements `y` a node's scan value is
//! `V_c = ½‖c‖² − c·y = ½‖c − y‖² − ½‖y‖²` (see the module documentation of `scan`),
//! so by the triangle inequality every node of a group whose centre lies at
//! `‖y − m‖ ≥ r` has
//!
//! ```text
//! V_c ≥ ½ (‖y − m‖ − r)² − ½‖y‖²,      ‖y − m‖² = 2 V_m + ‖y‖²
//! ```
//!
//! with `V_m` the centre's own scan value. The scan of four pixels then runs in four
//! stages, each over the four pixels side by side (independent chains of fused
//! multiply-adds that keep the vector units busy):
//!
//! 1. the scan values `V_m` of every centre (64 at the default size: four f32x16
//!    vectors, one multiply-add per vector and source position);
//! 2. the nodes of the group with the nearest centre, whose best value `v₀` bounds
//!    the pixel's best value from above;
//! 3. the candidate groups: those with `2 V_m + ‖y‖² ≤ (r + L)² + Δ`,
//!    `L = √(2 v₀ + ‖y‖² + Δ)`; every other group has all its node values above `v₀`
//!    (below);
//! 4. the nodes of the candidate groups, in group order, into running lane minima
//!    as in the full scan (two pixels side by side, each pixel's broadcast
//!    measurements in registers; a pixel out of candidates scores its last group
//!    again, which changes nothing: equal values do not replace).
//!
//! A node is scored with the same multiply-adds in the same order from the same
//! `½‖c‖²` as in the full scan, so it gets the same value; every node whose value is
//! at most `v₀` (in particular the best one) is in a candidate group; and the nodes of
//! a lane (slot of the group) come in increasing order, so the lane minima and their
//! reduction (smallest value, then smallest node) give the full scan's [`BandMin`].
//!
//! # Rounding
//! `Δ` covers every rounding. With `u = 2⁻²⁴`, `y, c, m ∈ [0, 1]ᵀ` and
//! `B = max (½‖c‖² + Σ_t c_t)` over nodes and centres (a bound on every partial sum
//! of a scan value), a computed scan value is within `δ = (T + 2) u B` of the exact
//! value of its f32 data, the computed `‖y‖²` (a chain of `T` multiply-adds of values
//! at most `T`) within `T² u`, and the other roundings (of `2 V_m + ‖y‖²`, the square
//! root, `r + L` and the square, on quantities at most `T + 1` where they matter) add
//! at most `7 u (T + 1)`. A group is skipped only if the computed
//! `2 V_m + ‖y‖² > (r + L)² + Δ` with `Δ = 2 (2δ + T² u + 7 u (T + 1))`; then the exact
//! `‖y − m‖ > r + √(2 v₀ + ‖y‖² + 2δ)`, so every node of the group has the exact
//! `V_c > v₀ + δ` and a computed value above `v₀`. At `T = 10` `Δ ≤ 6.4·10⁻⁵`
//! (`B ≤ 15`), against a typical `2 v₀ + ‖y‖²` (the squared distance of the nearest
//! node) of 10⁻³.
//!
//! # Cost
//! On the benchmark problem of `examples/fit_throughput.rs` (`T = 10`, the default
//! 32 × 32 grid) a pixel scores the 64 centres, the nearest group, then 11.0 candidate
//! groups of 16 nodes (the nearest one again among them) instead of 1024 nodes: about
//! 340 multiply-add vectors instead of 640, and with the four-pixel centre stage and
//! the paired candidate stage throughput-bound, 100 against 175 ns per pixel (scan
//! alone, one thread, AVX-512). Only the AVX-512 backend runs it
//! ([`Scan::PRUNED`](super::Scan::PRUNED)); the others keep the full scan, which
//! gives the same nodes.

use super::{BandMin, reduce};

/// Nodes per group: one f32x16 vector.
pub(crate) const GROUP: usize = 16;

/// Side of a group's tile of coarse nodes (`TILE × TILE = GROUP`).
const TILE: usize = 4;

/// Most groups of a pruned scan (the candidate set is one `u64` mask).
pub(crate) const MAX_GROUPS: usize = 64;

/// Vectors of 16 centres ([`MAX_GROUPS`] / 16).
pub(crate) const NV: usize = MAX_GROUPS / GROUP;

/// Sixteen f32 values aligned to a cache line (one f32x16 vector).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct V16(pub [f32; GROUP]);

/// Sixteen node indices aligned to a cache line.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct I16(pub [u32; GROUP]);

/// The groups of a plan's coarse nodes for the pruned scan (see the module
/// documentation).
#[derive(Debug, Clone)]
pub(crate) struct Groups {
    /// Measurements per pixel, `T`.
    pub t_len: usize,
    /// Number of groups (without padding).
    pub q: usize,
    /// Centre curves, 16 groups per vector, always [`MAX_GROUPS`] groups:
    /// `cen[t · NV + v]` holds `m_{16v + l}(t)` in lane `l` (padding: 0).
    pub cen: Vec<V16>,
    /// `½‖m‖²` of every centre, f32 ([`NV`] vectors; padding: +∞).
    pub cen_half: Vec<V16>,
    /// Radius of every group, rounded up ([`NV`] vectors; padding: 0).
    pub radius: Vec<V16>,
    /// Node curves of group `g`: `curves[g · T + t]` holds `c_s(t)` of slot `s` in lane
    /// `s` (padding: 0).
    pub curves: Vec<V16>,
    /// `½‖c‖²` of every slot, the full scan's f32 value (padding: +∞).
    pub half: Vec<V16>,
    /// Coarse node of every slot (padding: `u32::MAX`).
    pub node: Vec<I16>,
    /// The rounding margin `Δ` (see the module documentation).
    pub delta: f32,
}

impl Groups {
    /// The groups of a coarse grid of `cn × ck` nodes (coarse node `c` at column
    /// `c % cn`, row `c / cn`) whose curves are `curve(c, t)` (DoLP, in [0, 1]) and
    /// whose scan bases are `half[c] = ½‖c‖²` (f32, as the full scan uses them).
    /// `None` when there would be more than [`MAX_GROUPS`] groups.
    pub fn new(
        cn: usize,
        ck: usize,
        t_len: usize,
        curve: impl Fn(usize, usize) -> f32,
        half: &[f32],
    ) -> Option<Self> {
        let (qi, qj) = (cn.div_ceil(TILE), ck.div_ceil(TILE));
        let q = qi * qj;
        if q > MAX_GROUPS || t_len == 0 {
            return None;
        }
        let mut g = Self {
            t_len,
            q,
            cen: vec![V16([0.0; GROUP]); NV * t_len],
            cen_half: vec![V16([f32::INFINITY; GROUP]); NV],
            radius: vec![V16([0.0; GROUP]); NV],
            curves: vec![V16([0.0; GROUP]); q * t_len],
            half: vec![V16([f32::INFINITY; GROUP]); q],
            node: vec![I16([u32::MAX; GROUP]); q],
            delta: 0.0,
        };
        // Largest partial sum of a scan value (y in [0, 1]): max ½‖c‖² + Σ c_t.
        let mut b = 0f64;
        let mut mean = vec![0f64; t_len];
        for bj in 0..qj {
            for bi in 0..qi {
                let gi = bj * qi + bi;
                mean.fill(0.0);
                let mut count = 0usize;
                for j in bj * TILE..((bj + 1) * TILE).min(ck) {
                    for i in bi * TILE..((bi + 1) * TILE).min(cn) {
                        let c = j * cn + i;
                        let s = (j - bj * TILE) * TILE + (i - bi * TILE);
                        g.node[gi].0[s] = c as u32;
                        g.half[gi].0[s] = half[c];
                        let (mut sq, mut sum) = (0f64, 0f64);
                        for (t, m) in mean.iter_mut().enumerate() {
                            let v = curve(c, t);
                            g.curves[gi * t_len + t].0[s] = v;
                            *m += f64::from(v);
                            sq += f64::from(v).powi(2);
                            sum += f64::from(v).abs();
                        }
                        b = b.max(0.5 * sq + sum);
                        count += 1;
                    }
                }
                let m32: Vec<f32> = mean.iter().map(|&m| (m / count as f64) as f32).collect();
                let mut r2 = 0f64;
                for s in 0..GROUP {
                    if g.node[gi].0[s] == u32::MAX {
                        continue;
                    }
                    let d2: f64 = (0..t_len)
                        .map(|t| {
                            (f64::from(g.curves[gi * t_len + t].0[s]) - f64::from(m32[t])).powi(2)
                        })
                        .sum();
                    r2 = r2.max(d2);
                }
                let (v, l) = (gi / GROUP, gi % GROUP);
                g.radius[v].0[l] = round_up(r2.sqrt() * (1.0 + 1e-9));
                let (mut sq, mut sum) = (0f64, 0f64);
                for (t, &m) in m32.iter().enumerate() {
                    g.cen[t * NV + v].0[l] = m;
                    sq += f64::from(m).powi(2);
                    sum += f64::from(m).abs();
                }
                g.cen_half[v].0[l] = (0.5 * sq) as f32;
                b = b.max(0.5 * sq + sum);
            }
        }
        let u = f64::powi(2.0, -24);
        let tf = t_len as f64;
        let delta = (tf + 2.0) * u * b;
        g.delta = round_up(2.0 * (2.0 * delta + tf * tf * u + 7.0 * u * (tf + 1.0)));
        Some(g)
    }
}

/// The smallest f32 at or above the non-negative `x`.
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) >= x {
        f
    } else {
        f32::from_bits(f.to_bits() + 1)
    }
}

/// The pruned scan of one pixel in plain Rust, with fused multiply-adds (`mul_add`,
/// the arithmetic of the vector kernels): `ny` its `T` measurements as f32, negated.
/// The [`BandMin`] of the full unweighted fused scan of the whole grid as one band;
/// the reference of the vector kernels' stages (and what a backend without a pruned
/// kernel would run).
pub(crate) fn pruned_reference(g: &Groups, ny: &[f32]) -> BandMin {
    let t_len = g.t_len;
    let ny = &ny[..t_len];
    let yy = ny.iter().fold(0f32, |a, &v| v.mul_add(v, a));
    // Stage 1: the centre values and the nearest centre.
    let mut cv = [f32::INFINITY; MAX_GROUPS];
    let mut g0 = usize::MAX;
    for v in 0..NV {
        let mut a = g.cen_half[v].0;
        for (t, &nyt) in ny.iter().enumerate() {
            for (al, &c) in a.iter_mut().zip(&g.cen[t * NV + v].0) {
                *al = c.mul_add(nyt, *al);
            }
        }
        for (l, &al) in a.iter().enumerate() {
            cv[v * GROUP + l] = al;
            if g0 == usize::MAX || al < cv[g0] {
                g0 = v * GROUP + l;
            }
        }
    }
    if g0 >= g.q {
        // Every centre value +∞ or NaN (not for data in [0, 1]): every group.
        return scan_groups(g, ny, u64::MAX >> (64 - g.q));
    }
    // Stage 2: the best value of the nearest group bounds the pixel's best value.
    let v0 = values(g, ny, g0)
        .iter()
        .fold(f32::INFINITY, |m, &v| if v < m { v } else { m });
    // Stage 3: the candidate groups.
    let lim = (2f32.mul_add(v0, yy).max(0.0) + g.delta).sqrt();
    let mut mask = 1u64 << g0;
    for (gi, &c) in cv.iter().enumerate().take(g.q) {
        let (v, l) = (gi / GROUP, gi % GROUP);
        let lhs = c.mul_add(2.0, yy);
        let s = g.radius[v].0[l] + lim;
        let rhs = s.mul_add(s, g.delta);
        // A candidate unless `lhs > rhs` (also when either is NaN).
        let skip = lhs.partial_cmp(&rhs) == Some(std::cmp::Ordering::Greater);
        mask |= u64::from(!skip) << gi;
    }
    // Stage 4: their nodes.
    scan_groups(g, ny, mask)
}

/// The scan values of the nodes of group `gi` (fused multiply-adds).
fn values(g: &Groups, ny: &[f32], gi: usize) -> [f32; GROUP] {
    let mut a = g.half[gi].0;
    for (t, &nyt) in ny.iter().enumerate() {
        for (al, &c) in a.iter_mut().zip(&g.curves[gi * g.t_len + t].0) {
            *al = c.mul_add(nyt, *al);
        }
    }
    a
}

/// The best node of the groups in `mask`, scanned in group order into lane minima.
fn scan_groups(g: &Groups, ny: &[f32], mut mask: u64) -> BandMin {
    let mut m = [f32::INFINITY; GROUP];
    let mut ix = [u32::MAX; GROUP];
    while mask != 0 {
        let gi = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let a = values(g, ny, gi);
        for s in 0..GROUP {
            if a[s] < m[s] {
                m[s] = a[s];
                ix[s] = g.node[gi].0[s];
            }
        }
    }
    reduce(&m, &ix)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::{Isa, cpu_features};
    use crate::fit::scan::{SCAN_BLOCK, Scan};
    use crate::fit::{FitBounds, FitOptions, FitPlan};
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// The full unweighted scan of one pixel with fused multiply-adds in plain Rust:
    /// the smallest value, then the smallest node.
    fn full_fused(plan_curves: &[f32], base: &[f32], ny: &[f32]) -> BandMin {
        let t_len = ny.len();
        let mut best = BandMin::default();
        for c in 0..base.len() {
            let mut a = base[c];
            for (t, &nyt) in ny.iter().enumerate() {
                let v = plan_curves[(c / SCAN_BLOCK * t_len + t) * SCAN_BLOCK + c % SCAN_BLOCK];
                a = v.mul_add(nyt, a);
            }
            if a < best.value {
                best = BandMin {
                    value: a,
                    node: c as u32,
                };
            }
        }
        best
    }

    /// The pruned scans of four pixels with instruction set `isa` (the reference for
    /// a backend without a pruned kernel).
    fn pruned_isa(isa: Isa, g: &Groups, ny: [&[f32]; 4]) -> [BandMin; 4] {
        let mut out = [BandMin::default(); 4];
        let [a, b, c, d] = &mut out;
        let bands = [
            std::slice::from_mut(a),
            std::slice::from_mut(b),
            std::slice::from_mut(c),
            std::slice::from_mut(d),
        ];
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => t.scan4_pruned(g, ny, bands),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma(t) => t.scan4_pruned(g, ny, bands),
            Isa::Portable => crate::fit::simd::Portable.scan4_pruned(g, ny, bands),
        }
        out
    }

    /// Measurement vectors that stress the pruning: on a node curve plus noise of
    /// several sizes (near-ties between neighbours), exactly on a node curve, uniform,
    /// all 0 and all 1.
    fn trial_y(
        rng: &mut StdRng,
        trial: usize,
        node_curve: &dyn Fn(usize, usize) -> f32,
        gc: usize,
        t_len: usize,
    ) -> Vec<f32> {
        match trial % 6 {
            0 => (0..t_len).map(|_| rng.random_range(0.0..1.0)).collect(),
            1 => vec![if trial % 12 == 1 { 0.0 } else { 1.0 }; t_len],
            2 => {
                let c = rng.random_range(0..gc);
                (0..t_len).map(|t| node_curve(c, t)).collect()
            }
            _ => {
                let c = rng.random_range(0..gc);
                let sd = [1e-6f32, 1e-3, 0.01, 0.05][rng.random_range(0..4)];
                (0..t_len)
                    .map(|t| {
                        (node_curve(c, t) + sd * rng.random_range(-1.0f32..1.0)).clamp(0.0, 1.0)
                    })
                    .collect()
            }
        }
    }

    /// The pruned scan (the plain-Rust reference and every kernel the CPU has) finds
    /// the full fused scan's best node and value bit for bit: several angle sets, boxes
    /// and grid sizes (partial tiles, fewer than 16 groups, one group).
    #[test]
    fn pruned_scan_equals_full_scan() {
        let mut rng = StdRng::seed_from_u64(11);
        let cases: Vec<(Vec<f64>, FitOptions)> = vec![
            (
                (0..10)
                    .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0).to_radians())
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
                    grid_n: 32,
                    grid_k: 29,
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
        let mut checked = 0usize;
        for (betas, opts) in cases {
            let plan = FitPlan::new(&betas, opts).unwrap();
            let g = plan.groups.as_ref().expect("groups of a one-band plan");
            let t_len = betas.len();
            let gc = plan.grid.coarse_len();
            let curve = |c: usize, t: usize| {
                plan.coarse_curves[(c / SCAN_BLOCK * t_len + t) * SCAN_BLOCK + c % SCAN_BLOCK]
            };
            for trial in 0..1200 {
                let ys: Vec<Vec<f32>> = (0..4)
                    .map(|i| trial_y(&mut rng, trial + i, &curve, gc, t_len))
                    .collect();
                let nys: Vec<Vec<f32>> =
                    ys.iter().map(|y| y.iter().map(|v| -v).collect()).collect();
                let ny4 = [&nys[0][..], &nys[1][..], &nys[2][..], &nys[3][..]];
                let want: Vec<BandMin> = nys
                    .iter()
                    .map(|ny| full_fused(&plan.coarse_curves, &plan.coarse_half_norm, ny))
                    .collect();
                for (p, ny) in nys.iter().enumerate() {
                    assert_eq!(
                        pruned_reference(g, ny),
                        want[p],
                        "reference, trial {trial} y {:?}",
                        ys[p]
                    );
                }
                for isa in cpu_features().all() {
                    if matches!(isa, Isa::Portable) {
                        continue;
                    }
                    let got = pruned_isa(isa, g, ny4);
                    assert_eq!(got[..], want[..], "{isa:?} trial {trial} y {ys:?}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 0 || cpu_features().all().len() == 1);
    }

    /// Exact ties between nodes (curves with few distinct values, many equal) resolve
    /// to the smallest node, as in the full scan, for a grid of partial tiles.
    #[test]
    fn pruned_scan_breaks_ties_by_node() {
        let (cn, ck, t_len) = (10usize, 7usize, 4usize);
        let curve = |c: usize, t: usize| ((c * 7 + t * 3) % 5) as f32 * 0.25;
        let gc = cn * ck;
        let gp = gc.div_ceil(SCAN_BLOCK) * SCAN_BLOCK;
        let mut curves = vec![0f32; gp * t_len];
        let mut half = vec![f32::INFINITY; gp];
        for c in 0..gc {
            let mut sq = 0f64;
            for t in 0..t_len {
                curves[(c / SCAN_BLOCK * t_len + t) * SCAN_BLOCK + c % SCAN_BLOCK] = curve(c, t);
                sq += f64::from(curve(c, t)).powi(2);
            }
            half[c] = (0.5 * sq) as f32;
        }
        let g = Groups::new(cn, ck, t_len, curve, &half).unwrap();
        let mut rng = StdRng::seed_from_u64(3);
        for trial in 0..400 {
            let nys: Vec<Vec<f32>> = (0..4)
                .map(|i| {
                    let c = rng.random_range(0..gc);
                    (0..t_len)
                        .map(|t| {
                            if (trial + i) % 3 == 0 {
                                -curve(c, t)
                            } else {
                                -rng.random_range(0..5) as f32 * 0.25
                            }
                        })
                        .collect()
                })
                .collect();
            let want: Vec<BandMin> = nys
                .iter()
                .map(|ny| full_fused(&curves, &half, ny))
                .collect();
            for (p, ny) in nys.iter().enumerate() {
                assert_eq!(pruned_reference(&g, ny), want[p], "trial {trial}");
            }
            let ny4 = [&nys[0][..], &nys[1][..], &nys[2][..], &nys[3][..]];
            for isa in cpu_features().all() {
                if !matches!(isa, Isa::Portable) {
                    assert_eq!(
                        pruned_isa(isa, &g, ny4)[..],
                        want[..],
                        "{isa:?} trial {trial}"
                    );
                }
            }
        }
    }

    /// Grids of more than [`MAX_GROUPS`] groups and plans with several bands have no
    /// groups (they keep the full scan).
    #[test]
    fn groups_only_for_small_one_band_grids() {
        let betas = [0.5, 0.8, 1.1];
        assert!(FitPlan::with_defaults(&betas).unwrap().groups.is_some());
        for opts in [
            FitOptions {
                grid_n: 33,
                grid_k: 32,
                ..Default::default()
            },
            FitOptions {
                max_candidates: 2,
                ..Default::default()
            },
        ] {
            assert!(FitPlan::new(&betas, opts).unwrap().groups.is_none());
        }
    }
}
