//! The scene file as deserialized: every key optional and spanned (for line numbers),
//! unknown keys refused (`deny_unknown_fields`). Checked by `Ctx` into a [`Scene`](super::Scene).

use serde::Deserialize;
use toml::Spanned;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawScene {
    pub(super) name: Option<Spanned<String>>,
    pub(super) width: Option<Spanned<i64>>,
    pub(super) height: Option<Spanned<i64>>,
    pub(super) theta_r_deg: Option<Spanned<f64>>,
    pub(super) phi_deg: Option<Spanned<f64>>,
    pub(super) theta_i_deg: Option<Spanned<toml::Value>>,
    pub(super) wavelength_nm: Option<Spanned<f64>>,
    pub(super) background: Option<Spanned<f64>>,
    pub(super) seed: Option<Spanned<i64>>,
    pub(super) format: Option<Spanned<String>>,
    pub(super) bands: Option<Spanned<toml::Value>>,
    pub(super) library: Option<Spanned<String>>,
    pub(super) sensor: Option<RawSensor>,
    pub(super) exposure: Option<RawExposure>,
    pub(super) capture: Option<RawCapture>,
    #[serde(default)]
    pub(super) plate: Vec<RawPlate>,
    pub(super) camera: Option<Spanned<RawCamera>>,
    pub(super) plane: Option<Spanned<Vec<RawPlane>>>,
    pub(super) site: Option<Spanned<RawSite>>,
    pub(super) source: Option<Spanned<Vec<RawSource>>>,
    /// `[plan]`: read by `polarid plan` alone (docs/PLAN.md), accepted here.
    #[allow(dead_code)]
    pub(super) plan: Option<toml::Value>,
}

/// `[camera]`: only the keys are checked here (the values by the manifest's parser,
/// `manifest::shared`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
pub(super) struct RawCamera {
    pub(super) focal_px: Option<toml::Value>,
    pub(super) principal_point_px: Option<toml::Value>,
    pub(super) distortion: Option<toml::Value>,
    pub(super) position: Option<toml::Value>,
    pub(super) look_at: Option<toml::Value>,
    pub(super) up: Option<toml::Value>,
    pub(super) rotation: Option<toml::Value>,
}

/// `[[plane]]`: keys only (values: the manifest's parser).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
pub(super) struct RawPlane {
    pub(super) name: Option<toml::Value>,
    pub(super) point: Option<toml::Value>,
    pub(super) normal: Option<toml::Value>,
}

/// `[site]`: keys only (values: the manifest's parser).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
pub(super) struct RawSite {
    pub(super) latitude_deg: Option<toml::Value>,
    pub(super) longitude_deg: Option<toml::Value>,
    pub(super) elevation_m: Option<toml::Value>,
    pub(super) pressure_mbar: Option<toml::Value>,
    pub(super) temperature_c: Option<toml::Value>,
}

/// `[[source]]`: where (one of `position`, `direction`, `sun`; checked by the manifest's
/// parser), how strong, and an optional capture name.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
pub(super) struct RawSource {
    pub(super) position: Option<toml::Value>,
    pub(super) direction: Option<toml::Value>,
    pub(super) sun: Option<toml::Value>,
    pub(super) intensity: Option<Spanned<f64>>,
    pub(super) name: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSensor {
    pub(super) bit_depth: Option<Spanned<i64>>,
    pub(super) full_well_e: Option<Spanned<f64>>,
    pub(super) read_noise_e: Option<Spanned<f64>>,
    pub(super) dark_level_dn: Option<Spanned<f64>>,
    pub(super) shot_noise: Option<Spanned<bool>>,
    pub(super) band_response: Option<Spanned<toml::Value>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawExposure {
    pub(super) mode: Option<Spanned<String>>,
    pub(super) value: Option<Spanned<f64>>,
    pub(super) fraction: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCapture {
    pub(super) kind: Option<Spanned<String>>,
    pub(super) angles_deg: Option<Spanned<Vec<f64>>>,
    pub(super) pattern: Option<Spanned<Vec<f64>>>,
    pub(super) color: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPlate {
    pub(super) name: Option<Spanned<String>>,
    pub(super) class: Option<Spanned<String>>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) n: Option<Spanned<toml::Value>>,
    pub(super) k: Option<Spanned<toml::Value>>,
    pub(super) sigma: Option<Spanned<f64>>,
    pub(super) rho_d: Option<Spanned<toml::Value>>,
    pub(super) rect: Option<Spanned<Vec<i64>>>,
    pub(super) region: Option<Spanned<Vec<i64>>>,
    pub(super) plane: Option<Spanned<String>>,
    pub(super) center: Option<Spanned<Vec<f64>>>,
    pub(super) size: Option<Spanned<toml::Value>>,
    pub(super) axis: Option<Spanned<Vec<f64>>>,
}
