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
    // --- Calibrated geometry (camera, planes, sources): `geometry::camera` and
    // `geometry::scene_geometry`. Keep these variants together.
    /// A vector that must be finite and of non-zero length is not.
    #[error("{name} = {value:?} must be a finite vector of non-zero length")]
    InvalidVector {
        /// Name of the vector.
        name: &'static str,
        /// The offending vector.
        value: [f64; 3],
    },
    /// A focal length that is not finite and positive.
    #[error("focal length (fx, fy) = ({fx}, {fy}) pixels must be finite and > 0")]
    InvalidFocalLength {
        /// Focal length along columns, pixels.
        fx: f64,
        /// Focal length along rows, pixels.
        fy: f64,
    },
    /// A camera orientation from `look_at` and `up` that does not define a rotation.
    #[error("camera at {position:?} looking at {look_at:?} with up {up:?}: {reason}")]
    DegenerateLookAt {
        /// Camera position.
        position: [f64; 3],
        /// Point looked at.
        look_at: [f64; 3],
        /// Up vector.
        up: [f64; 3],
        /// Why (coincident points, up parallel to the viewing direction).
        reason: &'static str,
    },
    /// A camera rotation matrix that is not a proper rotation.
    #[error("rotation {rows:?} is not a rotation matrix: {reason}")]
    NotARotation {
        /// The matrix, row by row.
        rows: [[f64; 3]; 3],
        /// Why (not orthonormal within 1e-6, determinant not +1), with the deviation.
        reason: String,
    },
    /// The camera is not on the side of a plane that its normal points to.
    #[error(
        "camera at {position:?} is not in front of the plane (height {height} along the normal; must be > 0)"
    )]
    CameraBehindPlane {
        /// Camera position.
        position: [f64; 3],
        /// Signed distance of the camera from the plane along its normal.
        height: f64,
    },
    /// The ray of a pixel does not meet its plane in front of the camera.
    #[error(
        "the ray of pixel ({u}, {v}) does not meet the plane in front of the camera \
         (cosine between ray and normal {cos_normal}; must be < 0)"
    )]
    RayMissesPlane {
        /// Column of the pixel.
        u: f64,
        /// Row of the pixel.
        v: f64,
        /// Cosine between the ray direction and the plane's normal (`>= 0`: the ray is
        /// parallel to the plane or leaves it).
        cos_normal: f64,
    },
    /// The source is on or below the horizon of the plane at a pixel's hit point.
    #[error(
        "the source is below the horizon of the plane at pixel ({u}, {v}) \
         (incidence angle {theta_i_deg} degrees; must be < 90)"
    )]
    SourceBelowHorizon {
        /// Column of the pixel.
        u: f64,
        /// Row of the pixel.
        v: f64,
        /// Source zenith angle about the plane's normal, degrees.
        theta_i_deg: f64,
    },
    /// The distortion model cannot be inverted at a pixel (outside its valid field).
    #[error(
        "lens distortion cannot be inverted at pixel ({u}, {v}) (residual {residual_px} pixels)"
    )]
    UndistortFailed {
        /// Column of the pixel.
        u: f64,
        /// Row of the pixel.
        v: f64,
        /// Remaining error of the inverse, pixels.
        residual_px: f64,
    },
    // --- end of calibrated geometry variants.
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

/// `got == expected`, or [`CoreError::LengthMismatch`] naming `name`.
#[inline]
pub(crate) fn check_len(name: &'static str, got: usize, expected: usize) -> Result<()> {
    if got != expected {
        return Err(CoreError::LengthMismatch {
            name,
            expected,
            got,
        });
    }
    Ok(())
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
