//! Linear Stokes vectors from polarizer frames, and the DoLP / AoLP images.
//!
//! A linear polarizer at angle `a` passes (CONVENTIONS, Optics)
//!
//! ```text
//! I(a) = (S0 + S1 cos 2a + S2 sin 2a) / 2
//! ```
//!
//! so `N >= 3` frames at angles `a_1 … a_N` give the linear system `I = A S` with the
//! `N × 3` design matrix `A_i = ½ (1, cos 2a_i, sin 2a_i)`. [`StokesSolver`] solves it
//! by least squares, `S = P I` with the pseudo-inverse `P = (AᵀA)⁻¹ Aᵀ` (3 × N) computed
//! once per angle set. For 0/45/90/135° this is exactly `S0 = ½ ΣI`, `S1 = I(0) − I(90)`,
//! `S2 = I(45) − I(135)`; for 0/60/120° it is `S0 = ⅔ ΣI` and so on.
//!
//! Raw frames first have the dark level subtracted; pixels whose raw value reaches the
//! saturation level in any frame, whose dark-subtracted `S0` is at or below
//! [`PixelRules::min_s0`] ("dark"), or whose raw value is not finite are flagged in a mask
//! (see [`mask`]) and counted ([`PixelCounts`]). Their Stokes values are still written.
//!
//! DoLP and AoLP (CONVENTIONS): `DoLP = √(S1² + S2²) / S0` clamped to `[0, 1]`,
//! `AoLP = atan2(S2, S1) / 2` in degrees in `[0, 180)`. Both are NaN where the mask
//! rejects the pixel or `S0 <= 0`.
//!
//! All kernels write into caller-owned buffers, run in parallel over image rows (rayon)
//! and keep their inner loops free of branches so that they vectorise.
//!
//! # Files
//! | file          | contents                                                            |
//! |---------------|---------------------------------------------------------------------|
//! | `solver.rs`   | [`StokesSolver`]: least squares for any `N ≥ 3` angles               |
//! | `quad/`       | the fused exact 0/45/90/135° kernel, portable and AVX2 + FMA         |
//! | `polar.rs`    | DoLP / AoLP ([`dolp_aolp`], [`dolp_aolp_pixel`], [`atan2_fast`])     |
//! | `pixels.rs`   | [`Sample`], [`PixelRules`], [`PixelCounts`], [`mask_stokes`], checks |
//! | `mask.rs`     | the mask values ([`mask`])                                          |
//!
//! # Reference
//! J. S. Tyo, D. L. Goldstein, D. B. Chenault and J. A. Shaw, "Review of passive
//! imaging polarimetry for remote sensing applications", *Applied Optics* 45(22),
//! 5453–5469, 2006 (the linear Stokes polarimeter `I = A S` and its least-squares data
//! reduction).

pub mod mask;
mod pixels;
mod polar;
mod quad;
mod solver;

pub(crate) use pixels::check_image;
#[cfg(test)]
pub(crate) use pixels::finish_mask_row;
pub use pixels::{PixelCounts, PixelRules, Sample, mask_stokes};
pub use polar::{atan2_fast, dolp_aolp, dolp_aolp_pixel};
pub use solver::{ILL_CONDITIONED, SINGULAR, StokesSolver};
