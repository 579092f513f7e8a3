//! Multi-band figures with one panel per band (docs/BANDS.md, "Per-band plots of your
//! data"): [`dolp_by_band`] (DoLP against β with each target's fitted eq. (9) curve of
//! that band) and [`nk_by_band`] (the `(n, k)` plane of each band: reference points and
//! the targets' estimates with their 1-σ ellipses). Each panel is titled `λ = 450 nm`
//! and its axes name the band (`DoLP at 450 nm`, `n at 450 nm`); one legend column
//! serves all panels, and a target keeps its colour in every panel.

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::PlotSize;
use super::canvas::*;
use super::dolp::{dolp_ranges, draw_dolp_series};
use super::nk::covariance_ellipse;
use super::style::DrawResult as _;
use super::style::*;
use super::{DolpSeries, NkEstimate, Prototype};
use crate::render::Rendered;

/// Width of one panel, pixels.
const PANEL_WIDTH: u32 = 470;
/// Height of one panel row, pixels.
const PANEL_HEIGHT: u32 = 520;
/// Panels per row.
const PER_ROW: usize = 3;

/// The figure size for `panels` panels: up to three per row, plus the legend column.
pub fn panel_size(panels: usize) -> PlotSize {
    let cols = panels.clamp(1, PER_ROW) as u32;
    let rows = panels.max(1).div_ceil(PER_ROW) as u32;
    PlotSize {
        width: (cols * PANEL_WIDTH + LEGEND_WIDTH).min(8000),
        height: (rows * PANEL_HEIGHT + 60).min(8000),
    }
}

/// The file-name and label tag of a band: `450` or `632.8` nm.
pub fn band_label(wavelength_nm: f64) -> String {
    if wavelength_nm.fract() == 0.0 && wavelength_nm.abs() < 1e9 {
        format!("{wavelength_nm:.0}")
    } else {
        format!("{wavelength_nm}")
    }
}

/// One band's DoLP data: the series of every target in the same order in every band
/// (a target without data in this band has empty `points` and `curve`).
#[derive(Debug, Clone, PartialEq)]
pub struct DolpBand {
    /// The band's centre wavelength, nm.
    pub wavelength_nm: f64,
    /// One series per target (legend text from the first band's series).
    pub series: Vec<DolpSeries>,
}

/// One band's `(n, k)` data: reference points (library materials or model prototypes)
/// and the targets' estimates, in the same target order in every band (`None`: the
/// target has no estimate in this band).
#[derive(Debug, Clone, PartialEq)]
pub struct NkBand {
    /// The band's centre wavelength, nm.
    pub wavelength_nm: f64,
    /// Reference points; a class keeps its colour across bands (first-appearance order
    /// over all bands).
    pub references: Vec<Prototype>,
    /// One entry per target.
    pub estimates: Vec<Option<NkEstimate>>,
}

/// DoLP against β, one panel per band: each target's measurements (±1 SE bars) and its
/// fitted eq. (9) curve in that band.
pub fn dolp_by_band(title: &str, bands: &[DolpBand]) -> Result<Rendered> {
    render(&DolpPanels { title, bands }, panel_size(bands.len()))
}

/// The `(n, k)` plane, one panel per band: reference points (circles) and the targets'
/// estimates with 1-σ covariance ellipses.
pub fn nk_by_band(title: &str, bands: &[NkBand]) -> Result<Rendered> {
    render(&NkPanels { title, bands }, panel_size(bands.len()))
}

struct DolpPanels<'a> {
    title: &'a str,
    bands: &'a [DolpBand],
}

fn draw_dolp_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, b: &DolpBand) -> Result<()> {
    let (Some((x0, x1)), ys) = dolp_ranges(&b.series) else {
        return draw_notice(area, "No DoLP data in this band");
    };
    let (y0, y1) = ys.unwrap_or((0.0, 1.0));
    let (x0, x1) = padded(x0, x1, 0.04, 2.0);
    let (x0, x1) = (x0.max(0.0), x1.min(90.0));
    let (y0, y1) = padded(y0, y1, 0.06, 0.05);
    let (y0, y1) = (y0.max(0.0), y1.min(1.05));
    let mut ch = chart(area, x0..x1, y0..y1, (8, 16, 4, 4))?;
    let tag = band_label(b.wavelength_nm);
    configure_axes(&mut ch, "β (degrees)", &format!("DoLP at {tag} nm"), true)?;
    for (i, s) in b.series.iter().enumerate() {
        draw_dolp_series(&mut ch, s, class_colour(i), (2, 5, false))?;
    }
    Ok(())
}

impl Figure for DolpPanels<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let legend = || {
            let mut legend = vec![LegendItem::Heading("targets (±1 SE)".into())];
            // ok: `bands` is not empty (`draw_bands` checks it before the legend).
            legend.extend(class_markers(self.bands[0].series.iter().map(|s| &s.label)));
            legend.push(LegendItem::Line(BLACK, "eq. (9) fit of the band".into()));
            legend
        };
        let wavelength = |b: &DolpBand| b.wavelength_nm;
        draw_bands(
            root,
            self.title,
            self.bands,
            wavelength,
            draw_dolp_panel,
            legend,
        )
    }
}

