//! The per-pixel noise model of a map: the standard error of every pixel's DoLP in every
//! capture, from the shot and read noise of the raw values, propagated through the
//! Stokes solve, the `b × b` block sum and the DoLP.
//!
//! # Model
//! A raw value `I_a` (DN above the dark level, polarizer angle `a`) has variance
//!
//! ```text
//! Var I_a = r² + Î_a / g          (read noise r in DN; shot noise, gain g in e⁻/DN)
//! ```
//!
//! with `Î_a = (S0 + S1 cos 2a + S2 sin 2a)/2` the value predicted by the pixel's Stokes
//! vector (CONVENTIONS). The Stokes vector is linear in the raw values, `S = Σ_a c_a I_a`
//! (`c_a` the column of the solver's pseudo-inverse), and a block's Stokes vector is the
//! sum of its `b²` pixels' (independent), so by the delta method on
//! `D = √(S1² + S2²)/S0` with gradient `∇D = (−D/S0, S1/(S0 L), S2/(S0 L))`,
//! `L = √(S1² + S2²)`:
//!
//! ```text
//! Var D = r² · A + (1/g) · B,    A = b² Σ_a (∇D·c_a)²,   B = Σ_a (∇D·c_a)² Î_a
//! ```
//!
//! (`Î_a` of the block sum). [`noise_terms`] gives `A` and `B` of a block; the DoLP
//! kernels ([`super::frames_dolp_noise`], [`super::stokes_dolp_noise`]) write them as two
//! images per capture. The unknowns `r²` and `1/g` are the same for every pixel and
//! capture of a map (one camera): [`NoiseModel`].
//!
//! Stokes captures (S0, S1, S2 files in DN / exposure) are taken back to DN (× exposure)
//! and treated as a 0/45/90/135° analyzer. Bilinearly demosaiced DoFP captures are
//! treated as independent 0/45/90/135° pixels: interpolation correlates neighbours, which
//! changes every block's variance by nearly the same factor (4 for even `b ≥ 2`), and that
//! factor is absorbed by the estimated scale below; at `b = 1` the factor depends on the
//! pixel's place in the 2 × 2 cell (1 to 1/4 per channel), an approximation.
//!
//! # Estimation from the data
//! A real camera's `r` and `g` are rarely at hand, so the map estimates them from its own
//! residuals ([`estimate_noise`]): a sample of up to [`NOISE_SAMPLE`] pixels without
//! flags is fitted with weights from a first guess; each residual `e_t` of a fit with
//! status `ok` has `E e_t² = (1 − h_t) Var D_t` (`h_t` the leverage of row `t` in the
//! weighted fit, `Σ h_t = 2`), which is linear in `(r², 1/g)`: iteratively reweighted least
//! squares (weights `1/Var(e_t²) ∝ 1/(E e_t²)²`) over all rows of the sample gives both,
//! constrained to be `≥ 0` (a single term when the two are not separable, e.g. when every
//! pixel has the same brightness). Pixels whose residuals are improbable under the
//! estimate (`P(χ²_{T−2} ≥ χ²) < 10⁻⁴`: plate edges, mixed pixels) are then left out and
//! the estimate made once more. With ~10⁴ pixels and `T − 2` degrees of freedom each, the
//! scale is known to a fraction of a per cent: the per-pixel standard errors from the
//! weighted covariance `(JᵀWJ)⁻¹` need no per-pixel reduced-χ² scaling (whose `T − 2`
//! degrees of freedom make `|error|/SE` a Student's t, within 3 SE for only ~97.6% of
//! pixels at `T = 8`).
//!
//! Systematic errors (the angles, a DoLP floor, the analyzer's extinction and retardance)
//! are not part of this model: they are common to many pixels, not noise (see
//! [`super::sets`] and `docs/ERRORS.md`).

use crate::dop::dop_grad;
use crate::error::{CoreError, Result, check_len};
use crate::fit::{FitStatus, NkFit, fit_batch, fit_batch_pixel_beta};
use crate::stokes::StokesSolver;
use crate::systematic::chi2_sf;

