//! The exact 0/45/90/135° kernel (`kernel.rs`) compiled for AVX2 + FMA.
//!
//! # Safety
//! [`quad_block_avx2`] is an `unsafe fn` with `#[target_feature(enable = "avx2,fma")]`:
//! calling it on a CPU without them is undefined behaviour. Its only caller,
//! [`quad_block`], is safe because it takes the [`Avx2Fma`] token, which exists only
//! when [`crate::cpu::cpu_features`] found AVX2 and FMA on this CPU.

use super::kernel;
use crate::cpu::Avx2Fma;
use crate::stokes::pixels::{PixelCounts, PixelRules, Sample};

/// [`kernel::quad_block`] with AVX2 + FMA code.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn quad_block<T: Sample, const POLAR: bool>(
    t: Avx2Fma,
    q: [&[T]; 4],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
    rd: &mut [f32],
    ra: &mut [f32],
) -> PixelCounts {
    let _ = t;
    // SAFETY: the token `t` proves the CPU has AVX2 and FMA.
    unsafe { quad_block_avx2::<T, POLAR>(q, rules, r0, r1, r2, rm, rd, ra) }
}

/// [`kernel::quad_block`] compiled for AVX2 + FMA.
///
/// # Safety
/// The CPU has AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn quad_block_avx2<T: Sample, const POLAR: bool>(
    q: [&[T]; 4],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
    rd: &mut [f32],
    ra: &mut [f32],
) -> PixelCounts {
    kernel::quad_block::<T, POLAR>(q, rules, r0, r1, r2, rm, rd, ra)
}
