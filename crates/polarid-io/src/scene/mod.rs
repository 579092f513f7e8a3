//! The scene file (TOML) of `polarid simulate`: plates of known optics in one frame, a
//! fixed camera, the source at several zenith angles, a sensor and how it is exposed.
//! `docs/SCENE.md` documents every key; `examples/scenes/` holds commented examples.
//!
//! ```toml
//! name = "training_60"          # optional label
//! width = 256                   # frame size, pixels
//! height = 128
//! theta_r_deg = 60.0            # camera zenith
//! phi_deg = 180.0               # phi_r - phi_i (default 180: in the plane of incidence)
//! theta_i_deg = [35, 40, 45]    # source zeniths, one capture each
//!                               # (or { start = 35, stop = 80, step = 5 })
//! wavelength_nm = 650.0         # optional, informational
//! background = 0.0              # unpolarized background radiance (default 0)
//! seed = 1                      # noise seed (default 0)
//! format = "png"                # png | tiff (16-bit, or 8-bit when bit_depth <= 8)
//!
//! [sensor]                      # every key optional
//! bit_depth = 12
//! full_well_e = 10000.0         # electrons at the top of the ADC range (sets the gain)
//! read_noise_e = 2.5
//! dark_level_dn = 64.0
//! shot_noise = true
//!
//! [exposure]                    # default: mode = "auto", fraction = 0.7
//! mode = "auto"                 # brightest plate pixel at `fraction` of full scale
//! fraction = 0.7
//! # mode = "fixed", value = 0.5 # radiance I behind the polarizer -> value * I * full well
//!
//! [capture]                     # default: kind = "frames", angles_deg = [0, 45, 90, 135]
//! kind = "frames"
//! angles_deg = [0, 45, 90, 135]
//! # kind = "dofp", pattern = [90, 45, 135, 0]
//!
//! [[plate]]
//! name = "aluminum"
//! class = "aluminum"            # optional (written to the manifest's region)
//! n = 1.24
//! k = 6.60
//! sigma = 0.2                   # Priest–Meier roughness (slope standard deviation)
//! rho_d = 0.0                   # optional Lambertian depolarized albedo
//! rect = [8, 8, 112, 112]       # x, y, width, height in the frame
//! region = [16, 16, 96, 96]     # optional measured region (default: an inset of rect)
//! ```
//!
//! **Calibrated scenes** (a `[camera]` table instead of the angles; `calibrated`):
//! `[camera]`, `[[plane]]` and `[site]` as in a manifest (read by the manifest's own
//! parser, [`crate::manifest::shared`]), one `[[source]]` per capture (`position`,
//! `direction` or `sun`, optional `intensity` and `name`), and plates placed by
//! `plane`, `center`, `size` and `axis` instead of `rect`; each plate's rectangle and
//! measured region follow from tracing the camera's pixels ([`Geometry::Calibrated`],
//! [`Placement`]).
//!
//! Errors are [`IoError::Manifest`](crate::IoError::Manifest) naming the file, the 1-based line, the dotted field
//! (`plate[2].sigma`; indices 1-based) and the value. Unknown keys are errors (a scene is
//! an input the simulator acts on, so a typo must not silently change the physics).
//!
//! # Layout
//!
//! `types` (the validated [`Scene`] and its parts), `raw` (the TOML as deserialized, with
//! spans), `context` (error construction and value checks that name file, line and field),
//! `top` (the top-level keys and `theta_i_deg`), `camera` (`[sensor]`, `[exposure]`,
//! `[capture]`), `plates` (`[[plate]]` and [`default_region`]), `calibrated` (the
//! calibrated geometry and the placed plates).

mod calibrated;
mod camera;
mod colour;
mod context;
mod plates;
mod raw;
mod top;
mod types;

use std::path::Path;

pub use plates::default_region;
pub use types::{
    Calibrated, CaptureKind, Geometry, ImageFormat, MAX_SIDE, Placement, Plate, Scene, SceneBand,
    SceneSource,
};

use crate::error::Result;
use context::Ctx;

