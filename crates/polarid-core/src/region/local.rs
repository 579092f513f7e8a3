//! Region statistics with per-pixel geometry (calibrated captures, docs/GEOMETRY.md).
//!
//! A region of a calibrated capture mixes pixels with different `β` (eq. 5) and
//! different planes of incidence. Each pixel's linear Stokes components are first
//! expressed in its own plane-of-incidence frame: with `ψ_p` the image angle of the
//! trace of pixel `p`'s plane of incidence (measured like the AoLP, CONVENTIONS.md),
//!
//! ```text
//! S1'_p =  S1_p cos 2ψ_p + S2_p sin 2ψ_p
//! S2'_p = −S1_p sin 2ψ_p + S2_p cos 2ψ_p        (a rotation of (S1, S2) by −2ψ_p)
//! ```
//!
//! so that the s-polarized light of a single interface (AoLP = ψ + 90°) has
//! `S1' = −S0 P(β_p)`, `S2' = 0` at every pixel, and averaging does not depolarize.
//! The region's DoLP is that of the mean `S̄' = (S̄0, S̄1', S̄2')`:
//!
//! ```text
//! DoLP = √(S̄1'² + S̄2'²)/S̄0 = Σ_p S0_p P(β_p) / Σ_p S0_p
//! ```
//!
//! (the second form for noiseless single-interface pixels): the mean of `P(β_p)`
//! weighted by brightness. The region's geometry is reported with the same weights:
//! `β̄ = Σ w β / Σ w`, `s_β² = Σ w (β − β̄)² / Σ w` (the weights are the data, not a
//! sample, so the divisor is `Σ w`), the weighted means of `θi`, `θr` and the circular
//! weighted mean of `φ`, with `w_p = S0_p`.
//!
//! **Standard error.** The delta method of the far-field estimator
//! ([`super::dolp_with_se`]) is `SE² = F Σ_p z_p² / (n (n − 1))` with
//! `z_p = g · (S'_p − S̄')` and `g` the gradient of the DoLP at `S̄'`. Across a calibrated
//! region `z_p` also holds the deterministic variation of `P(β_p)`:
//! `z_p ≈ (S0_p/S̄0)(P(β_p) − DoLP) + noise`, which is not noise. It is removed by
//! least squares on the regressors `(S0_p/S̄0)·(1, Δ_p, Δ_p²)` with
//! `Δ_p = (β_p − β̄)/s_β` (the S0-weighted trend of the polarization in β, to second
//! order), and `SE² = F Σ_p r_p² / (n (n − q))` with `r_p` the residuals and `q` the
//! regressors kept (fewer when β does not vary). `F` is the [`Sampling`] inflation.

use crate::error::{CoreError, Result};
use crate::stokes::mask;

use super::{Rect, RegionStats, Sampling, dolp_with_se};

/// Below this spread of β (radians) a region is treated as having one β: the SE
/// regression keeps only its first regressor.
const FLAT_BETA: f64 = 1e-9;

/// Per-pixel geometry of a region: one value per pixel of its rectangle, row-major over
/// the rectangle (its first row first), radians, as
/// [`ViewGeometry::fill`](crate::geometry::ViewGeometry::fill) writes them.
#[derive(Debug, Clone, Copy)]
pub struct RegionGeometry<'a> {
    /// `β` of eq. (5).
    pub beta: &'a [f64],
    /// Source zenith `θi`.
    pub theta_i: &'a [f64],
    /// Camera zenith `θr`.
    pub theta_r: &'a [f64],
    /// `φ = φr − φi`, in `[0, 2π)`.
    pub phi: &'a [f64],
    /// Image angle of the trace of the plane of incidence, `[0, π)`; NaN (undefined,
    /// `β = 0`) is taken as 0.
    pub poi_angle: &'a [f64],
}

