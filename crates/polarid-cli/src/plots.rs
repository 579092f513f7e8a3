//! Plots for reports and commands, each rendered to PNG and SVG from plain data.
//!
//! - [`dolp_vs_beta`]: measured DoLP against β with standard-error bars and the fitted
//!   paper eq. (9) curve, one colour per target;
//! - [`nk_plane`]: the (n, k) plane with class prototypes, test estimates with 1-σ
//!   covariance ellipses and the nearest-neighbour decision regions (paper § 6);
//! - [`class_map`]: a material map (class index image, 0 = unclassified) with a legend;
//! - [`scalar_map`]: a scalar image (n, k, DoLP, ...) in the viridis colour map with a
//!   colour bar.
//!
//! Every function returns a [`Rendered`] (PNG bytes and SVG text of the same drawing);
//! [`Rendered::write`] writes `STEM.png` and `STEM.svg`. Text is drawn with the bundled
//! DejaVu Sans font (`assets/fonts/`, registered with plotters' `ab_glyph` table), so
//! plots render on machines without system fonts. Empty data draws a "no data" notice
//! rather than failing; inconsistent data (an image buffer of the wrong length) is an
//! error. Angles are in degrees, as everywhere outside the numerical code.

// Nothing calls this module until `polarid demo` is wired to it.
#![allow(dead_code)]

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{Context, Result, anyhow, bail};
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::report::base64_encode;

/// DejaVu Sans 2.37 (Bitstream Vera licence, see `assets/fonts/LICENSE-DejaVu.txt`).
static FONT_DATA: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// The font family every plot uses (registered to the bundled font).
const FONT: &str = "sans-serif";

/// Register the bundled font with plotters under the generic family names, once.
fn ensure_fonts() -> Result<()> {
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

// ---------------------------------------------------------------------------------
// Output

/// Pixel size of a plot (the SVG has the same size in user units).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlotSize {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl PlotSize {
    /// The default report size, 1000 × 640 pixels: legible when shown at 100 % in the
    /// HTML report and when scaled down to a page width.
    pub const REPORT: PlotSize = PlotSize {
        width: 1000,
        height: 640,
    };

    fn check(self) -> Result<()> {
        if !(320..=8000).contains(&self.width) || !(240..=8000).contains(&self.height) {
            bail!(
                "plot size {}x{} is out of range (320..=8000 by 240..=8000 pixels)",
                self.width,
                self.height
            );
        }
        Ok(())
    }
}

impl Default for PlotSize {
    fn default() -> Self {
        Self::REPORT
    }
}

/// One drawing, rendered both as a PNG image and as an SVG document.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The PNG file's bytes (8-bit RGB).
    pub png: Vec<u8>,
    /// The SVG document.
    pub svg: String,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// The files written by [`Rendered::write`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlotFiles {
    /// `DIR/STEM.png`.
    pub png: PathBuf,
    /// `DIR/STEM.svg`.
    pub svg: PathBuf,
}

impl Rendered {
    /// Write `dir/stem.png` and `dir/stem.svg` (overwriting them: callers that must not
    /// overwrite write into a `polarid_io::atomic::StagedDir`).
    pub fn write(&self, dir: &Path, stem: &str) -> Result<PlotFiles> {
        if stem.is_empty() || stem.contains(['/', '\\']) {
            bail!("plot file stem {stem:?} must be a non-empty file name");
        }
        let png = dir.join(format!("{stem}.png"));
        let svg = dir.join(format!("{stem}.svg"));
        std::fs::write(&png, &self.png)
            .with_context(|| format!("cannot write {}", png.display()))?;
        std::fs::write(&svg, self.svg.as_bytes())
            .with_context(|| format!("cannot write {}", svg.display()))?;
        Ok(PlotFiles { png, svg })
    }
}

// ---------------------------------------------------------------------------------
// Data

/// One DoLP measurement of a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DolpPoint {
    /// β, half the source–camera angle (eq. 5), degrees.
    pub beta_deg: f64,
    /// Measured degree of linear polarization.
    pub dolp: f64,
    /// Its standard error (drawn as a ±1 SE bar), if known.
    pub dolp_se: Option<f64>,
}

/// One target's measurements and fitted curve for [`dolp_vs_beta`].
#[derive(Debug, Clone, PartialEq)]
pub struct DolpSeries {
    /// Target name (legend).
    pub label: String,
    /// Measurements.
    pub points: Vec<DolpPoint>,
    /// The fitted model as `(β in degrees, DoLP)` samples, drawn as a line; may be empty.
    pub curve: Vec<(f64, f64)>,
    /// Legend text of the curve, e.g. `"fit n = 1.37, k = 3.97"`.
    pub curve_label: Option<String>,
}

/// `samples` points of `f(β)` for β evenly spaced over `[beta_min_deg, beta_max_deg]`
/// (degrees; `f` takes degrees), for [`DolpSeries::curve`].
pub fn sample_curve(
    beta_min_deg: f64,
    beta_max_deg: f64,
    samples: usize,
    f: impl Fn(f64) -> f64,
) -> Vec<(f64, f64)> {
    if samples == 0 || !beta_min_deg.is_finite() || !beta_max_deg.is_finite() {
        return Vec::new();
    }
    if samples == 1 {
        return vec![(beta_min_deg, f(beta_min_deg))];
    }
    let step = (beta_max_deg - beta_min_deg) / (samples - 1) as f64;
    (0..samples)
        .map(|i| {
            let b = beta_min_deg + step * i as f64;
            (b, f(b))
        })
        .collect()
}

/// The paper's eq. (9) DoLP `P(n, k, β)` sampled over `[beta_min_deg, beta_max_deg]`
/// (degrees, clamped to `[0, 90]`), via [`polarid_core::dop::dop`].
pub fn eq9_curve(
    n: f64,
    k: f64,
    beta_min_deg: f64,
    beta_max_deg: f64,
    samples: usize,
) -> Vec<(f64, f64)> {
    let lo = beta_min_deg.clamp(0.0, 90.0);
    let hi = beta_max_deg.clamp(0.0, 90.0);
    sample_curve(lo, hi, samples, |b| {
        polarid_core::dop::dop(n, k, b.to_radians())
    })
}

