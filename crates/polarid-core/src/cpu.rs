//! CPU feature detection, done once, and the instruction-set tokens that prove it.
//!
//! The kernels of the fit and of the Stokes images have AVX-512F and AVX2 + FMA
//! versions on x86_64. Executing one of their instructions on a CPU without the feature
//! is undefined behaviour, so the crate never decides "from a comment" that a feature
//! is there: it asks [`cpu_features`], which runs `is_x86_feature_detected!` once per
//! process (cached in a [`OnceLock`]) and hands out *tokens*:
//!
//! | token       | proves the CPU has        | obtained from                  |
//! |-------------|---------------------------|--------------------------------|
//! | [`Avx2Fma`] | AVX2 and FMA              | [`CpuFeatures::avx2_fma`]      |
//! | [`Avx512`]  | AVX-512F, AVX2 and FMA    | [`CpuFeatures::avx512`]        |
//!
//! A token is a zero-sized `Copy` value with a private field: no code outside this
//! module can construct one, so holding a token *is* the proof that the detection ran
//! and found the features. Every ISA-specific function of the crate either
//!
//! - takes the token as a parameter (a safe function or a method on `self`: it may
//!   execute the instructions because its caller could not have called it without the
//!   proof), or
//! - is an `unsafe fn` with `#[target_feature(enable = ...)]` whose `# Safety` contract
//!   is "the CPU has these features"; every call site holds a token and says so in its
//!   `SAFETY:` comment. (These are the entry points that let the compiler use the
//!   instructions in the code inlined into them.)
//!
//! No safe function of the crate can execute an instruction the CPU was not checked
//! for. On other architectures there are no tokens and every kernel is portable.
//!
//! # Forcing the portable kernels
//! Setting the environment variable `POLARID_NO_SIMD` to anything but `""` or `"0"`
//! before the first kernel runs makes [`cpu_features`] report no feature: every kernel
//! then takes its portable path (read once; changing it later has no effect). Results
//! of the portable fit kernels differ from the vector ones in the last bits (separate
//! multiply and add instead of fused multiply-add); the Stokes kernels give the same
//! bits. Inside the crate, tests choose a path explicitly with [`Isa`] instead.

use std::sync::OnceLock;

/// What [`cpu_features`] found (nothing off x86_64, or with `POLARID_NO_SIMD`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct CpuFeatures {
    /// AVX2 and FMA.
    avx2_fma: bool,
    /// AVX-512F, AVX2 and FMA.
    avx512: bool,
}

/// Proof that the CPU has AVX2 and FMA (see the module documentation). Only
/// [`CpuFeatures::avx2_fma`] makes one.
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy)]
pub(crate) struct Avx2Fma {
    _private: (),
}

/// Proof that the CPU has AVX-512F, AVX2 and FMA (see the module documentation). Only
/// [`CpuFeatures::avx512`] makes one.
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy)]
pub(crate) struct Avx512 {
    _private: (),
}

/// An instruction set to run a kernel with: the portable code, or a vector extension
/// with the token that proves the CPU has it.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Isa {
    /// Plain Rust (any CPU).
    Portable,
    /// AVX2 + FMA.
    #[cfg(target_arch = "x86_64")]
    Avx2Fma(Avx2Fma),
    /// AVX-512F (+ AVX2 + FMA).
    #[cfg(target_arch = "x86_64")]
    Avx512(Avx512),
}

impl Isa {
    /// The AVX2 + FMA token if this instruction set includes them (AVX-512 does: its
    /// token is only made when the CPU also has AVX2 and FMA).
    #[cfg(target_arch = "x86_64")]
    #[inline]
    pub(crate) fn avx2_fma(self) -> Option<Avx2Fma> {
        match self {
            Isa::Portable => None,
            Isa::Avx2Fma(t) => Some(t),
            Isa::Avx512(_) => Some(Avx2Fma { _private: () }),
        }
    }
}

impl CpuFeatures {
    /// The AVX2 + FMA token, if the CPU has both.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    pub(crate) fn avx2_fma(self) -> Option<Avx2Fma> {
        self.avx2_fma.then_some(Avx2Fma { _private: () })
    }

    /// The AVX-512 token, if the CPU has AVX-512F, AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    pub(crate) fn avx512(self) -> Option<Avx512> {
        self.avx512.then_some(Avx512 { _private: () })
    }

    /// The widest instruction set available: AVX-512, then AVX2 + FMA, then portable.
    #[inline]
    pub(crate) fn best(self) -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(t) = self.avx512() {
                return Isa::Avx512(t);
            }
            if let Some(t) = self.avx2_fma() {
                return Isa::Avx2Fma(t);
            }
        }
        Isa::Portable
    }

    /// Every instruction set available, portable first (for tests comparing them).
    #[cfg(test)]
    pub(crate) fn all(self) -> Vec<Isa> {
        #[allow(unused_mut)]
        let mut v = vec![Isa::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            v.extend(self.avx2_fma().map(Isa::Avx2Fma));
            v.extend(self.avx512().map(Isa::Avx512));
        }
        v
    }
}

/// True when `POLARID_NO_SIMD` holds a value that asks for the portable kernels.
fn no_simd_requested(value: Option<&std::ffi::OsStr>) -> bool {
    value.is_some_and(|v| !v.is_empty() && v != "0")
}

/// Run the detection (no caching).
fn detect() -> CpuFeatures {
    if no_simd_requested(std::env::var_os("POLARID_NO_SIMD").as_deref()) {
        return CpuFeatures::default();
    }
    #[cfg(target_arch = "x86_64")]
    {
        let avx2_fma = std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma");
        let avx512 = avx2_fma && std::arch::is_x86_feature_detected!("avx512f");
        CpuFeatures { avx2_fma, avx512 }
    }
    #[cfg(not(target_arch = "x86_64"))]
    CpuFeatures::default()
}

/// The features of this CPU, detected on the first call and cached for the process.
#[inline]
pub(crate) fn cpu_features() -> CpuFeatures {
    static FEATURES: OnceLock<CpuFeatures> = OnceLock::new();
    *FEATURES.get_or_init(detect)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::OsStr;

    #[test]
    fn no_simd_values() {
        assert!(!no_simd_requested(None));
        assert!(!no_simd_requested(Some(OsStr::new(""))));
        assert!(!no_simd_requested(Some(OsStr::new("0"))));
        assert!(no_simd_requested(Some(OsStr::new("1"))));
        assert!(no_simd_requested(Some(OsStr::new("yes"))));
    }

    /// The cached answer is the detection's, and AVX-512 implies AVX2 + FMA.
    #[test]
    fn detection_is_cached_and_consistent() {
        let f = cpu_features();
        assert_eq!(f, cpu_features());
        assert_eq!(f, detect());
        assert!(!f.avx512 || f.avx2_fma);
        assert!(matches!(f.all()[0], Isa::Portable));
    }
}
