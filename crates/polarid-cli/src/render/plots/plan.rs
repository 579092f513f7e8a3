//! `polarid plan`'s figure: DoLP against β per plate, one colour per plate: its material's
//! curve (solid), its hardest alternative's (dashed), the recommended rows (filled
//! circles, ±1 σ of the row) and the current ones (hollow diamonds). The legend gives the
//! answer: per plate its verdict and its hardest alternative's power.

use anyhow::Result;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::PlotSize;
use super::canvas::*;
use super::dolp::{DolpPoint, draw_se_bar, finite};
use super::style::DrawResult as _;
use super::style::*;
use crate::render::Rendered;

/// One plate of [`plan_dolp`].
#[derive(Debug, Clone, PartialEq)]
pub struct PlanPlate {
    /// Legend heading: the plate and its verdict, e.g. `gold: NOT identifiable`.
    pub heading: String,
    /// Its material's curve `(β degrees, DoLP)`.
    pub curve: Vec<(f64, f64)>,
    /// Its legend text (the material).
    pub curve_label: String,
    /// The hardest alternative's curve (may be empty).
    pub alt_curve: Vec<(f64, f64)>,
    /// Its legend text, e.g. `magnesium: power 0.66`.
    pub alt_label: String,
    /// The recommended rows (on the material's curve, `dolp_se`: the row's σ).
    pub recommended: Vec<DolpPoint>,
    /// The current rows (the scene's own sources; may be empty).
    pub current: Vec<DolpPoint>,
}

/// Dash and gap of the alternatives' curves, pixels.
const DASH: (u32, u32) = (10, 6);

/// The axes of a plan figure: labels and the largest extents.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanAxes {
    /// The x axis' label.
    pub x_label: &'static str,
    /// The y axis' label.
    pub y_label: &'static str,
    /// The x axis' widest range.
    pub x_limits: (f64, f64),
    /// The y axis' top limit.
    pub y_cap: f64,
}

impl PlanAxes {
    /// DoLP against β (degrees).
    pub const DOLP: PlanAxes = PlanAxes {
        x_label: "β (degrees)",
        y_label: "DoLP",
        x_limits: (0.0, 90.0),
        y_cap: 1.05,
    };
}

/// Draw the plan figure (DoLP against β: [`PlanAxes::DOLP`]; the curves and rows may be
/// any other pair of quantities of the positions, e.g. β against the time of day).
pub fn plan_dolp(
    title: &str,
    plates: &[PlanPlate],
    notes: &[String],
    axes: PlanAxes,
    size: PlotSize,
) -> Result<Rendered> {
    render(
        &PlanFigure {
            title,
            plates,
            notes,
            axes,
        },
        size,
    )
}

struct PlanFigure<'a> {
    title: &'a str,
    plates: &'a [PlanPlate],
    notes: &'a [String],
    axes: PlanAxes,
}

/// Plate `p`'s rows in colour `c`: the current positions (diamonds) and the recommended
/// ones (circles, with their ±1 σ bars).
fn draw_rows<DB: DrawingBackend>(
    area: &DrawingArea<DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    p: &PlanPlate,
    c: RGBColor,
) -> Result<()> {
    for q in p.current.iter().filter(|q| q.valid()) {
        draw_marker(
            area,
            (q.beta_deg, q.dolp),
            Marker::Diamond,
            6,
            WHITE.filled(),
        )?;
        draw_marker(
            area,
            (q.beta_deg, q.dolp),
            Marker::Diamond,
            6,
            shade(c, 0.8).stroke_width(2),
        )?;
    }
    for q in p.recommended.iter().filter(|q| q.valid()) {
        draw_se_bar(area, q, shade(c, 0.7).stroke_width(2))?;
        draw_marker(area, (q.beta_deg, q.dolp), Marker::Circle, 6, c.filled())?;
        draw_marker(
            area,
            (q.beta_deg, q.dolp),
            Marker::Circle,
            6,
            shade(c, 0.6).stroke_width(1),
        )?;
    }
    Ok(())
}

impl Figure for PlanFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let (main, side) = layout(root, self.title)?;
        let points = || {
            self.plates
                .iter()
                .flat_map(|p| p.recommended.iter().chain(&p.current))
                .filter(|p| p.valid())
        };
        let curves = || {
            self.plates
                .iter()
                .flat_map(|p| finite(&p.curve).into_iter().chain(finite(&p.alt_curve)))
        };
        let Some((x0, x1)) = min_max(points().map(|p| p.beta_deg).chain(curves().map(|c| c.0)))
        else {
            draw_notice(&main, "No DoLP data to plot")?;
            return Ok(None);
        };
        let ys = points()
            .flat_map(|p| [p.dolp - p.se(), p.dolp + p.se()])
            .chain(curves().map(|c| c.1));
        let (_, y1) = min_max(ys).unwrap_or((0.0, 1.0));
        let (x0, x1) = padded(x0, x1, 0.02, 2.0);
        let a = self.axes;
        let (x0, x1) = (x0.max(a.x_limits.0), x1.min(a.x_limits.1));
        let (y0, y1) = (0.0, (y1 * 1.06).clamp(0.02 * a.y_cap, a.y_cap));
        let mut ch = chart(&main, x0..x1, y0..y1, (12, 20, 8, 8))?;
        configure_axes(&mut ch, a.x_label, a.y_label, true)?;

        let mut legend = Vec::new();
        for (i, p) in self.plates.iter().enumerate() {
            let c = class_colour(i);
            let alt = finite(&p.alt_curve);
            let area = ch.plotting_area();
            if !alt.is_empty() {
                area.draw(&plotters::element::DashedPathElement::new(
                    alt.iter().copied(),
                    DASH.0,
                    DASH.1,
                    tint(c, 0.6).stroke_width(2),
                ))
                .dr()?;
            }
            let curve = finite(&p.curve);
            if !curve.is_empty() {
                ch.draw_series(LineSeries::new(curve, c.stroke_width(3)))
                    .dr()?;
            }
            draw_rows(ch.plotting_area(), p, c)?;
            legend.push(LegendItem::Heading(p.heading.clone()));
            legend.push(LegendItem::Line(c, p.curve_label.clone()));
            if !alt.is_empty() {
                legend.push(LegendItem::Dashed(tint(c, 0.6), DASH, p.alt_label.clone()));
            }
        }
        let grey = RGBColor(90, 90, 90);
        legend.push(LegendItem::Heading("rows".into()));
        let bars = self
            .plates
            .iter()
            .flat_map(|p| &p.recommended)
            .any(|q| q.se() > 0.0);
        legend.push(LegendItem::Marker(
            Marker::Circle,
            grey,
            if bars {
                "recommended (bar ±1 σ)".into()
            } else {
                "recommended".into()
            },
        ));
        if self.plates.iter().any(|p| !p.current.is_empty()) {
            legend.push(LegendItem::Marker(Marker::Diamond, grey, "current".into()));
        }
        for n in self.notes {
            legend.push(LegendItem::Note(n.clone()));
        }
        draw_legend(&side, &legend)?;
        Ok(None)
    }
}