/// Statistics of one region of a calibrated capture ([`region_stats_local`]). Angles
/// in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalRegionStats {
    /// The statistics in the pixels' plane-of-incidence frames: `mean` is `S̄'`,
    /// `cov_mean` its covariance from the pixel scatter (as for a far-field region),
    /// `dolp` the DoLP of `S̄'` and `dolp_se` its standard error with the deterministic
    /// trend in β removed (module docs); the pixel counts.
    pub stats: RegionStats,
    /// Mean Stokes vector in the image frame.
    pub image_mean: [f64; 3],
    /// DoLP of `image_mean` (what averaging in the image frame would give; lower than
    /// `stats.dolp` when the plane of incidence turns across the region).
    pub image_dolp: f64,
    /// AoLP of `image_mean`, in `[0, π)` (NaN when its DoLP is 0).
    pub aolp: f64,
    /// AoLP of `S̄'` measured from the plane of incidence, in `[0, π)`; single-interface
    /// reflection gives `π/2`.
    pub aolp_poi: f64,
    /// S0-weighted mean of `β`.
    pub beta: f64,
    /// S0-weighted standard deviation of `β`.
    pub beta_sd: f64,
    /// S0-weighted mean of `θi`.
    pub theta_i: f64,
    /// S0-weighted mean of `θr`.
    pub theta_r: f64,
    /// S0-weighted circular mean of `φ`, in `[0, 2π)`.
    pub phi: f64,
    /// The far-field estimator's SE (pixel scatter, trend not removed), for comparison.
    pub dolp_se_scatter: Option<f64>,
    /// Regressors removed from the scatter for `stats.dolp_se` (0 to 3).
    pub trend_terms: usize,
}

/// `(S0, S1', S2')` of a pixel: `(S1, S2)` rotated by `−2ψ` (module docs).
#[inline]
fn to_poi_frame(s: [f64; 3], psi: f64) -> [f64; 3] {
    let psi = if psi.is_finite() { psi } else { 0.0 };
    let (sn, cs) = (2.0 * psi).sin_cos();
    [s[0], s[1] * cs + s[2] * sn, -s[1] * sn + s[2] * cs]
}

/// Half the angle of `(x, y)` in `[0, π)`; NaN at the origin.
fn half_angle(y: f64, x: f64) -> f64 {
    if x == 0.0 && y == 0.0 {
        return f64::NAN;
    }
    let a = (0.5 * y.atan2(x)).rem_euclid(std::f64::consts::PI);
    if a >= std::f64::consts::PI { 0.0 } else { a }
}

/// [`CoreError::InvalidRegion`] for `rect` with `reason`.
fn invalid(rect: Rect, reason: String) -> CoreError {
    CoreError::InvalidRegion {
        x: rect.x,
        y: rect.y,
        width: rect.width,
        height: rect.height,
        reason,
    }
}

/// The length checks of [`region_stats_local`]: the images `s` and `mask` of one frame
/// `width` pixels wide, `rect` inside it, and every geometry map of `rect`'s area.
fn check_inputs(
    width: usize,
    s: [&[f32]; 3],
    mask: &[u8],
    rect: Rect,
    geom: &RegionGeometry<'_>,
) -> Result<()> {
    crate::stokes::check_image(width, s[0].len())?;
    let n_img = s[0].len();
    crate::error::check_len("s1", s[1].len(), n_img)?;
    crate::error::check_len("s2", s[2].len(), n_img)?;
    crate::error::check_len("mask", mask.len(), n_img)?;
    rect.check(width, n_img / width)?;
    let area = rect.width * rect.height;
    for (name, len) in [
        ("beta map", geom.beta.len()),
        ("theta_i map", geom.theta_i.len()),
        ("theta_r map", geom.theta_r.len()),
        ("phi map", geom.phi.len()),
        ("poi_angle map", geom.poi_angle.len()),
    ] {
        crate::error::check_len(name, len, area)?;
    }
    Ok(())
}

/// Pass 1 of [`region_stats_local`]: counts, image and local sums, S0-weighted
/// geometry sums; `(S', β)` of every valid pixel.
struct Sums {
    /// Pixels per mask class (valid, saturated, dark, invalid).
    cnt: [u64; 4],
    /// `(S', β)` per valid pixel.
    px: Vec<([f64; 3], f64)>,
    /// `Σ S` in the image frame.
    sum_img: [f64; 3],
    /// `Σ S'` in the plane-of-incidence frames.
    sum_loc: [f64; 3],
    /// `Σ w`, `Σ w β`, `Σ w θi`, `Σ w θr`, `Σ w cos φ`, `Σ w sin φ` (`w = max(S0, 0)`).
    w: [f64; 6],
}

