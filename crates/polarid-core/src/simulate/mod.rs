//! Synthetic polarimetric captures: plates of known optics seen by a noisy sensor.
//!
//! Radiometry (per capture, collimated unpolarized source of normal irradiance `E0`):
//! the radiance Stokes vector leaving a plate towards the camera is
//!
//! ```text
//! L = E0 cos θi · ( f00 + ρd/π ,  f10 ,  f20 )
//! ```
//!
//! with `f` the Priest–Meier pBRDF (paper eq. 3) in the camera beam's global s/p frame and
//! `ρd` the albedo of an optional Lambertian, fully depolarizing diffuse component.
//! The camera's image +x axis is the camera beam's `s = unit(z × k)` and image up (−y)
//! is `p = k × s`, so with the polarizer-angle convention of `CONVENTIONS.md` the image
//! Stokes vector equals the s/p one (`S1 = I_s − I_p`). In the paper's geometry
//! (`φ = 180°`) `f20 = 0` and the light is s-polarized: `AoLP = 0°`.
//!
//! Sensor: expected photo-electrons `e = exposure · gain_scale · I(a)` with
//! `I(a) = (S0 + S1 cos 2a + S2 sin 2a)/2`; Poisson shot noise, Gaussian read noise,
//! conversion to DN with the gain that maps the full well onto the ADC range above the
//! dark level, rounding, and clipping to `[0, 2^bits − 1]` (saturation).
//!
//! Calibrated scenes (a perspective camera, plates on planes, a lamp at a finite
//! distance or the sun): [`perspective`] renders a Stokes vector per pixel, and
//! [`render_frame_stokes`] turns such a map into a raw frame with the same sensor model.
//!
//! Colour polarization cameras ([`colour`]): per-band optics, one raw colour mosaic per
//! capture ([`render_colour_frame`], [`render_colour_frame_stokes`]).

pub mod colour;
pub mod imperfect;
pub mod perspective;

pub use colour::{ColourRect, render_colour_frame, render_colour_frame_stokes};
pub use perspective::{
    BandStokesMaps, Light, PerspectiveScene, PixelHit, PlanarPlate, plate_stokes,
};

use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;
use rand_distr::{Distribution, Normal, Poisson};
use rayon::prelude::*;

use crate::error::{CoreError, Result, check_len, ensure_finite, ensure_range};

/// A linear sensor with shot and read noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    /// ADC bit depth (1–16).
    pub bit_depth: u32,
    /// Full-well capacity, electrons (the charge that reaches the top of the ADC range).
    pub full_well_e: f64,
    /// Read noise, electrons rms.
    pub read_noise_e: f64,
    /// Dark level (offset), DN.
    pub dark_level_dn: f64,
    /// Draw Poisson shot noise (false: noiseless expected values, still quantized).
    pub shot_noise: bool,
}

impl Default for Sensor {
    /// A 12-bit machine-vision sensor: 10 000 e⁻ full well, 3 e⁻ read noise, no offset.
    fn default() -> Self {
        Self {
            bit_depth: 12,
            full_well_e: 10_000.0,
            read_noise_e: 3.0,
            dark_level_dn: 0.0,
            shot_noise: true,
        }
    }
}

impl Sensor {
    /// Validate the parameters.
    pub fn validate(&self) -> Result<()> {
        if !(1..=16).contains(&self.bit_depth) {
            return Err(CoreError::OutOfRange {
                name: "bit_depth",
                value: self.bit_depth as f64,
                expected: "1 to 16",
            });
        }
        ensure_range(
            "full_well_e",
            self.full_well_e,
            1.0,
            1e9,
            "1 to 1e9 electrons",
        )?;
        ensure_range(
            "read_noise_e",
            self.read_noise_e,
            0.0,
            1e6,
            ">= 0 electrons",
        )?;
        ensure_range(
            "dark_level_dn",
            self.dark_level_dn,
            0.0,
            self.max_dn() - 1.0,
            "0 <= dark level < the ADC maximum",
        )?;
        Ok(())
    }

    /// Largest raw value, `2^bits − 1` (the saturation level).
    #[inline]
    pub fn max_dn(&self) -> f64 {
        ((1u32 << self.bit_depth) - 1) as f64
    }

