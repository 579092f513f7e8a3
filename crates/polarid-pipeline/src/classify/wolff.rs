//! Wolff's metal/dielectric baseline (Fresnel-ratio rule) from a measurements CSV, shared
//! by [`classify`](super::classify) and [`evaluate`](crate::evaluate::evaluate).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use polarid_core::CoreError;
use polarid_core::classify::{WolffConfig, WolffDecision, WolffObservation, wolff_classify};
use polarid_io::table::measurements;

use crate::{PipelineError, Result};

/// Settings of Wolff's rule as the user gives them (angles in degrees); the defaults are
/// those of `--wolff-threshold 6 --wolff-beta 40,70`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WolffSettings {
    /// Threshold on the Fresnel ratio (1 + P)/(1 - P): dielectric above it (> 1).
    pub threshold: f64,
    /// Window of specular angles β, degrees: `(min, max)`.
    pub beta_deg: (f64, f64),
}

impl Default for WolffSettings {
    fn default() -> Self {
        Self {
            threshold: 6.0,
            beta_deg: (40.0, 70.0),
        }
    }
}

impl WolffSettings {
    /// The settings of Wolff's rule (radians), checked by `polarid_core`'s rule.
    pub fn check(&self) -> std::result::Result<WolffConfig, CoreError> {
        let cfg = WolffConfig {
            threshold: self.threshold,
            beta_min: self.beta_deg.0.to_radians(),
            beta_max: self.beta_deg.1.to_radians(),
        };
        wolff_classify(&[], &cfg)?;
        Ok(cfg)
    }

    /// [`WolffSettings::check`] as a [`PipelineError::Config`] naming `wolff` and the
    /// settings.
    pub fn validate(&self) -> Result<WolffConfig> {
        self.check()
            .map_err(|e| PipelineError::config("wolff", self.describe(), e.to_string()))
    }

    /// A one-line description, e.g. `Fresnel ratio threshold 6, beta in [40, 70] deg`.
    pub fn describe(&self) -> String {
        let (lo, hi) = self.beta_deg;
        format!(
            "Fresnel ratio threshold {}, beta in [{lo}, {hi}] deg",
            self.threshold
        )
    }
}

/// Wolff's observations of every target of a measurements CSV, with checked settings.
#[derive(Debug, Clone)]
pub struct WolffData {
    /// The measurements file.
    pub path: PathBuf,
    /// The settings as given.
    pub settings: WolffSettings,
    /// The settings, checked (radians).
    pub config: WolffConfig,
    /// Observations per target.
    pub observations: BTreeMap<String, Vec<WolffObservation>>,
}

impl WolffData {
    /// Check `settings`, then read `path` (every row validated by the measurements
    /// reader: a bad file, line, column or value is an error naming them).
    pub fn load(path: &Path, settings: WolffSettings) -> Result<Self> {
        let config = settings.validate()?;
        let mut observations: BTreeMap<String, Vec<WolffObservation>> = BTreeMap::new();
        for row in measurements::read(path)? {
            observations
                .entry(row.target)
                .or_default()
                .push(WolffObservation {
                    beta: row.beta_deg.to_radians(),
                    dolp: row.dolp,
                });
        }
        Ok(Self {
            path: path.to_path_buf(),
            settings,
            config,
            observations,
        })
    }

    /// The observations of `target` (none when it has no row).
    pub fn of(&self, target: &str) -> &[WolffObservation] {
        self.observations.get(target).map_or(&[], Vec::as_slice)
    }

    /// Wolff's decision on `target`; `context` is put before the rule's error (after the
    /// measurements file), e.g. `target T1 (line 2 of fits.csv)`.
    pub fn decide(&self, target: &str, context: &str) -> Result<WolffDecision> {
        wolff_classify(self.of(target), &self.config).map_err(|e| PipelineError::Data {
            path: self.path.display().to_string(),
            reason: format!("{context}: {e}"),
        })
    }
}
