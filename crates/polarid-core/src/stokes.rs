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

use rayon::prelude::*;

use crate::error::{CoreError, Result};

/// Pixel mask values written by the Stokes kernels (one byte per pixel).
pub mod mask {
    /// The pixel is usable.
    pub const VALID: u8 = 0;
    /// A raw value reached the saturation level.
    pub const SATURATED: u8 = 1;
    /// The dark-subtracted `S0` is at or below the dark threshold.
    pub const DARK: u8 = 2;
    /// A raw value (or a Stokes component) is NaN or infinite.
    pub const INVALID: u8 = 3;
}

/// Condition number of the design matrix above which [`StokesSolver::ill_conditioned`]
/// is true. The best possible value, reached by any set of `N >= 3` angles equally
/// spaced over 180° (0/45/90/135, 0/60/120), is `√2`; at 10 the noise of the recovered
/// `S1, S2` is several times that of a well spread set.
pub const ILL_CONDITIONED: f64 = 10.0;

/// Condition number above which the angle set is treated as singular.
pub const SINGULAR: f64 = 1e6;

/// A raw sample type that frames may hold (8/16-bit integer or 32-bit float).
pub trait Sample: Copy + Send + Sync + 'static {
    /// The value as `f32` (exact for `u8` and `u16`).
    fn to_f32(self) -> f32;
}

impl Sample for u8 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}

impl Sample for u16 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}

impl Sample for f32 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
}

/// How raw values are turned into usable signal: dark level and rejection thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelRules {
    /// DN subtracted from every raw value.
    pub dark_level: f32,
    /// Raw values at or above this (before dark subtraction) are saturated.
    /// `f32::INFINITY` disables the test.
    pub saturation: f32,
    /// Pixels whose dark-subtracted `S0` is at or below this are "dark" and rejected.
    pub min_s0: f32,
}

impl Default for PixelRules {
    fn default() -> Self {
        Self {
            dark_level: 0.0,
            saturation: f32::INFINITY,
            min_s0: 0.0,
        }
    }
}

impl PixelRules {
    /// Check that the rules are usable (finite dark level and threshold, saturation not
    /// NaN).
    pub fn validate(&self) -> Result<()> {
        crate::error::ensure_finite("dark_level", self.dark_level as f64)?;
        crate::error::ensure_finite("min_s0", self.min_s0 as f64)?;
        if self.saturation.is_nan() {
            return Err(CoreError::NonFinite {
                name: "saturation",
                value: self.saturation as f64,
            });
        }
        Ok(())
    }
}

/// How many pixels of an image were used and why the others were rejected.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PixelCounts {
    /// Usable pixels.
    pub valid: u64,
    /// Pixels with a saturated raw value.
    pub saturated: u64,
    /// Pixels whose `S0` is at or below the dark threshold.
    pub dark: u64,
    /// Pixels with a non-finite raw value.
    pub invalid: u64,
}

impl PixelCounts {
    /// Pixels rejected for any reason.
    pub fn rejected(&self) -> u64 {
        self.saturated + self.dark + self.invalid
    }

    fn add(self, o: Self) -> Self {
        Self {
            valid: self.valid + o.valid,
            saturated: self.saturated + o.saturated,
            dark: self.dark + o.dark,
            invalid: self.invalid + o.invalid,
        }
    }

    /// Count the mask values of `mask`.
    pub fn from_mask(mask: &[u8]) -> Self {
        let mut h = [0u64; 4];
        for &m in mask {
            h[(m & 3) as usize] += 1;
        }
        Self {
            valid: h[0],
            saturated: h[1],
            dark: h[2],
            invalid: h[3],
        }
    }
}

/// Least-squares Stokes solver for one set of polarizer angles.
#[derive(Debug, Clone, PartialEq)]
pub struct StokesSolver {
    angles: Vec<f64>,
    /// Pseudo-inverse, one `[p0, p1, p2]` column per frame: `S_j = Σ_i pinv[i][j] I_i`.
    pinv: Vec<[f64; 3]>,
    cond: f64,
    /// Frame indices of the 0°, 45°, 90° and 135° polarizers when the angle set is
    /// exactly that (any order): the kernels then use the exact form
    /// `S0 = ½ ΣI`, `S1 = I0 − I90`, `S2 = I45 − I135`.
    quad: Option<[usize; 4]>,
}