use super::{Betas, signal_reason};

/// Largest number of pixels fitted to estimate the noise model.
pub const NOISE_SAMPLE: usize = 20_000;

/// Fewest usable pixels for an estimate.
pub const NOISE_MIN_PIXELS: usize = 30;

/// The analyzer of a capture as the noise model sees it: per polarizer angle `a`,
/// `cos 2a`, `sin 2a` and the pseudo-inverse column `c_a` (`S = Σ_a c_a I_a`).
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseAnalyzer {
    rows: Vec<[f64; 5]>,
}

impl NoiseAnalyzer {
    /// The analyzer of a Stokes solver (its angles and pseudo-inverse).
    pub fn of_solver(s: &StokesSolver) -> Self {
        let rows = s
            .angles()
            .iter()
            .zip(s.coef_f32())
            .map(|(&a, c)| {
                let (sn, cs) = (2.0 * a).sin_cos();
                [cs, sn, c[0] as f64, c[1] as f64, c[2] as f64]
            })
            .collect();
        Self { rows }
    }

    /// The ideal 0/45/90/135° analyzer (DoFP and Stokes captures):
    /// `S0 = (I0 + I45 + I90 + I135)/2`, `S1 = I0 − I90`, `S2 = I45 − I135`.
    pub fn quad() -> Self {
        Self {
            rows: vec![
                [1.0, 0.0, 0.5, 1.0, 0.0],
                [0.0, 1.0, 0.5, 0.0, 1.0],
                [-1.0, 0.0, 0.5, -1.0, 0.0],
                [0.0, -1.0, 0.5, 0.0, -1.0],
            ],
        }
    }
}

/// The noise terms `(A, B)` of one block (module documentation) from its summed Stokes
/// vector in DN; `bin2` = number of pixels of the block. NaN when `S0 ≤ 0` or a value is
/// not finite. With `L = 0` the gradient direction is undefined; `(0, 1/S0, 0)` is used
/// (the scale of the DoLP noise floor).
#[inline]
pub fn noise_terms(an: &NoiseAnalyzer, s: [f64; 3], bin2: f64) -> (f32, f32) {
    let [s0, s1, s2] = s;
    if !(s0 > 0.0 && s0.is_finite() && s1.is_finite() && s2.is_finite()) {
        return (f32::NAN, f32::NAN);
    }
    let l = (s1 * s1 + s2 * s2).sqrt();
    let d = l / s0;
    let g = if l > 0.0 {
        [-d / s0, s1 / (s0 * l), s2 / (s0 * l)]
    } else {
        [0.0, 1.0 / s0, 0.0]
    };
    let (mut a, mut b) = (0.0, 0.0);
    for r in &an.rows {
        let c = g[0] * r[2] + g[1] * r[3] + g[2] * r[4];
        let c2 = c * c;
        a += c2;
        b += c2 * (0.5 * (s0 + s1 * r[0] + s2 * r[1])).max(0.0);
    }
    ((a * bin2) as f32, b as f32)
}

/// The two parameters of the noise model, the same for every pixel and capture of a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// Read-noise variance `r²`, DN².
    pub read_var_dn2: f64,
    /// Inverse gain `1/g`, DN per electron (the shot-noise variance of a raw value `I`
    /// is `I/g`).
    pub inv_gain: f64,
}

impl NoiseModel {
    /// The DoLP standard error of a block with noise terms `(a, b)`:
    /// `√(r² A + B/g)` (NaN when the terms are).
    #[inline]
    pub fn dolp_se(&self, a: f32, b: f32) -> f64 {
        (self.read_var_dn2 * a as f64 + self.inv_gain * b as f64).sqrt()
    }
}

/// The result of [`estimate_noise`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseEstimate {
    /// The estimated model.
    pub model: NoiseModel,
    /// Pixels of the sample used in the final estimate.
    pub pixels: usize,
    /// Pixels of the sample left out as improbable under the first estimate.
    pub outliers: usize,
    /// Mean over the used pixels of `χ²/(T − 2)` (weighted by the final model): ≈ 1.
    pub reduced_chi2: f64,
}

