//! `polarid simulate SCENE.toml -o DIR`: synthetic captures of plates of known optics.
//!
//! The workflow is [`polarid_pipeline::simulate`]: `DIR` receives the frames, a capture
//! manifest (`docs/FORMATS.md`) that `polarid measure` reads, `truth.csv` (the
//! noise-free DoLP and S0 of every plate per capture) and a copy of the scene. Everything
//! is written into a staging directory first (the pipeline writes the frames into it as
//! they are rendered), so a failure leaves nothing behind.

use std::path::PathBuf;

use anyhow::Context;
use polarid_io::scene::{self, CaptureKind, ImageFormat};
use polarid_pipeline::simulate as pipeline;

use super::common::{Bars, PipeResult, output_dir, warn_all};
use crate::Ctx;
use crate::render::join;

/// Arguments of `polarid simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene (TOML, docs/SCENE.md).
    pub scene: PathBuf,
    /// Output directory (frames, manifest.toml, truth.csv, scene.toml).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
}

/// Run `polarid simulate`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let scene = scene::load(&args.scene)?;
    let staged = output_dir(&args.output, ctx)?;
    // A progress bar over the frames.
    let sim = {
        let bars = Bars::new(ctx);
        pipeline::simulate_into(&scene, &staged, "", &|s, d, t| bars.report(s, d, t)).cli()
    }
    .with_context(|| format!("simulating {}", args.scene.display()))?;
    staged.commit()?;
    warn_all(ctx, &sim.warnings);
    let kind = match &scene.capture {
        CaptureKind::Frames { angles_deg } => format!("{} polarizer angles", angles_deg.len()),
        CaptureKind::Dofp { .. } => "DoFP mosaics".to_string(),
        CaptureKind::ColourDofp { pattern, bands } => format!(
            "colour DoFP mosaics ({}, bands {})",
            pattern.color(),
            join(
                bands
                    .iter()
                    .map(|b| format!("{} {} nm", b.letter, b.wavelength_nm)),
                ", "
            )
        ),
    };
    ctx.info(format!(
        "polarid simulate: {} plate(s), {} capture(s) ({kind}), {} {} file(s) -> {}",
        scene.plates.len(),
        sim.captures,
        sim.frames,
        match scene.format {
            ImageFormat::Png => "PNG",
            ImageFormat::Tiff => "TIFF",
        },
        args.output.join(&sim.manifest).display()
    ));
    Ok(())
}