/// Eigenvalues of a symmetric 3×3 matrix (cyclic Jacobi), unordered.
fn sym3_eigenvalues(m: [[f64; 3]; 3]) -> [f64; 3] {
    let mut a = m;
    for _ in 0..50 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off <= 1e-300 {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // Rotate rows/columns p and q.
            let mut b = a;
            for k in 0..3 {
                b[k][p] = c * a[k][p] - s * a[k][q];
                b[k][q] = s * a[k][p] + c * a[k][q];
            }
            let mut r = b;
            for k in 0..3 {
                r[p][k] = c * b[p][k] - s * b[q][k];
                r[q][k] = s * b[p][k] + c * b[q][k];
            }
            a = r;
        }
    }
    [a[0][0], a[1][1], a[2][2]]
}

fn inverse3(m: [[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let d = 1.0 / det;
    Some([
        [
            (m[1][1] * m[2][2] - m[1][2] * m[2][1]) * d,
            (m[0][2] * m[2][1] - m[0][1] * m[2][2]) * d,
            (m[0][1] * m[1][2] - m[0][2] * m[1][1]) * d,
        ],
        [
            (m[1][2] * m[2][0] - m[1][0] * m[2][2]) * d,
            (m[0][0] * m[2][2] - m[0][2] * m[2][0]) * d,
            (m[0][2] * m[1][0] - m[0][0] * m[1][2]) * d,
        ],
        [
            (m[1][0] * m[2][1] - m[1][1] * m[2][0]) * d,
            (m[0][1] * m[2][0] - m[0][0] * m[2][1]) * d,
            (m[0][0] * m[1][1] - m[0][1] * m[1][0]) * d,
        ],
    ])
}

impl StokesSolver {
    /// Prepare the least-squares solution for polarizer angles `angles` (radians).
    ///
    /// Errors: [`CoreError::TooFew`] for fewer than 3 angles, [`CoreError::NonFinite`]
    /// for a NaN/infinite angle, [`CoreError::SingularAngles`] when fewer than 3 angles
    /// are distinct modulo 180° or the design matrix is numerically singular (condition
    /// number above [`SINGULAR`]).
    pub fn new(angles: &[f64]) -> Result<Self> {
        if angles.len() < 3 {
            return Err(CoreError::TooFew {
                what: "polarizer angles",
                needed: 3,
                got: angles.len(),
            });
        }
        for &a in angles {
            crate::error::ensure_finite("polarizer angle", a)?;
        }
        let deg: Vec<f64> = angles.iter().map(|a| a.to_degrees()).collect();
        // Distinct angles modulo 180°.
        let mut reduced: Vec<f64> = deg.iter().map(|d| d.rem_euclid(180.0)).collect();
        reduced.sort_by(f64::total_cmp);
        let mut distinct = 0usize;
        for (i, &r) in reduced.iter().enumerate() {
            let dup_prev = i > 0 && (r - reduced[i - 1]).abs() < 1e-9;
            let dup_wrap = i + 1 == reduced.len() && i > 0 && (r - 180.0 - reduced[0]).abs() < 1e-9;
            if !dup_prev && !dup_wrap {
                distinct += 1;
            }
        }
        if distinct < 3 {
            return Err(CoreError::SingularAngles {
                angles_deg: deg,
                reason: format!(
                    "only {distinct} distinct angle(s) modulo 180°, at least 3 are needed"
                ),
            });
        }
        let rows: Vec<[f64; 3]> = angles
            .iter()
            .map(|a| [0.5, 0.5 * (2.0 * a).cos(), 0.5 * (2.0 * a).sin()])
            .collect();
        let mut ata = [[0.0f64; 3]; 3];
        for r in &rows {
            for j in 0..3 {
                for k in 0..3 {
                    ata[j][k] += r[j] * r[k];
                }
            }
        }
        let ev = sym3_eigenvalues(ata);
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for e in ev {
            lo = lo.min(e.abs());
            hi = hi.max(e.abs());
        }
        let cond = if lo > 0.0 {
            (hi / lo).sqrt()
        } else {
            f64::INFINITY
        };
        let inv = match inverse3(ata) {
            Some(inv) if cond <= SINGULAR => inv,
            _ => {
                return Err(CoreError::SingularAngles {
                    angles_deg: deg,
                    reason: format!("the design matrix is singular (condition number {cond:.3e})"),
                });
            }
        };
        let pinv = rows
            .iter()
            .map(|r| {
                let mut p = [0.0; 3];
                for (j, pj) in p.iter_mut().enumerate() {
                    *pj = inv[j][0] * r[0] + inv[j][1] * r[1] + inv[j][2] * r[2];
                }
                p
            })
            .collect();
        let quad = quad_indices(&deg);
        Ok(Self {
            angles: angles.to_vec(),
            pinv,
            cond,
            quad,
        })
    }

    /// True when the angles are exactly 0/45/90/135° (in any order): the kernels then
    /// use the specialised exact form `S0 = ½ ΣI`, `S1 = I0 − I90`, `S2 = I45 − I135`.
    pub fn is_standard_quad(&self) -> bool {
        self.quad.is_some()
    }

    /// Stokes of one row without the dark decision: writes `r0, r1, r2` (dark
    /// subtracted) and the raw flag bits into `rm` (bit 0: a raw value reached the
    /// saturation level; bit 1: a raw value is not finite). `rows` holds the row of
    /// each frame (same length as `r0`), `coef` the `f32` pseudo-inverse
    /// ([`Self::coef_f32`]). Used by the per-pixel map pipeline.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn stokes_row_raw<T: Sample>(
        &self,
        rows: &[&[T]],
        coef: &[[f32; 3]],
        rules: &PixelRules,
        r0: &mut [f32],
        r1: &mut [f32],
        r2: &mut [f32],
        rm: &mut [u8],
    ) {
        if let Some(q) = self.quad {
            quad_row_raw(
                [rows[q[0]], rows[q[1]], rows[q[2]], rows[q[3]]],
                rules,
                r0,
                r1,
                r2,
                rm,
            );
            return;
        }
        r0.fill(0.0);
        r1.fill(0.0);
        r2.fill(0.0);
        rm.fill(0);
        for (raw, c) in rows.iter().zip(coef) {
            accumulate_row(raw, *c, rules, r0, r1, r2, rm);
        }
    }

    /// The pseudo-inverse in `f32`, one `[p0, p1, p2]` per frame.
    pub(crate) fn coef_f32(&self) -> Vec<[f32; 3]> {
        self.pinv
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect()
    }

    /// Convenience constructor from angles in degrees.
    pub fn from_degrees(angles_deg: &[f64]) -> Result<Self> {
        let rad: Vec<f64> = angles_deg.iter().map(|d| d.to_radians()).collect();
        Self::new(&rad)
    }

    /// The polarizer angles, radians.
    pub fn angles(&self) -> &[f64] {
        &self.angles
    }

    /// Number of frames the solver expects.
    pub fn len(&self) -> usize {
        self.angles.len()
    }

    /// Always false (a solver has at least 3 angles); for symmetry with [`Self::len`].
    pub fn is_empty(&self) -> bool {
        self.angles.is_empty()
    }

    /// 2-norm condition number of the design matrix `A` (`√2` at best).
    pub fn condition_number(&self) -> f64 {
        self.cond
    }

    /// True when the condition number exceeds [`ILL_CONDITIONED`]: the angles are poorly
    /// spread and the recovered `S1, S2` are noisy. Callers should warn.
    pub fn ill_conditioned(&self) -> bool {
        self.cond > ILL_CONDITIONED
    }

    /// The pseudo-inverse, one `[∂S0/∂I_i, ∂S1/∂I_i, ∂S2/∂I_i]` per frame `i`.
    pub fn pinv(&self) -> &[[f64; 3]] {
        &self.pinv
    }

    /// Stokes vector of one pixel from its (dark-subtracted) intensities, in `f64`.
    pub fn solve(&self, intensities: &[f64]) -> Result<[f64; 3]> {
        if intensities.len() != self.pinv.len() {
            return Err(CoreError::LengthMismatch {
                name: "intensities",
                expected: self.pinv.len(),
                got: intensities.len(),
            });
        }
        let mut s = [0.0; 3];
        for (p, &v) in self.pinv.iter().zip(intensities) {
            s[0] += p[0] * v;
            s[1] += p[1] * v;
            s[2] += p[2] * v;
        }
        Ok(s)
    }

    /// Stokes images from `frames` (one per angle, `width × height`, row-major), with
    /// dark subtraction and pixel rejection by `rules`. Writes `s0, s1, s2` and `mask`
    /// (values of [`mask`]), all `width × height`, and returns the pixel counts.
    #[allow(clippy::too_many_arguments)]
    pub fn compute<T: Sample>(
        &self,
        frames: &[&[T]],
        width: usize,
        rules: &PixelRules,
        s0: &mut [f32],
        s1: &mut [f32],
        s2: &mut [f32],
        mask: &mut [u8],
    ) -> Result<PixelCounts> {
        self.compute_impl(frames, width, rules, s0, s1, s2, mask, None)
    }

    /// [`Self::compute`] fused with [`dolp_aolp`]: also writes `dolp` and `aolp` while
    /// each row is still in cache.
    #[allow(clippy::too_many_arguments)]
    pub fn compute_with_polar<T: Sample>(
        &self,
        frames: &[&[T]],
        width: usize,
        rules: &PixelRules,
        s0: &mut [f32],
        s1: &mut [f32],
        s2: &mut [f32],
        mask: &mut [u8],
        dolp: &mut [f32],
        aolp: &mut [f32],
    ) -> Result<PixelCounts> {
        self.compute_impl(frames, width, rules, s0, s1, s2, mask, Some((dolp, aolp)))
    }

    #[allow(clippy::too_many_arguments)]
    fn compute_impl<T: Sample>(
        &self,
        frames: &[&[T]],
        width: usize,
        rules: &PixelRules,
        s0: &mut [f32],
        s1: &mut [f32],
        s2: &mut [f32],
        mask: &mut [u8],
        polar: Option<(&mut [f32], &mut [f32])>,
    ) -> Result<PixelCounts> {
        rules.validate()?;
        if frames.len() != self.pinv.len() {
            return Err(CoreError::LengthMismatch {
                name: "frames",
                expected: self.pinv.len(),
                got: frames.len(),
            });
        }
        let n = s0.len();
        check_image(width, n)?;
        for f in frames {
            check_len("frame", f.len(), n)?;
        }
        check_len("s1", s1.len(), n)?;
        check_len("s2", s2.len(), n)?;
        check_len("mask", mask.len(), n)?;
        if let Some(q) = self.quad {
            let rows = [frames[q[0]], frames[q[1]], frames[q[2]], frames[q[3]]];
            return Ok(match polar {
                None => {
                    quad_image::<T, false>(rows, width, rules, s0, s1, s2, mask, &mut [], &mut [])
                }
                Some((dolp, aolp)) => {
                    check_len("dolp", dolp.len(), n)?;
                    check_len("aolp", aolp.len(), n)?;
                    quad_image::<T, true>(rows, width, rules, s0, s1, s2, mask, dolp, aolp)
                }
            });
        }
        let coef = self.coef_f32();
        let rows = s0
            .par_chunks_mut(width)
            .zip(s1.par_chunks_mut(width))
            .zip(s2.par_chunks_mut(width))
            .zip(mask.par_chunks_mut(width))
            .enumerate();
        let row_fn = |y: usize, r0: &mut [f32], r1: &mut [f32], r2: &mut [f32], rm: &mut [u8]| {
            let off = y * width;
            r0.fill(0.0);
            r1.fill(0.0);
            r2.fill(0.0);
            rm.fill(0);
            for (f, c) in frames.iter().zip(&coef) {
                let raw = &f[off..off + width];
                accumulate_row(raw, *c, rules, r0, r1, r2, rm);
            }
            finish_mask_row(r0, r1, r2, rm, rules.min_s0)
        };
        let counts = match polar {
            None => rows
                .map(|(y, (((r0, r1), r2), rm))| row_fn(y, r0, r1, r2, rm))
                .reduce(PixelCounts::default, PixelCounts::add),
            Some((dolp, aolp)) => {
                check_len("dolp", dolp.len(), n)?;
                check_len("aolp", aolp.len(), n)?;
                rows.zip(dolp.par_chunks_mut(width))
                    .zip(aolp.par_chunks_mut(width))
                    .map(|(((y, (((r0, r1), r2), rm)), rd), ra)| {
                        let c = row_fn(y, r0, r1, r2, rm);
                        polar_row(r0, r1, r2, Some(rm), rd, ra);
                        c
                    })
                    .reduce(PixelCounts::default, PixelCounts::add)
            }
        };
        Ok(counts)
    }
}

/// Frame indices of 0/45/90/135° when `deg` is exactly that set (any order, modulo 180°).
fn quad_indices(deg: &[f64]) -> Option<[usize; 4]> {
    if deg.len() != 4 {
        return None;
    }
    let mut idx = [usize::MAX; 4];
    for (i, d) in deg.iter().enumerate() {
        let r = d.rem_euclid(180.0);
        let slot = [0.0, 45.0, 90.0, 135.0]
            .iter()
            .position(|&a| (r - a).abs() < 1e-9 || (r - 180.0 - a).abs() < 1e-9)?;
        if idx[slot] != usize::MAX {
            return None;
        }
        idx[slot] = i;
    }
    Some(idx)
}

/// Rows per parallel task of the image kernels (big enough to amortise scheduling,
/// small enough to balance two to a few dozen threads).
const ROWS_PER_TASK: usize = 16;

/// The exact 0/45/90/135° kernel over a whole image, fused with the mask, the counts
/// and (when `POLAR`) DoLP/AoLP: one pass, every output written once.
#[allow(clippy::too_many_arguments)]
fn quad_image<T: Sample, const POLAR: bool>(
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
                quad_block_dispatch::<T, true>(rows, rules, c0, c1, c2, cm, cd, ca)
            })
            .reduce(PixelCounts::default, PixelCounts::add)
    } else {
        base.map(|(i, (((c0, c1), c2), cm))| {
            let rows = rows_at(i, c0.len());
            quad_block_dispatch::<T, false>(rows, rules, c0, c1, c2, cm, &mut [], &mut [])
        })
        .reduce(PixelCounts::default, PixelCounts::add)
    }
}