impl Sums {
    /// Pass 1 over `rect` of the images `s` (see [`region_stats_local`] for the errors).
    fn gather(
        width: usize,
        s: [&[f32]; 3],
        mask: &[u8],
        rect: Rect,
        geom: &RegionGeometry<'_>,
    ) -> Result<Self> {
        let [s0, s1, s2] = s;
        let mut cnt = [0u64; 4];
        let mut px: Vec<([f64; 3], f64)> = Vec::with_capacity(rect.width * rect.height);
        let mut sum_img = [0.0f64; 3];
        let mut sum_loc = [0.0f64; 3];
        let mut ws = [0.0f64; 6];
        for row in 0..rect.height {
            let o = (rect.y + row) * width + rect.x;
            let go = row * rect.width;
            for col in 0..rect.width {
                let (i, g) = (o + col, go + col);
                let m = mask[i];
                cnt[(m & 3) as usize] += 1;
                if m != mask::VALID {
                    continue;
                }
                let (b, ti, tr, ph) = (geom.beta[g], geom.theta_i[g], geom.theta_r[g], geom.phi[g]);
                if !(b.is_finite() && ti.is_finite() && tr.is_finite() && ph.is_finite()) {
                    return Err(invalid(
                        rect,
                        format!(
                            "pixel (column {}, row {}) has no geometry (beta {b}, theta_i {ti}, \
                             theta_r {tr}, phi {ph} rad)",
                            rect.x + col,
                            rect.y + row
                        ),
                    ));
                }
                let s = [s0[i] as f64, s1[i] as f64, s2[i] as f64];
                let l = to_poi_frame(s, geom.poi_angle[g]);
                for c in 0..3 {
                    sum_img[c] += s[c];
                    sum_loc[c] += l[c];
                }
                let w = s[0].max(0.0);
                for (acc, v) in ws.iter_mut().zip([1.0, b, ti, tr, ph.cos(), ph.sin()]) {
                    *acc += w * v;
                }
                px.push((l, b));
            }
        }
        Ok(Self {
            cnt,
            px,
            sum_img,
            sum_loc,
            w: ws,
        })
    }
}

/// Pass 2 of [`region_stats_local`]: `Σ w (β − β̄)²` and the upper triangle of
/// `Σ (S' − S̄')(S' − S̄')ᵀ`.
fn spread(px: &[([f64; 3], f64)], mean: [f64; 3], beta: f64) -> (f64, [[f64; 3]; 3]) {
    let mut swdb2 = 0.0;
    let mut c = [[0.0f64; 3]; 3];
    for (l, b) in px {
        swdb2 += l[0].max(0.0) * (b - beta) * (b - beta);
        let d = [l[0] - mean[0], l[1] - mean[1], l[2] - mean[2]];
        for a in 0..3 {
            for e in a..3 {
                c[a][e] += d[a] * d[e];
            }
        }
    }
    (swdb2, c)
}

/// Statistics of the region `rect` of Stokes images `s0, s1, s2` with validity `mask`
/// (all `width` pixels wide) whose pixels have the geometry `geom` (module docs).
///
/// Errors: [`CoreError::InvalidRegion`] when the region is empty, leaves the frame,
/// holds no valid pixel or has a valid pixel without a finite `β`, `θi`, `θr` or `φ`;
/// [`CoreError::LengthMismatch`] when a geometry map is not `width × height` of `rect`
/// long.
#[allow(clippy::too_many_arguments)]
pub fn region_stats_local(
    width: usize,
    s0: &[f32],
    s1: &[f32],
    s2: &[f32],
    mask: &[u8],
    rect: Rect,
    sampling: Sampling,
    geom: &RegionGeometry<'_>,
) -> Result<LocalRegionStats> {
    check_inputs(width, [s0, s1, s2], mask, rect, geom)?;
    let Sums {
        cnt,
        px,
        sum_img,
        sum_loc,
        w,
    } = Sums::gather(width, [s0, s1, s2], mask, rect, geom)?;
    let [sw, swb, swi, swr, swc, sws] = w;
    let pixels = cnt[0];
    let rejected = cnt[1] + cnt[2] + cnt[3];
    if px.is_empty() {
        return Err(invalid(
            rect,
            format!(
                "has no usable pixel ({} saturated, {} dark, {} invalid)",
                cnt[1], cnt[2], cnt[3]
            ),
        ));
    }
    let nf = px.len() as f64;
    let mean = sum_loc.map(|v| v / nf);
    let image_mean = sum_img.map(|v| v / nf);
    let wmean = |v: f64| if sw > 0.0 { v / sw } else { f64::NAN };
    let beta = wmean(swb);
    let phi = if swc == 0.0 && sws == 0.0 {
        f64::NAN
    } else {
        sws.atan2(swc).rem_euclid(std::f64::consts::TAU)
    };
    let (swdb2, c) = spread(&px, mean, beta);
    let beta_sd = wmean(swdb2).max(0.0).sqrt();
    let inflation = sampling.variance_inflation();
    let mut cov_mean = [[0.0f64; 3]; 3];
    if px.len() >= 2 {
        let f = inflation / ((nf - 1.0) * nf);
        for a in 0..3 {
            for e in a..3 {
                cov_mean[a][e] = c[a][e] * f;
                cov_mean[e][a] = cov_mean[a][e];
            }
        }
    }
    let (dolp, se_scatter) = dolp_with_se(mean, cov_mean);
    let se_scatter = if px.len() >= 2 { se_scatter } else { None };
    let (dolp_se, trend_terms) = match detrended_se(&px, mean, beta, beta_sd, inflation) {
        Some((se, q)) => (Some(se), q),
        None => (se_scatter, 0),
    };
    let image_dolp = (image_mean[1].hypot(image_mean[2]) / image_mean[0]).clamp(0.0, 1.0);
    Ok(LocalRegionStats {
        stats: RegionStats {
            mean,
            cov_mean,
            dolp,
            dolp_se,
            pixels,
            rejected,
            saturated: cnt[1],
        },
        image_mean,
        image_dolp,
        aolp: half_angle(image_mean[2], image_mean[1]),
        aolp_poi: half_angle(mean[2], mean[1]),
        beta,
        beta_sd,
        theta_i: wmean(swi),
        theta_r: wmean(swr),
        phi,
        dolp_se_scatter: se_scatter,
        trend_terms,
    })
}

