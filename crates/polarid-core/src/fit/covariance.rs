//! Uncertainties and trust status of a polished minimum: the covariance `(JᵀWJ)⁻¹`
//! (scaled by the reduced χ² when no standard errors are given), in `(n, u = k²)` when
//! the linearised interval on `k` reaches 0, and the [`FitStatus`] with its reason
//! (see "Uncertainty" in the module documentation of [`crate::fit`]).
//!
//! Two implementations of the same arithmetic: [`Grid::finish`], one pixel in scalar
//! code (every case), and [`FitPlan::finish_lanes`], [`W`] pixels of a chunk side by
//! side in the vector lanes of the engine's backend ([`Simd`]) for the common case
//! (regular `JᵀJ`, the interval on `k` clear of 0), handing every other lane to
//! [`Grid::finish`]. The lanes run the same IEEE operations in the same order (no
//! fused multiply-add, division and square root correctly rounded in both), so the
//! results are bit-identical to the scalar ones on every instruction set.

use super::engine;
use super::grid::Grid;
use super::lm;
use super::simd::{Simd, W};
use super::{FitBounds, FitPlan, FitStatus, NkFit};
use crate::dop::{BetaTerms, dop_grad_terms, dop_terms};

impl FitPlan {
    /// Standard errors, correlation and status of a polished minimum (the chunk driver
    /// goes through [`FitPlan::finish_lanes`]; the tests compare them).
    #[cfg(test)]
    pub(super) fn finish(&self, out: &engine::JobOut, y: &[f64], w: Option<&[f64]>) -> NkFit {
        self.grid.finish(&self.terms, self.issue, out, y, w)
    }

    /// [`FitPlan::finish`] written into `o` in place (field by field: no copy of a
    /// just-assembled NkFit through the stack, whose wide reload of scalar stores
    /// would stall).
    #[inline(never)]
    fn finish_into(&self, out: &engine::JobOut, y: &[f64], w: Option<&[f64]>, o: &mut NkFit) {
        *o = self.grid.finish(&self.terms, self.issue, out, y, w);
    }
}

impl Grid {
    /// Standard errors, correlation and status of a polished minimum of a fit at the
    /// angles of `terms`; `issue`: why that β set is ill-conditioned, if it is.
    #[inline]
    pub(super) fn finish(
        &self,
        terms: &[BetaTerms],
        issue: Option<&'static str>,
        out: &engine::JobOut,
        y: &[f64],
        w: Option<&[f64]>,
    ) -> NkFit {
        let t_len = terms.len();
        let b = &self.opts.bounds;
        let ev = &out.ev;
        let (n, k) = (out.n, out.k);
        // The lane evaluation returns the weighted cost; the rms residual is unweighted.
        let ss = match w {
            Some(_) => lm::eval(terms, y, None, n, k).ss,
            None => ev.cost,
        };
        let s2 = match w {
            Some(_) => 1.0,
            None => ev.cost / (t_len as f64 - 2.0),
        };
        // The u-steps stop at k = K_FLOOR when the lower bound is 0: that is k = 0.
        let k = if b.k_min == 0.0 && k <= lm::K_FLOOR {
            0.0
        } else {
            k
        };
        let mut fit = NkFit {
            n,
            k,
            rms_residual: (ss / t_len as f64).sqrt(),
            cost: ev.cost,
            ..Default::default()
        };
        // Linearised covariance in (n, k).
        let lin = inv2(ev.h00, ev.h01, ev.h11);
        let k_se_lin = lin.map_or(f64::INFINITY, |(_, _, c11)| (c11 * s2).sqrt());
        let use_u = b.k_min == 0.0 && (lin.is_none() || k < k_se_lin);
        let mut singular = false;
        if use_u {
            // (n, u = k²): P depends on k through k² only (eq. 14–15), so
            // ∂P/∂u = (∂P/∂k)/(2k) exactly: the polish's normal equations give the
            // (n, u) ones for k ≥ 1e-4; closer to 0 (where ∂P/∂k vanishes with k),
            // ∂P/∂u by a secant over Δu = 1e-6.
            let (a00, a01, a11) = if out.k >= 1e-4 {
                let s = 0.5 / out.k;
                (ev.h00, ev.h01 * s, ev.h11 * s * s)
            } else {
                let du = 1e-6;
                let k1 = (k * k + du).sqrt();
                let (mut a00, mut a01, mut a11) = (0.0, 0.0, 0.0);
                for (t, bt) in terms.iter().enumerate() {
                    let d = dop_grad_terms(n, k, bt);
                    let ju = (dop_terms(n, k1, bt) - d.p) / (k1 * k1 - k * k);
                    let wt = w.map_or(1.0, |w| w[t]);
                    a00 += wt * d.dp_dn * d.dp_dn;
                    a01 += wt * d.dp_dn * ju;
                    a11 += wt * ju * ju;
                }
                (a00, a01, a11)
            };
            match inv2(a00, a01, a11) {
                Some((c00, c01, c11)) => {
                    let se_u = (c11 * s2).sqrt();
                    fit.n_se = (c00 * s2).sqrt();
                    fit.k_se = (k * k + se_u).sqrt() - k;
                    fit.nk_corr = c01 / (c00 * c11).sqrt();
                }
                None => singular = true,
            }
        } else if let Some((c00, c01, c11)) = lin {
            fit.n_se = (c00 * s2).sqrt();
            fit.k_se = (c11 * s2).sqrt();
            fit.nk_corr = c01 / (c00 * c11).sqrt();
        } else {
            singular = true;
        }
        if singular {
            fit.n_se = f64::NAN;
            fit.k_se = f64::NAN;
            fit.nk_corr = f64::NAN;
        }
        let (status, reason) = status_rule(issue, is_flat(y), singular, out.converged, n, k, b);
        fit.status = status;
        fit.reason = reason;
        fit
    }
}

