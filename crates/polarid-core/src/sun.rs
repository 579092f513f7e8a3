//! The sun's position in the sky of a site at a time, to the accuracy of NREL's Solar
//! Position Algorithm (SPA), with atmospheric refraction.
//!
//! # Which implementation, and why
//!
//! The arithmetic is that of the crate [`solar_positioning`] (0.7.2, MIT, by K. Brunner,
//! built without default features: no dependencies, no chrono), which implements SPA
//! (Reda & Andreas, *Solar Position Algorithm for Solar Radiation Applications*,
//! NREL/TP-560-34302, 2003/2008) with its full periodic-term tables, topocentric
//! parallax and SPA's refraction formula. This module wraps it: it validates the inputs
//! into [`CoreError`]s that name the field and value, works in Unix seconds, picks a
//! default ΔT and gives the sun's direction in the scene frame.
//!
//! Measured before choosing, on the SPA report's reference
//! case — 17 Oct 2003 12:30:30 at UTC−7 h, 39.742476° N, 105.1786° W, 1830.14 m,
//! 820 mbar, 11 °C, ΔT = 67 s, ΔUT1 = 0:
//!
//! | quantity | report | this module | difference |
//! | --- | --- | --- | --- |
//! | Julian day | 2452930.312847 | 2452930.3128472 | < 1e-6 d |
//! | Earth–sun distance R | 0.9965422974 AU | 0.9965422974 AU | < 1e-10 AU |
//! | geocentric right ascension α | 202.22741° | 202.227408° | < 1e-5° |
//! | geocentric declination δ | −9.31434° | −9.314340° | < 1e-5° |
//! | topocentric zenith θ (refracted) | 50.11162° | 50.111622° | 2.0e-6° |
//! | topocentric azimuth Φ | 194.34024° | 194.340241° | 5.1e-7° |
//! | topocentric elevation e0 (unrefracted) | 39.872046° | 39.8720459° | < 1e-6° |
//! | incidence on the report's surface (slope 30°, rotation −10°) | 25.18700° | 25.1870002° | 2e-7° |
//!
//! The acceptance bound is 0.001°; the crate's own test suite checks SPA positions
//! against NREL reference data to 0.0003°. The crate is maintained (several releases in
//! 2026, a changelog with accuracy fixes), declares `rust-version = 1.85` (ours: 1.89),
//! has no dependencies with the features we use, and compiles in about 2 s. An own
//! implementation would have meant about 800 lines of periodic-term tables and
//! algorithm to transcribe and keep; the crate was preferred.
//!
//! # Conventions
//!
//! Unlike the rest of this crate (radians), angles here are **degrees**, as in
//! astronomy and in the manifest, and every field says so (`_deg`).
//!
//! - **Time**: Unix seconds (seconds since 1970-01-01T00:00:00Z, leap seconds not
//!   counted), taken as UT1. UTC differs from UT1 by less than 0.9 s, which moves the
//!   sun by at most 0.004° in hour angle; a caller who knows ΔUT1 = UT1 − UTC passes
//!   `unix_seconds_utc + ΔUT1`. RFC 3339 strings are parsed by `polarid_io::time`.
//! - **ΔT** = TT − UT1, in seconds: `None` takes [`delta_t_estimate_s`] (Espenak &
//!   Meeus polynomials, with fits to IERS observations from 2015 on, as kept in
//!   `solar_positioning::delta_t`; within about 1 s of the observed values for
//!   1950–2026, an extrapolation after that). SPA uses ΔT only to place the sun on its
//!   orbit, which it travels at about 1° a day: an error of 1 s in ΔT moves the sun by
//!   about 1.2e-5°, so even 10 s of error is far below the acceptance bound.
//! - **Zenith** ([`SolarPosition::zenith_deg`]): topocentric (seen from the site, with
//!   parallax and the site's elevation) and **refracted** (apparent): SPA's refraction
//!   for the site's pressure and temperature, applied while the unrefracted sun is above
//!   −0.83337° (SPA's atmospheric refraction at sunrise and sunset 0.5667° plus the sun's
//!   radius 0.26667°, the report's values), not below. [`SolarPosition::zenith_geometric_deg`]
//!   is the same without refraction.
//! - **Azimuth** ([`SolarPosition::azimuth_deg`]): from north, eastward (clockwise seen
//!   from above), in [0°, 360°): 90° east, 180° south. (SPA's "astronomers' azimuth" Γ,
//!   westward from south, is Φ − 180°.)
//! - **Elevation** = 90° − zenith (refracted).
//! - **Direction** ([`sun_direction`]): the unit vector from the site towards the sun in
//!   the scene frame of the manifest's `[site]`: x east, y north, z up.
//!
//! # Skylight is polarized
//!
//! Under a clear sky the target is lit by the sun *and* by the sky, and Rayleigh-scattered
//! skylight is partially linearly polarized: up to about 70–80 % in the band 90° from the
//! sun, less near the sun and the antisolar point, and much less under haze or overcast.
//! The paper's model assumes an unpolarized source; see `docs/SUN.md` for where the sky's
//! polarization matters (low-DoLP dielectrics, targets facing away from the sun) and what
//! to do about it (shade the target from the sky, measure the sky's polarization, or keep
//! captures where the sun's specular reflection dominates).