/// The standard error of the DoLP of `mean` with the trend in β removed (module docs):
/// `(SE, regressors kept)`, or `None` when it cannot be formed (fewer pixels than
/// regressors + 1, `S̄0 <= 0`, or a mean without polarization, where the gradient is
/// undefined).
fn detrended_se(
    px: &[([f64; 3], f64)],
    mean: [f64; 3],
    beta: f64,
    beta_sd: f64,
    inflation: f64,
) -> Option<(f64, usize)> {
    let [m0, m1, m2] = mean;
    let l = m1.hypot(m2);
    if !(m0 > 0.0 && l > 0.0 && m0.is_finite()) {
        return None;
    }
    let g = [-(l / m0) / m0, m1 / (m0 * l), m2 / (m0 * l)];
    let scale = if beta_sd > FLAT_BETA { beta_sd } else { 1.0 };
    let regressors = |s: &[f64; 3], b: f64| -> [f64; 3] {
        let w = s[0] / m0;
        let d = (b - beta) / scale;
        [w, w * d, w * d * d]
    };
    let z = |s: &[f64; 3]| g[0] * (s[0] - m0) + g[1] * (s[1] - m1) + g[2] * (s[2] - m2);
    // Normal equations of z on the regressors.
    let mut xtx = [[0.0f64; 3]; 3];
    let mut xtz = [0.0f64; 3];
    for (s, b) in px {
        let x = regressors(s, *b);
        let zp = z(s);
        for a in 0..3 {
            xtz[a] += x[a] * zp;
            for e in 0..3 {
                xtx[a][e] += x[a] * x[e];
            }
        }
    }
    let q_max = if beta_sd > FLAT_BETA { 3 } else { 1 };
    let (theta, q) = (1..=q_max)
        .rev()
        .find_map(|q| solve_spd(&xtx, &xtz, q).map(|t| (t, q)))?;
    if px.len() <= q {
        return None;
    }
    let mut rss = 0.0;
    for (s, b) in px {
        let x = regressors(s, *b);
        let fit: f64 = (0..q).map(|a| x[a] * theta[a]).sum();
        let r = z(s) - fit;
        rss += r * r;
    }
    let nf = px.len() as f64;
    let var = inflation * rss / (nf * (nf - q as f64));
    Some((var.max(0.0).sqrt(), q))
}

