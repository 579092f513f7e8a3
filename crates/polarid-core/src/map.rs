//! Per-pixel material maps: the paper's pipeline (sections 4–6) applied to every pixel
//! instead of a 100 × 100 region average.
//!
//! For every (optionally binned) pixel:
//!
//! 1. **Stokes per capture** from the polarizer frames (`S0, S1, S2`, see
//!    [`crate::stokes`]; dark level subtracted), summed over `b × b` blocks when binning
//!    (`b = 1, 2, 4, …`; summing raw frames and summing Stokes vectors are the same
//!    linear operation), then the DoLP
//!    `P = √(S1² + S2²) / S0` clamped to `[0, 1]` ([`frames_dolp`], [`stokes_dolp`]).
//!    Only the DoLP (f32) of each capture is kept, so memory holds `T` DoLP images and
//!    one capture's frames at a time.
//! 2. **Rejection by signal**: a pixel is left unclassified when, in any capture, a raw
//!    value of its block reached the saturation level, a value is not finite, or the
//!    block's mean dark-subtracted `S0` is at or below the dark threshold
//!    ([`flag`]; reasons in [`reason`]).
//! 3. **(n, k) fit** of the remaining pixels' `T` DoLP values against paper eq. (9),
//!    unweighted (covariance scaled by the reduced χ²) or weighted by every pixel's DoLP
//!    standard errors from the noise model ([`noise`], [`MapNoise`]; covariance
//!    `(JᵀWJ)⁻¹`), in tiles of pixels so that the
//!    fit's working memory stays small ([`fit_and_classify`]). The local incidence
//!    angles ([`Betas`]) are one per capture (the far field: one [`FitPlan`] shared by
//!    every pixel, [`fit_batch`]) or one per pixel and capture (calibrated geometry:
//!    β images from [`crate::geometry::ViewGeometry::fill`], [`fit_batch_pixel_beta`]);
//!    a pixel without a finite β in some capture (its ray misses its plane, or the
//!    source is below the plane's horizon there) is not fitted
//!    ([`reason::NO_GEOMETRY`]).
//! 4. **Class**: the nearest prototype in `(n, k)` (paper section 6, Euclidean
//!    distance, [`Classifier::nearest_euclidean`]), optionally rejected beyond a maximum
//!    distance. Pixels whose fit status is not `ok` are not classified. (The set rule's
//!    covariance of a pixel, with the systematic error model, is [`sets`].)
//!
//! Class indices in the map are 1-based into [`PixelClassifier::names`] (sorted class
//! names); 0 means "not classified", with the reason in the reason image.

pub mod noise;
pub mod sets;

use std::collections::BTreeSet;

use rayon::prelude::*;

use crate::classify::{Classifier, Cov2};
use crate::error::{CoreError, Result, check_len};
use crate::fit::{FitPlan, FitStatus, NkFit, PixelBetaPlan, fit_batch, fit_batch_pixel_beta};
use crate::stokes::{PixelRules, Sample, StokesSolver, check_image, mask};
use noise::NoiseModel;

/// Signal flag bits accumulated per pixel over the captures (OR of every capture).
pub mod flag {
    /// A raw value of the pixel's block reached the saturation level.
    pub const SATURATED: u8 = 1;
    /// The block's mean dark-subtracted `S0` is at or below the dark threshold.
    pub const DARK: u8 = 2;
    /// A raw value or Stokes component is not finite.
    pub const INVALID: u8 = 4;
}

/// Why a map pixel is (not) classified: the values of the reason image.
pub mod reason {
    /// Classified.
    pub const CLASSIFIED: u8 = 0;
    /// Saturated in at least one capture.
    pub const SATURATED: u8 = 1;
    /// Too dark (low `S0`) in at least one capture.
    pub const DARK: u8 = 2;
    /// Non-finite data in at least one capture.
    pub const INVALID: u8 = 3;
    /// The fit is ill-conditioned.
    pub const FIT_ILL_CONDITIONED: u8 = 4;
    /// The fit did not converge.
    pub const FIT_NOT_CONVERGED: u8 = 5;
    /// The fit's minimum lies on the edge of the `(n, k)` box.
    pub const FIT_AT_BOUND: u8 = 6;
    /// The fit rejected the pixel's DoLP values.
    pub const FIT_INVALID_INPUT: u8 = 7;
    /// Not placed: the nearest prototype is farther than the maximum distance (nearest
    /// rule), or no material is consistent with the estimate (set rule: `unknown`).
    pub const REJECTED: u8 = 8;
    /// No geometry (calibrated maps only): in some capture the pixel's ray misses its
    /// plane or the source is below the plane's horizon, so it has no β there.
    pub const NO_GEOMETRY: u8 = 9;
    /// Set rule: several materials are consistent with the pixel's estimate (its class
    /// is the map's `ambiguous` class).
    pub const AMBIGUOUS: u8 = 10;
    /// Number of reasons.
    pub const COUNT: usize = 11;
    /// The word of each reason (index = reason value), as written in summaries.
    pub const NAMES: [&str; COUNT] = [
        "classified",
        "saturated",
        "dark",
        "invalid",
        "fit_ill_conditioned",
        "fit_not_converged",
        "fit_at_bound",
        "fit_invalid_input",
        "rejected",
        "no_geometry",
        "ambiguous",
    ];
}

/// The reason of a pixel's signal flags ([`flag`]): invalid before saturated before
/// dark; [`reason::CLASSIFIED`] (0) when no flag is set.
#[inline]
pub fn signal_reason(flags: u8) -> u8 {
    if flags & flag::INVALID != 0 {
        reason::INVALID
    } else if flags & flag::SATURATED != 0 {
        reason::SATURATED
    } else if flags & flag::DARK != 0 {
        reason::DARK
    } else {
        reason::CLASSIFIED
    }
}

/// Size of the map of a `width × height` frame binned by `bin` (incomplete blocks at
/// the right and bottom edges are dropped). Errors: `bin` is 0 or larger than the
/// frame.
pub fn binned_size(width: usize, height: usize, bin: usize) -> Result<(usize, usize)> {
    if bin == 0 || bin > width || bin > height {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: format!("binning factor {bin} must be >= 1 and fit in the frame"),
        });
    }
    Ok((width / bin, height / bin))
}

