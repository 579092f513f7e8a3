//! The configuration of the fit: reflectance model, search boxes and the mixed fit's
//! options, with the checks shared by the CLI and Python.

use polarid_core::classify::Nuisances;
use polarid_core::fit::{FitBounds, FitOptions};
use polarid_core::mixed::{DEPOLARIZED_MAX_DOLP, MixedOptions, Shadowing};
use polarid_core::systematic::Polarimetric;

use crate::error::ensure;
use crate::{PipelineError, Result};

/// Reflectance model of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Reflectance {
    /// The default: the specular DoLP-only fit, then, when
    /// [`FitConfig::brightness_check`] is on and every row of a target carries its
    /// brightness (`s0`, `exposure`), the brightness check (docs/MIXED.md): `s0`
    /// following Lambert's law makes the target `depolarized`, and the mixed model
    /// selected by BIC replaces the specular fit.
    #[default]
    Auto,
    /// Specular Fresnel reflection only (the paper's eq. 9): DoLP only, as asked, with
    /// no brightness check.
    Specular,
    /// Specular plus a Lambertian depolarized diffuse term; uses `s0` too.
    Mixed,
}

impl Reflectance {
    /// Every model, in documentation order.
    pub const ALL: [Reflectance; 3] =
        [Reflectance::Auto, Reflectance::Specular, Reflectance::Mixed];

