//! Calibrated geometry tables of a manifest parse into `CameraSpec`, `PlaneSpec`,
//! `SiteSpec` and `SourceSpec`, convert to the core types, and leave far-field manifests
//! as they were.

use polarid_core::geometry::Source;
use polarid_io::manifest::{self, CameraOrientation, SourceSpec};

const TEXT: &str = r#"
[camera]
focal_px = 1350
principal_point_px = [239.5, 179.5]
distortion = [-0.1, 0.02, 0.0, 0.0]
position = [0.459, 0.0, 0.655]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]

[[plane]]
name = "bench"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 2.0]

[[plane]]
name = "riser"
point = [0.0, 0.0, 0.05]
normal = [0.1, 0.0, 1.0]

[site]
latitude_deg = 39.742476
longitude_deg = -105.1786
elevation_m = 1830.14

[[region]]
name = "A"
rect = [200, 150, 40, 40]

[[region]]
name = "B"
rect = [260, 150, 20, 20]
plane = "riser"

[[capture]]
source = { position = [-0.35, 0.0, 0.606] }
stokes = { s0 = "s.tif", s1 = "s.tif", s2 = "s.tif" }

[[capture]]
source = { direction = [-1.0, 0.0, 1.0] }
stokes = { s0 = "s.tif", s1 = "s.tif", s2 = "s.tif" }

[[capture]]
source = { sun = "2003-10-17T12:30:30-07:00" }
stokes = { s0 = "s.tif", s1 = "s.tif", s2 = "s.tif" }
"#;

#[test]
fn calibrated_tables_parse_and_convert() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("s.tif"), b"x").unwrap();
    let m = manifest::parse(&d.path().join("m.toml"), TEXT).unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let cam = m.camera.as_ref().unwrap();
    assert_eq!(cam.focal_px, [1350.0, 1350.0]);
    assert_eq!(cam.distortion, [-0.1, 0.02, 0.0, 0.0, 0.0]);
    assert!(matches!(cam.orientation, CameraOrientation::LookAt { .. }));
    assert_eq!(cam.to_camera().position(), [0.459, 0.0, 0.655]);
    assert_eq!(m.planes.len(), 2);
    assert_eq!(m.planes[1].name, "riser");
    assert_eq!(m.planes[0].to_plane().unwrap().normal(), [0.0, 0.0, 1.0]);
    assert_eq!((m.regions[0].plane, m.regions[1].plane), (0, 1));
    let site = m.site.as_ref().unwrap();
    assert_eq!(site.pressure_mbar, 1013.25);
    assert_eq!(site.temperature_c, 10.0);
    assert_eq!(site.elevation_m, 1830.14);
    let s: Vec<_> = m.captures.iter().map(|c| c.illumination.clone()).collect();
    assert_eq!(s[0], Some(SourceSpec::Position([-0.35, 0.0, 0.606])));
    let h = 0.5f64.sqrt();
    let Some(SourceSpec::Direction(dir)) = s[1] else {
        panic!("{:?}", s[1]);
    };
    assert!((dir[0] + h).abs() < 1e-15 && dir[1] == 0.0 && (dir[2] - h).abs() < 1e-15);
    assert_eq!(
        s[2],
        Some(SourceSpec::Sun("2003-10-17T12:30:30-07:00".into()))
    );
    assert_eq!(
        s[0].as_ref().unwrap().to_source(),
        Some(Source::Position([-0.35, 0.0, 0.606]))
    );
    assert_eq!(s[2].as_ref().unwrap().to_source(), None);
    assert!(m.captures.iter().all(|c| c.theta_i_deg.is_nan()));
}

#[test]
fn far_field_manifests_get_the_default_plane_and_no_calibration() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("s.tif"), b"x").unwrap();
    let text = "theta_r_deg = 60\n[[region]]\nname = \"A\"\nrect = [0, 0, 4, 4]\n\
                [[capture]]\ntheta_i_deg = 35\nstokes = { s0 = \"s.tif\", s1 = \"s.tif\", s2 = \"s.tif\" }\n";
    let m = manifest::parse(&d.path().join("m.toml"), text).unwrap();
    assert!(m.camera.is_none() && m.site.is_none());
    assert_eq!(m.planes.len(), 1);
    assert_eq!(m.planes[0].name, "default");
    assert_eq!(m.regions[0].plane, 0);
    assert_eq!(m.captures[0].illumination, None);
    assert_eq!(m.captures[0].theta_i_deg, 35.0);
}

#[test]
fn rotation_form_and_site_ranges() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("s.tif"), b"x").unwrap();
    // Looking straight down from 1 m: x east = columns, rows towards -y.
    let base = "[camera]\nfocal_px = [100, 100]\nprincipal_point_px = [10, 10]\n\
                position = [0, 0, 1]\nrotation = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]\n\
                [[region]]\nname = \"A\"\nrect = [0, 0, 20, 20]\n\
                [[capture]]\nsource = { direction = [0, 0, 1] }\n\
                stokes = { s0 = \"s.tif\", s1 = \"s.tif\", s2 = \"s.tif\" }\n";
    let m = manifest::parse(&d.path().join("m.toml"), base).unwrap();
    assert!(matches!(
        m.camera.unwrap().orientation,
        CameraOrientation::Rotation(_)
    ));
    let bad = format!("{base}[site]\nlatitude_deg = 95\nlongitude_deg = 0\n");
    let e = manifest::parse(&d.path().join("m.toml"), &bad)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("field `site.latitude_deg`") && e.contains("95"),
        "{e}"
    );
    let missing = format!("{base}[site]\nlatitude_deg = 45\n");
    let e = manifest::parse(&d.path().join("m.toml"), &missing)
        .unwrap_err()
        .to_string();
    assert!(e.contains("field `site.longitude_deg`"), "{e}");
}
