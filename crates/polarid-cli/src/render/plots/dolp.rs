//! (a) Measured DoLP against β with the fitted eq. (9) curve.

use anyhow::Result;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::PlotSize;
use super::canvas::*;
use super::style::DrawResult as _;
use super::style::*;
use crate::render::Rendered;

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

impl DolpPoint {
    /// Whether the point can be drawn: its β and DoLP are finite.
    pub(super) fn valid(&self) -> bool {
        self.beta_deg.is_finite() && self.dolp.is_finite()
    }

    /// Its ±1 SE bar's half-height (0 when it has no standard error).
    pub(super) fn se(&self) -> f64 {
        self.dolp_se
            .filter(|s| s.is_finite() && *s > 0.0)
            .unwrap_or(0.0)
    }
}

/// The samples of curve `c` whose both coordinates are finite.
pub(super) fn finite(c: &[(f64, f64)]) -> Vec<(f64, f64)> {
    c.iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect()
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

/// DoLP against β (degrees) for each target: measurements with ±1 SE bars and the
/// fitted eq. (9) curve, one colour per series.
pub fn dolp_vs_beta(title: &str, series: &[DolpSeries], size: PlotSize) -> Result<Rendered> {
    render(&DolpFigure { title, series }, size)
}

/// The ranges of β and of DoLP ± 1 SE over the valid points and the curves of `series`
/// (`None`: no finite value).
pub(super) fn dolp_ranges(series: &[DolpSeries]) -> (Option<(f64, f64)>, Option<(f64, f64)>) {
    let xs = series.iter().flat_map(|s| {
        s.points
            .iter()
            .filter(|p| p.valid())
            .map(|p| p.beta_deg)
            .chain(s.curve.iter().filter(|c| c.1.is_finite()).map(|c| c.0))
    });
    let ys = series.iter().flat_map(|s| {
        s.points
            .iter()
            .filter(|p| p.valid())
            .flat_map(|p| [p.dolp - p.se(), p.dolp + p.se()])
            .chain(s.curve.iter().filter(|c| c.0.is_finite()).map(|c| c.1))
    });
    (min_max(xs), min_max(ys))
}

/// Draw `p`'s ±1 SE bar in `st`; `false` (nothing drawn) when its SE is 0.
pub(super) fn draw_se_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    p: &DolpPoint,
    st: ShapeStyle,
) -> Result<bool> {
    let e = p.se();
    if e > 0.0 {
        area.draw(&PathElement::new(
            vec![(p.beta_deg, p.dolp - e), (p.beta_deg, p.dolp + e)],
            st,
        ))
        .dr()?;
    }
    Ok(e > 0.0)
}

/// Draw `s` in colour `c`: its finite curve `line` pixels wide, then every valid point as
/// a filled circle of radius `radius` over its ±1 SE bar; `detailed`: with caps on the
/// bars and a ring around the circles.
pub(super) fn draw_dolp_series<DB: DrawingBackend>(
    ch: &mut Chart2d<'_, DB>,
    s: &DolpSeries,
    c: RGBColor,
    (line, radius, detailed): (u32, i32, bool),
) -> Result<()> {
    let curve = finite(&s.curve);
    if !curve.is_empty() {
        ch.draw_series(LineSeries::new(curve, c.stroke_width(line)))
            .dr()?;
    }
    let area = ch.plotting_area();
    for p in s.points.iter().filter(|p| p.valid()) {
        let (at, e) = ((p.beta_deg, p.dolp), p.se());
        let st = shade(c, 0.8).stroke_width(2);
        if draw_se_bar(area, p, st)? {
            for yy in [p.dolp - e, p.dolp + e].into_iter().filter(|_| detailed) {
                area.draw(
                    &(EmptyElement::at((p.beta_deg, yy))
                        + PathElement::new(vec![(-5, 0), (5, 0)], st)),
                )
                .dr()?;
            }
        }
        draw_marker(area, at, Marker::Circle, radius, c.filled())?;
        if detailed {
            let ring = shade(c, 0.6).stroke_width(1);
            draw_marker(area, at, Marker::Circle, radius, ring)?;
        }
    }
    Ok(())
}

struct DolpFigure<'a> {
    title: &'a str,
    series: &'a [DolpSeries],
}

impl Figure for DolpFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let (main, side) = layout(root, self.title)?;
        let (Some((x0, x1)), ys) = dolp_ranges(self.series) else {
            draw_notice(&main, "No DoLP data to plot")?;
            return Ok(None);
        };
        let (y0, y1) = ys.unwrap_or((0.0, 1.0));
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
            draw_dolp_series(&mut ch, s, c, (3, 6, true))?;
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