/// One residual of the sample: its regressors `(1 − h) A`, `(1 − h) B` and `e²`.
#[derive(Debug, Clone, Copy)]
struct Row {
    xa: f64,
    xb: f64,
    e2: f64,
    one_h: f64,
}

/// Estimate the noise model of a map from its own fit residuals (module documentation).
///
/// Inputs as [`super::fit_and_classify`]: the angles, the DoLP images, the noise terms
/// `(A, B)` of every capture (`read`, `shot`) and the signal flags. Only pixels without a
/// flag, with every capture's DoLP, angle and terms finite, enter the sample (every
/// `m`-th such pixel, at most [`NOISE_SAMPLE`]). `Ok(None)` when fewer than
/// [`NOISE_MIN_PIXELS`] pixels give an `ok` fit, or the residuals give no positive
/// variance.
///
/// Errors: inconsistent numbers or sizes of images.
pub fn estimate_noise(
    betas: Betas<'_>,
    dolp: &[&[f32]],
    read: &[&[f32]],
    shot: &[&[f32]],
    flags: &[u8],
) -> Result<Option<NoiseEstimate>> {
    let inp = NoiseInputs {
        betas,
        dolp,
        read,
        shot,
        flags,
    };
    inp.check()?;
    let npix = flags.len();
    let t_len = dolp.len();
    if t_len < 3 {
        return Ok(None);
    }
    let count = (0..npix).filter(|&p| inp.mask_of(p) != 0).count();
    if count < NOISE_MIN_PIXELS {
        return Ok(None);
    }
    let stride = count.div_ceil(NOISE_SAMPLE);
    let mut sample: Vec<(u64, usize)> = (0..npix)
        .map(|p| (inp.mask_of(p), p))
        .filter(|&(m, _)| m != 0)
        .step_by(stride)
        .collect();
    sample.sort_unstable();
    // Residuals and leverages of the ok fits; first guess: read and shot terms of equal
    // weight at 1 DN² and 1 DN/e⁻.
    let mut rows: Vec<Row> = Vec::with_capacity(sample.len() * t_len);
    let mut spans: Vec<(usize, usize)> = Vec::with_capacity(sample.len());
    let mut blk = Block::default();
    let mut fits: Vec<NkFit> = Vec::new();
    for group in sample.chunk_by(|a, b| a.0 == b.0) {
        let mask = group[0].0;
        let ts: Vec<usize> = (0..t_len)
            .filter(|&t| mask == u64::MAX || mask & (1 << t) != 0)
            .collect();
        let tp = ts.len();
        blk.fill(&inp, group, &ts);
        fits.clear();
        fits.resize(group.len(), NkFit::default());
        match betas {
            Betas::Shared(plan) => fit_batch(plan, &blk.y, Some(&blk.se), &mut fits)?,
            Betas::PerPixel { plan, .. } => {
                fit_batch_pixel_beta(plan, &blk.b, &blk.y, Some(&blk.se), &mut fits)?
            }
        }
        for (i, f) in fits.iter().enumerate() {
            if f.status != FitStatus::Ok {
                continue;
            }
            let start = rows.len();
            if blk.push_rows(f, i * tp..(i + 1) * tp, &mut rows) {
                spans.push((start, rows.len() - start));
            }
        }
    }
    if spans.len() < NOISE_MIN_PIXELS {
        return Ok(None);
    }
    let Some(theta) = irls(&rows, spans.iter().copied()) else {
        return Ok(None);
    };
    Ok(Some(refit_without_outliers(&rows, &spans, theta)))
}

/// The inputs of [`estimate_noise`].
struct NoiseInputs<'a> {
    betas: Betas<'a>,
    dolp: &'a [&'a [f32]],
    read: &'a [&'a [f32]],
    shot: &'a [&'a [f32]],
    flags: &'a [u8],
}