/// Inverse of the symmetric 2×2 `[[a, b], [b, c]]` as `(i00, i01, i11)`, or `None`
/// when it is singular (a zero diagonal or `1 − ρ² < 1e-12`).
pub(crate) fn inv2(a: f64, b: f64, c: f64) -> Option<(f64, f64, f64)> {
    if !(a > 0.0 && c > 0.0) || !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return None;
    }
    let det = a * c - b * b;
    if !(det > 1e-12 * a * c) {
        return None;
    }
    Some((c / det, -b / det, a / det))
}

/// Whether the DoLP curve `y` is flat: `max y − min y ≤ 1e-9` (the same DoLP at every
/// β). Fast path: rounding is monotone, so `max − min` computes to at least
/// `|y_first − y_last|`, and a curve whose end points differ by more than 1e-9 is not
/// flat without looking at the others.
#[inline(always)]
fn is_flat(y: &[f64]) -> bool {
    if let (Some(&a), Some(&b)) = (y.first(), y.last())
        && (a - b).abs() > 1e-9
    {
        return false;
    }
    // Plain comparisons (the data are validated: no NaN), one instruction each.
    let (ymin, ymax) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (if v < a { v } else { a }, if v > b { v } else { b })
        });
    ymax - ymin <= 1e-9
}

/// The trust status of a fit and its reason, first rule that applies: an
/// ill-conditioned β set (`issue`), a flat DoLP curve, a singular `JᵀWJ`, no
/// convergence, `n` or `k` at a bound of the box `b`.
#[inline(always)]
fn status_rule(
    issue: Option<&'static str>,
    flat: bool,
    singular: bool,
    converged: bool,
    n: f64,
    k: f64,
    b: &FitBounds,
) -> (FitStatus, &'static str) {
    if let Some(r) = issue {
        (FitStatus::IllConditioned, r)
    } else if flat {
        (
            FitStatus::IllConditioned,
            "flat DoLP curve: the same DoLP at every beta",
        )
    } else if singular {
        (
            FitStatus::IllConditioned,
            "singular J^T W J: the DoLP curve does not determine n and k here",
        )
    } else if !converged {
        (
            FitStatus::NotConverged,
            "Levenberg-Marquardt did not converge within the iteration limit",
        )
    } else if b.n_min > 0.0 && n <= b.n_min {
        (FitStatus::AtBound, "n at the lower bound of the box")
    } else if n >= b.n_max {
        (FitStatus::AtBound, "n at the upper bound of the box")
    } else if b.k_min > 0.0 && k <= b.k_min {
        (FitStatus::AtBound, "k at the lower bound of the box")
    } else if k >= b.k_max {
        (FitStatus::AtBound, "k at the upper bound of the box")
    } else {
        (FitStatus::Ok, "")
    }
}

