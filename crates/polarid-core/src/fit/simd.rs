//! Lane-parallel evaluation of the fit's cost and normal equations: eq. (9) and its
//! analytic gradient (the forms of [`crate::dop::dop_grad_terms`]) for all `T` source
//! positions at once.
//!
//! The β terms are stored structure-of-arrays and padded to a multiple of
//! [`LANES`] (padding lanes carry weight 0), and the loop body is free of data-dependent
//! branches, so that the compiler maps each group of four positions onto one f64x4
//! vector (AVX2 + FMA when the caller is compiled for them: the fit selects such a
//! build at run time, see `FitPlan::fit_checked`), with a plain scalar fallback
//! elsewhere. The arithmetic is that of `dop_grad_terms` step by step; only the
//! `hypot` fallback for `√(x² + y²)` is dropped, which is exact inside any box whose
//! bounds stay below `1e100` (checked when the plan is built).

use crate::dop::BetaTerms;

use super::lm::Eval;

/// Positions evaluated together (one f64x4 vector).
pub(crate) const LANES: usize = 4;

/// Largest `n_max`, `k_max` for which the lane evaluation cannot overflow.
pub(crate) const MAX_BOUND: f64 = 1e100;

/// The β terms of eq. (9), padded to a multiple of [`LANES`].
#[derive(Debug, Clone)]
pub(crate) struct Lanes {
    /// Padded length.
    pub len: usize,
    s2: Vec<f64>,
    c: Vec<f64>,
    c2: Vec<f64>,
    s4: Vec<f64>,
    /// `2 sin²β cos β`.
    num: Vec<f64>,
}

impl Lanes {
    /// Terms of `terms`, padded with copies of the first (weight 0 in the fit).
    pub fn new(terms: &[BetaTerms]) -> Self {
        let len = terms.len().div_ceil(LANES) * LANES;
        let pad = |f: &dyn Fn(&BetaTerms) -> f64| -> Vec<f64> {
            (0..len)
                .map(|i| f(terms.get(i).unwrap_or(&terms[0])))
                .collect()
        };
        Self {
            len,
            s2: pad(&|t| t.s2),
            c: pad(&|t| t.c),
            c2: pad(&|t| t.c2),
            s4: pad(&|t| t.s4),
            num: pad(&|t| 2.0 * t.s2 * t.c),
        }
    }

    /// The first `t_len` values of `sin²β`, `cos β`, `cos²β`, `sin⁴β` and
    /// `2 sin²β cos β`.
    #[inline(always)]
    pub fn terms(&self, t_len: usize) -> (&[f64], &[f64], &[f64], &[f64], &[f64]) {
        (
            &self.s2[..t_len],
            &self.c[..t_len],
            &self.c2[..t_len],
            &self.s4[..t_len],
            &self.num[..t_len],
        )
    }
}

/// Cost `Σ w (P − y)²` and normal equations `Σ w ∇P ∇Pᵀ`, `Σ w ∇P (P − y)` at
/// `(n, k)`; `y` and `w` have the padded length (`w = 0` on padding). `Eval::ss` is set
/// to the cost (the unweighted sum when every weight is 1).
///
/// AVX2 + FMA intrinsics when the CPU has them (checked at run time, a cached flag),
/// the portable [`eval_scalar`] otherwise; both compute the same expressions.
#[inline(always)]
pub(crate) fn eval(l: &Lanes, y: &[f64], w: &[f64], n: f64, k: f64) -> Eval {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports the features the function is compiled for.
            return unsafe { eval_avx2(l, y, w, n, k) };
        }
    }
    eval_scalar(l, y, w, n, k)
}