/// Per-thread row buffers of the DoLP kernels.
struct RowBufs {
    r0: Vec<f32>,
    r1: Vec<f32>,
    r2: Vec<f32>,
    rm: Vec<u8>,
    a0: Vec<f32>,
    a1: Vec<f32>,
    a2: Vec<f32>,
    am: Vec<u8>,
}

impl RowBufs {
    fn new(width: usize, out_width: usize) -> Self {
        Self {
            r0: vec![0.0; width],
            r1: vec![0.0; width],
            r2: vec![0.0; width],
            rm: vec![0; width],
            a0: vec![0.0; out_width],
            a1: vec![0.0; out_width],
            a2: vec![0.0; out_width],
            am: vec![0; out_width],
        }
    }
}

/// DoLP of one block from its summed Stokes: `√(S1² + S2²)/S0` clamped to `[0, 1]`,
/// NaN when `S0 <= 0` or a value is not finite; the flags gain DARK / INVALID.
#[inline(always)]
fn block_dolp(s0: f32, s1: f32, s2: f32, inv_area: f32, min_s0: f32, f: &mut u8) -> f32 {
    let mean0 = s0 * inv_area;
    let finite = s0.is_finite() && s1.is_finite() && s2.is_finite();
    *f |= ((!finite as u8) * flag::INVALID) | (((mean0 <= min_s0) as u8) * flag::DARK);
    let d = ((s1 * s1 + s2 * s2).sqrt() / s0).clamp(0.0, 1.0);
    if finite && s0 > 0.0 { d } else { f32::NAN }
}

/// The shared binning driver: `fill(y, bufs)` writes raw row `y`'s Stokes into
/// `bufs.r0..r2` and raw flag bits into `bufs.rm` (bit 0 saturated, bit 1 not finite).
fn binned_dolp<F>(
    width: usize,
    bin: usize,
    min_s0: f32,
    dolp: &mut [f32],
    flags: &mut [u8],
    noise: Option<NoiseOut<'_>>,
    fill: F,
) -> Result<()>
where
    F: Fn(usize, &mut RowBufs) + Sync,
{
    let ow = width / bin;
    let oh = dolp.len() / ow.max(1);
    let inv_area = 1.0 / (bin * bin) as f32;
    let (an, scale, noise_rows) = match noise {
        Some(n) => {
            check_len("noise read terms", n.read.len(), dolp.len())?;
            check_len("noise shot terms", n.shot.len(), dolp.len())?;
            (
                Some(n.analyzer),
                n.scale,
                rayon::iter::Either::Left(
                    n.read
                        .par_chunks_mut(ow)
                        .zip(n.shot.par_chunks_mut(ow))
                        .map(Some),
                ),
            )
        }
        None => (
            None,
            1.0,
            rayon::iter::Either::Right((0..oh).into_par_iter().map(|_| None)),
        ),
    };
    let bin2 = (bin * bin) as f64;
    // The noise terms of a row of blocks from their summed Stokes vectors.
    let terms = |nr: Option<(&mut [f32], &mut [f32])>, a0: &[f32], a1: &[f32], a2: &[f32]| {
        if let (Some(an), Some((ra, rb))) = (an, nr) {
            for i in 0..ra.len() {
                let s = [
                    a0[i] as f64 * scale,
                    a1[i] as f64 * scale,
                    a2[i] as f64 * scale,
                ];
                (ra[i], rb[i]) = noise::noise_terms(an, s, bin2);
            }
        }
    };
    dolp.par_chunks_mut(ow)
        .zip(flags.par_chunks_mut(ow))
        .zip(noise_rows)
        .enumerate()
        .for_each_init(
            || RowBufs::new(width, ow),
            |b, (oy, ((rd, rf), nr))| {
                if bin == 1 {
                    fill(oy, b);
                    for i in 0..ow {
                        let m = b.rm[i];
                        let f = &mut rf[i];
                        *f |= ((m & 1) * flag::SATURATED) | (((m >> 1) & 1) * flag::INVALID);
                        rd[i] = block_dolp(b.r0[i], b.r1[i], b.r2[i], 1.0, min_s0, f);
                    }
                    terms(nr, &b.r0[..ow], &b.r1[..ow], &b.r2[..ow]);
                    return;
                }
                b.a0.fill(0.0);
                b.a1.fill(0.0);
                b.a2.fill(0.0);
                b.am.fill(0);
                for dy in 0..bin {
                    fill(oy * bin + dy, b);
                    let RowBufs {
                        r0,
                        r1,
                        r2,
                        rm,
                        a0,
                        a1,
                        a2,
                        am,
                    } = b;
                    for ((((s0, s1), s2), sm), (((t0, t1), t2), tm)) in r0
                        .chunks_exact(bin)
                        .zip(r1.chunks_exact(bin))
                        .zip(r2.chunks_exact(bin))
                        .zip(rm.chunks_exact(bin))
                        .zip(
                            a0.iter_mut()
                                .zip(a1.iter_mut())
                                .zip(a2.iter_mut())
                                .zip(am.iter_mut()),
                        )
                    {
                        *t0 += s0.iter().sum::<f32>();
                        *t1 += s1.iter().sum::<f32>();
                        *t2 += s2.iter().sum::<f32>();
                        *tm |= sm.iter().fold(0u8, |a, &m| a | m);
                    }
                }
                for i in 0..ow {
                    let m = b.am[i];
                    let f = &mut rf[i];
                    *f |= ((m & 1) * flag::SATURATED) | (((m >> 1) & 1) * flag::INVALID);
                    rd[i] = block_dolp(b.a0[i], b.a1[i], b.a2[i], inv_area, min_s0, f);
                }
                terms(nr, &b.a0, &b.a1, &b.a2);
            },
        );
    Ok(())
}

/// Where the DoLP kernels write the noise terms of every block
/// ([`noise::noise_terms`]): one image each of `A` (read) and `B` (shot), of the
/// binned size.
#[derive(Debug)]
pub struct NoiseOut<'a> {
    /// The capture's analyzer.
    pub analyzer: &'a noise::NoiseAnalyzer,
    /// Factor from the block's Stokes values to DN (1 for frames; the exposure for
    /// Stokes captures in DN / exposure).
    pub scale: f64,
    /// `A` of every block.
    pub read: &'a mut [f32],
    /// `B` of every block.
    pub shot: &'a mut [f32],
}

