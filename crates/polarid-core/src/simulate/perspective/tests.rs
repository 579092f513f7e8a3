use super::*;
use crate::geometry::{Distortion, Intrinsics};
use crate::simulate::{plate_radiance, stokes_dolp};
use std::f64::consts::PI;

fn optics(n: f64, k: f64, sigma: f64) -> PlateOptics {
    PlateOptics {
        n,
        k,
        sigma,
        rho_d: 0.0,
    }
}

/// A 320 × 240 camera with a ~40° horizontal field, 0.8 m from the bench, looking down at
/// the origin from the −x side (zenith 45°).
fn bench_camera(distortion: Distortion) -> PinholeCamera {
    PinholeCamera::look_at(
        Intrinsics {
            fx: 440.0,
            fy: 440.0,
            cx: 159.5,
            cy: 119.5,
        },
        distortion,
        [-0.5657, 0.0, 0.5657],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
    )
    .unwrap()
}

/// `render_bands` with one band, the plates' own optics: the Stokes and plate maps of a
/// `w × h` frame.
fn render(
    scene: &PerspectiveScene,
    w: usize,
    h: usize,
    light: &Light,
    background: [f64; 3],
    stokes: &mut [[f32; 3]],
    plate: &mut [u16],
) -> Result<()> {
    let optics: Vec<Vec<PlateOptics>> = scene.plates().iter().map(|p| vec![*p.optics()]).collect();
    let out = BandStokesMaps {
        stokes: vec![stokes],
        plate,
    };
    scene.render_bands(w, h, light, &optics, &[background], out)
}

fn floor_plate(center: V3, size: f64, o: PlateOptics) -> PlanarPlate {
    PlanarPlate::new(
        Plane::horizontal(),
        center,
        [0.0, 1.0, 0.0],
        [size, size],
        o,
    )
    .unwrap()
}

fn aolp(s: &[f64; 3]) -> f64 {
    (0.5 * s[2].atan2(s[1])).rem_euclid(PI)
}

/// Difference of two axial angles (period π), in [0, π/2].
fn axial_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(PI);
    d.min(PI - d)
}

#[test]
fn pixel_stokes_matches_independent_physics() {
    let cam = bench_camera(Distortion::from_array([-0.12, 0.05, 1e-3, -5e-4, 0.0]));
    let o = PlateOptics {
        n: 0.27,
        k: 3.41,
        sigma: 0.25,
        rho_d: 0.0,
    };
    let scene = PerspectiveScene::new(cam, vec![floor_plate([0.0; 3], 3.0, o)]).unwrap();
    let lamp = [0.35, 0.2, 0.6];
    let light = Light {
        source: Source::Position(lamp),
        power: 2.5,
    };
    let c = cam.position();
    for &(u, v) in &[(159.5, 119.5), (40.0, 200.0), (290.0, 30.0), (10.0, 10.0)] {
        let hit = scene.pixel(u, v, &light).unwrap().unwrap();
        // Independent: ray, plane z = 0, unit vectors, angles by acos.
        let d = cam.ray(u, v).unwrap();
        let t = -c[2] / d[2];
        let x = [c[0] + t * d[0], c[1] + t * d[1], 0.0];
        let norm = |a: V3| dot(a, a).sqrt();
        let to_l = sub(lamp, x);
        let r2 = dot(to_l, to_l);
        let ui = to_l.map(|a| a / r2.sqrt());
        let ur = sub(c, x).map(|a| a / norm(sub(c, x)));
        let (ci, cr) = (ui[2], ur[2]);
        let beta = 0.5 * dot(ui, ur).acos();
        let h = [ui[0] + ur[0], ui[1] + ur[1], ui[2] + ur[2]];
        let cos_tilt = h[2] / norm(h);
        let tan2 = (1.0 - cos_tilt * cos_tilt) / (cos_tilt * cos_tilt);
        let (rs, rp) = crate::fresnel::reflectances(o.n, o.k, beta);
        let s2 = o.sigma * o.sigma;
        let f00 = 0.5 * (rs + rp) * (-tan2 / (2.0 * s2)).exp()
            / (8.0 * PI * s2 * cos_tilt.powi(4) * ci * cr);
        let s0 = 2.5 / r2 * ci * f00;
        let dolp = (rs - rp) / (rs + rp);
        assert!((hit.stokes[0] - s0).abs() < 1e-11 * s0, "S0 at ({u}, {v})");
        assert!(
            (stokes_dolp(&hit.stokes) - dolp).abs() < 1e-11,
            "DoLP at ({u}, {v})"
        );
        assert!((dolp - crate::dop::dop(o.n, o.k, beta)).abs() < 1e-12);
        assert!((hit.geometry.beta - beta).abs() < 1e-9);
        // AoLP: perpendicular to the image of the plane of incidence, which holds the
        // camera, the point and the lamp: the trace runs from the pixel towards the
        // image of a point between X and the lamp.
        let q = [
            x[0] + 1e-3 * to_l[0],
            x[1] + 1e-3 * to_l[1],
            x[2] + 1e-3 * to_l[2],
        ];
        let [qu, qv] = cam.project(q).unwrap();
        let [xu, xv] = cam.project(x).unwrap();
        let trace = (-(qv - xv)).atan2(qu - xu).rem_euclid(PI);
        let want = (trace + 0.5 * PI).rem_euclid(PI);
        assert!(
            axial_diff(aolp(&hit.stokes), want) < 1e-4,
            "AoLP at ({u}, {v}): {} vs {}",
            aolp(&hit.stokes).to_degrees(),
            want.to_degrees()
        );
    }
}

