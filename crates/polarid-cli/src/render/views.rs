//! PNG views of the `stokes` outputs: S0, DoLP and AoLP.
//!
//! * S0 (`s0.png`): gray levels, black at 0 and white at the 99.5th percentile of the
//!   valid pixels' S0, with gamma 1/2.2 (as the colour preview `s0_rgb.png`).
//! * DoLP (`dolp.png`): the viridis colour map over `[0, max]`, `max` = 1 by default
//!   (a fixed scale, so views of different scenes compare; `--dolp-max auto` picks a
//!   round value above the 99th percentile, [`auto_dolp_max`], for weakly polarized
//!   scenes); values above `max` saturate. A colour bar labelled `0`, `max/2`, `max`
//!   sits under the image.
//! * AoLP (`aolp.png`), [`AolpView`]: `hue` (default) maps AoLP once around the HSV hue
//!   wheel, a cyclic map (0° and 180° meet in red; 45° yellow-green, 90° cyan, 135°
//!   blue-violet), at full saturation and brightness; `hsv` also uses DoLP / `max` as
//!   the value (brightness), so weakly polarized pixels, whose angle is noise, fade to
//!   black, as polarization tools commonly show it. A hue bar labelled `0`, `90`, `180`
//!   (degrees) sits under the image.
//!
//! Rejected pixels are drawn in two colours that none of the maps produces:
//! [`SATURATED_RGB`] (pink-magenta) for saturated pixels and [`DARK_RGB`] (dark slate)
//! for dark or invalid ones (and any pixel whose value is undefined, e.g. DoLP where
//! S0 ≤ 0). Neither is gray (S0 view), on the viridis curve (DoLP view), nor has a zero
//! channel as every colour of the hue wheel has (AoLP views).
//!
//! The colours come from [`crate::render::colormap`], the map the plots use too; the
//! pixels are mapped through look-up tables, rows in parallel.

use std::io::Write;
use std::path::Path;

use polarid_core::stokes::mask;
use polarid_io::IoError;
use rayon::prelude::*;

use super::colormap::{self, hsv};

/// Colour of saturated pixels in every view (pink-magenta).
pub const SATURATED_RGB: [u8; 3] = [255, 96, 255];
/// Colour of dark, invalid or undefined pixels in every view (dark slate).
pub const DARK_RGB: [u8; 3] = [40, 56, 72];

/// How `aolp.png` shows the angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AolpView {
    /// AoLP as hue (cyclic, 0°..180° once around the wheel), full brightness.
    Hue,
    /// AoLP as hue, DoLP / --dolp-max as value (brightness): unpolarized pixels dark.
    Hsv,
}

/// The upper end of the DoLP colour scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DolpScale {
    /// A fixed value in (0, 1].
    Fixed(f32),
    /// [`auto_dolp_max`] of the image.
    Auto,
}

/// Parse `--dolp-max`: `auto` or a number in (0, 1].
pub fn parse_dolp_scale(s: &str) -> Result<DolpScale, String> {
    if s.trim().eq_ignore_ascii_case("auto") {
        return Ok(DolpScale::Auto);
    }
    match s.trim().parse::<f32>() {
        Ok(m) if m > 0.0 && m <= 1.0 => Ok(DolpScale::Fixed(m)),
        _ => Err(format!("expected `auto` or a DoLP in (0, 1], got {s:?}")),
    }
}

impl DolpScale {
    /// The scale's upper end for `dolp`.
    pub fn resolve(self, dolp: &[f32]) -> f32 {
        match self {
            DolpScale::Fixed(m) => m,
            DolpScale::Auto => auto_dolp_max(dolp),
        }
    }
}

/// The `q`-quantile (0..1) of the finite values of a sample of about 200 000 of `v`
/// (`None` when there are none).
pub fn sample_quantile(v: &[f32], q: f64) -> Option<f32> {
    let step = (v.len() / 200_000).max(1);
    let mut s: Vec<f32> = v
        .iter()
        .step_by(step)
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if s.is_empty() {
        return None;
    }
    let k = ((s.len() as f64 * q) as usize).min(s.len() - 1);
    let (_, p, _) = s.select_nth_unstable_by(k, f32::total_cmp);
    Some(*p)
}