/// DoLP image of one capture from its polarizer frames (one per angle of `solver`,
/// `width` pixels wide), binned by `bin`: writes `dolp` (binned size, see
/// [`binned_size`]) and ORs the capture's signal [`flag`]s into `flags` (callers zero
/// `flags` once before the first capture). `rules.min_s0` is compared with the block's
/// mean `S0`.
pub fn frames_dolp<T: Sample>(
    solver: &StokesSolver,
    frames: &[&[T]],
    width: usize,
    rules: &PixelRules,
    bin: usize,
    dolp: &mut [f32],
    flags: &mut [u8],
) -> Result<()> {
    frames_dolp_noise(solver, frames, width, rules, bin, dolp, flags, None)
}

/// [`frames_dolp`], writing also the noise terms of every block into `noise` (see
/// [`noise`]; its analyzer should be [`noise::NoiseAnalyzer::of_solver`] of `solver`,
/// its scale 1).
#[allow(clippy::too_many_arguments)]
pub fn frames_dolp_noise<T: Sample>(
    solver: &StokesSolver,
    frames: &[&[T]],
    width: usize,
    rules: &PixelRules,
    bin: usize,
    dolp: &mut [f32],
    flags: &mut [u8],
    noise: Option<NoiseOut<'_>>,
) -> Result<()> {
    rules.validate()?;
    check_len("frames", frames.len(), solver.len())?;
    let n = frames.first().map_or(0, |f| f.len());
    check_image(width, n)?;
    for f in frames {
        check_len("frame", f.len(), n)?;
    }
    let (ow, oh) = binned_size(width, n / width, bin)?;
    check_len("dolp", dolp.len(), ow * oh)?;
    check_len("flags", flags.len(), ow * oh)?;
    let coef = solver.coef_f32();
    binned_dolp(width, bin, rules.min_s0, dolp, flags, noise, |y, b| {
        let off = y * width;
        // At most a handful of frames: a fixed array of row slices avoids allocating.
        const MAX: usize = 16;
        if frames.len() <= MAX {
            let mut rows: [&[T]; MAX] = [&[]; MAX];
            for (r, f) in rows.iter_mut().zip(frames) {
                *r = &f[off..off + width];
            }
            solver.stokes_row_raw(
                &rows[..frames.len()],
                &coef,
                rules,
                &mut b.r0,
                &mut b.r1,
                &mut b.r2,
                &mut b.rm,
            );
        } else {
            let rows: Vec<&[T]> = frames.iter().map(|f| &f[off..off + width]).collect();
            solver.stokes_row_raw(
                &rows, &coef, rules, &mut b.r0, &mut b.r1, &mut b.r2, &mut b.rm,
            );
        }
    })
}

/// DoLP image of one capture from Stokes images (DoFP captures after demosaicing, or
/// Stokes captures), binned by `bin`. `mask` (values of [`crate::stokes::mask`]) marks
/// saturated and invalid pixels; its DARK values are ignored (the dark test is made
/// on the block mean `S0` against `min_s0`). Outputs as in [`frames_dolp`].
#[allow(clippy::too_many_arguments)]
pub fn stokes_dolp(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    stokes_mask: Option<&[u8]>,
    min_s0: f32,
    bin: usize,
    dolp: &mut [f32],
    flags: &mut [u8],
) -> Result<()> {
    stokes_dolp_noise(
        width,
        s0,
        s1,
        s2,
        stokes_mask,
        min_s0,
        bin,
        dolp,
        flags,
        None,
    )
}

/// [`stokes_dolp`], writing also the noise terms of every block into `noise` (see
/// [`noise`]; its analyzer [`noise::NoiseAnalyzer::quad`], its scale the factor from
/// the Stokes values to DN).
#[allow(clippy::too_many_arguments)]
pub fn stokes_dolp_noise(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    stokes_mask: Option<&[u8]>,
    min_s0: f32,
    bin: usize,
    dolp: &mut [f32],
    flags: &mut [u8],
    noise: Option<NoiseOut<'_>>,
) -> Result<()> {
    let n = s0.len();
    check_image(width, n)?;
    check_len("s1", s1.len(), n)?;
    check_len("s2", s2.len(), n)?;
    if let Some(m) = stokes_mask {
        check_len("mask", m.len(), n)?;
    }
    crate::error::ensure_finite("min_s0", min_s0 as f64)?;
    let (ow, oh) = binned_size(width, n / width, bin)?;
    check_len("dolp", dolp.len(), ow * oh)?;
    check_len("flags", flags.len(), ow * oh)?;
    binned_dolp(width, bin, min_s0, dolp, flags, noise, |y, b| {
        let r = y * width..(y + 1) * width;
        b.r0.copy_from_slice(&s0[r.clone()]);
        b.r1.copy_from_slice(&s1[r.clone()]);
        b.r2.copy_from_slice(&s2[r.clone()]);
        match stokes_mask {
            Some(m) => {
                for (o, &v) in b.rm.iter_mut().zip(&m[r]) {
                    *o = (v == mask::SATURATED) as u8 | ((v == mask::INVALID) as u8) << 1;
                }
            }
            None => b.rm.fill(0),
        }
    })
}

/// The per-pixel classifier: nearest prototype in `(n, k)` with an optional maximum
/// distance, and the map's class indices.
#[derive(Debug, Clone)]
pub struct PixelClassifier {
    classifier: Classifier,
    names: Vec<String>,
    /// 1-based class index of each prototype.
    proto_class: Vec<u16>,
    max_distance: Option<f64>,
    mahalanobis: bool,
}

impl PixelClassifier {
    /// Wrap a classifier; `max_distance` (Euclidean, in `(n, k)` units) rejects pixels
    /// whose nearest prototype is farther. Errors: more than 65535 classes, or a
    /// maximum distance that is not finite and positive.
    pub fn new(classifier: Classifier, max_distance: Option<f64>) -> Result<Self> {
        if let Some(d) = max_distance
            && !(d.is_finite() && d > 0.0)
        {
            return Err(CoreError::OutOfRange {
                name: "maximum distance",
                value: d,
                expected: "finite and > 0",
            });
        }
        let names: Vec<String> = classifier
            .prototypes()
            .iter()
            .map(|p| p.class.clone())
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();
        if names.len() > u16::MAX as usize {
            return Err(CoreError::OutOfRange {
                name: "number of classes",
                value: names.len() as f64,
                expected: "<= 65535",
            });
        }
        let proto_class = classifier
            .prototypes()
            .iter()
            .map(|p| {
                names
                    .iter()
                    .position(|n| *n == p.class)
                    .map_or(0, |i| i as u16 + 1)
            })
            .collect();
        Ok(Self {
            classifier,
            names,
            proto_class,
            max_distance,
            mahalanobis: false,
        })
    }

