//! An in-scene reference: a region of known material measured in the same captures as
//! the targets calibrates the polarimeter scale and the common angle offset that the
//! hypothesis tests ([`super::hypothesis`]) otherwise bound only by the error model.
//!
//! # The reference's fit
//!
//! The reference's rows `t` (local incidence angle `β_t`, measured DoLP `y_t`, band
//! `b(t)`) follow the model of the hypothesis tests with the reference's own bulk index
//! `N_b` and native layer `N_L,b` of thickness `d ∈ [d_min, d_max]`:
//!
//! ```text
//! m_t(d, s, δ) = s · |P_layer(N_b, N_L,b, d/λ_b; β_t + δ)|
//! ```
//!
//! (`P_layer` the single-layer Airy sum, Born & Wolf, *Principles of Optics*, 7th ed.,
//! §1.6.4 eq. 58; eq. 9 of the paper without a layer; [`layered_dolp`]). Here the scale
//! `s` and the offset `δ` are not bounded by the error model: they are what the reference
//! measures. `s` is free (`s > 0`; a fit above 1 is reported as it is) and `δ` is searched
//! within `±`[`SEARCH_OFFSET_DEG`]; only the layer thickness keeps its box. The estimate
//! minimises
//!
//! ```text
//! χ²(d, s, δ) = Σ_t (y_t − m_t)² / σ_t²,   σ_t² = dolp_sd_t² + (P'_t σ_angle,t / 2)²
//! ```
//!
//! (the row variance of the hypothesis tests: `P'_t = ∂P/∂β` of the reference under its
//! layer at mid range, [`angle_slope`]), with `s = Σ w y p / Σ w p²` in closed form, `(d, δ)`
//! on a grid refined by golden sections.
//!
//! # Uncertainty
//!
//! The standard errors are those of weighted least squares (e.g. Bevington & Robinson,
//! *Data Reduction and Error Analysis*, 3rd ed., §8.2): the covariance of `(s, δ, d)` is
//! `C = (JᵀWJ + Π)⁻¹`, `J` the model's derivatives at the minimum (central differences in
//! `δ` and `d`, `∂m/∂s = P`), `W = diag(1/σ_t²)`, and `Π` the precision of the thickness's
//! uniform box, `12/(d_max − d_min)²` on the `d` diagonal (a thickness the rows do not
//! pin is uncertain by its box, never more). `SE_s = √C_ss`, `SE_δ = √C_δδ`: the thickness
//! is marginalised, not fixed, so the calibration carries the reference's own layer.
//!
//! # What the targets get
//!
//! The scale and the common offset are shared by every region of the captures (one
//! polarimeter; the camera's direction error moves every region's `β` alike,
//! docs/ERRORS.md). A target measured with the reference is tested with its bounds
//! shrunk to what the reference leaves ([`Calibration::bounds`]):
//!
//! ```text
//! s ∈ [ŝ − k SE_s, min(ŝ + k SE_s, 1)],   δ ∈ [δ̂ − k SE_δ, δ̂ + k SE_δ]
//! ```
//!
//! with `k` = [`REFERENCE_SIGMAS`] = 3 (the truth is outside with probability 0.27% per
//! nuisance, small against the test's `1 − p`), and the hypothesis tests run on these
//! boxes ([`classify_rows_within`]).

// NaN-safe negated comparisons on purpose; index loops over 3×3 blocks read as the
// equations.
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    clippy::needless_range_loop,
    clippy::manual_range_contains
)]

use super::MultiPrototype;
use super::hypothesis::{
    CandidateModel, HypRow, HypothesisConfig, HypothesisOutcome, Nuisances, angle_slope,
    classify_rows, golden, layered_dolp,
};
use crate::error::{CoreError, Result};
use crate::systematic::chi2_sf;

/// The targets' boxes are the reference's estimates `± REFERENCE_SIGMAS` standard errors.
pub const REFERENCE_SIGMAS: f64 = 3.0;

/// The reference's common angle offset is searched within `±SEARCH_OFFSET_DEG` degrees.
pub const SEARCH_OFFSET_DEG: f64 = 5.0;

/// The smallest lower bound of a calibrated scale (a scale interval reaching 0 is not a
/// calibration).
const SCALE_FLOOR: f64 = 1e-3;

