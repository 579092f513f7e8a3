//! The exact 0/45/90/135° Stokes kernel over a whole image, fused with the mask, the
//! counts and (optionally) DoLP/AoLP: one pass, every output written once, blocks of
//! [`ROWS_PER_TASK`] rows in parallel (rayon).
//!
//! # Instruction sets
//! The per-pixel code (`kernel.rs`) is portable and branch-free; `avx2.rs` compiles the
//! same code for AVX2 + FMA (`#[target_feature]`), which lets the compiler use 256-bit
//! vectors. Rust does not contract `a·b + c` into a fused multiply-add, so both give
//! the same bits. The AVX2 version is reached only through a safe function that takes
//! the [`crate::cpu::Avx2Fma`] token, i.e. only when [`crate::cpu::cpu_features`]
//! found the features.

mod kernel;

#[cfg(target_arch = "x86_64")]
mod avx2;

use rayon::prelude::*;

pub(super) use kernel::quad_row_raw;

use super::pixels::{PixelCounts, PixelRules, Sample};
use crate::cpu::Isa;

/// Rows per parallel task of the image kernels (big enough to amortise scheduling,
/// small enough to balance two to a few dozen threads).
const ROWS_PER_TASK: usize = 16;

/// The exact 0/45/90/135° kernel over a whole image, fused with the mask, the counts
/// and (when `POLAR`) DoLP/AoLP: one pass, every output written once.
/// `isa`: the instruction set to run (`cpu_features().best()` in production).
#[allow(clippy::too_many_arguments)]
pub(super) fn quad_image<T: Sample, const POLAR: bool>(
    isa: Isa,
    q: [&[T]; 4],
    width: usize,
    rules: &PixelRules,
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    mask: &mut [u8],
    dolp: &mut [f32],
    aolp: &mut [f32],
) -> PixelCounts {
    let chunk = width * ROWS_PER_TASK;
    let base = s0
        .par_chunks_mut(chunk)
        .zip(s1.par_chunks_mut(chunk))
        .zip(s2.par_chunks_mut(chunk))
        .zip(mask.par_chunks_mut(chunk))
        .enumerate();
    let rows_at = |i: usize, len: usize| {
        let off = i * chunk;
        [
            &q[0][off..off + len],
            &q[1][off..off + len],
            &q[2][off..off + len],
            &q[3][off..off + len],
        ]
    };
    if POLAR {
        base.zip(dolp.par_chunks_mut(chunk))
            .zip(aolp.par_chunks_mut(chunk))
            .map(|(((i, (((c0, c1), c2), cm)), cd), ca)| {
                let rows = rows_at(i, c0.len());
                quad_block_dispatch::<T, true>(isa, rows, rules, c0, c1, c2, cm, cd, ca)
            })
            .reduce(PixelCounts::default, PixelCounts::add)
    } else {
        base.map(|(i, (((c0, c1), c2), cm))| {
            let rows = rows_at(i, c0.len());
            quad_block_dispatch::<T, false>(isa, rows, rules, c0, c1, c2, cm, &mut [], &mut [])
        })
        .reduce(PixelCounts::default, PixelCounts::add)
    }
}

