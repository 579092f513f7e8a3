//! The validated scene: frame, camera and source geometry (far field, or calibrated),
//! sensor, exposure, capture kind and plates.

use std::path::PathBuf;

use polarid_core::geometry::Source;
use polarid_core::mosaic::{ColourPattern, Pattern};
use polarid_core::region::Rect;
use polarid_core::simulate::{Exposure, Light, PlateOptics, Sensor};

use crate::manifest::{CameraSpec, PlaneSpec, SiteSpec, SourceSpec};

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
    /// A colour polarization raw mosaic (`[capture] color = "RGGB"`; docs/SCENE.md): a
    /// 2×2 polarizer block under each colour of a 2×2 colour pattern of blocks.
    ColourDofp {
        /// The polarizer block and the colours of the 4×4 period.
        pattern: ColourPattern,
        /// The bands, in the order of [`ColourPattern::bands`].
        bands: Vec<SceneBand>,
    },
}

impl CaptureKind {
    /// Every polarizer angle a capture uses, degrees.
    pub fn angles_deg(&self) -> Vec<f64> {
        match self {
            CaptureKind::Frames { angles_deg } => angles_deg.clone(),
            CaptureKind::Dofp { pattern } => pattern.angles_deg().to_vec(),
            CaptureKind::ColourDofp { pattern, .. } => pattern.polar().angles_deg().to_vec(),
        }
    }

    /// The bands of a colour capture (`None` for single-band captures).
    pub fn bands(&self) -> Option<&[SceneBand]> {
        match self {
            CaptureKind::ColourDofp { bands, .. } => Some(bands),
            _ => None,
        }
    }
}

/// One band (colour) of a colour polarization scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneBand {
    /// The colour letter (upper case), as in the capture's `color`.
    pub letter: char,
    /// The band's wavelength, nm (`bands`, default R 650, G 550, B 450).
    pub wavelength_nm: f64,
    /// Relative response of the band (`[sensor] band_response`, default 1): the
    /// expected electrons of the band's pixels are scaled by it (filter transmission ×
    /// quantum efficiency × the source's spectrum).
    pub response: f64,
}

/// Where a plate of a calibrated scene lies (scene frame, scene length units).
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// Index into [`Calibrated::planes`] of the plane it lies on.
    pub plane: usize,
    /// Its centre, on the plane.
    pub center: [f64; 3],
    /// The direction of its width, in the plane (unit vector); the height runs along
    /// `normal × axis`.
    pub axis: [f64; 3],
    /// Width and height.
    pub size: [f64; 2],
}

/// One light source of a calibrated scene: one capture.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSource {
    /// Where the light is (as the manifest writes it: `position`, `direction`, `sun`).
    pub spec: SourceSpec,
    /// A lamp's radiant intensity, or a distant source's irradiance (default 1).
    pub intensity: f64,
    /// Optional capture name (its directory and the manifest's capture `name`).
    pub name: Option<String>,
    /// 1-based line of the source in the scene file.
    pub line: usize,
}

impl SceneSource {
    /// The core light: a `sun` is a distant source towards the sun.
    pub fn light(&self) -> Light {
        let source = match &self.spec {
            SourceSpec::Position(p) => Source::Position(*p),
            SourceSpec::Direction(d) => Source::Direction(*d),
            SourceSpec::Sun { direction, .. } => Source::Direction(*direction),
        };
        Light {
            source,
            power: self.intensity,
        }
    }
}

/// The calibrated geometry of a scene: a pinhole camera, planes, an optional site and
/// the light sources (one capture each).
#[derive(Debug, Clone, PartialEq)]
pub struct Calibrated {
    /// The camera (`[camera]`, as in a manifest).
    pub camera: CameraSpec,
    /// The planes (`[[plane]]`; the default plane when none is given).
    pub planes: Vec<PlaneSpec>,
    /// The site (`[site]`), needed by `sun` sources.
    pub site: Option<SiteSpec>,
    /// The light sources, one capture each, in order.
    pub sources: Vec<SceneSource>,
}

/// How the scene's geometry is given.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// The paper's far field: one camera zenith, one azimuth difference, and a list of
    /// source zeniths, the same for every pixel.
    FarField {
        /// Camera zenith, degrees.
        theta_r_deg: f64,
        /// `phi_r − phi_i`, degrees (180: in the plane of incidence).
        phi_deg: f64,
        /// Source zeniths, degrees, one capture each (in order).
        theta_i_deg: Vec<f64>,
    },
    /// A calibrated camera, plates on planes, and lamps or distant sources.
    Calibrated(Box<Calibrated>),
}

/// One plate of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Plate {
    /// Unique name (the manifest's region and the target of the measurements).
    pub name: String,
    /// Material class, if given.
    pub class: Option<String>,
    /// Index, roughness and diffuse albedo (a colour scene: those of its first band,
    /// `bands[0]`).
    pub optics: PlateOptics,
    /// A colour scene's optics per band, in the order of the capture's bands
    /// ([`CaptureKind::bands`]); empty in single-band scenes.
    pub bands: Vec<PlateOptics>,
    /// The library material the index was taken from (`material`), if any.
    pub material: Option<String>,
    /// The plate's rectangle in the frame (calibrated scenes: the bounding box of the
    /// pixels that see it).
    pub rect: Rect,
    /// The measured region (inside `rect`; calibrated scenes: every pixel of it sees the
    /// plate).
    pub region: Rect,
    /// Where the plate lies (calibrated scenes only).
    pub placement: Option<Placement>,
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
    /// The camera and source geometry.
    pub geometry: Geometry,
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

impl Scene {
    /// Number of captures (source positions).
    pub fn captures(&self) -> usize {
        match &self.geometry {
            Geometry::FarField { theta_i_deg, .. } => theta_i_deg.len(),
            Geometry::Calibrated(c) => c.sources.len(),
        }
    }

    /// The calibrated geometry, if the scene has one.
    pub fn calibrated(&self) -> Option<&Calibrated> {
        match &self.geometry {
            Geometry::Calibrated(c) => Some(c),
            Geometry::FarField { .. } => None,
        }
    }
}
