//! (b) The (n, k) plane: prototypes, nearest-neighbour decision regions, and the estimates
//! with the confidence regions that decide their consistent sets (or 1-σ ellipses when
//! none was computed).

use std::ops::Range;

use anyhow::Result;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::PlotSize;
use super::canvas::*;
use super::style::DrawResult as _;
use super::style::*;
use crate::render::Rendered;

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
    /// The answer for the legend (see [`answer_text`]), e.g. `aluminum`,
    /// `ambiguous: gold, copper`, `unknown`.
    pub answer: Option<String>,
    /// The confidence regions that decide the consistent set (see
    /// `polarid_pipeline::classify::decision_regions`); when empty the 1-σ ellipse of
    /// `n_se`, `k_se`, `corr` is drawn instead.
    pub regions: Vec<NkRegion>,
}

/// One drawn confidence region of an estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct NkRegion {
    /// Closed boundary in (n, k).
    pub boundary: Vec<(f64, f64)>,
    /// The confidence, e.g. 0.95.
    pub confidence: f64,
    /// `None`: the region with the estimate's covariance alone (every prototype without a
    /// covariance is tested with it; drawn solid in the estimate's colour). `Some(classes)`:
    /// the region with these prototypes' covariance added (drawn dashed in the first
    /// class's colour); a prototype is consistent exactly when it lies inside its region.
    pub with_prototype: Option<Vec<String>>,
}

/// The answer of a classification row in a few words: `aluminum`,
/// `ambiguous: gold, copper`, `unknown (none at 95%)`; under the nearest rule the
/// consistent set follows when it differs from the answer (`aluminum; 95% set: aluminum,
/// copper`).
pub fn answer_text(c: &polarid_io::table::classification::ClassificationRow) -> String {
    let pct = c.confidence.map(|p| format!("{}%", p * 100.0));
    let set = if c.candidates.is_empty() {
        "none".to_string()
    } else {
        c.candidates.join(", ")
    };
    match (c.rule.as_str(), c.status.as_str()) {
        (_, "ambiguous") => format!("ambiguous: {set}"),
        ("set", "rejected") => match &pct {
            Some(p) => format!("{} (none at {p})", c.predicted),
            None => c.predicted.clone(),
        },
        _ => match &pct {
            Some(p) if c.candidates != [c.predicted.clone()] => {
                format!("{}; {p} set: {set}", c.predicted)
            }
            _ => c.predicted.clone(),
        },
    }
}

impl NkEstimate {
    /// The estimate of a fits-table row, labelled `label`, with the prediction and answer
    /// of the classification row of the same target (if any) and, when `classifier` is
    /// given, the confidence regions that decide its consistent set under that
    /// classifier's prototypes and confidence. A non-finite correlation is drawn as 0.
    pub fn from_fit(
        label: String,
        f: &polarid_io::table::fits::FitRow,
        classification: &[polarid_io::table::classification::ClassificationRow],
        classifier: Option<&polarid_core::classify::Classifier>,
    ) -> Self {
        let row = classification.iter().find(|c| c.target == f.target);
        let regions = classifier
            .map(|clf| {
                let est = polarid_pipeline::classify::estimate_of(f);
                polarid_pipeline::classify::decision_regions(&est, clf, 256)
                    .into_iter()
                    .map(|r| NkRegion {
                        boundary: r.region.boundary,
                        confidence: r.region.confidence,
                        with_prototype: r.region.proto_cov.map(|_| {
                            r.prototypes
                                .iter()
                                // ok: indices from decision_regions are clf's prototypes.
                                .map(|&i| clf.prototypes()[i].class.clone())
                                .collect()
                        }),
                    })
                    .collect()
            })
            .unwrap_or_default();
        NkEstimate {
            label,
            n: f.n,
            k: f.k,
            n_se: f.n_se,
            k_se: f.k_se,
            corr: if f.nk_corr.is_finite() {
                f.nk_corr
            } else {
                0.0
            },
            predicted: row.map(|c| c.predicted.clone()),
            answer: row.map(answer_text),
            regions,
        }
    }
}