    /// Electrons per DN.
    #[inline]
    pub fn gain_e_per_dn(&self) -> f64 {
        self.full_well_e / (self.max_dn() - self.dark_level_dn)
    }

    /// One raw sample for `electrons` expected photo-electrons.
    #[inline]
    pub fn sample(&self, electrons: f64, rng: &mut Xoshiro256PlusPlus) -> u16 {
        let e = electrons.max(0.0);
        let mut q = if self.shot_noise && e > 0.0 {
            match Poisson::new(e) {
                Ok(p) => p.sample(rng),
                Err(_) => e,
            }
        } else {
            e
        };
        if self.read_noise_e > 0.0
            && let Ok(nd) = Normal::new(0.0, self.read_noise_e)
        {
            q += nd.sample(rng);
        }
        let dn = (self.dark_level_dn + q / self.gain_e_per_dn()).round();
        dn.clamp(0.0, self.max_dn()) as u16
    }

    /// Raw DN above the dark level per unit of radiance behind the polarizer at relative
    /// exposure 1: `2^bits − 1 − dark`. At exposure `x`, a radiance `I` behind the
    /// polarizer gives `x · I · full_well` expected electrons, i.e.
    /// `x · I · dn_per_unit()` DN above the dark level, so `S0 (DN) / x` is the radiance
    /// in these units whatever the exposure (the manifest's `exposure` convention).
    #[inline]
    pub fn dn_per_unit(&self) -> f64 {
        self.max_dn() - self.dark_level_dn
    }

    /// Expected electrons per unit radiance behind the polarizer at relative exposure
    /// `exposure` (`exposure · full_well`), the `electrons_per_unit` of [`render_frame`].
    #[inline]
    pub fn electrons_per_unit(&self, exposure: f64) -> f64 {
        exposure * self.full_well_e
    }
}

/// How the exposure of a capture is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Exposure {
    /// A fixed relative exposure (time × gain): a radiance `I` behind the polarizer gives
    /// `exposure · I · full_well` electrons.
    Fixed(f64),
    /// Per capture, the exposure that brings the brightest plate pixel (noise-free,
    /// brightest polarizer angle) to `fraction` of the full scale above the dark level.
    Auto {
        /// Fraction of the full scale, in (0, 1].
        fraction: f64,
    },
}

impl Exposure {
    /// Validate the parameters.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Exposure::Fixed(x) => ensure_range("exposure", x, 1e-12, 1e12, "> 0")?,
            Exposure::Auto { fraction } => {
                ensure_range("exposure fraction", fraction, 1e-6, 1.0, "in (0, 1]")?
            }
        };
        Ok(())
    }

    /// The relative exposure of a capture whose brightest plate pixel has the expected
    /// radiance `peak` behind the polarizer (see [`peak_intensity`]). An auto exposure of
    /// a capture with no light (`peak <= 0`) is 1.
    pub fn resolve(&self, peak: f64) -> Result<f64> {
        self.validate()?;
        ensure_finite("peak intensity", peak)?;
        Ok(match *self {
            Exposure::Fixed(x) => x,
            Exposure::Auto { fraction } if peak > 0.0 => fraction / peak,
            Exposure::Auto { .. } => 1.0,
        })
    }
}

/// The largest noise-free intensity `(S0 + S1 cos 2a + S2 sin 2a)/2` over the Stokes
/// vectors `stokes` and the polarizer angles `angles` (radians); 0 when either is empty.
pub fn peak_intensity(stokes: &[[f64; 3]], angles: &[f64]) -> f64 {
    let mut peak = 0.0f64;
    for s in stokes {
        for &a in angles {
            peak = peak.max(polarizer_intensity(s, a));
        }
    }
    peak
}

/// DoLP `sqrt(S1² + S2²) / S0` of a Stokes vector (0 when `S0 <= 0`).
#[inline]
pub fn stokes_dolp(s: &[f64; 3]) -> f64 {
    if s[0] > 0.0 {
        s[1].hypot(s[2]) / s[0]
    } else {
        0.0
    }
}