use crate::error::{CoreError, Result, ensure_finite, ensure_range};
use crate::geometry::vec3::dot;
use solar_positioning::{
    Location, RefractionCorrection, SolarPositions, delta_t as sp_delta_t, time::JulianDate,
};

/// Standard sea-level pressure, millibar (hPa): the default of [`Site::pressure_mbar`].
pub const DEFAULT_PRESSURE_MBAR: f64 = 1013.25;

/// Default air temperature for refraction, °C: the default of [`Site::temperature_c`].
pub const DEFAULT_TEMPERATURE_C: f64 = 10.0;

/// Julian day of the Unix epoch, 1970-01-01T00:00:00 UT.
pub const UNIX_EPOCH_JULIAN_DAY: f64 = 2_440_587.5;

/// Seconds per day.
const SECONDS_PER_DAY: f64 = 86_400.0;

/// Largest |ΔT| accepted from a caller, seconds (ΔT is about 70 s today and was about
/// 17 000 s in −500; a day guards against minutes or days passed as seconds in the
/// modern era without rejecting historic values).
pub const MAX_ABS_DELTA_T_S: f64 = 86_400.0;

/// SPA's sun radius plus atmospheric refraction at sunrise and sunset, degrees: the
/// refraction correction is applied while the unrefracted elevation is above minus this.
pub const REFRACTION_CUTOFF_DEG: f64 = 0.26667 + 0.5667;

/// Where the sun is seen from: a point on the Earth and its air.
///
/// Build one with [`Site::new`] (standard pressure and [`DEFAULT_TEMPERATURE_C`]) and set
/// the weather fields when they are known; [`solar_position`] validates every field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Site {
    /// Geodetic latitude, degrees, north positive, in [−90, 90].
    pub latitude_deg: f64,
    /// Longitude, degrees, east positive (west negative), in [−180, 180].
    pub longitude_deg: f64,
    /// Height above mean sea level, metres, in [−1000, 100 000].
    pub elevation_m: f64,
    /// Annual mean (or actual) local air pressure, millibar (hPa), in (0, 2000]:
    /// station pressure, not reduced to sea level (about 820 mbar at 1830 m).
    pub pressure_mbar: f64,
    /// Annual mean (or actual) local air temperature, °C, in (−273, 100].
    pub temperature_c: f64,
}

impl Site {
    /// A site at the given latitude, longitude (degrees, east positive) and elevation
    /// (metres), with [`DEFAULT_PRESSURE_MBAR`] and [`DEFAULT_TEMPERATURE_C`].
    ///
    /// Not validated here: [`Site::validate`] and [`solar_position`] do it.
    pub fn new(latitude_deg: f64, longitude_deg: f64, elevation_m: f64) -> Self {
        Site {
            latitude_deg,
            longitude_deg,
            elevation_m,
            pressure_mbar: DEFAULT_PRESSURE_MBAR,
            temperature_c: DEFAULT_TEMPERATURE_C,
        }
    }