#[test]
fn far_field_limit_matches_plate_radiance() {
    // Camera 1e4 away with a narrow field, lamp 1e6 away with I = r² (unit irradiance):
    // the pixels see the far-field geometry (θi, θr, φ) of the uniform renderer.
    let o = optics(1.24, 6.6, 0.2);
    for &(ti_deg, tr_deg, phi_deg) in &[
        (40.0, 60.0, 180.0),
        (55.0, 50.0, 150.0),
        (30.0, 45.0, 230.0),
    ] {
        let (ti, tr, phi): (f64, f64, f64) = (
            f64::to_radians(ti_deg),
            f64::to_radians(tr_deg),
            f64::to_radians(phi_deg),
        );
        let dist_c = 1e4;
        let cpos = crate::geometry::camera_dir(tr, phi).map(|a| a * dist_c);
        let cam = PinholeCamera::look_at(
            Intrinsics {
                fx: 1e7,
                fy: 1e7,
                cx: 4.0,
                cy: 4.0,
            },
            Distortion::default(),
            cpos,
            [0.0; 3],
            [0.0, 0.0, 1.0],
        )
        .unwrap();
        let scene = PerspectiveScene::new(cam, vec![floor_plate([0.0; 3], 10.0, o)]).unwrap();
        let r = 1e6;
        let light = Light {
            source: Source::Position(crate::geometry::source_dir(ti).map(|a| a * r)),
            power: r * r,
        };
        let far = plate_radiance(&o, ti, tr, phi).unwrap();
        for (u, v) in [(4.0, 4.0), (0.0, 0.0), (8.0, 3.0)] {
            let hit = scene.pixel(u, v, &light).unwrap().unwrap();
            let g = hit.geometry;
            assert!((g.theta_i - ti).abs() < 1e-5 && (g.theta_r - tr).abs() < 1e-5);
            assert!(
                (g.phi - phi).abs() < 1e-5,
                "{} vs {phi_deg}",
                g.phi.to_degrees()
            );
            assert!(
                (stokes_dolp(&hit.stokes) - stokes_dolp(&far)).abs() < 1e-6,
                "DoLP {ti_deg}/{tr_deg}/{phi_deg}"
            );
            assert!((hit.stokes[0] / far[0] - 1.0).abs() < 1e-4, "S0");
            // The far-field image frame: +x along the camera beam's s = z × k, which is
            // the image x axis of a camera with up = +z; both give the same AoLP.
            assert!(
                axial_diff(aolp(&hit.stokes), aolp(&far)) < 1e-4,
                "AoLP {} vs {}",
                aolp(&hit.stokes).to_degrees(),
                aolp(&far).to_degrees()
            );
        }
    }
}

