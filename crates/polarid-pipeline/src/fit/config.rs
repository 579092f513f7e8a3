//! The configuration of the fit: reflectance model, search boxes and the mixed fit's
//! options, with the checks shared by the CLI and Python.

use polarid_core::fit::{FitBounds, FitOptions};
use polarid_core::mixed::{DEPOLARIZED_MAX_DOLP, MixedOptions, Shadowing};

use crate::{PipelineError, Result};

/// Reflectance model of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Reflectance {
    /// Specular Fresnel reflection only (the paper's eq. 9): DoLP only.
    #[default]
    Specular,
    /// Specular plus a Lambertian depolarized diffuse term; uses `s0` too.
    Mixed,
}

impl Reflectance {
    /// Every model, in documentation order.
    pub const ALL: [Reflectance; 2] = [Reflectance::Specular, Reflectance::Mixed];

    /// The name used on the command line and in Python: `specular` or `mixed`.
    pub fn as_str(self) -> &'static str {
        match self {
            Reflectance::Specular => "specular",
            Reflectance::Mixed => "mixed",
        }
    }

    /// The model of a name of [`Reflectance::as_str`].
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|r| r.as_str() == name)
    }
}

/// The name of a shadowing factor used on the command line and in Python: `none` or
/// `smith`.
pub fn shadowing_name(s: Shadowing) -> &'static str {
    match s {
        Shadowing::None => "none",
        Shadowing::SmithBeckmann => "smith",
    }
}

/// The shadowing factor of a name of [`shadowing_name`].
pub fn parse_shadowing(name: &str) -> Option<Shadowing> {
    [Shadowing::None, Shadowing::SmithBeckmann]
        .into_iter()
        .find(|s| shadowing_name(*s) == name)
}

/// The problem with a search range `(min, max)`, if any: both finite and
/// `0 <= min < max` (the rule of `--n-range`, `--k-range`, `--sigma-range`).
pub fn range_problem((lo, hi): (f64, f64)) -> Option<String> {
    if !(lo.is_finite() && hi.is_finite()) {
        return Some(format!(
            "{} is not finite",
            if lo.is_finite() { hi } else { lo }
        ));
    }
    if !(lo >= 0.0 && hi > lo) {
        return Some(format!("need 0 <= MIN < MAX, got {lo},{hi}"));
    }
    None
}

/// Check a search range with [`range_problem`]; the error names `option` and the range.
pub fn check_range(option: &str, range: (f64, f64)) -> Result<()> {
    match range_problem(range) {
        Some(reason) => Err(PipelineError::Range {
            option: option.to_string(),
            reason,
        }),
        None => Ok(()),
    }
}

/// Check a fraction in (0, 1].
fn check_unit(option: &str, v: f64) -> Result<()> {
    if v > 0.0 && v <= 1.0 {
        Ok(())
    } else {
        Err(PipelineError::config(option, v, "must be in (0, 1]"))
    }
}

/// How [`fit`](super::fit()) models the reflection; the defaults are those of `polarid fit`.
///
/// Checked by [`FitConfig::validate`] (called by [`fit`](super::fit())); an error names the field as
/// the Python keyword (`n_range`, `s0_rel_sd`...).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitConfig {
    /// Reflectance model.
    pub reflectance: Reflectance,
    /// Search range of `n`, `(min, max)` with `0 <= min < max`.
    pub n_range: (f64, f64),
    /// Search range of `k`, `(min, max)` with `0 <= min < max`.
    pub k_range: (f64, f64),
    /// Specular fit: status `depolarized` when the DoLP stays below this, in (0, 1], at
    /// every source position.
    pub depolarized_dolp: f64,
    /// Mixed fit: estimate the camera zenith θr (in-plane captures only).
    pub estimate_theta_r: bool,
    /// Mixed fit: shadowing factor of the specular term.
    pub shadowing: Shadowing,
    /// Mixed fit: relative standard deviation of `s0`, in (0, 1].
    pub s0_rel_sd: f64,
    /// Mixed fit: search range of the roughness σ (its minimum is raised to 0.001).
    pub sigma_range: (f64, f64),
}

impl Default for FitConfig {
    fn default() -> Self {
        let b = FitBounds::default();
        let m = MixedOptions::default();
        Self {
            reflectance: Reflectance::Specular,
            n_range: (b.n_min, b.n_max),
            k_range: (b.k_min, b.k_max),
            depolarized_dolp: DEPOLARIZED_MAX_DOLP,
            estimate_theta_r: false,
            shadowing: Shadowing::None,
            s0_rel_sd: m.s0_rel_sd,
            sigma_range: (m.sigma_min, m.sigma_max),
        }
    }
}

impl FitConfig {
    /// Check every value ([`PipelineError::Config`] naming the field and value).
    pub fn validate(&self) -> Result<()> {
        check_range("n_range", self.n_range)?;
        check_range("k_range", self.k_range)?;
        check_range("sigma_range", self.sigma_range)?;
        check_unit("depolarized_dolp", self.depolarized_dolp)?;
        check_unit("s0_rel_sd", self.s0_rel_sd)?;
        if self.reflectance != Reflectance::Mixed {
            if self.estimate_theta_r {
                return Err(PipelineError::config(
                    "estimate_theta_r",
                    true,
                    "needs reflectance mixed",
                ));
            }
            if self.shadowing != Shadowing::None {
                return Err(PipelineError::config(
                    "shadowing",
                    shadowing_name(self.shadowing),
                    "needs reflectance mixed",
                ));
            }
        }
        Ok(())
    }

    /// The options of the specular fit (the search box, other settings default).
    pub fn fit_options(&self) -> FitOptions {
        FitOptions {
            bounds: self.bounds(),
            ..Default::default()
        }
    }

    /// The options of the mixed fit.
    pub fn mixed_options(&self) -> MixedOptions {
        MixedOptions {
            bounds: self.bounds(),
            estimate_theta_r: self.estimate_theta_r,
            shadowing: self.shadowing,
            s0_rel_sd: self.s0_rel_sd,
            sigma_min: self.sigma_range.0.max(1e-3),
            sigma_max: self.sigma_range.1,
            ..MixedOptions::default()
        }
    }

    fn bounds(&self) -> FitBounds {
        FitBounds {
            n_min: self.n_range.0,
            n_max: self.n_range.1,
            k_min: self.k_range.0,
            k_max: self.k_range.1,
        }
    }
}
