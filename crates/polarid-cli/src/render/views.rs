//! PNG views of DoLP and AoLP images.
//!
//! * DoLP: the viridis colour map from 0 to `max` (values above `max` saturate), with a
//!   scale bar under the image labelled `0`, `max/2` and `max`.
//! * AoLP: hue = AoLP (0°..180° mapped once around the colour wheel, so 0° and 180° meet
//!   in red), saturation = DoLP / `max` (clamped), value 1; a hue bar labelled `0`, `90`,
//!   `180` (degrees) sits under the image.
//!
//! Rejected pixels (NaN) are black. `max` defaults to a round value just above the 99th
//! percentile of the DoLP image ([`auto_dolp_max`]), because real scenes are often only
//! a few percent polarized.
//!
//! The colours come from [`crate::render::colormap`], the map the plots use too.

use super::colormap::{self, hsv};

/// The DoLP colour map: [`colormap::viridis`] of `t` in `[0, 1]`.
fn viridis(t: f32) -> [u8; 3] {
    colormap::viridis(f64::from(t))
}

/// A round upper limit for the DoLP colour scale: the smallest of 0.01, 0.02, 0.05,
/// 0.1, 0.2, 0.5, 1 at or above the 99th percentile of the finite values (1 when there
/// are none).
pub fn auto_dolp_max(dolp: &[f32]) -> f32 {
    let step = (dolp.len() / 200_000).max(1);
    let mut v: Vec<f32> = dolp
        .iter()
        .step_by(step)
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if v.is_empty() {
        return 1.0;
    }
    let k = ((v.len() as f64 * 0.99) as usize).min(v.len() - 1);
    let (_, p, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    let p = *p;
    for m in [0.01, 0.02, 0.05, 0.1, 0.2, 0.5] {
        if p <= m {
            return m;
        }
    }
    1.0
}

/// 3×5 pixel glyphs for digits, '.', and '°' (rows top to bottom, 3 bits each).
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

/// Image plus a colour bar strip under it: returns (width, height, RGB bytes).
fn with_bar(
    w: usize,
    h: usize,
    image: impl Fn(usize) -> [u8; 3],
    bar: impl Fn(f32) -> [u8; 3],
    labels: &[(f32, String)],
) -> (usize, usize, Vec<u8>) {
    let s = (w / 300).max(1);
    let margin = 4 * s;
    let bar_h = 6 * s;
    let strip = margin + bar_h + 2 * s + 5 * s + margin;
    let total_h = h + strip;
    let mut c = Canvas {
        w,
        h: total_h,
        px: vec![255; w * total_h * 3],
    };
    for i in 0..w * h {
        let v = image(i);
        c.px[3 * i..3 * i + 3].copy_from_slice(&v);
    }
    let x0 = margin.min(w / 4);
    let x1 = w.saturating_sub(margin.min(w / 4));
    let y0 = h + margin;
    let span = (x1 - x0).max(1);
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

/// DoLP view: viridis over `[0, max]`, NaN black, with a scale bar.
pub fn dolp_view(w: usize, h: usize, dolp: &[f32], max: f32) -> (usize, usize, Vec<u8>) {
    let inv = 1.0 / max.max(1e-6);
    with_bar(
        w,
        h,
        |i| {
            let d = dolp[i];
            if d.is_nan() {
                [0, 0, 0]
            } else {
                viridis(d * inv)
            }
        },
        viridis,
        &[
            (0.0, "0".into()),
            (0.5, fmt_label(max / 2.0)),
            (1.0, fmt_label(max)),
        ],
    )
}

/// AoLP view: hue from AoLP (degrees, period 180), saturation from DoLP / `max`.
pub fn aolp_view(
    w: usize,
    h: usize,
    aolp: &[f32],
    dolp: &[f32],
    max: f32,
) -> (usize, usize, Vec<u8>) {
    let inv = 1.0 / max.max(1e-6);
    with_bar(
        w,
        h,
        |i| {
            let (a, d) = (aolp[i], dolp[i]);
            if a.is_nan() || d.is_nan() {
                [0, 0, 0]
            } else {
                hsv(2.0 * a, (d * inv).clamp(0.0, 1.0), 1.0)
            }
        },
        |t| hsv(360.0 * t, 1.0, 1.0),
        &[(0.0, "0".into()), (0.5, "90".into()), (1.0, "180".into())],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_maps() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(hsv(0.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv(120.0, 1.0, 1.0), [0, 255, 0]);
        assert_eq!(hsv(77.0, 0.0, 1.0), [255, 255, 255]);
        assert_eq!(auto_dolp_max(&[0.03, 0.04, f32::NAN]), 0.05);
        let (w, h, px) = dolp_view(4, 2, &[0.0, 0.5, 1.0, f32::NAN, 0.1, 0.2, 0.3, 0.4], 1.0);
        assert_eq!(w, 4);
        assert!(h > 2);
        assert_eq!(px.len(), w * h * 3);
        assert_eq!(&px[9..12], &[0, 0, 0]);
    }
}