/// Read and validate a scene file.
pub fn load(path: &Path) -> Result<Scene> {
    let text = crate::limits::read_text(path)?;
    parse(path, &text)
}

/// Validate scene `text`; `path` labels errors.
pub fn parse(path: &Path, text: &str) -> Result<Scene> {
    Ctx { path, text }.scene()
}

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_core::region::Rect;
    use polarid_core::simulate::Exposure;

    pub(super) const GOOD: &str = r#"
name = "t"
width = 64
height = 32
theta_r_deg = 60
theta_i_deg = { start = 35, stop = 80, step = 5 }
seed = 3

[sensor]
dark_level_dn = 64

[capture]
kind = "dofp"

[[plate]]
name = "al"
class = "aluminum"
n = 1.24
k = 6.6
sigma = 0.2
rect = [0, 0, 32, 32]

[[plate]]
name = "cu"
n = 0.4
k = 2.95
sigma = 0.15
rect = [32, 0, 32, 32]
region = [36, 4, 20, 20]
"#;

    pub(super) fn parse_err(text: &str) -> String {
        parse(Path::new("s.toml"), text).unwrap_err().to_string()
    }

    #[test]
    fn parses_a_scene_with_defaults() {
        let s = parse(Path::new("s.toml"), GOOD).unwrap();
        assert_eq!((s.width, s.height), (64, 32));
        let Geometry::FarField {
            theta_i_deg,
            phi_deg,
            ..
        } = &s.geometry
        else {
            panic!("far field expected")
        };
        assert_eq!(theta_i_deg.len(), 10);
        assert_eq!(theta_i_deg[9], 80.0);
        assert_eq!(*phi_deg, 180.0);
        assert_eq!(s.exposure, Exposure::Auto { fraction: 0.7 });
        assert_eq!(s.sensor.dark_level_dn, 64.0);
        assert_eq!(s.sensor.bit_depth, 12);
        assert!(matches!(s.capture, CaptureKind::Dofp { .. }));
        // default region: inset 4, even
        assert_eq!(
            s.plates[0].region,
            Rect {
                x: 4,
                y: 4,
                width: 24,
                height: 24
            }
        );
        assert_eq!(s.plates[1].region.x, 36);
        assert_eq!(s.plates[0].class.as_deref(), Some("aluminum"));
        assert_eq!(s.plates[1].line, 24);
    }

    #[test]
    fn errors_name_line_and_field() {
        let e = parse_err(&GOOD.replace("sigma = 0.15", "sigma = -1"));
        assert!(e.contains("line 27") && e.contains("plate[2].sigma"), "{e}");
        let e = parse_err(&GOOD.replace("rect = [32, 0, 32, 32]", "rect = [40, 0, 32, 32]"));
        assert!(e.contains("plate[2].rect") && e.contains("64x32"), "{e}");
        let e = parse_err(&GOOD.replace("rect = [32, 0, 32, 32]", "rect = [16, 0, 16, 16]"));
        assert!(e.contains("overlaps plate \"al\""), "{e}");
        let e = parse_err(&GOOD.replace("seed = 3", "sede = 3"));
        assert!(e.contains("line 7") && e.contains("sede"), "{e}");
        let e = parse_err(&GOOD.replace("kind = \"dofp\"", "kind = \"video\""));
        assert!(e.contains("capture.kind") && e.contains("line 13"), "{e}");
        let e = parse_err(&GOOD.replace("region = [36, 4, 20, 20]", "region = [30, 4, 20, 20]"));
        assert!(e.contains("plate[2].region") && e.contains("inside"), "{e}");
        let e = parse_err(&GOOD.replace("theta_r_deg = 60", "theta_r_deg = 95"));
        assert!(e.contains("line 5") && e.contains("theta_r_deg"), "{e}");
        let e = parse_err(&GOOD.replace("k = 6.6", "k = \"big\""));
        assert!(e.contains("line 19") && e.contains("plate[1].k"), "{e}");
        let e = parse_err(&GOOD.replace("dark_level_dn = 64", "dark_level_dn = 5000"));
        assert!(e.contains("sensor.dark_level_dn"), "{e}");
    }
}