#[test]
fn brightness_falls_with_the_square_of_the_lamp_distance() {
    let cam = bench_camera(Distortion::default());
    let scene = PerspectiveScene::new(cam, vec![floor_plate([0.0; 3], 0.4, optics(1.5, 0.0, 0.3))])
        .unwrap();
    let (u, v) = (150.0, 110.0);
    let x = scene
        .pixel(
            u,
            v,
            &Light {
                source: Source::Direction([0.0, 0.0, 1.0]),
                power: 1.0,
            },
        )
        .unwrap()
        .unwrap()
        .geometry
        .point;
    let dir = [0.5, 0.1, 0.8];
    let at = |r: f64| {
        let n = dot(dir, dir).sqrt();
        let p = [0, 1, 2].map(|i| x[i] + r * dir[i] / n);
        scene
            .pixel(
                u,
                v,
                &Light {
                    source: Source::Position(p),
                    power: 1.0,
                },
            )
            .unwrap()
            .unwrap()
            .stokes
    };
    let (near, far) = (at(0.5), at(1.0));
    assert!(
        (near[0] / far[0] - 4.0).abs() < 1e-9,
        "{}",
        near[0] / far[0]
    );
    assert!((stokes_dolp(&near) - stokes_dolp(&far)).abs() < 1e-12);
    // A distant source in the same direction has the irradiance it is given.
    let d = scene
        .pixel(
            u,
            v,
            &Light {
                source: Source::Direction(dir),
                power: 4.0,
            },
        )
        .unwrap()
        .unwrap()
        .stokes;
    assert!((d[0] / near[0] - 1.0).abs() < 1e-9);
}

#[test]
fn specular_lobe_sits_at_the_mirror_point() {
    // A smooth plate: the brightest pixel is where the camera sees the lamp's mirror image.
    let cam = bench_camera(Distortion::default());
    let scene = PerspectiveScene::new(
        cam,
        vec![floor_plate([0.0; 3], 3.0, optics(1.2, 7.0, 0.03))],
    )
    .unwrap();
    let lamp = [0.3, -0.1, 0.7];
    let light = Light {
        source: Source::Position(lamp),
        power: 1.0,
    };
    let (w, h) = (320, 240);
    let mut st = vec![[0f32; 3]; w * h];
    let mut pl = vec![0u16; w * h];
    render(&scene, w, h, &light, [0.0; 3], &mut st, &mut pl).unwrap();
    let (imax, _) =
        st.iter().enumerate().fold(
            (0, f32::MIN),
            |b, (i, s)| if s[0] > b.1 { (i, s[0]) } else { b },
        );
    let (bu, bv) = ((imax % w) as f64, (imax / w) as f64);
    // Mirror image of the lamp in z = 0; the ray from the camera to it crosses z = 0 at X.
    let c = cam.position();
    let m = [lamp[0], lamp[1], -lamp[2]];
    let t = c[2] / (c[2] - m[2]);
    let x = [c[0] + t * (m[0] - c[0]), c[1] + t * (m[1] - c[1]), 0.0];
    let [mu, mv] = cam.project(x).unwrap();
    assert!(
        (bu - mu).hypot(bv - mv) < 3.0,
        "peak at ({bu}, {bv}), mirror point at ({mu:.1}, {mv:.1})"
    );
    // There β = angle of incidence of the mirror reflection, and the AoLP is that of s.
    assert!(pl.iter().all(|&p| p == 1), "the plate fills the frame");
}

