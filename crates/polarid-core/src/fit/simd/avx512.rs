//! [`Simd`] with AVX-512F intrinsics, two f64x8 per vector, implemented on the token
//! [`Avx512`].
//!
//! # Safety
//! Every operation takes an [`Avx512`] as `self`; such a value exists only when
//! [`crate::cpu::cpu_features`] found AVX-512F (and AVX2, FMA) on this CPU, so
//! executing their instructions is defined. Loads and stores index a slice of [`W`]
//! values first (bounds-checked), so every pointer passed to an intrinsic covers `W`
//! valid `f64`.

use std::arch::x86_64::*;

use super::{Simd, W};
use crate::cpu::Avx512;

/// The intrinsic `$f` on each of the two f64x8 of its operands.
macro_rules! pair2 {
    ($f:ident($($a:ident),*)) => {
        // SAFETY: `self` is an `Avx512` token (see the module documentation).
        unsafe { [$f($($a[0]),*), $f($($a[1]),*)] }
    };
}

// SAFETY (every `unsafe` block below): the module documentation's argument: the
// `Avx512` token proves the CPU has AVX-512F; pointers come from slices of `W`.
impl Simd for Avx512 {
    type V = [__m512d; 2];
    type M = [__mmask8; 2];
    #[inline(always)]
    fn splat(self, x: f64) -> Self::V {
        unsafe { [_mm512_set1_pd(x); 2] }
    }
    #[inline(always)]
    fn load(self, p: &[f64]) -> Self::V {
        let p = &p[..W];
        unsafe {
            [
                _mm512_loadu_pd(p.as_ptr()),
                _mm512_loadu_pd(p.as_ptr().add(8)),
            ]
        }
    }
    #[inline(always)]
    fn store(self, v: Self::V, p: &mut [f64]) {
        let p = &mut p[..W];
        unsafe {
            _mm512_storeu_pd(p.as_mut_ptr(), v[0]);
            _mm512_storeu_pd(p.as_mut_ptr().add(8), v[1]);
        }
    }
    #[inline(always)]
    fn add(self, a: Self::V, b: Self::V) -> Self::V {
        pair2!(_mm512_add_pd(a, b))
    }
    #[inline(always)]
    fn sub(self, a: Self::V, b: Self::V) -> Self::V {
        pair2!(_mm512_sub_pd(a, b))
    }
    #[inline(always)]
    fn mul(self, a: Self::V, b: Self::V) -> Self::V {
        pair2!(_mm512_mul_pd(a, b))
    }
    #[inline(always)]
    fn div(self, a: Self::V, b: Self::V) -> Self::V {
        pair2!(_mm512_div_pd(a, b))
    }
    #[inline(always)]
    fn sqrt(self, a: Self::V) -> Self::V {
        pair2!(_mm512_sqrt_pd(a))
    }
    #[inline(always)]
    fn fma(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V {
        pair2!(_mm512_fmadd_pd(a, b, c))
    }
    #[inline(always)]
    fn abs(self, a: Self::V) -> Self::V {
        pair2!(_mm512_abs_pd(a))
    }
    #[inline(always)]
    fn min(self, a: Self::V, b: Self::V) -> Self::V {
        pair2!(_mm512_min_pd(a, b))
    }
    #[inline(always)]
    fn max(self, a: Self::V, b: Self::V) -> Self::V {
        pair2!(_mm512_max_pd(a, b))
    }
    #[inline(always)]
    fn lt(self, a: Self::V, b: Self::V) -> Self::M {
        unsafe {
            [
                _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a[0], b[0]),
                _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a[1], b[1]),
            ]
        }
    }
    #[inline(always)]
    fn le(self, a: Self::V, b: Self::V) -> Self::M {
        unsafe {
            [
                _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a[0], b[0]),
                _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a[1], b[1]),
            ]
        }
    }
    #[inline(always)]
    fn eq(self, a: Self::V, b: Self::V) -> Self::M {
        unsafe {
            [
                _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a[0], b[0]),
                _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a[1], b[1]),
            ]
        }
    }
    #[inline(always)]
    fn and(self, a: Self::M, b: Self::M) -> Self::M {
        [a[0] & b[0], a[1] & b[1]]
    }
    #[inline(always)]
    fn or(self, a: Self::M, b: Self::M) -> Self::M {
        [a[0] | b[0], a[1] | b[1]]
    }
    #[inline(always)]
    fn not(self, a: Self::M) -> Self::M {
        [!a[0], !a[1]]
    }
    #[inline(always)]
    fn select(self, m: Self::M, a: Self::V, b: Self::V) -> Self::V {
        unsafe {
            [
                _mm512_mask_blend_pd(m[0], b[0], a[0]),
                _mm512_mask_blend_pd(m[1], b[1], a[1]),
            ]
        }
    }
    #[inline(always)]
    fn bits(self, m: Self::M) -> u32 {
        u32::from(m[0]) | (u32::from(m[1]) << 8)
    }
    #[inline(always)]
    fn mask(self, b: u32) -> Self::M {
        [b as u8, (b >> 8) as u8]
    }
}