/// A round upper limit for the DoLP colour scale: the smallest of 0.01, 0.02, 0.05,
/// 0.1, 0.2, 0.5, 1 at or above the 99th percentile of the finite values (1 when there
/// are none).
pub fn auto_dolp_max(dolp: &[f32]) -> f32 {
    let Some(p) = sample_quantile(dolp, 0.99) else {
        return 1.0;
    };
    for m in [0.01, 0.02, 0.05, 0.1, 0.2, 0.5] {
        if p <= m {
            return m;
        }
    }
    1.0
}

/// The flag colour of pixel `i` from the mask (values of `polarid_core::stokes::mask`),
/// `None` for a valid pixel or without a mask.
fn flag(mask: Option<&[u8]>, i: usize) -> Option<[u8; 3]> {
    match mask.map(|m| m[i]) {
        None | Some(mask::VALID) => None,
        Some(mask::SATURATED) => Some(SATURATED_RGB),
        Some(_) => Some(DARK_RGB),
    }
}

/// Entries of the viridis table minus one: `t` maps to entry `round(t * VIRIDIS_N)`, so
/// 0, 1/2 and 1 hit [`colormap::viridis`] of exactly 0, 0.5 and 1.
const VIRIDIS_N: usize = 1024;

fn viridis_lut() -> Vec<[u8; 3]> {
    (0..=VIRIDIS_N)
        .map(|k| colormap::viridis(k as f64 / VIRIDIS_N as f64))
        .collect()
}

/// Viridis of `t` (clamped to [0, 1]) from the table.
fn viridis_at(lut: &[[u8; 3]], t: f32) -> [u8; 3] {
    lut[(t.clamp(0.0, 1.0) * VIRIDIS_N as f32).round() as usize]
}

/// 3×5 pixel glyphs for digits and '.' (rows top to bottom, 3 bits each).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        _ => return None,
    })
}

/// An RGB image being drawn.
struct Canvas {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

impl Canvas {
    fn set(&mut self, x: usize, y: usize, c: [u8; 3]) {
        if x < self.w && y < self.h {
            let i = 3 * (y * self.w + x);
            self.px[i..i + 3].copy_from_slice(&c);
        }
    }

    fn rect(&mut self, x: usize, y: usize, w: usize, h: usize, c: [u8; 3]) {
        for yy in y..y + h {
            for xx in x..x + w {
                self.set(xx, yy, c);
            }
        }
    }

    /// Text of height `5 s` with its top-left corner at (x, y).
    fn text(&mut self, x: usize, y: usize, s: usize, t: &str, c: [u8; 3]) {
        let mut cx = x;
        for ch in t.chars() {
            if let Some(g) = glyph(ch) {
                for (row, bits) in g.iter().enumerate() {
                    for col in 0..3 {
                        if bits & (4 >> col) != 0 {
                            self.rect(cx + col * s, y + row * s, s, s, c);
                        }
                    }
                }
            }
            cx += 4 * s;
        }
    }
}

fn text_width(t: &str, s: usize) -> usize {
    (4 * t.chars().count()).saturating_sub(1) * s
}

/// The `w × h` image of `pixel(i)` (RGB bytes), rows in parallel.
fn paint(w: usize, h: usize, pixel: impl Fn(usize) -> [u8; 3] + Sync) -> Vec<u8> {
    let mut px = vec![0u8; 3 * w * h];
    if w == 0 {
        return px;
    }
    px.par_chunks_mut(3 * w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.chunks_exact_mut(3).enumerate() {
            out.copy_from_slice(&pixel(y * w + x));
        }
    });
    px
}

/// Image plus a colour bar strip under it: returns (width, height, RGB bytes).
fn with_bar(
    w: usize,
    h: usize,
    image: impl Fn(usize) -> [u8; 3] + Sync,
    bar: impl Fn(f32) -> [u8; 3],
    labels: &[(f32, String)],
) -> (usize, usize, Vec<u8>) {
    let s = (w / 300).max(1);
    let margin = 4 * s;
    let bar_h = 6 * s;
    let strip = margin + bar_h + 2 * s + 5 * s + margin;
    let total_h = h + strip;
    let mut px = paint(w, h, image);
    px.resize(3 * w * total_h, 255);
    let mut c = Canvas { w, h: total_h, px };
    let x0 = margin.min(w / 4);
    let x1 = w.saturating_sub(margin.min(w / 4));
    let y0 = h + margin;
    let span = x1.saturating_sub(x0).max(1);
    for x in x0..x1 {
        let col = bar((x - x0) as f32 / (span - 1).max(1) as f32);
        c.rect(x, y0, 1, bar_h, col);
    }
    for (t, label) in labels {
        let xt = x0 + ((span - 1) as f32 * t.clamp(0.0, 1.0)).round() as usize;
        c.rect(
            xt.saturating_sub(s / 2),
            y0 + bar_h,
            s.max(1),
            2 * s,
            [0, 0, 0],
        );
        let tw = text_width(label, s);
        let lx = xt.saturating_sub(tw / 2).min(w.saturating_sub(tw));
        c.text(lx, y0 + bar_h + 2 * s, s, label, [0, 0, 0]);
    }
    (w, total_h, c.px)
}

