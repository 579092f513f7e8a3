//! Rendering a figure to PNG and SVG (with an optional raster overlay) and the chart
//! frame shared by the figures: axes, margins, title and legend column.

use std::ops::Range;

use anyhow::{Context, Result, anyhow};
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::PlotSize;
use super::style::DrawResult as _;
use super::style::*;
use crate::render::{Rendered, base64};

/// An RGB raster to place over the plotting area after drawing (image maps).
pub(super) struct Raster {
    /// Top-left pixel.
    pub(super) x: i32,
    pub(super) y: i32,
    pub(super) w: u32,
    pub(super) h: u32,
    pub(super) rgb: Vec<u8>,
}

/// A drawing that can target any plotters backend.
pub(super) trait Figure {
    /// Draw onto `root` (already white). Returns the raster to overlay, if any.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>>;

    /// Draw over the raster (called after it is placed; nothing by default).
    fn overlay<DB: DrawingBackend>(&self, _root: &DrawingArea<DB, Shift>) -> Result<()> {
        Ok(())
    }
}

pub(super) fn encode_png(rgb: &[u8], w: u32, h: u32) -> Result<Vec<u8>> {
    crate::render::png::encode_rgb8(rgb, w, h).context("PNG encoding failed")
}

/// Render `fig` to PNG and SVG.
pub(super) fn render(fig: &impl Figure, size: PlotSize) -> Result<Rendered> {
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
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        fig.overlay(&root)?;
        root.present().dr()?;
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
            base64::encode(&img)
        );
        let end = svg
            .rfind("</svg>")
            .ok_or_else(|| anyhow!("internal error: SVG output has no closing tag"))?;
        svg.insert_str(end, &tag);
        // The overlay's elements after the image (without their own <svg> wrapper).
        let mut over = String::new();
        {
            let root = SVGBackend::with_string(&mut over, (w, h)).into_drawing_area();
            fig.overlay(&root)?;
            root.present().dr()?;
        }
        let open = over
            .find("<svg")
            .and_then(|i| over[i..].find('>').map(|j| i + j + 1));
        if let (Some(a), Some(b)) = (open, over.rfind("</svg>"))
            && a < b
        {
            let end = svg
                .rfind("</svg>")
                .ok_or_else(|| anyhow!("internal error: SVG output has no closing tag"))?;
            svg.insert_str(end, &over[a..b]);
        }
    }
    Ok(Rendered { png, svg })
}

/// Copy `r` into the RGB buffer `buf` (`w` × `h`), clipped.
pub(super) fn paste(buf: &mut [u8], w: u32, h: u32, r: &Raster) {
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
pub(super) fn padded(lo: f64, hi: f64, frac: f64, min_span: f64) -> (f64, f64) {
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

pub(super) fn min_max(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((a, b)) => Some((a.min(v), b.max(v))),
        })
}

pub(super) type Chart2d<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart in `area` with the project's axis styling.
pub(super) fn chart<'a, DB: DrawingBackend>(
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

pub(super) fn configure_axes<DB: DrawingBackend>(
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
pub(super) fn layout<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<(DrawingArea<DB, Shift>, DrawingArea<DB, Shift>)> {
    let body = root.titled(title, font(TITLE_SIZE)).dr()?;
    let (w, _) = body.dim_in_pixel();
    Ok(body.split_horizontally(w.saturating_sub(LEGEND_WIDTH)))
}
