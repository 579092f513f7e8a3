//! The sun's position (`polarid_core::sun`): NREL SPA's reference case (Reda & Andreas,
//! NREL/TP-560-34302, table A4.1 inputs and published results) and independent checks.

use polarid_core::CoreError;
use polarid_core::sun::{
    CLEAR_SKY_MAX_DOLP, REFRACTION_CUTOFF_DEG, Site, SolarPosition, delta_t_estimate_s,
    incidence_angle_deg, julian_day, rayleigh_sky_dolp, solar_position, sun_direction,
};

/// 2003-10-17T12:30:30-07:00 = 2003-10-17T19:30:30Z.
const SPA_UNIX: f64 = 1_066_419_030.0;

fn spa_site() -> Site {
    Site {
        latitude_deg: 39.742476,
        longitude_deg: -105.1786,
        elevation_m: 1830.14,
        pressure_mbar: 820.0,
        temperature_c: 11.0,
    }
}

fn spa_reference() -> SolarPosition {
    solar_position(SPA_UNIX, Some(67.0), &spa_site()).unwrap()
}

/// Unix seconds of a UTC calendar time (proleptic Gregorian, days from civil).
fn unix(y: i64, m: i64, d: i64, h: i64, min: i64, s: i64) -> f64 {
    let (y, m) = if m <= 2 { (y - 1, m + 9) } else { (y, m - 3) };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * m + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    (days * 86_400 + h * 3600 + min * 60 + s) as f64
}

#[test]
fn unix_helper_matches_the_reference_time() {
    assert_eq!(unix(2003, 10, 17, 19, 30, 30), SPA_UNIX);
    assert_eq!(unix(1970, 1, 1, 0, 0, 0), 0.0);
}

#[test]
fn spa_reference_case_zenith_and_azimuth() {
    let p = spa_reference();
    assert!(
        (p.zenith_deg - 50.11162).abs() < 1e-3,
        "zenith {}",
        p.zenith_deg
    );
    assert!(
        (p.azimuth_deg - 194.34024).abs() < 1e-3,
        "azimuth {}",
        p.azimuth_deg
    );
    // Much tighter than the acceptance bound: SPA itself prints 50.111622 and 194.340241.
    assert!((p.zenith_deg - 50.111622).abs() < 1e-5, "{}", p.zenith_deg);
    assert!(
        (p.azimuth_deg - 194.340241).abs() < 1e-5,
        "{}",
        p.azimuth_deg
    );
    assert!((p.elevation_deg - 39.888378).abs() < 1e-5);
    assert!(p.is_up());
}

#[test]
fn spa_reference_case_intermediate_values() {
    let p = spa_reference();
    assert!(
        (p.julian_day - 2_452_930.312847).abs() < 1e-6,
        "{}",
        p.julian_day
    );
    assert!((julian_day(SPA_UNIX) - 2_452_930.312_847_222).abs() < 1e-8);
    assert_eq!(p.delta_t_s, 67.0);
    assert!((p.earth_sun_distance_au - 0.996_542_297_4).abs() < 1e-9);
    assert!((p.right_ascension_deg - 202.22741).abs() < 1e-5);
    assert!((p.declination_deg - -9.31434).abs() < 1e-5);
    // Topocentric elevation without refraction e0 = 39.872046°; refraction Δe = 0.016332°.
    assert!((90.0 - p.zenith_geometric_deg - 39.872046).abs() < 1e-5);
    assert!(
        (p.refraction_deg - 0.016332).abs() < 1e-5,
        "{}",
        p.refraction_deg
    );
}

#[test]
fn spa_reference_case_incidence_on_the_tilted_surface() {
    // Slope 30°, surface azimuth rotation −10° (from south, west positive): the normal
    // points 10° east of south, i.e. azimuth 170° from north, tilted 30° from up.
    let p = spa_reference();
    let (slope, az) = (30f64.to_radians(), 170f64.to_radians());
    let normal = [slope.sin() * az.sin(), slope.sin() * az.cos(), slope.cos()];
    let inc = incidence_angle_deg(&p, normal).unwrap();
    assert!((inc - 25.18700).abs() < 1e-4, "incidence {inc}");
    // Length of the normal does not matter.
    let inc2 = incidence_angle_deg(&p, normal.map(|c| 7.0 * c)).unwrap();
    assert!((inc - inc2).abs() < 1e-9);
}