/// What a reference region measured: the polarimeter scale and the common angle offset
/// with their standard errors, its own layer thickness, and how well its material
/// explains its rows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// The polarimeter scale `ŝ` (unbounded: above 1 means the reference's model or
    /// index does not fit).
    pub scale: f64,
    /// Standard error of `ŝ`.
    pub scale_se: f64,
    /// The common angle offset `δ̂`, radians.
    pub offset: f64,
    /// Standard error of `δ̂`, radians.
    pub offset_se: f64,
    /// Correlation of `ŝ` and `δ̂`.
    pub corr: f64,
    /// The reference's layer thickness at the minimum, nm (0 without a layer).
    pub thickness_nm: f64,
    /// `χ²` at the minimum.
    pub chi2: f64,
    /// Degrees of freedom: rows − 2 − (1 with a layer range).
    pub dof: f64,
    /// `P(χ²_dof ≥ χ²)`: small when the reference's material does not explain its rows.
    pub p_value: f64,
    /// Rows used.
    pub rows: usize,
    /// Whether `δ̂` is at the edge of the search window (`±SEARCH_OFFSET_DEG`): then it is
    /// not a measurement.
    pub offset_at_edge: bool,
}

/// The scale and offset boxes given to the targets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// `[s_lo, s_hi]`, `0 < s_lo ≤ s_hi ≤ 1`.
    pub scale: (f64, f64),
    /// `[δ_lo, δ_hi]`, radians.
    pub offset: (f64, f64),
}

impl Calibration {
    /// The targets' boxes `ŝ ± k SE_s` (capped at 1) and `δ̂ ± k SE_δ` (module
    /// documentation). `None` when the scale box is empty (the reference's scale is above
    /// 1 by more than `k` standard errors) or the offset is not measured (at the edge of
    /// the search, or a non-finite error).
    pub fn bounds(&self, k: f64) -> Option<Bounds> {
        if self.offset_at_edge
            || !(self.scale_se.is_finite() && self.offset_se.is_finite() && k >= 0.0)
        {
            return None;
        }
        let s_hi = (self.scale + k * self.scale_se).min(1.0);
        let s_lo = (self.scale - k * self.scale_se).max(SCALE_FLOOR);
        if !(s_lo <= s_hi) {
            return None;
        }
        let half = k * self.offset_se;
        Some(Bounds {
            scale: (s_lo, s_hi),
            offset: (self.offset - half, self.offset + half),
        })
    }
}

/// Several references' calibrations as one: the inverse-variance weighted mean of each of
/// `ŝ` and `δ̂` (independent references; Bevington & Robinson §4.1), the summed `χ²` and
/// degrees of freedom. `None` for an empty list.
pub fn combine(cals: &[Calibration]) -> Option<Calibration> {
    let first = *cals.first()?;
    if cals.len() == 1 {
        return Some(first);
    }
    let mean = |v: &dyn Fn(&Calibration) -> (f64, f64)| {
        let (mut sw, mut swx) = (0.0, 0.0);
        for c in cals {
            let (x, se) = v(c);
            let w = 1.0 / (se * se);
            sw += w;
            swx += w * x;
        }
        (swx / sw, (1.0 / sw).sqrt())
    };
    let (scale, scale_se) = mean(&|c| (c.scale, c.scale_se));
    let (offset, offset_se) = mean(&|c| (c.offset, c.offset_se));
    let chi2: f64 = cals.iter().map(|c| c.chi2).sum();
    let dof: f64 = cals.iter().map(|c| c.dof).sum();
    Some(Calibration {
        scale,
        scale_se,
        offset,
        offset_se,
        corr: 0.0,
        thickness_nm: f64::NAN,
        chi2,
        dof,
        p_value: chi2_sf(chi2, dof),
        rows: cals.iter().map(|c| c.rows).sum(),
        offset_at_edge: cals.iter().any(|c| c.offset_at_edge),
    })
}

/// The model `|P_layer|` of row `r` at thickness `d` (nm) and offset `o` (radians).
fn model(cand: &CandidateModel, wavelengths: &[f64], r: &HypRow, d: f64, o: f64) -> f64 {
    let beta = (r.beta + o).clamp(0.0, std::f64::consts::FRAC_PI_2 - 1e-9);
    let bulk = cand.bulk[r.band];
    match &cand.layer {
        Some(l) if d > 0.0 => layered_dolp(bulk, l.index[r.band], d / wavelengths[r.band], beta),
        _ => crate::dop::dop(bulk.0, bulk.1, beta),
    }
}