    /// Number of class indices of the map, including 0 (not classified).
    pub fn class_count(&self) -> usize {
        self.names.len() + 1
    }

    /// The class and reason of a pixel's fit.
    fn decide(&self, f: &NkFit) -> (u16, u8) {
        match f.status {
            FitStatus::Ok => {}
            FitStatus::IllConditioned => return (0, reason::FIT_ILL_CONDITIONED),
            FitStatus::NotConverged => return (0, reason::FIT_NOT_CONVERGED),
            FitStatus::AtBound => return (0, reason::FIT_AT_BOUND),
            // `fit_batch` never reports `depolarized` or `model_mismatch` (per-target
            // rules of the table fit); a pixel would count as unusable input.
            FitStatus::InvalidInput | FitStatus::Depolarized | FitStatus::ModelMismatch => {
                return (0, reason::FIT_INVALID_INPUT);
            }
        }
        match self.classify_fit(f) {
            Ok((c, _)) => (c, reason::CLASSIFIED),
            Err(r) => (0, r),
        }
    }

    /// Rank prototypes by the Mahalanobis distance
    /// `d² = Δᵀ (Σ_pixel + Σ_proto)⁻¹ Δ` with the pixel fit's covariance (from `n_se`,
    /// `k_se`, `nk_corr`) instead of the Euclidean distance; `max_distance` is then in
    /// standard deviations. Pixels without a usable covariance fall back to Euclidean.
    pub fn with_mahalanobis(mut self, on: bool) -> Self {
        self.mahalanobis = on;
        self
    }

    /// Classify a pixel's fit ([`Self::classify`], or the Mahalanobis ranking when
    /// enabled and the fit has a covariance).
    #[inline]
    pub fn classify_fit(&self, f: &NkFit) -> std::result::Result<(u16, f64), u8> {
        if self.mahalanobis {
            let corr = if f.nk_corr.is_finite() {
                f.nk_corr
            } else {
                0.0
            };
            if let Some(cov) = Cov2::from_se(f.n_se, f.k_se, corr.clamp(-1.0, 1.0)) {
                let mut best = (usize::MAX, f64::INFINITY);
                for (i, p) in self.classifier.prototypes().iter().enumerate() {
                    let c = match p.cov {
                        Some(pc) => cov + pc,
                        None => cov,
                    };
                    if let Some(d2) = c.mahalanobis2(f.n - p.n, f.k - p.k)
                        && d2 < best.1
                    {
                        best = (i, d2);
                    }
                }
                if best.0 != usize::MAX {
                    let d = best.1.sqrt();
                    if self.max_distance.is_some_and(|m| d > m) {
                        return Err(reason::REJECTED);
                    }
                    return Ok((self.proto_class.get(best.0).copied().unwrap_or(0), d));
                }
            }
        }
        self.classify(f.n, f.k)
    }

    /// Class names, sorted; map index `i >= 1` is `names()[i - 1]`.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The 1-based class index of `(n, k)` and its distance, or `Err(reason)` when
    /// not classified ([`reason::REJECTED`], or [`reason::FIT_INVALID_INPUT`] for a
    /// non-finite estimate).
    #[inline]
    pub fn classify(&self, n: f64, k: f64) -> std::result::Result<(u16, f64), u8> {
        let (i, d) = self
            .classifier
            .nearest_euclidean(n, k)
            .ok_or(reason::FIT_INVALID_INPUT)?;
        if self.max_distance.is_some_and(|m| d > m) {
            return Err(reason::REJECTED);
        }
        Ok((self.proto_class.get(i).copied().unwrap_or(0), d))
    }
}

/// The local incidence angles `β` (eq. 5) of a map's fit.
#[derive(Debug, Clone, Copy)]
pub enum Betas<'a> {
    /// One β per capture (the far field): the plan of that β set, shared by every
    /// pixel.
    Shared(&'a FitPlan),
    /// A β per pixel and capture (calibrated geometry).
    PerPixel {
        /// The grid and column cache of the fit (its options apply).
        plan: &'a PixelBetaPlan,
        /// One β image per capture (radians, in the order of the DoLP images, each of
        /// the map's size); NaN (any non-finite value) where the pixel has no geometry.
        beta: &'a [&'a [f32]],
    },
}

impl<'a> From<&'a FitPlan> for Betas<'a> {
    fn from(plan: &'a FitPlan) -> Self {
        Betas::Shared(plan)
    }
}

/// The caller-owned output images of [`fit_and_classify`] (all of the map's size).
#[derive(Debug)]
pub struct MapOutputs<'a> {
    /// Fitted `n` (NaN where not fitted).
    pub n: &'a mut [f32],
    /// Fitted `k`.
    pub k: &'a mut [f32],
    /// Standard error of `n`.
    pub n_se: &'a mut [f32],
    /// Standard error of `k`.
    pub k_se: &'a mut [f32],
    /// RMS DoLP residual of the fit.
    pub rms_residual: &'a mut [f32],
    /// Class index (0 = not classified).
    pub class: &'a mut [u16],
    /// Reason ([`reason`]).
    pub reason: &'a mut [u8],
}

/// Pixel counts of a map.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct MapCounts {
    /// Pixels per reason (index = [`reason`] value; index 0 = classified).
    pub reasons: [u64; reason::COUNT],
    /// Pixels per class index (index 0 = not classified).
    pub classes: Vec<u64>,
}

/// The noise model of a map's fit: the model and the noise terms of every capture
/// ([`noise`]), one image each (map size, in the order of the DoLP images).
#[derive(Debug, Clone, Copy)]
pub struct MapNoise<'a> {
    /// The model's parameters.
    pub model: NoiseModel,
    /// `A` (read-noise term) of every capture.
    pub read: &'a [&'a [f32]],
    /// `B` (shot-noise term) of every capture.
    pub shot: &'a [&'a [f32]],
}

