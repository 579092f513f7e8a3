//! Colour polarization mosaics (Sony IMX250MYR and kin, docs/BANDS.md): plates of known
//! per-band optics seen through a 2×2 polarizer block under each colour of a 2×2 colour
//! pattern of blocks ([`ColourPattern`], a 4×4 period), with the sensor model of the
//! monochrome simulator ([`Sensor`]).
//!
//! **Radiometry per band.** Band `b` of a plate has its own index `n_b + i k_b` (and
//! optionally its own diffuse albedo); the roughness σ is a property of the surface's
//! shape and the same in every band. In the far field (collimated source of normal
//! irradiance `E0 = 1`) the radiance Stokes vector of band `b` is that of the monochrome
//! simulator, [`super::plate_radiance`]:
//!
//! ```text
//! L_b = cos θi · ( f00_b + ρd_b/π ,  f10_b ,  f20_b ),     f_b: paper eq. (3) at (n_b, k_b)
//! ```
//!
//! so that with `ρd = 0` each band's DoLP is the paper's eq. (9) at `(n_b, k_b)` and β
//! (eq. 5). For calibrated (perspective) scenes each band's Stokes map comes from
//! [`super::perspective`] rendered with that band's optics; [`render_colour_frame_stokes`]
//! turns the maps into one raw frame.
//!
//! **Sensor.** Raw pixel `(y, x)` lies under the colour filter of band `b` and the
//! polarizer `a = k·45°` of [`ColourPattern::channel_at`]; its expected photo-electrons
//! are `e = ε_b · I_b(a)`, `I_b(a) = (S0_b + S1_b cos 2a + S2_b sin 2a)/2`, where
//! `ε_b = exposure · full_well · r_b` folds the band's relative response `r_b` (filter
//! transmission × quantum efficiency × the source's spectrum; 1 for a flat response) into
//! the exposure. Then Poisson shot noise, Gaussian read noise, the dark level, rounding
//! and clipping, exactly as [`Sensor::sample`], with one random stream per row seeded as
//! in [`super::render_frame`].

use super::{Sensor, check_frame_size, check_rects, polarizer_intensity, sample_frame};
use crate::error::{CoreError, Result, check_len, ensure_finite};
use crate::mosaic::ColourPattern;

/// A rectangle of a colour frame with uniform radiance in every band.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourRect {
    /// Column of the top-left corner.
    pub x: usize,
    /// Row of the top-left corner.
    pub y: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Radiance Stokes vector `(S0, S1, S2)` of each band, in the order of
    /// [`ColourPattern::bands`].
    pub stokes: Vec<[f64; 3]>,
}