/// A class prototype in the (n, k) plane (a training estimate or a library entry).
#[derive(Debug, Clone, PartialEq)]
pub struct Prototype {
    /// Class (material) name; prototypes of one class share a colour.
    pub class: String,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index.
    pub k: f64,
}

/// An estimate of (n, k) with its uncertainty, for [`nk_plane`].
#[derive(Debug, Clone, PartialEq)]
pub struct NkEstimate {
    /// Legend text, e.g. `"test, θr = 60°"`.
    pub label: String,
    /// Estimated n.
    pub n: f64,
    /// Estimated k.
    pub k: f64,
    /// Standard error of n.
    pub n_se: f64,
    /// Standard error of k.
    pub k_se: f64,
    /// Correlation of the n and k errors, in [-1, 1].
    pub corr: f64,
    /// Predicted class: the marker takes that class's colour when it is a prototype class.
    pub predicted: Option<String>,
}

// ---------------------------------------------------------------------------------
// Styling

/// Title, axis-label, tick and legend font sizes (plotters units, ≈ 1.24 × pixel height).
const TITLE_SIZE: u32 = 30;
const LABEL_SIZE: u32 = 24;
const TICK_SIZE: u32 = 19;
const LEGEND_SIZE: u32 = 19;
const LEGEND_WIDTH: u32 = 290;

/// Tableau-10 without its grey (grey marks "unclassified"/"no data").
const PALETTE: [RGBColor; 9] = [
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
const NO_DATA: RGBColor = RGBColor(200, 200, 200);

/// The categorical colour of class `i` (0-based): Tableau-10, then golden-ratio hues.
pub fn class_colour(i: usize) -> RGBColor {
    if let Some(c) = PALETTE.get(i) {
        return *c;
    }
    let h = (i as f64 * 0.618_033_988_75).fract();
    let (r, g, b) = HSLColor(h, 0.65, 0.45).rgb();
    RGBColor(r, g, b)
}

/// matplotlib's viridis at 10 evenly spaced points.
const VIRIDIS: [(u8, u8, u8); 10] = [
    (0x44, 0x01, 0x54),
    (0x48, 0x28, 0x78),
    (0x3e, 0x49, 0x89),
    (0x31, 0x68, 0x8e),
    (0x26, 0x82, 0x8e),
    (0x1f, 0x9e, 0x89),
    (0x35, 0xb7, 0x79),
    (0x6e, 0xce, 0x58),
    (0xb5, 0xde, 0x2b),
    (0xfd, 0xe7, 0x25),
];

/// The viridis colour of `t` in [0, 1] (clamped; NaN gives the no-data grey).
pub fn viridis(t: f64) -> RGBColor {
    if t.is_nan() {
        return NO_DATA;
    }
    let x = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + (q as f64 - p as f64) * f).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// `c` mixed with white, `t` = share of `c`.
fn tint(c: RGBColor, t: f64) -> RGBColor {
    let m = |v: u8| (255.0 - (255.0 - v as f64) * t).round() as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

/// `c` darkened, `t` = share of `c` kept.
fn shade(c: RGBColor, t: f64) -> RGBColor {
    let m = |v: u8| (v as f64 * t).round() as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

/// Marker shapes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Marker {
    Circle,
    Triangle,
    Square,
    Diamond,
    Cross,
}

const ESTIMATE_MARKERS: [Marker; 4] = [
    Marker::Triangle,
    Marker::Square,
    Marker::Diamond,
    Marker::Cross,
];

/// Entries of the legend column.
#[derive(Debug, Clone)]
enum LegendItem {
    Marker(Marker, RGBColor, String),
    Line(RGBColor, String),
    Swatch(RGBColor, String),
    Heading(String),
}

// ---------------------------------------------------------------------------------
// Drawing helpers

/// Conversion of plotters' drawing errors (whose backend error type varies) to anyhow.
trait DrawResult<T> {
    fn dr(self) -> Result<T>;
}

impl<T, E: std::error::Error + Send + Sync> DrawResult<T> for std::result::Result<T, E> {
    fn dr(self) -> Result<T> {
        self.map_err(|e| anyhow!("drawing the plot failed: {e}"))
    }
}

fn font(size: u32) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// Shorten `s` to at most `max` characters, with an ellipsis.
fn ellipsize(s: &str, max: usize) -> String {
    if s.chars().count() <= max {
        s.to_string()
    } else {
        let mut t: String = s.chars().take(max.saturating_sub(1)).collect();
        t.push('…');
        t
    }
}

/// Shorten `s` (with an ellipsis) until it is at most `max_px` pixels wide in `style`.
fn fit_text<DB: DrawingBackend>(
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
fn fmt_tick(v: &f64) -> String {
    let s = format!("{v:.4}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" { "0".to_string() } else { s }
}

fn draw_marker<DB: DrawingBackend, CT: CoordTranslate>(
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
fn draw_legend<DB: DrawingBackend>(
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
fn draw_notice<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, msg: &str) -> Result<()> {
    let (w, h) = area.dim_in_pixel();
    area.draw(&Text::new(
        msg.to_string(),
        (w as i32 / 2, h as i32 / 2),
        font(LABEL_SIZE).pos(Pos::new(HPos::Center, VPos::Center)),
    ))
    .dr()
}

/// An RGB raster to place over the plotting area after drawing (image maps).
struct Raster {
    /// Top-left pixel.
    x: i32,
    y: i32,
    w: u32,
    h: u32,
    rgb: Vec<u8>,
}

/// A drawing that can target any plotters backend.
trait Figure {
    /// Draw onto `root` (already white). Returns the raster to overlay, if any.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>>;
}

fn encode_png(rgb: &[u8], w: u32, h: u32) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(rgb, w, h, image::ExtendedColorType::Rgb8)
        .context("PNG encoding failed")?;
    Ok(out)
}

/// Render `fig` to PNG and SVG.
fn render(fig: &impl Figure, size: PlotSize) -> Result<Rendered> {
    ensure_fonts()?;
    size.check()?;
    let (w, h) = (size.width, size.height);
    let mut buf = vec![255u8; w as usize * h as usize * 3];
    let raster = {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).dr()?;
        let raster = fig.draw(&root)?;
        root.present().dr()?;
        raster
    };
    if let Some(r) = &raster {
        paste(&mut buf, w, h, r);
    }
    let png = encode_png(&buf, w, h)?;

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE).dr()?;
        fig.draw(&root)?;
        root.present().dr()?;
    }
    if let Some(r) = &raster {
        let img = encode_png(&r.rgb, r.w, r.h)?;
        let tag = format!(
            "<image x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" style=\"image-rendering:pixelated\" href=\"data:image/png;base64,{}\"/>\n",
            r.x,
            r.y,
            r.w,
            r.h,
            base64_encode(&img)
        );
        let end = svg
            .rfind("</svg>")
            .ok_or_else(|| anyhow!("internal error: SVG output has no closing tag"))?;
        svg.insert_str(end, &tag);
    }
    Ok(Rendered {
        png,
        svg,
        width: w,
        height: h,
    })
}

/// Copy `r` into the RGB buffer `buf` (`w` × `h`), clipped.
fn paste(buf: &mut [u8], w: u32, h: u32, r: &Raster) {
    for ry in 0..r.h as i64 {
        let y = r.y as i64 + ry;
        if y < 0 || y >= h as i64 {
            continue;
        }
        for rx in 0..r.w as i64 {
            let x = r.x as i64 + rx;
            if x < 0 || x >= w as i64 {
                continue;
            }
            let src = ((ry * r.w as i64 + rx) * 3) as usize;
            let dst = ((y * w as i64 + x) * 3) as usize;
            if let (Some(s), Some(d)) = (r.rgb.get(src..src + 3), buf.get_mut(dst..dst + 3)) {
                d.copy_from_slice(s);
            }
        }
    }
}

/// `[lo, hi]` padded by `frac` of its span (at least `min_span` wide).
fn padded(lo: f64, hi: f64, frac: f64, min_span: f64) -> (f64, f64) {
    let mut span = hi - lo;
    let (mut lo, mut hi) = (lo, hi);
    if span < min_span {
        let mid = 0.5 * (lo + hi);
        lo = mid - 0.5 * min_span;
        hi = mid + 0.5 * min_span;
        span = min_span;
    }
    (lo - frac * span, hi + frac * span)
}

fn min_max(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((a, b)) => Some((a.min(v), b.max(v))),
        })
}