/// Fit and classify every pixel of a map, in tiles of `tile` pixels.
///
/// `betas`: the angles, one per capture ([`Betas::Shared`]) or per pixel and capture
/// ([`Betas::PerPixel`]). `dolp` holds one DoLP image per capture (in the β order,
/// each of the map's size), `flags` the signal [`flag`]s. Pixels without a finite β
/// in some capture (per-pixel angles only) are not fitted (NaN outputs, reason
/// [`reason::NO_GEOMETRY`]), nor are pixels with a flag (reason from
/// [`signal_reason`]); the others are fitted with [`fit_batch`] or
/// [`fit_batch_pixel_beta`] (parallel) and classified when the fit status is `ok`.
/// With `noise`, every pixel's fit is weighted by its DoLP standard errors
/// `√(r² A + B/g)` and its standard errors are those of the weighted covariance
/// `(JᵀWJ)⁻¹`; without, the fit is unweighted and its covariance scaled by the
/// pixel's reduced χ² (the paper's fit). `progress` is called with the number of
/// pixels done after each tile.
///
/// Errors: inconsistent numbers or sizes of images.
#[allow(clippy::too_many_arguments)]
pub fn fit_and_classify(
    betas: Betas<'_>,
    classifier: &PixelClassifier,
    dolp: &[&[f32]],
    noise: Option<MapNoise<'_>>,
    flags: &[u8],
    tile: usize,
    out: MapOutputs<'_>,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<MapCounts> {
    fit_and_classify_corr(
        betas,
        classifier,
        dolp,
        noise,
        flags,
        tile,
        out,
        &mut [],
        progress,
    )
}

/// [`fit_and_classify`], writing also every pixel's fit correlation of `n` and `k`
/// (`NkFit::nk_corr`; NaN where not fitted) into `nk_corr` when it is not empty (then of
/// the map's size): the covariance `classify` reads from a fit row, for decisions made
/// after the fit (`polarid_pipeline::map`).
#[allow(clippy::too_many_arguments)]
pub fn fit_and_classify_corr(
    betas: Betas<'_>,
    classifier: &PixelClassifier,
    dolp: &[&[f32]],
    noise: Option<MapNoise<'_>>,
    flags: &[u8],
    tile: usize,
    out: MapOutputs<'_>,
    nk_corr: &mut [f32],
    progress: &(dyn Fn(usize) + Sync),
) -> Result<MapCounts> {
    let npix = flags.len();
    let t_len = check_map_inputs(betas, dolp, noise.as_ref(), flags, &out, nk_corr)?;
    let inp = MapInput {
        betas,
        classifier,
        dolp,
        noise,
        flags,
        t_len,
    };
    let tile = tile.max(1);
    let mut sink = MapSink {
        out,
        counts: MapCounts {
            reasons: [0; reason::COUNT],
            classes: vec![0; classifier.class_count()],
        },
        nk_corr,
    };
    let mut sc = TileScratch::new(tile.min(npix), t_len);
    let mut start = 0usize;
    while start < npix {
        let end = (start + tile).min(npix);
        inp.run_tile(start..end, &mut sc, &mut sink)?;
        progress(end);
        start = end;
    }
    Ok(sink.counts)
}

/// The size checks of [`fit_and_classify_corr`]; the number of captures.
fn check_map_inputs(
    betas: Betas<'_>,
    dolp: &[&[f32]],
    noise: Option<&MapNoise<'_>>,
    flags: &[u8],
    out: &MapOutputs<'_>,
    nk_corr: &[f32],
) -> Result<usize> {
    let npix = flags.len();
    if !nk_corr.is_empty() {
        check_len("nk_corr", nk_corr.len(), npix)?;
    }
    let t_len = match betas {
        Betas::Shared(plan) => plan.len(),
        Betas::PerPixel { beta, .. } => {
            for b in beta {
                check_len("beta", b.len(), npix)?;
            }
            beta.len()
        }
    };
    check_len("DoLP images (captures)", dolp.len(), t_len)?;
    for d in dolp {
        check_len("dolp", d.len(), npix)?;
    }
    if let Some(nz) = noise {
        for (name, imgs) in [("noise read terms", nz.read), ("noise shot terms", nz.shot)] {
            check_len(name, imgs.len(), t_len)?;
            for d in imgs {
                check_len(name, d.len(), npix)?;
            }
        }
    }
    for (name, len) in [
        ("n", out.n.len()),
        ("k", out.k.len()),
        ("n_se", out.n_se.len()),
        ("k_se", out.k_se.len()),
        ("rms_residual", out.rms_residual.len()),
    ] {
        check_len(name, len, npix)?;
    }
    check_len("class", out.class.len(), npix)?;
    check_len("reason", out.reason.len(), npix)?;
    Ok(t_len)
}

/// What a map run reads (checked by [`check_map_inputs`]).
struct MapInput<'a> {
    betas: Betas<'a>,
    classifier: &'a PixelClassifier,
    dolp: &'a [&'a [f32]],
    noise: Option<MapNoise<'a>>,
    flags: &'a [u8],
    /// Number of captures.
    t_len: usize,
}

/// Where a map run writes: the output images, the counts and the optional `n`–`k`
/// correlation image.
struct MapSink<'a, 'c> {
    out: MapOutputs<'a>,
    counts: MapCounts,
    nk_corr: &'c mut [f32],
}

impl MapSink<'_, '_> {
    /// Record pixel `p` as not fitted, for reason `r`.
    fn skip(&mut self, p: usize, r: u8) {
        write_skip(&mut self.out, &mut self.counts, p, r);
        if let Some(v) = self.nk_corr.get_mut(p) {
            *v = f32::NAN;
        }
    }

    /// Record pixel `p`'s fit `f`, class `c` and reason `r`.
    fn fit(&mut self, p: usize, f: &NkFit, c: u16, r: u8) {
        write_fit(&mut self.out, &mut self.counts, p, f, c, r);
        if let Some(v) = self.nk_corr.get_mut(p) {
            *v = f.nk_corr as f32;
        }
    }
}

/// The buffers of one tile, reused from tile to tile.
struct TileScratch {
    /// Pixels fitted on every capture: measurements (pixel by pixel), angles (per-pixel
    /// angles only), standard errors (weighted fits only), pixel indices.
    y: Vec<f64>,
    b: Vec<f64>,
    se: Vec<f64>,
    idx: Vec<usize>,
    /// Fits and decisions of a batch.
    fits: Vec<NkFit>,
    decisions: Vec<(u16, u8)>,
    /// Per-pixel angles: pixels with some captures left out (DoLP NaN: dark or
    /// saturated there), fitted on the others, grouped by the set of captures used
    /// (bits, pixel).
    partial: Vec<(u64, usize)>,
    /// Measurements, angles and standard errors of one such group.
    py: Vec<f64>,
    pb: Vec<f64>,
    ps: Vec<f64>,
}

