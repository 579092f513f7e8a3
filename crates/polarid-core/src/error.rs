//! Errors of the core crate.

use thiserror::Error;

/// Everything that can go wrong in the pure core (bad arguments, unusable data).
///
/// Every variant carries the offending value so that callers (CLI, Python) can print a
/// message that names it.
#[non_exhaustive]
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    /// A value that must be finite is NaN or infinite.
    #[error("{name} must be finite, got {value}")]
    NonFinite {
        /// Name of the quantity.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A value lies outside its valid range.
    #[error("{name} = {value} is out of range (expected {expected})")]
    OutOfRange {
        /// Name of the quantity.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// Human-readable description of the valid range.
        expected: &'static str,
    },
    /// A caller-owned buffer or input slice has the wrong length.
    #[error("{name} has length {got}, expected {expected}")]
    LengthMismatch {
        /// Name of the buffer.
        name: &'static str,
        /// Required length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// Not enough items (measurements, frames, prototypes ...).
    #[error("need at least {needed} {what}, got {got}")]
    TooFew {
        /// What is counted.
        what: &'static str,
        /// Minimum required.
        needed: usize,
        /// Number given.
        got: usize,
    },
    /// A set of polarizer angles from which S0, S1, S2 cannot be recovered.
    #[error("polarizer angles {angles_deg:?} (degrees) are singular: {reason}")]
    SingularAngles {
        /// The angles, in degrees.
        angles_deg: Vec<f64>,
        /// Why the set is singular.
        reason: String,
    },
    /// A division-of-focal-plane pattern that is not a permutation of four distinct angles.
    #[error("invalid 2x2 polarizer pattern {pattern_deg:?}: {reason}")]
    InvalidPattern {
        /// The pattern, row by row, in degrees.
        pattern_deg: Vec<f64>,
        /// Why it is invalid.
        reason: String,
    },
    /// Image dimensions that cannot be used (odd mosaic, zero size, mismatch).
    #[error("image of {width}x{height} pixels cannot be used: {reason}")]
    InvalidDimensions {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// Why.
        reason: String,
    },
    /// A region (x, y, width, height) that is empty or leaves the frame.
    #[error("region [{x}, {y}, {width}, {height}] {reason}")]
    InvalidRegion {
        /// Column of the top-left corner.
        x: usize,
        /// Row of the top-left corner.
        y: usize,
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Why it is invalid.
        reason: String,
    },
    /// A named item (class, target ...) is unknown or duplicated.
    #[error("{what} {name:?}: {reason}")]
    InvalidName {
        /// What kind of item.
        what: &'static str,
        /// The offending name.
        name: String,
        /// Why.
        reason: String,
    },
    /// The solar-position algorithm refused its (already validated) inputs or gave a
    /// non-finite result; `reason` is its message.
    #[error("solar position at unix time {unix_seconds} s: {reason}")]
    SolarPosition {
        /// The time, in seconds since 1970-01-01T00:00:00Z.
        unix_seconds: f64,
        /// The algorithm's message.
        reason: String,
    },
}

/// Result alias of the core crate.
pub type Result<T> = std::result::Result<T, CoreError>;

/// Check that `value` is finite.
#[inline]
pub fn ensure_finite(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(CoreError::NonFinite { name, value })
    }
}

/// Check that `value` lies in `[lo, hi]` (and is finite).
#[inline]
pub fn ensure_range(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    expected: &'static str,
) -> Result<f64> {
    ensure_finite(name, value)?;
    if value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(CoreError::OutOfRange {
            name,
            value,
            expected,
        })
    }
}