/// Up to [`W`] polished pixels of a chunk awaiting their uncertainties, one lane
/// each (structure of arrays), for [`FitPlan::finish_lanes`].
#[derive(Debug, Clone)]
pub(super) struct FinishLanes {
    /// Lanes in use.
    len: usize,
    /// Pixel of each lane (its row of the chunk).
    pixel: [usize; W],
    /// Best polish of each lane (index into the polishes of the chunk).
    job: [usize; W],
    /// Iterations, evaluations and starts of the pixel, over all of its polishes.
    iters: [u32; W],
    evals: [u32; W],
    starts: [u32; W],
    /// Whether the best polish converged.
    converged: [bool; W],
    /// The best polish: `n`, `k`, cost, `JᵀWJ`; the unweighted `Σ r²` (filled by
    /// [`FitPlan::finish_lanes`] when there are weights).
    n: [f64; W],
    k: [f64; W],
    cost: [f64; W],
    ss: [f64; W],
    h00: [f64; W],
    h01: [f64; W],
    h11: [f64; W],
}

impl Default for FinishLanes {
    fn default() -> Self {
        Self {
            len: 0,
            pixel: [0; W],
            job: [0; W],
            iters: [0; W],
            evals: [0; W],
            starts: [0; W],
            converged: [false; W],
            n: [0.0; W],
            k: [0.0; W],
            cost: [0.0; W],
            ss: [0.0; W],
            h00: [0.0; W],
            h01: [0.0; W],
            h11: [0.0; W],
        }
    }
}

impl FinishLanes {
    /// Every lane is in use.
    #[inline(always)]
    pub(super) fn is_full(&self) -> bool {
        self.len == W
    }