#[allow(clippy::too_many_arguments)]
fn quad_block_dispatch<T: Sample, const POLAR: bool>(
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
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above).
            return unsafe { quad_block_avx2::<T, POLAR>(q, rules, r0, r1, r2, rm, rd, ra) };
        }
    }
    quad_block::<T, POLAR>(q, rules, r0, r1, r2, rm, rd, ra)
}

#[cfg(target_arch = "x86_64")]
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
    quad_block::<T, POLAR>(q, rules, r0, r1, r2, rm, rd, ra)
}

/// One block of pixels of the exact 0/45/90/135° kernel (see [`quad_image`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn quad_block<T: Sample, const POLAR: bool>(
    q: [&[T]; 4],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
    rd: &mut [f32],
    ra: &mut [f32],
) -> PixelCounts {
    let n = r0.len();
    let (q0, q1, q2, q3) = (&q[0][..n], &q[1][..n], &q[2][..n], &q[3][..n]);
    let (r1, r2, rm) = (&mut r1[..n], &mut r2[..n], &mut rm[..n]);
    let dark2 = 2.0 * rules.dark_level;
    let sat = rules.saturation;
    let min_s0 = rules.min_s0;
    let (mut n_sat, mut n_dark, mut n_inv) = (0u32, 0u32, 0u32);
    if POLAR {
        let (rd, ra) = (&mut rd[..n], &mut ra[..n]);
        for i in 0..n {
            let (a, b, c, d) = (
                q0[i].to_f32(),
                q1[i].to_f32(),
                q2[i].to_f32(),
                q3[i].to_f32(),
            );
            let (v0, v1, v2, m) = quad_pixel(a, b, c, d, dark2, sat, min_s0);
            r0[i] = v0;
            r1[i] = v1;
            r2[i] = v2;
            rm[i] = m;
            n_sat += (m == mask::SATURATED) as u32;
            n_dark += (m == mask::DARK) as u32;
            n_inv += (m == mask::INVALID) as u32;
            let (pd, pa) = dolp_aolp_pixel(v0, v1, v2);
            let ok = m == mask::VALID;
            rd[i] = if ok { pd } else { f32::NAN };
            ra[i] = if ok { pa } else { f32::NAN };
        }
    } else {
        for i in 0..n {
            let (a, b, c, d) = (
                q0[i].to_f32(),
                q1[i].to_f32(),
                q2[i].to_f32(),
                q3[i].to_f32(),
            );
            let (v0, v1, v2, m) = quad_pixel(a, b, c, d, dark2, sat, min_s0);
            r0[i] = v0;
            r1[i] = v1;
            r2[i] = v2;
            rm[i] = m;
            n_sat += (m == mask::SATURATED) as u32;
            n_dark += (m == mask::DARK) as u32;
            n_inv += (m == mask::INVALID) as u32;
        }
    }
    let rejected = (n_sat + n_dark + n_inv) as u64;
    PixelCounts {
        valid: n as u64 - rejected,
        saturated: n_sat as u64,
        dark: n_dark as u64,
        invalid: n_inv as u64,
    }
}