/// [`eval`] with AVX2 + FMA intrinsics: one f64x4 vector per group of four positions.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(crate) fn eval_avx2(l: &Lanes, y: &[f64], w: &[f64], n: f64, k: f64) -> Eval {
    use std::arch::x86_64::*;
    let len = l.len;
    assert!(y.len() >= len && w.len() >= len && l.s2.len() >= len);
    let nn = n * n;
    let kk = k * k;
    let nk = n * k;
    let v_n = _mm256_set1_pd(n);
    let v_k = _mm256_set1_pd(k);
    let v_nk = _mm256_set1_pd(nk);
    let v_nn_kk = _mm256_set1_pd(nn + kk);
    let v_d0 = _mm256_set1_pd(nn - kk);
    let v_4nk2 = _mm256_set1_pd(4.0 * nk * nk);
    let v_2n = _mm256_set1_pd(2.0 * n);
    let v_2k = _mm256_set1_pd(2.0 * k);
    let half = _mm256_set1_pd(0.5);
    let one = _mm256_set1_pd(1.0);
    let two = _mm256_set1_pd(2.0);
    let zero = _mm256_setzero_pd();
    let tiny = _mm256_set1_pd(f64::MIN_POSITIVE);
    let sign = _mm256_set1_pd(-0.0);
    let mut a_cost = zero;
    let mut a_h00 = zero;
    let mut a_h01 = zero;
    let mut a_h11 = zero;
    let mut a_g0 = zero;
    let mut a_g1 = zero;
    let mut o = 0;
    while o < len {
        // SAFETY: o + 4 <= len <= the length of every array (asserted above).
        let (s2, c, c2, s4, num, yv, wv) = unsafe {
            (
                _mm256_loadu_pd(l.s2.as_ptr().add(o)),
                _mm256_loadu_pd(l.c.as_ptr().add(o)),
                _mm256_loadu_pd(l.c2.as_ptr().add(o)),
                _mm256_loadu_pd(l.s4.as_ptr().add(o)),
                _mm256_loadu_pd(l.num.as_ptr().add(o)),
                _mm256_loadu_pd(y.as_ptr().add(o)),
                _mm256_loadu_pd(w.as_ptr().add(o)),
            )
        };
        let d = _mm256_sub_pd(v_d0, s2);
        let r = _mm256_sqrt_pd(_mm256_fmadd_pd(d, d, v_4nk2));
        let dabs = _mm256_andnot_pd(sign, d);
        let rho = _mm256_sqrt_pd(_mm256_mul_pd(_mm256_add_pd(r, dabs), half));
        let small = _mm256_div_pd(v_nk, _mm256_max_pd(rho, tiny));
        let pos = _mm256_cmp_pd::<_CMP_GE_OQ>(d, zero);
        let a = _mm256_blendv_pd(small, rho, pos);
        let b = _mm256_blendv_pd(rho, small, pos);
        let q = _mm256_fmadd_pd(c2, r, s4);
        let inv_q = _mm256_div_pd(one, q);
        let x = _mm256_mul_pd(c, a);
        let p_lo = _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(two, x), s2), inv_q);
        let e = _mm256_sub_pd(x, s2);
        let cb = _mm256_mul_pd(c, b);
        let p_hi = _mm256_sub_pd(
            one,
            _mm256_mul_pd(_mm256_fmadd_pd(e, e, _mm256_mul_pd(cb, cb)), inv_q),
        );
        let hi = _mm256_cmp_pd::<_CMP_GT_OQ>(p_lo, half);
        let p = _mm256_blendv_pd(p_lo, p_hi, hi);
        let p = _mm256_min_pd(_mm256_max_pd(p, zero), one);
        let ok = _mm256_cmp_pd::<_CMP_GT_OQ>(r, zero);
        let inv_r = _mm256_div_pd(one, _mm256_max_pd(r, tiny));
        let u = _mm256_sub_pd(v_nn_kk, s2);
        let v = _mm256_add_pd(v_nn_kk, s2);
        let da_dn = _mm256_mul_pd(_mm256_fmadd_pd(v_n, a, _mm256_mul_pd(v_k, b)), inv_r);
        let da_dk = _mm256_div_pd(
            _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(v_2n, s2), b), inv_r),
            _mm256_add_pd(v, r),
        );
        let dr_dn = _mm256_mul_pd(_mm256_mul_pd(v_2n, u), inv_r);
        let dr_dk = _mm256_mul_pd(_mm256_mul_pd(v_2k, v), inv_r);
        let ac2 = _mm256_mul_pd(a, c2);
        let f = _mm256_mul_pd(_mm256_mul_pd(num, inv_q), inv_q);
        let jn = _mm256_mul_pd(f, _mm256_fnmadd_pd(ac2, dr_dn, _mm256_mul_pd(da_dn, q)));
        let jk = _mm256_mul_pd(f, _mm256_fnmadd_pd(ac2, dr_dk, _mm256_mul_pd(da_dk, q)));
        let jn = _mm256_and_pd(jn, ok);
        let jk = _mm256_and_pd(jk, ok);
        let res = _mm256_sub_pd(_mm256_and_pd(p, ok), yv);
        let wr = _mm256_mul_pd(wv, res);
        let wjn = _mm256_mul_pd(wv, jn);
        a_cost = _mm256_fmadd_pd(wr, res, a_cost);
        a_h00 = _mm256_fmadd_pd(wjn, jn, a_h00);
        a_h01 = _mm256_fmadd_pd(wjn, jk, a_h01);
        a_h11 = _mm256_fmadd_pd(_mm256_mul_pd(wv, jk), jk, a_h11);
        a_g0 = _mm256_fmadd_pd(jn, wr, a_g0);
        a_g1 = _mm256_fmadd_pd(jk, wr, a_g1);
        o += LANES;
    }
    let hsum = |v: __m256d| -> f64 {
        let mut a = [0.0f64; 4];
        // SAFETY: `a` holds four f64.
        unsafe { _mm256_storeu_pd(a.as_mut_ptr(), v) };
        (a[0] + a[2]) + (a[1] + a[3])
    };
    let cost = hsum(a_cost);
    Eval {
        cost,
        ss: cost,
        h00: hsum(a_h00),
        h01: hsum(a_h01),
        h11: hsum(a_h11),
        g0: hsum(a_g0),
        g1: hsum(a_g1),
    }
}

