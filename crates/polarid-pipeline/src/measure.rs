//! Frames → Stokes images → region DoLP rows: the workflow of `polarid measure`.
//!
//! The kernels live in `polarid_io::measure` (re-exported here, so that one path serves
//! every front end); [`measure`] is the workflow around them: every capture of a loaded
//! manifest, progress per capture, and the warnings a user should see (the manifest's
//! own, and regions with more than 1 % saturated pixels).

pub use polarid_io::measure::*;

use polarid_io::manifest::Manifest;
use polarid_io::table::measurements::Measurement;

use crate::Result;
use crate::progress::{Progress, Warning};

/// The rows of `polarid measure` and what to tell the user about them.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasureOutput {
    /// One row per target per capture (targets of capture 1 in region order, then
    /// capture 2, ...).
    pub rows: Vec<Measurement>,
    /// Saturated regions (one warning each). The manifest's own warnings (unknown keys)
    /// are in `Manifest::warnings`, reported when it is loaded.
    pub warnings: Vec<Warning>,
}

/// Measure every region of every capture of `m`. Progress stage: `captures`.
pub fn measure(m: &Manifest, progress: Progress) -> Result<MeasureOutput> {
    let total = m.captures.len() as u64;
    progress("captures", 0, total);
    let rows = measure_manifest(m, &mut |done| progress("captures", done as u64, total))?;
    let warnings = saturation_warnings(m, &rows)
        .into_iter()
        .map(Warning)
        .collect();
    Ok(MeasureOutput { rows, warnings })
}
