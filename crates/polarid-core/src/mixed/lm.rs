//! The polish: bounded Levenberg–Marquardt over the free parameters with the analytic
//! Jacobian,
//!
//! ```text
//! (JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr
//! ```
//!
//! stepping in `u = k²` below `k = 1` (as in [`crate::fit`]), holding parameters on a bound
//! whose descent direction points outwards, and clamping every step to the box.

use super::linalg::cholesky_solve;
use super::problem::Problem;
use super::{K_U, NPAR, P_K};

pub(super) struct Polished {
    pub(super) x: [f64; NPAR],
    pub(super) cost: f64,
    pub(super) iters: u32,
    pub(super) converged: bool,
}

/// Bounded Levenberg–Marquardt over the free parameters (steps in `u = k²` below
/// `k = 1`, parameters on a bound with an outward descent direction held).
pub(super) fn polish(pb: &Problem, x0: [f64; NPAR]) -> Polished {
    let (mut r, mut j) = (Vec::with_capacity(pb.m()), Vec::with_capacity(pb.m()));
    let mut x = x0;
    let mut cost = pb.eval(&x, &mut r, &mut j);
    let mut lam = 1e-3;
    let mut iters = 0;
    let mut converged = false;
    while iters < pb.opts.max_iter {
        iters += 1;
        // Normal equations in the step variables.
        let in_u = x[P_K] < K_U;
        let mut g = [0.0; NPAR];
        let mut h = [[0.0; NPAR]; NPAR];
        for (ri, row) in r.iter().zip(&j) {
            let mut row = *row;
            if in_u {
                row[P_K] /= 2.0 * x[P_K];
            }
            for a in 0..NPAR {
                g[a] += row[a] * ri;
                for b in 0..NPAR {
                    h[a][b] += row[a] * row[b];
                }
            }
        }
        // Active set.
        let mut idx = [0usize; NPAR];
        let mut d = 0;
        for a in 0..NPAR {
            if !pb.free[a] {
                continue;
            }
            let at_lo = x[a] <= pb.lo[a] && g[a] > 0.0;
            let at_hi = x[a] >= pb.hi[a] && g[a] < 0.0;
            if at_lo || at_hi || !(h[a][a] > 0.0) {
                continue;
            }
            idx[d] = a;
            d += 1;
        }
        if d == 0 {
            converged = true;
            break;
        }
        let mut a_m = [[0.0; NPAR]; NPAR];
        let mut b_v = [0.0; NPAR];
        for p in 0..d {
            b_v[p] = -g[idx[p]];
            for q in 0..d {
                a_m[p][q] = h[idx[p]][idx[q]];
            }
            a_m[p][p] *= 1.0 + lam;
        }
        let Some(step) = cholesky_solve(&a_m, &b_v, d) else {
            lam *= 10.0;
            if lam > 1e12 {
                break;
            }
            continue;
        };
        let mut xt = x;
        for p in 0..d {
            let a = idx[p];
            if a == P_K && in_u {
                let lo = pb.lo[P_K];
                let u = (x[P_K] * x[P_K] + step[p]).clamp(lo * lo, pb.hi[P_K] * pb.hi[P_K]);
                xt[P_K] = u.sqrt();
            } else {
                xt[a] = (x[a] + step[p]).clamp(pb.lo[a], pb.hi[a]);
            }
        }
        let moved = (0..NPAR).all(|a| (xt[a] - x[a]).abs() <= 1e-10 * (x[a].abs() + 1e-8));
        if moved {
            converged = true;
            break;
        }
        let (mut rt, mut jt) = (Vec::with_capacity(pb.m()), Vec::with_capacity(pb.m()));
        let ct = pb.eval(&xt, &mut rt, &mut jt);
        if ct <= cost {
            let dec = cost - ct;
            x = xt;
            cost = ct;
            r = rt;
            j = jt;
            lam = (lam * 0.2).max(1e-12);
            if dec <= 1e-13 * cost.max(1e-300) && lam < 1e-2 {
                converged = true;
                break;
            }
        } else {
            lam *= 10.0;
            if lam > 1e12 {
                // No decrease possible at this precision: a minimum if the gradient
                // predicts nothing to gain.
                let pred: f64 = (0..d).map(|p| -g[idx[p]] * step[p]).sum();
                converged = pred.abs() <= 1e-9 * cost + 1e-24;
                break;
            }
        }
    }
    Polished {
        x,
        cost,
        iters,
        converged,
    }
}
