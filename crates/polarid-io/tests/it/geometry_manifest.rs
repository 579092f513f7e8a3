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
    let Some(SourceSpec::Sun {
        time, direction, ..
    }) = &s[2]
    else {
        panic!("{:?}", s[2]);
    };
    assert_eq!(time, "2003-10-17T12:30:30-07:00");
    assert_eq!(
        s[0].as_ref().unwrap().to_source(),
        Some(Source::Position([-0.35, 0.0, 0.606]))
    );
    // The sun is resolved at load time (it used to be left to the caller: `None`).
    assert_eq!(
        s[2].as_ref().unwrap().to_source(),
        Some(Source::Direction(*direction))
    );
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

/// A manifest with the SPA report's site (NREL/TP-560-34302, table A4.1) and one sun
/// capture at `time`.
fn sun_manifest(time: &str) -> String {
    format!(
        "[camera]\nfocal_px = [100, 100]\nprincipal_point_px = [10, 10]\n\
         position = [0, 0, 1]\nrotation = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]\n\
         [site]\nlatitude_deg = 39.742476\nlongitude_deg = -105.1786\n\
         elevation_m = 1830.14\npressure_mbar = 820\ntemperature_c = 11\n\
         [[region]]\nname = \"A\"\nrect = [0, 0, 20, 20]\n\
         [[capture]]\nsource = {{ sun = \"{time}\" }}\n\
         stokes = {{ s0 = \"s.tif\", s1 = \"s.tif\", s2 = \"s.tif\" }}\n"
    )
}

#[test]
fn sun_source_resolves_to_the_spa_reports_direction() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("s.tif"), b"x").unwrap();
    let m = manifest::parse(
        &d.path().join("m.toml"),
        &sun_manifest("2003-10-17T12:30:30-07:00"),
    )
    .unwrap();
    let Some(SourceSpec::Sun {
        time,
        unix_seconds,
        zenith_deg,
        azimuth_deg,
        direction,
    }) = m.captures[0].illumination.clone()
    else {
        panic!("{:?}", m.captures[0].illumination);
    };
    assert_eq!(time, "2003-10-17T12:30:30-07:00");
    assert_eq!(unix_seconds, 1_066_419_030.0);
    assert!((zenith_deg - 50.1116).abs() < 1e-3, "zenith {zenith_deg}");
    assert!(
        (azimuth_deg - 194.340).abs() < 1e-3,
        "azimuth {azimuth_deg}"
    );
    // From the direction itself: zenith = acos z, azimuth = atan2(x, y) from north eastward.
    let z = direction[2].acos().to_degrees();
    let az = direction[0]
        .atan2(direction[1])
        .to_degrees()
        .rem_euclid(360.0);
    assert!((z - 50.1116).abs() < 1e-3, "zenith from direction {z}");
    assert!((az - 194.340).abs() < 1e-3, "azimuth from direction {az}");
    let (sz, cz) = zenith_deg.to_radians().sin_cos();
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    for (a, b) in direction.iter().zip([sz * sa, sz * ca, cz]) {
        assert!((a - b).abs() < 1e-12, "{direction:?}");
    }
    assert_eq!(
        m.captures[0].illumination.as_ref().unwrap().to_source(),
        Some(Source::Direction(direction))
    );
}

#[test]
fn sun_at_night_and_bad_times_are_refused() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("s.tif"), b"x").unwrap();
    let path = d.path().join("m.toml");
    let night = "2003-10-17T23:30:30-07:00";
    let e = manifest::parse(&path, &sun_manifest(night))
        .unwrap_err()
        .to_string();
    assert!(e.contains("field `capture[1].source.sun`"), "{e}");
    assert!(e.contains(night) && e.contains("below the horizon"), "{e}");
    assert!(e.contains("elevation -"), "{e}");
    assert!(e.contains("line 16"), "{e}");
    for bad in ["2003-10-17 12:30:30", "2003-13-17T12:30:30Z", "yesterday"] {
        let e = manifest::parse(&path, &sun_manifest(bad))
            .unwrap_err()
            .to_string();
        assert!(e.contains("field `capture[1].source.sun`"), "{bad}: {e}");
        assert!(e.contains(bad), "{bad}: {e}");
        assert!(e.contains("line 16"), "{bad}: {e}");
    }
}
