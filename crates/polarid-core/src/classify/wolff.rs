//! Wolff's metal/dielectric baseline: the polarization Fresnel ratio
//!
//! ```text
//! FR = Rs/Rp = (1 + P)/(1 − P),      P = (Rs − Rp)/(Rs + Rp)
//! ```
//!
//! is large near Brewster's angle for a dielectric and of order 1 for a metal; the
//! target is a dielectric when the largest `FR` over the measurements in a β window
//! exceeds a threshold (default 6 over β ∈ [40°, 70°]: see [`WolffConfig`]).
//!
//! # Reference
//! L. B. Wolff, "Polarization-based material classification from specular reflection",
//! IEEE PAMI 12(11), 1990 (the paper's ref. \[1\]); β is the paper's eq. (5).

use super::UNKNOWN;
use crate::error::{CoreError, Result};

/// Wolff's two classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WolffClass {
    /// Small Fresnel ratio at every measured angle.
    Metal,
    /// Large Fresnel ratio near Brewster's angle.
    Dielectric,
    /// No measurement in the angle window.
    Unknown,
}

impl WolffClass {
    /// `metal`, `dielectric` or `unknown`.
    pub fn name(self) -> &'static str {
        match self {
            WolffClass::Metal => "metal",
            WolffClass::Dielectric => "dielectric",
            WolffClass::Unknown => UNKNOWN,
        }
    }
}

/// Settings of Wolff's rule (angles in radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WolffConfig {
    /// Fresnel-ratio threshold: `FR_max > threshold` → dielectric.
    pub threshold: f64,
    /// Smallest specular angle β used.
    pub beta_min: f64,
    /// Largest specular angle β used.
    pub beta_max: f64,
}

impl Default for WolffConfig {
    /// Threshold 6, β window 40°–70°.
    ///
    /// Why: over β ∈ [40°, 70°] the Fresnel ratio of every metal of the built-in library
    /// stays below 4.8 (tungsten reaches 4.76 at 70°, iron 3.9, aluminum 1.26, copper
    /// 1.13), while every dielectric of the library (n from 1.31 to 2.58) has its Brewster
    /// angle (52°–69°) inside the window, where its ratio exceeds 20 for measurements
    /// within a few degrees of it. 6 (`P = 5/7 ≈ 0.714`) sits between the two with room
    /// for depolarization, which lowers a dielectric's ratio.
    fn default() -> Self {
        Self {
            threshold: 6.0,
            beta_min: 40f64.to_radians(),
            beta_max: 70f64.to_radians(),
        }
    }
}

/// One DoLP measurement for Wolff's rule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WolffObservation {
    /// Specular (half-) angle β, radians (eq. 5).
    pub beta: f64,
    /// Measured degree of linear polarization, in `[0, 1]`.
    pub dolp: f64,
}

/// Wolff's decision for one target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WolffDecision {
    /// Metal, dielectric or unknown.
    pub class: WolffClass,
    /// Largest Fresnel ratio over the measurements in the window (NaN when none;
    /// infinite for `P = 1`).
    pub fr_max: f64,
    /// β (radians) of that measurement (NaN when none).
    pub beta_at_max: f64,
    /// Measurements in the window.
    pub used: usize,
}

/// The polarization Fresnel ratio `FR = Rs/Rp = (1 + P)/(1 − P)` from the degree of
/// polarization of unpolarized light specularly reflected (`P = (Rs − Rp)/(Rs + Rp)`).
/// Infinite for `P = 1`.
#[inline]
pub fn fresnel_ratio(dolp: f64) -> f64 {
    (1.0 + dolp) / (1.0 - dolp)
}

/// Wolff's threshold rule: among the measurements whose β lies in
/// `[beta_min, beta_max]`, take the largest Fresnel ratio `FR_max`; the target is a
/// dielectric when `FR_max > threshold`, a metal otherwise, and unknown when no
/// measurement falls in the window.
///
/// Fails when a DoLP is outside `[0, 1]` or an angle is not finite, or the settings are
/// invalid (threshold ≤ 1, empty window).
pub fn wolff_classify(obs: &[WolffObservation], cfg: &WolffConfig) -> Result<WolffDecision> {
    if !(cfg.threshold > 1.0 && cfg.threshold.is_finite()) {
        return Err(CoreError::OutOfRange {
            name: "Fresnel-ratio threshold",
            value: cfg.threshold,
            expected: "finite and > 1",
        });
    }
    if !(cfg.beta_min <= cfg.beta_max && cfg.beta_min.is_finite() && cfg.beta_max.is_finite()) {
        return Err(CoreError::OutOfRange {
            name: "Wolff beta window minimum (radians)",
            value: cfg.beta_min,
            expected: "<= the window maximum",
        });
    }
    let mut fr_max = f64::NAN;
    let mut beta_at_max = f64::NAN;
    let mut used = 0;
    for o in obs {
        crate::error::ensure_finite("beta", o.beta)?;
        crate::error::ensure_range("dolp", o.dolp, 0.0, 1.0, "in [0, 1]")?;
        if o.beta < cfg.beta_min || o.beta > cfg.beta_max {
            continue;
        }
        used += 1;
        let fr = fresnel_ratio(o.dolp);
        if fr_max.is_nan() || fr > fr_max {
            fr_max = fr;
            beta_at_max = o.beta;
        }
    }
    let class = if used == 0 {
        WolffClass::Unknown
    } else if fr_max > cfg.threshold {
        WolffClass::Dielectric
    } else {
        WolffClass::Metal
    };
    Ok(WolffDecision {
        class,
        fr_max,
        beta_at_max,
        used,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wolff_fresnel_ratio_rule() {
        use crate::dop::dop;
        let cfg = WolffConfig::default();
        let betas: Vec<f64> = (0..=9)
            .map(|i| (47.5 + 2.5 * i as f64).to_radians())
            .collect();
        let obs = |n: f64, k: f64| -> Vec<WolffObservation> {
            betas
                .iter()
                .map(|&b| WolffObservation {
                    beta: b,
                    dolp: dop(n, k, b),
                })
                .collect()
        };
        // Paper's estimates: aluminum, copper are metals, green paint a dielectric.
        assert_eq!(
            wolff_classify(&obs(1.64, 4.56), &cfg).unwrap().class,
            WolffClass::Metal
        );
        assert_eq!(
            wolff_classify(&obs(0.54, 3.19), &cfg).unwrap().class,
            WolffClass::Metal
        );
        let g = wolff_classify(&obs(1.47, 0.47), &cfg).unwrap();
        assert_eq!(g.class, WolffClass::Dielectric);
        assert!(g.fr_max > 15.0, "{}", g.fr_max);
        // FR = Rs/Rp.
        assert!((fresnel_ratio(0.5) - 3.0).abs() < 1e-15);
        // Nothing in the window.
        let none = wolff_classify(
            &[WolffObservation {
                beta: 0.1,
                dolp: 0.1,
            }],
            &cfg,
        )
        .unwrap();
        assert_eq!(none.class, WolffClass::Unknown);
        assert!(
            wolff_classify(
                &[WolffObservation {
                    beta: 1.0,
                    dolp: 1.5
                }],
                &cfg
            )
            .is_err()
        );
    }
}
