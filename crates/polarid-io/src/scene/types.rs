//! The validated scene: frame, camera and source geometry, sensor, exposure, capture
//! kind and plates.

use std::path::PathBuf;

use polarid_core::mosaic::Pattern;
use polarid_core::region::Rect;
use polarid_core::simulate::{Exposure, PlateOptics, Sensor};

/// Largest frame side accepted, pixels.
pub const MAX_SIDE: usize = 16384;

/// Image file format of the simulated frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// PNG (`.png`).
    Png,
    /// TIFF (`.tif`).
    Tiff,
}

impl ImageFormat {
    /// File extension without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Tiff => "tif",
        }
    }
}

/// What each capture records.
#[derive(Debug, Clone, PartialEq)]
pub enum CaptureKind {
    /// A rotating polarizer: one frame per angle (degrees), at least 3 distinct angles.
    Frames {
        /// Polarizer angles, degrees.
        angles_deg: Vec<f64>,
    },
    /// A division-of-focal-plane raw mosaic with a 2×2 pattern.
    Dofp {
        /// The pattern, row by row from the top-left.
        pattern: Pattern,
    },
}

impl CaptureKind {
    /// Every polarizer angle a capture uses, degrees.
    pub fn angles_deg(&self) -> Vec<f64> {
        match self {
            CaptureKind::Frames { angles_deg } => angles_deg.clone(),
            CaptureKind::Dofp { pattern } => pattern.angles_deg().to_vec(),
        }
    }
}

/// One plate of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Plate {
    /// Unique name (the manifest's region and the target of the measurements).
    pub name: String,
    /// Material class, if given.
    pub class: Option<String>,
    /// Index, roughness and diffuse albedo.
    pub optics: PlateOptics,
    /// The plate's rectangle in the frame.
    pub rect: Rect,
    /// The measured region (inside `rect`).
    pub region: Rect,
    /// Line of the plate's `name` in the scene file.
    pub line: usize,
}

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The scene file.
    pub path: PathBuf,
    /// The scene's text as read (copied next to the outputs).
    pub text: String,
    /// Optional label.
    pub name: Option<String>,
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Camera zenith, degrees.
    pub theta_r_deg: f64,
    /// `phi_r − phi_i`, degrees.
    pub phi_deg: f64,
    /// Source zeniths, degrees, one capture each (in order).
    pub theta_i_deg: Vec<f64>,
    /// Informational wavelength, nm.
    pub wavelength_nm: Option<f64>,
    /// Unpolarized background radiance (same units as the plates' radiance).
    pub background: f64,
    /// Noise seed.
    pub seed: u64,
    /// Output image format.
    pub format: ImageFormat,
    /// The sensor.
    pub sensor: Sensor,
    /// How each capture is exposed.
    pub exposure: Exposure,
    /// What each capture records.
    pub capture: CaptureKind,
    /// The plates, in file order.
    pub plates: Vec<Plate>,
}