type Chart2d<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart in `area` with the project's axis styling.
fn chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    x: Range<f64>,
    y: Range<f64>,
    margins: (u32, u32, u32, u32),
) -> Result<Chart2d<'a, DB>> {
    let (top, right, bottom, left) = margins;
    ChartBuilder::on(area)
        .margin_top(top)
        .margin_right(right)
        .margin_bottom(bottom)
        .margin_left(left)
        .x_label_area_size(62)
        .y_label_area_size(86)
        .build_cartesian_2d(x, y)
        .dr()
}

fn configure_axes<DB: DrawingBackend>(
    chart: &mut Chart2d<'_, DB>,
    x_desc: &str,
    y_desc: &str,
    mesh: bool,
) -> Result<()> {
    let mut m = chart.configure_mesh();
    m.x_desc(x_desc)
        .y_desc(y_desc)
        .axis_desc_style(font(LABEL_SIZE))
        .label_style(font(TICK_SIZE))
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&fmt_tick)
        .y_label_formatter(&fmt_tick)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210));
    if !mesh {
        m.disable_mesh();
    }
    m.draw().dr()
}

/// Title on top, legend column on the right; returns (main, legend).
fn layout<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<(DrawingArea<DB, Shift>, DrawingArea<DB, Shift>)> {
    let body = root.titled(title, font(TITLE_SIZE)).dr()?;
    let (w, _) = body.dim_in_pixel();
    Ok(body.split_horizontally(w.saturating_sub(LEGEND_WIDTH)))
}

// ---------------------------------------------------------------------------------
// (a) DoLP against β

/// DoLP against β (degrees) for each target: measurements with ±1 SE bars and the
/// fitted eq. (9) curve, one colour per series.
pub fn dolp_vs_beta(title: &str, series: &[DolpSeries], size: PlotSize) -> Result<Rendered> {
    render(&DolpFigure { title, series }, size)
}

struct DolpFigure<'a> {
    title: &'a str,
    series: &'a [DolpSeries],
}

impl Figure for DolpFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let (main, side) = layout(root, self.title)?;
        let valid = |p: &DolpPoint| p.beta_deg.is_finite() && p.dolp.is_finite();
        let xs = self.series.iter().flat_map(|s| {
            s.points
                .iter()
                .filter(|p| valid(p))
                .map(|p| p.beta_deg)
                .chain(s.curve.iter().filter(|c| c.1.is_finite()).map(|c| c.0))
        });
        let Some((x0, x1)) = min_max(xs) else {
            draw_notice(&main, "No DoLP data to plot")?;
            return Ok(None);
        };
        let se = |p: &DolpPoint| {
            p.dolp_se
                .filter(|s| s.is_finite() && *s > 0.0)
                .unwrap_or(0.0)
        };
        let ys = self.series.iter().flat_map(|s| {
            s.points
                .iter()
                .filter(|p| valid(p))
                .flat_map(|p| [p.dolp - se(p), p.dolp + se(p)])
                .chain(s.curve.iter().filter(|c| c.0.is_finite()).map(|c| c.1))
        });
        let (y0, y1) = min_max(ys).unwrap_or((0.0, 1.0));
        let (x0, x1) = padded(x0, x1, 0.04, 2.0);
        let (x0, x1) = (x0.max(0.0), x1.min(90.0));
        let y0 = if y0 > 0.0 && y0 < 0.5 * y1 {
            0.0
        } else {
            y0 - 0.05 * (y1 - y0).max(0.02)
        };
        let (y0, y1) = (y0.max(0.0), (y1 + 0.08 * (y1 - y0).max(0.05)).min(1.05));
        let mut ch = chart(&main, x0..x1, y0..y1, (12, 20, 8, 8))?;
        configure_axes(&mut ch, "β (degrees)", "DoLP", true)?;

        let mut legend = Vec::new();
        for (i, s) in self.series.iter().enumerate() {
            let c = class_colour(i);
            let curve: Vec<(f64, f64)> = s
                .curve
                .iter()
                .copied()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect();
            if !curve.is_empty() {
                ch.draw_series(LineSeries::new(curve, c.stroke_width(3)))
                    .dr()?;
            }
            let area = ch.plotting_area();
            for p in s.points.iter().filter(|p| valid(p)) {
                let e = se(p);
                if e > 0.0 {
                    let st = shade(c, 0.8).stroke_width(2);
                    area.draw(&PathElement::new(
                        vec![(p.beta_deg, p.dolp - e), (p.beta_deg, p.dolp + e)],
                        st,
                    ))
                    .dr()?;
                    for yy in [p.dolp - e, p.dolp + e] {
                        area.draw(
                            &(EmptyElement::at((p.beta_deg, yy))
                                + PathElement::new(vec![(-5, 0), (5, 0)], st)),
                        )
                        .dr()?;
                    }
                }
                draw_marker(area, (p.beta_deg, p.dolp), Marker::Circle, 6, c.filled())?;
                draw_marker(
                    area,
                    (p.beta_deg, p.dolp),
                    Marker::Circle,
                    6,
                    shade(c, 0.6).stroke_width(1),
                )?;
            }
            legend.push(LegendItem::Marker(
                Marker::Circle,
                c,
                format!("{} (data)", s.label),
            ));
            if !s.curve.is_empty() {
                let l = s
                    .curve_label
                    .clone()
                    .unwrap_or_else(|| "eq. (9) fit".into());
                legend.push(LegendItem::Line(c, l));
            }
        }
        legend.push(LegendItem::Heading("bars: ±1 standard error".into()));
        draw_legend(&side, &legend)?;
        Ok(None)
    }
}