/// Fit the reference `reference` (its bulk index and native layer at the rows' bands
/// `wavelengths`, nm) to its rows: the polarimeter scale and the common angle offset with
/// their standard errors, the layer thickness marginalised (module documentation).
///
/// Errors: [`CoreError::TooFew`] with fewer rows than parameters + 1 (3, or 4 with a
/// layer range); [`CoreError::OutOfRange`] / [`CoreError::LengthMismatch`] for a bad row,
/// wavelength or index.
pub fn calibrate(
    rows: &[HypRow],
    wavelengths: &[f64],
    reference: &CandidateModel,
) -> Result<Calibration> {
    // The rows and the index are checked as the hypothesis tests check them.
    let probe = HypothesisConfig {
        confidence: 0.95,
        nuisances: Nuisances::from_error_model(f64::INFINITY, 0.0, 0.0),
        open_world: false,
    };
    super::hypothesis::test_hypothesis(rows, wavelengths, reference, &probe)?;
    let (d_lo, d_hi) = reference
        .layer
        .as_ref()
        .map_or((0.0, 0.0), |l| (l.min_nm, l.max_nm));
    let with_d = d_hi > d_lo;
    let params = 2 + usize::from(with_d);
    if rows.len() <= params {
        return Err(CoreError::TooFew {
            what: "reference rows",
            needed: params + 1,
            got: rows.len(),
        });
    }
    let w: Vec<f64> = rows
        .iter()
        .map(|r| {
            // The slope of the reference as it is found (its layer at mid range), as the
            // hypothesis tests take it ([`angle_slope`]).
            let slope = angle_slope(reference, wavelengths, r.band, r.beta);
            let a = 0.5 * slope * r.angle_sd;
            1.0 / (r.dolp_sd * r.dolp_sd + a * a)
        })
        .collect();
    let c: f64 = rows.iter().zip(&w).map(|(r, w)| w * r.dolp * r.dolp).sum();
    let fit = RefFit {
        rows,
        wavelengths,
        reference,
        w,
        c,
        d_lo,
        d_hi,
    };
    let win = SEARCH_OFFSET_DEG.to_radians();
    let (d, o, step_o) = fit.search(win);
    let (chi2, s) = fit.profile(d, o);
    let cov = fit.covariance(d, o, s);
    let (scale_se, offset_se, corr) = match cov {
        Some(m) if m[0][0] > 0.0 && m[1][1] > 0.0 => {
            let (a, b) = (m[0][0].sqrt(), m[1][1].sqrt());
            (a, b, m[0][1] / (a * b))
        }
        _ => (f64::INFINITY, f64::INFINITY, 0.0),
    };
    let dof = (rows.len() - params) as f64;
    Ok(Calibration {
        scale: s,
        scale_se,
        offset: o,
        offset_se,
        corr,
        thickness_nm: d,
        chi2,
        dof,
        p_value: chi2_sf(chi2, dof),
        rows: rows.len(),
        offset_at_edge: (o.abs() - win).abs() < 0.5 * step_o,
    })
}

/// The reference's rows with their weights, and the thickness range, for [`calibrate`].
struct RefFit<'a> {
    rows: &'a [HypRow],
    wavelengths: &'a [f64],
    reference: &'a CandidateModel,
    /// Row weights `1/(σ_P² + (½ ∂P/∂β σ_angle)²)`.
    w: Vec<f64>,
    /// `Σ w P_meas²`.
    c: f64,
    /// Thickness range, nm (equal ends without a layer range).
    d_lo: f64,
    d_hi: f64,
}

