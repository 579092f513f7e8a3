//! Depolarization-aware inversion: the Priest–Meier specular pBRDF (paper eq. 3) plus
//! a Lambertian, fully depolarizing diffuse term, fitted to the DoLP **and** the
//! intensity `S0` of a target across captures (see `docs/MIXED.md`).
//!
//! # Model
//! For an unpolarized source of unknown normal irradiance `E` (one value shared by the
//! captures of a target: the *scale*), the radiance Stokes vector seen by the camera is
//! (paper eq. 2, 3, 7, with a Lambertian term of albedo `ρd` added to `f00`)
//!
//! ```text
//! S0_t = E cos θi_t · (a_t + ρd/π),       a_t = f00(n, k, σ, θi_t, θr, φ_t) · G_t
//! S1_t = E cos θi_t · f10,                DoLP_t = P(n, k, β_t) · a_t / (a_t + ρd/π)
//! ```
//!
//! where `f00 = m00(β) · exp(−tan²θ/(2σ²)) / (8π σ² cos⁴θ cos θi cos θr)` is eq. (3)
//! (`m00 = (Rs + Rp)/2`), `P` is eq. (9) (`= m10/m00`, eq. 8; the DoLP of the specular
//! part is frame-invariant, so this holds for any `φ`), `β` is eq. (5), `θ` eq. (4),
//! and `G_t` is 1 (the paper's model) or, with [`Shadowing::SmithBeckmann`], the Smith
//! shadowing–masking factor `G1(θi) G1(θr)` of a Beckmann surface with
//! `α = √2 σ` (Walter et al. 2007, eq. 25–27; the paper's eq. 3 omits it).
//! The diffuse term dilutes the DoLP by the *specular share* `s_t = a_t/(a_t + ρd/π)`.
//!
//! # Fit
//! Parameters `x = (n, k, σ, ρd, ln E[, θr])`. Residuals, `2T` for `T` captures:
//!
//! ```text
//! r_t     = (DoLP_model − DoLP_t) / se_t                 (se_t = dolp_se, or MixedOptions::dolp_sd)
//! r_{T+t} = (ln S0_model − ln S0_t) / ε                  (ε = MixedOptions::s0_rel_sd)
//! ```
//!
//! The measurements carry no standard error for `S0`; the region mean's shot noise is
//! negligible next to the capture-to-capture systematic errors (source drift, exposure
//! calibration, flat field, model error such as shadowing), which are *multiplicative*,
//! hence the relative (log) error model with a documented `ε` (default 2%).
//!
//! 1. Global start: a grid over `(n, k) × σ × ρd [× θr]` with `ln E` profiled out in
//!    closed form (the mean of `ln S0_t − ln(model/E)`); the best node of each of a few
//!    well-separated `(n, k)` cells is polished.
//! 2. Polish: bounded Levenberg–Marquardt with the analytic Jacobian ([`model_point`];
//!    checked against finite differences in `tests/mixed_props.rs`), steps in
//!    `u = k²` below `k = 1` as in [`crate::fit`].
//! 3. Covariance `s² (JᵀJ)⁻¹` (weighted residuals), `s² = max(1, χ²/(2T − p))` when the
//!    DoLP standard errors are given (the S0 weight is an assumption: a misfit inflates
//!    the errors, a good fit does not shrink them), `s² = χ²/(2T − p)` otherwise.
//!
//! # Unknown view angle
//! With [`MixedOptions::estimate_theta_r`], `θr` is estimated jointly. What is known is
//! the source–camera angle of every capture (the paper's `θsc = 2β`, section 5), i.e.
//! `β_t`; in the plane of incidence (`φ = 180°`) then `θi_t = 2β_t − θr` and the facet
//! tilt is `θ_t = β_t − θr`. The DoLP depends on `β` only, so `θr` is determined by the
//! position of the intensity lobe (and of the dilution) along `β`. When the lobe does
//! not pin it (flat lobe, lobe peak far outside the measured `β` range) the standard
//! error of `θr` exceeds [`MixedOptions::theta_r_se_max`] and the status is
//! `ill_conditioned`.
//!
//! # Model selection
//! The pure-specular radiometric model (`ρd = 0`, `p − 1` parameters) and the mixed
//! model are both fitted and compared with the Gaussian information criteria
//! `AIC = χ²/s² + 2p`, `BIC = χ²/s² + p ln m` (`m = 2T` residuals), where the error
//! scale `s²` is that of the larger (mixed) model — `max(1, χ²/(m − p))` with DoLP
//! standard errors, `χ²/(m − p)` without (the usual "ĉ" of overdispersed least
//! squares). The mixed model is selected when its BIC is lower, i.e. when adding `ρd`
//! lowers `χ²/s²` by more than `ln m`.
//!
//! # Layout
//!
//! `options` (inputs and settings), `shadowing` (Smith–Beckmann `G1`), `model` (the
//! radiometric model and its analytic gradients), `depolarized` (the DoLP-only
//! `depolarized` rule), `problem` (validation, parameter box, weighted residuals),
//! `linalg` (Cholesky), `lm` (bounded Levenberg–Marquardt), `start` (global grid start),
//! `solve` ([`fit_model`]), `finish` (covariance, summaries, status), `select`
//! ([`fit_mixed`]: both models and BIC/AIC selection), `report` (the result types),
//! `systematic` ([`total_nk_cov`]: noise + systematic covariance of `(n, k)`).
//!
//! # Reference
//!
//! - Thilak, Creusere & Voelz, "Material classification using passive polarimetric
//!   imagery", ICIP 2007: eq. (2), (3) (Priest–Meier pBRDF), (4), (5) (geometry), (7),
//!   (8), (9) (DoLP of the specular term); section 5 (`θsc = 2β`).
//! - Walter, Marschner, Li & Torrance, "Microfacet models for refraction through rough
//!   surfaces", EGSR 2007: eq. (25)–(27) (Smith `G1` of the Beckmann distribution).

mod depolarized;
mod finish;
mod linalg;
mod lm;
mod model;
mod options;
mod problem;
mod report;
mod select;
mod shadowing;
mod solve;
mod start;
mod systematic;

pub use crate::status::FitStatus;
pub use depolarized::{DEPOLARIZED_MAX_DOLP, depolarized_reason};
pub use model::{ModelPoint, m00_grad, model_point};
pub use options::{MixedCapture, MixedOptions};
pub use report::{MixedFit, MixedModel, MixedReport};
pub use select::fit_mixed;
pub use shadowing::{Shadowing, smith_g1};
pub use solve::fit_model;
pub use systematic::total_nk_cov;

/// Index of `n` in the parameter vector.
pub const P_N: usize = 0;
/// Index of `k`.
pub const P_K: usize = 1;
/// Index of `σ`.
pub const P_SIGMA: usize = 2;
/// Index of `ρd`.
pub const P_RHO: usize = 3;
/// Index of `ln E` (the source scale).
pub const P_LN_E: usize = 4;
/// Index of `θr` (radians).
pub const P_THETA_R: usize = 5;
/// Number of parameters of the full model.
pub const NPAR: usize = 6;

/// Smallest `k` reached by the `u = k²` steps (a fit ending there reports `k = 0`).
const K_FLOOR: f64 = 1e-9;
/// Below this `k` the polish steps in `u = k²`.
const K_U: f64 = 1.0;
