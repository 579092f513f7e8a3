//! How well planned captures can tell two materials apart under the hypothesis test of
//! [`super::hypothesis`] (`polarid classify MEASUREMENTS.csv`): the expected test
//! statistic of a wrong hypothesis, and the probability that the test rejects it.
//!
//! # Non-centrality
//!
//! A plan gives, per row `t`, the local incidence angle `β_t`, the row's independent
//! standard deviation `σ_t` (the same `σ_t² = dolp_se_t² + f² + (P'_t σ_angle/2)²` as the
//! test) and its band. Let material `A` be the truth, under its own nuisances
//! `θ_A = (d, s, δ)` (layer thickness in its range, polarimeter scale, common angle
//! offset), so that the noise-free rows are
//!
//! ```text
//! y_t = s · |P_layer(N_A, N_L,A, d/λ; β_t + δ)|
//! ```
//!
//! Testing hypothesis `B` on these noise-free rows gives
//!
//! ```text
//! λ_AB(θ_A) = min over B's box of Σ_t (y_t − m_B,t)² / σ_t²
//! ```
//!
//! the non-centrality of `B`'s statistic: with noise, a model locally linear in `B`'s
//! nuisances gives `χ²_min,B ~ χ'²_ν(λ_AB)`, the non-central χ² with `ν` degrees of
//! freedom (Seber & Wild, *Nonlinear Regression*, 1989, §5.9; for a linear model exact:
//! Scheffé, *The Analysis of Variance*, 1959, §2.6). `λ_AA = 0` when `A`'s nuisances lie
//! in its own box. The plan takes the worst case over `A`'s nuisances: the smallest
//! `λ_AB` over a grid of `θ_A` ([`truth_grid`]: the ends and middle of the thickness
//! range, both ends of the scale, the offset at `−Δ`, 0, `+Δ`).
//!
//! # Power
//!
//! `B` is rejected at confidence `p` when `χ²_min,B` exceeds the test's critical value.
//! The test's null distribution is the mixture of [`super::hypothesis`]; its mean, the
//! effective degrees of freedom `ν` (`NuisanceFit::dof`), is used here as the degrees
//! of freedom of a plain χ²: `c = χ²_ν(p)` (the mixture's quantile differs from it by
//! the box's part, a fraction of one degree of freedom). The power is
//!
//! ```text
//! power_AB = P(χ'²_ν(λ_AB) > c) = Σ_j Pois(j; λ/2) · Q_χ²(c; ν + 2j)
//! ```
//!
//! (the Poisson mixture of central χ² laws; Johnson, Kotz & Balakrishnan, *Continuous
//! Univariate Distributions* vol. 2, 2nd ed., 1995, eq. 29.2). The **margin** is
//! `λ_AB / λ*(ν)`, with `λ*` the non-centrality at which the power reaches the target
//! (default 0.95): ≥ 1 means `B` is rejected with at least that power.

use super::hypothesis::{
    CandidateModel, HypRow, HypothesisConfig, NuisanceFit, layered_dolp, test_hypothesis,
    test_statistic,
};
use crate::error::{CoreError, Result, check_len};
use crate::systematic::chi2_sf;

use super::hypothesis::chi2_quantile_any;

/// One planned row: where it is measured and how noisy it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanRow {
    /// Local incidence angle `β`, radians, in `(0, π/2)`.
    pub beta: f64,
    /// Independent DoLP standard deviation without the angle part, `√(dolp_se² + f²)`.
    pub dolp_sd: f64,
    /// Standard uncertainty of the source direction, radians (≥ 0).
    pub angle_sd: f64,
    /// Index of the row's band in the wavelengths given with the rows.
    pub band: usize,
}

/// The true material's nuisances: one point of its box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthPoint {
    /// Layer thickness, nm (0 without a layer).
    pub thickness_nm: f64,
    /// Polarimeter scale in `[s_min, 1]`.
    pub scale: f64,
    /// Common angle offset, radians.
    pub offset: f64,
}

