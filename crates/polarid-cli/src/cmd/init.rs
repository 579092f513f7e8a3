//! `polarid init FRAMES_DIR [-o manifest.toml] [--opencv calib.yml]`: a commented
//! manifest skeleton from a folder of frames (the work is `polarid_pipeline::init`;
//! docs/CAPTURE.md walks through filling it in).

use std::path::PathBuf;

use polarid_pipeline::init::{InitConfig, init};

use super::common::PipeResult;
use crate::Ctx;

/// Arguments of `polarid init`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The folder of frames: one sub-folder per capture, or frames named by capture and
    /// polarizer angle, or one polarization-camera raw frame per capture.
    pub frames_dir: PathBuf,
    /// The manifest to write (default: FRAMES_DIR/manifest.toml); frame paths in it are
    /// relative to its folder.
    #[arg(short = 'o', long, value_name = "TOML")]
    pub output: Option<PathBuf>,
    /// An OpenCV calibration file (cv::FileStorage YAML/JSON/XML from calibrateCamera):
    /// write a calibrated skeleton ([camera] opencv = ..., a source position per capture)
    /// instead of far-field angles.
    #[allow(rustdoc::broken_intra_doc_links)] // the help text's TOML table, not a link
    #[arg(long, value_name = "FILE")]
    pub opencv: Option<PathBuf>,
}

/// Run `polarid init`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| args.frames_dir.join("manifest.toml"));
    if let Some(cal) = &args.opencv {
        // Read it now: a calibration file that cannot be used is better known before the
        // skeleton refers to it.
        polarid_io::manifest::opencv::read_opencv_calibration(cal, &Default::default())?;
    }
    let out = init(&InitConfig {
        frames_dir: args.frames_dir.clone(),
        manifest_path: output.clone(),
        opencv: args.opencv.clone(),
    })
    .cli()?;
    super::common::warn_all(ctx, &out.warnings);
    let inputs: Vec<&std::path::Path> = out.inputs.iter().map(PathBuf::as_path).collect();
    ctx.write_output(Some(&output), &inputs, |w, p| {
        w.write_all(out.text.as_bytes())
            .map_err(|e| polarid_io::IoError::io(p, e))
    })?;
    let files: usize = out
        .captures
        .iter()
        .map(|c| polarid_pipeline::init::capture_files(&c.data).len())
        .sum();
    ctx.info(format!(
        "polarid init: {} capture(s), {files} frame(s) of {}x{} ({}) -> {}; fill in the \
         values marked FILL IN, then run polarid measure",
        out.captures.len(),
        out.size[0],
        out.size[1],
        out.depth.evidence,
        output.display()
    ));
    Ok(())
}
