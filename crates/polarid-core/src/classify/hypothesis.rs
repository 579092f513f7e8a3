//! Testing each material hypothesis directly against a target's measured DoLP rows, with
//! the material as it is really found: its bulk index under its own native layer, seen
//! through a polarimeter that can only lose DoLP, from a pose known to a bounded angle.
//!
//! # The model of one hypothesis
//!
//! Row `t` of a target has the local incidence angle `β_t` (radians), the measured DoLP
//! `y_t` and a band `b(t)` of wavelength `λ_b`. Under the hypothesis "this is material
//! `M`" with bulk index `N_b = n_b + i k_b` and native layer of index `N_L,b` (per band)
//! and thickness range `[d_min, d_max]` (nm; [`NativeLayer`](super::NativeLayer),
//! [`BandPoint::layer`](super::BandPoint::layer)), the predicted DoLP is
//!
//! ```text
//! m_t(d, s, δ) = s · |P_layer(N_b, N_L,b, d/λ_b; β_t + δ)|
//! ```
//!
//! where `P_layer = (Rs − Rp)/(Rs + Rp)` of the single-layer Airy sum (Born & Wolf,
//! *Principles of Optics*, 7th ed., §1.6.4 eq. 58; Azzam & Bashara eq. 4.37; the same sum
//! as [`crate::film::thin_film`], see [`layered_dolp`]). With `d = 0` (or no layer) it is
//! the paper's eq. (9) ([`crate::dop::dop`]) exactly. The measured DoLP is a magnitude,
//! hence `|·|` (a single interface or a thin layer on a metal never changes the sign).
//!
//! Three nuisances are shared by every row of a target and bounded, never given a
//! variance:
//!
//! - the **layer thickness** `d ∈ [d_min, d_max]` nm, one thickness for every band (a
//!   layer has one thickness in nanometres however many bands see it); `d = 0` when the
//!   hypothesis has no layer;
//! - the **polarimeter scale** `s ∈ [s_min, 1]`: an analyzer of extinction ratio `ER`
//!   measures `P (ER − 1)/(ER + 1)` and a retardance `ρ` ahead of it at most
//!   `P cos ρ` (docs/ERRORS.md), so a real analyzer only LOSES DoLP:
//!   `s_min = cos ρ · (ER_min − 1)/(ER_min + 1)` from the lowest extinction ratio the
//!   analyzer may have ([`Nuisances::from_error_model`]);
//! - a **common angle offset** `δ ∈ [−Δ, Δ]`: the camera's direction error is common to
//!   every capture of a target and moves `β` by half of it (docs/ERRORS.md), standard
//!   deviation `σ_angle/2`. The bound is [`OFFSET_SIGMAS`] = 3 of those standard
//!   deviations, `Δ = 3 σ_angle / 2` (0.3° for the default `σ_angle` = 0.2°).
//!
//! The parts of the error model that are independent from row to row make the row's
//! standard deviation (the shared parts are the nuisances above, never also in `σ`):
//!
//! ```text
//! σ_t² = dolp_se_t² + f² + (P'_t σ_angle,t / 2)²
//! P'_t = ∂|P_layer(N_b, N_L,b, d̄/λ_b; β)|/∂β at β_t,   d̄ = (d_min + d_max)/2
//! ```
//!
//! (`f` the DoLP floor; the source direction's error is independent per capture and
//! moves `β` by half of it, so the row's DoLP moves by the slope of the hypothesis' OWN
//! model: the material under its native layer, at the middle of the layer's thickness
//! range, [`angle_slope`]; eq. 9's slope at the bulk index,
//! [`crate::dop::dop_beta_derivs`], when there is no layer or `d̄ = 0`). The bare
//! bulk's slope is not the model's: a metal's curve is steeper bare than under its oxide,
//! and with the bulk's slope the χ² at the true nuisances of 144,000 simulated library
//! targets passed its own `χ²_T` quantile for 0.9027 / 0.9521 / 0.9905 at 90 / 95 / 99%
//! (iron 0.9059 / 0.9551 / 0.9924); with the model's slope 0.9010 / 0.9510 / 0.9902
//! (`row_variance_model_is_calibrated`,
//! crates/polarid-pipeline/tests/it/hypothesis_study.rs). The test statistic is
//!
//! ```text
//! χ²_min = min over the box of Σ_t (y_t − m_t(d, s, δ))² / σ_t²
//! ```
//!
//! `m_t` is linear in `s`, so for each `(d, δ)` the best `s = Σ w y p / Σ w p²` (clamped to
//! `[s_min, 1]`) is closed-form; `(d, δ)` are searched on a grid and refined by golden
//! sections. To keep a test at tens of microseconds, `P_layer` is evaluated exactly only at
//! Chebyshev–Lobatto nodes in `d` (3–17, from the layer's largest phase `4π d q_L/λ`) and
//! in `δ` (3–9, from `Δ`) and interpolated between them (tensor-product Lagrange; the
//! DoLP is smooth in both); the reported `χ²` is re-evaluated exactly at the optimum.
//!
//! # Passing, degrees of freedom
//!
//! The hypothesis passes at confidence `p` when `χ²_min ≤ χ²_ν(p)` with
//! `ν = T − m` (`T` rows, `m` the nuisances whose range is not empty; at least 1). When
//! the truth's nuisances are interior the model is locally linear in them and `χ²_min`
//! follows `χ²_{T−m}`, so the true material passes with probability `p` (measured in both
//! directions over many seeds: `tests` below and docs/CLASSIFY.md); a nuisance held at
//! its bound makes the test conservative (between `χ²_{T−m}` and `χ²_T`).
//!
//! # Probability
//!
//! Each hypothesis' evidence is its likelihood averaged over the uniform prior box of the
//! nuisances,
//!
//! ```text
//! Z_M = ∫∫∫ Π_t N(y_t; m_t, σ_t²) ds dd dδ / |box|
//! ```
//!
//! with the `s` integral in closed form (a Gaussian in `s` truncated to `[s_min, 1]`,
//! through the normal CDF) and `(d, δ)` by the trapezoid rule on a grid refined around the
//! likelihood's peak. The probability of material `M` is `π_M Z_M / Σ_M' π_M' Z_M'` (priors
//! `π` uniform unless given), computed in logs relative to the best.
//!
//! # Decision
//!
//! The passing materials ranked by probability: one → that material ([`Status::Ok`]),
//! several → [`AMBIGUOUS`], none → [`UNKNOWN`] ([`Status::Rejected`]): no material of the
//! list, as it is found, explains the rows.
//!
//! # Layers beyond their range
//!
//! A surface whose layer grew beyond its material's declared range (aged, heated or
//! anodised) is outside every hypothesis, and at one band another material under its own
//! layer may still pass alone (aluminium under 8–15 nm of Al₂O₃ passes as brass under
//! 1–3 nm of ZnO; silicon under 5–10 nm of SiO₂ as GaAs). So a single passing material
//! `M` stands only if no other material `M'`, its layer's range widened to
//! `[d_min, EXTENDED_LAYER_NM]`, both passes and explains the rows better:
//!
//! ```text
//! χ²_min(M', widened) < χ²_min(M)
//! ```
//!
//! (the unusual surface is offered only when it is the likelier explanation: requiring a
//! margin of `χ²_1(0.95)` = 3.84 left aluminium under 8–15 nm of Al₂O₃ named brass alone
//! for 2.3% and silicon under 5–10 nm of SiO₂ named GaAs for 1.3%). Each such `M'` joins
//! the set, which is
//! then [`AMBIGUOUS`] (the reason names the widened materials). Only a single answer is
//! questioned: an ambiguous or empty set is left as it is, the probabilities are those of
//! the declared ranges.
//!
//! # Transparent materials and the open world
//!
//! A material whose extinction coefficient is below [`TRANSPARENT_K`](super::TRANSPARENT_K) in every band is
//! seen by DoLP through its index alone: at `k = 0.01` the Fresnel DoLP moves by less
//! than 10⁻⁴ from that of `k = 0` (n 1.33–2.7, β 20–85°), far below any row's error.
//! Every transparent material of the same index (and dispersion over the bands used)
//! predicts the same rows, and a literature catalogue holds only a few of the many
//! transparent materials of any index from 1.3 to 2.7. So when the materials are a
//! catalogue ([`HypothesisConfig::open_world`]), a transparent material that passes alone
//! is reported [`AMBIGUOUS`] with its category ([`Decision::open_world`]): the data say "a
//! transparent material of this index", of which the catalogue's one is an example
//! (LSAT, `n ≈ 2.02`, is ZnO's index twin at 550 nm). A trained model or the user's own
//! library is the list of what the scene holds (`open_world` false): its single answers
//! stand.