impl NoiseInputs<'_> {
    /// The numbers and sizes of the images agree.
    fn check(&self) -> Result<()> {
        let npix = self.flags.len();
        let t_len = self.dolp.len();
        for (name, imgs) in [
            ("dolp", self.dolp),
            ("read", self.read),
            ("shot", self.shot),
        ] {
            check_len(name, imgs.len(), t_len)?;
            for d in imgs {
                check_len(name, d.len(), npix)?;
            }
        }
        match self.betas {
            Betas::Shared(plan) if plan.len() != t_len => Err(CoreError::LengthMismatch {
                name: "DoLP images (captures)",
                expected: plan.len(),
                got: t_len,
            }),
            Betas::PerPixel { beta, .. } if beta.len() != t_len => Err(CoreError::LengthMismatch {
                name: "beta images (captures)",
                expected: t_len,
                got: beta.len(),
            }),
            _ => Ok(()),
        }
    }

    /// β of pixel `p` in capture `t`.
    fn beta_of(&self, p: usize, t: usize) -> f64 {
        match self.betas {
            Betas::Shared(plan) => plan.betas()[t],
            Betas::PerPixel { beta, .. } => beta.get(t).map_or(f64::NAN, |b| b[p] as f64),
        }
    }

    /// The captures pixel `p` can use, as bits (`u64::MAX`: all, from 64 captures on):
    /// DoLP, terms and angle finite (a calibrated map leaves a pixel's dark or saturated
    /// captures out, DoLP NaN); at least 3, and all of them with shared angles; 0 for a
    /// flagged pixel.
    fn mask_of(&self, p: usize) -> u64 {
        let t_len = self.dolp.len();
        let full: u64 = if t_len >= 64 {
            u64::MAX
        } else {
            (1u64 << t_len) - 1
        };
        let per_pixel = matches!(self.betas, Betas::PerPixel { .. }) && t_len < 64;
        if signal_reason(self.flags[p]) != 0 {
            return 0;
        }
        let (dolp, read, shot) = (self.dolp, self.read, self.shot);
        let ok = |t: usize| {
            dolp[t][p].is_finite()
                && read[t][p].is_finite()
                && shot[t][p].is_finite()
                && (read[t][p] > 0.0 || shot[t][p] > 0.0)
                && self.beta_of(p, t).is_finite()
        };
        if per_pixel {
            let m = (0..t_len)
                .filter(|&t| ok(t))
                .fold(0u64, |m, t| m | (1 << t));
            if m.count_ones() >= 3 { m } else { 0 }
        } else if (0..t_len).all(ok) {
            full
        } else {
            0
        }
    }
}

/// The measurements of one group of sample pixels that use the same captures, pixel by
/// pixel: DoLP `y`, β `b`, standard error `se = √(A + B)` (first guess), read and shot
/// terms `ra`, `rb`.
#[derive(Default)]
struct Block {
    y: Vec<f64>,
    b: Vec<f64>,
    se: Vec<f64>,
    ra: Vec<f64>,
    rb: Vec<f64>,
}

impl Block {
    /// Fill with the captures `ts` of the pixels of `group`.
    fn fill(&mut self, inp: &NoiseInputs<'_>, group: &[(u64, usize)], ts: &[usize]) {
        self.y.clear();
        self.b.clear();
        self.se.clear();
        self.ra.clear();
        self.rb.clear();
        for &(_, p) in group {
            for &t in ts {
                self.y.push(inp.dolp[t][p] as f64);
                self.b.push(inp.beta_of(p, t));
                let (a, s) = (inp.read[t][p] as f64, inp.shot[t][p] as f64);
                self.ra.push(a);
                self.rb.push(s);
                self.se.push((a + s).sqrt());
            }
        }
    }