/// One pixel of the exact 0/45/90/135° form: `(S0, S1, S2, mask)` from the raw values
/// at 0, 45, 90 and 135° (`dark2` = twice the dark level).
#[inline(always)]
fn quad_pixel(
    a: f32,
    b: f32,
    c: f32,
    d: f32,
    dark2: f32,
    sat: f32,
    min_s0: f32,
) -> (f32, f32, f32, u8) {
    let sum = (a + c) + (b + d);
    let s0 = 0.5 * sum - dark2;
    let s1 = a - c;
    let s2 = b - d;
    let mx = a.max(b).max(c.max(d));
    let nonfinite = !(sum.is_finite() && (s1 + s2).is_finite());
    let m = if nonfinite {
        mask::INVALID
    } else if mx >= sat {
        mask::SATURATED
    } else if s0 <= min_s0 {
        mask::DARK
    } else {
        mask::VALID
    };
    (s0, s1, s2, m)
}

/// Raw Stokes of one row by the exact 0/45/90/135° form, with the raw flag bits of
/// [`StokesSolver::stokes_row_raw`].
fn quad_row_raw<T: Sample>(
    q: [&[T]; 4],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
) {
    let n = r0.len();
    let (q0, q1, q2, q3) = (&q[0][..n], &q[1][..n], &q[2][..n], &q[3][..n]);
    let (r1, r2, rm) = (&mut r1[..n], &mut r2[..n], &mut rm[..n]);
    let dark2 = 2.0 * rules.dark_level;
    let sat = rules.saturation;
    for i in 0..n {
        let (a, b, c, d) = (
            q0[i].to_f32(),
            q1[i].to_f32(),
            q2[i].to_f32(),
            q3[i].to_f32(),
        );
        let sum = (a + c) + (b + d);
        r0[i] = 0.5 * sum - dark2;
        r1[i] = a - c;
        r2[i] = b - d;
        let mx = a.max(b).max(c.max(d));
        rm[i] = (mx >= sat) as u8 | ((!sum.is_finite()) as u8) << 1;
    }
}