// NaN-safe negated comparisons on purpose; index loops over 3×3 blocks read as the
// equations.
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    clippy::needless_range_loop,
    clippy::nonminimal_bool,
    clippy::type_complexity,
    clippy::manual_range_contains
)]

use std::f64::consts::PI;

use num_complex::Complex64;

use super::decision::{Candidate, Decision, Neighbour, Status};
use super::{AMBIGUOUS, MultiPrototype, UNKNOWN, same_band};
use crate::dop::{BetaTerms, dop_beta_derivs, dop_terms};
use crate::error::{CoreError, Result, check_len};
use crate::systematic::chi2_sf;

/// The common angle offset's bound in standard deviations of its part of the error
/// model: `Δ = OFFSET_SIGMAS · σ_angle / 2`.
pub const OFFSET_SIGMAS: f64 = 3.0;

/// The thickest native layer of the widened test ([`classify_rows`]): a layer grown
/// beyond its material's declared range (aged, heated, anodised or long-humid surfaces),
/// nm.
pub const EXTENDED_LAYER_NM: f64 = 20.0;

/// One measured row of a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HypRow {
    /// Local incidence angle `β`, radians, in `[0, π/2)`.
    pub beta: f64,
    /// Measured DoLP.
    pub dolp: f64,
    /// The row's independent DoLP standard deviation without the angle part:
    /// `√(dolp_se² + f²)` (> 0).
    pub dolp_sd: f64,
    /// Standard uncertainty of the source direction, radians (≥ 0): adds
    /// `(P'_t σ/2)²` to the row's variance.
    pub angle_sd: f64,
    /// Index of the row's band in the wavelengths given with the rows.
    pub band: usize,
}

/// The bounds of the shared nuisances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nuisances {
    /// Lowest polarimeter scale `s_min` in `(0, 1]` (1: an ideal analyzer).
    pub scale_min: f64,
    /// Bound `Δ` of the common angle offset, radians (≥ 0; 0: none).
    pub offset_max: f64,
}

impl Nuisances {
    /// The bounds from the error model (docs/ERRORS.md): `s_min = cos ρ (ER − 1)/(ER + 1)`
    /// for the lowest extinction ratio `extinction_ratio` (infinite: 1) and the largest
    /// retardance `retardance` (radians), and `Δ = OFFSET_SIGMAS · angle_sd / 2` for the
    /// directions' standard uncertainty `angle_sd` (radians).
    pub fn from_error_model(extinction_ratio: f64, retardance: f64, angle_sd: f64) -> Self {
        let ext = if extinction_ratio.is_finite() {
            (extinction_ratio - 1.0) / (extinction_ratio + 1.0)
        } else {
            1.0
        };
        Self {
            scale_min: ext * retardance.cos(),
            offset_max: OFFSET_SIGMAS * angle_sd / 2.0,
        }
    }
}

/// Settings of the hypothesis tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HypothesisConfig {
    /// Confidence `p` of the test, in `(0, 1)`.
    pub confidence: f64,
    /// The nuisances' bounds.
    pub nuisances: Nuisances,
    /// The materials are a literature catalogue, not every material the scene can hold:
    /// a transparent material passing alone is [`AMBIGUOUS`] (module documentation,
    /// "Transparent materials and the open world"). `false` for a trained model or the
    /// user's own list.
    pub open_world: bool,
}

impl HypothesisConfig {
    /// Check the values ([`CoreError::OutOfRange`] naming the field).
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
    pub fn validate(&self) -> Result<()> {
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return Err(CoreError::OutOfRange {
                name: "confidence",
                value: self.confidence,
                expected: "(0, 1)",
            });
        }
        let s = self.nuisances.scale_min;
        if !(s > 0.0 && s <= 1.0) {
            return Err(CoreError::OutOfRange {
                name: "scale_min",
                value: s,
                expected: "(0, 1]",
            });
        }
        let o = self.nuisances.offset_max;
        if !(o.is_finite() && (0.0..0.5).contains(&o)) {
            return Err(CoreError::OutOfRange {
                name: "offset_max",
                value: o,
                expected: "[0, 0.5) radians",
            });
        }
        Ok(())
    }
}

/// A hypothesis' native layer: its index per band of the rows and its thickness range.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerModel {
    /// `(n, k)` of the layer per band (same order as the rows' wavelengths).
    pub index: Vec<(f64, f64)>,
    /// Thinnest layer, nm (≥ 0).
    pub min_nm: f64,
    /// Thickest layer, nm (≥ `min_nm`).
    pub max_nm: f64,
}

/// One hypothesis at the rows' bands: its bulk index per band and its native layer.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateModel {
    /// `(n, k)` of the bulk per band (same order as the rows' wavelengths).
    pub bulk: Vec<(f64, f64)>,
    /// The native layer, when the material has one.
    pub layer: Option<LayerModel>,
}

impl CandidateModel {
    /// The prototype `p` at the bands `wavelengths` (nm): each band matched by
    /// [`same_band`], or a prototype's single band without a wavelength matched to a
    /// single band. The layer is used when the prototype has a
    /// [`NativeLayer`](super::NativeLayer) and every matched band has its index
    /// ([`BandPoint::layer`](super::BandPoint::layer)). `None` when a band is missing.
    pub fn from_prototype(p: &MultiPrototype, wavelengths: &[f64]) -> Option<Self> {
        let mut bands = Vec::with_capacity(wavelengths.len());
        for &w in wavelengths {
            let b = if p.bands.len() == 1 && p.bands[0].wavelength_nm.is_none() {
                (wavelengths.len() == 1).then_some(&p.bands[0])
            } else {
                p.bands.iter().find(|b| same_band(b.wavelength_nm, Some(w)))
            }?;
            bands.push(b);
        }
        let layer = p.surface.as_ref().and_then(|s| {
            let index: Option<Vec<(f64, f64)>> = bands.iter().map(|b| b.layer).collect();
            index.map(|index| LayerModel {
                index,
                min_nm: s.min_nm,
                max_nm: s.max_nm,
            })
        });
        Some(Self {
            bulk: bands.iter().map(|b| (b.n, b.k)).collect(),
            layer,
        })
    }
}

pub use super::decision::NuisanceFit;

/// `|DoLP|` of unpolarized light reflected at `beta` (radians) by a substrate `bulk`
/// under a layer `layer` of thickness `d_waves` (in vacuum wavelengths): the Airy sum of
/// [`crate::film`], `|Rs − Rp|/(Rs + Rp)`. `d_waves = 0` equals eq. (9).
pub fn layered_dolp(bulk: (f64, f64), layer: (f64, f64), d_waves: f64, beta: f64) -> f64 {
    let st = Stack::new(bulk, layer, beta);
    st.dolp(4.0 * PI * d_waves)
}

/// The slope `∂m/∂β` (per unit scale) of hypothesis `cand`'s model of band `band` (of
/// the rows' `wavelengths`, nm) at `beta` (radians): the material under its native layer
/// at the middle of the layer's thickness range `d̄ = (d_min + d_max)/2`, the slope the
/// row variance's angle term takes (module documentation):
///
/// ```text
/// P'(β) = ∂|P_layer(N_b, N_L,b, d̄/λ_b; β)|/∂β
/// ```
///
/// by a central difference (step 1e-6 rad, within `[0, π/2]`) of the Airy sum; eq. 9's
/// analytic slope ([`crate::dop::dop_beta_derivs`]) at the bulk index when there is no
/// layer or `d̄ = 0`. Panics if `band` is not an index of `wavelengths` and of the
/// model's bands.
pub fn angle_slope(cand: &CandidateModel, wavelengths: &[f64], band: usize, beta: f64) -> f64 {
    band_slope(cand, band, wavelengths[band], beta)
}

/// [`angle_slope`] at band `band` of wavelength `wavelength` (nm).
pub(crate) fn band_slope(cand: &CandidateModel, band: usize, wavelength: f64, beta: f64) -> f64 {
    let (n, k) = cand.bulk[band];
    let mid = cand
        .layer
        .as_ref()
        .map_or(0.0, |l| 0.5 * (l.min_nm + l.max_nm));
    match &cand.layer {
        Some(l) if mid > 0.0 => {
            const H: f64 = 1e-6;
            let kappa = 4.0 * PI * mid / wavelength;
            let at = |b: f64| Stack::new((n, k), l.index[band], b).dolp(kappa);
            let (lo, hi) = ((beta - H).max(0.0), (beta + H).min(PI / 2.0));
            (at(hi) - at(lo)) / (hi - lo)
        }
        _ => dop_beta_derivs(n, k, beta).dp_dbeta,
    }
}