    /// Check every field against the ranges of its documentation.
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] naming the field
    /// (`site.latitude_deg`, ...) and its value.
    pub fn validate(&self) -> Result<()> {
        ensure_range(
            "site.latitude_deg",
            self.latitude_deg,
            -90.0,
            90.0,
            "-90 to 90 degrees, north positive",
        )?;
        ensure_range(
            "site.longitude_deg",
            self.longitude_deg,
            -180.0,
            180.0,
            "-180 to 180 degrees, east positive",
        )?;
        ensure_range(
            "site.elevation_m",
            self.elevation_m,
            -1000.0,
            100_000.0,
            "-1000 to 100000 metres above sea level",
        )?;
        ensure_finite("site.pressure_mbar", self.pressure_mbar)?;
        if !(self.pressure_mbar > 0.0 && self.pressure_mbar <= 2000.0) {
            return Err(CoreError::OutOfRange {
                name: "site.pressure_mbar",
                value: self.pressure_mbar,
                expected: "more than 0 and at most 2000 millibar",
            });
        }
        ensure_finite("site.temperature_c", self.temperature_c)?;
        if !(self.temperature_c > -273.0 && self.temperature_c <= 100.0) {
            return Err(CoreError::OutOfRange {
                name: "site.temperature_c",
                value: self.temperature_c,
                expected: "more than -273 and at most 100 degrees Celsius",
            });
        }
        Ok(())
    }
}

/// The sun seen from a [`Site`] at a time (all angles in degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolarPosition {
    /// Topocentric zenith angle with refraction (apparent), degrees, in [0, 180].
    pub zenith_deg: f64,
    /// Topocentric azimuth, degrees from north eastward, in [0, 360).
    pub azimuth_deg: f64,
    /// Apparent elevation above the horizon, degrees: `90 − zenith_deg`.
    pub elevation_deg: f64,
    /// Topocentric zenith angle without refraction (geometric), degrees.
    pub zenith_geometric_deg: f64,
    /// Refraction correction, degrees: `zenith_geometric_deg − zenith_deg` (≥ 0; zero
    /// when the sun is more than [`REFRACTION_CUTOFF_DEG`] below the horizon).
    pub refraction_deg: f64,
    /// Julian day (UT) of the time.
    pub julian_day: f64,
    /// ΔT = TT − UT1 used, seconds (the caller's, or the estimate).
    pub delta_t_s: f64,
    /// Earth–sun distance, astronomical units.
    pub earth_sun_distance_au: f64,
    /// Geocentric apparent right ascension, degrees, in [0, 360).
    pub right_ascension_deg: f64,
    /// Geocentric apparent declination, degrees.
    pub declination_deg: f64,
}

impl SolarPosition {
    /// True when the sun's apparent centre is above the horizon (elevation > 0).
    pub fn is_up(&self) -> bool {
        self.elevation_deg > 0.0
    }
}

/// Most times [`sun_path`] evaluates.
pub const MAX_SUN_PATH_STEPS: usize = 100_000;

/// The sun over a time window: [`solar_position`] at `start`, `start + step`, … up to
/// `end` (Unix seconds UTC, both included when `end − start` is a whole number of steps),
/// `ΔT` estimated, keeping the times when the sun is up ([`SolarPosition::is_up`]).
///
/// # Errors
/// [`CoreError::NonFinite`] or [`CoreError::OutOfRange`] for a bad site, a window with
/// `end < start`, a step that is not positive or that gives more than
/// [`MAX_SUN_PATH_STEPS`] times; those of [`solar_position`].
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn sun_path(
    site: &Site,
    start_unix_s: f64,
    end_unix_s: f64,
    step_s: f64,
) -> Result<Vec<(f64, SolarPosition)>> {
    site.validate()?;
    ensure_finite("start", start_unix_s)?;
    ensure_finite("end", end_unix_s)?;
    ensure_finite("step", step_s)?;
    if !(end_unix_s >= start_unix_s) {
        return Err(CoreError::OutOfRange {
            name: "end",
            value: end_unix_s,
            expected: "a time not before the start",
        });
    }
    if !(step_s > 0.0) {
        return Err(CoreError::OutOfRange {
            name: "step",
            value: step_s,
            expected: "more than 0 seconds",
        });
    }
    let steps = ((end_unix_s - start_unix_s) / step_s + 1e-9).floor();
    if steps >= MAX_SUN_PATH_STEPS as f64 {
        return Err(CoreError::OutOfRange {
            name: "step",
            value: step_s,
            expected: "a step giving at most 100000 times over the window",
        });
    }
    let mut out = Vec::new();
    for i in 0..=(steps as usize) {
        let t = start_unix_s + i as f64 * step_s;
        let pos = solar_position(t, None, site)?;
        if pos.is_up() {
            out.push((t, pos));
        }
    }
    Ok(out)
}