impl RefFit<'_> {
    /// Whether the thickness is fitted.
    fn with_d(&self) -> bool {
        self.d_hi > self.d_lo
    }

    /// χ² profiled over s (closed form, s > 0), and that s, at thickness `d`, offset `o`.
    fn profile(&self, d: f64, o: f64) -> (f64, f64) {
        let (mut a, mut b) = (0.0, 0.0);
        for (r, wt) in self.rows.iter().zip(&self.w) {
            let p = model(self.reference, self.wavelengths, r, d, o);
            a += wt * p * p;
            b += wt * r.dolp * p;
        }
        if a > 0.0 && b > 0.0 {
            ((self.c - b * b / a).max(0.0), b / a)
        } else {
            (self.c, 0.0)
        }
    }

    /// The profiled minimum `(d, o)` over offsets within `±win`: a grid, then alternating
    /// golden-section refinements; also the offset grid step.
    fn search(&self, win: f64) -> (f64, f64, f64) {
        let (d_lo, d_hi) = (self.d_lo, self.d_hi);
        let (gd, go) = (if self.with_d() { 9 } else { 1 }, 81usize);
        let at = |lo: f64, hi: f64, n: usize, i: usize| {
            if n == 1 {
                lo
            } else {
                lo + (hi - lo) * i as f64 / (n - 1) as f64
            }
        };
        let mut best = (f64::INFINITY, d_lo, 0.0);
        for i in 0..gd {
            let d = at(d_lo, d_hi, gd, i);
            for j in 0..go {
                let o = at(-win, win, go, j);
                let chi2 = self.profile(d, o).0;
                if chi2 < best.0 {
                    best = (chi2, d, o);
                }
            }
        }
        let (mut d, mut o) = (best.1, best.2);
        let step_d = if gd > 1 {
            (d_hi - d_lo) / (gd - 1) as f64
        } else {
            0.0
        };
        let step_o = 2.0 * win / (go - 1) as f64;
        for _ in 0..4 {
            let (lo, hi) = ((o - step_o).max(-win), (o + step_o).min(win));
            o = golden(lo, hi, (60, 1e-10), |x| self.profile(d, x).0).0;
            if step_d > 0.0 {
                let (lo, hi) = ((d - step_d).max(d_lo), (d + step_d).min(d_hi));
                d = golden(lo, hi, (60, 1e-10), |x| self.profile(x, o).0).0;
            }
        }
        (d, o, step_o)
    }

    /// Covariance of (s, δ, d) from JᵀWJ plus the thickness box's precision, at
    /// thickness `d`, offset `o`, scale `s`; `None` when singular.
    fn covariance(&self, d: f64, o: f64, s: f64) -> Option<[[f64; 3]; 3]> {
        let (reference, wavelengths) = (self.reference, self.wavelengths);
        let (d_lo, d_hi, with_d) = (self.d_lo, self.d_hi, self.with_d());
        let ho = 1e-6;
        let hd = 1e-3 * (d_hi - d_lo).max(1e-3);
        let mut f = [[0.0f64; 3]; 3];
        for (r, wt) in self.rows.iter().zip(&self.w) {
            let p = model(reference, wavelengths, r, d, o);
            let mut j = [p, 0.0, 0.0];
            j[1] = s
                * (model(reference, wavelengths, r, d, o + ho)
                    - model(reference, wavelengths, r, d, o - ho))
                / (2.0 * ho);
            if with_d {
                let (lo, hi) = ((d - hd).max(0.0), d + hd);
                j[2] = s
                    * (model(reference, wavelengths, r, hi, o)
                        - model(reference, wavelengths, r, lo, o))
                    / (hi - lo);
            }
            for a in 0..3 {
                for b in 0..3 {
                    f[a][b] += wt * j[a] * j[b];
                }
            }
        }
        if with_d {
            f[2][2] += 12.0 / ((d_hi - d_lo) * (d_hi - d_lo));
            inverse3(&f)
        } else {
            let det = f[0][0] * f[1][1] - f[0][1] * f[1][0];
            (det > 0.0).then(|| {
                let mut m = [[0.0; 3]; 3];
                m[0][0] = f[1][1] / det;
                m[1][1] = f[0][0] / det;
                m[0][1] = -f[0][1] / det;
                m[1][0] = m[0][1];
                m
            })
        }
    }
}

/// The inverse of a symmetric positive definite 3×3 matrix (cofactors); `None` when
/// singular.
fn inverse3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let c = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    if !(det.is_finite() && det > 0.0) {
        return None;
    }
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = c(j, i) / det;
        }
    }
    Some(out)
}

