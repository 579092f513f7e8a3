//! The plots' look: the bundled font, text sizes, the categorical palette and the
//! viridis colours (from [`crate::render::colormap`]), markers, legends and notices.

use std::sync::OnceLock;

use anyhow::{Result, anyhow, bail};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::render::colormap;

/// DejaVu Sans 2.37 (Bitstream Vera licence, see `assets/fonts/LICENSE-DejaVu.txt`).
pub(super) static FONT_DATA: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// The font family every plot uses (registered to the bundled font).
pub(super) const FONT: &str = "sans-serif";

/// Register the bundled font with plotters under the generic family names, once.
pub(super) fn ensure_fonts() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        ["sans-serif", "serif", "monospace"]
            .iter()
            .all(|name| plotters::style::register_font(name, FontStyle::Normal, FONT_DATA).is_ok())
    });
    if ok {
        Ok(())
    } else {
        bail!("the bundled plot font (DejaVu Sans) could not be loaded")
    }
}

/// Title, axis-label, tick and legend font sizes (plotters units, ≈ 1.24 × pixel height).
pub(super) const TITLE_SIZE: u32 = 30;
pub(super) const LABEL_SIZE: u32 = 24;
pub(super) const TICK_SIZE: u32 = 19;
pub(super) const LEGEND_SIZE: u32 = 19;
pub(super) const LEGEND_WIDTH: u32 = 290;

/// Tableau-10 without its grey (grey marks "unclassified"/"no data").
pub(super) const PALETTE: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Colour of unclassified pixels and missing values.
pub(super) const NO_DATA: RGBColor = RGBColor(200, 200, 200);

/// The categorical colour of class `i` (0-based): Tableau-10, then golden-ratio hues.
pub fn class_colour(i: usize) -> RGBColor {
    if let Some(c) = PALETTE.get(i) {
        return *c;
    }
    let h = (i as f64 * 0.618_033_988_75).fract();
    let (r, g, b) = HSLColor(h, 0.65, 0.45).rgb();
    RGBColor(r, g, b)
}

/// The viridis colour of `t` in [0, 1] (clamped; NaN gives the no-data grey).
pub fn viridis(t: f64) -> RGBColor {
    if t.is_nan() {
        return NO_DATA;
    }
    let [r, g, b] = colormap::viridis(t);
    RGBColor(r, g, b)
}

/// `c` mixed with white, `t` = share of `c`.
pub(super) fn tint(c: RGBColor, t: f64) -> RGBColor {
    let m = |v: u8| (255.0 - (255.0 - v as f64) * t).round() as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

/// `c` darkened, `t` = share of `c` kept.
pub(super) fn shade(c: RGBColor, t: f64) -> RGBColor {
    let m = |v: u8| (v as f64 * t).round() as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

/// Marker shapes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Marker {
    Circle,
    Triangle,
    Square,
    Diamond,
    Cross,
}

pub(super) const ESTIMATE_MARKERS: [Marker; 4] = [
    Marker::Triangle,
    Marker::Square,
    Marker::Diamond,
    Marker::Cross,
];

/// Entries of the legend column.
#[derive(Debug, Clone)]
pub(super) enum LegendItem {
    Marker(Marker, RGBColor, String),
    Line(RGBColor, String),
    Swatch(RGBColor, String),
    Heading(String),
}

/// Conversion of plotters' drawing errors (whose backend error type varies) to anyhow.
pub(super) trait DrawResult<T> {
    fn dr(self) -> Result<T>;
}

impl<T, E: std::error::Error + Send + Sync> DrawResult<T> for std::result::Result<T, E> {
    fn dr(self) -> Result<T> {
        self.map_err(|e| anyhow!("drawing the plot failed: {e}"))
    }
}

pub(super) fn font(size: u32) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// Shorten `s` to at most `max` characters, with an ellipsis.
pub(super) fn ellipsize(s: &str, max: usize) -> String {
    if s.chars().count() <= max {
        s.to_string()
    } else {
        let mut t: String = s.chars().take(max.saturating_sub(1)).collect();
        t.push('…');
        t
    }
}

/// Shorten `s` (with an ellipsis) until it is at most `max_px` pixels wide in `style`.
pub(super) fn fit_text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &str,
    style: &TextStyle<'_>,
    max_px: u32,
) -> String {
    let fits = |t: &str| {
        area.estimate_text_size(t, style)
            .map(|(w, _)| w <= max_px)
            .unwrap_or(true)
    };
    if fits(s) {
        return s.to_string();
    }
    let mut n = s.chars().count();
    while n > 2 {
        n -= 1;
        let t = ellipsize(s, n);
        if fits(&t) {
            return t;
        }
    }
    ellipsize(s, 2)
}

