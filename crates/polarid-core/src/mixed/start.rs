//! The global start: a grid over `(n, k) × σ × ρd [× θr]` with `ln E` profiled out in
//! closed form,
//!
//! ```text
//! χ²(node) = Σ_t r_t² + Σ_t (l_t − mean(l))² / ε²,   l_t = ln S0_t − ln cos θi_t − ln(a_t + ρd/π)
//! ```
//!
//! keeping the best node of each of a few well-separated `(n, k)` cells (quadratic grids in
//! `n` and `k`, plus `n = 1` and `1.05`, the index-matched, purely diffuse limit).

use std::f64::consts::PI;

use super::model::lobe;
use super::problem::Problem;
use super::{K_FLOOR, MixedModel, NPAR, P_K, P_N, P_RHO, P_SIGMA, P_THETA_R, m00_grad};
use crate::dop::dop_grad_terms;

/// The axes of the start grid.
struct Grid {
    /// Refractive indices (quadratic in `n`, plus `n = 1` and `1.05` inside the box).
    ns: Vec<f64>,
    /// Extinction coefficients (quadratic in `k`).
    ks: Vec<f64>,
    /// Roughnesses (geometric).
    sigmas: Vec<f64>,
    /// Diffuse albedos.
    rhos: Vec<f64>,
    /// View angles (`[0]` when not estimated).
    trs: Vec<f64>,
}

impl Grid {
    fn new(pb: &Problem, model: MixedModel) -> Self {
        let o = pb.opts;
        let b = &o.bounds;
        let warp = |lo: f64, hi: f64, m: usize| -> Vec<f64> {
            (0..m)
                .map(|i| {
                    let u = i as f64 / (m - 1) as f64;
                    lo + (hi - lo) * u * u
                })
                .collect()
        };
        let gn = 18;
        let gk = 18;
        let mut ns = warp(b.n_min.max(0.02), b.n_max, gn);
        // The index-matched limit n = 1 (no specular reflection at all: a purely diffuse
        // surface) and its neighbourhood, which the quadratic grid would skip.
        for extra in [1.0, 1.05] {
            if extra > b.n_min && extra < b.n_max {
                ns.push(extra);
            }
        }
        ns.sort_by(f64::total_cmp);
        ns.dedup();
        let ks = warp(b.k_min.max(K_FLOOR), b.k_max, gk);
        let sigmas: Vec<f64> = (0..8)
            .map(|i| o.sigma_min * (o.sigma_max / o.sigma_min).powf(i as f64 / 7.0))
            .collect();
        let rhos: Vec<f64> = match model {
            MixedModel::Specular => vec![0.0],
            MixedModel::Mixed => [0.0, 0.02, 0.05, 0.1, 0.2, 0.35, 0.55, 0.8, 1.0]
                .iter()
                .map(|f| f * o.rho_d_max)
                .collect(),
        };
        let trs: Vec<f64> = if o.estimate_theta_r {
            let (lo, hi) = (pb.lo[P_THETA_R], pb.hi[P_THETA_R]);
            let m = (((hi - lo) / 2.5f64.to_radians()).ceil() as usize).clamp(2, 40);
            (0..=m)
                .map(|i| lo + (hi - lo) * i as f64 / m as f64)
                .collect()
        } else {
            vec![0.0]
        };
        Self {
            ns,
            ks,
            sigmas,
            rhos,
            trs,
        }
    }
}

/// `χ²(node)` of the module documentation at one grid node: `pmn`, the node's `(P, m00)`
/// per capture; `lob`, its `(G, ln cos θi)` per capture; `bb = ρd/π`; `dl`: scratch of
/// one value per capture.
///
/// `bound`: the best cost so far. The DoLP term alone (the first sum, cheap: no
/// logarithm) is a lower bound of the total, in floating point too (every term added is
/// ≥ 0 and rounding is monotone); when it already reaches `bound` the node cannot be
/// better (the caller keeps a node only when its cost is `< bound`) and that partial sum
/// is returned without the brightness term. The costs below `bound` are bit-identical to
/// the full evaluation's (the same operations in the same order).
#[inline]
fn node_cost(
    pb: &Problem,
    pmn: &[(f64, f64)],
    lob: &[(f64, f64)],
    bb: f64,
    dl: &mut [f64],
    bound: f64,
) -> f64 {
    let t_len = pb.caps.len();
    let mut c = 0.0;
    for t in 0..t_len {
        let (pp, m00) = pmn[t];
        let (g, _) = lob[t];
        let a = m00 * g;
        let ab = a + bb;
        let s = if ab > 0.0 { a / ab } else { 1.0 };
        let p = &pb.caps[t];
        let v = (pp * s - p.y_dolp) * p.inv_se;
        c += v * v;
        dl[t] = ab;
    }
    if c >= bound {
        return c;
    }
    let mut mean = 0.0;
    for t in 0..t_len {
        let l = pb.caps[t].ln_s0 - lob[t].1 - dl[t].ln();
        dl[t] = l;
        mean += l;
    }
    mean /= t_len as f64;
    let mut cs = 0.0;
    for &l in dl.iter() {
        cs += (l - mean) * (l - mean);
    }
    c + cs * (pb.inv_eps * pb.inv_eps)
}