// ---------------------------------------------------------------------------------
// (b) The (n, k) plane

/// The (n, k) plane: the nearest-neighbour decision regions of the prototypes
/// (Euclidean distance in (n, k), paper § 6) shaded by class, the prototypes, and the
/// estimates with their 1-σ covariance ellipses.
pub fn nk_plane(
    title: &str,
    prototypes: &[Prototype],
    estimates: &[NkEstimate],
    size: PlotSize,
) -> Result<Rendered> {
    render(
        &NkFigure {
            title,
            prototypes,
            estimates,
        },
        size,
    )
}

struct NkFigure<'a> {
    title: &'a str,
    prototypes: &'a [Prototype],
    estimates: &'a [NkEstimate],
}

/// Points of the 1-σ ellipse of a bivariate normal with standard deviations `sn`, `sk`
/// and correlation `rho`, centred on `(n, k)`: `c + L (cos t, sin t)` with `L` the
/// Cholesky factor of the covariance `[[sn², ρ sn sk], [ρ sn sk, sk²]]`.
pub fn covariance_ellipse(
    n: f64,
    k: f64,
    sn: f64,
    sk: f64,
    rho: f64,
    points: usize,
) -> Vec<(f64, f64)> {
    if !(sn.is_finite() && sk.is_finite() && sn >= 0.0 && sk >= 0.0) || points < 3 {
        return Vec::new();
    }
    let rho = if rho.is_finite() {
        rho.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let q = (1.0 - rho * rho).max(0.0).sqrt();
    (0..=points)
        .map(|i| {
            let t = std::f64::consts::TAU * i as f64 / points as f64;
            let (s, c) = t.sin_cos();
            (n + sn * c, k + sk * (rho * c + q * s))
        })
        .collect()
}

/// The cell of prototype `i` in the Euclidean nearest-neighbour partition, clipped to
/// the rectangle `[x0, x1] × [y0, y1]` (a convex polygon, possibly empty).
fn voronoi_cell(sites: &[(f64, f64)], i: usize, x: Range<f64>, y: Range<f64>) -> Vec<(f64, f64)> {
    let mut poly = vec![
        (x.start, y.start),
        (x.end, y.start),
        (x.end, y.end),
        (x.start, y.end),
    ];
    let Some(&p) = sites.get(i) else {
        return Vec::new();
    };
    for (j, &q) in sites.iter().enumerate() {
        if j == i || poly.is_empty() {
            continue;
        }
        // Keep points nearer p than q: a·v <= b.
        let a = (2.0 * (q.0 - p.0), 2.0 * (q.1 - p.1));
        let b = (q.0 * q.0 + q.1 * q.1) - (p.0 * p.0 + p.1 * p.1);
        if a.0 == 0.0 && a.1 == 0.0 {
            continue;
        }
        let f = |v: (f64, f64)| a.0 * v.0 + a.1 * v.1 - b;
        let mut out = Vec::with_capacity(poly.len() + 1);
        for idx in 0..poly.len() {
            let cur = poly[idx];
            let nxt = poly[(idx + 1) % poly.len()];
            let (fc, fn_) = (f(cur), f(nxt));
            if fc <= 0.0 {
                out.push(cur);
            }
            if (fc < 0.0 && fn_ > 0.0) || (fc > 0.0 && fn_ < 0.0) {
                let t = fc / (fc - fn_);
                out.push((cur.0 + t * (nxt.0 - cur.0), cur.1 + t * (nxt.1 - cur.1)));
            }
        }
        poly = out;
    }
    poly
}

impl Figure for NkFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let (main, side) = layout(root, self.title)?;
        let protos: Vec<&Prototype> = self
            .prototypes
            .iter()
            .filter(|p| p.n.is_finite() && p.k.is_finite())
            .collect();
        let ests: Vec<&NkEstimate> = self
            .estimates
            .iter()
            .filter(|e| e.n.is_finite() && e.k.is_finite())
            .collect();
        let fin = |v: f64| if v.is_finite() && v > 0.0 { v } else { 0.0 };
        let ns = protos.iter().map(|p| p.n).chain(
            ests.iter()
                .flat_map(|e| [e.n - fin(e.n_se), e.n + fin(e.n_se)]),
        );
        let ks = protos.iter().map(|p| p.k).chain(
            ests.iter()
                .flat_map(|e| [e.k - fin(e.k_se), e.k + fin(e.k_se)]),
        );
        let (Some((n0, n1)), Some((k0, k1))) = (min_max(ns), min_max(ks)) else {
            draw_notice(&main, "No (n, k) values to plot")?;
            return Ok(None);
        };
        let (n0, n1) = padded(n0, n1, 0.12, 0.5);
        let (k0, k1) = padded(k0, k1, 0.12, 0.5);
        let (n0, k0) = (n0.max(0.0), k0.max(0.0));
        let mut ch = chart(&main, n0..n1, k0..k1, (12, 20, 8, 8))?;

        // Classes in order of first appearance.
        let mut classes: Vec<&str> = Vec::new();
        for p in &protos {
            if !classes.contains(&p.class.as_str()) {
                classes.push(&p.class);
            }
        }
        let class_idx = |name: &str| classes.iter().position(|c| *c == name);

        // Decision regions first, under the mesh lines.
        let sites: Vec<(f64, f64)> = protos.iter().map(|p| (p.n, p.k)).collect();
        for (i, p) in protos.iter().enumerate() {
            let cell = voronoi_cell(&sites, i, n0..n1, k0..k1);
            if cell.len() >= 3 {
                let c = class_colour(class_idx(&p.class).unwrap_or(0));
                ch.draw_series(std::iter::once(Polygon::new(cell, tint(c, 0.18).filled())))
                    .dr()?;
            }
        }
        configure_axes(
            &mut ch,
            "n (real part of N)",
            "k (imaginary part of N)",
            true,
        )?;
        let area = ch.plotting_area();
        // Region boundaries (cell edges between different classes are drawn darker).
        for (i, p) in protos.iter().enumerate() {
            let cell = voronoi_cell(&sites, i, n0..n1, k0..k1);
            if cell.len() >= 3 {
                let c = class_colour(class_idx(&p.class).unwrap_or(0));
                let mut closed = cell.clone();
                closed.push(cell[0]);
                area.draw(&PathElement::new(closed, tint(c, 0.45).stroke_width(1)))
                    .dr()?;
            }
        }
        for p in &protos {
            let c = class_colour(class_idx(&p.class).unwrap_or(0));
            draw_marker(area, (p.n, p.k), Marker::Circle, 8, c.filled())?;
            draw_marker(area, (p.n, p.k), Marker::Circle, 8, BLACK.stroke_width(2))?;
        }
        let mut legend = vec![LegendItem::Heading("Prototypes / regions".into())];
        for (i, c) in classes.iter().enumerate() {
            legend.push(LegendItem::Marker(
                Marker::Circle,
                class_colour(i),
                c.to_string(),
            ));
        }
        if !ests.is_empty() {
            legend.push(LegendItem::Heading("Estimates (1-σ ellipse)".into()));
        }
        for (j, e) in ests.iter().enumerate() {
            let m = ESTIMATE_MARKERS[j % ESTIMATE_MARKERS.len()];
            let c = e
                .predicted
                .as_deref()
                .and_then(class_idx)
                .map(|i| shade(class_colour(i), 0.55))
                .unwrap_or(BLACK);
            let ell = covariance_ellipse(e.n, e.k, e.n_se, e.k_se, e.corr, 96);
            if ell.len() > 3 {
                area.draw(&PathElement::new(ell, c.stroke_width(2))).dr()?;
            }
            draw_marker(area, (e.n, e.k), m, 6, c.filled())?;
            legend.push(LegendItem::Marker(m, c, e.label.clone()));
        }
        draw_legend(&side, &legend)?;
        Ok(None)
    }
}

