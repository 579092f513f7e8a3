//! Stokes least squares: exact noiseless round trips for several angle sets, errors for
//! singular sets, and the statistical coverage of the region DoLP standard error with
//! photon and read noise.

use polarid_core::CoreError;
use polarid_core::region::{Rect, Sampling, region_stats};
use polarid_core::stokes::{PixelRules, StokesSolver, dolp_aolp, mask};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal, Poisson};

/// `I(a) = (S0 + S1 cos 2a + S2 sin 2a) / 2` (CONVENTIONS).
fn intensity(s: [f64; 3], a_deg: f64) -> f64 {
    let a = 2.0 * a_deg.to_radians();
    0.5 * (s[0] + s[1] * a.cos() + s[2] * a.sin())
}

/// A random Stokes field (DoLP in [0, 1), any AoLP), `w × h`.
fn random_field(w: usize, h: usize, rng: &mut StdRng) -> Vec<[f64; 3]> {
    (0..w * h)
        .map(|_| {
            let s0 = 100.0 + 3000.0 * rng.random::<f64>();
            let p = rng.random::<f64>();
            let psi = std::f64::consts::PI * rng.random::<f64>();
            [s0, s0 * p * (2.0 * psi).cos(), s0 * p * (2.0 * psi).sin()]
        })
        .collect()
}

#[test]
fn noiseless_round_trip_is_exact_for_several_angle_sets() {
    let sets: [&[f64]; 5] = [
        &[0.0, 45.0, 90.0, 135.0],
        &[0.0, 60.0, 120.0],
        &[7.0, 41.0, 93.5, 128.0, 163.0],
        &[135.0, 0.0, 90.0, 45.0],
        &[-30.0, 30.0, 90.0, 200.0, 250.0, 310.0],
    ];
    let (w, h) = (37, 23);
    let mut rng = StdRng::seed_from_u64(7);
    let field = random_field(w, h, &mut rng);
    for angles in sets {
        let solver = StokesSolver::from_degrees(angles).unwrap();
        assert!(!solver.ill_conditioned(), "{angles:?}");
        let frames: Vec<Vec<f32>> = angles
            .iter()
            .map(|&a| field.iter().map(|&s| intensity(s, a) as f32).collect())
            .collect();
        let views: Vec<&[f32]> = frames.iter().map(|f| f.as_slice()).collect();
        let n = w * h;
        let (mut s0, mut s1, mut s2, mut m) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![9; n]);
        let (mut d, mut a) = (vec![0.0; n], vec![0.0; n]);
        let counts = solver
            .compute_with_polar(
                &views,
                w,
                &PixelRules::default(),
                &mut s0,
                &mut s1,
                &mut s2,
                &mut m,
                &mut d,
                &mut a,
            )
            .unwrap();
        assert_eq!(counts.valid as usize, n);
        let mut worst = 0.0f64;
        for (i, s) in field.iter().enumerate() {
            let got = [s0[i] as f64, s1[i] as f64, s2[i] as f64];
            for k in 0..3 {
                // float32 precision relative to S0 (frames are stored as f32).
                worst = worst.max((got[k] - s[k]).abs() / s[0]);
            }
            let dolp = s[1].hypot(s[2]) / s[0];
            assert!(
                (d[i] as f64 - dolp).abs() < 2e-6,
                "{angles:?} dolp {} vs {dolp}",
                d[i]
            );
            if dolp > 0.01 {
                let aolp = (0.5 * s[2].atan2(s[1])).to_degrees().rem_euclid(180.0);
                let da = (a[i] as f64 - aolp).abs();
                assert!(
                    da.min(180.0 - da) < 2e-3,
                    "{angles:?} aolp {} vs {aolp}",
                    a[i]
                );
            }
        }
        assert!(worst < 2e-6, "{angles:?}: worst relative error {worst:e}");
        eprintln!("angles {angles:?}: worst |S - S_true| / S0 = {worst:.2e}");
        // The separate DoLP/AoLP kernel gives the same images as the fused one.
        let (mut d2, mut a2) = (vec![0.0; n], vec![0.0; n]);
        dolp_aolp(w, &s0, &s1, &s2, Some(&m), &mut d2, &mut a2).unwrap();
        assert_eq!(d, d2);
        assert_eq!(a, a2);
    }
}

#[test]
fn u16_and_u8_frames_use_the_same_kernel() {
    let solver = StokesSolver::from_degrees(&[0.0, 45.0, 90.0, 135.0]).unwrap();
    let f: Vec<Vec<u16>> = vec![
        vec![300, 65535],
        vec![200, 10],
        vec![100, 10],
        vec![200, 10],
    ];
    let v: Vec<&[u16]> = f.iter().map(|x| x.as_slice()).collect();
    let rules = PixelRules {
        dark_level: 50.0,
        saturation: 65535.0,
        min_s0: 0.0,
    };
    let (mut s0, mut s1, mut s2, mut m) = (vec![0.0; 2], vec![0.0; 2], vec![0.0; 2], vec![0; 2]);
    let c = solver
        .compute(&v, 2, &rules, &mut s0, &mut s1, &mut s2, &mut m)
        .unwrap();
    // (250 + 150 + 50 + 150) / 2 = 300, S1 = 250 - 50, S2 = 0.
    assert_eq!((s0[0], s1[0], s2[0]), (300.0, 200.0, 0.0));
    assert_eq!(m, vec![mask::VALID, mask::SATURATED]);
    assert_eq!((c.valid, c.saturated, c.rejected()), (1, 1, 1));
    // Dark pixels: S0 at or below the threshold after dark subtraction.
    let f8: Vec<Vec<u8>> = vec![vec![10, 200]; 4];
    let v8: Vec<&[u8]> = f8.iter().map(|x| x.as_slice()).collect();
    let rules = PixelRules {
        dark_level: 10.0,
        ..PixelRules::default()
    };
    let c = solver
        .compute(&v8, 2, &rules, &mut s0, &mut s1, &mut s2, &mut m)
        .unwrap();
    assert_eq!(m, vec![mask::DARK, mask::VALID]);
    assert_eq!((c.dark, c.valid), (1, 1));
    // NaN raw values (float frames) are invalid.
    let ff: Vec<Vec<f32>> = vec![vec![1.0, f32::NAN]; 4];
    let vf: Vec<&[f32]> = ff.iter().map(|x| x.as_slice()).collect();
    let c = solver
        .compute(
            &vf,
            2,
            &PixelRules::default(),
            &mut s0,
            &mut s1,
            &mut s2,
            &mut m,
        )
        .unwrap();
    assert_eq!(m, vec![mask::VALID, mask::INVALID]);
    assert_eq!(c.invalid, 1);
}