/// The interfaces of one layer stack at one angle (everything but the layer's phase).
struct Stack {
    rs01: Complex64,
    rp01: Complex64,
    rs12: Complex64,
    rp12: Complex64,
    q1: Complex64,
}

impl Stack {
    fn new(bulk: (f64, f64), layer: (f64, f64), beta: f64) -> Self {
        let (s, c) = beta.sin_cos();
        let s2 = s * s;
        let n1 = Complex64::new(layer.0, layer.1);
        let n2 = Complex64::new(bulk.0, bulk.1);
        let (e1, e2) = (n1 * n1, n2 * n2);
        // Principal square roots: Im(N² − sin²β) ≥ 0 for k ≥ 0, so Im q ≥ 0.
        let q0 = Complex64::new(c, 0.0);
        let q1 = (e1 - s2).sqrt();
        let q2 = (e2 - s2).sqrt();
        Self {
            rs01: (q0 - q1) / (q0 + q1),
            rp01: (e1 * q0 - q1) / (e1 * q0 + q1),
            rs12: (q1 - q2) / (q1 + q2),
            rp12: (e2 * q1 - e1 * q2) / (e2 * q1 + e1 * q2),
            q1,
        }
    }

    /// `|Rs − Rp|/(Rs + Rp)` for the phase factor `κ = 4π d/λ` (`2δ = κ q1`).
    fn dolp(&self, kappa: f64) -> f64 {
        let ph = (Complex64::new(0.0, kappa) * self.q1).exp();
        let rs = (self.rs01 + self.rs12 * ph) / (1.0 + self.rs01 * self.rs12 * ph);
        let rp = (self.rp01 + self.rp12 * ph) / (1.0 + self.rp01 * self.rp12 * ph);
        let (a, b) = (rs.norm_sqr(), rp.norm_sqr());
        if a + b > 0.0 {
            ((a - b) / (a + b)).abs()
        } else {
            0.0
        }
    }
}

/// The χ² quantile for any number of degrees of freedom (bisection on
/// [`chi2_sf`]); NaN unless `p ∈ (0, 1)` and `dof > 0` finite.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn chi2_quantile_any(p: f64, dof: f64) -> f64 {
    if !(p > 0.0 && p < 1.0) || !(dof > 0.0 && dof.is_finite()) {
        return f64::NAN;
    }
    let target = 1.0 - p;
    let nu = dof;
    let (mut lo, mut hi) = (0.0f64, nu + 10.0);
    while chi2_sf(hi, nu) > target {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_sf(mid, nu) > target {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// `ln erfc(x)` for `x ≥ 0` (Numerical Recipes' Chebyshev fit, relative error of
/// `erfc` < 1.2e-7; written in logs so the far tail does not underflow).
fn ln_erfc_pos(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.5 * x);
    let poly = -1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    t.ln() - x * x + poly
}

/// `ln Q(z)`, `Q` the standard normal upper tail, for `z ≥ 0`.
fn ln_q(z: f64) -> f64 {
    ln_erfc_pos(z / std::f64::consts::SQRT_2) - std::f64::consts::LN_2
}

/// `ln(Φ(z2) − Φ(z1))` for `z1 ≤ z2`, without underflow in the tails.
fn ln_normal_mass(z1: f64, z2: f64) -> f64 {
    if z1 >= 0.0 {
        let (a, b) = (ln_q(z1), ln_q(z2));
        a + (-(b - a).exp()).ln_1p()
    } else if z2 <= 0.0 {
        let (a, b) = (ln_q(-z2), ln_q(-z1));
        a + (-(b - a).exp()).ln_1p()
    } else {
        (1.0 - ln_q(-z1).exp() - ln_q(z2).exp()).max(1e-300).ln()
    }
}

/// Chebyshev–Lobatto nodes on `[lo, hi]` (`m ≥ 2`) and their barycentric weights.
fn nodes(lo: f64, hi: f64, m: usize) -> (Vec<f64>, Vec<f64>) {
    if m == 1 {
        return (vec![lo], vec![1.0]);
    }
    let x = (0..m)
        .map(|i| {
            let c = (PI * i as f64 / (m - 1) as f64).cos();
            0.5 * (lo + hi) - 0.5 * (hi - lo) * c
        })
        .collect();
    let w = (0..m)
        .map(|i| {
            let s = if i % 2 == 0 { 1.0 } else { -1.0 };
            if i == 0 || i == m - 1 { 0.5 * s } else { s }
        })
        .collect();
    (x, w)
}

/// The Lagrange basis values at `x` (barycentric form; exact at the nodes).
fn basis(x: f64, xs: &[f64], ws: &[f64], out: &mut [f64]) {
    if xs.len() == 1 {
        out[0] = 1.0;
        return;
    }
    if let Some(i) = xs.iter().position(|&xi| xi == x) {
        out.iter_mut().for_each(|o| *o = 0.0);
        out[i] = 1.0;
        return;
    }
    let mut sum = 0.0;
    for i in 0..xs.len() {
        let v = ws[i] / (x - xs[i]);
        out[i] = v;
        sum += v;
    }
    out.iter_mut().for_each(|o| *o /= sum);
}

/// The profile of one hypothesis: exact node values, row weights, and the closed-form
/// scale.
struct Profile<'a> {
    rows: &'a [HypRow],
    /// `1/σ_t²`.
    w: Vec<f64>,
    /// `Σ w y²`.
    c: f64,
    d_nodes: (Vec<f64>, Vec<f64>),
    o_nodes: (Vec<f64>, Vec<f64>),
    /// `vals[t][i * no + j]`: the DoLP of row t at thickness node i and offset node j.
    vals: Vec<Vec<f64>>,
    scale_min: f64,
    ld: Vec<f64>,
    lo: Vec<f64>,
}

impl Profile<'_> {
    /// `(a, b) = (Σ w p², Σ w y p)` at `(d, δ)` on the interpolant.
    fn ab(&mut self, d: f64, o: f64) -> (f64, f64) {
        basis(d, &self.d_nodes.0, &self.d_nodes.1, &mut self.ld);
        basis(o, &self.o_nodes.0, &self.o_nodes.1, &mut self.lo);
        let no = self.lo.len();
        let (mut a, mut b) = (0.0, 0.0);
        for (t, v) in self.vals.iter().enumerate() {
            let mut p = 0.0;
            for (i, li) in self.ld.iter().enumerate() {
                if *li == 0.0 {
                    continue;
                }
                let row = &v[i * no..(i + 1) * no];
                let mut q = 0.0;
                for (lj, vj) in self.lo.iter().zip(row) {
                    q += lj * vj;
                }
                p += li * q;
            }
            a += self.w[t] * p * p;
            b += self.w[t] * self.rows[t].dolp * p;
        }
        (a, b)
    }

    /// `(a, b)` at every `(ds[i], os[j])` (index `i * os.len() + j`): the interpolant
    /// contracted over `d` once per `ds[i]`, then over `δ`.
    fn grid_ab(&mut self, ds: &[f64], os: &[f64]) -> Vec<(f64, f64)> {
        let no = self.lo.len();
        let lo_all: Vec<Vec<f64>> = os
            .iter()
            .map(|&o| {
                let mut l = vec![0.0; no];
                basis(o, &self.o_nodes.0, &self.o_nodes.1, &mut l);
                l
            })
            .collect();
        let mut out = vec![(0.0, 0.0); ds.len() * os.len()];
        let mut v = vec![0.0; no];
        for (i, &d) in ds.iter().enumerate() {
            basis(d, &self.d_nodes.0, &self.d_nodes.1, &mut self.ld);
            for (t, vals) in self.vals.iter().enumerate() {
                v.iter_mut().for_each(|x| *x = 0.0);
                for (k, lk) in self.ld.iter().enumerate() {
                    if *lk != 0.0 {
                        for (x, y) in v.iter_mut().zip(&vals[k * no..(k + 1) * no]) {
                            *x += lk * y;
                        }
                    }
                }
                let (wt, y) = (self.w[t], self.rows[t].dolp);
                for (j, l) in lo_all.iter().enumerate() {
                    let p: f64 = l.iter().zip(&v).map(|(a, b)| a * b).sum();
                    let e = &mut out[i * os.len() + j];
                    e.0 += wt * p * p;
                    e.1 += wt * y * p;
                }
            }
        }
        out
    }

    /// `(χ², s)` with the best scale in `[s_min, 1]`.
    fn chi2_of(&self, a: f64, b: f64) -> (f64, f64) {
        let s = if a > 0.0 {
            (b / a).clamp(self.scale_min, 1.0)
        } else {
            1.0
        };
        ((self.c - 2.0 * s * b + s * s * a).max(0.0), s)
    }

    /// `ln ∫ exp(−χ²(s)/2) ds/(1 − s_min)` over `[s_min, 1]` (`exp(−χ²(1)/2)` when
    /// `s_min = 1`).
    fn ln_integrand(&self, a: f64, b: f64) -> f64 {
        let range = 1.0 - self.scale_min;
        if range <= 0.0 || a <= 0.0 {
            return -0.5 * self.chi2_of(a, b).0;
        }
        let su = b / a;
        let base = (self.c - b * b / a).max(0.0);
        let ra = a.sqrt();
        -0.5 * base
            + 0.5 * (2.0 * PI / a).ln()
            + ln_normal_mass(ra * (self.scale_min - su), ra * (1.0 - su))
            - range.ln()
    }
}