// ---------------------------------------------------------------------------------
// (c) Image maps

/// A material map: `classes` is a `width × height` row-major class-index image
/// (0 = unclassified, `i ≥ 1` = `names[i - 1]`), drawn in the categorical palette with
/// a legend. Indices without a name are labelled `class i`.
pub fn class_map(
    title: &str,
    width: usize,
    height: usize,
    classes: &[u16],
    names: &[String],
    size: PlotSize,
) -> Result<Rendered> {
    check_image(width, height, classes.len())?;
    render(
        &MapFigure {
            title,
            width,
            height,
            kind: MapKind::Classes { classes, names },
        },
        size,
    )
}

/// A scalar image (`width × height`, row-major; NaN = no data, drawn grey) in the
/// viridis colour map with a colour bar labelled `quantity` (with its unit, e.g.
/// `"DoLP"`, `"n"`). `range` fixes the colour scale; by default it spans the finite
/// values.
pub fn scalar_map<T: Copy + Into<f64>>(
    title: &str,
    width: usize,
    height: usize,
    values: &[T],
    range: Option<(f64, f64)>,
    quantity: &str,
    size: PlotSize,
) -> Result<Rendered> {
    check_image(width, height, values.len())?;
    if let Some((a, b)) = range
        && !(a.is_finite() && b.is_finite() && a < b)
    {
        bail!("colour range {a}..{b} must be finite and increasing");
    }
    let vals: Vec<f64> = values.iter().map(|&v| v.into()).collect();
    let range = range.or_else(|| {
        min_max(vals.iter().copied()).map(|(a, b)| {
            if b > a {
                (a, b)
            } else {
                let d = (a.abs() * 0.05).max(0.5);
                (a - d, b + d)
            }
        })
    });
    render(
        &MapFigure {
            title,
            width,
            height,
            kind: MapKind::Scalar {
                values: &vals,
                range,
                quantity,
            },
        },
        size,
    )
}

fn check_image(width: usize, height: usize, len: usize) -> Result<()> {
    match width.checked_mul(height) {
        Some(n) if n == len => Ok(()),
        _ => bail!("image buffer has {len} values, expected {width} × {height}"),
    }
}

enum MapKind<'a> {
    Classes {
        classes: &'a [u16],
        names: &'a [String],
    },
    Scalar {
        values: &'a [f64],
        range: Option<(f64, f64)>,
        quantity: &'a str,
    },
}

struct MapFigure<'a> {
    title: &'a str,
    width: usize,
    height: usize,
    kind: MapKind<'a>,
}

