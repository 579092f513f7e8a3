//! The strip kernels of `kernel.rs` behind one entry point per instruction set.
//!
//! [`entry_points!`] writes, for one instruction set, a safe function per kernel that
//! takes the set's token and calls an `unsafe fn` compiled with
//! `#[target_feature(enable = ...)]` (the kernel is `#[inline(always)]`, so it is
//! compiled inside it with the set's vector instructions).
//!
//! # Safety
//! The `unsafe fn`s may only run on a CPU with the features they enable. Their only
//! callers are the safe functions of the same module, which take the token that
//! [`crate::cpu::cpu_features`] hands out only when it found these features.

/// Safe, token-gated entry points to the strip kernels for one instruction set.
macro_rules! entry_points {
    ($token:ty, $features:literal) => {
        use crate::mosaic::kernel::{self, Bilinear, IntSample, Scratch, StripOut, Superpixel};
        use crate::stokes::{PixelCounts, Sample};

        /// [`kernel::bilinear_strip`] for this instruction set.
        #[inline]
        pub(in crate::mosaic) fn bilinear_strip<T: Sample, const ROUND: bool, const POLAR: bool>(
            _t: $token,
            job: &Bilinear<'_, T>,
            out: &mut StripOut<'_>,
            sc: &mut Scratch,
        ) -> PixelCounts {
            // SAFETY: the token proves the CPU has the enabled features.
            unsafe { bilinear_strip_tf::<T, ROUND, POLAR>(job, out, sc) }
        }

        /// # Safety
        /// The CPU has the enabled features.
        #[target_feature(enable = $features)]
        unsafe fn bilinear_strip_tf<T: Sample, const ROUND: bool, const POLAR: bool>(
            job: &Bilinear<'_, T>,
            out: &mut StripOut<'_>,
            sc: &mut Scratch,
        ) -> PixelCounts {
            kernel::bilinear_strip::<T, ROUND, POLAR>(job, out, sc)
        }

        /// [`kernel::superpixel_strip`] for this instruction set.
        #[inline]
        pub(in crate::mosaic) fn superpixel_strip<T: Sample, const POLAR: bool>(
            _t: $token,
            job: &Superpixel<'_, T>,
            out: &mut StripOut<'_>,
            sc: &mut Scratch,
        ) -> PixelCounts {
            // SAFETY: the token proves the CPU has the enabled features.
            unsafe { superpixel_strip_tf::<T, POLAR>(job, out, sc) }
        }

        /// # Safety
        /// The CPU has the enabled features.
        #[target_feature(enable = $features)]
        unsafe fn superpixel_strip_tf<T: Sample, const POLAR: bool>(
            job: &Superpixel<'_, T>,
            out: &mut StripOut<'_>,
            sc: &mut Scratch,
        ) -> PixelCounts {
            kernel::superpixel_strip::<T, POLAR>(job, out, sc)
        }

        /// [`kernel::demosaic_strip`] for this instruction set.
        #[inline]
        pub(in crate::mosaic) fn demosaic_strip<T: Sample, const ROUND: bool>(
            _t: $token,
            job: &Bilinear<'_, T>,
            dark: f32,
            y0: usize,
            out: [&mut [f32]; 4],
        ) {
            // SAFETY: the token proves the CPU has the enabled features.
            unsafe { demosaic_strip_tf::<T, ROUND>(job, dark, y0, out) }
        }

        /// # Safety
        /// The CPU has the enabled features.
        #[target_feature(enable = $features)]
        unsafe fn demosaic_strip_tf<T: Sample, const ROUND: bool>(
            job: &Bilinear<'_, T>,
            dark: f32,
            y0: usize,
            out: [&mut [f32]; 4],
        ) {
            kernel::demosaic_strip::<T, ROUND>(job, dark, y0, out)
        }

        /// [`kernel::demosaic_int_strip`] for this instruction set.
        #[inline]
        pub(in crate::mosaic) fn demosaic_int_strip<T: IntSample>(
            _t: $token,
            job: &Bilinear<'_, T>,
            y0: usize,
            out: [&mut [T]; 4],
        ) {
            // SAFETY: the token proves the CPU has the enabled features.
            unsafe { demosaic_int_strip_tf::<T>(job, y0, out) }
        }

        /// # Safety
        /// The CPU has the enabled features.
        #[target_feature(enable = $features)]
        unsafe fn demosaic_int_strip_tf<T: IntSample>(
            job: &Bilinear<'_, T>,
            y0: usize,
            out: [&mut [T]; 4],
        ) {
            kernel::demosaic_int_strip::<T>(job, y0, out)
        }
    };
}

pub(super) use entry_points;