#[test]
fn default_delta_t_is_close_to_observed_and_hardly_matters() {
    // Observed ΔT (IERS): about 64.6 s in late 2003, 69.36 s at 2020.0.
    let dt2003 = delta_t_estimate_s(SPA_UNIX).unwrap();
    assert!((dt2003 - 64.6).abs() < 1.0, "{dt2003}");
    let dt2020 = delta_t_estimate_s(unix(2020, 1, 1, 0, 0, 0)).unwrap();
    assert!((dt2020 - 69.36).abs() < 1.0, "{dt2020}");

    let p = solar_position(SPA_UNIX, None, &spa_site()).unwrap();
    assert_eq!(p.delta_t_s, dt2003);
    assert!((p.zenith_deg - 50.11162).abs() < 1e-3);
    assert!((p.azimuth_deg - 194.34024).abs() < 1e-3);

    // 10 s of ΔT error moves the sun by about 1e-4°.
    let a = solar_position(SPA_UNIX, Some(67.0), &spa_site()).unwrap();
    let b = solar_position(SPA_UNIX, Some(77.0), &spa_site()).unwrap();
    assert!((a.zenith_deg - b.zenith_deg).abs() < 2e-4);
    assert!((a.azimuth_deg - b.azimuth_deg).abs() < 2e-4);
    assert!(a != b);
}

#[test]
fn direction_is_a_unit_vector_in_east_north_up() {
    let p = spa_reference();
    let d = sun_direction(&p);
    let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    assert!((norm - 1.0).abs() < 1e-12);
    // Afternoon in October at 40° N: south-south-west, up.
    assert!(d[0] < 0.0 && d[1] < 0.0 && d[2] > 0.0, "{d:?}");
    assert!((d[2].asin().to_degrees() - p.elevation_deg).abs() < 1e-9);
    let az = d[0].atan2(d[1]).to_degrees().rem_euclid(360.0);
    assert!((az - p.azimuth_deg).abs() < 1e-9);

    let mut east = p;
    east.azimuth_deg = 90.0;
    east.elevation_deg = 0.0;
    let d = sun_direction(&east);
    assert!((d[0] - 1.0).abs() < 1e-12 && d[1].abs() < 1e-12 && d[2].abs() < 1e-12);
}

/// Time of the highest sun on a day (golden-section search on elevation).
fn solar_noon(day_start: f64, site: &Site) -> f64 {
    let f = |t: f64| solar_position(t, Some(69.0), site).unwrap().elevation_deg;
    // Coarse scan, then refine.
    let mut best = day_start;
    for i in 0..=288 {
        let t = day_start + 300.0 * i as f64;
        if f(t) > f(best) {
            best = t;
        }
    }
    let (mut a, mut b) = (best - 300.0, best + 300.0);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..60 {
        let c = b - g * (b - a);
        let d = a + g * (b - a);
        if f(c) > f(d) {
            b = d;
        } else {
            a = c;
        }
    }
    0.5 * (a + b)
}

#[test]
fn equinox_noon_elevation_is_ninety_minus_latitude() {
    for (lat, lon) in [(40.0, 0.0), (52.5, 13.4), (-34.0, 151.0), (0.0, -78.5)] {
        let site = Site::new(lat, lon, 0.0);
        // Equinox 2024-03-20 03:06 UTC: the day around the local noon of 20 March.
        let start = unix(2024, 3, 20, 0, 0, 0) - lon / 15.0 * 3600.0;
        let noon = solar_noon(start, &site);
        let p = solar_position(noon, Some(69.0), &site).unwrap();
        assert!(
            (p.elevation_deg - (90.0 - lat.abs())).abs() < 0.5,
            "lat {lat}: noon elevation {}",
            p.elevation_deg
        );
        // Local solar noon within 20 minutes of 12:00 mean local time (equation of
        // time about −7.5 min in March).
        let mean_noon = start + 12.0 * 3600.0;
        assert!(
            (noon - mean_noon).abs() < 1200.0,
            "lat {lat}: {noon} vs {mean_noon}"
        );
        if lat > 1.0 {
            assert!((p.azimuth_deg - 180.0).abs() < 0.5, "{}", p.azimuth_deg);
        } else if lat < -1.0 {
            let from_north = p.azimuth_deg.min(360.0 - p.azimuth_deg);
            assert!(from_north < 0.5, "{}", p.azimuth_deg);
        }
    }
}