impl TileScratch {
    /// Buffers for tiles of up to `cap` pixels and `t_len` captures.
    fn new(cap: usize, t_len: usize) -> Self {
        Self {
            y: Vec::with_capacity(cap * t_len),
            b: Vec::new(),
            se: Vec::new(),
            idx: Vec::with_capacity(cap),
            fits: vec![NkFit::default(); cap],
            decisions: Vec::with_capacity(cap),
            partial: Vec::new(),
            py: Vec::new(),
            pb: Vec::new(),
            ps: Vec::new(),
        }
    }
}

impl MapInput<'_> {
    /// Weighted fits (with a noise model).
    fn weighted(&self) -> bool {
        self.noise.is_some()
    }

    /// DoLP standard error of pixel `p` in capture `t` (1 without a noise model).
    #[inline]
    fn se_of(&self, t: usize, p: usize) -> f64 {
        match &self.noise {
            Some(nz) => nz.model.dolp_se(nz.read[t][p], nz.shot[t][p]),
            None => 1.0,
        }
    }

    /// Fit, classify and record the pixels `range`.
    fn run_tile(
        &self,
        range: std::ops::Range<usize>,
        sc: &mut TileScratch,
        sink: &mut MapSink<'_, '_>,
    ) -> Result<()> {
        let (betas, dolp, t_len, weighted) = (self.betas, self.dolp, self.t_len, self.weighted());
        sc.y.clear();
        sc.b.clear();
        sc.se.clear();
        sc.idx.clear();
        sc.partial.clear();
        for p in range {
            let r = match betas {
                Betas::PerPixel { beta, .. } if beta.iter().any(|b| !b[p].is_finite()) => {
                    reason::NO_GEOMETRY
                }
                _ => signal_reason(self.flags[p]),
            };
            let used = match betas {
                Betas::PerPixel { .. } if t_len < 64 => dolp
                    .iter()
                    .enumerate()
                    .filter(|(_, d)| !d[p].is_nan())
                    .fold(0u64, |m, (t, _)| m | (1 << t)),
                _ => u64::MAX,
            };
            let all = used == u64::MAX || used == (1u64 << t_len) - 1;
            if r == reason::CLASSIFIED && !all {
                sc.partial.push((used, p));
            } else if r == reason::CLASSIFIED {
                sc.idx.push(p);
                sc.y.extend(dolp.iter().map(|d| d[p] as f64));
                if let Betas::PerPixel { beta, .. } = betas {
                    sc.b.extend(beta.iter().map(|b| b[p] as f64));
                }
                if weighted {
                    sc.se.extend((0..t_len).map(|t| self.se_of(t, p)));
                }
            } else {
                sink.skip(p, r);
            }
        }
        let m = sc.idx.len();
        let se_arg = weighted.then_some(&sc.se[..]);
        match betas {
            Betas::Shared(plan) => fit_batch(plan, &sc.y, se_arg, &mut sc.fits[..m])?,
            Betas::PerPixel { plan, .. } => {
                fit_batch_pixel_beta(plan, &sc.b, &sc.y, se_arg, &mut sc.fits[..m])?
            }
        }
        decide_all(self.classifier, &sc.fits[..m], &mut sc.decisions);
        for ((&p, f), &(c, r)) in sc.idx.iter().zip(&sc.fits[..m]).zip(&sc.decisions) {
            sink.fit(p, f, c, r);
        }
        if let Betas::PerPixel { plan, beta } = betas {
            let mut partial = std::mem::take(&mut sc.partial);
            partial.sort_unstable();
            for group in partial.chunk_by(|a, b| a.0 == b.0) {
                self.fit_group(plan, beta, group, sc, sink)?;
            }
            sc.partial = partial;
        }
        Ok(())
    }

    /// Fit, classify and record a `group` of pixels with per-pixel angles `beta` that
    /// use the same captures (bits, pixel), on those captures.
    fn fit_group(
        &self,
        plan: &PixelBetaPlan,
        beta: &[&[f32]],
        group: &[(u64, usize)],
        sc: &mut TileScratch,
        sink: &mut MapSink<'_, '_>,
    ) -> Result<()> {
        let (dolp, weighted) = (self.dolp, self.weighted());
        let used = group[0].0;
        let ts: Vec<usize> = (0..self.t_len).filter(|t| used & (1 << t) != 0).collect();
        if ts.len() < 3 {
            // Not reached: the caller flags pixels with fewer than 3 usable
            // captures; counted as dark if it ever is.
            for &(_, p) in group {
                sink.skip(p, reason::DARK);
            }
            return Ok(());
        }
        sc.py.clear();
        sc.pb.clear();
        sc.ps.clear();
        for &(_, p) in group {
            sc.py.extend(ts.iter().map(|&t| dolp[t][p] as f64));
            sc.pb.extend(ts.iter().map(|&t| beta[t][p] as f64));
            if weighted {
                sc.ps.extend(ts.iter().map(|&t| self.se_of(t, p)));
            }
        }
        let g = group.len();
        if sc.fits.len() < g {
            sc.fits.resize(g, NkFit::default());
        }
        let ps_arg = weighted.then_some(&sc.ps[..]);
        fit_batch_pixel_beta(plan, &sc.pb, &sc.py, ps_arg, &mut sc.fits[..g])?;
        let gidx: Vec<usize> = group.iter().map(|&(_, p)| p).collect();
        decide_all(self.classifier, &sc.fits[..g], &mut sc.decisions);
        for ((&p, f), &(c, r)) in gidx.iter().zip(&sc.fits[..g]).zip(&sc.decisions) {
            sink.fit(p, f, c, r);
        }
        Ok(())
    }
}

/// The class and reason of every fit of a batch (in parallel).
fn decide_all(classifier: &PixelClassifier, fits: &[NkFit], out: &mut Vec<(u16, u8)>) {
    fits.par_iter()
        .map(|f| classifier.decide(f))
        .collect_into_vec(out);
}