/// Julian day (UT) of a Unix time: `2440587.5 + unix_seconds / 86400`.
#[inline]
pub fn julian_day(unix_seconds_utc: f64) -> f64 {
    UNIX_EPOCH_JULIAN_DAY + unix_seconds_utc / SECONDS_PER_DAY
}

/// Estimated ΔT = TT − UT1 at a Unix time, seconds.
///
/// Espenak & Meeus's polynomials, with fits to IERS observations from 2015 on and an
/// extrapolation after 2026 (`solar_positioning::delta_t::estimate`): about 64.5 s in
/// 2003, 69.4 s in 2020. Within about 1 s of the observed ΔT for 1950–2026; an error of
/// 1 s in ΔT moves the computed sun by about 1.2e-5° (see the module documentation).
///
/// # Errors
/// [`CoreError::NonFinite`] for a non-finite time, [`CoreError::OutOfRange`] outside the
/// years −500 to 3000 that the polynomials cover.
pub fn delta_t_estimate_s(unix_seconds_utc: f64) -> Result<f64> {
    ensure_finite("unix_seconds_utc", unix_seconds_utc)?;
    // Decimal year, Gregorian mean year from 2000-01-01T00:00 UT (JD 2451544.5); ΔT
    // varies slowly enough that this approximation of the calendar is immaterial.
    let year = 2000.0 + (julian_day(unix_seconds_utc) - 2_451_544.5) / 365.2425;
    sp_delta_t::estimate(year).map_err(|_| CoreError::OutOfRange {
        name: "unix_seconds_utc",
        value: unix_seconds_utc,
        expected: "a time in the years -500 to 3000 (range of the ΔT estimate)",
    })
}