pub(crate) fn check_len(name: &'static str, got: usize, expected: usize) -> Result<()> {
    if got != expected {
        return Err(CoreError::LengthMismatch {
            name,
            expected,
            got,
        });
    }
    Ok(())
}

pub(crate) fn check_image(width: usize, len: usize) -> Result<()> {
    if width == 0 || len == 0 || !len.is_multiple_of(width) {
        return Err(CoreError::InvalidDimensions {
            width,
            height: len.checked_div(width).unwrap_or(0),
            reason: format!("{len} pixels do not form whole rows of a non-empty image"),
        });
    }
    Ok(())
}

/// Add one frame's row into the Stokes accumulators; flag saturated / non-finite raws.
#[inline]
fn accumulate_row<T: Sample>(
    raw: &[T],
    c: [f32; 3],
    rules: &PixelRules,
    r0: &mut [f32],
    r1: &mut [f32],
    r2: &mut [f32],
    rm: &mut [u8],
) {
    let dark = rules.dark_level;
    let sat = rules.saturation;
    for ((((&v, a0), a1), a2), m) in raw
        .iter()
        .zip(r0.iter_mut())
        .zip(r1.iter_mut())
        .zip(r2.iter_mut())
        .zip(rm.iter_mut())
    {
        let v = v.to_f32();
        let d = v - dark;
        *a0 += c[0] * d;
        *a1 += c[1] * d;
        *a2 += c[2] * d;
        // Bit 0: saturated; bit 1: not finite (NaN compares false with everything).
        *m |= ((v >= sat) as u8) | ((!v.is_finite()) as u8) << 1;
    }
}