/// Solve the leading `q × q` block of a symmetric positive definite system by Cholesky;
/// `None` when a pivot falls below `1e-12` of its diagonal (the regressors are
/// collinear).
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
fn solve_spd(a: &[[f64; 3]; 3], b: &[f64; 3], q: usize) -> Option<[f64; 3]> {
    let mut l = [[0.0f64; 3]; 3];
    for i in 0..q {
        for j in 0..=i {
            let s: f64 = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if !(s > 1e-12 * a[i][i]) || !s.is_finite() {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0f64; 3];
    for i in 0..q {
        y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0f64; 3];
    for i in (0..q).rev() {
        x[i] = (y[i] - (i + 1..q).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(w: usize, h: usize) -> Rect {
        Rect {
            x: 0,
            y: 0,
            width: w,
            height: h,
        }
    }

    #[test]
    fn rotation_to_the_plane_of_incidence() {
        // s-polarized light (AoLP = ψ + 90°) has S1' = −S0 P, S2' = 0.
        for psi_deg in [0.0f64, 17.0, 90.0, 133.0] {
            let psi = psi_deg.to_radians();
            let a = psi + std::f64::consts::FRAC_PI_2;
            let s = [2.0, 0.6 * (2.0 * a).cos(), 0.6 * (2.0 * a).sin()];
            let l = to_poi_frame(s, psi);
            assert!((l[1] + 0.6).abs() < 1e-12 && l[2].abs() < 1e-12, "{l:?}");
            assert!((half_angle(l[2], l[1]) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        }
    }

    #[test]
    fn turning_plane_of_incidence_does_not_depolarize() {
        // 2 x 2 pixels, ψ of 0°, 30°, 60°, 90°, DoLP 0.5 each, S0 from 1 to 4.
        let (w, h) = (2, 2);
        let psis: Vec<f64> = [0.0f64, 30.0, 60.0, 90.0]
            .iter()
            .map(|d| d.to_radians())
            .collect();
        let s0v: Vec<f32> = vec![1.0, 2.0, 3.0, 4.0];
        let mut s1v = vec![0f32; 4];
        let mut s2v = vec![0f32; 4];
        for p in 0..4 {
            let a = psis[p] + std::f64::consts::FRAC_PI_2;
            s1v[p] = (0.5 * s0v[p] as f64 * (2.0 * a).cos()) as f32;
            s2v[p] = (0.5 * s0v[p] as f64 * (2.0 * a).sin()) as f32;
        }
        let beta = [0.5, 0.6, 0.7, 0.8];
        let zeros = [0.0; 4];
        let phi = [std::f64::consts::PI; 4];
        let geom = RegionGeometry {
            beta: &beta,
            theta_i: &beta,
            theta_r: &zeros,
            phi: &phi,
            poi_angle: &psis,
        };
        let st = region_stats_local(
            w,
            &s0v,
            &s1v,
            &s2v,
            &[0u8; 4],
            rect(w, h),
            Sampling::Independent,
            &geom,
        )
        .unwrap();
        assert!((st.stats.dolp - 0.5).abs() < 1e-6, "{st:?}");
        assert!(st.image_dolp < 0.3, "{st:?}");
        assert!((st.aolp_poi - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        // Weighted by S0: (1·0.5 + 2·0.6 + 3·0.7 + 4·0.8)/10 = 0.7.
        assert!((st.beta - 0.7).abs() < 1e-12);
        let sd = ((0.04 + 2.0 * 0.01 + 0.0 + 4.0 * 0.01) / 10.0f64).sqrt();
        assert!((st.beta_sd - sd).abs() < 1e-12);
        assert!((st.phi - std::f64::consts::PI).abs() < 1e-12);
        // A map of the wrong length is refused.
        let short = RegionGeometry {
            beta: &beta[..3],
            ..geom
        };
        assert!(matches!(
            region_stats_local(
                w,
                &s0v,
                &s1v,
                &s2v,
                &[0u8; 4],
                rect(w, h),
                Sampling::Independent,
                &short
            ),
            Err(CoreError::LengthMismatch { .. })
        ));
    }

    #[test]
    fn spd_solver_and_collinear_fallback() {
        let a = [[4.0, 2.0, 0.0], [2.0, 3.0, 1.0], [0.0, 1.0, 2.0]];
        let x = solve_spd(&a, &[2.0, 5.0, 3.0], 3).unwrap();
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| a[i][j] * x[j]).sum();
            assert!((r - [2.0, 5.0, 3.0][i]).abs() < 1e-12);
        }
        let singular = [[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(solve_spd(&singular, &[1.0, 1.0, 1.0], 2).is_none());
        assert!(solve_spd(&singular, &[1.0, 1.0, 1.0], 1).is_some());
    }
}