/// A well-mixed 64-bit seed for frame `frame` of capture `capture` of a simulation with
/// seed `seed` (SplitMix64 finaliser), so frames have independent noise streams.
pub fn frame_seed(seed: u64, capture: u64, frame: u64) -> u64 {
    let mut z = seed
        .wrapping_add(capture.wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(frame.wrapping_mul(0xD1B5_4A32_D192_ED03))
        .wrapping_add(0x2545_F491_4F6C_DD1D);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Optics of a plate: complex index, roughness, and diffuse albedo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateOptics {
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index (≥ 0).
    pub k: f64,
    /// Priest–Meier slope parameter σ (per-axis slope standard deviation), > 0.
    pub sigma: f64,
    /// Albedo of the Lambertian depolarized component (0 for the paper's pure specular
    /// model).
    pub rho_d: f64,
}

impl PlateOptics {
    /// Validate the parameters.
    pub fn validate(&self) -> Result<()> {
        ensure_range("n", self.n, 1e-6, 100.0, "0 < n <= 100")?;
        ensure_range("k", self.k, 0.0, 100.0, "0 <= k <= 100")?;
        ensure_range("sigma", self.sigma, 1e-6, 10.0, "0 < sigma <= 10")?;
        ensure_range("rho_d", self.rho_d, 0.0, 1.0, "0 <= rho_d <= 1")?;
        Ok(())
    }
}

/// Radiance Stokes vector `(S0, S1, S2)` in the camera's image frame, per unit normal
/// irradiance, of a plate lit from zenith `theta_i` and seen from zenith `theta_r` with
/// azimuth difference `phi` (radians): `cos θi · (f00 + ρd/π, f10, f20)`, `f` from
/// paper eq. (3) in the global s/p frame.
pub fn plate_radiance(
    optics: &PlateOptics,
    theta_i: f64,
    theta_r: f64,
    phi: f64,
) -> Result<[f64; 3]> {
    optics.validate()?;
    let f = crate::pbrdf::pbrdf(optics.n, optics.k, optics.sigma, theta_i, theta_r, phi)?;
    let g = f.global;
    let ci = theta_i.cos();
    Ok([
        ci * (g[0][0] + optics.rho_d / std::f64::consts::PI),
        ci * g[1][0],
        ci * g[2][0],
    ])
}

/// A rectangle of the frame with uniform radiance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UniformRect {
    /// Column of the top-left corner.
    pub x: usize,
    /// Row of the top-left corner.
    pub y: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Radiance Stokes vector `(S0, S1, S2)` (arbitrary linear units).
    pub stokes: [f64; 3],
}

/// Intensity behind a linear polarizer at angle `a` (radians): `(S0 + S1 cos 2a + S2 sin 2a)/2`.
#[inline]
pub fn polarizer_intensity(s: &[f64; 3], a: f64) -> f64 {
    let (s2a, c2a) = (2.0 * a).sin_cos();
    0.5 * (s[0] + s[1] * c2a + s[2] * s2a)
}

/// Which polarizer angle (radians) each pixel of a frame sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Analyzer {
    /// A rotating polarizer: the same angle everywhere.
    Uniform(f64),
    /// A 2×2 division-of-focal-plane mosaic, row by row from the top-left.
    Mosaic([f64; 4]),
}

impl Analyzer {
    /// The polarizer angle of pixel `(row, col)`.
    #[inline]
    pub fn angle_at(&self, row: usize, col: usize) -> f64 {
        match *self {
            Analyzer::Uniform(a) => a,
            Analyzer::Mosaic(p) => p[(row % 2) * 2 + (col % 2)],
        }
    }
}