/// The sun seen from `site` at `unix_seconds_utc` (taken as UT1), by NREL's SPA.
///
/// `delta_t_s` is ΔT = TT − UT1 in seconds, or `None` for [`delta_t_estimate_s`].
///
/// # Errors
/// - the site's fields: see [`Site::validate`];
/// - `unix_seconds_utc` not finite, or outside the years −2000 to 6000 of SPA (or
///   −500 to 3000 with `delta_t_s = None`): [`CoreError::NonFinite`] /
///   [`CoreError::OutOfRange`] named `unix_seconds_utc`;
/// - `delta_t_s` not finite or beyond ±[`MAX_ABS_DELTA_T_S`]: named `delta_t_s`;
/// - anything else the algorithm refuses: [`CoreError::SolarPosition`].
///
/// # Example
/// The SPA report's reference case, 2003-10-17T12:30:30-07:00 at Golden, Colorado:
/// ```
/// use polarid_core::sun::{Site, solar_position, sun_direction};
///
/// let mut site = Site::new(39.742476, -105.1786, 1830.14);
/// site.pressure_mbar = 820.0;
/// site.temperature_c = 11.0;
/// let sun = solar_position(1_066_419_030.0, Some(67.0), &site)?;
/// assert!((sun.zenith_deg - 50.11162).abs() < 1e-3);
/// assert!((sun.azimuth_deg - 194.34024).abs() < 1e-3);
/// let [east, north, up] = sun_direction(&sun);
/// assert!(east < 0.0 && north < 0.0 && up > 0.0); // south-south-west, above the horizon
/// # Ok::<(), polarid_core::CoreError>(())
/// ```
pub fn solar_position(
    unix_seconds_utc: f64,
    delta_t_s: Option<f64>,
    site: &Site,
) -> Result<SolarPosition> {
    site.validate()?;
    ensure_finite("unix_seconds_utc", unix_seconds_utc)?;
    let delta_t_s = match delta_t_s {
        Some(dt) => ensure_range(
            "delta_t_s",
            dt,
            -MAX_ABS_DELTA_T_S,
            MAX_ABS_DELTA_T_S,
            "-86400 to 86400 seconds (TT - UT1, about 69 s in 2000-2030)",
        )?,
        None => delta_t_estimate_s(unix_seconds_utc)?,
    };
    let jd = julian_day(unix_seconds_utc);
    let other = |e: solar_positioning::Error| CoreError::SolarPosition {
        unix_seconds: unix_seconds_utc,
        reason: e.to_string(),
    };
    let time = JulianDate::new(jd, delta_t_s).map_err(other)?;
    let prepared = SolarPositions::new()
        .for_time_from_julian(time)
        .map_err(|e| match e {
            solar_positioning::Error::InvalidDateTime { .. } => CoreError::OutOfRange {
                name: "unix_seconds_utc",
                value: unix_seconds_utc,
                expected: "a time in the years -2000 to 6000 (range of SPA)",
            },
            e => other(e),
        })?;
    let location = Location {
        latitude: site.latitude_deg,
        longitude: site.longitude_deg,
    };
    let refraction =
        RefractionCorrection::new(site.pressure_mbar, site.temperature_c).map_err(other)?;
    let apparent = prepared
        .at(location, site.elevation_m, Some(refraction))
        .map_err(other)?;
    let geometric = prepared
        .at(location, site.elevation_m, None)
        .map_err(other)?;
    let earth_sun_distance_au =
        prepared
            .earth_radius_vector()
            .ok_or_else(|| CoreError::SolarPosition {
                unix_seconds: unix_seconds_utc,
                reason: "SPA gave no Earth-sun distance".to_string(),
            })?;
    let zenith_deg = apparent.zenith_angle();
    let pos = SolarPosition {
        zenith_deg,
        azimuth_deg: apparent.azimuth(),
        elevation_deg: 90.0 - zenith_deg,
        zenith_geometric_deg: geometric.zenith_angle(),
        refraction_deg: geometric.zenith_angle() - zenith_deg,
        julian_day: jd,
        delta_t_s,
        earth_sun_distance_au,
        right_ascension_deg: prepared.right_ascension(),
        declination_deg: prepared.declination(),
    };
    for (name, value) in [
        ("zenith_deg", pos.zenith_deg),
        ("azimuth_deg", pos.azimuth_deg),
        ("earth_sun_distance_au", pos.earth_sun_distance_au),
    ] {
        if !value.is_finite() {
            return Err(CoreError::SolarPosition {
                unix_seconds: unix_seconds_utc,
                reason: format!("non-finite {name} {value}"),
            });
        }
    }
    Ok(pos)
}

/// Unit vector from the site towards the sun's apparent (refracted) position, in the
/// scene frame x east, y north, z up:
/// `(cos e · sin Φ, cos e · cos Φ, sin e)` for elevation `e` and azimuth `Φ` (from north,
/// eastward). Its `z` is negative when the sun is below the horizon.
#[inline]
pub fn sun_direction(pos: &SolarPosition) -> [f64; 3] {
    let (se, ce) = pos.elevation_deg.to_radians().sin_cos();
    let (sa, ca) = pos.azimuth_deg.to_radians().sin_cos();
    [ce * sa, ce * ca, se]
}

/// Angle between the sun's apparent direction and a surface normal given in the scene
/// frame (x east, y north, z up; any length), degrees, in [0, 180]: SPA's incidence
/// angle for a tilted surface. Above 90° the sun is behind the surface.
///
/// # Errors
/// [`CoreError::NonFinite`] for a non-finite component, [`CoreError::OutOfRange`] for a
/// zero normal (both named `normal`).
pub fn incidence_angle_deg(pos: &SolarPosition, normal: [f64; 3]) -> Result<f64> {
    Ok(cos_to_sun(pos, "normal", normal)?.acos().to_degrees())
}

