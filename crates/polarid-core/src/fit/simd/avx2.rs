//! [`Simd`] with AVX2 + FMA intrinsics, four f64x4 per vector, implemented on the
//! token [`Avx2Fma`].
//!
//! # Safety
//! Every operation takes an [`Avx2Fma`] as `self`; such a value exists only when
//! [`crate::cpu::cpu_features`] found AVX2 and FMA on this CPU, so executing their
//! instructions is defined. Loads and stores index a slice of [`W`] values first
//! (bounds-checked), so every pointer passed to an intrinsic covers `W` valid `f64`.

use std::arch::x86_64::*;

use super::{Simd, W};
use crate::cpu::Avx2Fma;

/// The intrinsic `$f` on each of the four f64x4 of its operands.
macro_rules! pair {
    ($f:ident($($a:ident),*)) => {
        // SAFETY: `self` is an `Avx2Fma` token (see the module documentation).
        unsafe { [$f($($a[0]),*), $f($($a[1]),*), $f($($a[2]),*), $f($($a[3]),*)] }
    };
}

// SAFETY (every `unsafe` block below): the module documentation's argument: the
// `Avx2Fma` token proves the CPU has AVX2 + FMA; pointers come from slices of `W`.
impl Simd for Avx2Fma {
    type V = [__m256d; 4];
    type M = [__m256d; 4];
    #[inline(always)]
    fn splat(self, x: f64) -> Self::V {
        unsafe { [_mm256_set1_pd(x); 4] }
    }
    #[inline(always)]
    fn load(self, p: &[f64]) -> Self::V {
        let p = &p[..W];
        unsafe {
            [
                _mm256_loadu_pd(p.as_ptr()),
                _mm256_loadu_pd(p.as_ptr().add(4)),
                _mm256_loadu_pd(p.as_ptr().add(8)),
                _mm256_loadu_pd(p.as_ptr().add(12)),
            ]
        }
    }
    #[inline(always)]
    fn store(self, v: Self::V, p: &mut [f64]) {
        let p = &mut p[..W];
        unsafe {
            _mm256_storeu_pd(p.as_mut_ptr(), v[0]);
            _mm256_storeu_pd(p.as_mut_ptr().add(4), v[1]);
            _mm256_storeu_pd(p.as_mut_ptr().add(8), v[2]);
            _mm256_storeu_pd(p.as_mut_ptr().add(12), v[3]);
        }
    }
    #[inline(always)]
    fn add(self, a: Self::V, b: Self::V) -> Self::V {
        pair!(_mm256_add_pd(a, b))
    }
    #[inline(always)]
    fn sub(self, a: Self::V, b: Self::V) -> Self::V {
        pair!(_mm256_sub_pd(a, b))
    }
    #[inline(always)]
    fn mul(self, a: Self::V, b: Self::V) -> Self::V {
        pair!(_mm256_mul_pd(a, b))
    }
    #[inline(always)]
    fn div(self, a: Self::V, b: Self::V) -> Self::V {
        pair!(_mm256_div_pd(a, b))
    }
    #[inline(always)]
    fn sqrt(self, a: Self::V) -> Self::V {
        pair!(_mm256_sqrt_pd(a))
    }
    #[inline(always)]
    fn fma(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V {
        pair!(_mm256_fmadd_pd(a, b, c))
    }
    #[inline(always)]
    fn abs(self, a: Self::V) -> Self::V {
        let m = self.splat(-0.0);
        pair!(_mm256_andnot_pd(m, a))
    }
    #[inline(always)]
    fn min(self, a: Self::V, b: Self::V) -> Self::V {
        // vminpd gives the second operand unless a < b.
        pair!(_mm256_min_pd(a, b))
    }
    #[inline(always)]
    fn max(self, a: Self::V, b: Self::V) -> Self::V {
        pair!(_mm256_max_pd(a, b))
    }
    #[inline(always)]
    fn lt(self, a: Self::V, b: Self::V) -> Self::M {
        unsafe {
            [
                _mm256_cmp_pd::<_CMP_LT_OQ>(a[0], b[0]),
                _mm256_cmp_pd::<_CMP_LT_OQ>(a[1], b[1]),
                _mm256_cmp_pd::<_CMP_LT_OQ>(a[2], b[2]),
                _mm256_cmp_pd::<_CMP_LT_OQ>(a[3], b[3]),
            ]
        }
    }
    #[inline(always)]
    fn le(self, a: Self::V, b: Self::V) -> Self::M {
        unsafe {
            [
                _mm256_cmp_pd::<_CMP_LE_OQ>(a[0], b[0]),
                _mm256_cmp_pd::<_CMP_LE_OQ>(a[1], b[1]),
                _mm256_cmp_pd::<_CMP_LE_OQ>(a[2], b[2]),
                _mm256_cmp_pd::<_CMP_LE_OQ>(a[3], b[3]),
            ]
        }
    }
    #[inline(always)]
    fn eq(self, a: Self::V, b: Self::V) -> Self::M {
        unsafe {
            [
                _mm256_cmp_pd::<_CMP_EQ_OQ>(a[0], b[0]),
                _mm256_cmp_pd::<_CMP_EQ_OQ>(a[1], b[1]),
                _mm256_cmp_pd::<_CMP_EQ_OQ>(a[2], b[2]),
                _mm256_cmp_pd::<_CMP_EQ_OQ>(a[3], b[3]),
            ]
        }
    }
    #[inline(always)]
    fn and(self, a: Self::M, b: Self::M) -> Self::M {
        pair!(_mm256_and_pd(a, b))
    }
    #[inline(always)]
    fn or(self, a: Self::M, b: Self::M) -> Self::M {
        pair!(_mm256_or_pd(a, b))
    }
    #[inline(always)]
    fn not(self, a: Self::M) -> Self::M {
        let ones = unsafe { [_mm256_castsi256_pd(_mm256_set1_epi64x(-1)); 4] };
        pair!(_mm256_xor_pd(a, ones))
    }
    #[inline(always)]
    fn select(self, m: Self::M, a: Self::V, b: Self::V) -> Self::V {
        pair!(_mm256_blendv_pd(b, a, m))
    }
    #[inline(always)]
    fn bits(self, m: Self::M) -> u32 {
        unsafe {
            (_mm256_movemask_pd(m[0])
                | (_mm256_movemask_pd(m[1]) << 4)
                | (_mm256_movemask_pd(m[2]) << 8)
                | (_mm256_movemask_pd(m[3]) << 12)) as u32
        }
    }
    #[inline(always)]
    fn mask(self, b: u32) -> Self::M {
        unsafe {
            let sel = _mm256_set_epi64x(8, 4, 2, 1);
            let part = |q: u32| {
                let v = _mm256_set1_epi64x(i64::from((b >> (4 * q)) & 15));
                _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(v, sel), sel))
            };
            [part(0), part(1), part(2), part(3)]
        }
    }
}
