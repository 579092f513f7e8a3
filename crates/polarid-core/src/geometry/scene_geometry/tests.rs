use std::f64::consts::PI;

use proptest::prelude::*;

use super::*;
use crate::geometry::camera::{Distortion, Intrinsics};
use crate::geometry::{camera_dir, source_dir};

fn intr(fx: f64, cx: f64, cy: f64) -> Intrinsics {
    Intrinsics { fx, fy: fx, cx, cy }
}

fn look(k: Intrinsics, d: Distortion, pos: V3, at: V3, up: V3) -> PinholeCamera {
    PinholeCamera::look_at(k, d, pos, at, up).unwrap()
}

fn view(cam: PinholeCamera) -> ViewGeometry {
    ViewGeometry::new(cam, Plane::horizontal()).unwrap()
}

fn eq5(ti: f64, tr: f64, phi: f64) -> f64 {
    0.5 * (ti.cos() * tr.cos() + ti.sin() * tr.sin() * phi.cos())
        .clamp(-1.0, 1.0)
        .acos()
}

/// Camera and lamp very far away, a very long focal length: every pixel sees the far
/// field's angles.
#[test]
fn far_field_limit() {
    let far = 1e6;
    for &(ti_deg, tr_deg, phi_deg, directional) in &[
        (35.0, 60.0, 180.0, false),
        (50.0, 30.0, 130.0, false),
        (20.0, 70.0, 250.0, true),
        (0.0, 45.0, 180.0, false),
    ] {
        let (ti, tr, phi): (f64, f64, f64) = (
            f64::to_radians(ti_deg),
            f64::to_radians(tr_deg),
            f64::to_radians(phi_deg),
        );
        let cam = look(
            intr(1e12, 50.0, 40.0),
            Distortion::default(),
            vec3::scale(camera_dir(tr, phi), far),
            [0.0; 3],
            [0.0, 0.0, 1.0],
        );
        let src = if directional {
            Source::Direction(source_dir(ti))
        } else {
            Source::Position(vec3::scale(source_dir(ti), far))
        };
        let rect = Rect {
            x: 0,
            y: 0,
            width: 101,
            height: 81,
        };
        let n = rect.width * rect.height;
        let (mut b, mut i, mut r, mut p) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        view(cam)
            .fill(
                rect,
                &src,
                GeometryMaps {
                    beta: &mut b,
                    theta_i: &mut i,
                    theta_r: &mut r,
                    phi: &mut p,
                    poi_angle: None,
                },
            )
            .unwrap();
        let beta_ff = crate::geometry::beta(ti, tr, phi);
        for k in 0..n {
            assert!((i[k] - ti).abs() < 1e-9, "theta_i {} vs {ti}", i[k]);
            assert!((r[k] - tr).abs() < 1e-9, "theta_r {} vs {tr}", r[k]);
            if ti > 0.0 {
                assert!((p[k] - phi).abs() < 1e-9, "phi {} vs {phi}", p[k]);
            }
            assert!((b[k] - beta_ff).abs() < 1e-9, "beta {} vs {beta_ff}", b[k]);
        }
    }
}

#[test]
fn principal_point_looking_straight_down_has_zero_view_angle() {
    let k = intr(1350.0, 239.5, 179.5);
    let cam = look(
        k,
        Distortion::from_array([-0.2, 0.1, 1e-3, -1e-3, 0.0]),
        [0.3, 0.2, 1.0],
        [0.3, 0.2, 0.0],
        [0.0, 1.0, 0.0],
    );
    let g = view(cam)
        .pixel(k.cx, k.cy, &Source::Position([-0.5, 0.0, 1.0]))
        .unwrap();
    assert!(g.theta_r.abs() < 1e-15, "{}", g.theta_r);
    assert!((g.point[0] - 0.3).abs() < 1e-15 && (g.point[1] - 0.2).abs() < 1e-15);
    // θr = 0: φ is undefined and reported as π; β is half the source zenith.
    assert_eq!(g.phi, PI);
    assert!((g.beta - 0.5 * g.theta_i).abs() < 1e-15);
}

