//! The colour maps of every image polarid draws: viridis for scalar values (plots, the
//! `stokes` DoLP view) and the HSV hue wheel for angles (the `stokes` AoLP view).
//!
//! [`VIRIDIS`] is matplotlib's viridis sampled at 10 evenly spaced points; these are
//! exactly matplotlib's `viridis(np.linspace(0, 1, 10))` colours (entries 0, 28, 56, 85,
//! 113, 141, 170, 198, 226 and 255 of its 256-entry table, rounded to 8 bits).
//! [`viridis`] interpolates linearly between them; where viridis bends (its dark purple
//! end) the interpolation strays from matplotlib's curve by up to ~15 of 255 in one
//! channel, elsewhere by a few units.

/// matplotlib's viridis at 10 evenly spaced points (8-bit RGB).
pub const VIRIDIS: [[u8; 3]; 10] = [
    [0x44, 0x01, 0x54],
    [0x48, 0x28, 0x78],
    [0x3e, 0x49, 0x89],
    [0x31, 0x68, 0x8e],
    [0x26, 0x82, 0x8e],
    [0x1f, 0x9e, 0x89],
    [0x35, 0xb7, 0x79],
    [0x6e, 0xce, 0x58],
    [0xb5, 0xde, 0x2b],
    [0xfd, 0xe7, 0x25],
];

/// The viridis colour of `t` in `[0, 1]` (clamped; NaN is treated as 0), piecewise
/// linear between the [`VIRIDIS`] anchors, each channel rounded to the nearest integer.
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + (q as f64 - p as f64) * f).round() as u8;
    std::array::from_fn(|k| mix(a[k], b[k]))
}

/// RGB of hue `h` (degrees), saturation `s` and value `v` in `[0, 1]`.
pub fn hsv(h: f32, s: f32, v: f32) -> [u8; 3] {
    let h = h.rem_euclid(360.0) / 60.0;
    let c = v * s;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r + m, g + m, b + m].map(|u| (u * 255.0).round().clamp(0.0, 255.0) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_hits_its_anchors_and_clamps() {
        for (i, c) in VIRIDIS.iter().enumerate() {
            assert_eq!(viridis(i as f64 / 9.0), *c, "anchor {i}");
        }
        assert_eq!(viridis(-1.0), [68, 1, 84]);
        assert_eq!(viridis(f64::NAN), [68, 1, 84]);
        assert_eq!(viridis(2.0), [253, 231, 37]);
        // Halfway between the first two anchors.
        let mid = viridis(0.5 / 9.0);
        for k in 0..3 {
            let want = (f64::from(VIRIDIS[0][k]) + f64::from(VIRIDIS[1][k])) / 2.0;
            assert!((f64::from(mid[k]) - want).abs() <= 0.5, "{mid:?}");
        }
    }

    #[test]
    fn hue_wheel() {
        assert_eq!(hsv(0.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv(120.0, 1.0, 1.0), [0, 255, 0]);
        assert_eq!(hsv(360.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv(77.0, 0.0, 1.0), [255, 255, 255]);
    }
}