/// [`classify_rows`] with the scale in `bounds.scale` and the common offset in
/// `bounds.offset` instead of the error model's `[s_min, 1]` and `[−Δ, Δ]`
/// (`cfg.nuisances` is not used; `cfg.confidence` is).
///
/// The hypothesis tests bound the scale by `[s_min, 1]` and the offset by a box centred
/// on 0; a box `[s_lo, s_hi] × [δ_lo, δ_hi]` is the same problem in new variables:
/// with `c = (δ_lo + δ_hi)/2` the rows' angles become `β_t + c` (offset box
/// `±(δ_hi − δ_lo)/2`), and with `y'_t = y_t/s_hi`, `σ'_t = σ_t/s_hi` (both parts: the
/// DoLP's and the angle's) the scale becomes `s' = s/s_hi ∈ [s_lo/s_hi, 1]`: every
/// `χ² = Σ (y − s P)²/σ²` is unchanged, and the evidence of every hypothesis is divided
/// by the same `s_hi^T`, so the probabilities are unchanged. The fitted scale, offset
/// and evidence are mapped back (`s = s_hi s'`, `δ = c + δ'`, `ln Z = ln Z' − T ln s_hi`).
/// The only approximation: the angle part of `σ_t` takes `P'` at `β_t + c` (the
/// calibrated angle) instead of `β_t`.
///
/// Errors: those of [`classify_rows`]; [`CoreError::OutOfRange`] for a box that is
/// empty, not finite, with `s_lo ≤ 0` or `s_hi > 1`, or an offset box of half-width
/// 0.5 radian or more.
pub fn classify_rows_within(
    rows: &[HypRow],
    wavelengths: &[f64],
    protos: &[MultiPrototype],
    priors: Option<&[f64]>,
    cfg: &HypothesisConfig,
    bounds: &Bounds,
) -> Result<HypothesisOutcome> {
    let (s_lo, s_hi) = bounds.scale;
    if !(s_lo > 0.0 && s_lo <= s_hi && s_hi <= 1.0) {
        return Err(CoreError::OutOfRange {
            name: "scale bounds",
            value: s_lo,
            expected: "0 < s_lo <= s_hi <= 1",
        });
    }
    let (o_lo, o_hi) = bounds.offset;
    if !(o_lo.is_finite() && o_hi.is_finite() && o_lo <= o_hi) {
        return Err(CoreError::OutOfRange {
            name: "offset bounds",
            value: o_lo,
            expected: "finite, o_lo <= o_hi (radians)",
        });
    }
    let c = 0.5 * (o_lo + o_hi);
    let half = 0.5 * (o_hi - o_lo);
    let moved: Vec<HypRow> = rows
        .iter()
        .map(|r| HypRow {
            beta: (r.beta + c).clamp(0.0, std::f64::consts::FRAC_PI_2 - 1e-9),
            dolp: r.dolp / s_hi,
            dolp_sd: r.dolp_sd / s_hi,
            angle_sd: r.angle_sd / s_hi,
            band: r.band,
        })
        .collect();
    let inner = HypothesisConfig {
        confidence: cfg.confidence,
        nuisances: Nuisances {
            scale_min: s_lo / s_hi,
            offset_max: half,
        },
        open_world: cfg.open_world,
    };
    let mut out = classify_rows(&moved, wavelengths, protos, priors, &inner)?;
    let shift = rows.len() as f64 * s_hi.ln();
    let back = |f: &mut super::NuisanceFit| {
        f.scale *= s_hi;
        f.offset += c;
        f.log_evidence -= shift;
    };
    for cand in out
        .tested
        .iter_mut()
        .chain(out.decision.candidates.iter_mut())
    {
        if let Some(f) = cand.fit.as_mut() {
            back(f);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::LayerModel;

    const WL: f64 = 650.0;

    fn bk7() -> CandidateModel {
        CandidateModel {
            bulk: vec![(1.5145, 0.0)],
            layer: Some(LayerModel {
                index: vec![(1.5, 0.0)],
                min_nm: 0.0,
                max_nm: 2.0,
            }),
        }
    }

    /// Noiseless rows of `cand` at scale `s`, offset `o`, thickness `d`, with a
    /// deterministic ±`e` pattern.
    fn rows(cand: &CandidateModel, s: f64, o: f64, d: f64, e: f64, sd: f64) -> Vec<HypRow> {
        (0..10)
            .map(|i| {
                let beta = (45.0 + 25.0 * i as f64 / 9.0f64).to_radians();
                let r = HypRow {
                    beta,
                    dolp: 0.0,
                    dolp_sd: sd,
                    angle_sd: 0.001,
                    band: 0,
                };
                HypRow {
                    dolp: s * model(cand, &[WL], &r, d, o) + if i % 2 == 0 { e } else { -e },
                    ..r
                }
            })
            .collect()
    }

    #[test]
    fn a_glass_reference_measures_the_scale_and_the_offset() {
        let cand = bk7();
        let (s, o) = (0.88, 0.6f64.to_radians());
        let cal = calibrate(&rows(&cand, s, o, 1.0, 0.0, 0.003), &[WL], &cand).unwrap();
        assert!((cal.scale - s).abs() < 1e-4, "{cal:?}");
        assert!((cal.offset - o).abs() < 1e-4, "{cal:?}");
        assert!(cal.chi2 < 1e-6 && !cal.offset_at_edge, "{cal:?}");
        // The errors shrink with the noise and are small against the error model's
        // boxes (a 10:1 analyzer leaves s in [0.82, 1]).
        assert!(cal.scale_se > 0.0 && cal.scale_se < 0.01, "{cal:?}");
        assert!(
            cal.offset_se > 0.0 && cal.offset_se < 0.2f64.to_radians(),
            "{cal:?}"
        );
        let b = cal.bounds(REFERENCE_SIGMAS).unwrap();
        assert!(b.scale.0 < s && s < b.scale.1 && b.scale.1 <= 1.0, "{b:?}");
        assert!(b.offset.0 < o && o < b.offset.1, "{b:?}");
        // Noise moves the estimate by about its standard error, not by many.
        let noisy = calibrate(&rows(&cand, s, o, 1.0, 0.003, 0.003), &[WL], &cand).unwrap();
        assert!((noisy.scale - s).abs() < 4.0 * noisy.scale_se, "{noisy:?}");
        assert!(
            (noisy.offset - o).abs() < 4.0 * noisy.offset_se,
            "{noisy:?}"
        );
        // A scale above 1 beyond its errors leaves no box; too few rows are refused.
        let high = Calibration { scale: 1.2, ..cal };
        assert!(high.bounds(REFERENCE_SIGMAS).is_none());
        assert!(matches!(
            calibrate(&rows(&cand, s, o, 1.0, 0.0, 0.003)[..3], &[WL], &cand),
            Err(CoreError::TooFew { .. })
        ));
    }

    #[test]
    fn boxes_away_from_the_defaults_are_the_same_problem() {
        // Aluminium-like rows at scale 0.9 and offset +0.5°, tested within the box
        // [0.88, 0.92] × [0.4°, 0.6°]: the fitted nuisances lie in the box, and the
        // reported χ² is that of the original rows at the fitted (s, δ) mapped back.
        let protos = vec![MultiPrototype::from(crate::classify::Prototype {
            class: "al".into(),
            n: 1.5,
            k: 7.6,
            cov: None,
            category: None,
            source: String::new(),
        })];
        let cand = CandidateModel::from_prototype(&protos[0], &[WL]).unwrap();
        let (s, o) = (0.9, 0.5f64.to_radians());
        let r = rows(&cand, s, o, 0.0, 0.001, 0.003);
        let cfg = HypothesisConfig {
            confidence: 0.95,
            nuisances: Nuisances::from_error_model(10.0, 0.0, 0.01),
            open_world: false,
        };
        let b = Bounds {
            scale: (0.88, 0.92),
            offset: (0.4f64.to_radians(), 0.6f64.to_radians()),
        };
        let out = classify_rows_within(&r, &[WL], &protos, None, &cfg, &b).unwrap();
        let f = out.tested[0].fit.unwrap();
        assert!(f.scale >= 0.88 - 1e-12 && f.scale <= 0.92 + 1e-12, "{f:?}");
        assert!(
            f.offset >= b.offset.0 - 1e-12 && f.offset <= b.offset.1 + 1e-12,
            "{f:?}"
        );
        assert!(f.consistent, "{f:?}");
        let c = 0.5 * (b.offset.0 + b.offset.1);
        let direct: f64 = r
            .iter()
            .map(|x| {
                let m = f.scale * model(&cand, &[WL], x, 0.0, f.offset);
                let a =
                    0.5 * crate::dop::dop_beta_derivs(1.5, 7.6, x.beta + c).dp_dbeta * x.angle_sd;
                (x.dolp - m).powi(2) / (x.dolp_sd.powi(2) + a * a)
            })
            .sum();
        assert!(
            (direct - f.chi2).abs() < 1e-9 * (1.0 + direct),
            "{direct} {f:?}"
        );
        // The same box at the origin is classify_rows itself.
        let origin = Bounds {
            scale: (0.5, 1.0),
            offset: (-0.01, 0.01),
        };
        let a = classify_rows_within(&r, &[WL], &protos, None, &cfg, &origin).unwrap();
        let plain = HypothesisConfig {
            confidence: 0.95,
            nuisances: Nuisances {
                scale_min: 0.5,
                offset_max: 0.01,
            },
            open_world: false,
        };
        let p = classify_rows(&r, &[WL], &protos, None, &plain).unwrap();
        // (Compared field by field: the decision's NaN distances are never `==`.)
        assert_eq!(a.tested, p.tested);
        assert_eq!(a.decision.predicted, p.decision.predicted);
        let bad = Bounds {
            scale: (0.9, 1.1),
            offset: (0.0, 0.0),
        };
        assert!(classify_rows_within(&r, &[WL], &protos, None, &cfg, &bad).is_err());
    }
}