/// Interpolation node counts `(thickness, offset)` from the nonlinearity of the model
/// of `cand` over the box `[d_lo, d_hi] × [−off, off]`.
fn node_counts(
    cand: &CandidateModel,
    wavelengths: &[f64],
    (d_lo, d_hi): (f64, f64),
    off: f64,
) -> (usize, usize) {
    let nd = if d_hi > d_lo {
        let phase = cand.layer.as_ref().map_or(0.0, |l| {
            l.index
                .iter()
                .zip(wavelengths)
                .map(|(&(n, k), &w)| 4.0 * PI * d_hi * n.hypot(k) / w)
                .fold(0.0, f64::max)
        });
        match phase {
            p if p <= 0.3 => 3,
            p if p <= 1.0 => 5,
            p if p <= 3.0 => 9,
            _ => 17,
        }
    } else {
        1
    };
    let no = match off {
        o if o <= 0.0 => 1,
        o if o <= 0.01 => 3,
        o if o <= 0.03 => 5,
        _ => 9,
    };
    (nd, no)
}

impl<'a> Profile<'a> {
    /// The profile of `cand` on `rows` over the box `[d_lo, d_hi] × [−off, off]` with
    /// scales from `scale_min`, and `Σ ln σ_t` of its row weights.
    fn new(
        rows: &'a [HypRow],
        wavelengths: &[f64],
        cand: &CandidateModel,
        (d_lo, d_hi): (f64, f64),
        off: f64,
        scale_min: f64,
    ) -> (Self, f64) {
        // Node counts from the nonlinearity over the box.
        let (nd, no) = node_counts(cand, wavelengths, (d_lo, d_hi), off);
        let d_nodes = nodes(d_lo, d_hi, nd);
        let o_nodes = nodes(-off, off, no);
        let w: Vec<f64> = rows
            .iter()
            .map(|r| {
                let a = 0.5 * band_slope(cand, r.band, wavelengths[r.band], r.beta) * r.angle_sd;
                1.0 / (r.dolp_sd * r.dolp_sd + a * a)
            })
            .collect();
        let ln_sigma: f64 = w.iter().map(|w| -0.5 * w.ln()).sum();
        let c: f64 = rows.iter().zip(&w).map(|(r, w)| w * r.dolp * r.dolp).sum();
        let vals: Vec<Vec<f64>> = rows
            .iter()
            .map(|r| {
                let mut v = Vec::with_capacity(nd * no);
                for &d in &d_nodes.0 {
                    for &o in &o_nodes.0 {
                        v.push(exact(cand, wavelengths, r, d, o));
                    }
                }
                v
            })
            .collect();
        let prof = Profile {
            rows,
            w,
            c,
            d_nodes,
            o_nodes,
            vals,
            scale_min,
            ld: vec![0.0; nd],
            lo: vec![0.0; no],
        };
        (prof, ln_sigma)
    }
}

impl Profile<'_> {
    /// `χ²` on the interpolant at `(d, δ)` with the best scale.
    fn chi2_at(&mut self, d: f64, o: f64) -> f64 {
        let (a, b) = self.ab(d, o);
        self.chi2_of(a, b).0
    }

    /// The `(d, δ)` of least `χ²` in the box `[d_lo, d_hi] × [−off, off]`: a coarse grid,
    /// then [`Self::refine`].
    fn minimum(&mut self, (d_lo, d_hi): (f64, f64), off: f64) -> (f64, f64) {
        let (nd, no) = (self.ld.len(), self.lo.len());
        // Coarse grid: minimum of χ² and the log integrand.
        let gd = if nd > 1 { 17 } else { 1 };
        let go = if no > 1 { 17 } else { 1 };
        let at = |lo: f64, hi: f64, n: usize, i: usize| {
            if n == 1 {
                lo
            } else {
                lo + (hi - lo) * i as f64 / (n - 1) as f64
            }
        };
        let gds: Vec<f64> = (0..gd).map(|i| at(d_lo, d_hi, gd, i)).collect();
        let gos: Vec<f64> = (0..go).map(|j| at(-off, off, go, j)).collect();
        let mut best = (f64::INFINITY, 0usize, 0usize);
        for (k, &(a, b)) in self.grid_ab(&gds, &gos).iter().enumerate() {
            let (chi2, _) = self.chi2_of(a, b);
            if chi2 < best.0 {
                best = (chi2, k / go, k % go);
            }
        }
        // Refine by alternating golden sections within one grid step of the best point.
        let start = (at(d_lo, d_hi, gd, best.1), at(-off, off, go, best.2));
        let step_d = if gd > 1 {
            (d_hi - d_lo) / (gd - 1) as f64
        } else {
            0.0
        };
        let step_o = if go > 1 {
            2.0 * off / (go - 1) as f64
        } else {
            0.0
        };
        self.refine(start, (step_d, step_o), (d_lo, d_hi), off)
    }

    /// Alternating golden sections from `(d, o)` within one grid step `(step_d, step_o)`,
    /// until converged (at most 12 rounds): a thin layer and an offset can move the DoLP
    /// curve alike, and coordinate steps alone crawl along such a diagonal valley; each
    /// round ends with a line search along its own displacement (Hooke–Jeeves' pattern
    /// move). (Measured on the library study: the same mean χ²_min as three plain rounds,
    /// so the search is not what keeps the true material's coverage below its level.)
    fn refine(
        &mut self,
        (mut d, mut o): (f64, f64),
        (step_d, step_o): (f64, f64),
        (d_lo, d_hi): (f64, f64),
        off: f64,
    ) -> (f64, f64) {
        let mut last = self.chi2_at(d, o);
        for _ in 0..12 {
            let (d0, o0) = (d, o);
            if step_d > 0.0 {
                let (lo, hi) = ((d - step_d).max(d_lo), (d + step_d).min(d_hi));
                d = golden(lo, hi, GOLDEN, |x| self.chi2_at(x, o)).0;
            }
            if step_o > 0.0 {
                let (lo, hi) = ((o - step_o).max(-off), (o + step_o).min(off));
                o = golden(lo, hi, GOLDEN, |x| self.chi2_at(d, x)).0;
            }
            let (dd, dm) = (d - d0, o - o0);
            if step_d > 0.0 && step_o > 0.0 && (dd != 0.0 || dm != 0.0) {
                // Largest t with (d0, o0) + t (dd, dm) inside the box, at most 4.
                let reach = |x0: f64, dx: f64, lo: f64, hi: f64| {
                    if dx > 0.0 {
                        (hi - x0) / dx
                    } else if dx < 0.0 {
                        (lo - x0) / dx
                    } else {
                        f64::INFINITY
                    }
                };
                let tmax = reach(d0, dd, d_lo, d_hi)
                    .min(reach(o0, dm, -off, off))
                    .min(4.0);
                if tmax > 1.0 {
                    let (t, c) = golden(0.0, tmax, GOLDEN, |t| {
                        self.chi2_at(d0 + t * dd, o0 + t * dm)
                    });
                    let here = self.chi2_at(d, o);
                    if c < here {
                        d = (d0 + t * dd).clamp(d_lo, d_hi);
                        o = (o0 + t * dm).clamp(-off, off);
                    }
                }
            }
            let now = self.chi2_at(d, o);
            if !(last - now > 1e-6) {
                break;
            }
            last = now;
        }
        (d, o)
    }
}

/// Rounds and relative tolerance of the golden sections of [`Profile::refine`].
const GOLDEN: (usize, f64) = (30, 1e-9);

