//! Plots for reports and commands, each rendered to PNG and SVG from plain data.
//!
//! - [`dolp_vs_beta`]: measured DoLP against β with standard-error bars and the fitted
//!   paper eq. (9) curve, one colour per target;
//! - [`nk_plane`]: the (n, k) plane with class prototypes, test estimates with 1-σ
//!   covariance ellipses and the nearest-neighbour decision regions (paper § 6);
//! - `class_map`, [`answer_map`]: a material map (class index image, 0 = `unknown`)
//!   with a legend of the answers (docs/FORMATS.md, "Answers"), the `unknown` pixels by
//!   reason and the regions outlined;
//! - [`scalar_map`]: a scalar image (n, k, DoLP, ...) in the viridis colour map with a
//!   colour bar;
//! - [`bands::nk_spectra`]: `n(λ)`, `k(λ)` of multi-band targets against a library's
//!   curves, and [`bands::by_band`], the per-band split of the DoLP and `(n, k)` figures
//!   (drawn per band in the colour demo's report, `render::colour_demo`);
//! - [`panels::dolp_by_band`], [`panels::nk_by_band`]: one panel per band in one figure
//!   (the reports of a user's tables, `render::table_report`, and `map`'s colour figures,
//!   `render::map_figures`).
//!
//! Every function returns a [`Rendered`](crate::render::Rendered) (PNG bytes and SVG text of the same drawing);
//! [`Rendered::write`](crate::render::Rendered::write) writes `STEM.png` and `STEM.svg`. Text is drawn with the bundled
//! DejaVu Sans font (`assets/fonts/`, registered with plotters' `ab_glyph` table), so
//! plots render on machines without system fonts. Empty data draws a "no data" notice
//! rather than failing; inconsistent data (an image buffer of the wrong length) is an
//! error. Angles are in degrees, as everywhere outside the numerical code.
//!
//! Modules: [`style`] (font, sizes, colours, legend), [`canvas`] (PNG + SVG rendering,
//! chart frame), one module per figure ([`dolp`], [`nk`], [`maps`]). The output type,
//! [`Rendered`](crate::render::Rendered), is shared with the report and lives in [`crate::render`].

use anyhow::{Result, bail};

pub use dolp::{DolpPoint, DolpSeries, dolp_vs_beta, eq9_curve};
#[cfg(test)]
pub use maps::class_map;
pub use maps::scalar_map;
pub use maps::{ClassMap, MapRegion, answer_map};
pub use nk::{NkEstimate, Prototype, nk_plane};
pub use plan::{PlanAxes, PlanPlate, plan_dolp};

// Multi-band figures (docs/BANDS.md): `demo --color`, `fit`/`classify --report`, `map`.
pub mod bands;
mod canvas;
mod dolp;
mod maps;
mod nk;
pub mod panels;
mod plan;
mod style;
#[cfg(test)]
mod tests;

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