/// One block with the AVX2 kernel when `isa` proves AVX2 + FMA (AVX-512 implies them;
/// the kernel has no wider version), else with the portable one.
#[allow(clippy::too_many_arguments)]
#[inline]
fn quad_block_dispatch<T: Sample, const POLAR: bool>(
    isa: Isa,
    q: [&[T]; 4],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
    rd: &mut [f32],
    ra: &mut [f32],
) -> PixelCounts {
    #[cfg(target_arch = "x86_64")]
    if let Some(t) = isa.avx2_fma() {
        return avx2::quad_block::<T, POLAR>(t, q, rules, r0, r1, r2, rm, rd, ra);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = isa;
    kernel::quad_block::<T, POLAR>(q, rules, r0, r1, r2, rm, rd, ra)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::cpu_features;
    use crate::stokes::{StokesSolver, mask};

    /// The exact 0/45/90/135 kernel (any frame order) agrees with the least-squares
    /// solution of every pixel, and flags saturated, dark and non-finite pixels.
    #[test]
    fn quad_kernel_matches_least_squares() {
        let (w, h) = (37usize, 21usize);
        let n = w * h;
        let order = [90.0, 0.0, 135.0, 45.0];
        let solver = StokesSolver::from_degrees(&order).unwrap();
        assert!(solver.is_standard_quad());
        assert!(
            !StokesSolver::from_degrees(&[0.0, 60.0, 120.0])
                .unwrap()
                .is_standard_quad()
        );
        let mut frames = vec![vec![0f32; n]; 4];
        let mut x = 12345u64;
        for i in 0..n {
            for f in frames.iter_mut() {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                f[i] = ((x >> 33) % 4000) as f32;
            }
        }
        frames[0][5] = 4095.0;
        frames[2][7] = f32::NAN;
        for f in frames.iter_mut() {
            f[9] = 10.0;
        }
        let rules = PixelRules {
            dark_level: 8.0,
            saturation: 4095.0,
            min_s0: 20.0,
        };
        let views: Vec<&[f32]> = frames.iter().map(|f| f.as_slice()).collect();
        let mut o: Vec<Vec<f32>> = vec![vec![0f32; n]; 5];
        let mut m = vec![0u8; n];
        let [s0, s1, s2, d, a] = &mut o[..] else {
            unreachable!()
        };
        let c = solver
            .compute_with_polar(&views, w, &rules, s0, s1, s2, &mut m, d, a)
            .unwrap();
        assert_eq!((c.saturated, c.invalid, c.dark), (1, 1, 1));
        assert_eq!(c.valid, n as u64 - 3);
        assert_eq!(
            (m[5], m[7], m[9]),
            (mask::SATURATED, mask::INVALID, mask::DARK)
        );
        for i in 0..n {
            if i == 7 {
                continue;
            }
            let iv: Vec<f64> = views.iter().map(|f| f[i] as f64 - 8.0).collect();
            let r = solver.solve(&iv).unwrap();
            for (got, want) in [o[0][i], o[1][i], o[2][i]].iter().zip(r) {
                assert!(
                    (*got as f64 - want).abs() < 1e-3,
                    "pixel {i}: {got} vs {want}"
                );
            }
            if m[i] == mask::VALID {
                let want = ((r[1] * r[1] + r[2] * r[2]).sqrt() / r[0]).min(1.0);
                assert!((o[3][i] as f64 - want).abs() < 1e-5);
            } else {
                assert!(o[3][i].is_nan() && o[4][i].is_nan());
            }
        }
    }

    /// The detected kernel (AVX2 + FMA here when the CPU has them) and the forced
    /// portable one give the same bits: Stokes, mask, counts, DoLP and AoLP, with and
    /// without the fused polar outputs, on `u16` and `f32` frames with saturated, dark
    /// and non-finite pixels, for a width that leaves a partial block.
    #[test]
    fn portable_matches_detected() {
        let (w, h) = (53usize, 41usize);
        let n = w * h;
        let mut x = 987654321u64;
        let mut next = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 33) as u32
        };
        let mut frames: Vec<Vec<u16>> = (0..4)
            .map(|_| (0..n).map(|_| (next() % 4096) as u16).collect())
            .collect();
        for f in frames.iter_mut() {
            f[5] = 10;
            f[200] = 3;
        }
        let mut framesf: Vec<Vec<f32>> = frames
            .iter()
            .map(|f| f.iter().map(|&v| v as f32 + 0.37).collect())
            .collect();
        framesf[1][17] = f32::NAN;
        framesf[3][99] = f32::INFINITY;
        let rules = PixelRules {
            dark_level: 11.5,
            saturation: 4000.0,
            min_s0: 30.0,
        };
        let detected = cpu_features().best();
        fn run<T: Sample>(
            isa: Isa,
            q: [&[T]; 4],
            w: usize,
            rules: &PixelRules,
            polar: bool,
        ) -> (Vec<Vec<u32>>, Vec<u8>, PixelCounts) {
            let n = q[0].len();
            let mut o = vec![vec![0f32; n]; 5];
            let mut m = vec![0u8; n];
            let [s0, s1, s2, d, a] = &mut o[..] else {
                unreachable!()
            };
            let c = if polar {
                quad_image::<T, true>(isa, q, w, rules, s0, s1, s2, &mut m, d, a)
            } else {
                quad_image::<T, false>(isa, q, w, rules, s0, s1, s2, &mut m, &mut [], &mut [])
            };
            let bits = o
                .iter()
                .map(|v| v.iter().map(|f| f.to_bits()).collect())
                .collect();
            (bits, m, c)
        }
        for polar in [false, true] {
            let q = [
                &frames[0][..],
                &frames[1][..],
                &frames[2][..],
                &frames[3][..],
            ];
            let p = run(Isa::Portable, q, w, &rules, polar);
            assert!(p.2.saturated > 0 && p.2.dark > 0 && p.2.valid > 0);
            assert_eq!(p, run(detected, q, w, &rules, polar));
            let q = [
                &framesf[0][..],
                &framesf[1][..],
                &framesf[2][..],
                &framesf[3][..],
            ];
            let p = run(Isa::Portable, q, w, &rules, polar);
            assert_eq!(p.2.invalid, 2);
            assert_eq!(p, run(detected, q, w, &rules, polar));
        }
    }
}
