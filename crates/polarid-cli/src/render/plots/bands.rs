//! Plots of multi-band data (colour polarization cameras, docs/BANDS.md):
//!
//! - [`nk_spectra`]: `n(λ)` and `k(λ)` of each target (markers with ±1 SE bars, one
//!   colour per target) against the library's curves (lines, one colour per material),
//!   two panels sharing the wavelength axis;
//! - [`by_band`]: the per-band split that the per-band DoLP-against-β and `(n, k)`-plane
//!   figures are drawn from (one [`dolp_vs_beta`](super::dolp_vs_beta) or
//!   [`nk_plane`](super::nk_plane) per band).

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::PlotSize;
use super::canvas::*;
use super::style::DrawResult as _;
use super::style::*;
use crate::render::Rendered;

/// One band of a target's (or a material's) spectrum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectrumPoint {
    /// Centre wavelength of the band, nm.
    pub wavelength_nm: f64,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index.
    pub k: f64,
    /// Standard error of `n` (a ±1 SE bar when finite and > 0).
    pub n_se: Option<f64>,
    /// Standard error of `k`.
    pub k_se: Option<f64>,
}

impl SpectrumPoint {
    /// A point without error bars (a curve sample, a material's band).
    pub fn bare(wavelength_nm: f64, n: f64, k: f64) -> Self {
        Self {
            wavelength_nm,
            n,
            k,
            n_se: None,
            k_se: None,
        }
    }

    /// A fit's band: its `(n, k)` with their standard errors at its wavelength (NaN
    /// without one).
    pub fn of_fit(f: &polarid_io::table::fits::FitRow) -> Self {
        Self {
            n_se: Some(f.n_se),
            k_se: Some(f.k_se),
            ..Self::bare(f.wavelength_nm.unwrap_or(f64::NAN), f.n, f.k)
        }
    }
}

/// A labelled spectrum: a target's per-band estimates or a library material's bands.
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrum {
    /// Legend text (target or material name).
    pub label: String,
    /// The bands (drawn in wavelength order).
    pub points: Vec<SpectrumPoint>,
    /// A library material's continuous `(λ nm, n, k)` curve (e.g. its refractiveindex.info
    /// data), drawn as the line instead of the segments between `points` (within the
    /// figure's wavelength range); empty: the line joins the points.
    pub curve: Vec<(f64, f64, f64)>,
}

/// Items of `items` split by band: `(wavelength_nm, items of that band)` in increasing
/// wavelength, items without a band (`None`) under NaN last. For the per-band
/// DoLP-against-β and `(n, k)`-plane figures.
pub fn by_band<T: Clone>(items: &[(Option<f64>, T)]) -> Vec<(f64, Vec<T>)> {
    let mut out: Vec<(f64, Vec<T>)> = Vec::new();
    for (wl, item) in items {
        let key = wl.unwrap_or(f64::NAN);
        match out
            .iter_mut()
            .find(|(w, _)| *w == key || (w.is_nan() && key.is_nan()))
        {
            Some((_, v)) => v.push(item.clone()),
            None => out.push((key, vec![item.clone()])),
        }
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// `n(λ)` (top) and `k(λ)` (bottom) of the `targets` (markers, ±1 SE bars) against the
/// `library` materials' curves (lines through their bands).
pub fn nk_spectra(
    title: &str,
    targets: &[Spectrum],
    library: &[Spectrum],
    size: PlotSize,
) -> Result<Rendered> {
    render(
        &SpectraFigure {
            title,
            targets,
            library,
        },
        size,
    )
}

struct SpectraFigure<'a> {
    title: &'a str,
    targets: &'a [Spectrum],
    library: &'a [Spectrum],
}

fn ok(p: &SpectrumPoint) -> bool {
    p.wavelength_nm.is_finite() && p.n.is_finite() && p.k.is_finite()
}

fn bar(se: Option<f64>) -> f64 {
    se.filter(|s| s.is_finite() && *s > 0.0).unwrap_or(0.0)
}

impl SpectraFigure<'_> {
    fn all(&self) -> impl Iterator<Item = &SpectrumPoint> {
        self.targets
            .iter()
            .chain(self.library)
            .flat_map(|s| s.points.iter())
            .filter(|p| ok(p))
    }

    /// One panel: `value` of each point (`n` or `k`) against the wavelength.
    fn panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: (f64, f64),
        y_desc: &str,
        value: fn(&SpectrumPoint) -> (f64, f64),
    ) -> Result<()> {
        let in_x = |w: f64| w >= x.0 && w <= x.1;
        let curve_ys = self.library.iter().flat_map(|s| {
            s.curve
                .iter()
                .filter(move |c| in_x(c.0))
                .map(move |&(w, n, k)| value(&SpectrumPoint::bare(w, n, k)).0)
        });
        let ys = self
            .all()
            .flat_map(|p| {
                let (v, e) = value(p);
                [v - e, v + e]
            })
            .chain(curve_ys);
        let (y0, y1) = min_max(ys).unwrap_or((0.0, 1.0));
        let (y0, y1) = padded(y0, y1, 0.06, 0.1);
        let mut ch = chart(
            area,
            x.0..x.1,
            y0.max(0.0).min(y1 - 0.05)..y1,
            (8, 20, 4, 8),
        )?;
        configure_axes(&mut ch, "wavelength (nm)", y_desc, true)?;
        for (i, s) in self.library.iter().enumerate() {
            let c = tint(class_colour(i), 0.7);
            let mut pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .filter(|p| ok(p))
                .map(|p| (p.wavelength_nm, value(p).0))
                .collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut line: Vec<(f64, f64)> = s
                .curve
                .iter()
                .filter(|c| in_x(c.0))
                .map(|&(w, n, k)| (w, value(&SpectrumPoint::bare(w, n, k)).0))
                .filter(|p| p.1.is_finite())
                .collect();
            line.sort_by(|a, b| a.0.total_cmp(&b.0));
            if line.len() < 2 {
                line = pts.clone();
            }
            ch.draw_series(LineSeries::new(line, c.stroke_width(2)))
                .dr()?;
            for p in pts {
                draw_marker(ch.plotting_area(), p, Marker::Circle, 3, c.filled())?;
            }
        }
        let area = ch.plotting_area();
        for (i, s) in self.targets.iter().enumerate() {
            let c = class_colour(self.library.len() + i);
            let marker = ESTIMATE_MARKERS[i % ESTIMATE_MARKERS.len()];
            for p in s.points.iter().filter(|p| ok(p)) {
                let (v, e) = value(p);
                if e > 0.0 {
                    area.draw(&PathElement::new(
                        vec![(p.wavelength_nm, v - e), (p.wavelength_nm, v + e)],
                        shade(c, 0.8).stroke_width(2),
                    ))
                    .dr()?;
                }
                draw_marker(area, (p.wavelength_nm, v), marker, 6, c.filled())?;
            }
        }
        Ok(())
    }
}