#[test]
fn nearest_plate_hides_and_background_is_dark() {
    let cam = bench_camera(Distortion::default());
    let low = floor_plate([0.0; 3], 0.3, optics(1.5, 0.0, 0.3));
    // A plate 5 cm above the floor, over part of the low one.
    let high = PlanarPlate::new(
        Plane::new([0.0, 0.0, 0.05], [0.0, 0.0, 2.0]).unwrap(),
        [0.05, 0.0, 0.05],
        [1.0, 0.0, 0.0],
        [0.1, 0.1],
        optics(0.27, 3.4, 0.2),
    )
    .unwrap();
    let scene = PerspectiveScene::new(cam, vec![low, high]).unwrap();
    let [u, v] = cam.project([0.05, 0.0, 0.05]).unwrap();
    assert_eq!(scene.plate_at(u, v).unwrap(), Some(1));
    let [u, v] = cam.project([-0.12, 0.1, 0.0]).unwrap();
    assert_eq!(scene.plate_at(u, v).unwrap(), Some(0));
    let [u, v] = cam.project([0.0, 0.3, 0.0]).unwrap();
    assert_eq!(scene.plate_at(u, v).unwrap(), None);
    let light = Light {
        source: Source::Position([0.3, 0.0, 0.5]),
        power: 1.0,
    };
    assert!(scene.pixel(u, v, &light).unwrap().is_none());
    let (w, h) = (320, 240);
    let mut st = vec![[9f32; 3]; w * h];
    let mut pl = vec![9u16; w * h];
    render(&scene, w, h, &light, [0.0; 3], &mut st, &mut pl).unwrap();
    let counts = [0u16, 1, 2].map(|k| pl.iter().filter(|&&p| p == k).count());
    let mut pm = vec![7u16; w * h];
    scene.plate_map(w, h, &mut pm).unwrap();
    assert_eq!(pm, pl, "plate_map agrees with render");
    assert!(counts.iter().all(|&c| c > 100), "{counts:?}");
    assert!(
        st.iter()
            .zip(&pl)
            .all(|(s, &p)| (p == 0) == (s == &[0.0f32; 3]))
    );
    // A light below the floor leaves it unlit.
    let below = Light {
        source: Source::Direction([0.0, 0.3, -1.0]),
        power: 1.0,
    };
    let [u, v] = cam.project([-0.12, 0.1, 0.0]).unwrap();
    let hit = scene.pixel(u, v, &below).unwrap().unwrap();
    assert_eq!((hit.irradiance, hit.stokes), (0.0, [0.0; 3]));
    // Buffers of the wrong size.
    let mut short = vec![0u16; 5];
    assert!(matches!(
        render(&scene, w, h, &light, [0.0; 3], &mut st, &mut short),
        Err(CoreError::LengthMismatch { .. })
    ));
}

#[test]
fn plate_construction_errors() {
    let o = optics(1.5, 0.0, 0.3);
    let p = Plane::horizontal();
    assert!(PlanarPlate::new(p, [0.0; 3], [0.0, 0.0, 1.0], [1.0, 1.0], o).is_err());
    assert!(PlanarPlate::new(p, [0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0], o).is_err());
    assert!(PlanarPlate::new(p, [f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0], o).is_err());
    assert!(
        PlanarPlate::new(
            p,
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [1.0, 1.0],
            optics(1.5, 0.0, 0.0)
        )
        .is_err()
    );
    // The centre is projected onto the plane; the axis made perpendicular to the normal.
    let q = PlanarPlate::new(p, [0.1, 0.2, 0.3], [1.0, 0.0, 1.0], [0.2, 0.1], o).unwrap();
    assert_eq!(q.center(), [0.1, 0.2, 0.0]);
    assert_eq!(q.axes(), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    assert!(q.contains([0.2, 0.25, 0.0]) && !q.contains([0.21, 0.2, 0.0]));
    let cam = bench_camera(Distortion::default());
    let under = PlanarPlate::new(
        Plane::new([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]).unwrap(),
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0],
        o,
    )
    .unwrap();
    assert!(matches!(
        PerspectiveScene::new(cam, vec![under]),
        Err(CoreError::CameraBehindPlane { .. })
    ));
}