/// Render one raw frame into `out` (`width × height`, row-major): background radiance
/// `background` (Stokes) outside the rectangles, sensor noise everywhere.
/// `electrons_per_unit` converts radiance units to expected electrons (exposure ×
/// optical throughput). Deterministic for a given `seed` (rows use independent streams).
#[allow(clippy::too_many_arguments)]
pub fn render_frame(
    width: usize,
    height: usize,
    rects: &[UniformRect],
    background: [f64; 3],
    analyzer: Analyzer,
    sensor: &Sensor,
    electrons_per_unit: f64,
    seed: u64,
    out: &mut [u16],
) -> Result<()> {
    sensor.validate()?;
    ensure_finite("electrons_per_unit", electrons_per_unit)?;
    check_frame_size(width, height, &[("out", out.len())])?;
    check_rects(
        width,
        height,
        rects.iter().map(|r| [r.x, r.y, r.width, r.height]),
    )?;
    sample_frame(width, sensor, seed, out, |row, col| {
        let s = rects
            .iter()
            .rev()
            .find(|r| col >= r.x && col < r.x + r.width && row >= r.y && row < r.y + r.height)
            .map_or(background, |r| r.stokes);
        electrons_per_unit * polarizer_intensity(&s, analyzer.angle_at(row, col))
    });
    Ok(())
}

/// Render one raw frame into `out` (`width × height`, row-major) from a per-pixel
/// radiance Stokes map `stokes` (e.g. of [`PerspectiveScene::render_bands`]), with the sensor
/// model and seeding of [`render_frame`]: `electrons_per_unit · I(a)` expected
/// electrons per pixel behind the polarizer angle `a` of `analyzer`.
#[allow(clippy::too_many_arguments)]
pub fn render_frame_stokes(
    width: usize,
    height: usize,
    stokes: &[[f32; 3]],
    analyzer: Analyzer,
    sensor: &Sensor,
    electrons_per_unit: f64,
    seed: u64,
    out: &mut [u16],
) -> Result<()> {
    sensor.validate()?;
    ensure_finite("electrons_per_unit", electrons_per_unit)?;
    check_frame_size(
        width,
        height,
        &[("stokes map", stokes.len()), ("out", out.len())],
    )?;
    sample_frame(width, sensor, seed, out, |row, col| {
        let s = stokes[row * width + col].map(f64::from);
        electrons_per_unit * polarizer_intensity(&s, analyzer.angle_at(row, col))
    });
    Ok(())
}

/// Check a frame's size: not empty, and every buffer (`name`, length) `width × height`
/// long.
pub(crate) fn check_frame_size(
    width: usize,
    height: usize,
    buffers: &[(&'static str, usize)],
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: "empty frame".into(),
        });
    }
    for &(name, len) in buffers {
        check_len(name, len, width * height)?;
    }
    Ok(())
}

/// Check that every rectangle `[x, y, width, height]` is non-empty and inside the frame.
fn check_rects(
    width: usize,
    height: usize,
    rects: impl IntoIterator<Item = [usize; 4]>,
) -> Result<()> {
    for [x, y, w, h] in rects {
        if w == 0 || h == 0 || x + w > width || y + h > height {
            return Err(CoreError::InvalidRegion {
                x,
                y,
                width: w,
                height: h,
                reason: format!("is empty or leaves the {width}x{height} frame"),
            });
        }
    }
    Ok(())
}

