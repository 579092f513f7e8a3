//! (c) Image maps: a class-index image with a legend, a scalar image with a colour bar.

use anyhow::Result;
use anyhow::bail;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::PlotSize;
use super::canvas::*;
use super::style::DrawResult as _;
use super::style::*;
use crate::render::Rendered;

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