/// Cosine of the angle between the sun's apparent direction and `v` (scene frame, any
/// length), clamped to [-1, 1].
///
/// Errors: [`CoreError::NonFinite`] for a non-finite component, [`CoreError::OutOfRange`]
/// for a zero (or overflowing) length, both named `name`.
fn cos_to_sun(pos: &SolarPosition, name: &'static str, v: [f64; 3]) -> Result<f64> {
    for c in v {
        ensure_finite(name, c)?;
    }
    let len = dot(v, v).sqrt();
    if !(len > 0.0 && len.is_finite()) {
        return Err(CoreError::OutOfRange {
            name,
            value: len,
            expected: "a non-zero, finite length",
        });
    }
    Ok((dot(sun_direction(pos), v) / len).clamp(-1.0, 1.0))
}

/// A typical maximum degree of linear polarization of a clear, blue sky (at 90° from
/// the sun): 0.75. Measured values are about 0.7–0.8 on very clear days, lower with
/// haze, thin cloud, a bright ground or a low sun; an overcast sky is nearly unpolarized.
pub const CLEAR_SKY_MAX_DOLP: f64 = 0.75;

/// Degree of linear polarization of the skylight coming from `sky_direction` (scene
/// frame, from the site towards the sky; any length) in the single-scattering Rayleigh
/// model: `max_dolp · sin²γ / (1 + cos²γ)`, where `γ` is the angle between that
/// direction and the sun ([`sun_direction`]). Zero towards the sun and the antisolar
/// point, `max_dolp` at 90° from the sun; the skylight's electric vector is
/// perpendicular to the plane through the sun, the site and the sky point.
///
/// A first estimate only (the real sky has neutral points, multiple scattering and
/// aerosols): use it to judge whether the sky that a target mirrors towards the camera is
/// strongly polarized, not to correct measurements. See `docs/SUN.md`.
///
/// # Errors
/// `max_dolp` outside [0, 1] or not finite (named `max_dolp`); a non-finite or zero
/// `sky_direction` (named `sky_direction`).
pub fn rayleigh_sky_dolp(
    pos: &SolarPosition,
    sky_direction: [f64; 3],
    max_dolp: f64,
) -> Result<f64> {
    ensure_range("max_dolp", max_dolp, 0.0, 1.0, "0 to 1")?;
    let cos_g = cos_to_sun(pos, "sky_direction", sky_direction)?;
    let cos2 = cos_g * cos_g;
    Ok(max_dolp * (1.0 - cos2) / (1.0 + cos2))
}

#[cfg(test)]
mod sun_path_tests {
    use super::*;

    /// NREL's SPA example site (Golden, Colorado) on 2003-10-17: the path keeps the
    /// daylight times only, each as `solar_position` gives it, and noon is highest.
    #[test]
    fn the_path_is_the_sun_at_each_step_while_it_is_up() {
        let site = Site::new(39.742476, -105.1786, 1830.14);
        // 2003-10-17 00:00 to 24:00 local (UTC-7), hourly.
        let start = 1_066_374_000.0;
        let path = sun_path(&site, start, start + 86_400.0, 3600.0).unwrap();
        assert!(path.len() >= 10 && path.len() <= 13, "{}", path.len());
        for (t, p) in &path {
            assert!(p.is_up());
            assert_eq!(*p, solar_position(*t, None, &site).unwrap());
            assert_eq!((t - start) % 3600.0, 0.0);
        }
        let highest = path
            .iter()
            .max_by(|a, b| a.1.elevation_deg.total_cmp(&b.1.elevation_deg))
            .unwrap();
        let hour = (highest.0 - start) / 3600.0;
        assert!((11.0..=13.0).contains(&hour), "{hour}");
        assert!(sun_path(&site, start, start - 1.0, 60.0).is_err());
        assert!(sun_path(&site, start, start + 60.0, 0.0).is_err());
        assert!(sun_path(&site, start, start + 1e9, 1.0).is_err());
    }
}