    /// The name used on the command line and in Python: `auto`, `specular` or `mixed`.
    pub fn as_str(self) -> &'static str {
        match self {
            Reflectance::Auto => "auto",
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
    ensure(v > 0.0 && v <= 1.0, option, v, "must be in (0, 1]")
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
    /// Specular fit: standard uncertainty of the source and camera directions, degrees,
    /// in `[0, 90)`, for rows without an `angle_sd_deg` (docs/ERRORS.md).
    pub angle_sd_deg: f64,
    /// Specular fit: additive DoLP error (standard deviation, independent per row), in
    /// `[0, 1)`.
    pub dolp_floor: f64,
    /// Specular fit: the lowest extinction ratio the analyzer may have, `> 1`
    /// (infinite: an ideal polarizer); the DoLP scale's uncertainty is `2/(ER + 1)`.
    pub extinction_ratio: f64,
    /// Specular fit: the largest retardance ahead of the analyzer, degrees, in `[0, 90]`.
    pub retardance_deg: f64,
    /// Specular fit: standard thickness of an unmodelled surface layer (native oxide,
    /// contamination), nanometres, in `[0, 1000)` (docs/ERRORS.md).
    pub film_sd_nm: f64,
    /// Specular fit: the wavelength the layer's thickness is compared with, nanometres,
    /// in `[100, 100000)`, for rows without a `wavelength_nm` (rows with one use their
    /// own; [`FitConfig::polarimetric_at`]).
    pub wavelength_nm: f64,
    /// [`Reflectance::Auto`]: when every row of a target carries its brightness (`s0`
    /// and `exposure`, as `measure` writes them) and its angles, decide by the mixed
    /// model selection whether it reflects specularly at all (docs/MIXED.md). Unused
    /// by an explicit [`Reflectance::Specular`] or [`Reflectance::Mixed`].
    pub brightness_check: bool,
    /// Specular fit: status `model_mismatch` when the goodness-of-fit or the AoLP test
    /// has a p-value below this, in `[0, 1)` (0: never).
    pub mismatch_p: f64,
    /// Stop at the first problem (a measurement row whose status is not `ok`, a target
    /// that cannot be fitted) with an error, instead of a fits row with a status and a
    /// reason (docs/FORMATS.md, "Partial failure").
    pub strict: bool,
}

/// Default of [`FitConfig::angle_sd_deg`], degrees.
pub const DEFAULT_ANGLE_SD_DEG: f64 = 0.2;
/// Default of [`FitConfig::dolp_floor`].
pub const DEFAULT_DOLP_FLOOR: f64 = 0.002;
/// Default of [`FitConfig::extinction_ratio`].
pub const DEFAULT_EXTINCTION_RATIO: f64 = 100.0;
/// Default of [`FitConfig::retardance_deg`], degrees.
pub const DEFAULT_RETARDANCE_DEG: f64 = 0.0;
/// Default of [`FitConfig::film_sd_nm`], nanometres.
pub const DEFAULT_FILM_SD_NM: f64 = 3.0;
/// Default of [`FitConfig::wavelength_nm`], nanometres.
pub const DEFAULT_WAVELENGTH_NM: f64 = 550.0;
/// Default of [`FitConfig::mismatch_p`].
pub const DEFAULT_MISMATCH_P: f64 = 0.001;

impl Default for FitConfig {
    fn default() -> Self {
        let b = FitBounds::default();
        let m = MixedOptions::default();
        Self {
            reflectance: Reflectance::Auto,
            n_range: (b.n_min, b.n_max),
            k_range: (b.k_min, b.k_max),
            depolarized_dolp: DEPOLARIZED_MAX_DOLP,
            estimate_theta_r: false,
            shadowing: Shadowing::None,
            s0_rel_sd: m.s0_rel_sd,
            sigma_range: (m.sigma_min, m.sigma_max),
            angle_sd_deg: DEFAULT_ANGLE_SD_DEG,
            dolp_floor: DEFAULT_DOLP_FLOOR,
            extinction_ratio: DEFAULT_EXTINCTION_RATIO,
            retardance_deg: DEFAULT_RETARDANCE_DEG,
            film_sd_nm: DEFAULT_FILM_SD_NM,
            wavelength_nm: DEFAULT_WAVELENGTH_NM,
            brightness_check: true,
            mismatch_p: DEFAULT_MISMATCH_P,
            strict: false,
        }
    }
}

/// Check `lo <= v < hi` (or `<= hi` when `closed`), finite.
fn check_in(option: &str, v: f64, lo: f64, hi: f64, closed: bool) -> Result<()> {
    let ok = v.is_finite() && v >= lo && (v < hi || (closed && v == hi));
    let close = if closed { ']' } else { ')' };
    ensure(
        ok,
        option,
        v,
        format!("must be finite and in [{lo}, {hi}{close}"),
    )
}

impl FitConfig {
    /// Check every value ([`PipelineError::Config`] naming the field and value).
    pub fn validate(&self) -> Result<()> {
        check_range("n_range", self.n_range)?;
        check_range("k_range", self.k_range)?;
        check_range("sigma_range", self.sigma_range)?;
        check_unit("depolarized_dolp", self.depolarized_dolp)?;
        check_unit("s0_rel_sd", self.s0_rel_sd)?;
        check_in("angle_sd_deg", self.angle_sd_deg, 0.0, 90.0, false)?;
        check_in("dolp_floor", self.dolp_floor, 0.0, 1.0, false)?;
        check_in("retardance_deg", self.retardance_deg, 0.0, 90.0, true)?;
        check_in("mismatch_p", self.mismatch_p, 0.0, 1.0, false)?;
        check_in("film_sd_nm", self.film_sd_nm, 0.0, 1000.0, false)?;
        check_in("wavelength_nm", self.wavelength_nm, 100.0, 100_000.0, false)?;
        ensure(
            self.extinction_ratio > 1.0,
            "extinction_ratio",
            self.extinction_ratio,
            "must be > 1 (inf: an ideal polarizer)",
        )?;
        if self.reflectance != Reflectance::Mixed {
            let why = "needs reflectance mixed";
            ensure(!self.estimate_theta_r, "estimate_theta_r", true, why)?;
            let shadowing = shadowing_name(self.shadowing);
            ensure(
                self.shadowing == Shadowing::None,
                "shadowing",
                shadowing,
                why,
            )?;
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

    /// The polarimetric part of the error model, with the surface layer compared with
    /// [`FitConfig::wavelength_nm`].
    pub fn polarimetric(&self) -> Polarimetric {
        self.polarimetric_at(None)
    }

    /// The polarimetric part of the error model for rows of wavelength `band` (nm): the
    /// surface-layer allowance `film_sd_nm / λ` uses the rows' own wavelength when they
    /// have one (a finite value > 0), else [`FitConfig::wavelength_nm`].
    pub fn polarimetric_at(&self, band: Option<f64>) -> Polarimetric {
        let wl = band
            .filter(|w| w.is_finite() && *w > 0.0)
            .unwrap_or(self.wavelength_nm);
        Polarimetric {
            dolp_floor: self.dolp_floor,
            extinction_ratio: self.extinction_ratio,
            retardance: self.retardance_deg.to_radians(),
            film_sd_waves: self.film_sd_nm / wl,
        }
    }

    /// The hypothesis tests' nuisance bounds of this error model (the analyzer's
    /// extinction ratio and retardance) with a direction uncertainty `angle_sd` (radians).
    pub fn nuisances(&self, angle_sd: f64) -> Nuisances {
        let retardance = self.retardance_deg.to_radians();
        Nuisances::from_error_model(self.extinction_ratio, retardance, angle_sd)
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