fn fmt_label(v: f32) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() {
        "0".into()
    } else {
        s.to_string()
    }
}

/// S0 view: gray `(S0 / p)^(1/2.2)` with `p` the 99.5th percentile of the valid
/// pixels' S0 (1 when there are none or it is not positive); flagged pixels in their
/// colours. Returns RGB bytes, `w × h`.
pub fn s0_view(w: usize, h: usize, s0: &[f32], mask: Option<&[u8]>) -> Vec<u8> {
    let valid: Vec<f32> = match mask {
        Some(m) => {
            let step = (s0.len() / 200_000).max(1);
            s0.iter()
                .zip(m)
                .step_by(step)
                .filter(|(_, m)| **m == mask::VALID)
                .map(|(v, _)| *v)
                .collect()
        }
        None => s0.to_vec(),
    };
    let scale = match sample_quantile(&valid, 0.995) {
        Some(p) if p > 0.0 => p,
        _ => 1.0,
    };
    // Gamma table over [0, 1] in 4096 steps.
    const N: usize = 4096;
    let lut: Vec<u8> = (0..=N)
        .map(|k| ((k as f32 / N as f32).powf(1.0 / 2.2) * 255.0).round() as u8)
        .collect();
    let inv = 1.0 / scale;
    paint(w, h, |i| {
        if let Some(c) = flag(mask, i) {
            return c;
        }
        let v = s0[i] * inv;
        if v.is_nan() {
            return DARK_RGB;
        }
        let g = lut[(v.clamp(0.0, 1.0) * N as f32).round() as usize];
        [g, g, g]
    })
}

/// DoLP view: viridis over `[0, max]` with a scale bar; flagged pixels in their colours.
pub fn dolp_view(
    w: usize,
    h: usize,
    dolp: &[f32],
    mask: Option<&[u8]>,
    max: f32,
) -> (usize, usize, Vec<u8>) {
    let inv = 1.0 / max.max(1e-6);
    let lut = viridis_lut();
    with_bar(
        w,
        h,
        |i| {
            if let Some(c) = flag(mask, i) {
                return c;
            }
            let d = dolp[i];
            if d.is_nan() {
                DARK_RGB
            } else {
                viridis_at(&lut, d * inv)
            }
        },
        |t| viridis_at(&lut, t),
        &[
            (0.0, "0".into()),
            (0.5, fmt_label(max / 2.0)),
            (1.0, fmt_label(max)),
        ],
    )
}

/// Entries of the hue table: AoLP `a` degrees maps to entry `round(a / 180 * HUE_N)`
/// modulo `HUE_N` (0.18° steps).
const HUE_N: usize = 1000;

/// AoLP view ([`AolpView`]): hue from AoLP (degrees, period 180), value 1 or DoLP /
/// `max`; flagged pixels in their colours.
pub fn aolp_view(
    w: usize,
    h: usize,
    aolp: &[f32],
    dolp: &[f32],
    mask: Option<&[u8]>,
    max: f32,
    mode: AolpView,
) -> (usize, usize, Vec<u8>) {
    let inv = 1.0 / max.max(1e-6);
    let hue: Vec<[u8; 3]> = (0..HUE_N)
        .map(|k| hsv(360.0 * k as f32 / HUE_N as f32, 1.0, 1.0))
        .collect();
    with_bar(
        w,
        h,
        |i| {
            if let Some(c) = flag(mask, i) {
                return c;
            }
            let (a, d) = (aolp[i], dolp[i]);
            if a.is_nan() || d.is_nan() {
                return DARK_RGB;
            }
            match mode {
                AolpView::Hue => {
                    let k = (a.rem_euclid(180.0) / 180.0 * HUE_N as f32).round() as usize;
                    hue[k % HUE_N]
                }
                AolpView::Hsv => hsv(2.0 * a, 1.0, (d * inv).clamp(0.0, 1.0)),
            }
        },
        |t| hsv(360.0 * t, 1.0, 1.0),
        &[(0.0, "0".into()), (0.5, "90".into()), (1.0, "180".into())],
    )
}