impl MapFigure<'_> {
    fn colour_at(&self, idx: usize) -> RGBColor {
        match &self.kind {
            MapKind::Classes { classes, .. } => match classes.get(idx) {
                Some(0) | None => NO_DATA,
                Some(&c) => class_colour(c as usize - 1),
            },
            MapKind::Scalar { values, range, .. } => match (values.get(idx), range) {
                (Some(v), Some((a, b))) if v.is_finite() => viridis((v - a) / (b - a)),
                _ => NO_DATA,
            },
        }
    }
}

impl Figure for MapFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let (main, side) = layout(root, self.title)?;
        if self.width == 0 || self.height == 0 {
            draw_notice(&main, "Empty image")?;
            return Ok(None);
        }
        // Fit the image's aspect ratio into the main area.
        let (mw, mh) = main.dim_in_pixel();
        let (left, bottom, pad) = (86.0, 62.0, 12.0);
        let aw = (mw as f64 - left - 2.0 * pad).max(10.0);
        let ah = (mh as f64 - bottom - 2.0 * pad).max(10.0);
        let s = (aw / self.width as f64).min(ah / self.height as f64);
        let pw = self.width as f64 * s;
        let ph = self.height as f64 * s;
        let extra_w = ((aw - pw) / 2.0).max(0.0) as u32;
        let extra_h = ((ah - ph) / 2.0).max(0.0) as u32;
        let (w, h) = (self.width as f64, self.height as f64);
        let mut ch = chart(
            &main,
            0.0..w,
            h..0.0,
            (
                pad as u32 + extra_h,
                pad as u32 + extra_w,
                pad as u32 + extra_h,
                pad as u32 + extra_w,
            ),
        )?;
        configure_axes(&mut ch, "x (pixel column)", "y (pixel row)", false)?;
        let (xr, yr) = ch.plotting_area().get_pixel_range();
        let (rw, rh) = (
            (xr.end - xr.start).max(1) as u32,
            (yr.end - yr.start).max(1) as u32,
        );
        let mut rgb = Vec::with_capacity(rw as usize * rh as usize * 3);
        for py in 0..rh as usize {
            let row = ((py as f64 + 0.5) * h / rh as f64) as usize;
            let row = row.min(self.height - 1);
            for px in 0..rw as usize {
                let col = ((px as f64 + 0.5) * w / rw as f64) as usize;
                let col = col.min(self.width - 1);
                let c = self.colour_at(row * self.width + col);
                rgb.extend_from_slice(&[c.0, c.1, c.2]);
            }
        }
        let raster = Raster {
            x: xr.start,
            y: yr.start,
            w: rw,
            h: rh,
            rgb,
        };

        match &self.kind {
            MapKind::Classes { classes, names } => {
                let mut present = vec![false; names.len() + 1];
                let mut unnamed: Vec<u16> = Vec::new();
                for &c in classes.iter() {
                    match present.get_mut(c as usize) {
                        Some(p) => *p = true,
                        None => {
                            if !unnamed.contains(&c) {
                                unnamed.push(c);
                            }
                        }
                    }
                }
                unnamed.sort_unstable();
                let total = classes.len().max(1) as f64;
                let count = |i: u16| classes.iter().filter(|&&c| c == i).count() as f64;
                let mut legend = vec![LegendItem::Heading("Classes (pixel share)".into())];
                for (i, name) in names.iter().enumerate() {
                    let pct = 100.0 * count(i as u16 + 1) / total;
                    legend.push(LegendItem::Swatch(
                        class_colour(i),
                        format!("{name} ({pct:.0} %)"),
                    ));
                }
                for c in unnamed {
                    let pct = 100.0 * count(c) / total;
                    legend.push(LegendItem::Swatch(
                        class_colour(c as usize - 1),
                        format!("class {c} ({pct:.0} %)"),
                    ));
                }
                let pct = 100.0 * count(0) / total;
                legend.push(LegendItem::Swatch(
                    NO_DATA,
                    format!("unclassified ({pct:.0} %)"),
                ));
                draw_legend(&side, &legend)?;
            }
            MapKind::Scalar {
                range, quantity, ..
            } => match range {
                Some((a, b)) => {
                    let (_, sy) = side.get_pixel_range();
                    let top = (yr.start - sy.start).max(0) as u32;
                    let bottom = (sy.end - yr.end).max(0) as u32;
                    draw_colour_bar(&side, *a, *b, quantity, (top, bottom))?
                }
                None => {
                    draw_legend(
                        &side,
                        &[
                            LegendItem::Heading(quantity.to_string()),
                            LegendItem::Swatch(NO_DATA, "no finite values".into()),
                        ],
                    )?;
                }
            },
        }
        Ok(Some(raster))
    }
}