/// Portable form of [`eval`] (lane loops the compiler may vectorise).
#[inline(always)]
pub(crate) fn eval_scalar(l: &Lanes, y: &[f64], w: &[f64], n: f64, k: f64) -> Eval {
    const L: usize = LANES;
    let len = l.len;
    let (y, w) = (&y[..len], &w[..len]);
    let (s2v, cv, c2v, s4v, numv) = (
        &l.s2[..len],
        &l.c[..len],
        &l.c2[..len],
        &l.s4[..len],
        &l.num[..len],
    );
    let nn = n * n;
    let kk = k * k;
    let nk = n * k;
    let nn_kk = nn + kk;
    let d0 = nn - kk;
    let four_nk2 = 4.0 * nk * nk;
    let (two_n, two_k) = (2.0 * n, 2.0 * k);
    let mut acc = [[0.0f64; L]; 6];
    for ch in 0..len / L {
        let o = ch * L;
        for i in 0..L {
            let (s2, c, c2, s4, num) = (s2v[o + i], cv[o + i], c2v[o + i], s4v[o + i], numv[o + i]);
            let d = d0 - s2; // eq. (15)
            let r = (four_nk2 + d * d).sqrt(); // √C, eq. (14)
            let rho = ((r + d.abs()) * 0.5).sqrt();
            let small = nk / rho.max(f64::MIN_POSITIVE);
            let pos = d >= 0.0;
            let a = if pos { rho } else { small };
            let b = if pos { small } else { rho };
            let q = c2 * r + s4;
            let inv_q = 1.0 / q;
            // P, eq. (9), with the cancellation-free form above 1/2 (see dop::p_value).
            let x = c * a;
            let p_lo = 2.0 * x * s2 * inv_q;
            let e = x - s2;
            let cb = c * b;
            let p_hi = 1.0 - (e * e + cb * cb) * inv_q;
            let p = if p_lo > 0.5 { p_hi } else { p_lo };
            let p = p.clamp(0.0, 1.0);
            // Gradient (dop::dop_grad_terms).
            let ok = r > 0.0;
            let inv_r = 1.0 / r.max(f64::MIN_POSITIVE);
            let u = nn_kk - s2;
            let v = nn_kk + s2;
            let da_dn = (n * a + k * b) * inv_r;
            let da_dk = two_n * s2 * b * inv_r / (v + r);
            let dr_dn = two_n * u * inv_r;
            let dr_dk = two_k * v * inv_r;
            let ac2 = a * c2;
            let f = num * inv_q * inv_q;
            let jn = if ok {
                f * (da_dn * q - ac2 * dr_dn)
            } else {
                0.0
            };
            let jk = if ok {
                f * (da_dk * q - ac2 * dr_dk)
            } else {
                0.0
            };
            let res = if ok { p } else { 0.0 } - y[o + i];
            let wt = w[o + i];
            let wr = wt * res;
            let wjn = wt * jn;
            acc[0][i] += wr * res;
            acc[1][i] += wjn * jn;
            acc[2][i] += wjn * jk;
            acc[3][i] += wt * jk * jk;
            acc[4][i] += jn * wr;
            acc[5][i] += jk * wr;
        }
    }
    let s = |a: &[f64; L]| (a[0] + a[2]) + (a[1] + a[3]);
    let cost = s(&acc[0]);
    Eval {
        cost,
        ss: cost,
        h00: s(&acc[1]),
        h01: s(&acc[2]),
        h11: s(&acc[3]),
        g0: s(&acc[4]),
        g1: s(&acc[5]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dop::BetaTerms;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// The lane evaluation agrees with the scalar one built on `dop_grad_terms`,
    /// weighted and unweighted, including `k = 0`, `n < 1` and index matching.
    #[test]
    fn matches_scalar_eval() {
        let betas: Vec<f64> = (0..7).map(|i| 0.3 + 0.17 * i as f64).collect();
        let terms: Vec<BetaTerms> = betas.iter().map(|&b| BetaTerms::new(b)).collect();
        let lanes = Lanes::new(&terms);
        assert_eq!(lanes.len, 8);
        let mut rng = StdRng::seed_from_u64(3);
        let mut pts: Vec<(f64, f64)> = (0..2000)
            .map(|_| (rng.random_range(0.01..10.0), rng.random_range(0.0..15.0)))
            .collect();
        pts.extend([
            (1.0, 0.0),
            (0.3, 0.0),
            (1.5, 0.0),
            (0.5, 1e-9),
            (10.0, 15.0),
        ]);
        for (i, &(n, k)) in pts.iter().enumerate() {
            let y: Vec<f64> = (0..7).map(|t| 0.1 * t as f64 + 0.05).collect();
            let w: Vec<f64> = (0..7).map(|t| 1.0 + (i + t) as f64 % 3.0).collect();
            let mut yp = y.clone();
            yp.resize(8, 0.0);
            for weighted in [false, true] {
                let mut wp = if weighted { w.clone() } else { vec![1.0; 7] };
                wp.resize(8, 0.0);
                let b = super::super::lm::eval(&terms, &y, weighted.then_some(&w[..]), n, k);
                for a in [
                    eval(&lanes, &yp, &wp, n, k),
                    eval_scalar(&lanes, &yp, &wp, n, k),
                ] {
                    for (x, z) in [
                        (a.cost, b.cost),
                        (a.h00, b.h00),
                        (a.h01, b.h01),
                        (a.h11, b.h11),
                        (a.g0, b.g0),
                        (a.g1, b.g1),
                    ] {
                        assert!(
                            (x - z).abs() <= 1e-12 * (x.abs() + z.abs()) + 1e-14,
                            "({n}, {k}) weighted {weighted}: {a:?} vs {b:?}"
                        );
                    }
                }
            }
        }
    }
}