/// The grid of the true material's nuisances over which the worst case is taken: the
/// thickness at its range's ends and middle (0 without a layer), the scale at `s_min`
/// and 1, the offset at `−Δ`, 0 and `Δ` (duplicates removed).
pub fn truth_grid(truth: &CandidateModel, cfg: &HypothesisConfig) -> Vec<TruthPoint> {
    let ds: Vec<f64> = match &truth.layer {
        Some(l) if l.max_nm > l.min_nm => vec![l.min_nm, 0.5 * (l.min_nm + l.max_nm), l.max_nm],
        Some(l) => vec![l.min_nm],
        None => vec![0.0],
    };
    let s_min = cfg.nuisances.scale_min;
    let ss: Vec<f64> = if s_min < 1.0 {
        vec![s_min, 1.0]
    } else {
        vec![1.0]
    };
    let off = cfg.nuisances.offset_max;
    let os: Vec<f64> = if off > 0.0 {
        vec![-off, 0.0, off]
    } else {
        vec![0.0]
    };
    let mut out = Vec::with_capacity(ds.len() * ss.len() * os.len());
    for &thickness_nm in &ds {
        for &scale in &ss {
            for &offset in &os {
                out.push(TruthPoint {
                    thickness_nm,
                    scale,
                    offset,
                });
            }
        }
    }
    out
}

/// The noise-free rows of material `truth` at nuisances `at`: `y_t = s · P_layer(β_t + δ)`
/// (module documentation), as [`HypRow`]s with the plan's `σ`.
pub fn truth_rows(
    rows: &[PlanRow],
    wavelengths: &[f64],
    truth: &CandidateModel,
    at: TruthPoint,
) -> Vec<HypRow> {
    rows.iter()
        .map(|r| {
            let bulk = truth.bulk[r.band];
            let (layer, d_waves) = match &truth.layer {
                Some(l) => (l.index[r.band], at.thickness_nm / wavelengths[r.band]),
                None => ((1.0, 0.0), 0.0),
            };
            HypRow {
                beta: r.beta,
                dolp: at.scale * layered_dolp(bulk, layer, d_waves, r.beta + at.offset),
                dolp_sd: r.dolp_sd,
                angle_sd: r.angle_sd,
                band: r.band,
            }
        })
        .collect()
}

/// The survival function of the non-central χ² law with `dof` degrees of freedom and
/// non-centrality `lambda`, `P(X > x)` (Poisson mixture of central χ² laws, module
/// documentation; summed outwards from the Poisson mode until the weights fall below
/// 1e-16). NaN for a NaN argument, `dof ≤ 0` or `lambda < 0`.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn noncentral_chi2_sf(x: f64, dof: f64, lambda: f64) -> f64 {
    if x.is_nan() || !(dof > 0.0) || !(lambda >= 0.0) || !dof.is_finite() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    if lambda == 0.0 {
        return chi2_sf(x, dof);
    }
    if !lambda.is_finite() {
        return 1.0;
    }
    let mu = 0.5 * lambda;
    let mode = mu.floor();
    // ln Pois(j; μ) = j ln μ − μ − ln j!
    let ln_w = |j: f64| j * mu.ln() - mu - ln_factorial(j);
    let term = |j: f64| ln_w(j).exp() * chi2_sf(x, dof + 2.0 * j);
    let mut sum = term(mode);
    let mut j = mode + 1.0;
    while ln_w(j) > -37.0 {
        sum += term(j);
        j += 1.0;
    }
    let mut j = mode - 1.0;
    while j >= 0.0 && ln_w(j) > -37.0 {
        sum += term(j);
        j -= 1.0;
    }
    sum.clamp(0.0, 1.0)
}

/// `ln j!` for a whole `j ≥ 0`: the sum of logs below 32, Stirling's series above
/// (error below 1e-12 there).
fn ln_factorial(j: f64) -> f64 {
    if j < 32.0 {
        (2..=(j as u64)).map(|i| (i as f64).ln()).sum()
    } else {
        j * j.ln() - j + 0.5 * (2.0 * std::f64::consts::PI * j).ln() + 1.0 / (12.0 * j)
            - 1.0 / (360.0 * j * j * j)
    }
}