/// Fill `out` (rows of `width` pixels) with raw samples of `electrons(row, col)` expected
/// photo-electrons, in parallel over rows, each row with its own random stream from
/// `seed` (the pixels of a row draw in order).
fn sample_frame(
    width: usize,
    sensor: &Sensor,
    seed: u64,
    out: &mut [u16],
    electrons: impl Fn(usize, usize) -> f64 + Sync,
) {
    out.par_chunks_mut(width)
        .enumerate()
        .for_each(|(row, line)| {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(
                seed ^ (row as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
            );
            for (col, px) in line.iter_mut().enumerate() {
                *px = sensor.sample(electrons(row, col), &mut rng);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stokes_frame_matches_uniform_frame() {
        // The same radiance as a map or as a rectangle gives the same noisy frame.
        let s = Sensor::default();
        let rect = UniformRect {
            x: 0,
            y: 0,
            width: 6,
            height: 4,
            stokes: [2.0, 0.5, -0.25],
        };
        for an in [
            Analyzer::Uniform(0.7),
            Analyzer::Mosaic([1.0, 0.2, 0.3, 0.4]),
        ] {
            let mut a = vec![0u16; 24];
            let mut b = vec![0u16; 24];
            render_frame(6, 4, &[rect], [0.0; 3], an, &s, 900.0, 5, &mut a).unwrap();
            let map = vec![[2.0f32, 0.5, -0.25]; 24];
            render_frame_stokes(6, 4, &map, an, &s, 900.0, 5, &mut b).unwrap();
            assert_eq!(a, b);
        }
        let mut b = vec![0u16; 23];
        let map = vec![[1.0f32, 0.0, 0.0]; 24];
        assert!(
            render_frame_stokes(6, 4, &map, Analyzer::Uniform(0.0), &s, 1.0, 5, &mut b).is_err()
        );
    }

    #[test]
    fn noiseless_sensor_is_linear_and_saturates() {
        let s = Sensor {
            shot_noise: false,
            read_noise_e: 0.0,
            ..Sensor::default()
        };
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
        let g = s.gain_e_per_dn();
        assert_eq!(s.sample(100.0 * g, &mut rng), 100);
        assert_eq!(s.sample(1e9, &mut rng), 4095);
        assert_eq!(s.sample(-5.0, &mut rng), 0);
    }

    #[test]
    fn auto_exposure_hits_the_requested_fraction() {
        let s = Sensor {
            shot_noise: false,
            read_noise_e: 0.0,
            dark_level_dn: 64.0,
            ..Sensor::default()
        };
        let stokes = [[2.0, 1.0, 0.0], [0.5, 0.0, 0.1]];
        let angles = [0.0, std::f64::consts::FRAC_PI_2];
        let peak = peak_intensity(&stokes, &angles);
        assert!((peak - 1.5).abs() < 1e-15);
        let x = Exposure::Auto { fraction: 0.6 }.resolve(peak).unwrap();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
        let dn = s.sample(s.electrons_per_unit(x) * peak, &mut rng);
        // 64 + 0.6 * (4095 - 64) = 2482.6 -> 2483
        assert_eq!(dn, 2483);
        assert_eq!(Exposure::Fixed(0.3).resolve(peak).unwrap(), 0.3);
        assert!(Exposure::Auto { fraction: 1.5 }.resolve(peak).is_err());
        assert!(Exposure::Fixed(0.0).resolve(peak).is_err());
        assert_ne!(frame_seed(1, 0, 0), frame_seed(1, 0, 1));
        assert_ne!(frame_seed(1, 0, 1), frame_seed(1, 1, 0));
    }

    #[test]
    fn specular_plate_dolp_is_eq9() {
        let o = PlateOptics {
            n: 1.24,
            k: 6.6,
            sigma: 0.2,
            rho_d: 0.0,
        };
        for ti in [35.0f64, 50.0, 80.0] {
            let l = plate_radiance(
                &o,
                ti.to_radians(),
                60.0f64.to_radians(),
                std::f64::consts::PI,
            )
            .unwrap();
            let beta = (0.5 * (ti + 60.0)).to_radians();
            let p = crate::dop::dop(o.n, o.k, beta);
            assert!((stokes_dolp(&l) - p).abs() < 1e-12, "ti {ti}");
            assert!(l[0] > 0.0 && l[1] > 0.0, "s-polarized, S1 > 0");
        }
    }

    #[test]
    fn frame_places_rects_and_background() {
        let s = Sensor {
            shot_noise: false,
            read_noise_e: 0.0,
            ..Sensor::default()
        };
        let g = s.gain_e_per_dn();
        let rect = UniformRect {
            x: 2,
            y: 1,
            width: 3,
            height: 2,
            stokes: [2.0, 1.0, 0.0],
        };
        let mut out = vec![0u16; 8 * 4];
        render_frame(
            8,
            4,
            &[rect],
            [0.0; 3],
            Analyzer::Uniform(0.0),
            &s,
            100.0 * g,
            7,
            &mut out,
        )
        .unwrap();
        // I(0) = (2 + 1)/2 = 1.5 units -> 150 DN
        assert_eq!(out[8 + 2], 150);
        assert_eq!(out[0], 0);
        let bad = UniformRect { x: 7, ..rect };
        assert!(
            render_frame(
                8,
                4,
                &[bad],
                [0.0; 3],
                Analyzer::Uniform(0.0),
                &s,
                1.0,
                7,
                &mut out
            )
            .is_err()
        );
    }
}