/// `render_bands` gives, in every band, the map it gives with one band for the same
/// plates with that band's optics (bit for bit), the same plate map, and the band's background; bad
/// list lengths are refused.
#[test]
fn render_bands_matches_render_per_band() {
    let cam = bench_camera(Distortion::from_array([-0.1, 0.02, 0.0, 0.0, 0.0]));
    // Copper and gold at 650, 550, 450 nm (rho_d in the last band of the second plate).
    let bands: Vec<Vec<PlateOptics>> = vec![
        vec![
            optics(0.25, 3.61, 0.2),
            optics(0.97, 2.64, 0.2),
            optics(1.25, 2.39, 0.2),
        ],
        vec![
            optics(0.17, 3.15, 0.3),
            optics(0.43, 2.45, 0.3),
            PlateOptics {
                rho_d: 0.2,
                ..optics(1.47, 1.95, 0.3)
            },
        ],
    ];
    let centers = [[-0.08, 0.0, 0.0], [0.08, 0.05, 0.0]];
    let scene_with = |b: usize| {
        let plates = centers
            .iter()
            .zip(&bands)
            .map(|(&c, o)| floor_plate(c, 0.12, o[b]))
            .collect();
        PerspectiveScene::new(cam, plates).unwrap()
    };
    let light = Light {
        source: Source::Position([0.4, -0.1, 0.6]),
        power: 0.5,
    };
    let (w, h) = (320, 240);
    let bg = [[0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [0.3, 0.01, 0.0]];
    let mut maps = vec![vec![[0f32; 3]; w * h]; 3];
    let mut pl = vec![0u16; w * h];
    // Plates' own optics (band 0's here) are not used by render_bands.
    let scene = scene_with(1);
    scene
        .render_bands(
            w,
            h,
            &light,
            &bands,
            &bg,
            BandStokesMaps {
                stokes: maps.iter_mut().map(|m| m.as_mut_slice()).collect(),
                plate: &mut pl,
            },
        )
        .unwrap();
    for (b, map) in maps.iter().enumerate() {
        let mut st = vec![[0f32; 3]; w * h];
        let mut pb = vec![0u16; w * h];
        render(&scene_with(b), w, h, &light, bg[b], &mut st, &mut pb).unwrap();
        assert_eq!(&st, map, "band {b}");
        assert_eq!(pb, pl);
    }
    assert!(pl.iter().filter(|&&p| p == 1).count() > 1000);
    assert!(pl.iter().filter(|&&p| p == 2).count() > 1000);
    // Copper's DoLP differs between bands (dispersion).
    let i = pl.iter().position(|&p| p == 1).unwrap();
    let d: Vec<f64> = maps
        .iter()
        .map(|m| stokes_dolp(&m[i].map(f64::from)))
        .collect();
    assert!((d[0] - d[2]).abs() > 0.01, "{d:?}");
    // One optics list per plate, one entry per band.
    let mut pl2 = vec![0u16; w * h];
    let e = scene.render_bands(
        w,
        h,
        &light,
        &bands[..1],
        &bg,
        BandStokesMaps {
            stokes: maps.iter_mut().map(|m| m.as_mut_slice()).collect(),
            plate: &mut pl2,
        },
    );
    assert!(
        matches!(
            e,
            Err(CoreError::LengthMismatch {
                expected: 2,
                got: 1,
                ..
            })
        ),
        "{e:?}"
    );
    let e = scene.render_bands(
        w,
        h,
        &light,
        &bands,
        &bg[..2],
        BandStokesMaps {
            stokes: maps.iter_mut().map(|m| m.as_mut_slice()).collect(),
            plate: &mut pl2,
        },
    );
    assert!(
        matches!(
            e,
            Err(CoreError::LengthMismatch {
                expected: 3,
                got: 2,
                ..
            })
        ),
        "{e:?}"
    );
}