/// Record a pixel that is not fitted, for `reason`.
fn write_skip(out: &mut MapOutputs<'_>, counts: &mut MapCounts, p: usize, r: u8) {
    out.n[p] = f32::NAN;
    out.k[p] = f32::NAN;
    out.n_se[p] = f32::NAN;
    out.k_se[p] = f32::NAN;
    out.rms_residual[p] = f32::NAN;
    out.class[p] = 0;
    out.reason[p] = r;
    counts.reasons[r as usize] += 1;
    counts.classes[0] += 1;
}

/// Record a pixel's fit and its class `c` and reason `r`.
fn write_fit(out: &mut MapOutputs<'_>, counts: &mut MapCounts, p: usize, f: &NkFit, c: u16, r: u8) {
    out.n[p] = f.n as f32;
    out.k[p] = f.k as f32;
    out.n_se[p] = f.n_se as f32;
    out.k_se[p] = f.k_se as f32;
    out.rms_residual[p] = f.rms_residual as f32;
    out.class[p] = c;
    out.reason[p] = r;
    counts.reasons[r as usize] += 1;
    if let Some(cc) = counts.classes.get_mut(c as usize) {
        *cc += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::{ClassifierConfig, Prototype};
    use crate::dop::dop;

    fn proto(class: &str, n: f64, k: f64) -> Prototype {
        Prototype {
            class: class.into(),
            n,
            k,
            cov: None,
            category: None,
            source: "test".into(),
        }
    }

    /// Copper, aluminum and green paint; pixels farther than 1 (in `(n, k)`) from the
    /// nearest prototype rejected.
    fn copper_aluminum_paint() -> PixelClassifier {
        let cls = Classifier::new(
            vec![
                proto("copper", 0.4, 2.95),
                proto("aluminum", 1.24, 6.6),
                proto("green_paint", 1.39, 0.34),
            ],
            ClassifierConfig::default(),
        )
        .unwrap();
        PixelClassifier::new(cls, Some(1.0)).unwrap()
    }

    /// The map outputs of one [`fit_and_classify`] run: `n, k, n_se, k_se, rms` rows,
    /// classes and reasons.
    type Maps = (Vec<Vec<f32>>, Vec<u16>, Vec<u8>);

    /// [`fit_and_classify`] of `views` (no noise, no progress) into fresh outputs
    /// (classes and reasons start at 9, values the run never writes).
    fn run_map(
        betas: Betas<'_>,
        pc: &PixelClassifier,
        views: &[&[f32]],
        flags: &[u8],
        tile: usize,
    ) -> Result<(Maps, MapCounts)> {
        let np = flags.len();
        let mut o: Vec<Vec<f32>> = vec![vec![0f32; np]; 5];
        let (mut class, mut why) = (vec![9u16; np], vec![9u8; np]);
        let [n, k, n_se, k_se, rms] = &mut o[..] else {
            unreachable!()
        };
        let out = MapOutputs {
            n,
            k,
            n_se,
            k_se,
            rms_residual: rms,
            class: &mut class,
            reason: &mut why,
        };
        let counts = fit_and_classify(betas, pc, views, None, flags, tile, out, &|_| {})?;
        Ok(((o, class, why), counts))
    }

    #[test]
    fn binned_dolp_of_uniform_frames_and_flags() {
        // 8 x 4 frames of a pixel with S = (200, 60, -80) + dark 10; one saturated raw.
        let (w, h) = (8usize, 4usize);
        let s = [200.0f64, 60.0, -80.0];
        let angles = [0.0f64, 45.0, 90.0, 135.0];
        let mut frames: Vec<Vec<f32>> = angles
            .iter()
            .map(|a| {
                let a = 2.0 * a.to_radians();
                vec![(10.0 + 0.5 * (s[0] + s[1] * a.cos() + s[2] * a.sin())) as f32; w * h]
            })
            .collect();
        frames[1][3] = 1000.0; // block (1, 0) at bin 2
        let solver = StokesSolver::from_degrees(&angles).unwrap();
        let rules = PixelRules {
            dark_level: 10.0,
            saturation: 1000.0,
            min_s0: 5.0,
        };
        let views: Vec<&[f32]> = frames.iter().map(|f| f.as_slice()).collect();
        let want = (60.0f32 * 60.0 + 80.0 * 80.0).sqrt() / 200.0;
        for bin in [1usize, 2, 4] {
            let (ow, oh) = binned_size(w, h, bin).unwrap();
            let mut d = vec![0f32; ow * oh];
            let mut f = vec![0u8; ow * oh];
            frames_dolp(&solver, &views, w, &rules, bin, &mut d, &mut f).unwrap();
            let sat_block = 3 / bin;
            for (i, (&d, &f)) in d.iter().zip(&f).enumerate() {
                let expect = if i == sat_block { flag::SATURATED } else { 0 };
                if expect == 0 {
                    assert!((d - want).abs() < 1e-6, "bin {bin} px {i}: {d}");
                }
                assert_eq!(f, expect, "bin {bin} px {i}");
            }
        }
        // Dark: the threshold compares the block mean S0.
        let rules = PixelRules {
            min_s0: 200.0,
            ..rules
        };
        let mut d = vec![0f32; 8];
        let mut f = vec![0u8; 8];
        frames_dolp(&solver, &views, w, &rules, 2, &mut d, &mut f).unwrap();
        // Every block but the one holding the saturated raw (whose mean S0 is higher).
        assert!(
            f.iter()
                .enumerate()
                .all(|(i, &f)| (i == 1) != (f & flag::DARK != 0))
        );
        assert!(binned_size(8, 4, 0).is_err() && binned_size(8, 4, 5).is_err());
    }

    #[test]
    fn stokes_dolp_matches_frames_dolp() {
        let (w, h) = (6usize, 4usize);
        let s0: Vec<f32> = (0..w * h).map(|i| 100.0 + i as f32).collect();
        let s1: Vec<f32> = (0..w * h).map(|i| 10.0 - i as f32).collect();
        let s2: Vec<f32> = (0..w * h).map(|i| (i % 5) as f32).collect();
        let mut m = vec![mask::VALID; w * h];
        m[7] = mask::INVALID;
        m[0] = mask::DARK; // ignored: the dark test is on the block mean
        let mut d = vec![0f32; 6];
        let mut f = vec![0u8; 6];
        stokes_dolp(w, &s0, &s1, &s2, Some(&m), 0.0, 2, &mut d, &mut f).unwrap();
        // Block 0 holds pixels 0, 1, 6, 7 (7 invalid); block 1 holds 2, 3, 8, 9.
        assert_eq!(f, vec![flag::INVALID, 0, 0, 0, 0, 0]);
        let sum = |v: &[f32]| [2usize, 3, 8, 9].iter().map(|&i| v[i]).sum::<f32>();
        let want = (sum(&s1).powi(2) + sum(&s2).powi(2)).sqrt() / sum(&s0);
        assert!((d[1] - want).abs() < 1e-6, "{} vs {want}", d[1]);
        // Dark threshold on the block mean S0 (the smallest block mean is 103.5).
        let mut f = vec![0u8; 6];
        stokes_dolp(w, &s0, &s1, &s2, None, 103.5, 2, &mut d, &mut f).unwrap();
        assert_eq!(f, vec![flag::DARK, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn fit_and_classify_recovers_classes_and_reasons() {
        let betas: Vec<f64> = (0..10)
            .map(|i| ((35.0 + 5.0 * i as f64 + 60.0) / 2.0f64).to_radians())
            .collect();
        let plan = FitPlan::new(&betas, Default::default()).unwrap();
        let pc = copper_aluminum_paint();
        assert_eq!(pc.names(), ["aluminum", "copper", "green_paint"]);
        // Pixels: copper, aluminum, green paint, far away (rejected), saturated.
        let truth = [
            (0.4, 2.95),
            (1.24, 6.6),
            (1.39, 0.34),
            (3.0, 0.0),
            (1.0, 1.0),
        ];
        let imgs: Vec<Vec<f32>> = betas
            .iter()
            .map(|&b| truth.iter().map(|&(n, k)| dop(n, k, b) as f32).collect())
            .collect();
        let views: Vec<&[f32]> = imgs.iter().map(|v| v.as_slice()).collect();
        let flags = [0, 0, 0, 0, flag::SATURATED | flag::DARK];
        let ((o, class, why), counts) = run_map((&plan).into(), &pc, &views, &flags, 2).unwrap();
        assert_eq!(class, vec![2, 1, 3, 0, 0]);
        assert_eq!(why, vec![0, 0, 0, reason::REJECTED, reason::SATURATED]);
        assert_eq!(counts.classes, vec![2, 1, 1, 1]);
        assert_eq!(counts.reasons[reason::CLASSIFIED as usize], 3);
        assert!((o[0][0] - 0.4).abs() < 1e-3 && (o[1][1] - 6.6).abs() < 1e-2);
        assert!(o[0][4].is_nan());
    }

    /// Per-pixel angles: every pixel's DoLP at its own angles gives back its `(n, k)`
    /// and class; a pixel without a finite β is `no_geometry` (before its signal
    /// flags); angles equal to the shared ones give the shared map bit for bit.
    #[test]
    fn fit_and_classify_with_per_pixel_angles() {
        let t_len = 6;
        let pc = copper_aluminum_paint();
        let truth = [
            (0.4, 2.95),
            (1.24, 6.6),
            (1.39, 0.34),
            (0.4, 2.95),
            (1.0, 1.0),
            (1.0, 1.0),
        ];
        let np = truth.len();
        // β_t(p): 40° + 6° t, shifted by up to 4° from pixel to pixel.
        let mut beta: Vec<Vec<f32>> = (0..t_len)
            .map(|t| {
                (0..np)
                    .map(|p| {
                        (40.0 + 6.0 * t as f64 + 4.0 * (p as f64 * 0.7 + t as f64).sin())
                            .to_radians() as f32
                    })
                    .collect()
            })
            .collect();
        beta[2][4] = f32::NAN;
        let imgs: Vec<Vec<f32>> = (0..t_len)
            .map(|t| {
                truth
                    .iter()
                    .enumerate()
                    .map(|(p, &(n, k))| {
                        let b = if beta[t][p].is_finite() {
                            beta[t][p] as f64
                        } else {
                            0.8
                        };
                        dop(n, k, b) as f32
                    })
                    .collect()
            })
            .collect();
        let views: Vec<&[f32]> = imgs.iter().map(|v| v.as_slice()).collect();
        let bviews: Vec<&[f32]> = beta.iter().map(|v| v.as_slice()).collect();
        let flags = [0, 0, 0, 0, flag::DARK, flag::SATURATED];
        let pp = PixelBetaPlan::with_defaults().unwrap();
        let run = |betas: Betas<'_>| run_map(betas, &pc, &views, &flags, 4).unwrap().0;
        let ((o, class, why), counts) = run_map(
            Betas::PerPixel {
                plan: &pp,
                beta: &bviews,
            },
            &pc,
            &views,
            &flags,
            4,
        )
        .unwrap();
        assert_eq!(class, vec![2, 1, 3, 2, 0, 0]);
        assert_eq!(
            why,
            vec![0, 0, 0, 0, reason::NO_GEOMETRY, reason::SATURATED]
        );
        assert_eq!(counts.reasons[reason::NO_GEOMETRY as usize], 1);
        for p in 0..4 {
            let (n, k) = truth[p];
            assert!(
                (o[0][p] as f64 - n).abs() < 1e-4 && (o[1][p] as f64 - k).abs() < 1e-3,
                "pixel {p}: {} {}",
                o[0][p],
                o[1][p]
            );
        }
        assert!(o[0][4].is_nan());
        // Wrong lengths.
        let short: Vec<&[f32]> = bviews.iter().map(|b| &b[..3]).collect();
        let bad = Betas::PerPixel {
            plan: &pp,
            beta: &short,
        };
        assert!(run_map(bad, &pc, &views, &flags, 4).is_err());
        // Equal angles everywhere: the shared map, bit for bit.
        let same: Vec<Vec<f32>> = (0..t_len).map(|t| vec![beta[t][0]; np]).collect();
        let sviews: Vec<&[f32]> = same.iter().map(|v| v.as_slice()).collect();
        let plan =
            FitPlan::with_defaults(&same.iter().map(|v| v[0] as f64).collect::<Vec<_>>()).unwrap();
        let per = run(Betas::PerPixel {
            plan: &pp,
            beta: &sviews,
        });
        let shared = run((&plan).into());
        assert_eq!(per.1, shared.1);
        assert_eq!(per.2, shared.2);
        for (a, b) in per.0.iter().zip(&shared.0) {
            assert_eq!(
                a.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                b.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
    }
}