/// Turn the accumulated flag bits of a row into mask values and count them.
#[inline]
pub(crate) fn finish_mask_row(
    r0: &[f32],
    r1: &[f32],
    r2: &[f32],
    rm: &mut [u8],
    min_s0: f32,
) -> PixelCounts {
    let mut h = [0u32; 4];
    for (((&a0, &a1), &a2), m) in r0.iter().zip(r1).zip(r2).zip(rm.iter_mut()) {
        let nonfinite = (*m & 2 != 0) || !(a0 + a1 + a2).is_finite();
        let v = if nonfinite {
            mask::INVALID
        } else if *m & 1 != 0 {
            mask::SATURATED
        } else if a0 <= min_s0 {
            mask::DARK
        } else {
            mask::VALID
        };
        *m = v;
        h[v as usize] += 1;
    }
    PixelCounts {
        valid: h[0] as u64,
        saturated: h[1] as u64,
        dark: h[2] as u64,
        invalid: h[3] as u64,
    }
}

const ATAN_C: [f32; 8] = [
    0.999_999_34,
    -0.333_298_6,
    0.199_465_66,
    -0.139_086_28,
    0.096_421_91,
    -0.055_912_23,
    0.021_862_883,
    -0.004_054_544_5,
];

/// `atan2(y, x)` in radians by an odd minimax polynomial on `[0, 1]` (max error
/// 4e-8 rad, below `f32` resolution of the result) and octant folding; branch-free so
/// that loops over it vectorise. `atan2(0, 0) = 0`.
#[inline(always)]
pub fn atan2_fast(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let mx = ax.max(ay);
    let mn = ax.min(ay);
    let t = if mx > 0.0 { mn / mx } else { 0.0 };
    let s = t * t;
    let mut p = ATAN_C[7];
    p = p * s + ATAN_C[6];
    p = p * s + ATAN_C[5];
    p = p * s + ATAN_C[4];
    p = p * s + ATAN_C[3];
    p = p * s + ATAN_C[2];
    p = p * s + ATAN_C[1];
    p = p * s + ATAN_C[0];
    let mut r = p * t;
    r = if ay > ax {
        std::f32::consts::FRAC_PI_2 - r
    } else {
        r
    };
    r = if x < 0.0 { std::f32::consts::PI - r } else { r };
    if y < 0.0 { -r } else { r }
}

