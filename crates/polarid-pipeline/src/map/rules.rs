//! Pixel rules from user options: the dark level and saturation checks shared by
//! `polarid stokes`, the Python bindings and the map's dark threshold.

use polarid_core::stokes::PixelRules;

use crate::error::{Result, ensure};

/// Check a dark level (DN, finite and `>= 0`) and an optional saturation level (finite
/// and above the dark level). Errors are [`crate::PipelineError::Config`] naming
/// `--dark-level` or `--saturation` (the Python bindings show them as `dark_level`,
/// `saturation`).
pub fn check_levels(dark_level: f64, saturation: Option<f64>) -> Result<()> {
    ensure(
        (0.0..=f32::MAX as f64).contains(&dark_level),
        "--dark-level",
        dark_level,
        "must be a finite number >= 0 within the float32 range",
    )?;
    let Some(s) = saturation else { return Ok(()) };
    let ok = s.is_finite() && s > dark_level && s <= f32::MAX as f64;
    ensure(
        ok,
        "--saturation",
        s,
        "must be a finite number above the dark level",
    )
}

/// The map's dark threshold (DN) for a capture's frames: `min_s0` when given, else 1 %
/// of the range from the dark level to the saturation level for integer frames, 0 for
/// float frames.
pub fn min_s0_for(rules: &PixelRules, is_integer: bool, min_s0: Option<f64>) -> f32 {
    match min_s0 {
        Some(v) => v as f32,
        None if is_integer && rules.saturation.is_finite() => {
            0.01 * (rules.saturation - rules.dark_level).max(0.0)
        }
        None => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels() {
        assert!(check_levels(0.0, None).is_ok());
        assert!(check_levels(10.0, Some(4095.0)).is_ok());
        let e = check_levels(-1.0, None).unwrap_err();
        assert!(e.to_string().contains("--dark-level"), "{e}");
        let e = check_levels(10.0, Some(10.0)).unwrap_err();
        assert!(e.to_string().contains("--saturation"), "{e}");
        assert!(check_levels(f64::NAN, None).is_err());
    }

    #[test]
    fn default_dark_threshold() {
        let r = PixelRules {
            dark_level: 32.0,
            saturation: 4095.0,
            min_s0: 0.0,
        };
        assert_eq!(min_s0_for(&r, true, Some(5.0)), 5.0);
        assert!((min_s0_for(&r, true, None) - 40.63).abs() < 1e-3);
        assert_eq!(min_s0_for(&r, false, None), 0.0);
    }
}