/// Check a colour frame's size (non-zero multiples of the 4×4 period), the output
/// buffer and the per-band lists (`name`, length) against the pattern's bands.
fn check_frame(
    width: usize,
    height: usize,
    pattern: &ColourPattern,
    out_len: usize,
    per_band: &[(&'static str, usize)],
    electrons_per_band: &[f64],
) -> Result<()> {
    if width == 0 || height == 0 || !width.is_multiple_of(4) || !height.is_multiple_of(4) {
        return Err(CoreError::InvalidDimensions {
            width,
            height,
            reason: "a colour polarization mosaic has a 4x4 period: width and height must be \
                     non-zero multiples of 4"
                .into(),
        });
    }
    check_frame_size(width, height, &[("out", out_len)])?;
    let nb = pattern.bands().len();
    for &(name, len) in per_band {
        check_len(name, len, nb)?;
    }
    for &e in electrons_per_band {
        ensure_finite("electrons_per_unit", e)?;
        if e < 0.0 {
            return Err(CoreError::OutOfRange {
                name: "electrons_per_unit",
                value: e,
                expected: ">= 0",
            });
        }
    }
    Ok(())
}

/// Render one raw colour polarization frame into `out` (`width × height`, row-major,
/// both non-zero multiples of 4): in each band, the radiance `background[b]` outside the
/// rectangles (the last rectangle holding a pixel wins), `electrons_per_unit[b]` expected
/// electrons per unit radiance behind the pixel's polarizer (module documentation), and
/// the sensor's noise. Deterministic for a given `seed` (rows use independent streams, as
/// [`super::render_frame`]).
///
/// Errors: [`CoreError::InvalidDimensions`] (a frame that is not whole 4×4 periods),
/// [`CoreError::LengthMismatch`] (`out`, or a per-band list — `background`,
/// `electrons_per_unit`, a rectangle's `stokes` — whose length is not the pattern's
/// number of bands), [`CoreError::InvalidRegion`] (a rectangle that is empty or leaves
/// the frame), [`CoreError::NonFinite`] / [`CoreError::OutOfRange`] (a negative or
/// non-finite `electrons_per_unit`), and those of [`Sensor::validate`].
#[allow(clippy::too_many_arguments)]
pub fn render_colour_frame(
    width: usize,
    height: usize,
    rects: &[ColourRect],
    background: &[[f64; 3]],
    pattern: &ColourPattern,
    sensor: &Sensor,
    electrons_per_unit: &[f64],
    seed: u64,
    out: &mut [u16],
) -> Result<()> {
    sensor.validate()?;
    let mut lists = vec![
        ("background", background.len()),
        ("electrons_per_unit", electrons_per_unit.len()),
    ];
    lists.extend(rects.iter().map(|r| ("rect stokes", r.stokes.len())));
    check_frame(
        width,
        height,
        pattern,
        out.len(),
        &lists,
        electrons_per_unit,
    )?;
    check_rects(
        width,
        height,
        rects.iter().map(|r| [r.x, r.y, r.width, r.height]),
    )?;
    let angles = polarizer_angles();
    sample_frame(width, sensor, seed, out, |row, col| {
        let s = rects
            .iter()
            .rev()
            .find(|r| col >= r.x && col < r.x + r.width && row >= r.y && row < r.y + r.height)
            .map_or(background, |r| r.stokes.as_slice());
        let (b, k) = pattern.channel_at(row, col);
        electrons_per_unit[b] * polarizer_intensity(&s[b], angles[k])
    });
    Ok(())
}

/// Render one raw colour polarization frame into `out` (`width × height`, both non-zero
/// multiples of 4) from per-band radiance Stokes maps (`stokes[b]`, each `width × height`,
/// e.g. [`super::PerspectiveScene::render_bands`]), with the sensor
/// model and seeding of [`render_colour_frame`].
///
/// Errors: those of [`render_colour_frame`]; [`CoreError::LengthMismatch`] for a map
/// that is not `width × height` long.
#[allow(clippy::too_many_arguments)]
pub fn render_colour_frame_stokes(
    width: usize,
    height: usize,
    stokes: &[&[[f32; 3]]],
    pattern: &ColourPattern,
    sensor: &Sensor,
    electrons_per_unit: &[f64],
    seed: u64,
    out: &mut [u16],
) -> Result<()> {
    sensor.validate()?;
    check_frame(
        width,
        height,
        pattern,
        out.len(),
        &[
            ("stokes maps", stokes.len()),
            ("electrons_per_unit", electrons_per_unit.len()),
        ],
        electrons_per_unit,
    )?;
    let maps: Vec<_> = stokes.iter().map(|m| ("stokes map", m.len())).collect();
    check_frame_size(width, height, &maps)?;
    let angles = polarizer_angles();
    sample_frame(width, sensor, seed, out, |row, col| {
        let (b, k) = pattern.channel_at(row, col);
        let s = stokes[b][row * width + col].map(f64::from);
        electrons_per_unit[b] * polarizer_intensity(&s, angles[k])
    });
    Ok(())
}

/// The polarizer angle of `k` (radians): `k × 45°` (the `k` of [`ColourPattern::channel_at`]).
fn polarizer_angles() -> [f64; 4] {
    std::array::from_fn(|k| (45.0 * k as f64).to_radians())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dop::dop;
    use crate::mosaic::{ColourMethod, DofpOutputs, Pattern, colour_polar};
    use crate::simulate::{PlateOptics, plate_radiance};
    use crate::stokes::PixelRules;

    /// Copper at 450, 550 and 650 nm (builtin-rgb band means), in the band order of
    /// `RGGB` (R, G, B).
    const COPPER_RGB: [(f64, f64); 3] = [(0.2514, 3.612), (0.9671, 2.6377), (1.2457, 2.3921)];

    fn optics(nk: &[(f64, f64)]) -> Vec<PlateOptics> {
        nk.iter()
            .map(|&(n, k)| PlateOptics {
                n,
                k,
                sigma: 0.2,
                rho_d: 0.0,
            })
            .collect()
    }

    /// Super-pixel reconstruction of `raw`: per band, the mean DoLP of the mean Stokes
    /// vector over the whole frame and its standard error from the pixel scatter.
    fn superpixel_dolp(
        raw: &[u16],
        w: usize,
        pattern: &ColourPattern,
        dark: f32,
    ) -> Vec<(f64, f64)> {
        let (ow, oh) = ColourMethod::Superpixel.output_size(w, raw.len() / w);
        let nb = pattern.bands().len();
        let mut bufs: Vec<[Vec<f32>; 3]> = (0..nb)
            .map(|_| {
                [
                    vec![0f32; ow * oh],
                    vec![0f32; ow * oh],
                    vec![0f32; ow * oh],
                ]
            })
            .collect();
        let outs = bufs
            .iter_mut()
            .map(|[s0, s1, s2]| DofpOutputs {
                s0: Some(s0),
                s1: Some(s1),
                s2: Some(s2),
                ..Default::default()
            })
            .collect();
        let rules = PixelRules {
            dark_level: dark,
            ..Default::default()
        };
        colour_polar(raw, w, pattern, ColourMethod::Superpixel, &rules, outs).unwrap();
        bufs.iter()
            .map(|[s0, s1, s2]| {
                let n = s0.len() as f64;
                let m = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / n;
                let (m0, m1, m2) = (m(s0), m(s1), m(s2));
                let d = m1.hypot(m2) / m0;
                // Per-pixel DoLP scatter -> SE of the mean (S1 dominates: AoLP = 0).
                let var = s0
                    .iter()
                    .zip(s1.iter().zip(s2))
                    .map(|(&a, (&b, &c))| {
                        let p = (b as f64).hypot(c as f64) / a as f64;
                        (p - d) * (p - d)
                    })
                    .sum::<f64>()
                    / (n - 1.0);
                (d, (var / n).sqrt())
            })
            .collect()
    }

    #[test]
    fn superpixel_round_trip_gives_each_bands_eq9_dolp() {
        // simulate -> super-pixel demosaic -> per-band DoLP = eq. (9) at the band's
        // (n, k), within 4 standard errors, for several seeds, patterns and angles.
        let sensor = Sensor {
            dark_level_dn: 64.0,
            ..Sensor::default()
        };
        let patterns = [
            ColourPattern::imx250myr(),
            ColourPattern::new(Pattern::new(&[0.0, 45.0, 135.0, 90.0]).unwrap(), "BGGR").unwrap(),
        ];
        let (w, h) = (64, 48);
        let mut worst = 0.0f64;
        for (pi, pattern) in patterns.iter().enumerate() {
            // Band order of the pattern: R, G, B for RGGB; B, G, R for BGGR.
            let mut nk: Vec<(f64, f64)> = COPPER_RGB.to_vec();
            if pattern.bands()[0] == 'B' {
                nk.reverse();
            }
            let opt = optics(&nk);
            for (si, ti) in [35.0f64, 55.0, 75.0].into_iter().enumerate() {
                let (tr, phi) = (60.0f64.to_radians(), std::f64::consts::PI);
                let stokes: Vec<[f64; 3]> = opt
                    .iter()
                    .map(|o| plate_radiance(o, ti.to_radians(), tr, phi).unwrap())
                    .collect();
                let rect = ColourRect {
                    x: 0,
                    y: 0,
                    width: w,
                    height: h,
                    stokes: stokes.clone(),
                };
                // Bright but unsaturated in every band (auto exposure of the peak).
                let peak = stokes
                    .iter()
                    .map(|s| s[0].abs() + s[1].hypot(s[2]))
                    .fold(0.0, f64::max)
                    / 2.0;
                let epu = vec![0.7 * sensor.full_well_e / peak; 3];
                let mut raw = vec![0u16; w * h];
                let bg = vec![[0.0; 3]; 3];
                let seed = 100 * pi as u64 + si as u64;
                render_colour_frame(w, h, &[rect], &bg, pattern, &sensor, &epu, seed, &mut raw)
                    .unwrap();
                let got = superpixel_dolp(&raw, w, pattern, 64.0);
                let beta = (0.5 * (ti + 60.0)).to_radians();
                for (b, &(d, se)) in got.iter().enumerate() {
                    let want = dop(nk[b].0, nk[b].1, beta);
                    let z = (d - want) / se;
                    worst = worst.max(z.abs());
                    assert!(
                        z.abs() < 4.0,
                        "pattern {pi}, ti {ti}, band {b}: {d} vs {want} (se {se})"
                    );
                    assert!(se < 0.01, "se {se}");
                }
                // The three bands differ by far more than the noise (dispersion).
                assert!((got[0].0 - got[2].0).abs() > 10.0 * got[0].1, "{got:?}");
            }
        }
        assert!(worst > 0.0);
    }

    #[test]
    fn noiseless_render_puts_each_band_under_its_filter_and_polarizer() {
        let sensor = Sensor {
            shot_noise: false,
            read_noise_e: 0.0,
            ..Sensor::default()
        };
        let g = sensor.gain_e_per_dn();
        let pattern = ColourPattern::imx250myr();
        // Band b: S0 = 1, S1 = 0.5 (b = 0), 0 (b = 1), -0.5 (b = 2); epu = 1000 g per band.
        let stokes = vec![[1.0, 0.5, 0.0], [1.0, 0.0, 0.25], [1.0, -0.5, 0.0]];
        let rect = ColourRect {
            x: 0,
            y: 0,
            width: 8,
            height: 8,
            stokes: stokes.clone(),
        };
        let mut raw = vec![0u16; 64];
        let epu = [1000.0 * g, 1000.0 * g, 2000.0 * g];
        render_colour_frame(
            8,
            8,
            &[rect],
            &[[0.0; 3]; 3],
            &pattern,
            &sensor,
            &epu,
            1,
            &mut raw,
        )
        .unwrap();
        for y in 0..8 {
            for x in 0..8 {
                let (b, k) = pattern.channel_at(y, x);
                let a = (45.0 * k as f64).to_radians();
                let want = (epu[b] / g * polarizer_intensity(&stokes[b], a)).round();
                assert_eq!(raw[y * 8 + x] as f64, want, "({y}, {x})");
            }
        }
        // IMX250MYR: (0, 0) is R under 90°: (1 - 0.5)/2 * 1000 = 250 DN.
        assert_eq!(raw[0], 250);
        // The same radiance as per-band maps gives the same frame.
        let maps: Vec<Vec<[f32; 3]>> = stokes
            .iter()
            .map(|s| vec![s.map(|x| x as f32); 64])
            .collect();
        let refs: Vec<&[[f32; 3]]> = maps.iter().map(|m| m.as_slice()).collect();
        let mut raw2 = vec![0u16; 64];
        render_colour_frame_stokes(8, 8, &refs, &pattern, &sensor, &epu, 1, &mut raw2).unwrap();
        assert_eq!(raw, raw2);
        // And with noise, the same seed gives the same frame both ways.
        let noisy = Sensor::default();
        let rect = ColourRect {
            x: 0,
            y: 0,
            width: 8,
            height: 8,
            stokes,
        };
        let (mut a, mut b) = (vec![0u16; 64], vec![0u16; 64]);
        render_colour_frame(
            8,
            8,
            &[rect],
            &[[0.0; 3]; 3],
            &pattern,
            &noisy,
            &epu,
            9,
            &mut a,
        )
        .unwrap();
        render_colour_frame_stokes(8, 8, &refs, &pattern, &noisy, &epu, 9, &mut b).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn bad_frames_and_band_lists_are_refused() {
        let s = Sensor::default();
        let p = ColourPattern::imx250myr();
        let bg = [[0.0; 3]; 3];
        let mut out = vec![0u16; 6 * 8];
        let e = render_colour_frame(6, 8, &[], &bg, &p, &s, &[1.0; 3], 0, &mut out);
        assert!(matches!(
            e,
            Err(CoreError::InvalidDimensions { width: 6, .. })
        ));
        let mut out = vec![0u16; 64];
        let e = render_colour_frame(8, 8, &[], &bg[..2], &p, &s, &[1.0; 3], 0, &mut out);
        assert!(matches!(
            e,
            Err(CoreError::LengthMismatch {
                name: "background",
                expected: 3,
                got: 2
            })
        ));
        let rect = ColourRect {
            x: 4,
            y: 0,
            width: 8,
            height: 4,
            stokes: vec![[1.0, 0.0, 0.0]; 3],
        };
        let e = render_colour_frame(8, 8, &[rect], &bg, &p, &s, &[1.0; 3], 0, &mut out);
        assert!(matches!(e, Err(CoreError::InvalidRegion { x: 4, .. })));
        let e = render_colour_frame(8, 8, &[], &bg, &p, &s, &[1.0, f64::NAN, 1.0], 0, &mut out);
        assert!(e.is_err());
        let short = vec![[0f32; 3]; 63];
        let maps: Vec<&[[f32; 3]]> = vec![&short; 3];
        let e = render_colour_frame_stokes(8, 8, &maps, &p, &s, &[1.0; 3], 0, &mut out);
        assert!(matches!(
            e,
            Err(CoreError::LengthMismatch {
                name: "stokes map",
                ..
            })
        ));
    }
}