/// Write an RGB PNG (`w × h × 3` bytes) with fast compression (the views are large and
/// written once; fast deflate is ~10× quicker than the default for ~20% more bytes).
pub fn write_png_fast(path: &Path, w: usize, h: usize, px: &[u8]) -> Result<(), IoError> {
    let bad = |e: String| IoError::io(path, std::io::Error::other(e));
    let (wu, hu) = (
        u32::try_from(w).map_err(|e| bad(e.to_string()))?,
        u32::try_from(h).map_err(|e| bad(e.to_string()))?,
    );
    let buf = crate::render::png::encode_rgb8(px, wu, hu)
        .map_err(|e| bad(format!("cannot encode PNG: {e}")))?;
    polarid_io::atomic::write_atomic(path, true, |out: &mut dyn Write| {
        out.write_all(&buf).map_err(|e| IoError::io(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(px: &[u8], w: usize, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * w + x);
        [px[i], px[i + 1], px[i + 2]]
    }

    #[test]
    fn colour_maps() {
        assert_eq!(auto_dolp_max(&[0.03, 0.04, f32::NAN]), 0.05);
        let lut = viridis_lut();
        for t in [0.0, 0.5, 1.0, 0.25] {
            assert_eq!(viridis_at(&lut, t), colormap::viridis(t as f64), "{t}");
        }
        let m = [0, 0, 0, mask::SATURATED, 0, mask::DARK, 0, 0];
        let d = [0.0, 0.5, 1.0, 0.3, 0.1, 0.2, 0.3, f32::NAN];
        let (w, h, px) = dolp_view(4, 2, &d, Some(&m), 1.0);
        assert_eq!(w, 4);
        assert!(h > 2);
        assert_eq!(px.len(), w * h * 3);
        assert_eq!(at(&px, 4, 1, 0), colormap::viridis(0.5));
        assert_eq!(at(&px, 4, 3, 0), SATURATED_RGB);
        assert_eq!(at(&px, 4, 1, 1), DARK_RGB);
        assert_eq!(at(&px, 4, 3, 1), DARK_RGB);
    }

    #[test]
    fn aolp_modes() {
        let a = [0.0, 45.0, 90.0, 179.99];
        let d = [1.0, 0.5, 0.0, 1.0];
        let (_, _, px) = aolp_view(4, 1, &a, &d, None, 1.0, AolpView::Hue);
        assert_eq!(at(&px, 4, 0, 0), [255, 0, 0]);
        assert_eq!(at(&px, 4, 2, 0), [0, 255, 255]);
        assert_eq!(at(&px, 4, 3, 0), [255, 0, 0]);
        let (_, _, px) = aolp_view(4, 1, &a, &d, None, 1.0, AolpView::Hsv);
        assert_eq!(at(&px, 4, 0, 0), [255, 0, 0]);
        assert_eq!(at(&px, 4, 2, 0), [0, 0, 0]);
        assert_eq!(at(&px, 4, 1, 0), hsv(90.0, 1.0, 0.5));
    }

    #[test]
    fn flag_colours_are_no_map_colour() {
        for c in [SATURATED_RGB, DARK_RGB] {
            assert!(c[0] != c[1] || c[1] != c[2], "gray");
            assert!(c.iter().all(|&v| v > 0), "a hue-wheel colour");
            for k in 0..=100 {
                let v = colormap::viridis(k as f64 / 100.0);
                let dist: i32 = (0..3).map(|j| (v[j] as i32 - c[j] as i32).abs()).sum();
                assert!(dist > 30, "{c:?} near viridis {v:?}");
            }
        }
    }

    #[test]
    fn dolp_scale_parses() {
        assert_eq!(parse_dolp_scale("auto"), Ok(DolpScale::Auto));
        assert_eq!(parse_dolp_scale("0.2"), Ok(DolpScale::Fixed(0.2)));
        assert!(parse_dolp_scale("0").is_err());
        assert!(parse_dolp_scale("1.5").is_err());
        assert!(parse_dolp_scale("nan").is_err());
    }
}