impl Figure for SpectraFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<Option<Raster>> {
        let (main, side) = layout(root, self.title)?;
        let Some((x0, x1)) = min_max(self.all().map(|p| p.wavelength_nm)) else {
            draw_notice(&main, "No bands to plot")?;
            return Ok(None);
        };
        let x = padded(x0, x1, 0.08, 40.0);
        let (_, h) = main.dim_in_pixel();
        let (top, bottom) = main.split_vertically(h / 2);
        self.panel(&top, x, "n", |p| (p.n, bar(p.n_se)))?;
        self.panel(&bottom, x, "k", |p| (p.k, bar(p.k_se)))?;
        let mut legend = Vec::new();
        if !self.targets.is_empty() {
            legend.push(LegendItem::Heading("targets (±1 SE)".into()));
        }
        for (i, s) in self.targets.iter().enumerate() {
            legend.push(LegendItem::Marker(
                ESTIMATE_MARKERS[i % ESTIMATE_MARKERS.len()],
                class_colour(self.library.len() + i),
                s.label.clone(),
            ));
        }
        if !self.library.is_empty() {
            legend.push(LegendItem::Heading("library".into()));
        }
        for (i, s) in self.library.iter().enumerate() {
            legend.push(LegendItem::Line(
                tint(class_colour(i), 0.7),
                s.label.clone(),
            ));
        }
        draw_legend(&side, &legend)?;
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(label: &str, v: &[(f64, f64, f64)], se: Option<f64>) -> Spectrum {
        Spectrum {
            label: label.into(),
            points: v
                .iter()
                .map(|&(wavelength_nm, n, k)| SpectrumPoint {
                    wavelength_nm,
                    n,
                    k,
                    n_se: se,
                    k_se: se,
                })
                .collect(),
            curve: Vec::new(),
        }
    }

    #[test]
    fn spectra_draw_targets_and_library() {
        let lib = vec![
            spec(
                "copper",
                &[
                    (450.0, 1.25, 2.38),
                    (550.0, 0.97, 2.63),
                    (650.0, 0.25, 3.61),
                ],
                None,
            ),
            spec(
                "gold",
                &[
                    (450.0, 1.36, 1.90),
                    (550.0, 0.46, 2.46),
                    (650.0, 0.16, 3.60),
                ],
                None,
            ),
        ];
        let t = vec![spec(
            "plate 1",
            &[(450.0, 1.3, 2.3), (550.0, 0.9, 2.6), (650.0, 0.2, 3.6)],
            Some(0.05),
        )];
        let r = nk_spectra("n(λ), k(λ)", &t, &lib, PlotSize::REPORT).unwrap();
        assert!(r.png.starts_with(&[0x89, b'P', b'N', b'G']));
        for text in ["copper", "gold", "plate 1", "wavelength (nm)", "library"] {
            assert!(r.svg.contains(text), "{text}");
        }
        // The target's colour is drawn (its markers).
        let c = class_colour(lib.len());
        let (_, _, rgb) = crate::render::png::decode_rgb8(&r.png);
        let hits = rgb
            .chunks_exact(3)
            .filter(|p| p[0] == c.0 && p[1] == c.1 && p[2] == c.2)
            .count();
        assert!(hits > 50, "{hits}");
        // No data: a notice, not an error.
        let r = nk_spectra("empty", &[], &[], PlotSize::REPORT).unwrap();
        assert!(r.svg.contains("No bands"));
    }

    #[test]
    fn by_band_splits_in_wavelength_order() {
        let items = vec![
            (Some(650.0), "a650"),
            (Some(450.0), "a450"),
            (None, "x"),
            (Some(650.0), "b650"),
        ];
        let b = by_band(&items);
        assert_eq!(b.len(), 3);
        assert_eq!((b[0].0, b[0].1.clone()), (450.0, vec!["a450"]));
        assert_eq!((b[1].0, b[1].1.clone()), (650.0, vec!["a650", "b650"]));
        assert!(b[2].0.is_nan());
    }
}
