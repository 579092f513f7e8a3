//! (c) Image maps: a class-index image with a legend, a scalar image with a colour bar.

use anyhow::Result;
use anyhow::bail;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::PlotSize;
use super::canvas::*;
use super::style::DrawResult as _;
use super::style::*;
use crate::render::Rendered;

/// A material map: `classes` is a `width × height` row-major class-index image
/// (0 = `unknown`, `i ≥ 1` = `names[i - 1]`), drawn in the categorical palette with
/// a legend. Indices without a name are labelled `class i`. The same as
/// [`answer_map`] without reasons or regions.
#[cfg(test)]
pub fn class_map(
    title: &str,
    width: usize,
    height: usize,
    classes: &[u16],
    names: &[String],
    size: PlotSize,
) -> Result<Rendered> {
    answer_map(
        title,
        &ClassMap {
            width,
            height,
            classes,
            names,
            reasons: None,
            regions: Vec::new(),
        },
        size,
    )
}

/// A labelled rectangle outlined over a class map.
#[derive(Debug, Clone, PartialEq)]
pub struct MapRegion {
    /// The label (the region's name).
    pub name: String,
    /// `[x, y, width, height]` in map pixels (a manifest rectangle divided by the map's
    /// binning).
    pub rect: [f64; 4],
}

/// The data of a material map ([`answer_map`]).
#[derive(Debug, Clone)]
pub struct ClassMap<'a> {
    /// Image width (map pixels).
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Class index per pixel, row-major (0 = `unknown`, `i ≥ 1` = `names[i - 1]`).
    pub classes: &'a [u16],
    /// The class names; a name `ambiguous` is the set rule's answer for several
    /// materials and gets its own colour.
    pub names: &'a [String],
    /// The reason codes of `reason.tif` (`polarid_core::map::reason`), same size: the
    /// `unknown` pixels are then coloured by why (docs/FORMATS.md, "Answers").
    pub reasons: Option<&'a [u8]>,
    /// Rectangles outlined and labelled over the image.
    pub regions: Vec<MapRegion>,
}

/// The four kinds of `unknown` pixels a class map tells apart (with reasons).
#[derive(Clone, Copy, PartialEq, Eq)]
enum UnknownKind {
    /// Fitted `ok`, no material consistent (reason `rejected`).
    Rejected,
    /// No usable fit: a fit status other than `ok`, or no geometry.
    NoFit,
    /// Saturated in some capture.
    Saturated,
    /// Dark or invalid data.
    Dark,
}

impl UnknownKind {
    const ALL: [UnknownKind; 4] = [
        UnknownKind::Rejected,
        UnknownKind::NoFit,
        UnknownKind::Saturated,
        UnknownKind::Dark,
    ];

    fn of(reason: u8) -> Self {
        use polarid_core::map::reason as r;
        match reason {
            r::REJECTED => UnknownKind::Rejected,
            r::SATURATED => UnknownKind::Saturated,
            r::DARK | r::INVALID => UnknownKind::Dark,
            _ => UnknownKind::NoFit,
        }
    }

    fn colour(self) -> RGBColor {
        let [sr, sg, sb] = crate::render::views::SATURATED_RGB;
        let [dr, dg, db] = crate::render::views::DARK_RGB;
        match self {
            UnknownKind::Rejected => REJECTED_COLOUR,
            UnknownKind::NoFit => NO_DATA,
            UnknownKind::Saturated => RGBColor(sr, sg, sb),
            UnknownKind::Dark => RGBColor(dr, dg, db),
        }
    }

    fn label(self) -> &'static str {
        match self {
            UnknownKind::Rejected => "unknown: rejected (no material consistent)",
            UnknownKind::NoFit => "unknown: no usable fit",
            UnknownKind::Saturated => "unknown: saturated",
            UnknownKind::Dark => "unknown: dark or invalid",
        }
    }
}

/// A material map with the answer words of docs/FORMATS.md ("Answers"): each material
/// in the categorical palette, `ambiguous` dark grey, and the `unknown` pixels by reason
/// when `data.reasons` is given (`rejected` mid grey, no usable fit light grey,
/// `saturated` pink-magenta and `dark`/`invalid` dark slate, the colours of the `stokes`
/// views), with the regions outlined and labelled and a legend of the pixel shares.
pub fn answer_map(title: &str, data: &ClassMap<'_>, size: PlotSize) -> Result<Rendered> {
    check_image(data.width, data.height, data.classes.len())?;
    if let Some(r) = data.reasons {
        check_image(data.width, data.height, r.len())?;
    }
    render(
        &MapFigure {
            title,
            width: data.width,
            height: data.height,
            kind: MapKind::Classes {
                classes: data.classes,
                names: data.names,
                reasons: data.reasons,
                regions: &data.regions,
            },
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
        reasons: Option<&'a [u8]>,
        regions: &'a [MapRegion],
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
            MapKind::Classes {
                classes,
                names,
                reasons,
                ..
            } => match classes.get(idx) {
                Some(0) | None => match reasons.and_then(|r| r.get(idx)) {
                    Some(&r) => UnknownKind::of(r).colour(),
                    None => NO_DATA,
                },
                Some(&c) => match names.get(c as usize - 1) {
                    Some(n) if n == polarid_core::classify::AMBIGUOUS => AMBIGUOUS_COLOUR,
                    _ => class_colour(c as usize - 1),
                },
            },
            MapKind::Scalar { values, range, .. } => match (values.get(idx), range) {
                (Some(v), Some((a, b))) if v.is_finite() => viridis((v - a) / (b - a)),
                _ => NO_DATA,
            },
        }
    }

    /// The chart of the image in `main`: the image's aspect ratio fitted into the area.
    fn image_chart<'a, DB: DrawingBackend>(
        &self,
        main: &'a DrawingArea<DB, Shift>,
    ) -> Result<Chart2d<'a, DB>> {
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
        chart(
            main,
            0.0..w,
            h..0.0,
            (
                pad as u32 + extra_h,
                pad as u32 + extra_w,
                pad as u32 + extra_h,
                pad as u32 + extra_w,
            ),
        )
    }
}

