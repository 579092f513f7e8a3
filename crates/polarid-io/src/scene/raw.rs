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
    pub(super) sensor: Option<RawSensor>,
    pub(super) exposure: Option<RawExposure>,
    pub(super) capture: Option<RawCapture>,
    #[serde(default)]
    pub(super) plate: Vec<RawPlate>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSensor {
    pub(super) bit_depth: Option<Spanned<i64>>,
    pub(super) full_well_e: Option<Spanned<f64>>,
    pub(super) read_noise_e: Option<Spanned<f64>>,
    pub(super) dark_level_dn: Option<Spanned<f64>>,
    pub(super) shot_noise: Option<Spanned<bool>>,
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
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPlate {
    pub(super) name: Option<Spanned<String>>,
    pub(super) class: Option<Spanned<String>>,
    pub(super) n: Option<Spanned<f64>>,
    pub(super) k: Option<Spanned<f64>>,
    pub(super) sigma: Option<Spanned<f64>>,
    pub(super) rho_d: Option<Spanned<f64>>,
    pub(super) rect: Option<Spanned<Vec<i64>>>,
    pub(super) region: Option<Spanned<Vec<i64>>>,
}