/// Camera and lamp in the xz plane, radial distortion only: the image is mirror
/// symmetric about the principal column, and that column is in the plane of incidence.
#[test]
fn mirror_symmetry_and_in_plane_column() {
    let k = intr(880.0, 319.0, 239.5);
    let cam = look(
        k,
        Distortion::from_array([-0.15, 0.05, 0.0, 0.0, 0.0]),
        vec3::scale(camera_dir(50f64.to_radians(), PI), 0.8),
        [0.0; 3],
        [0.0, 0.0, 1.0],
    );
    let vg = view(cam);
    let src = Source::Position(vec3::scale(source_dir(40f64.to_radians()), 0.7));
    for v in [0.0, 100.0, 239.5, 400.0, 479.0] {
        let c = vg.pixel(k.cx, v, &src).unwrap();
        if c.point[0] < 0.7 * 40f64.to_radians().sin() {
            assert!((c.phi - PI).abs() < 1e-12, "phi {} at row {v}", c.phi);
            assert!((c.beta - 0.5 * (c.theta_i + c.theta_r)).abs() < 1e-12);
        } else {
            // The top row looks beyond the lamp: backscatter, in the plane.
            assert!(
                c.phi.abs() < 1e-12 || (c.phi - 2.0 * PI).abs() < 1e-12,
                "{}",
                c.phi
            );
        }
        // The plane of incidence is the xz plane, whose trace is the vertical column.
        assert!((c.poi_angle - PI / 2.0).abs() < 1e-9, "{}", c.poi_angle);
        for du in [1.0, 37.0, 150.0, 319.0] {
            let a = vg.pixel(k.cx + du, v, &src).unwrap();
            let b = vg.pixel(k.cx - du, v, &src).unwrap();
            assert!((a.theta_i - b.theta_i).abs() < 1e-12);
            assert!((a.theta_r - b.theta_r).abs() < 1e-12);
            assert!((a.beta - b.beta).abs() < 1e-12);
            assert!(
                (a.phi + b.phi - 2.0 * PI).abs() < 1e-12,
                "{} {}",
                a.phi,
                b.phi
            );
            assert!((a.point[1] + b.point[1]).abs() < 1e-12);
            assert!((a.poi_angle + b.poi_angle - PI).abs() < 1e-9);
        }
    }
    // Swapping lamp and camera roles: θi ↔ θr at the same plane point, same β.
    let p = vg.pixel(100.0, 50.0, &src).unwrap();
    let cam2 = look(
        k,
        Distortion::default(),
        vec3::scale(source_dir(40f64.to_radians()), 0.7),
        p.point,
        [0.0, 0.0, 1.0],
    );
    let q = view(cam2)
        .pixel(k.cx, k.cy, &Source::Position(cam.position()))
        .unwrap();
    assert!((q.theta_i - p.theta_r).abs() < 1e-12 && (q.theta_r - p.theta_i).abs() < 1e-12);
    assert!((q.beta - p.beta).abs() < 1e-12);
    assert!(((q.phi + p.phi) - 2.0 * PI).abs() < 1e-9 || (q.phi - p.phi).abs() < 1e-9);
}

/// A typical bench: a 40° lens 0.8 m from 10 cm plates, a lamp 0.7 m away.
#[test]
fn bench_beta_varies_by_a_fraction_of_a_degree_to_degrees() {
    let (w, h) = (640usize, 480usize);
    let fx = 0.5 * w as f64 / 20f64.to_radians().tan(); // 40° horizontal field
    let k = intr(fx, 319.5, 239.5);
    let cam = look(
        k,
        Distortion::default(),
        vec3::scale(camera_dir(55f64.to_radians(), PI), 0.8),
        [0.0; 3],
        [0.0, 0.0, 1.0],
    );
    let vg = view(cam);
    let src = Source::Position(vec3::scale(source_dir(40f64.to_radians()), 0.7));
    let rect = Rect {
        x: 0,
        y: 0,
        width: w,
        height: h,
    };
    let n = w * h;
    let (mut b, mut i, mut r, mut p) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut poi = vec![0.0; n];
    vg.fill(
        rect,
        &src,
        GeometryMaps {
            beta: &mut b,
            theta_i: &mut i,
            theta_r: &mut r,
            phi: &mut p,
            poi_angle: Some(&mut poi),
        },
    )
    .unwrap();
    // Pixels whose points fall on a 10 cm plate centred at (cx, cy) in the plane.
    let spread = |cx: f64, cy: f64| {
        let (mut lo, mut hi, mut phi_dev) = (f64::MAX, f64::MIN, 0f64);
        for v in 0..h {
            for u in 0..w {
                let g = vg.pixel(u as f64, v as f64, &src).unwrap();
                if (g.point[0] - cx).abs() <= 0.05 && (g.point[1] - cy).abs() <= 0.05 {
                    let j = v * w + u;
                    assert_eq!(g.beta, b[j]);
                    lo = lo.min(b[j]);
                    hi = hi.max(b[j]);
                    phi_dev = phi_dev.max((p[j] - PI).abs());
                }
            }
        }
        ((hi - lo).to_degrees(), phi_dev.to_degrees())
    };
    let (centre, centre_phi) = spread(0.0, 0.0);
    let (side, side_phi) = spread(0.0, 0.12);
    println!(
        "bench: beta spread over the centre plate {centre:.3} deg (phi within {centre_phi:.1} \
         deg of 180), over a plate 12 cm aside {side:.3} deg (phi off by up to {side_phi:.1} deg)"
    );
    assert!((0.1..=3.0).contains(&centre), "{centre}");
    assert!((0.1..=3.0).contains(&side), "{side}");
    assert!(side_phi > centre_phi);
}