/// The legend of a class map: each answer's share of the pixels, and the kinds of
/// `unknown` (with `reasons`) or `unknown` as a whole.
fn class_legend(classes: &[u16], names: &[String], reasons: Option<&[u8]>) -> Vec<LegendItem> {
    let mut counts = vec![0u64; names.len() + 1];
    let mut unnamed: Vec<(u16, u64)> = Vec::new();
    let mut unknown = [0u64; UnknownKind::ALL.len()];
    for (i, &c) in classes.iter().enumerate() {
        if c == 0
            && let Some(&r) = reasons.and_then(|r| r.get(i))
        {
            let k = UnknownKind::of(r);
            if let Some(j) = UnknownKind::ALL.iter().position(|&u| u == k) {
                unknown[j] += 1;
            }
        }
        match counts.get_mut(c as usize) {
            Some(n) => *n += 1,
            None => match unnamed.iter_mut().find(|(u, _)| *u == c) {
                Some((_, n)) => *n += 1,
                None => unnamed.push((c, 1)),
            },
        }
    }
    unnamed.sort_unstable();
    let total = classes.len().max(1) as f64;
    let pct = |n: u64| 100.0 * n as f64 / total;
    let mut legend = vec![LegendItem::Heading("Answers (pixel share)".into())];
    for (i, name) in names.iter().enumerate() {
        let colour = if name == polarid_core::classify::AMBIGUOUS {
            AMBIGUOUS_COLOUR
        } else {
            class_colour(i)
        };
        legend.push(LegendItem::Swatch(
            colour,
            format!("{name} ({:.0} %)", pct(counts[i + 1])),
        ));
    }
    for (c, n) in unnamed {
        legend.push(LegendItem::Swatch(
            class_colour(c as usize - 1),
            format!("class {c} ({:.0} %)", pct(n)),
        ));
    }
    let any_unknown = unknown.iter().any(|&n| n > 0);
    if reasons.is_some() && any_unknown {
        for (k, n) in UnknownKind::ALL.iter().zip(unknown) {
            if n > 0 {
                legend.push(LegendItem::Swatch(
                    k.colour(),
                    format!("{} ({:.0} %)", k.label(), pct(n)),
                ));
            }
        }
    } else {
        legend.push(LegendItem::Swatch(
            NO_DATA,
            format!(
                "{} ({:.0} %)",
                polarid_core::classify::UNKNOWN,
                pct(counts[0])
            ),
        ));
    }
    legend
}

impl Figure for MapFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let (main, side) = layout(root, self.title)?;
        if self.width == 0 || self.height == 0 {
            draw_notice(&main, "Empty image")?;
            return Ok(None);
        }
        let (w, h) = (self.width as f64, self.height as f64);
        let mut ch = self.image_chart(&main)?;
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
            MapKind::Classes {
                classes,
                names,
                reasons,
                ..
            } => {
                draw_legend(&side, &class_legend(classes, names, *reasons))?;
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

    /// The regions' outlines and labels, over the image.
    fn overlay<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        let MapKind::Classes { regions, .. } = &self.kind else {
            return Ok(());
        };
        if regions.is_empty() || self.width == 0 || self.height == 0 {
            return Ok(());
        }
        let (main, _) = layout(root, self.title)?;
        let ch = self.image_chart(&main)?;
        let area = ch.plotting_area();
        let (w, h) = (self.width as f64, self.height as f64);
        let label = font(LEGEND_SIZE - 3).pos(Pos::new(HPos::Left, VPos::Top));
        for r in regions.iter() {
            let [x, y, rw, rh] = r.rect;
            if !(x.is_finite() && y.is_finite() && rw > 0.0 && rh > 0.0) {
                continue;
            }
            let (x0, y0) = (x.clamp(0.0, w), y.clamp(0.0, h));
            let (x1, y1) = ((x + rw).clamp(0.0, w), (y + rh).clamp(0.0, h));
            if x1 <= x0 || y1 <= y0 {
                continue;
            }
            let corners = vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)];
            // White under black: visible on every colour of the map.
            area.draw(&PathElement::new(corners.clone(), WHITE.stroke_width(4)))
                .dr()?;
            area.draw(&PathElement::new(corners, BLACK.stroke_width(2)))
                .dr()?;
            let (tw, th) = area
                .estimate_text_size(&r.name, &label)
                .unwrap_or((8 * r.name.len() as u32, 16));
            area.draw(
                &(EmptyElement::at((x0, y0))
                    + Rectangle::new(
                        [(2, 2), (tw as i32 + 8, th as i32 + 6)],
                        WHITE.mix(0.85).filled(),
                    )
                    + Text::new(r.name.clone(), (5, 4), label.clone())),
            )
            .dr()?;
        }
        Ok(())
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