/// DoLP and AoLP of one pixel (CONVENTIONS): `DoLP = √(S1²+S2²)/S0` clamped to `[0, 1]`,
/// `AoLP = atan2(S2, S1)/2` in degrees in `[0, 180)`. NaN for both when `S0 <= 0` or
/// any component is not finite.
#[inline(always)]
pub fn dolp_aolp_pixel(s0: f32, s1: f32, s2: f32) -> (f32, f32) {
    let l = (s1 * s1 + s2 * s2).sqrt();
    let d = (l / s0).clamp(0.0, 1.0);
    let a = atan2_fast(s2, s1) * (90.0 / std::f32::consts::PI);
    let a = if a < 0.0 { a + 180.0 } else { a };
    let a = if a >= 180.0 { a - 180.0 } else { a };
    let ok = s0 > 0.0 && s0.is_finite() && s1.is_finite() && s2.is_finite();
    if ok { (d, a) } else { (f32::NAN, f32::NAN) }
}

#[inline]
fn polar_row(
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    mask: Option<&[u8]>,
    dolp: &mut [f32],
    aolp: &mut [f32],
) {
    for ((((&a0, &a1), &a2), d), a) in s0
        .iter()
        .zip(s1)
        .zip(s2)
        .zip(dolp.iter_mut())
        .zip(aolp.iter_mut())
    {
        let (pd, pa) = dolp_aolp_pixel(a0, a1, a2);
        *d = pd;
        *a = pa;
    }
    if let Some(m) = mask {
        for ((&m, d), a) in m.iter().zip(dolp.iter_mut()).zip(aolp.iter_mut()) {
            if m != mask::VALID {
                *d = f32::NAN;
                *a = f32::NAN;
            }
        }
    }
}

/// DoLP and AoLP images from Stokes images (all `width × height`), NaN where `mask`
/// (if given) rejects the pixel or `S0 <= 0`. See [`dolp_aolp_pixel`].
pub fn dolp_aolp(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    mask: Option<&[u8]>,
    dolp: &mut [f32],
    aolp: &mut [f32],
) -> Result<()> {
    let n = s0.len();
    check_image(width, n)?;
    check_len("s1", s1.len(), n)?;
    check_len("s2", s2.len(), n)?;
    check_len("dolp", dolp.len(), n)?;
    check_len("aolp", aolp.len(), n)?;
    if let Some(m) = mask {
        check_len("mask", m.len(), n)?;
    }
    dolp.par_chunks_mut(width)
        .zip(aolp.par_chunks_mut(width))
        .enumerate()
        .for_each(|(y, (rd, ra))| {
            let r = y * width..(y + 1) * width;
            polar_row(
                &s0[r.clone()],
                &s1[r.clone()],
                &s2[r.clone()],
                mask.map(|m| &m[r]),
                rd,
                ra,
            );
        });
    Ok(())
}

