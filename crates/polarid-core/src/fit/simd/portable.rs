//! [`Simd`] by plain lane loops: any CPU, no token. `fma` is a separate multiply and
//! add (one more rounding than the fused vector backends).

use super::{Simd, W};

/// [`Simd`] by lane loops (any CPU).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

type L = [f64; W];

macro_rules! lanes {
    (|$($x:ident),*| $e:expr) => {{
        let mut o = [Default::default(); W];
        for l in 0..W {
            $(let $x = $x[l];)*
            o[l] = $e;
        }
        o
    }};
}

impl Simd for Portable {
    type V = L;
    type M = [bool; W];
    #[inline(always)]
    fn splat(self, x: f64) -> L {
        [x; W]
    }
    #[inline(always)]
    fn load(self, p: &[f64]) -> L {
        let mut v = [0.0; W];
        v.copy_from_slice(&p[..W]);
        v
    }
    #[inline(always)]
    fn store(self, v: L, p: &mut [f64]) {
        p[..W].copy_from_slice(&v);
    }
    #[inline(always)]
    fn add(self, a: L, b: L) -> L {
        lanes!(|a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, a: L, b: L) -> L {
        lanes!(|a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, a: L, b: L) -> L {
        lanes!(|a, b| a * b)
    }
    #[inline(always)]
    fn div(self, a: L, b: L) -> L {
        lanes!(|a, b| a / b)
    }
    #[inline(always)]
    fn sqrt(self, a: L) -> L {
        lanes!(|a| a.sqrt())
    }
    #[inline(always)]
    fn fma(self, a: L, b: L, c: L) -> L {
        lanes!(|a, b, c| a * b + c)
    }
    #[inline(always)]
    fn abs(self, a: L) -> L {
        lanes!(|a| a.abs())
    }
    #[inline(always)]
    fn min(self, a: L, b: L) -> L {
        lanes!(|a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn max(self, a: L, b: L) -> L {
        lanes!(|a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn lt(self, a: L, b: L) -> [bool; W] {
        lanes!(|a, b| a < b)
    }
    #[inline(always)]
    fn le(self, a: L, b: L) -> [bool; W] {
        lanes!(|a, b| a <= b)
    }
    #[inline(always)]
    fn eq(self, a: L, b: L) -> [bool; W] {
        lanes!(|a, b| a == b)
    }
    #[inline(always)]
    fn and(self, a: [bool; W], b: [bool; W]) -> [bool; W] {
        lanes!(|a, b| a & b)
    }
    #[inline(always)]
    fn or(self, a: [bool; W], b: [bool; W]) -> [bool; W] {
        lanes!(|a, b| a | b)
    }
    #[inline(always)]
    fn not(self, a: [bool; W]) -> [bool; W] {
        lanes!(|a| !a)
    }
    #[inline(always)]
    fn select(self, m: [bool; W], a: L, b: L) -> L {
        lanes!(|m, a, b| if m { a } else { b })
    }
    #[inline(always)]
    fn bits(self, m: [bool; W]) -> u32 {
        m.iter()
            .enumerate()
            .fold(0, |acc, (l, &v)| acc | (u32::from(v) << l))
    }
    #[inline(always)]
    fn mask(self, b: u32) -> [bool; W] {
        let mut m = [false; W];
        for (l, v) in m.iter_mut().enumerate() {
            *v = (b >> l) & 1 == 1;
        }
        m
    }
}