    /// No lane is in use.
    #[inline(always)]
    pub(super) fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Queue pixel `pixel` whose best polish is `out` (index `job` into the polishes
    /// of the chunk), with the iterations, evaluations and starts of all its
    /// polishes. The caller flushes a full set first.
    #[inline(always)]
    pub(super) fn push(
        &mut self,
        pixel: usize,
        job: usize,
        out: &engine::JobOut,
        iters: u32,
        evals: u32,
        starts: u32,
    ) {
        let l = self.len;
        if l >= W {
            return;
        }
        self.pixel[l] = pixel;
        self.job[l] = job;
        self.iters[l] = iters;
        self.evals[l] = evals;
        self.starts[l] = starts;
        self.converged[l] = out.converged;
        self.n[l] = out.n;
        self.k[l] = out.k;
        self.cost[l] = out.ev.cost;
        self.h00[l] = out.ev.h00;
        self.h01[l] = out.ev.h01;
        self.h11[l] = out.ev.h11;
        self.len = l + 1;
    }
}

/// `x / d` lane by lane, as a multiplication by `1/d` when `d` is a power of two (then
/// `1/d` is exact and both give the correctly rounded `x/d`: bit-identical).
#[inline(always)]
fn div_by<K: Simd>(s: K, x: K::V, d: f64) -> K::V {
    let pow2 = d.is_normal() && d > 0.0 && d.to_bits() & ((1u64 << 52) - 1) == 0;
    let r = 1.0 / d;
    if pow2 && r.is_normal() {
        s.mul(x, s.splat(r))
    } else {
        s.div(x, s.splat(d))
    }
}

impl FitPlan {
    /// Standard errors, correlation and status of the queued pixels of `lanes` (then
    /// emptied), written into `out[pixel]` with their iterations, evaluations and
    /// starts: bit for bit what [`Grid::finish`] gives each of them. `outs`: the
    /// polishes of the chunk; `y`, `w`: its measurements and weights (rows of `T`).
    ///
    /// The common case in the lanes of `s`: `(JᵀWJ)⁻¹` regular and, with a lower bound
    /// `k ≥ 0`, `k` at least its linearised standard error. Lanes outside it (singular
    /// `JᵀWJ`, the `(n, u = k²)` covariance) go to [`Grid::finish`].
    #[inline(always)]
    pub(super) fn finish_lanes<K: Simd>(
        &self,
        s: K,
        lanes: &mut FinishLanes,
        outs: &[engine::JobOut],
        y: &[f64],
        w: Option<&[f64]>,
        out: &mut [NkFit],
    ) {
        let t_len = self.len();
        let b = &self.grid.opts.bounds;
        let k_min0 = b.k_min == 0.0;
        let zero = s.splat(0.0);
        let cost = s.load(&lanes.cost);
        // s² = χ²/(T − 2) without standard errors, 1 with them; the rms residual is
        // unweighted: the cost without standard errors, re-evaluated with them.
        let (s2, ss) = match w {
            Some(_) => {
                for l in 0..lanes.len.min(W) {
                    let rows = lanes.pixel[l] * t_len..(lanes.pixel[l] + 1) * t_len;
                    lanes.ss[l] = lm::eval(&self.terms, &y[rows], None, lanes.n[l], lanes.k[l]).ss;
                }
                (s.splat(1.0), s.load(&lanes.ss))
            }
            None => (div_by(s, cost, t_len as f64 - 2.0), cost),
        };
        let rms = s.sqrt(div_by(s, ss, t_len as f64));
        // The u-steps stop at k = K_FLOOR when the lower bound is 0: that is k = 0.
        let kr = s.load(&lanes.k);
        let k = if k_min0 {
            s.select(s.le(kr, s.splat(lm::K_FLOOR)), zero, kr)
        } else {
            kr
        };
        // inv2 of (h00, h01, h11), lane by lane.
        let (a, bb, c) = (s.load(&lanes.h00), s.load(&lanes.h01), s.load(&lanes.h11));
        let inf = s.splat(f64::INFINITY);
        let finite = s.and(
            s.and(s.lt(s.abs(a), inf), s.lt(s.abs(bb), inf)),
            s.lt(s.abs(c), inf),
        );
        let det = s.sub(s.mul(a, c), s.mul(bb, bb));
        let regular = s.and(
            s.and(s.and(s.lt(zero, a), s.lt(zero, c)), finite),
            s.lt(s.mul(s.mul(s.splat(1e-12), a), c), det),
        );
        let c00 = s.div(c, det);
        let c01 = s.div(s.mul(s.splat(-1.0), bb), det);
        let c11 = s.div(a, det);
        let n_se = s.sqrt(s.mul(c00, s2));
        let k_se = s.sqrt(s.mul(c11, s2));
        let corr = s.div(c01, s.sqrt(s.mul(c00, c11)));
        let scalar = if k_min0 {
            s.or(s.not(regular), s.lt(k, k_se))
        } else {
            s.not(regular)
        };
        let scalar = s.bits(scalar);
        let mut v = [[0.0; W]; 5];
        s.store(k, &mut v[0]);
        s.store(n_se, &mut v[1]);
        s.store(k_se, &mut v[2]);
        s.store(corr, &mut v[3]);
        s.store(rms, &mut v[4]);
        let [kv, n_sev, k_sev, corrv, rmsv] = &v;
        for l in 0..lanes.len.min(W) {
            let p = lanes.pixel[l];
            let rows = p * t_len..(p + 1) * t_len;
            let yp = &y[rows.clone()];
            // Written in place, field by field: a copy of a whole NkFit assembled on
            // the stack would reload its scalar stores as wide vectors (a stalled
            // store-to-load forward per pixel).
            if scalar >> l & 1 != 0 {
                let wp = w.map(|w| &w[rows]);
                let o = &mut out[p];
                self.finish_into(&outs[lanes.job[l]], yp, wp, o);
                o.iterations = lanes.iters[l];
                o.evaluations = lanes.evals[l];
                o.starts = lanes.starts[l];
            } else {
                let (n, k) = (lanes.n[l], kv[l]);
                let (status, reason) =
                    status_rule(self.issue, is_flat(yp), false, lanes.converged[l], n, k, b);
                out[p] = NkFit {
                    n,
                    k,
                    n_se: n_sev[l],
                    k_se: k_sev[l],
                    nk_corr: corrv[l],
                    rms_residual: rmsv[l],
                    cost: lanes.cost[l],
                    iterations: lanes.iters[l],
                    evaluations: lanes.evals[l],
                    starts: lanes.starts[l],
                    status,
                    reason,
                };
            }
        }
        lanes.len = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::{Isa, cpu_features};
    use crate::fit::FitOptions;
    use crate::fit::simd::Portable;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// Polished minima covering every branch of the covariance: regular `JᵀJ` with
    /// `k` far from and near 0 (`(n, u)` covariance, by the normal equations and by
    /// the secant), `k` at the floor, singular, non-finite and non-positive `JᵀJ`,
    /// not converged, `n` and `k` at the bounds; and rows of `T` DoLP values, some of
    /// them flat or with equal end points.
    fn cases(t_len: usize, count: usize, seed: u64) -> (Vec<engine::JobOut>, Vec<f64>, Vec<f64>) {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut outs = Vec::new();
        let mut y = Vec::new();
        let mut w = Vec::new();
        for i in 0..count {
            let a = 10f64.powf(rng.random_range(-3.0..3.0));
            let c = 10f64.powf(rng.random_range(-3.0..3.0));
            let rho: f64 = rng.random_range(-1.0..1.0);
            let mut b = rho * (a * c).sqrt();
            let (mut a, mut c) = (a, c);
            let mut k = rng.random_range(0.0..9.0);
            let mut n = rng.random_range(0.2..4.0);
            match i % 23 {
                1 => k = 10f64.powf(rng.random_range(-12.0..0.0)),
                2 => k = 1e-9,
                3 => k = rng.random_range(0.0..1e-4),
                4 => b = (a * c).sqrt(),
                5 => a = 0.0,
                6 => c = -c,
                7 => b = f64::NAN,
                8 => a = f64::INFINITY,
                9 => n = 10.0,
                10 => n = 0.01,
                11 => k = 15.0,
                12 => k = 0.5,
                13 => b = 0.0,
                _ => {}
            }
            let cost = match i % 7 {
                0 => 0.0,
                _ => 10f64.powf(rng.random_range(-8.0..-2.0)),
            };
            outs.push(engine::JobOut {
                n,
                k,
                ev: lm::Eval {
                    cost,
                    ss: 0.0,
                    h00: a,
                    h01: b,
                    h11: c,
                    g0: 0.0,
                    g1: 0.0,
                },
                iters: i as u32 % 5,
                evals: i as u32 % 9,
                converged: i % 11 != 3,
            });
            let flat = i % 13 == 5;
            let v0 = rng.random_range(0.0..1.0);
            for _ in 0..t_len {
                y.push(if flat { v0 } else { rng.random_range(0.0..1.0) });
                w.push(rng.random_range(1e3..1e5));
            }
            if i % 17 == 2 {
                let r = &mut y[i * t_len..(i + 1) * t_len];
                r[t_len - 1] = r[0];
            }
        }
        (outs, y, w)
    }

    fn lanes_fits<K: Simd>(
        s: K,
        plan: &FitPlan,
        outs: &[engine::JobOut],
        y: &[f64],
        w: Option<&[f64]>,
    ) -> Vec<NkFit> {
        let mut fits = vec![NkFit::default(); outs.len()];
        let mut lanes = FinishLanes::default();
        for (p, o) in outs.iter().enumerate() {
            lanes.push(p, p, o, o.iters, o.evals, 1);
            if lanes.is_full() {
                plan.finish_lanes(s, &mut lanes, outs, y, w, &mut fits);
            }
        }
        if !lanes.is_empty() {
            plan.finish_lanes(s, &mut lanes, outs, y, w, &mut fits);
        }
        fits
    }

    fn bits(f: &NkFit) -> ([u64; 7], [u32; 3], FitStatus, &'static str) {
        (
            [f.n, f.k, f.n_se, f.k_se, f.nk_corr, f.rms_residual, f.cost].map(f64::to_bits),
            [f.iterations, f.evaluations, f.starts],
            f.status,
            f.reason,
        )
    }

    /// The vector lanes give bit for bit the scalar [`Grid::finish`] on every
    /// instruction set, weighted and not, for T − 2 a power of two and not, with the
    /// lower bound of `k` at 0 and above, and for an ill-conditioned β set.
    #[test]
    fn lanes_match_scalar_bit_for_bit() {
        let boxed = FitOptions {
            bounds: FitBounds {
                n_min: 0.0,
                n_max: 5.0,
                k_min: 0.2,
                k_max: 8.0,
            },
            ..Default::default()
        };
        let mut checked = [0usize; 2];
        for (t_len, opts, same_beta) in [
            (10, FitOptions::default(), false),
            (7, FitOptions::default(), false),
            (6, boxed, false),
            (5, FitOptions::default(), true),
        ] {
            let betas: Vec<f64> = (0..t_len)
                .map(|i| {
                    let d = if same_beta {
                        0.0
                    } else {
                        30.0 * i as f64 / (t_len - 1) as f64
                    };
                    (40.0 + d).to_radians()
                })
                .collect();
            let plan = FitPlan::new(&betas, opts).unwrap();
            let (outs, y, w) = cases(t_len, 1001, t_len as u64);
            for wt in [None, Some(&w[..])] {
                let want: Vec<NkFit> = outs
                    .iter()
                    .enumerate()
                    .map(|(p, o)| {
                        let rows = p * t_len..(p + 1) * t_len;
                        let mut f = plan.finish(o, &y[rows.clone()], wt.map(|w| &w[rows]));
                        (f.iterations, f.evaluations, f.starts) = (o.iters, o.evals, 1);
                        f
                    })
                    .collect();
                checked[0] += want.iter().filter(|f| f.status == FitStatus::Ok).count();
                checked[1] += want.iter().filter(|f| f.k_se.is_nan()).count();
                for isa in cpu_features().all() {
                    let got = match isa {
                        Isa::Portable => lanes_fits(Portable, &plan, &outs, &y, wt),
                        #[cfg(target_arch = "x86_64")]
                        Isa::Avx2Fma(t) => lanes_fits(t, &plan, &outs, &y, wt),
                        #[cfg(target_arch = "x86_64")]
                        Isa::Avx512(t) => lanes_fits(t, &plan, &outs, &y, wt),
                    };
                    for (p, (g, e)) in got.iter().zip(&want).enumerate() {
                        assert_eq!(
                            bits(g),
                            bits(e),
                            "{isa:?} T {t_len} pixel {p}: {g:?} vs {e:?}"
                        );
                    }
                }
            }
        }
        // Both the common case and the singular one were exercised.
        assert!(checked[0] > 1000 && checked[1] > 100, "{checked:?}");
    }

    /// The flat-curve test with its end-point shortcut agrees with the full fold.
    #[test]
    fn flat_shortcut_matches_fold() {
        let mut rng = StdRng::seed_from_u64(3);
        for i in 0..20_000 {
            let len = 1 + i % 12;
            let base: f64 = rng.random_range(0.0..1.0);
            let scale = 10f64.powf(rng.random_range(-12.0..-6.0));
            let y: Vec<f64> = (0..len)
                .map(|_| (base + scale * rng.random_range(-1.0..1.0)).clamp(0.0, 1.0))
                .collect();
            let (lo, hi) = y
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            assert_eq!(is_flat(&y), hi - lo <= 1e-9, "{y:?}");
        }
    }
}