/// Mask and counts for Stokes images read from files (no raw frames): a pixel is
/// [`mask::INVALID`] when a component is not finite and [`mask::DARK`] when
/// `S0 <= min_s0`.
pub fn mask_stokes(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    min_s0: f32,
    mask: &mut [u8],
) -> Result<PixelCounts> {
    let n = s0.len();
    check_image(width, n)?;
    check_len("s1", s1.len(), n)?;
    check_len("s2", s2.len(), n)?;
    check_len("mask", mask.len(), n)?;
    Ok(mask
        .par_chunks_mut(width)
        .enumerate()
        .map(|(y, rm)| {
            let r = y * width..(y + 1) * width;
            rm.fill(0);
            finish_mask_row(&s0[r.clone()], &s1[r.clone()], &s2[r], rm, min_s0)
        })
        .reduce(PixelCounts::default, PixelCounts::add))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pinv_of_standard_sets() {
        let s = StokesSolver::from_degrees(&[0.0, 45.0, 90.0, 135.0]).unwrap();
        let want = [
            [0.5, 1.0, 0.0],
            [0.5, 0.0, 1.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, -1.0],
        ];
        for (p, w) in s.pinv().iter().zip(want) {
            for j in 0..3 {
                assert!((p[j] - w[j]).abs() < 1e-12, "{p:?} vs {w:?}");
            }
        }
        assert!((s.condition_number() - 2f64.sqrt()).abs() < 1e-9);
        let s = StokesSolver::from_degrees(&[0.0, 60.0, 120.0]).unwrap();
        assert!((s.condition_number() - 2f64.sqrt()).abs() < 1e-9);
        assert!(!s.ill_conditioned());
    }

    #[test]
    fn singular_and_ill_conditioned_sets() {
        for bad in [
            vec![0.0, 90.0, 180.0],
            vec![0.0, 45.0, 45.0, 225.0],
            vec![10.0, 10.0, 10.0],
        ] {
            match StokesSolver::from_degrees(&bad) {
                Err(CoreError::SingularAngles { angles_deg, .. }) => {
                    assert_eq!(angles_deg.len(), bad.len())
                }
                other => panic!("{bad:?}: {other:?}"),
            }
        }
        assert!(matches!(
            StokesSolver::from_degrees(&[0.0, 45.0]),
            Err(CoreError::TooFew { .. })
        ));
        let s = StokesSolver::from_degrees(&[0.0, 5.0, 10.0]).unwrap();
        assert!(s.ill_conditioned(), "cond {}", s.condition_number());
    }

    #[test]
    fn atan2_fast_matches_std() {
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let t = i as f64 * 0.0031416 - 3.1;
            for r in [1e-3f64, 1.0, 1e4] {
                let (y, x) = ((r * t.sin()) as f32, (r * t.cos()) as f32);
                let e = (atan2_fast(y, x) as f64 - (y as f64).atan2(x as f64)).abs();
                worst = worst.max(e);
            }
        }
        assert!(worst < 5e-7, "worst {worst}");
        assert_eq!(atan2_fast(0.0, 0.0), 0.0);
        assert!((atan2_fast(0.0, -1.0) - std::f32::consts::PI).abs() < 1e-6);
    }

    #[test]
    fn dolp_aolp_conventions() {
        let (d, a) = dolp_aolp_pixel(2.0, 0.0, 1.0);
        assert!((d - 0.5).abs() < 1e-7 && (a - 45.0).abs() < 1e-4);
        let (_, a) = dolp_aolp_pixel(2.0, -1.0, -1e-9);
        assert!((0.0..180.0).contains(&a) && (a - 90.0).abs() < 1e-3, "{a}");
        let (_, a) = dolp_aolp_pixel(2.0, 1.0, -1e-3);
        assert!((0.0..180.0).contains(&a) && a > 179.9, "{a}");
        let (d, _) = dolp_aolp_pixel(1.0, 3.0, 0.0);
        assert_eq!(d, 1.0);
        assert!(dolp_aolp_pixel(0.0, 1.0, 0.0).0.is_nan());
    }

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
}
