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

/// Tableau-10 without its grey (greys mark `ambiguous`, `unknown` and "no data").
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

/// Colour of missing values, and of `unknown` map pixels without a usable fit (or all
/// `unknown` pixels when their reasons are not known).
pub(super) const NO_DATA: RGBColor = RGBColor(200, 200, 200);

/// Colour of `unknown` map pixels fitted `ok` but placed nowhere (reason `rejected`).
pub(super) const REJECTED_COLOUR: RGBColor = RGBColor(150, 150, 150);

/// Colour of `ambiguous` map pixels (several materials consistent).
pub(super) const AMBIGUOUS_COLOUR: RGBColor = RGBColor(90, 90, 90);

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
    /// A dashed line sample (dashed confidence regions): colour, (dash, gap) in pixels.
    Dashed(RGBColor, (u32, u32), String),
    /// A small-print note (wrapped over the whole column).
    Note(String),
}

/// Legend entries: a circle in [`class_colour`] `i` for the `i`-th of `labels`.
pub(super) fn class_markers(
    labels: impl IntoIterator<Item = impl ToString>,
) -> impl Iterator<Item = LegendItem> {
    let marker = |(i, l): (usize, _)| LegendItem::Marker(Marker::Circle, class_colour(i), l);
    labels
        .into_iter()
        .map(|l| l.to_string())
        .enumerate()
        .map(marker)
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

/// Break `s` into lines at most `max_px` wide in `style`: at spaces (not before a `%`),
/// a word wider than a line split between characters. Nothing is dropped.
pub(super) fn wrap_text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &str,
    style: &TextStyle<'_>,
    max_px: u32,
) -> Vec<String> {
    let fits = |t: &str| {
        area.estimate_text_size(t, style)
            .map(|(w, _)| w <= max_px)
            .unwrap_or(true)
    };
    let mut lines: Vec<String> = Vec::new();
    let mut cur = String::new();
    // Words, a percent sign kept with its number ("17 %").
    let mut words: Vec<String> = Vec::new();
    for w in s.split_inclusive(' ') {
        match words.last_mut() {
            Some(prev) if w.starts_with('%') => prev.push_str(w),
            _ => words.push(w.to_string()),
        }
    }
    for word in &words {
        let candidate = format!("{cur}{word}");
        if fits(candidate.trim_end()) {
            cur = candidate;
            continue;
        }
        if !cur.trim().is_empty() {
            lines.push(cur.trim_end().to_string());
        }
        // A word wider than a line: split it between characters.
        let mut piece = String::new();
        for ch in word.chars() {
            piece.push(ch);
            if !fits(piece.trim_end()) && piece.chars().count() > 1 {
                piece.pop();
                lines.push(piece);
                piece = ch.to_string();
            }
        }
        cur = piece;
    }
    if !cur.trim().is_empty() || lines.is_empty() {
        lines.push(cur.trim_end().to_string());
    }
    lines
}

/// Draw the legend column (pixel coordinates of `area`). Entries too long for the
/// column are wrapped onto continuation lines, never cut. When the entries do not fit
/// the column's height the lines are set closer; if that is not enough, the last
/// entries are left out and a final line says how many.
pub(super) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    items: &[LegendItem],
) -> Result<()> {
    let (w, h) = area.dim_in_pixel();
    let text = font(LEGEND_SIZE).pos(Pos::new(HPos::Left, VPos::Center));
    let small = font(LEGEND_SIZE - 3).pos(Pos::new(HPos::Left, VPos::Center));
    let room = w.saturating_sub(56).max(40);
    // Each entry's lines, wrapped to its column.
    let wrapped: Vec<Vec<String>> = items
        .iter()
        .map(|item| match item {
            LegendItem::Heading(s) => wrap_text(area, s, &text, room + 40),
            LegendItem::Note(s) => wrap_text(area, s, &small, room + 40),
            LegendItem::Marker(_, _, s)
            | LegendItem::Line(_, s)
            | LegendItem::Dashed(_, _, s)
            | LegendItem::Swatch(_, s) => wrap_text(area, s, &text, room),
        })
        .collect();
    let top = 24;
    let avail = (h as i32 - top - 8).max(40);
    let need = |line_h: i32, wrap_h: i32, k: usize| -> i32 {
        wrapped[..k]
            .iter()
            .map(|l| line_h + wrap_h * (l.len() as i32 - 1).max(0))
            .sum()
    };
    // Normal spacing, then closer, then fewer entries.
    let (mut line_h, mut wrap_h) = (30, 22);
    if need(line_h, wrap_h, items.len()) > avail {
        (line_h, wrap_h) = (23, 19);
    }
    let mut shown = items.len();
    while shown > 0
        && need(line_h, wrap_h, shown) + if shown < items.len() { line_h } else { 0 } > avail
    {
        shown -= 1;
    }
    let mut y = top;
    for (item, lines) in items.iter().zip(&wrapped).take(shown) {
        let (x, style) = match item {
            LegendItem::Heading(_) => (8, &text),
            LegendItem::Note(_) => (8, &small),
            _ => (48, &text),
        };
        match item {
            LegendItem::Heading(_) | LegendItem::Note(_) => {}
            LegendItem::Marker(m, c, _) => draw_marker(area, (26, y), *m, 6, c.filled())?,
            LegendItem::Line(c, _) => {
                area.draw(&PathElement::new(vec![(10, y), (40, y)], c.stroke_width(3)))
                    .dr()?;
            }
            LegendItem::Dashed(c, (dash, gap), _) => {
                area.draw(&plotters::element::DashedPathElement::new(
                    vec![(6, y), (44, y)],
                    *dash,
                    *gap,
                    c.stroke_width(3),
                ))
                .dr()?;
            }
            LegendItem::Swatch(c, _) => {
                let half = (line_h / 3).min(10);
                area.draw(&Rectangle::new(
                    [(12, y - half), (38, y + half)],
                    c.filled(),
                ))
                .dr()?;
                area.draw(&Rectangle::new(
                    [(12, y - half), (38, y + half)],
                    BLACK.stroke_width(1),
                ))
                .dr()?;
            }
        }
        for (i, line) in lines.iter().enumerate() {
            if i > 0 {
                y += wrap_h;
            }
            area.draw(&Text::new(line.clone(), (x, y), style.clone()))
                .dr()?;
        }
        y += line_h;
    }
    if shown < items.len() {
        area.draw(&Text::new(
            format!("… and {} more entries", items.len() - shown),
            (8, y),
            small.clone(),
        ))
        .dr()?;
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
