//! The vector operations of the Levenberg–Marquardt engine (`engine.rs`) on [`W`]
//! lanes of f64, one backend per instruction set:
//!
//! | backend                 | file          | vectors            | needs              |
//! |-------------------------|---------------|--------------------|--------------------|
//! | [`Portable`]            | `portable.rs` | `[f64; 16]` loops  | any CPU            |
//! | [`crate::cpu::Avx2Fma`] | `avx2.rs`     | four `__m256d`     | AVX2 + FMA         |
//! | [`crate::cpu::Avx512`]  | `avx512.rs`   | two `__m512d`      | AVX-512F           |
//!
//! # Safety argument
//! The vector backends *are* the tokens of [`crate::cpu`]: `Simd` is implemented for
//! [`crate::cpu::Avx2Fma`] and [`crate::cpu::Avx512`], and every operation takes the
//! backend as `self`. A token can only be obtained from [`crate::cpu::cpu_features`]
//! when the CPU has the features, so an operation that executes an AVX instruction
//! cannot be called (from safe or unsafe code) without that proof in hand: the
//! `unsafe` blocks inside the backends rely on nothing else. Loads and stores go
//! through slices of at least [`W`] values (bounds-checked) before a pointer is
//! formed.
//!
//! Speed is a separate matter: the operations are `#[inline(always)]` and the engine
//! is generic over the backend, so the whole engine is inlined into the chunk driver's
//! entry point compiled with `#[target_feature(enable = ...)]` for the backend's
//! features (`FitPlan::fit_chunk_avx2` / `_avx512` in `chunk.rs`), where every
//! intrinsic becomes one instruction. Called from elsewhere the operations would still
//! be correct, only slower (intrinsics called out of line).

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod portable;

pub(crate) use portable::Portable;

/// Lanes of a vector: fits polished side by side (two f64x8 vectors, or four f64x4).
pub(crate) const W: usize = 16;

/// The vector operations on [`W`] lanes the engine needs, each taking the backend
/// (for the vector backends: the token proving the CPU has the instructions) as
/// `self`. Comparisons give masks; `min`/`max` are `a < b ? a : b` / `a > b ? a : b`
/// (no NaN handling).
pub(crate) trait Simd: Copy {
    /// [`W`] f64.
    type V: Copy;
    /// [`W`] lane flags.
    type M: Copy;
    /// Every lane `x`.
    fn splat(self, x: f64) -> Self::V;
    /// The first [`W`] values of `p`.
    fn load(self, p: &[f64]) -> Self::V;
    /// Into the first [`W`] values of `p`.
    fn store(self, v: Self::V, p: &mut [f64]);
    /// `a + b`.
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a − b`.
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a · b`.
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a / b`.
    fn div(self, a: Self::V, b: Self::V) -> Self::V;
    /// `√a`.
    fn sqrt(self, a: Self::V) -> Self::V;
    /// `a·b + c` (fused on AVX2 + FMA and AVX-512F).
    fn fma(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `|a|`.
    fn abs(self, a: Self::V) -> Self::V;
    /// `a < b ? a : b`.
    fn min(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a > b ? a : b`.
    fn max(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a < b`.
    fn lt(self, a: Self::V, b: Self::V) -> Self::M;
    /// `a ≤ b`.
    fn le(self, a: Self::V, b: Self::V) -> Self::M;
    /// `a == b`.
    fn eq(self, a: Self::V, b: Self::V) -> Self::M;
    /// `a ∧ b`.
    fn and(self, a: Self::M, b: Self::M) -> Self::M;
    /// `a ∨ b`.
    fn or(self, a: Self::M, b: Self::M) -> Self::M;
    /// `¬a`.
    fn not(self, a: Self::M) -> Self::M;
    /// `m ? a : b` lane by lane.
    fn select(self, m: Self::M, a: Self::V, b: Self::V) -> Self::V;
    /// Bit `l` set when lane `l` of `m` is set.
    fn bits(self, m: Self::M) -> u32;
    /// The mask with lane `l` set when bit `l` of `b` is.
    fn mask(self, b: u32) -> Self::M;
}
