//! Validation of one pixel's measurements (DoLP in `[0, 1]`, positive finite standard
//! errors) and the reason reported for a pixel that fails it.

use crate::error::{CoreError, Result};

/// Reason a pixel's data cannot be fitted.
pub(super) fn check_pixel(dolp: &[f64], dolp_se: Option<&[f64]>) -> Result<()> {
    // Fast path: every value in [0, 1] (NaN fails both comparisons), no branches.
    let in_range = dolp
        .iter()
        .fold(true, |ok, &v| ok & (0.0..=1.0).contains(&v));
    if in_range && dolp_se.is_none() {
        return Ok(());
    }
    for &v in dolp {
        crate::error::ensure_range("dolp", v, 0.0, 1.0, "[0, 1]")?;
    }
    if let Some(se) = dolp_se {
        for &s in se {
            crate::error::ensure_finite("dolp_se", s)?;
            if !(s > 0.0) {
                return Err(CoreError::OutOfRange {
                    name: "dolp_se",
                    value: s,
                    expected: "> 0",
                });
            }
        }
    }
    Ok(())
}

/// The [`super::NkFit::reason`] of a pixel rejected by [`check_pixel`] with `e`.
pub(super) fn invalid_reason(e: &CoreError) -> &'static str {
    match e {
        CoreError::NonFinite { name: "dolp", .. } => "non-finite DoLP",
        CoreError::OutOfRange { name: "dolp", .. } => "DoLP outside [0, 1]",
        _ => "non-finite or non-positive DoLP standard error",
    }
}
