//! The scene parser of `polarid simulate` (`polarid_io::scene::parse`) on arbitrary text.
//!
//! Beyond "no panic, no hang": a scene the parser accepts satisfies every bound that
//! docs/SCENE.md promises and the simulator relies on (frame size, angles, sensor,
//! exposure, plates inside the frame and not overlapping, regions inside their plates).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use polarid_core::simulate::Exposure;
use polarid_io::scene::{self, CaptureKind, Geometry, MAX_SIDE};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(s) = scene::parse(Path::new("scene.toml"), text) else {
        return;
    };
    assert!((2..=MAX_SIDE).contains(&s.width) && (2..=MAX_SIDE).contains(&s.height));
    let calibrated = match &s.geometry {
        Geometry::FarField {
            theta_r_deg,
            phi_deg,
            theta_i_deg,
        } => {
            assert!((0.0..90.0).contains(theta_r_deg));
            assert!(phi_deg.is_finite());
            assert!(!theta_i_deg.is_empty());
            assert!(theta_i_deg.iter().all(|t| (0.0..90.0).contains(t)));
            false
        }
        Geometry::Calibrated(c) => {
            assert!(!c.sources.is_empty() && !c.planes.is_empty());
            assert!(c.sources.iter().all(|s| s.intensity > 0.0 && s.intensity.is_finite()));
            true
        }
    };
    assert!(s.captures() > 0);
    assert!(s.wavelength_nm.is_none_or(|w| w > 0.0 && w.is_finite()));
    assert!(s.background >= 0.0 && s.background.is_finite());
    let sn = &s.sensor;
    assert!((1..=16).contains(&sn.bit_depth));
    assert!(sn.full_well_e >= 1.0 && sn.full_well_e <= 1e9);
    assert!(sn.read_noise_e >= 0.0 && sn.read_noise_e.is_finite());
    assert!(sn.dark_level_dn >= 0.0 && sn.dark_level_dn < sn.max_dn());
    match s.exposure {
        Exposure::Auto { fraction } => assert!(fraction > 0.0 && fraction <= 1.0),
        Exposure::Fixed(v) => assert!(v > 0.0 && v.is_finite()),
    }
    match &s.capture {
        CaptureKind::Frames { angles_deg } => {
            assert!(angles_deg.len() >= 3 && angles_deg.iter().all(|a| a.is_finite()));
        }
        CaptureKind::Dofp { pattern } => {
            let mut a = pattern.angles_deg().to_vec();
            a.sort_by(f64::total_cmp);
            assert_eq!(a, [0.0, 45.0, 90.0, 135.0]);
        }
    }
    assert!(!s.plates.is_empty());
    for (i, p) in s.plates.iter().enumerate() {
        let o = &p.optics;
        assert!(o.n > 0.0 && o.n <= 100.0 && (0.0..=100.0).contains(&o.k));
        assert!((1e-3..=10.0).contains(&o.sigma) && (0.0..=1.0).contains(&o.rho_d));
        assert!(p.rect.check(s.width, s.height).is_ok());
        let (r, g) = (&p.rect, &p.region);
        assert!(g.width > 0 && g.height > 0);
        assert!(g.x >= r.x && g.y >= r.y);
        assert!(g.x + g.width <= r.x + r.width && g.y + g.height <= r.y + r.height);
        assert!(p.line >= 1 && p.line <= text.lines().count().max(1));
        assert_eq!(p.placement.is_some(), calibrated);
        for q in &s.plates[..i] {
            assert_ne!(p.name, q.name);
            if calibrated {
                // Plates may hide each other; their regions never overlap.
                let (a, b) = (&p.region, &q.region);
                assert!(
                    !(a.x < b.x + b.width
                        && b.x < a.x + a.width
                        && a.y < b.y + b.height
                        && b.y < a.y + a.height)
                );
                continue;
            }
            let overlap = r.x < q.rect.x + q.rect.width
                && q.rect.x < r.x + r.width
                && r.y < q.rect.y + q.rect.height
                && q.rect.y < r.y + r.height;
            assert!(!overlap);
        }
    }
});
