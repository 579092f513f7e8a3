//! Pixel mask values written by the Stokes kernels (one byte per pixel).

/// The pixel is usable.
pub const VALID: u8 = 0;
/// A raw value reached the saturation level.
pub const SATURATED: u8 = 1;
/// The dark-subtracted `S0` is at or below the dark threshold.
pub const DARK: u8 = 2;
/// A raw value (or a Stokes component) is NaN or infinite.
pub const INVALID: u8 = 3;