#[test]
fn errors() {
    let k = intr(880.0, 319.5, 239.5);
    let d = Distortion::default();
    // Camera below the plane.
    let below = look(k, d, [0.5, 0.0, -0.3], [0.0; 3], [0.0, 0.0, 1.0]);
    assert!(matches!(
        ViewGeometry::new(below, Plane::horizontal()),
        Err(CoreError::CameraBehindPlane { .. })
    ));
    // Camera in the plane.
    let level = look(k, d, [0.5, 0.0, 0.0], [0.0; 3], [0.0, 0.0, 1.0]);
    assert!(matches!(
        ViewGeometry::new(level, Plane::horizontal()),
        Err(CoreError::CameraBehindPlane { .. })
    ));
    // Camera looking horizontally: rows above the centre leave the plane, the centre
    // row is parallel to it.
    let horiz = view(look(
        k,
        d,
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
    ));
    let src = Source::Position([0.0, 0.0, 2.0]);
    assert!(matches!(
        horiz.pixel(k.cx, k.cy, &src),
        Err(CoreError::RayMissesPlane { .. })
    ));
    assert!(matches!(
        horiz.pixel(k.cx, 10.0, &src),
        Err(CoreError::RayMissesPlane { .. })
    ));
    assert!(horiz.pixel(k.cx, 470.0, &src).is_ok());
    // Sources below the horizon.
    let vg = view(look(k, d, [0.5, 0.0, 0.5], [0.0; 3], [0.0, 0.0, 1.0]));
    let e = vg
        .pixel(k.cx, k.cy, &Source::Position([-0.5, 0.0, -0.01]))
        .unwrap_err();
    assert!(matches!(e, CoreError::SourceBelowHorizon { .. }), "{e}");
    assert!(matches!(
        vg.pixel(k.cx, k.cy, &Source::Direction([1.0, 0.0, 0.0])),
        Err(CoreError::SourceBelowHorizon { .. })
    ));
    assert!(matches!(
        vg.pixel(k.cx, k.cy, &Source::Direction([0.0; 3])),
        Err(CoreError::InvalidVector { .. })
    ));
    // Plane with a zero normal.
    assert!(matches!(
        Plane::new([0.0; 3], [0.0; 3]),
        Err(CoreError::InvalidVector {
            name: "plane normal",
            ..
        })
    ));
    // Region checks and the kernel report the first bad pixel.
    let rect = Rect {
        x: 300,
        y: 200,
        width: 40,
        height: 40,
    };
    assert!(matches!(
        horiz.check_rect(rect, &src),
        Err(CoreError::RayMissesPlane { v, .. }) if v == 200.0
    ));
    let n = 1600;
    let (mut b, mut i, mut r, mut p) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let e = horiz
        .fill(
            rect,
            &src,
            GeometryMaps {
                beta: &mut b,
                theta_i: &mut i,
                theta_r: &mut r,
                phi: &mut p,
                poi_angle: None,
            },
        )
        .unwrap_err();
    assert!(
        matches!(e, CoreError::RayMissesPlane { u, v, .. } if u == 300.0 && v == 200.0),
        "{e}"
    );
    let mut short = vec![0.0; 3];
    assert!(matches!(
        vg.fill(
            rect,
            &src,
            GeometryMaps {
                beta: &mut b,
                theta_i: &mut i,
                theta_r: &mut r,
                phi: &mut short,
                poi_angle: None,
            },
        ),
        Err(CoreError::LengthMismatch {
            name: "phi map",
            ..
        })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// β of the kernel is eq. (5) of its own θi, θr, φ, and half the angle between the
    /// directions to the source and to the camera.
    #[test]
    fn kernel_beta_is_eq5(
        cam_r in 0.3f64..3.0, cam_az in 0.0f64..6.2, cam_zen in 0.0f64..1.3,
        lamp_r in 0.2f64..3.0, lamp_az in 0.0f64..6.2, lamp_zen in 0.0f64..1.4,
        tx in -0.1f64..0.1, ty in -0.1f64..0.1, k1 in -0.3f64..0.1,
    ) {
        let k = intr(900.0, 31.5, 23.5);
        let pos = vec3::scale(camera_dir(cam_zen, cam_az), cam_r);
        let up = if cam_zen < 1e-3 { [0.0, 1.0, 0.0] } else { [0.0, 0.0, 1.0] };
        let cam = look(k, Distortion { k1, ..Distortion::default() }, pos, [tx, ty, 0.0], up);
        let vg = view(cam);
        let src = Source::Position(vec3::scale(camera_dir(lamp_zen, lamp_az), lamp_r));
        let rect = Rect { x: 0, y: 0, width: 64, height: 48 };
        let n = 64 * 48;
        let (mut b, mut i, mut r, mut p) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let res = vg.fill(rect, &src, GeometryMaps {
            beta: &mut b, theta_i: &mut i, theta_r: &mut r, phi: &mut p, poi_angle: None,
        });
        prop_assume!(res.is_ok());
        for j in (0..n).step_by(7) {
            prop_assert!((b[j] - eq5(i[j], r[j], p[j])).abs() < 1e-7);
            let g = vg.pixel((j % 64) as f64, (j / 64) as f64, &src).unwrap();
            prop_assert!((b[j] - 0.5 * vec3::angle(g.u_i, g.u_r)).abs() < 1e-12);
            prop_assert!((0.0..2.0 * PI).contains(&p[j]));
        }
    }
}