/// Tick label: at most 4 decimals, without trailing zeros.
pub(super) fn fmt_tick(v: &f64) -> String {
    let s = format!("{v:.4}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" { "0".to_string() } else { s }
}

pub(super) fn draw_marker<DB: DrawingBackend, CT: CoordTranslate>(
    area: &DrawingArea<DB, CT>,
    at: CT::From,
    marker: Marker,
    r: i32,
    style: ShapeStyle,
) -> Result<()> {
    match marker {
        Marker::Circle => area
            .draw(&(EmptyElement::at(at) + Circle::new((0, 0), r, style)))
            .dr(),
        Marker::Triangle => area
            .draw(&(EmptyElement::at(at) + TriangleMarker::new((0, 0), r + 2, style)))
            .dr(),
        Marker::Square => area
            .draw(&(EmptyElement::at(at) + Rectangle::new([(-r, -r), (r, r)], style)))
            .dr(),
        Marker::Diamond => {
            let q = r + 2;
            area.draw(
                &(EmptyElement::at(at)
                    + Polygon::new(vec![(0, -q), (q, 0), (0, q), (-q, 0)], style)),
            )
            .dr()
        }
        Marker::Cross => area
            .draw(&(EmptyElement::at(at) + Cross::new((0, 0), r + 1, style.stroke_width(3))))
            .dr(),
    }
}

/// Draw the legend column (pixel coordinates of `area`).
pub(super) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    items: &[LegendItem],
) -> Result<()> {
    let line_h = 30;
    let (w, _) = area.dim_in_pixel();
    let text = font(LEGEND_SIZE).pos(Pos::new(HPos::Left, VPos::Center));
    let room = w.saturating_sub(56).max(40);
    let mut y = 24;
    for item in items {
        match item {
            LegendItem::Heading(s) => {
                area.draw(&Text::new(
                    fit_text(area, s, &text, room + 40),
                    (8, y),
                    text.clone(),
                ))
                .dr()?;
            }
            LegendItem::Marker(m, c, s) => {
                draw_marker(area, (26, y), *m, 6, c.filled())?;
                area.draw(&Text::new(
                    fit_text(area, s, &text, room),
                    (48, y),
                    text.clone(),
                ))
                .dr()?;
            }
            LegendItem::Line(c, s) => {
                area.draw(&PathElement::new(vec![(10, y), (40, y)], c.stroke_width(3)))
                    .dr()?;
                area.draw(&Text::new(
                    fit_text(area, s, &text, room),
                    (48, y),
                    text.clone(),
                ))
                .dr()?;
            }
            LegendItem::Swatch(c, s) => {
                area.draw(&Rectangle::new([(12, y - 10), (38, y + 10)], c.filled()))
                    .dr()?;
                area.draw(&Rectangle::new(
                    [(12, y - 10), (38, y + 10)],
                    BLACK.stroke_width(1),
                ))
                .dr()?;
                area.draw(&Text::new(
                    fit_text(area, s, &text, room),
                    (48, y),
                    text.clone(),
                ))
                .dr()?;
            }
        }
        y += line_h;
    }
    Ok(())
}

/// A centred notice (empty data).
pub(super) fn draw_notice<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    msg: &str,
) -> Result<()> {
    let (w, h) = area.dim_in_pixel();
    area.draw(&Text::new(
        msg.to_string(),
        (w as i32 / 2, h as i32 / 2),
        font(LABEL_SIZE).pos(Pos::new(HPos::Center, VPos::Center)),
    ))
    .dr()
}