/// The nodes (indices `i + gn j` of an `gn`-wide grid) of the `nstarts` best finite
/// costs `best[..].0` whose cells are more than two nodes apart in `n` or `k`.
fn separated_best(best: &[(f64, usize, usize, usize)], gn: usize, nstarts: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..best.len()).filter(|&i| best[i].0.is_finite()).collect();
    order.sort_by(|&a, &b| best[a].0.total_cmp(&best[b].0));
    let mut picked: Vec<usize> = Vec::new();
    for &g in &order {
        let (i, j) = (g % gn, g / gn);
        if picked
            .iter()
            .all(|&q| (q % gn).abs_diff(i) > 2 || (q / gn).abs_diff(j) > 2)
        {
            picked.push(g);
            if picked.len() >= nstarts {
                break;
            }
        }
    }
    picked
}

/// Grid start: `(n, k) × σ × ρd [× θr]`, `ln E` profiled. Returns up to `nstarts`
/// points, the best node of well-separated `(n, k)` cells.
pub(super) fn grid_starts(pb: &Problem, model: MixedModel, nstarts: usize) -> Vec<[f64; NPAR]> {
    let o = pb.opts;
    let Grid {
        ns,
        ks,
        sigmas,
        rhos,
        trs,
    } = Grid::new(pb, model);
    let (gn, gk) = (ns.len(), ks.len());
    let t_len = pb.caps.len();
    let est = o.estimate_theta_r;
    // Per (n, k) node and capture: P and m00.
    let mut pm = Vec::with_capacity(gn * gk * t_len);
    for &k in &ks {
        for &n in &ns {
            for p in &pb.caps {
                let d = dop_grad_terms(n, k, &p.bt);
                let (m00, _, _) = m00_grad(n, k, p.bt.s2, p.bt.c);
                pm.push((d.p, m00));
            }
        }
    }
    // Per (σ, θr) and capture: facet factor G and ln cos θi.
    let mut lobes = Vec::with_capacity(sigmas.len() * trs.len() * t_len);
    for &s in &sigmas {
        for &tr in &trs {
            for p in &pb.caps {
                let lt = lobe(p, s, tr, est, o.shadowing);
                lobes.push((lt.ln_g.exp(), lt.ln_cos_i));
            }
        }
    }
    // Best combination per (n, k) node.
    let mut best: Vec<(f64, usize, usize, usize)> = vec![(f64::INFINITY, 0, 0, 0); gn * gk];
    let mut dl = vec![0.0; t_len];
    for (node, bn) in best.iter_mut().enumerate() {
        let pmn = &pm[node * t_len..(node + 1) * t_len];
        for si in 0..sigmas.len() {
            for ti in 0..trs.len() {
                let lob = &lobes[(si * trs.len() + ti) * t_len..(si * trs.len() + ti + 1) * t_len];
                for (ri, &rho) in rhos.iter().enumerate() {
                    let total = node_cost(pb, pmn, lob, rho / PI, &mut dl, bn.0);
                    if total < bn.0 {
                        *bn = (total, si, ti, ri);
                    }
                }
            }
        }
    }
    separated_best(&best, gn, nstarts)
        .into_iter()
        .map(|g| {
            let (_, si, ti, ri) = best[g];
            let mut x = [0.0; NPAR];
            x[P_N] = ns[g % gn];
            x[P_K] = ks[g / gn];
            x[P_SIGMA] = sigmas[si];
            x[P_RHO] = rhos[ri];
            x[P_THETA_R] = if est { trs[ti] } else { 0.0 };
            pb.profile_ln_e(&mut x);
            x
        })
        .collect()
}