/// The probability that a test at confidence `confidence` with `dof` degrees of freedom
/// rejects a hypothesis whose statistic has non-centrality `lambda` (module
/// documentation).
pub fn rejection_power(lambda: f64, dof: f64, confidence: f64) -> f64 {
    let c = chi2_quantile_any(confidence, dof);
    noncentral_chi2_sf(c, dof, lambda.max(0.0))
}

/// The non-centrality at which the rejection power reaches `power` (NaN for arguments
/// out of range): the root of `P(χ'²_ν(λ) > c) = power` with `c = χ²_ν(p)`, by Newton's
/// method kept inside a bracket (bisection when a step leaves it), with the derivative
/// `∂/∂λ P(χ'²_ν(λ) > c) = ½ [P(χ'²_{ν+2}(λ) > c) − P(χ'²_ν(λ) > c)]` (from the Poisson
/// mixture, Johnson, Kotz & Balakrishnan vol. 2, §29.4); relative tolerance 1e-10.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn lambda_for_power(dof: f64, confidence: f64, power: f64) -> f64 {
    if !(power > 0.0 && power < 1.0) || !(confidence > 0.0 && confidence < 1.0) {
        return f64::NAN;
    }
    if !(dof > 0.0 && dof.is_finite()) {
        return f64::NAN;
    }
    let c = chi2_quantile_any(confidence, dof);
    let g = |l: f64| noncentral_chi2_sf(c, dof, l);
    if g(0.0) >= power {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0f64, 10.0f64);
    while g(hi) < power {
        lo = hi;
        hi *= 2.0;
    }
    let mut x = 0.5 * (lo + hi);
    for _ in 0..100 {
        let gx = g(x);
        if gx < power {
            lo = x;
        } else {
            hi = x;
        }
        let slope = 0.5 * (noncentral_chi2_sf(c, dof + 2.0, x) - gx);
        let newton = x - (gx - power) / slope;
        let next = if slope > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        let done = (next - x).abs() <= 1e-10 * next.abs().max(1e-300) || hi - lo <= 1e-10 * hi;
        x = next;
        if done {
            break;
        }
    }
    x
}

/// How well the rows separate the truth `A` from the hypothesis `B` (module
/// documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Separation {
    /// `λ_AB`: the smallest noise-free `χ²_min` of `B` over `A`'s nuisance grid.
    pub lambda: f64,
    /// `B`'s effective degrees of freedom at that point.
    pub dof: f64,
    /// The critical value `χ²_ν(p)`.
    pub critical: f64,
    /// The probability that `B` is rejected.
    pub power: f64,
    /// `λ_AB / λ*(ν)` for the target power (≥ 1: rejected with at least that power).
    pub margin: f64,
    /// `A`'s nuisances at the worst case.
    pub worst: TruthPoint,
    /// `B`'s test on those noise-free rows (its nuisances at the minimum).
    pub fit: NuisanceFit,
}

/// The worst case of truth `truth` against hypothesis `alt` over `grid`: `(λ, ν, θ_A)`,
/// the smallest noise-free `χ²_min` of `alt` ([`test_statistic`]), its effective degrees
/// of freedom and the truth point where it is reached (the first of equal ones).
///
/// Errors: as [`separation`] (an empty grid: [`CoreError::LengthMismatch`]).
pub fn worst_case(
    rows: &[PlanRow],
    wavelengths: &[f64],
    truth: &CandidateModel,
    alt: &CandidateModel,
    cfg: &HypothesisConfig,
    grid: &[TruthPoint],
) -> Result<(f64, f64, TruthPoint)> {
    check_len("truth bands", truth.bulk.len(), wavelengths.len())?;
    let mut best: Option<(f64, f64, TruthPoint)> = None;
    for &at in grid {
        let hrows = truth_rows(rows, wavelengths, truth, at);
        let (chi2, dof) = test_statistic(&hrows, wavelengths, alt, cfg)?;
        if best.is_none_or(|(b, _, _)| chi2 < b) {
            best = Some((chi2, dof, at));
        }
    }
    best.ok_or(CoreError::LengthMismatch {
        name: "truth grid",
        expected: 1,
        got: 0,
    })
}

