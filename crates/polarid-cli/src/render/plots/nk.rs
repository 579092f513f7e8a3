//! (b) The (n, k) plane: prototypes, decision regions, estimates with 1-σ ellipses.

use std::ops::Range;

use anyhow::Result;
use plotters::coord::Shift;
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
}

impl NkEstimate {
    /// The estimate of a fits-table row, labelled `label`, with the prediction of the
    /// classification row of the same target (if any). A non-finite correlation is
    /// drawn as 0.
    pub fn from_fit(
        label: String,
        f: &polarid_io::table::fits::FitRow,
        classification: &[polarid_io::table::classification::ClassificationRow],
    ) -> Self {
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
            predicted: classification
                .iter()
                .find(|c| c.target == f.target)
                .map(|c| c.predicted.clone()),
        }
    }
}

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