/// The (n, k) plane: the nearest-neighbour decision regions of the prototypes
/// (Euclidean distance in (n, k), paper § 6) shaded by class, the prototypes, and the
/// estimates with their confidence regions ([`NkEstimate::regions`]; 1-σ covariance
/// ellipses when an estimate has none) and answers.
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

/// Dash and gap lengths (pixels) of the dashed regions, one pattern per prototype class.
const DASHES: [(u32, u32); 4] = [(10, 5), (3, 4), (16, 5), (6, 3)];

/// The parts of the closed boundary `pts` (its last point joined to its first) that lie
/// in `n ≥ 0, k ≥ 0`, as open paths (each segment clipped, Liang–Barsky), and whether
/// anything was cut away. An uncut boundary comes back whole and closed.
pub(super) fn clip_to_physical(pts: &[(f64, f64)]) -> (Vec<Vec<(f64, f64)>>, bool) {
    let inside = |p: (f64, f64)| p.0 >= 0.0 && p.1 >= 0.0;
    if pts.iter().all(|&p| inside(p)) {
        let mut closed = pts.to_vec();
        if let (Some(&a), Some(&b)) = (pts.first(), pts.last())
            && a != b
        {
            closed.push(a);
        }
        return (vec![closed], false);
    }
    let mut pieces: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let n = pts.len();
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        // Keep a + t (b − a), t in [t0, t1], with both coordinates ≥ 0.
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, d) in [(a.0, b.0 - a.0), (a.1, b.1 - a.1)] {
            if d == 0.0 {
                if p < 0.0 {
                    t0 = 1.0;
                    t1 = 0.0;
                }
            } else {
                let t = -p / d;
                if d > 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
        if t0 > t1 {
            if !cur.is_empty() {
                pieces.push(std::mem::take(&mut cur));
            }
            continue;
        }
        let at = |t: f64| {
            (
                (a.0 + t * (b.0 - a.0)).max(0.0),
                (a.1 + t * (b.1 - a.1)).max(0.0),
            )
        };
        let (p0, p1) = (at(t0), at(t1));
        if t0 > 0.0 && !cur.is_empty() {
            pieces.push(std::mem::take(&mut cur));
        }
        if cur.is_empty() {
            cur.push(p0);
        }
        cur.push(p1);
        if t1 < 1.0 {
            pieces.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        pieces.push(cur);
    }
    // The walk starts anywhere on the loop: join the last piece to the first when the
    // loop runs through the start.
    if pieces.len() > 1
        && let (Some(first), Some(last)) = (pieces.first(), pieces.last())
        && first.first() == last.last()
    {
        let first = pieces.remove(0);
        if let Some(last) = pieces.last_mut() {
            last.extend(first.into_iter().skip(1));
        }
    }
    pieces.retain(|p| p.len() >= 2);
    (pieces, true)
}

/// The cell of prototype `i` in the Euclidean nearest-neighbour partition, clipped to
/// the rectangle `[x0, x1] × [y0, y1]` (a convex polygon, possibly empty).
pub(super) fn voronoi_cell(
    sites: &[(f64, f64)],
    i: usize,
    x: Range<f64>,
    y: Range<f64>,
) -> Vec<(f64, f64)> {
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

/// The styles of the confidence regions drawn, for the legend: solid (the estimate's own
/// Σ), one dashed style per prototype class (colour, dash pattern, text), and whether a
/// region was cut at n = 0 or k = 0.
#[derive(Default)]
struct RegionStyles {
    solid: bool,
    dashed: Vec<(RGBColor, (u32, u32), String)>,
    cut: bool,
}

/// The plotting area of the (n, k) chart.
type NkArea<DB> = DrawingArea<DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The (n, k) ranges that hold the prototypes, the estimates' ±1 SE and their regions
/// (padded, from 0 at the least); `None` when there is nothing to draw.
fn bounds(protos: &[&Prototype], ests: &[&NkEstimate]) -> Option<(Range<f64>, Range<f64>)> {
    let fin = |v: f64| if v.is_finite() && v > 0.0 { v } else { 0.0 };
    let region_points = || {
        ests.iter()
            .flat_map(|e| e.regions.iter().flat_map(|r| r.boundary.iter().copied()))
            .filter(|p| p.0.is_finite() && p.1.is_finite())
    };
    let ns = protos
        .iter()
        .map(|p| p.n)
        .chain(
            ests.iter()
                .flat_map(|e| [e.n - fin(e.n_se), e.n + fin(e.n_se)]),
        )
        .chain(region_points().map(|p| p.0));
    let ks = protos
        .iter()
        .map(|p| p.k)
        .chain(
            ests.iter()
                .flat_map(|e| [e.k - fin(e.k_se), e.k + fin(e.k_se)]),
        )
        .chain(region_points().map(|p| p.1));
    let ((n0, n1), (k0, k1)) = (min_max(ns)?, min_max(ks)?);
    let (n0, n1) = padded(n0, n1, 0.12, 0.5);
    let (k0, k1) = padded(k0, k1, 0.12, 0.5);
    Some((n0.max(0.0)..n1, k0.max(0.0)..k1))
}

/// Estimate `e`'s confidence regions (its 1-σ ellipse when it has none) in colour `c`,
/// lines `width` wide; `class_idx` gives a prototype class's colour index.
fn draw_regions<DB: DrawingBackend>(
    area: &NkArea<DB>,
    e: &NkEstimate,
    c: RGBColor,
    width: u32,
    class_idx: &dyn Fn(&str) -> Option<usize>,
    styles: &mut RegionStyles,
) -> Result<()> {
    if e.regions.is_empty() {
        let ell = covariance_ellipse(e.n, e.k, e.n_se, e.k_se, e.corr, 96);
        if ell.len() > 3 {
            area.draw(&PathElement::new(ell, c.stroke_width(2))).dr()?;
        }
    }
    for r in &e.regions {
        let pts: Vec<(f64, f64)> = r
            .boundary
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        if pts.len() < 4 {
            continue;
        }
        // n < 0 and k < 0 are not physical: the boundary is drawn only where
        // n ≥ 0 and k ≥ 0, open where it was cut (a note in the legend says so).
        let (pieces, was_cut) = clip_to_physical(&pts);
        styles.cut |= was_cut;
        match &r.with_prototype {
            None => {
                for piece in pieces {
                    area.draw(&PathElement::new(piece, c.stroke_width(2)))
                        .dr()?;
                }
                styles.solid = true;
            }
            Some(classes) => {
                let ci = classes.first().and_then(|name| class_idx(name));
                let pc = ci.map(|i| shade(class_colour(i), 0.75)).unwrap_or(c);
                // One dash pattern per prototype class, so that overlapping
                // regions of different classes stay apart.
                let (dash, gap) = DASHES[ci.unwrap_or(0) % DASHES.len()];
                for piece in &pieces {
                    area.draw(&plotters::element::DashedPathElement::new(
                        piece.iter().copied(),
                        dash,
                        gap,
                        pc.stroke_width(width),
                    ))
                    .dr()?;
                }
                let text = format!("with {}'s Σ", classes.join(", "));
                if !styles.dashed.iter().any(|(_, _, t)| *t == text) {
                    styles.dashed.push((pc, (dash, gap), text));
                }
            }
        }
    }
    Ok(())
}

/// The legend: the prototype classes, the estimates (in `colours`) with their answers,
/// and the region styles drawn.
fn nk_legend(
    classes: &[&str],
    ests: &[&NkEstimate],
    colours: &[RGBColor],
    styles: RegionStyles,
) -> Vec<LegendItem> {
    let mut legend = vec![LegendItem::Heading("Prototypes / regions".into())];
    legend.extend(class_markers(classes));
    if !ests.is_empty() {
        let heading = match ests.iter().find_map(|e| e.regions.first()) {
            Some(r) => format!("Estimates: answer ({}% region)", r.confidence * 100.0),
            None => "Estimates (1-σ ellipse)".to_string(),
        };
        legend.push(LegendItem::Heading(heading));
    }
    for (j, (e, &c)) in ests.iter().zip(colours).enumerate() {
        let m = ESTIMATE_MARKERS[j % ESTIMATE_MARKERS.len()];
        let text = match &e.answer {
            Some(a) => format!("{}: {a}", e.label),
            None => e.label.clone(),
        };
        legend.push(LegendItem::Marker(m, c, text));
    }
    if styles.solid || !styles.dashed.is_empty() {
        legend.push(LegendItem::Heading("Regions".into()));
    }
    if styles.solid {
        legend.push(LegendItem::Line(BLACK, "with the estimate's Σ only".into()));
    }
    for (c, pattern, text) in styles.dashed {
        legend.push(LegendItem::Dashed(c, pattern, text));
    }
    if styles.cut {
        legend.push(LegendItem::Note(
            "Regions are cut at n = 0 and k = 0: their parts at n < 0 or k < 0 are \
             not physical and not drawn (open ends)."
                .into(),
        ));
    }
    legend
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
        let Some((nr, kr)) = bounds(&protos, &ests) else {
            draw_notice(&main, "No (n, k) values to plot")?;
            return Ok(None);
        };
        let mut ch = chart(&main, nr.clone(), kr.clone(), (12, 20, 8, 8))?;

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
        let cells: Vec<(RGBColor, Vec<(f64, f64)>)> = (protos.iter().enumerate())
            .map(|(i, p)| {
                let c = class_colour(class_idx(&p.class).unwrap_or(0));
                (c, voronoi_cell(&sites, i, nr.clone(), kr.clone()))
            })
            .filter(|(_, cell)| cell.len() >= 3)
            .collect();
        for (c, cell) in &cells {
            ch.draw_series(std::iter::once(Polygon::new(
                cell.clone(),
                tint(*c, 0.18).filled(),
            )))
            .dr()?;
        }
        configure_axes(
            &mut ch,
            "n (real part of N)",
            "k (imaginary part of N)",
            true,
        )?;
        let area = ch.plotting_area();
        // Region boundaries (cell edges between different classes are drawn darker).
        for (c, cell) in &cells {
            let mut closed = cell.clone();
            closed.push(cell[0]);
            area.draw(&PathElement::new(closed, tint(*c, 0.45).stroke_width(1)))
                .dr()?;
        }
        // Confidence regions (or 1-σ ellipses) under the markers, then the prototypes,
        // then the estimates' markers on top.
        let colours: Vec<RGBColor> = ests
            .iter()
            .map(|e| {
                e.predicted
                    .as_deref()
                    .and_then(class_idx)
                    .map(|i| shade(class_colour(i), 0.55))
                    .unwrap_or(BLACK)
            })
            .collect();
        let mut styles = RegionStyles::default();
        // Thinner lines when many regions overlap.
        let n_regions: usize = ests.iter().map(|e| e.regions.len()).sum();
        let width = if n_regions > 6 { 1 } else { 2 };
        for (e, &c) in ests.iter().zip(&colours) {
            draw_regions(area, e, c, width, &class_idx, &mut styles)?;
        }
        for p in &protos {
            let c = class_colour(class_idx(&p.class).unwrap_or(0));
            draw_marker(area, (p.n, p.k), Marker::Circle, 8, c.filled())?;
            draw_marker(area, (p.n, p.k), Marker::Circle, 8, BLACK.stroke_width(2))?;
        }
        for (j, (e, &c)) in ests.iter().zip(&colours).enumerate() {
            let m = ESTIMATE_MARKERS[j % ESTIMATE_MARKERS.len()];
            draw_marker(area, (e.n, e.k), m, 6, c.filled())?;
        }
        draw_legend(&side, &nk_legend(&classes, &ests, &colours, styles))?;
        Ok(None)
    }
}