/// Evaluate the exact model of row `t` at `(d, δ)` (nm, radians).
fn exact(cand: &CandidateModel, wavelengths: &[f64], r: &HypRow, d: f64, o: f64) -> f64 {
    let beta = (r.beta + o).clamp(0.0, PI / 2.0 - 1e-9);
    let (n, k) = cand.bulk[r.band];
    match &cand.layer {
        Some(l) if d > 0.0 => {
            Stack::new((n, k), l.index[r.band], beta).dolp(4.0 * PI * d / wavelengths[r.band])
        }
        _ => dop_terms(n, k, &BetaTerms::new(beta)),
    }
}

/// Golden-section minimum `(x, f(x))` of `f` on `[lo, hi]`: at most `rounds` rounds,
/// until the bracket is narrower than `tol · (1 + |hi|)`.
pub(super) fn golden(
    mut lo: f64,
    mut hi: f64,
    (rounds, tol): (usize, f64),
    mut f: impl FnMut(f64) -> f64,
) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..rounds {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
        if hi - lo < tol * (1.0 + hi.abs()) {
            break;
        }
    }
    if f1 <= f2 { (x1, f1) } else { (x2, f2) }
}

/// Check the rows and their bands' wavelengths.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
fn check_rows(rows: &[HypRow], wavelengths: &[f64]) -> Result<()> {
    if rows.is_empty() {
        return Err(CoreError::TooFew {
            what: "rows",
            needed: 1,
            got: 0,
        });
    }
    for &w in wavelengths {
        if !(w.is_finite() && w > 0.0) {
            return Err(CoreError::OutOfRange {
                name: "wavelength_nm",
                value: w,
                expected: "finite and > 0",
            });
        }
    }
    for r in rows {
        if !(r.beta.is_finite() && (0.0..PI / 2.0).contains(&r.beta)) {
            return Err(CoreError::OutOfRange {
                name: "beta",
                value: r.beta,
                expected: "[0, pi/2) radians",
            });
        }
        if !r.dolp.is_finite() {
            return Err(CoreError::NonFinite {
                name: "dolp",
                value: r.dolp,
            });
        }
        if !(r.dolp_sd.is_finite() && r.dolp_sd > 0.0) {
            return Err(CoreError::OutOfRange {
                name: "dolp_sd",
                value: r.dolp_sd,
                expected: "finite and > 0 (dolp_se and the DoLP floor cannot both be 0)",
            });
        }
        if !(r.angle_sd.is_finite() && r.angle_sd >= 0.0) {
            return Err(CoreError::OutOfRange {
                name: "angle_sd",
                value: r.angle_sd,
                expected: "finite and >= 0",
            });
        }
        if r.band >= wavelengths.len() {
            return Err(CoreError::OutOfRange {
                name: "band",
                value: r.band as f64,
                expected: "an index into the rows' wavelengths",
            });
        }
    }
    Ok(())
}

#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
fn check_candidate(cand: &CandidateModel, wavelengths: &[f64]) -> Result<()> {
    let bad = |name, value| {
        Err(CoreError::OutOfRange {
            name,
            value,
            expected: "a finite index with n > 0, k >= 0 per band",
        })
    };
    check_len("bulk", cand.bulk.len(), wavelengths.len())?;
    for &(n, k) in &cand.bulk {
        if !(n.is_finite() && n > 0.0) {
            return bad("n", n);
        }
        if !(k.is_finite() && k >= 0.0) {
            return bad("k", k);
        }
    }
    if let Some(l) = &cand.layer {
        check_len("layer index", l.index.len(), wavelengths.len())?;
        for &(n, k) in &l.index {
            if !(n.is_finite() && n > 0.0) {
                return bad("layer n", n);
            }
            if !(k.is_finite() && k >= 0.0) {
                return bad("layer k", k);
            }
        }
        if !(l.min_nm.is_finite()
            && l.min_nm >= 0.0
            && l.max_nm.is_finite()
            && l.max_nm >= l.min_nm)
        {
            return Err(CoreError::OutOfRange {
                name: "layer thickness",
                value: l.max_nm,
                expected: "0 <= min_nm <= max_nm, finite",
            });
        }
    }
    Ok(())
}

/// The null distribution of `χ²_min` for the true material, from the Fisher information
/// of the nuisances with a range: `F = JᵀWJ` (`J` the model's derivatives in `(d, s, δ)`
/// at the minimum, by central differences; `W = diag(1/σ_t²)`).
///
/// Locally linear in the nuisances, `χ²_min = R + D`: `R ~ χ²_{T−m}` the residual
/// orthogonal to the `m` nuisance directions and, independent of it, `D` what the box
/// leaves of the nuisance part: with the truth `θ` uniform in the box (the prior) and the
/// unconstrained estimate `θ̂ = θ + N(0, F⁻¹)`, `D = min_{box} (θ' − θ̂)ᵀ F (θ' − θ̂)` (0 when
/// `θ̂` is inside). A nuisance the rows pin well inside its box removes one degree of
/// freedom; one its box pins better than the rows removes almost none. Returns `T − m`
/// and [`NULL_DRAWS`] draws of `D` (a fixed low-discrepancy design: the test is
/// deterministic).
fn nuisance_null(
    rows: &[HypRow],
    wavelengths: &[f64],
    cand: &CandidateModel,
    w: &[f64],
    (d, s, o): (f64, f64, f64),
    lows: [f64; 3],
    widths: [f64; 3],
) -> (usize, Vec<f64>) {
    let active: Vec<usize> = (0..3).filter(|&i| widths[i] > 0.0).collect();
    let m = active.len();
    let resid = rows.len().saturating_sub(m);
    if m == 0 {
        return (resid, vec![0.0]);
    }
    let hd = 1e-3 * widths[0].max(1e-3);
    let ho = 1e-6;
    let mut f = [[0.0f64; 3]; 3];
    for (r, wt) in rows.iter().zip(w) {
        let p = exact(cand, wavelengths, r, d, o);
        let mut j = [0.0f64; 3];
        if widths[0] > 0.0 {
            let (lo, hi) = ((d - hd).max(0.0), d + hd);
            j[0] = s * (exact(cand, wavelengths, r, hi, o) - exact(cand, wavelengths, r, lo, o))
                / (hi - lo);
        }
        j[1] = p;
        if widths[2] > 0.0 {
            j[2] = s
                * (exact(cand, wavelengths, r, d, o + ho) - exact(cand, wavelengths, r, d, o - ho))
                / (2.0 * ho);
        }
        for a in 0..3 {
            for b in 0..3 {
                f[a][b] += wt * j[a] * j[b];
            }
        }
    }
    // Active block, scaled to box units (θ_i = low_i + W_i u_i, u ∈ [0, 1]).
    let mut fa = [[0.0f64; 3]; 3];
    for (x, &i) in active.iter().enumerate() {
        for (y, &k) in active.iter().enumerate() {
            fa[x][y] = f[i][k] * widths[i] * widths[k];
        }
    }
    let _ = lows;
    // A tiny ridge keeps a degenerate direction finite. It is added to F itself, so that
    // the draws of θ̂ (from F + ridge) and their distance D (in F + ridge) use one matrix:
    // a direction the rows do not inform, less than the ridge, then has its θ̂ far outside
    // the box and adds its full z² to D (the box pins it, the rows remove nothing). With
    // the ridge in the draws only, D lost that z² and an unidentifiable nuisance counted
    // as a degree of freedom removed: a glass under 0–2 nm of contamination of nearly its
    // own index passed its test for 0.93 at 95% (0.948 with the thickness held fixed).
    let tr: f64 = (0..m).map(|x| fa[x][x]).sum();
    for x in 0..m {
        fa[x][x] += 1e-12 * tr.max(1e-300);
    }
    // Cholesky F = L Lᵀ.
    let mut l = [[0.0f64; 3]; 3];
    for x in 0..m {
        for y in 0..=x {
            let v = fa[x][y] - (0..y).map(|z| l[x][z] * l[y][z]).sum::<f64>();
            if x == y {
                l[x][x] = v.max(1e-300).sqrt();
            } else {
                l[x][y] = v / l[y][y];
            }
        }
    }
    let design = null_design();
    let mut draws = Vec::with_capacity(NULL_DRAWS);
    for (th, z) in design.theta.iter().zip(&design.z[m - 1]) {
        // e = L⁻ᵀ z (back substitution): θ̂ = θ + e has covariance F⁻¹.
        let mut e = [0.0f64; 3];
        for x in (0..m).rev() {
            let v = z[x] - (x + 1..m).map(|y| l[y][x] * e[y]).sum::<f64>();
            e[x] = v / l[x][x];
        }
        let hat: Vec<f64> = (0..m).map(|x| th[x] + e[x]).collect();
        // Box-constrained minimum of (u − θ̂)ᵀ F (u − θ̂): projected coordinate descent.
        let mut u: Vec<f64> = hat.iter().map(|h| h.clamp(0.0, 1.0)).collect();
        for _ in 0..30 {
            let mut moved = 0.0f64;
            for x in 0..m {
                if fa[x][x] <= 0.0 {
                    continue;
                }
                let off: f64 = (0..m)
                    .filter(|&y| y != x)
                    .map(|y| fa[x][y] * (u[y] - hat[y]))
                    .sum();
                let nu = (hat[x] - off / fa[x][x]).clamp(0.0, 1.0);
                moved = moved.max((nu - u[x]).abs());
                u[x] = nu;
            }
            if moved < 1e-10 {
                break;
            }
        }
        let mut dq = 0.0;
        for x in 0..m {
            for y in 0..m {
                dq += (u[x] - hat[x]) * fa[x][y] * (u[y] - hat[y]);
            }
        }
        draws.push(dq.max(0.0));
    }
    (resid, draws)
}

