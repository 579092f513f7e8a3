//! The results: one radiometric fit ([`MixedFit`]: parameters, standard errors, `χ²`,
//! information criteria, specular share, status) and both fits of a target with the
//! selected model ([`MixedReport`]).

use super::FitStatus;

/// Which reflectance model a fit uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MixedModel {
    /// Specular only (`ρd = 0`): the paper's eq. (3) with the intensity.
    Specular,
    /// Specular plus Lambertian diffuse.
    Mixed,
}

impl MixedModel {
    /// `specular` or `mixed` (the `model` column of the fits CSV).
    pub fn as_str(self) -> &'static str {
        match self {
            MixedModel::Specular => "specular",
            MixedModel::Mixed => "mixed",
        }
    }
}

/// One radiometric fit.
#[derive(Debug, Clone, PartialEq)]
pub struct MixedFit {
    /// The model fitted.
    pub model: MixedModel,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index.
    pub k: f64,
    /// Roughness σ (paper eq. 3).
    pub sigma: f64,
    /// Diffuse albedo ρd (0 for [`MixedModel::Specular`]).
    pub rho_d: f64,
    /// Source scale `E` (units of `S0`·sr).
    pub scale: f64,
    /// Camera zenith, radians (the input's when not estimated).
    pub theta_r: f64,
    /// Whether `θr` was estimated.
    pub theta_r_estimated: bool,
    /// Standard error of `n`.
    pub n_se: f64,
    /// Standard error of `k` (one-sigma upper deviation near `k = 0`).
    pub k_se: f64,
    /// Standard error of σ.
    pub sigma_se: f64,
    /// Standard error of ρd (NaN for the specular model).
    pub rho_d_se: f64,
    /// Relative standard error of the scale (standard error of `ln E`).
    pub scale_rel_se: f64,
    /// Standard error of θr, radians (NaN when not estimated).
    pub theta_r_se: f64,
    /// Correlation of `n` and `k`.
    pub nk_corr: f64,
    /// Weighted residual sum of squares.
    pub chi2: f64,
    /// Residuals minus free parameters (`2T − p`).
    pub dof: usize,
    /// Number of free parameters `p`.
    pub params: usize,
    /// Root-mean-square DoLP residual.
    pub rms_dolp: f64,
    /// Root-mean-square relative S0 residual (of `ln S0`).
    pub rms_s0_rel: f64,
    /// `χ²/s² + 2p` (`s²`: see the module documentation).
    pub aic: f64,
    /// `χ²/s² + p ln m`.
    pub bic: f64,
    /// Smallest specular share `a/(a + ρd/π)` over the captures.
    pub specular_share_min: f64,
    /// Largest specular share over the captures.
    pub specular_share_max: f64,
    /// Levenberg–Marquardt iterations over all starts.
    pub iterations: u32,
    /// Status.
    pub status: FitStatus,
    /// Why the status is not `ok` (empty when it is).
    pub reason: String,
}

/// Both fits of a target and the model selection.
#[derive(Debug, Clone, PartialEq)]
pub struct MixedReport {
    /// The pure-specular radiometric fit (`ρd = 0`).
    pub specular: MixedFit,
    /// The mixed fit.
    pub mixed: MixedFit,
    /// The model with the lower BIC.
    pub selected: MixedModel,
    /// `BIC(specular) − BIC(mixed)` (> 0 favours the mixed model).
    pub delta_bic: f64,
    /// `AIC(specular) − AIC(mixed)`.
    pub delta_aic: f64,
}

impl MixedReport {
    /// The selected fit.
    pub fn best(&self) -> &MixedFit {
        match self.selected {
            MixedModel::Specular => &self.specular,
            MixedModel::Mixed => &self.mixed,
        }
    }
}
