//! `polarid measure MANIFEST [-o measurements.csv]`: each region's DoLP per capture.
//!
//! Captures are processed one after the other (each one in parallel inside), so memory
//! holds one capture at a time. For every region and capture the row holds the DoLP of
//! the region's mean Stokes vector, its standard error from the pixel scatter
//! (`polarid_core::region`), the mean S0 divided by the capture's exposure, the pixels
//! used and rejected, and `beta` from the geometry (eq. 5).
//!
//! A standard error that comes out as 0 (noiseless data) is written as an empty cell.
//!
//! Saturation is reported, not hidden: `rejected` counts every pixel of the region left
//! out (saturated, dark or invalid — for DoFP, a pixel is rejected when any raw pixel its
//! bilinear interpolation uses is), and `saturated` the part of `rejected` that is
//! saturated (a raw value at or above the capture's `saturation`, default the type's
//! maximum). `pixels + rejected` is the region's area. When more than
//! [`polarid_io::measure::SATURATED_WARN`] of a region is saturated, a warning on
//! standard error names the target, the capture and the fraction.
//!
//! DoFP captures are demosaiced bilinearly at full resolution (so that `rect` is in raw
//! pixel coordinates) without rounding, and their standard errors use the bilinear
//! variance inflation. Stokes captures (float TIFF) are used as they are: `dark_level`
//! and `saturation` do not apply; pixels with `S0 <= 0` or non-finite values are
//! rejected.
//!
//! Captures with calibrated geometry (`[camera]` and a `source`) are measured with
//! per-pixel geometry: the region's mean Stokes vector in each pixel's
//! plane-of-incidence frame, its S0-weighted `theta_i_deg`, `theta_r_deg`, `phi_deg`,
//! `beta_deg` and `beta_sd_deg`, and `aolp_deg`, `aolp_poi_deg` (docs/GEOMETRY.md);
//! those three columns are written only when some row has them.
//!
//! A region that is dark in a capture (mean S0 below the dark threshold) or has no
//! usable pixel there gets a row with `status` and `reason` (docs/FORMATS.md, "Partial
//! failure"), listed in a warning; `--strict` stops at the first one with exit status
//! 2 instead. A manifest with no usable row at all is an error.
//!
//! A manifest with colour captures (docs/BANDS.md) gives one row per region, capture
//! and band, each with `wavelength_nm` (the band's wavelength from `bands`).
//!
//! The pipeline itself is [`polarid_io::measure`], shared with the Python bindings.

use std::path::{Path, PathBuf};

use polarid_io::manifest;
use polarid_io::table::measurements;
use polarid_pipeline::measure;

use super::common::{Bars, PipeResult, warn_all};
use crate::Ctx;

/// Arguments of `polarid measure`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The capture-set manifest (TOML, docs/FORMATS.md).
    pub manifest: PathBuf,
    /// Output CSV (default, or `-`: standard output).
    #[arg(short = 'o', long, value_name = "CSV")]
    pub output: Option<PathBuf>,
    /// Stop with exit status 2 at the first region that is dark or has no usable pixel
    /// in a capture, instead of writing its row with a status and a reason.
    #[arg(long)]
    pub strict: bool,
}

/// Run `polarid measure`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let m = manifest::load(&args.manifest)?;
    warn_all(ctx, &m.warnings);
    let mut inputs: Vec<&Path> = vec![args.manifest.as_path()];
    for c in &m.captures {
        inputs.extend(c.files());
    }
    // `-o -`: standard output.
    let output = args
        .output
        .clone()
        .filter(|p| !polarid_io::limits::is_stdin(p));
    if let Some(out) = &output {
        polarid_io::atomic::check_output(out, ctx.force, &inputs)?;
    }
    let cfg = measure::MeasureConfig {
        strict: args.strict,
    };
    // Every region of every capture (one row per target per capture, in manifest
    // order), a progress bar over the captures, a warning per saturated region.
    let out = {
        let bars = Bars::new(ctx);
        measure::measure_with(&m, &cfg, &|s, d, t| bars.report(s, d, t)).cli()?
    };
    warn_all(ctx, &out.warnings);
    let rows = out.rows;
    ctx.write_output(output.as_deref(), &inputs, |w, p| {
        measurements::write(w, p, &rows)
    })?;
    if let Some(out) = &output {
        let bands = if measure::has_colour(&m) {
            " per band"
        } else {
            ""
        };
        ctx.info(format!(
            "polarid measure: {} rows ({} targets x {} captures{bands}) written to {}",
            rows.len(),
            m.regions.len(),
            m.captures.len(),
            out.display()
        ));
    }
    Ok(())
}