/// Draws of the box's part of the null distribution ([`nuisance_null`]): a fixed
/// low-discrepancy design ([`null_design`]), not pseudo-random draws, so that the null's
/// tail does not depend on the luck of one fixed sample (64 pseudo-random draws moved the
/// true material's coverage at 95% between 93.9% and 95.4% with the seed).
const NULL_DRAWS: usize = 256;

/// The Halton bases of `(θ_1, θ_2, θ_3)` and of the direction of `z`.
const HALTON_BASES: [usize; 6] = [2, 3, 5, 7, 11, 13];

/// The design of [`nuisance_null`]'s draws: per draw `i = 1..N` ([`NULL_DRAWS`]) the truth
/// `θ` in the unit box and, per number `m = 1, 2, 3` of nuisances with a range, the
/// standard normal `z ∈ ℝ^m`.
///
/// `θ_x` is point `i` of the Halton sequence in base 2, 3, 5. `z` is written as a radius
/// and a direction, `z = r g/|g|` with `r² = Q_{χ²_m}((i − ½)/N)` (the `χ²_m` quantile
/// on the midpoints of `N` equal-probability strata) and `g_x = Φ⁻¹(halton(i, b_x))`,
/// bases 7, 11, 13 (`g/|g|` is uniform on the sphere): with the radius as the first
/// coordinate this is a Hammersley point set (H. Niederreiter, *Random Number Generation
/// and Quasi-Monte Carlo Methods*, SIAM 1992, §3.1). Drawing each `z_x` as `Φ⁻¹` of its
/// own Halton coordinate instead covered the joint tail of `zᵀz` poorly (the design's
/// mean `z_x²` was 0.964, 1.005 and 0.971 in bases 7, 11, 13): where the box pins every
/// nuisance (`D = zᵀz`), the mixture's tail at the true 95% point of `χ²_{T}` was 0.044–0.048
/// instead of 0.05 (T − m = 1–7), and the true material failed its test 5.3% of the time
/// at 95% (0.9474, `truths_own_test_passes_at_the_confidence`); with the radius on the
/// strata's midpoints the same tail is 0.0498–0.0502. Computed once.
struct NullDesign {
    theta: Vec<[f64; 3]>,
    z: [Vec<[f64; 3]>; 3],
}

fn null_design() -> &'static NullDesign {
    static DESIGN: std::sync::OnceLock<NullDesign> = std::sync::OnceLock::new();
    DESIGN.get_or_init(|| {
        let n = NULL_DRAWS;
        let theta = (1..=n)
            .map(|i| [0, 1, 2].map(|x| halton(i, HALTON_BASES[x])))
            .collect();
        let z = [1usize, 2, 3].map(|m| {
            (1..=n)
                .map(|i| {
                    let r = chi2_quantile_any((i as f64 - 0.5) / n as f64, m as f64).sqrt();
                    let mut g = [0.0f64; 3];
                    for (x, gx) in g.iter_mut().enumerate().take(m) {
                        *gx = normal_quantile(halton(i, HALTON_BASES[3 + x]));
                    }
                    let norm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
                    if norm > 0.0 {
                        g.map(|v| r * v / norm)
                    } else {
                        [r, 0.0, 0.0]
                    }
                })
                .collect()
        });
        NullDesign { theta, z }
    })
}

/// Point `i` (≥ 1) of the van der Corput sequence in base `b`, in `(0, 1)`.
fn halton(mut i: usize, b: usize) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while i > 0 {
        f /= b as f64;
        r += f * (i % b) as f64;
        i /= b;
    }
    r
}