#[test]
fn singular_angle_sets_are_errors_and_name_the_angles() {
    for bad in [
        &[0.0, 90.0, 180.0][..],
        &[0.0, 45.0, 225.0, 405.0],
        &[30.0, 30.0, 120.0],
    ] {
        let e = StokesSolver::from_degrees(bad).unwrap_err();
        match &e {
            CoreError::SingularAngles { angles_deg, .. } => assert_eq!(angles_deg.len(), bad.len()),
            other => panic!("{bad:?}: {other:?}"),
        }
        assert!(e.to_string().contains("singular"), "{e}");
    }
    let close = StokesSolver::from_degrees(&[0.0, 3.0, 6.0]).unwrap();
    assert!(close.ill_conditioned());
    assert!(close.condition_number() > 10.0);
}

#[test]
fn wrong_buffer_sizes_are_errors() {
    let solver = StokesSolver::from_degrees(&[0.0, 60.0, 120.0]).unwrap();
    let f = [0.0f32; 12];
    let v = [&f[..], &f[..]];
    let (mut a, mut b, mut c, mut m) = (vec![0.0; 12], vec![0.0; 12], vec![0.0; 12], vec![0; 12]);
    assert!(matches!(
        solver.compute(
            &v,
            4,
            &PixelRules::default(),
            &mut a,
            &mut b,
            &mut c,
            &mut m
        ),
        Err(CoreError::LengthMismatch { .. })
    ));
    let short = [0.0f32; 11];
    let v = [&f[..], &f[..], &short[..]];
    assert!(
        solver
            .compute(
                &v,
                4,
                &PixelRules::default(),
                &mut a,
                &mut b,
                &mut c,
                &mut m
            )
            .is_err()
    );
}

/// Photon (Poisson, gain 1 e⁻/DN) and read noise (Gaussian, 3 DN) on frames at the
/// given angles with a dark level of 64 DN, quantised to whole DN.
fn noisy_frames(angles: &[f64], s: [f64; 3], n: usize, rng: &mut StdRng) -> Vec<Vec<u16>> {
    let read = Normal::new(0.0, 3.0).unwrap();
    angles
        .iter()
        .map(|&a| {
            let lam = intensity(s, a);
            let pois = Poisson::new(lam).unwrap();
            (0..n)
                .map(|_| {
                    let e: f64 = pois.sample(rng);
                    (e + 64.0 + read.sample(rng)).round().clamp(0.0, 4095.0) as u16
                })
                .collect()
        })
        .collect()
}

#[test]
fn region_dolp_is_within_three_standard_errors_in_99_percent_of_trials() {
    let (w, h) = (16, 16);
    let rect = Rect {
        x: 0,
        y: 0,
        width: w,
        height: h,
    };
    let mut rng = StdRng::seed_from_u64(2024);
    for angles in [
        &[0.0, 45.0, 90.0, 135.0][..],
        &[0.0, 60.0, 120.0],
        &[10.0, 50.0, 95.0, 130.0, 170.0],
    ] {
        let solver = StokesSolver::from_degrees(angles).unwrap();
        let rules = PixelRules {
            dark_level: 64.0,
            saturation: 4095.0,
            min_s0: 0.0,
        };
        let mut inside = 0;
        let trials = 1000;
        let n = w * h;
        let (mut s0, mut s1, mut s2, mut m) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0; n]);
        for t in 0..trials {
            let truth_dolp = 0.05 + 0.5 * (t as f64 / trials as f64);
            let psi = 0.7 + t as f64 * 0.01;
            let s0_true = 1500.0;
            let s = [
                s0_true,
                s0_true * truth_dolp * (2.0 * psi).cos(),
                s0_true * truth_dolp * (2.0 * psi).sin(),
            ];
            let frames = noisy_frames(angles, s, n, &mut rng);
            let v: Vec<&[u16]> = frames.iter().map(|f| f.as_slice()).collect();
            solver
                .compute(&v, w, &rules, &mut s0, &mut s1, &mut s2, &mut m)
                .unwrap();
            let st = region_stats(w, &s0, &s1, &s2, &m, rect, Sampling::Independent).unwrap();
            let se = st.dolp_se.unwrap();
            if (st.dolp - truth_dolp).abs() <= 3.0 * se {
                inside += 1;
            }
        }
        let frac = inside as f64 / trials as f64;
        eprintln!("angles {angles:?}: {inside}/{trials} trials within 3 SE ({frac:.3})");
        assert!(frac >= 0.99, "{angles:?}: coverage {frac}");
    }
}
