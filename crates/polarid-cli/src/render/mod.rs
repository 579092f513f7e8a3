//! Everything polarid draws: plots (PNG + SVG), the HTML/Markdown report, and the PNG
//! views of Stokes images.
//!
//! The modules form a DAG, leaves first:
//!
//! - [`base64`] and [`colormap`] (viridis, the AoLP hue wheel) depend on nothing;
//! - this module's [`Rendered`] is one drawing as PNG bytes and SVG text;
//! - [`plots`] draws [`Rendered`] figures (colours from [`colormap`], SVG rasters
//!   embedded with [`base64`]);
//! - [`report`] lays [`Rendered`] figures out in HTML (embedded with [`base64`]) and
//!   Markdown, and never calls [`plots`];
//! - [`views`] makes the `stokes` command's DoLP/AoLP PNG views with [`colormap`];
//! - [`table_report`] (the `--report` of `fit` and `classify`) and [`map_figures`]
//!   (`map`'s figures) draw a user's tables with [`plots`] and lay them out with
//!   [`report`], as [`demo`] and [`colour_demo`] do for the demos.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

pub mod base64;
pub mod bench;
pub mod colormap;
pub mod colour_demo;
pub mod demo;
pub mod map_figures;
pub mod plots;
pub mod png;
pub mod report;
pub mod table_report;
pub mod views;

/// One drawing, rendered both as a PNG image and as an SVG document.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The PNG file's bytes (8-bit RGB).
    pub png: Vec<u8>,
    /// The SVG document.
    pub svg: String,
}

/// The files written by [`Rendered::write`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlotFiles {
    /// `DIR/STEM.png`.
    pub png: PathBuf,
    /// `DIR/STEM.svg`.
    pub svg: PathBuf,
}

/// `items` as text, separated by `sep`.
pub fn join<T: std::fmt::Display>(items: impl IntoIterator<Item = T>, sep: &str) -> String {
    items
        .into_iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(sep)
}

impl Rendered {
    /// Write `dir/stem.png` and `dir/stem.svg` (overwriting them: callers that must not
    /// overwrite write into a `polarid_io::atomic::StagedDir`).
    pub fn write(&self, dir: &Path, stem: &str) -> Result<PlotFiles> {
        if stem.is_empty() || stem.contains(['/', '\\']) {
            bail!("plot file stem {stem:?} must be a non-empty file name");
        }
        let png = dir.join(format!("{stem}.png"));
        let svg = dir.join(format!("{stem}.svg"));
        std::fs::write(&png, &self.png)
            .with_context(|| format!("cannot write {}", png.display()))?;
        std::fs::write(&svg, self.svg.as_bytes())
            .with_context(|| format!("cannot write {}", svg.display()))?;
        Ok(PlotFiles { png, svg })
    }
}