/// A vertical viridis colour bar for `[a, b]` with a labelled axis.
fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    a: f64,
    b: f64,
    quantity: &str,
    (top, bottom): (u32, u32),
) -> Result<()> {
    let (w, _) = area.dim_in_pixel();
    let mut ch = ChartBuilder::on(area)
        .margin_top(top)
        .margin_bottom(bottom)
        .margin_left(20)
        .margin_right(w.saturating_sub(20 + 36 + 90).max(4))
        .y_label_area_size(0)
        .set_label_area_size(LabelAreaPosition::Right, 90)
        .build_cartesian_2d(0.0..1.0, a..b)
        .dr()?;
    let steps = 128;
    let bars = (0..steps).map(|i| {
        let t0 = i as f64 / steps as f64;
        let t1 = (i + 1) as f64 / steps as f64;
        let c = viridis((t0 + t1) / 2.0);
        Rectangle::new(
            [(0.0, a + t0 * (b - a)), (1.0, a + t1 * (b - a))],
            c.filled(),
        )
    });
    ch.draw_series(bars).dr()?;
    ch.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(quantity)
        .axis_desc_style(font(LABEL_SIZE))
        .label_style(font(TICK_SIZE))
        .y_labels(7)
        .y_label_formatter(&fmt_tick)
        .set_all_tick_mark_size(6)
        .draw()
        .dr()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(png: &[u8]) -> image::DynamicImage {
        image::load_from_memory_with_format(png, image::ImageFormat::Png)
            .unwrap_or_else(|e| panic!("PNG does not decode: {e}"))
    }

    fn assert_outputs(r: &Rendered, size: PlotSize, texts: &[&str]) {
        let img = decode(&r.png);
        assert_eq!((img.width(), img.height()), (size.width, size.height));
        assert!(
            r.svg.starts_with("<svg"),
            "not an SVG: {}",
            &r.svg[..40.min(r.svg.len())]
        );
        assert!(r.svg.trim_end().ends_with("</svg>"));
        for t in texts {
            assert!(r.svg.contains(t), "SVG lacks the text {t:?}");
        }
    }

    /// Number of pixels of `png` within `tol` of colour `c`.
    fn count_colour(png: &[u8], c: RGBColor, tol: i32) -> usize {
        let img = decode(png).to_rgb8();
        img.pixels()
            .filter(|p| {
                (p[0] as i32 - c.0 as i32).abs() <= tol
                    && (p[1] as i32 - c.1 as i32).abs() <= tol
                    && (p[2] as i32 - c.2 as i32).abs() <= tol
            })
            .count()
    }

    fn synthetic_series() -> Vec<DolpSeries> {
        let targets = [
            ("green paint", 1.39, 0.34),
            ("aluminum", 1.24, 6.6),
            ("copper", 0.4, 2.95),
        ];
        targets
            .iter()
            .map(|&(name, n, k)| {
                let points = (0..10)
                    .map(|i| {
                        let beta = 47.5 + 2.5 * i as f64;
                        let p = polarid_core::dop::dop(n, k, beta.to_radians());
                        DolpPoint {
                            beta_deg: beta,
                            dolp: p + 0.01 * ((i as f64) * 1.7).sin(),
                            dolp_se: Some(0.01),
                        }
                    })
                    .collect();
                DolpSeries {
                    label: name.into(),
                    points,
                    curve: eq9_curve(n, k, 45.0, 72.0, 100),
                    curve_label: Some(format!("fit n = {n:.2}, k = {k:.2}")),
                }
            })
            .collect()
    }

    #[test]
    fn dolp_plot_writes_png_and_svg_with_labels() {
        let dir = tempfile::tempdir().unwrap();
        let size = PlotSize::REPORT;
        let r = dolp_vs_beta("DoLP against β", &synthetic_series(), size).unwrap();
        assert_outputs(
            &r,
            size,
            &[
                "β (degrees)",
                "DoLP",
                "green paint (data)",
                "fit n = 0.40, k = 2.95",
            ],
        );
        let files = r.write(dir.path(), "dolp_beta").unwrap();
        assert_eq!(files.png, dir.path().join("dolp_beta.png"));
        let on_disk = std::fs::read(&files.png).unwrap();
        assert_eq!(decode(&on_disk).width(), size.width);
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        assert!(svg.contains("β (degrees)"));
        // The series colours are really drawn (curves and markers), text really rendered.
        assert!(count_colour(&r.png, PALETTE[0], 10) > 200);
        assert!(count_colour(&r.png, PALETTE[2], 10) > 200);
        assert!(
            count_colour(&r.png, BLACK, 60) > 500,
            "no text drawn in the PNG"
        );
    }

    #[test]
    fn eq9_curve_matches_core() {
        let c = eq9_curve(1.24, 6.6, 40.0, 80.0, 5);
        assert_eq!(c.len(), 5);
        assert_eq!(c[0].0, 40.0);
        assert_eq!(c[4].0, 80.0);
        assert_eq!(
            c[2].1,
            polarid_core::dop::dop(1.24, 6.6, 60f64.to_radians())
        );
        assert!(sample_curve(0.0, 1.0, 0, |x| x).is_empty());
    }

    #[test]
    fn empty_data_draws_notices() {
        let size = PlotSize {
            width: 640,
            height: 400,
        };
        let r = dolp_vs_beta("empty", &[], size).unwrap();
        assert_outputs(&r, size, &["No DoLP data to plot"]);
        let nan = DolpSeries {
            label: "x".into(),
            points: vec![DolpPoint {
                beta_deg: f64::NAN,
                dolp: 0.3,
                dolp_se: None,
            }],
            curve: vec![],
            curve_label: None,
        };
        let r = dolp_vs_beta("nan", &[nan], size).unwrap();
        assert_outputs(&r, size, &["No DoLP data to plot"]);
        let r = nk_plane("empty", &[], &[], size).unwrap();
        assert_outputs(&r, size, &["No (n, k) values to plot"]);
        let r = class_map("empty", 0, 0, &[], &[], size).unwrap();
        assert_outputs(&r, size, &["Empty image"]);
        let r = scalar_map::<f32>("all NaN", 2, 1, &[f32::NAN, f32::NAN], None, "n", size).unwrap();
        assert_outputs(&r, size, &["no finite values"]);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let e = class_map("x", 3, 2, &[0; 5], &[], PlotSize::REPORT).unwrap_err();
        assert!(e.to_string().contains("5 values, expected 3 × 2"), "{e}");
        let e = scalar_map(
            "x",
            1,
            1,
            &[0.5f64],
            Some((1.0, 0.0)),
            "n",
            PlotSize::REPORT,
        )
        .unwrap_err();
        assert!(e.to_string().contains("colour range 1..0"), "{e}");
        let e = dolp_vs_beta(
            "x",
            &[],
            PlotSize {
                width: 10,
                height: 10,
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("10x10"), "{e}");
        let r = dolp_vs_beta("x", &[], PlotSize::REPORT).unwrap();
        assert!(r.write(Path::new("/nonexistent-dir-polarid"), "a").is_err());
        assert!(r.write(Path::new("."), "a/b").is_err());
    }

    #[test]
    fn ellipse_is_the_one_sigma_contour() {
        // Every point x of the ellipse satisfies (x - c)ᵀ Σ⁻¹ (x - c) = 1.
        let (n, k, sn, sk, rho) = (1.4, 4.0, 0.05, 0.3, 0.8);
        let pts = covariance_ellipse(n, k, sn, sk, rho, 64);
        assert_eq!(pts.len(), 65);
        let det = sn * sn * sk * sk * (1.0 - rho * rho);
        for (x, y) in pts {
            let (dx, dy) = (x - n, y - k);
            let m = (sk * sk * dx * dx - 2.0 * rho * sn * sk * dx * dy + sn * sn * dy * dy) / det;
            assert!((m - 1.0).abs() < 1e-9, "Mahalanobis² = {m}");
        }
        assert!(covariance_ellipse(0.0, 0.0, f64::NAN, 1.0, 0.0, 10).is_empty());
    }

    #[test]
    fn voronoi_cells_partition_by_nearest_prototype() {
        let sites = [(1.39, 0.34), (1.24, 6.6), (0.4, 2.95)];
        // Sample points: inside a cell iff that prototype is the nearest one.
        let inside = |poly: &[(f64, f64)], p: (f64, f64)| {
            (0..poly.len()).all(|i| {
                let a = poly[i];
                let b = poly[(i + 1) % poly.len()];
                (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0) >= -1e-12
            })
        };
        let cells: Vec<_> = (0..3)
            .map(|i| voronoi_cell(&sites, i, 0.0..2.0, 0.0..8.0))
            .collect();
        for gx in 0..20 {
            for gy in 0..20 {
                let p = (0.05 + 0.1 * gx as f64, 0.1 + 0.4 * gy as f64);
                let d = |s: (f64, f64)| (s.0 - p.0).powi(2) + (s.1 - p.1).powi(2);
                let nearest = (0..3)
                    .min_by(|&a, &b| d(sites[a]).total_cmp(&d(sites[b])))
                    .unwrap();
                for (i, c) in cells.iter().enumerate() {
                    assert_eq!(inside(c, p), i == nearest, "point {p:?} cell {i}");
                }
            }
        }
    }

    #[test]
    fn nk_plane_draws_regions_prototypes_and_ellipses() {
        let protos = vec![
            Prototype {
                class: "green paint".into(),
                n: 1.47,
                k: 0.47,
            },
            Prototype {
                class: "aluminum".into(),
                n: 1.64,
                k: 4.56,
            },
            Prototype {
                class: "copper".into(),
                n: 0.54,
                k: 3.19,
            },
        ];
        let ests = vec![
            NkEstimate {
                label: "test, θr = 60°".into(),
                n: 1.37,
                k: 3.97,
                n_se: 0.08,
                k_se: 0.3,
                corr: 0.6,
                predicted: Some("aluminum".into()),
            },
            NkEstimate {
                label: "test, θr = 50°".into(),
                n: 1.60,
                k: 4.34,
                n_se: 0.1,
                k_se: 0.4,
                corr: -0.2,
                predicted: None,
            },
        ];
        let size = PlotSize::REPORT;
        let r = nk_plane("(n, k) plane", &protos, &ests, size).unwrap();
        assert_outputs(
            &r,
            size,
            &[
                "n (real part of N)",
                "k (imaginary part of N)",
                "copper",
                "test, θr = 50°",
            ],
        );
        // All three decision regions are shaded.
        for (i, &c) in PALETTE.iter().take(3).enumerate() {
            let n = count_colour(&r.png, tint(c, 0.18), 2);
            assert!(n > 2000, "region {i} has {n} pixels");
            // Prototype markers in full colour.
            assert!(count_colour(&r.png, c, 8) > 50, "prototype {i}");
        }
        // No fourth class colour anywhere.
        assert_eq!(count_colour(&r.png, tint(PALETTE[3], 0.18), 2), 0);
        assert!(r.svg.matches("<polygon").count() >= 3);
    }

    #[test]
    fn class_map_colours_pixels_and_lists_classes() {
        let (w, h) = (40usize, 30usize);
        let classes: Vec<u16> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if y < 5 {
                    0
                } else if x < 20 {
                    1
                } else if x < 30 {
                    2
                } else {
                    3
                }
            })
            .collect();
        let names = vec!["aluminum".to_string(), "copper".to_string()];
        let size = PlotSize::REPORT;
        let r = class_map("Material map", w, h, &classes, &names, size).unwrap();
        assert_outputs(
            &r,
            size,
            &[
                "x (pixel column)",
                "y (pixel row)",
                "aluminum (42 %)",
                "class 3",
                "unclassified (17 %)",
            ],
        );
        assert!(r.svg.contains("<image") && r.svg.contains("data:image/png;base64,"));
        let a = count_colour(&r.png, PALETTE[0], 0);
        let c = count_colour(&r.png, PALETTE[1], 0);
        assert!(a > 10_000, "aluminum pixels: {a}");
        // Aluminium covers twice the area of copper (20 vs 10 columns).
        let ratio = a as f64 / c as f64;
        assert!((ratio - 2.0).abs() < 0.15, "area ratio {ratio}");
    }

    #[test]
    fn scalar_map_uses_viridis_and_colour_bar() {
        let (w, h) = (64usize, 48usize);
        let vals: Vec<f32> = (0..w * h)
            .map(|i| (i % w) as f32 / (w - 1) as f32)
            .collect();
        let size = PlotSize::REPORT;
        let r = scalar_map("DoLP map", w, h, &vals, None, "DoLP", size).unwrap();
        assert_outputs(&r, size, &["DoLP map", "DoLP", "x (pixel column)"]);
        let lo = count_colour(&r.png, viridis(0.0), 3);
        let hi = count_colour(&r.png, viridis(1.0), 3);
        assert!(lo > 500 && hi > 500, "ends of the map: {lo} {hi}");
        // NaN pixels are grey.
        let mut with_nan = vals.clone();
        for v in with_nan.iter_mut().take(w * 10) {
            *v = f32::NAN;
        }
        let r = scalar_map("n", w, h, &with_nan, Some((0.0, 1.0)), "n", size).unwrap();
        assert!(count_colour(&r.png, NO_DATA, 0) > 2000);
    }

    #[test]
    fn viridis_end_points_and_palette() {
        assert_eq!(viridis(0.0), RGBColor(0x44, 0x01, 0x54));
        assert_eq!(viridis(1.0), RGBColor(0xfd, 0xe7, 0x25));
        assert_eq!(viridis(2.0), viridis(1.0));
        assert_eq!(viridis(f64::NAN), NO_DATA);
        assert_ne!(class_colour(9), class_colour(10));
        assert_eq!(ellipsize("abcdef", 4), "abc…");
    }
}
