//! Least-squares Stokes vectors for any set of `N ≥ 3` polarizer angles
//! ([`StokesSolver`]): the design matrix `A_i = ½ (1, cos 2a_i, sin 2a_i)`, its
//! pseudo-inverse `(AᵀA)⁻¹Aᵀ` and condition number (computed once per angle set), and
//! the image kernels that apply it row by row. The exact 0/45/90/135° set is
//! recognised and handed to the fused kernel of `quad/`.
//!
//! # Reference
//! J. S. Tyo, D. L. Goldstein, D. B. Chenault and J. A. Shaw, "Review of passive
//! imaging polarimetry for remote sensing applications", *Applied Optics* 45(22),
//! 5453–5469, 2006: the linear Stokes polarimeter as `I = A S`, its least-squares
//! (pseudo-inverse) data reduction and the condition number of `A` as the measure of
//! an angle set.

use rayon::prelude::*;

use super::pixels::{PixelCounts, PixelRules, Sample, check_image, finish_mask_row};
use super::polar::polar_row;
use super::quad;
use crate::cpu::cpu_features;
use crate::error::{CoreError, Result, check_len};

/// Condition number of the design matrix above which [`StokesSolver::ill_conditioned`]
/// is true. The best possible value, reached by any set of `N >= 3` angles equally
/// spaced over 180° (0/45/90/135, 0/60/120), is `√2`; at 10 the noise of the recovered
/// `S1, S2` is several times that of a well spread set.
pub const ILL_CONDITIONED: f64 = 10.0;

/// Condition number above which the angle set is treated as singular.
pub const SINGULAR: f64 = 1e6;

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
            quad::quad_row_raw(
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

    /// Convenience constructor from angles in degrees; an angle outside
    /// `[-3600, 3600]` (ten turns: beyond, e.g. `1e308`, it has lost its precision) is
    /// [`CoreError::OutOfRange`](crate::CoreError::OutOfRange).
    pub fn from_degrees(angles_deg: &[f64]) -> Result<Self> {
        // A polarizer angle far outside a turn (1e308) has lost all its precision.
        for &a in angles_deg {
            crate::error::ensure_range(
                "polarizer angle (degrees)",
                a,
                -3600.0,
                3600.0,
                "in [-3600, 3600]",
            )?;
        }
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
        check_len("intensities", intensities.len(), self.pinv.len())?;
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
    /// (values of [`mask`](super::mask)), all `width × height`, and returns the pixel counts.
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

    /// [`Self::compute`] fused with [`dolp_aolp`](super::dolp_aolp): also writes `dolp`
    /// and `aolp` while each row is still in cache.
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
        check_len("frames", frames.len(), self.pinv.len())?;
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
            let isa = cpu_features().best();
            return Ok(match polar {
                None => quad::quad_image::<T, false>(
                    isa,
                    rows,
                    width,
                    rules,
                    s0,
                    s1,
                    s2,
                    mask,
                    &mut [],
                    &mut [],
                ),
                Some((dolp, aolp)) => {
                    check_len("dolp", dolp.len(), n)?;
                    check_len("aolp", aolp.len(), n)?;
                    quad::quad_image::<T, true>(
                        isa, rows, width, rules, s0, s1, s2, mask, dolp, aolp,
                    )
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
}