/// The standard normal quantile `Φ⁻¹(p)` for `p ∈ (0, 1)` (Acklam's rational
/// approximation, relative error < 1.2e-9, P. J. Acklam 2003, "An algorithm for computing
/// the inverse normal cumulative distribution function").
#[allow(clippy::excessive_precision)] // the published coefficients, as published
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let p_low = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < p_low {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - p_low {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// An upper bound of the `χ²_min` that can pass at `confidence` with `rows` rows,
/// whatever the nuisances' Fisher information: `P(R + D ≥ x) ≤ P(χ²_rows ≥ x − D_max)`
/// ([`mixture_sf`]: `R ~ χ²_{rows−m}` is stochastically below `χ²_rows`, and each draw
/// `D` of [`nuisance_null`] is at most its `zᵀz`, the box's value at the drawn `θ`), so
/// the bound is `χ²_rows(p) + max zᵀz` over the design. Keep it an upper bound when the
/// null changes: the per-pixel decisions ([`pixel`]) reject a material whose lower bound
/// of `χ²_min` exceeds it without testing it.
fn chi2_pass_bound(rows: usize, confidence: f64) -> f64 {
    let d_max = null_design()
        .z
        .iter()
        .flatten()
        .map(|z| z.iter().map(|v| v * v).sum::<f64>())
        .fold(0.0, f64::max);
    chi2_quantile_any(confidence, rows as f64) + d_max
}

/// `P(R + D ≥ x)` with `R ~ χ²_resid` and `D` the draws (module documentation).
fn mixture_sf(x: f64, resid: usize, draws: &[f64]) -> f64 {
    let n = draws.len() as f64;
    let zeros = draws.iter().filter(|&&d| d == 0.0).count() as f64;
    let at_zero = if zeros > 0.0 {
        zeros
            * if resid == 0 {
                f64::from(u8::from(x <= 0.0))
            } else {
                chi2_sf(x, resid as f64)
            }
    } else {
        0.0
    };
    (at_zero
        + draws
            .iter()
            .filter(|&&d| d != 0.0)
            .map(|&dj| {
                let y = x - dj;
                if y <= 0.0 {
                    1.0
                } else if resid == 0 {
                    0.0
                } else {
                    chi2_sf(y, resid as f64)
                }
            })
            .sum::<f64>())
        / n
}

/// Test one hypothesis `cand` against a target's `rows` (bands of wavelengths
/// `wavelengths`, nm): the minimum `χ²` over the nuisance box, its p-value and verdict,
/// the nuisances at the minimum and the log evidence (module documentation).
///
/// Errors: [`CoreError`] naming a bad row, wavelength, index or setting.
pub fn test_hypothesis(
    rows: &[HypRow],
    wavelengths: &[f64],
    cand: &CandidateModel,
    cfg: &HypothesisConfig,
) -> Result<NuisanceFit> {
    cfg.validate()?;
    check_rows(rows, wavelengths)?;
    check_candidate(cand, wavelengths)?;
    Ok(test_checked(rows, wavelengths, cand, cfg))
}

/// The statistic of [`test_hypothesis`] alone: `(χ²_min, ν)`, the minimum `χ²` over the
/// nuisance box and the effective degrees of freedom (the null's mean), without the
/// p-value and the evidence (for planning: `super::separability`).
///
/// Errors: as [`test_hypothesis`].
pub fn test_statistic(
    rows: &[HypRow],
    wavelengths: &[f64],
    cand: &CandidateModel,
    cfg: &HypothesisConfig,
) -> Result<(f64, f64)> {
    cfg.validate()?;
    check_rows(rows, wavelengths)?;
    check_candidate(cand, wavelengths)?;
    let f = fit_checked(rows, wavelengths, cand, cfg, Detail::Statistic);
    Ok((f.chi2, f.dof))
}

/// The full test: statistic, verdict and evidence.
fn test_checked(
    rows: &[HypRow],
    wavelengths: &[f64],
    cand: &CandidateModel,
    cfg: &HypothesisConfig,
) -> NuisanceFit {
    fit_checked(rows, wavelengths, cand, cfg, Detail::Evidence)
}

/// How much of a test [`fit_checked`] computes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Detail {
    /// `χ²_min` and `ν` only: the p-value, verdict and evidence are NaN, false, NaN
    /// (planning, [`test_statistic`]).
    Statistic,
    /// Also the p-value and verdict; the evidence is NaN (a pixel's decision, [`pixel`]).
    Verdict,
    /// Everything, the log evidence included.
    Evidence,
}

/// [`test_checked`] computing only what `detail` asks for.
fn fit_checked(
    rows: &[HypRow],
    wavelengths: &[f64],
    cand: &CandidateModel,
    cfg: &HypothesisConfig,
    detail: Detail,
) -> NuisanceFit {
    let nu = cfg.nuisances;
    let (d_lo, d_hi) = cand
        .layer
        .as_ref()
        .map_or((0.0, 0.0), |l| (l.min_nm, l.max_nm));
    let off = nu.offset_max;
    let (mut prof, ln_sigma) =
        Profile::new(rows, wavelengths, cand, (d_lo, d_hi), off, nu.scale_min);
    let (d, o) = prof.minimum((d_lo, d_hi), off);
    // Exact χ² at the optimum.
    let (mut a, mut b) = (0.0, 0.0);
    for (r, wt) in rows.iter().zip(&prof.w) {
        let p = exact(cand, wavelengths, r, d, o);
        a += wt * p * p;
        b += wt * r.dolp * p;
    }
    let (chi2, scale) = prof.chi2_of(a, b);
    let (resid, draws) = nuisance_null(
        rows,
        wavelengths,
        cand,
        &prof.w,
        (d, scale, o),
        [d_lo, nu.scale_min, -off],
        [d_hi - d_lo, 1.0 - nu.scale_min, 2.0 * off],
    );
    // The statistic's null mean: its effective degrees of freedom.
    let dof = resid as f64 + draws.iter().sum::<f64>() / draws.len() as f64;
    if detail == Detail::Statistic {
        return NuisanceFit {
            chi2,
            dof,
            p_value: f64::NAN,
            consistent: false,
            thickness_nm: d,
            scale,
            offset: o,
            log_evidence: f64::NAN,
        };
    }
    let p_value = mixture_sf(chi2, resid, &draws);
    let consistent = p_value >= 1.0 - cfg.confidence;
    let log_evidence = if detail == Detail::Evidence {
        evidence(&mut prof, (d_lo, d_hi), off) - ln_sigma
    } else {
        f64::NAN
    };
    NuisanceFit {
        chi2,
        dof,
        p_value,
        consistent,
        thickness_nm: d,
        scale,
        offset: o,
        log_evidence,
    }
}

/// `ln` of the integrand averaged over the `(d, δ)` box: trapezoid rule on a 17 × 17 grid
/// over the box, then on 25 × 25 grids over the window where the integrand is within
/// e^−25 of its peak, narrowed up to three times (so narrow peaks are resolved).
fn evidence(prof: &mut Profile, (d_lo, d_hi): (f64, f64), off: f64) -> f64 {
    let full = ((d_lo, d_hi), (-off, off));
    let mut win = full;
    let mut result = f64::NEG_INFINITY;
    for level in 0..4 {
        let n = if level == 0 { 17 } else { 25 };
        let nd = if win.0.1 > win.0.0 { n } else { 1 };
        let no = if win.1.1 > win.1.0 { n } else { 1 };
        let xs = |(lo, hi): (f64, f64), m: usize| -> Vec<f64> {
            (0..m)
                .map(|i| {
                    if m == 1 {
                        lo
                    } else {
                        lo + (hi - lo) * i as f64 / (m - 1) as f64
                    }
                })
                .collect()
        };
        let (dx, ox) = (xs(win.0, nd), xs(win.1, no));
        let f: Vec<f64> = prof
            .grid_ab(&dx, &ox)
            .iter()
            .map(|&(a, b)| prof.ln_integrand(a, b))
            .collect();
        let peak = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let tw = |i: usize, m: usize| {
            if m > 1 && (i == 0 || i == m - 1) {
                0.5
            } else {
                1.0
            }
        };
        let (mut sum, mut wsum) = (0.0, 0.0);
        for i in 0..nd {
            for j in 0..no {
                let wt = tw(i, nd) * tw(j, no);
                sum += wt * (f[i * no + j] - peak).exp();
                wsum += wt;
            }
        }
        let frac = |(lo, hi): (f64, f64), (flo, fhi): (f64, f64)| {
            if fhi > flo {
                (hi - lo) / (fhi - flo)
            } else {
                1.0
            }
        };
        result = peak + (sum / wsum).ln() + frac(win.0, full.0).ln() + frac(win.1, full.1).ln();
        // Next window: the cells where the integrand is within e^-25 of the peak, one cell
        // wider on each side.
        let (mut i0, mut i1, mut j0, mut j1) = (nd, 0, no, 0);
        for i in 0..nd {
            for j in 0..no {
                if f[i * no + j] > peak - 25.0 {
                    i0 = i0.min(i);
                    i1 = i1.max(i);
                    j0 = j0.min(j);
                    j1 = j1.max(j);
                }
            }
        }
        let narrow = |x: &[f64], a: usize, b: usize| {
            let lo = x[a.saturating_sub(1)];
            let hi = x[(b + 1).min(x.len() - 1)];
            (lo, hi)
        };
        let next = (
            if nd > 1 { narrow(&dx, i0, i1) } else { win.0 },
            if no > 1 { narrow(&ox, j0, j1) } else { win.1 },
        );
        // Stop when the window no longer shrinks by half along some axis.
        let shrink = |(a, b): (f64, f64), (c, d): (f64, f64)| (d - c) < 0.5 * (b - a);
        if !(shrink(win.0, next.0) || shrink(win.1, next.1)) {
            break;
        }
        win = next;
    }
    result
}

/// Every hypothesis tested against one target: the [`Decision`] (the passing set ranked
/// by probability) and every tested material as a [`Candidate`] with its probability and
/// nuisances, most probable first.
#[derive(Debug, Clone, PartialEq)]
pub struct HypothesisOutcome {
    /// The decision (`candidates`: the passing materials).
    pub decision: Decision,
    /// Every tested material, most probable first (passing or not).
    pub tested: Vec<Candidate>,
}

/// Test every prototype of `protos` that has the rows' bands against `rows`
/// ([`test_hypothesis`], [`CandidateModel::from_prototype`]) and decide (module
/// documentation). `priors`: a weight ≥ 0 per prototype (`None`: uniform). A class
/// with several prototypes keeps its most probable one and the sum of their
/// probabilities.
///
/// In the [`Decision`]: `nearest_class` is the most probable material, `distance` and
/// `gate` its `χ²`, `runner_up` the next most probable, `margin` the difference of their
/// `χ²`, `ranked` every tested prototype by probability (`distance`: `χ²`),
/// `candidates` the passing materials with [`Candidate::probability`] and
/// [`Candidate::fit`], `bands_used` the rows' wavelengths. No prototype with the rows'
/// bands: [`Status::NoCommonBand`].
///
/// Errors: [`CoreError`] for bad rows, settings, prototype indices or priors.
pub fn classify_rows(
    rows: &[HypRow],
    wavelengths: &[f64],
    protos: &[MultiPrototype],
    priors: Option<&[f64]>,
    cfg: &HypothesisConfig,
) -> Result<HypothesisOutcome> {
    cfg.validate()?;
    check_rows(rows, wavelengths)?;
    check_priors(priors, protos.len())?;
    let inp = RowsTest {
        rows,
        wavelengths,
        protos,
        priors,
        cfg,
    };
    let mut fits: Vec<(usize, NuisanceFit, f64)> = Vec::new();
    for (i, p) in protos.iter().enumerate() {
        let Some(cand) = CandidateModel::from_prototype(p, wavelengths) else {
            continue;
        };
        check_candidate(&cand, wavelengths)?;
        let prior = priors.map_or(1.0, |w| w[i]);
        fits.push((i, test_checked(rows, wavelengths, &cand, cfg), prior));
    }
    let bands_used: Vec<Option<f64>> = wavelengths.iter().map(|&w| Some(w)).collect();
    if fits.is_empty() {
        let mut d = Decision::unclassified(
            Status::NoCommonBand,
            format!(
                "no material has the rows' band(s) {}",
                wavelengths
                    .iter()
                    .map(|w| format!("{w} nm"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        );
        d.bands_used = bands_used;
        return Ok(HypothesisOutcome {
            decision: d,
            tested: Vec::new(),
        });
    }
    let prob = probabilities(&fits);
    let mut order: Vec<usize> = (0..fits.len()).collect();
    order.sort_by(|&a, &b| {
        prob[b]
            .total_cmp(&prob[a])
            .then(fits[a].1.chi2.total_cmp(&fits[b].1.chi2))
            .then(a.cmp(&b))
    });
    let tested = inp.per_class(&fits, &prob, &order);
    let ranked: Vec<Neighbour> = order
        .iter()
        .map(|&k| Neighbour {
            index: fits[k].0,
            distance: fits[k].1.chi2,
        })
        .collect();
    let mut candidates: Vec<Candidate> = tested
        .iter()
        .filter(|c| c.fit.is_some_and(|f| f.consistent))
        .cloned()
        .collect();
    let widened = if candidates.len() == 1 {
        inp.widen(&mut candidates, &tested)
    } else {
        Vec::new()
    };
    let set_category = match candidates.first().and_then(|c| c.category.clone()) {
        Some(cat) if candidates.iter().all(|c| c.category.as_ref() == Some(&cat)) => Some(cat),
        _ => None,
    };
    let (predicted, status, reason) = verdict(&candidates, &tested, &widened, cfg.confidence);
    let best = &tested[0];
    let runner = tested.get(1);
    let runner_up_distance = runner.map_or(f64::NAN, |r| r.distance);
    let mut decision = Decision {
        predicted,
        nearest_class: Some(best.class.clone()),
        nearest: Some(Neighbour {
            index: best.index,
            distance: best.distance,
        }),
        distance: best.distance,
        runner_up: runner.map(|r| r.class.clone()),
        runner_up_distance,
        margin: runner_up_distance - best.distance,
        gate: Some(best.distance),
        votes: 1,
        status,
        reason,
        ranked,
        candidates,
        set_tested: true,
        set_category,
        bands_used,
    };
    if cfg.open_world {
        decision.open_world(protos, wavelengths, cfg.confidence);
    }
    Ok(HypothesisOutcome { decision, tested })
}

/// `priors` (if any) hold one finite weight ≥ 0 per each of `n` prototypes.
fn check_priors(priors: Option<&[f64]>, n: usize) -> Result<()> {
    if let Some(p) = priors {
        check_len("priors", p.len(), n)?;
        if let Some(&bad) = p.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
            return Err(CoreError::OutOfRange {
                name: "prior",
                value: bad,
                expected: "finite and >= 0",
            });
        }
    }
    Ok(())
}

/// The probability of every fit `(prototype, fit, prior)` from its evidence and prior,
/// relative to the best (priors of 0 give 0).
fn probabilities(fits: &[(usize, NuisanceFit, f64)]) -> Vec<f64> {
    let top = fits
        .iter()
        .filter(|f| f.2 > 0.0)
        .map(|f| f.1.log_evidence + f.2.ln())
        .fold(f64::NEG_INFINITY, f64::max);
    let weights: Vec<f64> = fits
        .iter()
        .map(|f| {
            if f.2 > 0.0 && top.is_finite() {
                (f.1.log_evidence + f.2.ln() - top).exp()
            } else {
                0.0
            }
        })
        .collect();
    let total: f64 = weights.iter().sum();
    weights
        .iter()
        .map(|w| if total > 0.0 { w / total } else { 0.0 })
        .collect()
}

/// The inputs of [`classify_rows`].
struct RowsTest<'a> {
    rows: &'a [HypRow],
    wavelengths: &'a [f64],
    protos: &'a [MultiPrototype],
    priors: Option<&'a [f64]>,
    cfg: &'a HypothesisConfig,
}

impl RowsTest<'_> {
    /// The category of the first prototype of `class` that has one.
    fn category_of(&self, class: &str) -> Option<String> {
        self.protos
            .iter()
            .filter(|p| p.class == class)
            .find_map(|p| p.category.clone())
    }

    /// Per class: the most probable prototype, the class's summed probability and
    /// whether any of its prototypes passes; classes in the order of their best fit
    /// (`order`: the fits by probability).
    fn per_class(
        &self,
        fits: &[(usize, NuisanceFit, f64)],
        prob: &[f64],
        order: &[usize],
    ) -> Vec<Candidate> {
        let protos = self.protos;
        let mut tested: Vec<Candidate> = Vec::new();
        for &k in order {
            let (i, fit, _) = fits[k];
            let class = &protos[i].class;
            if tested.iter().any(|c| &c.class == class) {
                continue;
            }
            let class_prob: f64 = fits
                .iter()
                .zip(prob)
                .filter(|(f, _)| &protos[f.0].class == class)
                .map(|(_, p)| p)
                .sum();
            let consistent = fits
                .iter()
                .filter(|f| &protos[f.0].class == class)
                .any(|f| f.1.consistent);
            let mut fit = fit;
            fit.consistent = consistent;
            tested.push(Candidate {
                class: class.clone(),
                index: i,
                distance: fit.chi2,
                category: self.category_of(class),
                probability: Some(class_prob),
                fit: Some(fit),
            });
        }
        tested
    }

    /// A single passing material (`candidates[0]`) stands only if no other material,
    /// under its own layer grown up to EXTENDED_LAYER_NM, both passes and explains the
    /// rows better: such a material joins the set, which becomes ambiguous (module
    /// documentation, "Layers beyond their range"). Returns the classes that joined.
    fn widen(&self, candidates: &mut Vec<Candidate>, tested: &[Candidate]) -> Vec<String> {
        let (rows, wavelengths, cfg) = (self.rows, self.wavelengths, self.cfg);
        let mut widened: Vec<String> = Vec::new();
        let bar = candidates[0].distance;
        for (i, p) in self.protos.iter().enumerate() {
            if p.class == candidates[0].class || self.priors.is_some_and(|w| !(w[i] > 0.0)) {
                continue;
            }
            let Some(mut cand) = CandidateModel::from_prototype(p, wavelengths) else {
                continue;
            };
            let Some(l) = cand.layer.as_mut() else {
                continue;
            };
            if l.max_nm >= EXTENDED_LAYER_NM {
                continue;
            }
            l.max_nm = EXTENDED_LAYER_NM;
            let fit = test_checked(rows, wavelengths, &cand, cfg);
            if !(fit.consistent && fit.chi2 < bar) {
                continue;
            }
            match candidates.iter_mut().find(|c| c.class == p.class) {
                Some(c) if c.distance <= fit.chi2 => {}
                Some(c) => {
                    c.distance = fit.chi2;
                    c.fit = Some(fit);
                }
                None => {
                    candidates.push(Candidate {
                        class: p.class.clone(),
                        index: i,
                        distance: fit.chi2,
                        category: self.category_of(&p.class),
                        probability: tested
                            .iter()
                            .find(|c| c.class == p.class)
                            .and_then(|c| c.probability),
                        fit: Some(fit),
                    });
                    widened.push(p.class.clone());
                }
            }
        }
        widened
    }
}

/// `(predicted, status, reason)` of [`classify_rows`] from the passing `candidates`,
/// every `tested` class (most probable first) and the `widened` classes, at
/// `confidence`.
fn verdict(
    candidates: &[Candidate],
    tested: &[Candidate],
    widened: &[String],
    confidence: f64,
) -> (String, Status, String) {
    let pct = confidence * 100.0;
    match candidates.len() {
        0 => (
            UNKNOWN.to_string(),
            Status::Rejected,
            format!(
                "no material, under its native layer within its thickness range, explains the \
                 rows at {pct}% confidence (most probable {}: chi2 {:.2} on {:.1} dof)",
                tested[0].class,
                tested[0].distance,
                tested[0].fit.map_or(0.0, |f| f.dof)
            ),
        ),
        1 => (candidates[0].class.clone(), Status::Ok, String::new()),
        n => (
            AMBIGUOUS.to_string(),
            Status::Ambiguous,
            format!(
                "ambiguous: {n} materials explain the rows at {pct}% confidence: {}{}",
                candidates
                    .iter()
                    .map(|c| format!(
                        "{} (p {:.3}, chi2 {:.2})",
                        c.class,
                        c.probability.unwrap_or(f64::NAN),
                        c.distance
                    ))
                    .collect::<Vec<_>>()
                    .join(", "),
                if widened.is_empty() {
                    String::new()
                } else {
                    format!(
                        " ({} under a native layer thicker than its range, up to {} nm, \
                         explains them better than {})",
                        widened.join(", "),
                        EXTENDED_LAYER_NM,
                        candidates[0].class
                    )
                }
            ),
        ),
    }
}

pub(crate) mod pixel;

#[cfg(test)]
mod tests;