    /// Push the residual rows (regressors and leverages) of the fit `f` of the pixel
    /// whose measurements are `r`; `false` (nothing pushed) when its normal matrix is
    /// singular.
    fn push_rows(&self, f: &NkFit, r: std::ops::Range<usize>, rows: &mut Vec<Row>) -> bool {
        let (y, se) = (&self.y, &self.se);
        let grads: Vec<_> = self.b[r.clone()]
            .iter()
            .map(|&bt| dop_grad(f.n, f.k, bt))
            .collect();
        let (mut h00, mut h01, mut h11) = (0.0, 0.0, 0.0);
        for (g, s) in grads.iter().zip(&se[r.clone()]) {
            let w = 1.0 / (s * s);
            h00 += w * g.dp_dn * g.dp_dn;
            h01 += w * g.dp_dn * g.dp_dk;
            h11 += w * g.dp_dk * g.dp_dk;
        }
        let det = h00 * h11 - h01 * h01;
        if !(det > 0.0 && det.is_finite()) {
            return false;
        }
        for (t, g) in grads.iter().enumerate() {
            let j = r.start + t;
            let w = 1.0 / (se[j] * se[j]);
            let q = (h11 * g.dp_dn * g.dp_dn - 2.0 * h01 * g.dp_dn * g.dp_dk
                + h00 * g.dp_dk * g.dp_dk)
                / det;
            let one_h = (1.0 - w * q).clamp(0.0, 1.0);
            let e = y[j] - g.p;
            rows.push(Row {
                xa: one_h * self.ra[j],
                xb: one_h * self.rb[j],
                e2: e * e,
                one_h,
            });
        }
        true
    }
}

/// The final estimate from the first, `theta`: leave out the improbable pixels and
/// estimate once more.
fn refit_without_outliers(
    rows: &[Row],
    spans: &[(usize, usize)],
    theta: [f64; 2],
) -> NoiseEstimate {
    let mut theta = theta;
    // χ² = Σ e²/σ², σ² = v/(1 − h): T_p − 2 degrees of freedom.
    let chi2 = |th: [f64; 2], (s, c): (usize, usize)| -> f64 {
        rows[s..s + c]
            .iter()
            .map(|r| {
                let v = th[0] * r.xa + th[1] * r.xb;
                if v > 0.0 { r.e2 * r.one_h / v } else { 0.0 }
            })
            .sum::<f64>()
    };
    let dof = |(_, c): (usize, usize)| c.saturating_sub(2).max(1) as f64;
    let kept: Vec<(usize, usize)> = spans
        .iter()
        .copied()
        .filter(|&sp| chi2_sf(chi2(theta, sp), dof(sp)) >= 1e-4)
        .collect();
    let outliers = spans.len() - kept.len();
    if kept.len() >= NOISE_MIN_PIXELS
        && let Some(t2) = irls(rows, kept.iter().copied())
    {
        theta = t2;
    }
    let reduced_chi2 = kept
        .iter()
        .map(|&sp| chi2(theta, sp) / dof(sp))
        .sum::<f64>()
        / kept.len().max(1) as f64;
    NoiseEstimate {
        model: NoiseModel {
            read_var_dn2: theta[0],
            inv_gain: theta[1],
        },
        pixels: kept.len(),
        outliers,
        reduced_chi2,
    }
}