#[test]
fn sun_is_below_the_horizon_at_local_midnight() {
    for (lat, lon, (y, m, d)) in [
        (40.0, 0.0, (2024, 3, 20)),
        (40.0, -105.0, (2024, 6, 21)),
        (-34.0, 151.0, (2024, 12, 21)),
        (60.0, 25.0, (2024, 12, 21)),
    ] {
        let site = Site::new(lat, lon, 100.0);
        let midnight = unix(y, m, d, 0, 0, 0) - lon / 15.0 * 3600.0;
        let p = solar_position(midnight, None, &site).unwrap();
        assert!(p.elevation_deg < -10.0, "{lat},{lon}: {}", p.elevation_deg);
        assert!(!p.is_up());
        assert!(sun_direction(&p)[2] < 0.0);
        // Deep below the horizon: no refraction.
        assert!(p.elevation_deg < -REFRACTION_CUTOFF_DEG);
        assert_eq!(p.refraction_deg, 0.0);
        assert_eq!(p.zenith_deg, p.zenith_geometric_deg);
    }
}

#[test]
fn azimuth_is_symmetric_around_solar_noon() {
    let site = Site::new(45.0, 7.0, 300.0);
    let start = unix(2024, 6, 10, 0, 0, 0) - 7.0 / 15.0 * 3600.0;
    let noon = solar_noon(start, &site);
    for hours in [1.0, 2.5, 4.0] {
        let am = solar_position(noon - hours * 3600.0, Some(69.0), &site).unwrap();
        let pm = solar_position(noon + hours * 3600.0, Some(69.0), &site).unwrap();
        assert!(am.azimuth_deg < 180.0 && pm.azimuth_deg > 180.0);
        // The declination drifts by about 0.01° in 4 h in June: near-perfect symmetry.
        assert!(
            (am.azimuth_deg + pm.azimuth_deg - 360.0).abs() < 0.05,
            "{hours} h: {} + {}",
            am.azimuth_deg,
            pm.azimuth_deg
        );
        assert!((am.elevation_deg - pm.elevation_deg).abs() < 0.05);
    }
}

#[test]
fn refraction_lifts_the_low_sun_and_grows_with_pressure() {
    // Find a time with the sun just above the horizon (geometric elevation ~0.5°).
    let mut site = Site::new(40.0, 0.0, 0.0);
    let day = unix(2024, 3, 20, 0, 0, 0);
    let mut t = day + 12.0 * 3600.0;
    while solar_position(t, Some(69.0), &site)
        .unwrap()
        .zenith_geometric_deg
        < 89.5
    {
        t += 60.0;
    }
    let low = solar_position(t, Some(69.0), &site).unwrap();
    assert!(
        low.refraction_deg > 0.3 && low.refraction_deg < 0.7,
        "{}",
        low.refraction_deg
    );
    site.pressure_mbar = 700.0;
    let thin = solar_position(t, Some(69.0), &site).unwrap();
    assert!(thin.refraction_deg < low.refraction_deg);
    assert_eq!(thin.zenith_geometric_deg, low.zenith_geometric_deg);
    // Refraction at 40° elevation is about 1 arc minute.
    let high = spa_reference();
    assert!(high.refraction_deg > 0.005 && high.refraction_deg < 0.03);
}

fn out_of_range(e: CoreError) -> (&'static str, f64) {
    match e {
        CoreError::OutOfRange { name, value, .. } => (name, value),
        other => panic!("expected OutOfRange, got {other:?}"),
    }
}