/// `λ / λ*(ν)`: the margin of a non-centrality `lambda` at `dof` degrees of freedom for
/// the rejection power `target_power` at `confidence` (infinite when any `λ` reaches it).
pub fn margin_of(lambda: f64, dof: f64, confidence: f64, target_power: f64) -> f64 {
    let need = lambda_for_power(dof.max(1e-3), confidence, target_power);
    if need > 0.0 {
        lambda.max(0.0) / need
    } else {
        f64::INFINITY
    }
}

/// [`Separation`] of truth `truth` from hypothesis `alt` on the planned `rows`, the worst
/// case over `grid` (normally [`truth_grid`]), for the rejection power `target_power`.
///
/// Errors: [`CoreError`] for bad rows, wavelengths, models, settings, an empty grid or
/// a target power outside `(0, 1)`.
pub fn separation(
    rows: &[PlanRow],
    wavelengths: &[f64],
    truth: &CandidateModel,
    alt: &CandidateModel,
    cfg: &HypothesisConfig,
    grid: &[TruthPoint],
    target_power: f64,
) -> Result<Separation> {
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    if !(target_power > 0.0 && target_power < 1.0) {
        return Err(CoreError::OutOfRange {
            name: "power",
            value: target_power,
            expected: "(0, 1)",
        });
    }
    if grid.is_empty() {
        check_len("truth grid", 0, 1)?;
    }
    check_len("truth bands", truth.bulk.len(), wavelengths.len())?;
    let (_, _, worst) = worst_case(rows, wavelengths, truth, alt, cfg, grid)?;
    let fit = test_hypothesis(
        &truth_rows(rows, wavelengths, truth, worst),
        wavelengths,
        alt,
        cfg,
    )?;
    let lambda = fit.chi2.max(0.0);
    let dof = fit.dof.max(1e-3);
    let critical = chi2_quantile_any(cfg.confidence, dof);
    let power = noncentral_chi2_sf(critical, dof, lambda);
    let need = lambda_for_power(dof, cfg.confidence, target_power);
    let margin = if need > 0.0 {
        lambda / need
    } else {
        f64::INFINITY
    };
    Ok(Separation {
        lambda,
        dof,
        critical,
        power,
        margin,
        worst,
        fit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::hypothesis::{LayerModel, Nuisances};

    fn cfg() -> HypothesisConfig {
        HypothesisConfig {
            confidence: 0.95,
            nuisances: Nuisances::from_error_model(100.0, 0.0, 0.2f64.to_radians()),
            open_world: false,
        }
    }

    fn rows(betas: &[f64]) -> Vec<PlanRow> {
        betas
            .iter()
            .map(|&b| PlanRow {
                beta: b.to_radians(),
                dolp_sd: 0.002,
                angle_sd: 0.2f64.to_radians(),
                band: 0,
            })
            .collect()
    }

    fn aluminum() -> CandidateModel {
        CandidateModel {
            bulk: vec![(1.55803, 7.7124)],
            layer: Some(LayerModel {
                index: vec![(1.65, 0.0)],
                min_nm: 2.0,
                max_nm: 5.0,
            }),
        }
    }

    fn copper() -> CandidateModel {
        CandidateModel {
            bulk: vec![(0.2378, 3.6264)],
            layer: Some(LayerModel {
                index: vec![(2.9, 0.1)],
                min_nm: 0.5,
                max_nm: 3.0,
            }),
        }
    }

    #[test]
    fn noncentral_sf_matches_known_values() {
        // λ = 0: the central law.
        assert!((noncentral_chi2_sf(3.841_458_820_694_124, 1.0, 0.0) - 0.05).abs() < 1e-9);
        // ν = 1: X = (Z + √λ)², P(X > c) = Q(√c − √λ) + Q(√c + √λ).
        let q = |z: f64| 0.5 * libm_erfc(z / std::f64::consts::SQRT_2);
        for &(c, l) in &[(3.84f64, 4.0f64), (1.0, 9.0), (10.0, 2.5), (0.5, 30.0)] {
            let want = q(c.sqrt() - l.sqrt()) + q(c.sqrt() + l.sqrt());
            let got = noncentral_chi2_sf(c, 1.0, l);
            assert!((got - want).abs() < 1e-6, "c {c} λ {l}: {got} vs {want}");
        }
        // Mean ν + λ: the median is below it and the law moves right with λ.
        let mut last = 0.0;
        for l in [0.0, 1.0, 5.0, 20.0, 100.0, 1000.0] {
            let p = noncentral_chi2_sf(10.0, 5.0, l);
            assert!(p >= last - 1e-9, "{l}");
            last = p;
        }
        assert!(noncentral_chi2_sf(10.0, 5.0, 1000.0) > 0.999_999);
    }

    // erfc by the complement of the core's normal CDF through chi2_sf(x², 1) = erfc(x/√2).
    fn libm_erfc(x: f64) -> f64 {
        if x >= 0.0 {
            chi2_sf(2.0 * x * x, 1.0)
        } else {
            2.0 - chi2_sf(2.0 * x * x, 1.0)
        }
    }

    #[test]
    fn lambda_for_power_inverts_the_power() {
        for &nu in &[1.0, 3.5, 8.0, 20.0] {
            let l = lambda_for_power(nu, 0.95, 0.95);
            assert!(l > 5.0 && l < 60.0, "{nu}: {l}");
            assert!((rejection_power(l, nu, 0.95) - 0.95).abs() < 1e-6);
        }
        // Classic table value: ν = 1, α = 0.05, power 0.95 needs λ = (1.960 + 1.645)² = 13.0.
        assert!((lambda_for_power(1.0, 0.95, 0.95) - 12.995).abs() < 0.01);
        assert!(lambda_for_power(1.0, 0.95, 1.5).is_nan());
    }

    #[test]
    fn a_material_is_not_separated_from_itself() {
        let c = cfg();
        let r = rows(&[45.0, 50.0, 55.0, 60.0, 65.0, 70.0]);
        let a = aluminum();
        let grid = truth_grid(&a, &c);
        assert_eq!(grid.len(), 18);
        let s = separation(&r, &[650.0], &a, &a, &c, &grid, 0.95).unwrap();
        assert!(s.lambda < 1e-6, "{s:?}");
        assert!(s.power < 0.06, "{s:?}");
        // Every single grid point is explained by its own hypothesis.
        for &at in &grid {
            let s = separation(&r, &[650.0], &a, &a, &c, &[at], 0.95).unwrap();
            assert!(s.lambda < 1e-5, "{at:?}: {}", s.lambda);
        }
    }

    #[test]
    fn separation_grows_with_rows_and_with_the_span() {
        let c = cfg();
        let (a, b) = (aluminum(), copper());
        let grid = truth_grid(&a, &c);
        let narrow = rows(&[40.0, 42.0, 44.0, 46.0, 48.0, 50.0]);
        let wide = rows(&[40.0, 46.0, 52.0, 58.0, 64.0, 70.0]);
        let s_n = separation(&narrow, &[650.0], &a, &b, &c, &grid, 0.95).unwrap();
        let s_w = separation(&wide, &[650.0], &a, &b, &c, &grid, 0.95).unwrap();
        assert!(s_w.lambda > s_n.lambda, "{} vs {}", s_w.lambda, s_n.lambda);
        // Twice the rows at the same angles: λ doubles (noise-free rows, same σ).
        let twice: Vec<PlanRow> = wide.iter().chain(wide.iter()).copied().collect();
        let s_2 = separation(&twice, &[650.0], &a, &b, &c, &grid, 0.95).unwrap();
        assert!(
            (s_2.lambda / s_w.lambda - 2.0).abs() < 0.05,
            "{} vs {}",
            s_2.lambda,
            s_w.lambda
        );
        assert!(s_2.margin > s_w.margin);
        // Halving σ multiplies λ by 4 (the angle part is small at these β).
        let sharp: Vec<PlanRow> = wide
            .iter()
            .map(|r| PlanRow {
                dolp_sd: r.dolp_sd / 2.0,
                angle_sd: 0.0,
                ..*r
            })
            .collect();
        let flat: Vec<PlanRow> = wide
            .iter()
            .map(|r| PlanRow {
                angle_sd: 0.0,
                ..*r
            })
            .collect();
        let c0 = HypothesisConfig {
            nuisances: Nuisances::from_error_model(100.0, 0.0, 0.0),
            ..c
        };
        let g0 = truth_grid(&a, &c0);
        let l1 = separation(&flat, &[650.0], &a, &b, &c0, &g0, 0.95)
            .unwrap()
            .lambda;
        let l4 = separation(&sharp, &[650.0], &a, &b, &c0, &g0, 0.95)
            .unwrap()
            .lambda;
        assert!((l4 / l1 - 4.0).abs() < 0.1, "{l4} vs {l1}");
    }

    #[test]
    fn the_worst_case_is_the_smallest_over_the_grid() {
        let c = cfg();
        let (a, b) = (aluminum(), copper());
        let r = rows(&[45.0, 52.0, 60.0, 68.0]);
        let grid = truth_grid(&a, &c);
        let all = separation(&r, &[650.0], &a, &b, &c, &grid, 0.95).unwrap();
        for &at in &grid {
            let one = separation(&r, &[650.0], &a, &b, &c, &[at], 0.95).unwrap();
            assert!(one.lambda >= all.lambda - 1e-12);
        }
        assert!(grid.contains(&all.worst));
        assert!(separation(&r, &[650.0], &a, &b, &c, &[], 0.95).is_err());
        assert!(separation(&r, &[650.0], &a, &b, &c, &grid, 1.0).is_err());
    }

    /// The power is what the test does: noisy rows of A, B's test at 95%, over seeds.
    #[test]
    fn the_power_predicts_the_rejection_rate() {
        use rand::SeedableRng;
        use rand::rngs::StdRng;
        use rand_distr::{Distribution, Normal};
        let c = cfg();
        let (a, b) = (aluminum(), copper());
        // A design of moderate power (not saturated at 0 or 1).
        let r: Vec<PlanRow> = rows(&[40.0, 43.0, 46.0, 49.0, 52.0, 55.0])
            .into_iter()
            .map(|r| PlanRow {
                dolp_sd: 0.008,
                ..r
            })
            .collect();
        let at = TruthPoint {
            thickness_nm: 3.5,
            scale: 0.99,
            offset: 0.0,
        };
        let s = separation(&r, &[650.0], &a, &b, &c, &[at], 0.95).unwrap();
        assert!(s.power > 0.2 && s.power < 0.9, "{s:?}");
        let clean = truth_rows(&r, &[650.0], &a, at);
        let mut rng = StdRng::seed_from_u64(5);
        let n = 400;
        let mut rejected = 0;
        for _ in 0..n {
            let noisy: Vec<HypRow> = clean
                .iter()
                .map(|h| {
                    let sd = h.dolp_sd;
                    HypRow {
                        dolp: h.dolp + Normal::new(0.0, sd).unwrap().sample(&mut rng),
                        ..*h
                    }
                })
                .collect();
            let f = test_hypothesis(&noisy, &[650.0], &b, &c).unwrap();
            if !f.consistent {
                rejected += 1;
            }
        }
        let rate = rejected as f64 / n as f64;
        // Binomial standard error ≤ 0.025 at n = 400. The plain χ²_ν critical value with
        // the test's mean ν is a little above the mixture's own quantile, so the stated
        // power is conservative: measured 0.74 rejected for 0.63 stated (docs/PLAN.md).
        assert!(
            rate >= s.power - 0.05 && rate <= s.power + 0.2,
            "rejected {rate} vs power {}",
            s.power
        );
    }
}