/// A figure of one panel per band: `title`, the panels (each titled `λ = … nm`, then drawn
/// by `panel`) and the legend column, or a notice when there is no band.
fn draw_bands<DB: DrawingBackend, B>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    bands: &[B],
    wavelength: impl Fn(&B) -> f64,
    panel: impl Fn(&DrawingArea<DB, Shift>, &B) -> Result<()>,
    legend: impl FnOnce() -> Vec<LegendItem>,
) -> Result<Option<Raster>> {
    let (main, side) = layout(root, title)?;
    if bands.is_empty() {
        draw_notice(&main, "No bands to plot")?;
        return Ok(None);
    }
    let cells = main.split_evenly((bands.len().div_ceil(PER_ROW), bands.len().min(PER_ROW)));
    let label = |b: &B| format!("λ = {} nm", band_label(wavelength(b)));
    let titled = cells.into_iter().zip(bands);
    let titled = titled.map(|(c, b)| c.titled(&label(b), font(LABEL_SIZE)).dr());
    // Every panel titled first, then drawn (the order of the SVG's elements).
    for (area, b) in titled.collect::<Result<Vec<_>>>()?.iter().zip(bands) {
        panel(area, b)?;
    }
    draw_legend(&side, &legend())?;
    Ok(None)
}

struct NkPanels<'a> {
    title: &'a str,
    bands: &'a [NkBand],
}

impl NkPanels<'_> {
    /// Reference classes in first-appearance order over all bands.
    fn classes(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        for p in self.bands.iter().flat_map(|b| &b.references) {
            if !out.contains(&p.class.as_str()) {
                out.push(&p.class);
            }
        }
        out
    }

    /// Colour of target `j` (after the reference classes' colours, as in
    /// [`nk_spectra`](super::bands::nk_spectra)).
    fn target_colour(&self, j: usize) -> RGBColor {
        class_colour(self.classes().len() + j)
    }

    fn panel<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>, b: &NkBand) -> Result<()> {
        let classes = self.classes();
        let refs: Vec<&Prototype> = b
            .references
            .iter()
            .filter(|p| p.n.is_finite() && p.k.is_finite())
            .collect();
        let fin = |v: f64| if v.is_finite() && v > 0.0 { v } else { 0.0 };
        let ests = || {
            b.estimates
                .iter()
                .enumerate()
                .filter_map(|(j, e)| e.as_ref().map(|e| (j, e)))
                .filter(|(_, e)| e.n.is_finite() && e.k.is_finite())
        };
        let ns = refs
            .iter()
            .map(|p| p.n)
            .chain(ests().flat_map(|(_, e)| [e.n - fin(e.n_se), e.n + fin(e.n_se)]));
        let ks = refs
            .iter()
            .map(|p| p.k)
            .chain(ests().flat_map(|(_, e)| [e.k - fin(e.k_se), e.k + fin(e.k_se)]));
        let (Some((n0, n1)), Some((k0, k1))) = (min_max(ns), min_max(ks)) else {
            return draw_notice(area, "No (n, k) in this band");
        };
        let (n0, n1) = padded(n0, n1, 0.12, 0.5);
        let (k0, k1) = padded(k0, k1, 0.12, 0.5);
        let mut ch = chart(area, n0.max(0.0)..n1, k0.max(0.0)..k1, (8, 16, 4, 4))?;
        let tag = band_label(b.wavelength_nm);
        configure_axes(
            &mut ch,
            &format!("n at {tag} nm"),
            &format!("k at {tag} nm"),
            true,
        )?;
        let pa = ch.plotting_area();
        for (j, e) in ests() {
            let ell = covariance_ellipse(e.n, e.k, e.n_se, e.k_se, e.corr, 96);
            if ell.len() > 3 {
                pa.draw(&PathElement::new(
                    ell,
                    self.target_colour(j).stroke_width(2),
                ))
                .dr()?;
            }
        }
        for p in &refs {
            let i = classes.iter().position(|c| *c == p.class).unwrap_or(0);
            draw_marker(pa, (p.n, p.k), Marker::Circle, 7, class_colour(i).filled())?;
            draw_marker(pa, (p.n, p.k), Marker::Circle, 7, BLACK.stroke_width(1))?;
        }
        for (j, e) in ests() {
            let m = ESTIMATE_MARKERS[j % ESTIMATE_MARKERS.len()];
            draw_marker(pa, (e.n, e.k), m, 6, self.target_colour(j).filled())?;
        }
        Ok(())
    }

    /// The legend: the reference classes, then every target's marker and answer.
    fn legend(&self) -> Vec<LegendItem> {
        let mut legend = Vec::new();
        let classes = self.classes();
        if !classes.is_empty() {
            legend.push(LegendItem::Heading("references".into()));
        }
        legend.extend(class_markers(&classes));
        legend.push(LegendItem::Heading("targets (1-σ ellipse)".into()));
        let n_targets = self.bands.iter().map(|b| b.estimates.len()).max();
        for j in 0..n_targets.unwrap_or(0) {
            let Some(e) = self
                .bands
                .iter()
                .find_map(|b| b.estimates.get(j).and_then(|e| e.as_ref()))
            else {
                continue;
            };
            let text = match &e.answer {
                Some(a) => format!("{}: {a}", e.label),
                None => e.label.clone(),
            };
            legend.push(LegendItem::Marker(
                ESTIMATE_MARKERS[j % ESTIMATE_MARKERS.len()],
                self.target_colour(j),
                text,
            ));
        }
        legend
    }
}

impl Figure for NkPanels<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let wavelength = |b: &NkBand| b.wavelength_nm;
        let panel = |area: &DrawingArea<DB, Shift>, b: &NkBand| self.panel(area, b);
        draw_bands(root, self.title, self.bands, wavelength, panel, || {
            self.legend()
        })
    }
}