#[test]
fn invalid_sites_name_the_field_and_value() {
    type Case = (fn(&mut Site), &'static str, f64);
    let cases: [Case; 7] = [
        (|s| s.latitude_deg = 91.0, "site.latitude_deg", 91.0),
        (|s| s.latitude_deg = -90.5, "site.latitude_deg", -90.5),
        (|s| s.longitude_deg = 181.0, "site.longitude_deg", 181.0),
        (|s| s.elevation_m = -5000.0, "site.elevation_m", -5000.0),
        (|s| s.pressure_mbar = 0.0, "site.pressure_mbar", 0.0),
        (|s| s.pressure_mbar = -820.0, "site.pressure_mbar", -820.0),
        (|s| s.temperature_c = -300.0, "site.temperature_c", -300.0),
    ];
    for (set, name, value) in cases {
        let mut site = spa_site();
        set(&mut site);
        let e = solar_position(SPA_UNIX, Some(67.0), &site).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains(name), "{msg}");
        assert!(msg.contains(&value.to_string()), "{msg}");
        assert_eq!(out_of_range(e), (name, value));
        assert!(site.validate().is_err());
    }
    let mut site = spa_site();
    site.longitude_deg = f64::NAN;
    let e = solar_position(SPA_UNIX, Some(67.0), &site).unwrap_err();
    assert!(
        matches!(
            e,
            CoreError::NonFinite {
                name: "site.longitude_deg",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("NaN"));
    site.longitude_deg = -105.0;
    site.temperature_c = f64::INFINITY;
    let e = solar_position(SPA_UNIX, Some(67.0), &site).unwrap_err();
    assert!(matches!(
        e,
        CoreError::NonFinite {
            name: "site.temperature_c",
            ..
        }
    ));
    assert!(spa_site().validate().is_ok());
    // Boundaries are valid.
    let pole = Site::new(-90.0, 180.0, 0.0);
    assert!(solar_position(SPA_UNIX, None, &pole).is_ok());
}

#[test]
fn invalid_times_and_delta_t_name_the_value() {
    let site = spa_site();
    let e = solar_position(f64::NAN, Some(67.0), &site).unwrap_err();
    assert!(matches!(
        e,
        CoreError::NonFinite {
            name: "unix_seconds_utc",
            ..
        }
    ));
    let e = solar_position(SPA_UNIX, Some(f64::INFINITY), &site).unwrap_err();
    assert!(matches!(
        e,
        CoreError::NonFinite {
            name: "delta_t_s",
            ..
        }
    ));
    let e = solar_position(SPA_UNIX, Some(1e6), &site).unwrap_err();
    assert_eq!(out_of_range(e), ("delta_t_s", 1e6));

    // Year 7000: beyond SPA's −2000..6000.
    let far = unix(7000, 1, 1, 0, 0, 0);
    let e = solar_position(far, Some(69.0), &site).unwrap_err();
    assert!(e.to_string().contains("-2000 to 6000"), "{e}");
    assert_eq!(out_of_range(e), ("unix_seconds_utc", far));
    // Year 4000: SPA's range, but beyond the ΔT estimate's (−500..3000).
    let later = unix(4000, 1, 1, 0, 0, 0);
    assert!(solar_position(later, Some(69.0), &site).is_ok());
    let e = solar_position(later, None, &site).unwrap_err();
    assert!(e.to_string().contains("-500 to 3000"), "{e}");
    assert_eq!(out_of_range(e), ("unix_seconds_utc", later));
    assert!(delta_t_estimate_s(f64::NEG_INFINITY).is_err());
}

#[test]
fn invalid_normals_are_refused() {
    let p = spa_reference();
    let e = incidence_angle_deg(&p, [0.0, 0.0, 0.0]).unwrap_err();
    assert_eq!(out_of_range(e), ("normal", 0.0));
    let e = incidence_angle_deg(&p, [f64::NAN, 0.0, 1.0]).unwrap_err();
    assert!(matches!(e, CoreError::NonFinite { name: "normal", .. }));
    // Facing the sun: incidence 0; facing away: 180.
    let d = sun_direction(&p);
    assert!(incidence_angle_deg(&p, d).unwrap() < 1e-5);
    assert!((incidence_angle_deg(&p, d.map(|c| -c)).unwrap() - 180.0).abs() < 1e-5);
}

#[test]
fn rayleigh_sky_polarization_peaks_at_ninety_degrees_from_the_sun() {
    let p = spa_reference();
    let s = sun_direction(&p);
    // Towards the sun and the antisolar point: unpolarized.
    assert!(rayleigh_sky_dolp(&p, s, CLEAR_SKY_MAX_DOLP).unwrap() < 1e-12);
    assert!(rayleigh_sky_dolp(&p, s.map(|c| -c), 0.8).unwrap() < 1e-12);
    // 90° from the sun (a horizontal direction perpendicular to its azimuth, or any
    // direction orthogonal to s): the maximum.
    let perp = [s[1], -s[0], 0.0];
    let d = rayleigh_sky_dolp(&p, perp, CLEAR_SKY_MAX_DOLP).unwrap();
    assert!((d - CLEAR_SKY_MAX_DOLP).abs() < 1e-12, "{d}");
    // The zenith, 50.1° from the sun: sin²γ/(1+cos²γ) = 0.4172 of the maximum.
    let z = rayleigh_sky_dolp(&p, [0.0, 0.0, 3.0], 1.0).unwrap();
    let g = p.zenith_deg.to_radians();
    assert!((z - g.sin().powi(2) / (1.0 + g.cos().powi(2))).abs() < 1e-12);
    assert!((z - 0.4172).abs() < 1e-3, "{z}");
    // Errors name the argument.
    let e = rayleigh_sky_dolp(&p, perp, 1.5).unwrap_err();
    assert_eq!(out_of_range(e), ("max_dolp", 1.5));
    let e = rayleigh_sky_dolp(&p, [0.0; 3], 0.7).unwrap_err();
    assert_eq!(out_of_range(e), ("sky_direction", 0.0));
    let e = rayleigh_sky_dolp(&p, [0.0, f64::NAN, 1.0], 0.7).unwrap_err();
    assert!(matches!(
        e,
        CoreError::NonFinite {
            name: "sky_direction",
            ..
        }
    ));
}
