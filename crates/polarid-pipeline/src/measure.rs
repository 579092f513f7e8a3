//! Frames → Stokes images → region DoLP rows: the workflow of `polarid measure`.
//!
//! The kernels live in `polarid_io::measure` (re-exported here, so that one path serves
//! every front end); [`measure`] is the workflow around them: every capture of a loaded
//! manifest, progress per capture, and the warnings a user should see (the manifest's
//! own, a saturation level the data contradict, a colour mosaic's partial period
//! dropped, regions with more than 1 % saturated pixels, and the rows that are not
//! `ok`). Every capture must have the first one's size.
//!
//! Partial failure (docs/FORMATS.md): a region that is dark in a capture, or has no
//! usable pixel there, gives a row with a status and a reason and the other rows are
//! measured; only a manifest none of whose rows is usable is an error.
//! [`MeasureConfig::strict`] restores the error at the first such row.

pub use polarid_io::measure::*;

use polarid_io::manifest::Manifest;
use polarid_io::table::measurements::Measurement;

use crate::progress::{Progress, Warning};
use crate::{PipelineError, Result};

/// How many rows that are not `ok` the summary warning lists.
const SHOWN: usize = 8;

/// How [`measure_with`] treats problems; the default is that of `polarid measure`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MeasureConfig {
    /// Stop at the first region that is dark or has no usable pixel in a capture (an
    /// error naming the region's `rect` and the capture) instead of writing its row
    /// with a status and a reason.
    pub strict: bool,
}

/// The rows of `polarid measure` and what to tell the user about them.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasureOutput {
    /// One row per target per capture (targets of capture 1 in region order, then
    /// capture 2, ...).
    pub rows: Vec<Measurement>,
    /// Saturated regions (one warning each) and a summary of the rows that are not
    /// `ok`. The manifest's own warnings (unknown keys) are in `Manifest::warnings`,
    /// reported when it is loaded.
    pub warnings: Vec<Warning>,
}

/// Measure every region of every capture of `m` with the default [`MeasureConfig`].
/// Progress stage: `captures`.
pub fn measure(m: &Manifest, progress: Progress) -> Result<MeasureOutput> {
    measure_with(m, &MeasureConfig::default(), progress)
}

/// Measure every region of every capture of `m`. Progress stage: `captures`.
///
/// Errors: those of [`measure_manifest_with`]; [`PipelineError::Data`] naming the
/// manifest when no row is `ok` (every region dark or without a usable pixel in every
/// capture).
pub fn measure_with(
    m: &Manifest,
    cfg: &MeasureConfig,
    progress: Progress,
) -> Result<MeasureOutput> {
    let total = m.captures.len() as u64;
    progress("captures", 0, total);
    let (rows, notes) = measure_manifest_report(m, cfg.strict, &mut |done| {
        progress("captures", done as u64, total)
    })?;
    let mut warnings: Vec<Warning> = notes
        .into_iter()
        .chain(saturation_warnings(m, &rows))
        .map(Warning)
        .collect();
    let bad: Vec<&Measurement> = rows.iter().filter(|r| !r.status.is_ok()).collect();
    if !bad.is_empty() && bad.len() == rows.len() {
        return Err(PipelineError::Data {
            path: m.path.display().to_string(),
            reason: format!(
                "no usable measurement: every region is dark or has no usable pixel in \
                 every capture (first: target {:?}, {}: {})",
                bad[0].target, bad[0].status, bad[0].reason
            ),
        });
    }
    if !bad.is_empty() {
        warnings.push(Warning(format!(
            "{} of {} rows are not usable and will not be fitted (status and reason \
             columns): {}",
            bad.len(),
            rows.len(),
            bad.iter()
                .take(SHOWN)
                .map(|r| format!("target {:?} {} ({})", r.target, r.status, r.reason))
                .collect::<Vec<_>>()
                .join("; ")
                + &if bad.len() > SHOWN {
                    format!("; and {} more", bad.len() - SHOWN)
                } else {
                    String::new()
                }
        )));
    }
    Ok(MeasureOutput { rows, warnings })
}