/// Iteratively reweighted least squares of `e² ≈ θ_A xa + θ_B xb` over the rows of
/// `spans`, `θ ≥ 0`; `None` when no positive variance results.
fn irls(rows: &[Row], spans: impl Iterator<Item = (usize, usize)> + Clone) -> Option<[f64; 2]> {
    // Start: ordinary least squares of one scale on (xa + xb).
    let mut theta = {
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (s, c) in spans.clone() {
            for r in &rows[s..s + c] {
                let x = r.xa + r.xb;
                sxy += x * r.e2;
                sxx += x * x;
            }
        }
        let s = sxy / sxx;
        if !(s > 0.0 && s.is_finite()) {
            return None;
        }
        [s, s]
    };
    for _ in 0..6 {
        let (mut aa, mut ab, mut bb, mut ay, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (s, c) in spans.clone() {
            for r in &rows[s..s + c] {
                let v = theta[0] * r.xa + theta[1] * r.xb;
                if !(v > 0.0) {
                    continue;
                }
                let w = 1.0 / (v * v);
                aa += w * r.xa * r.xa;
                ab += w * r.xa * r.xb;
                bb += w * r.xb * r.xb;
                ay += w * r.xa * r.e2;
                by += w * r.xb * r.e2;
            }
        }
        let det = aa * bb - ab * ab;
        let two = if det > 1e-9 * aa * bb {
            let ta = (bb * ay - ab * by) / det;
            let tb = (aa * by - ab * ay) / det;
            (ta >= 0.0 && tb >= 0.0).then_some([ta, tb])
        } else {
            None
        };
        let next = match two {
            Some(t) => t,
            None => {
                // One term: the one with the smaller weighted sum of squares.
                let ta = if aa > 0.0 { (ay / aa).max(0.0) } else { 0.0 };
                let tb = if bb > 0.0 { (by / bb).max(0.0) } else { 0.0 };
                let sse = |th: [f64; 2]| -> f64 {
                    let mut s2 = 0.0;
                    for (s, c) in spans.clone() {
                        for r in &rows[s..s + c] {
                            let v = theta[0] * r.xa + theta[1] * r.xb;
                            if v > 0.0 {
                                let d = r.e2 - th[0] * r.xa - th[1] * r.xb;
                                s2 += d * d / (v * v);
                            }
                        }
                    }
                    s2
                };
                let (a_only, b_only) = ([ta, 0.0], [0.0, tb]);
                if sse(a_only) <= sse(b_only) {
                    a_only
                } else {
                    b_only
                }
            }
        };
        if !(next[0] + next[1] > 0.0) || !next[0].is_finite() || !next[1].is_finite() {
            return None;
        }
        let change = (next[0] - theta[0]).abs() / theta[0].max(1e-300)
            + (next[1] - theta[1]).abs() / theta[1].max(1e-300);
        theta = next;
        if change < 1e-6 {
            break;
        }
    }
    Some(theta)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The delta-method terms match a Monte Carlo of the 0/45/90/135° analyzer with shot
    /// and read noise.
    #[test]
    fn noise_terms_match_monte_carlo() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let an = NoiseAnalyzer::of_solver(
            &StokesSolver::from_degrees(&[0.0, 45.0, 90.0, 135.0]).unwrap(),
        );
        for (a, b) in an.rows.iter().zip(&NoiseAnalyzer::quad().rows) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() < 1e-6, "{a:?} vs {b:?}");
            }
        }
        let s = [3000.0f64, 400.0, -250.0];
        let (r2, inv_g) = (9.0, 0.4);
        let (a, b) = noise_terms(&an, s, 1.0);
        let want = (r2 * a as f64 + inv_g * b as f64).sqrt();
        let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(7);
        let unit = Normal::new(0.0, 1.0).unwrap();
        let n = 40_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let mut st = [0.0f64; 3];
            for r in &an.rows {
                let i = 0.5 * (s[0] + s[1] * r[0] + s[2] * r[1]);
                let v = i + (r2 + inv_g * i).sqrt() * unit.sample(&mut rng);
                st[0] += r[2] * v;
                st[1] += r[3] * v;
                st[2] += r[4] * v;
            }
            let d = (st[1] * st[1] + st[2] * st[2]).sqrt() / st[0];
            sum += d;
            sum2 += d * d;
        }
        let mean = sum / n as f64;
        let sd = (sum2 / n as f64 - mean * mean).sqrt();
        assert!((sd / want - 1.0).abs() < 0.02, "MC sd {sd} vs model {want}");
        // A 2 x 2 block: four times the read term, the shot term of the summed values.
        let (a4, b4) = noise_terms(&an, [4.0 * s[0], 4.0 * s[1], 4.0 * s[2]], 4.0);
        assert!((a4 as f64 / (a as f64 / 4.0) - 1.0).abs() < 1e-5);
        assert!((b4 as f64 / (b as f64 / 4.0) - 1.0).abs() < 1e-5);
        assert!(noise_terms(&an, [0.0, 1.0, 1.0], 1.0).0.is_nan());
    }

    #[test]
    fn dolp_se_of_the_model() {
        let m = NoiseModel {
            read_var_dn2: 4.0,
            inv_gain: 0.25,
        };
        assert!((m.dolp_se(1.0, 4.0) - 5f64.sqrt()).abs() < 1e-12);
    }
}
