//! The inputs of the radiometric fit: one [`MixedCapture`] per source position (geometry,
//! DoLP with its optional standard error, exposure-normalised `S0`) and the settings
//! [`MixedOptions`] (parameter box, error scales `ε = s0_rel_sd` and `dolp_sd`, joint `θr`,
//! shadowing, depolarization threshold, iteration limit).
//!
//! # Reference
//! `β` is the paper's eq. (5) (Thilak, Creusere & Voelz, ICIP 2007).

use super::Shadowing;
use crate::fit::FitBounds;

/// One capture of one target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MixedCapture {
    /// Source zenith `θi`, radians (ignored when `θr` is estimated: `β` is used).
    pub theta_i: f64,
    /// Camera zenith `θr`, radians (the nominal value when it is estimated).
    pub theta_r: f64,
    /// `φ = φr − φi`, radians (`π` in the paper's geometry; required when `θr` is
    /// estimated).
    pub phi: f64,
    /// Local incidence angle `β`, radians (eq. 5); the known quantity when `θr` is
    /// estimated. Use [`MixedCapture::new`] to derive it from the angles.
    pub beta: f64,
    /// Measured DoLP, in `[0, 1]`.
    pub dolp: f64,
    /// Its standard error (`None`: [`MixedOptions::dolp_sd`] is assumed).
    pub dolp_se: Option<f64>,
    /// Mean `S0` divided by the capture's exposure (consistent relative units), `> 0`.
    pub s0: f64,
}

impl MixedCapture {
    /// A capture from its angles (radians), with `β` from eq. (5).
    pub fn new(
        theta_i: f64,
        theta_r: f64,
        phi: f64,
        dolp: f64,
        dolp_se: Option<f64>,
        s0: f64,
    ) -> Self {
        Self {
            theta_i,
            theta_r,
            phi,
            beta: crate::geometry::beta(theta_i, theta_r, phi),
            dolp,
            dolp_se,
            s0,
        }
    }
}

/// Settings of [`fit_mixed`](super::fit_mixed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MixedOptions {
    /// Box of `(n, k)`.
    pub bounds: FitBounds,
    /// Smallest roughness `σ`.
    pub sigma_min: f64,
    /// Largest roughness `σ`.
    pub sigma_max: f64,
    /// Largest diffuse albedo `ρd` (≤ 1 for a physical surface).
    pub rho_d_max: f64,
    /// Relative standard deviation `ε` of the measured `S0` (log residual scale).
    pub s0_rel_sd: f64,
    /// DoLP standard deviation assumed for captures without `dolp_se`.
    pub dolp_sd: f64,
    /// Estimate `θr` jointly (in-plane captures only; see the module documentation).
    pub estimate_theta_r: bool,
    /// Range of `θr` searched when it is estimated, radians.
    pub theta_r_range: (f64, f64),
    /// Above this standard error of `θr` (radians) the fit is `ill_conditioned`.
    pub theta_r_se_max: f64,
    /// Shadowing factor of the specular term.
    pub shadowing: Shadowing,
    /// When the specular share `a/(a + ρd/π)` stays below this at every capture, the
    /// mixed fit is `depolarized`.
    pub min_specular_share: f64,
    /// Levenberg–Marquardt iteration limit per start.
    pub max_iter: u32,
}

impl Default for MixedOptions {
    fn default() -> Self {
        Self {
            bounds: FitBounds::default(),
            sigma_min: 0.02,
            sigma_max: 1.0,
            rho_d_max: 1.0,
            s0_rel_sd: 0.02,
            dolp_sd: 0.01,
            estimate_theta_r: false,
            theta_r_range: (0.0, 85f64.to_radians()),
            theta_r_se_max: 2f64.to_radians(),
            shadowing: Shadowing::None,
            min_specular_share: 0.1,
            max_iter: 300,
        }
    }
}
