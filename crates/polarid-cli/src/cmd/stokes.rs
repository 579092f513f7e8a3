//! `polarid stokes`: Stokes, DoLP and AoLP images from rotating-polarizer frames or a
//! division-of-focal-plane (DoFP) mosaic.
//!
//! The command translates its options into a [`StokesConfig`]; the pipeline
//! ([`polarid_pipeline::stokes`]) checks them and computes the images of every band. This
//! module writes `s0.tif`, `s1.tif`, `s2.tif`, `dolp.tif`, `aolp.tif` (float32; DoLP and
//! AoLP are NaN where a pixel is rejected) and the views `s0.png`, `dolp.png`, `aolp.png`
//! ([`crate::render::views`]) into the output directory, all or nothing, rendered,
//! encoded and written in parallel ([`write_files`]). A colour polarization mosaic
//! (`--color`) gives these per band (`stokes_colour.rs`).

use std::path::{Path, PathBuf};

use polarid_io::IoError;
use polarid_io::atomic::{StagedDir, check_output};
use polarid_io::image;
use polarid_io::measure;
use polarid_pipeline::stokes::{StokesConfig, StokesSource};
use rayon::prelude::*;

#[path = "stokes_colour.rs"]
mod colour;

use super::common::{PipeResult, warn_all};
use crate::render::views::{self, AolpView, DolpScale};
use crate::{BadInput, Ctx};

/// How a DoFP mosaic is turned into Stokes images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Demosaic {
    /// Full resolution, bilinear interpolation of each channel (OpenCV's / polanalyser's).
    Bilinear,
    /// Half resolution: one Stokes vector per 2x2 super-pixel.
    Superpixel,
}

impl From<Demosaic> for measure::Demosaic {
    fn from(d: Demosaic) -> Self {
        match d {
            Demosaic::Bilinear => measure::Demosaic::Bilinear,
            Demosaic::Superpixel => measure::Demosaic::Superpixel,
        }
    }
}

/// Arguments of `polarid stokes`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Frames taken through a polarizer at the angles of --angles (grayscale PNG/TIFF).
    #[arg(long, num_args = 1.., value_name = "FILE", conflicts_with = "dofp")]
    pub frames: Vec<PathBuf>,
    /// Polarizer angles of the frames, degrees, comma-separated (e.g. 0,45,90,135).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_name = "A,..."
    )]
    pub angles: Vec<f64>,
    /// A raw division-of-focal-plane mosaic (grayscale PNG/TIFF).
    #[arg(long, value_name = "RAW")]
    pub dofp: Option<PathBuf>,
    /// The DoFP 2x2 pattern, degrees, row by row from the top-left.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "90,45,135,0",
        value_name = "A,B,C,D"
    )]
    pub pattern: Vec<f64>,
    /// Colour polarization mosaic: the colour of each 2x2 polarizer block of the 4x4
    /// period, block-row by block-row (e.g. RGGB for IMX250MYR); outputs per band.
    #[arg(long, value_name = "RGGB", requires = "dofp")]
    pub color: Option<String>,
    /// Wavelength of each colour letter, nm (default R=650,G=550,B=450).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "L=NM,...",
        value_parser = band_entry,
        requires = "color"
    )]
    pub bands: Vec<(String, f64)>,
    /// DoFP reconstruction. `bilinear` rounds interpolated values of integer frames to
    /// whole DN exactly as OpenCV does, so results match polanalyser's demosaicing.
    #[arg(long, value_enum, default_value_t = Demosaic::Bilinear)]
    pub demosaic: Demosaic,
    /// Dark level (DN) subtracted from every raw value.
    #[arg(long, default_value_t = 0.0, value_name = "DN")]
    pub dark_level: f64,
    /// Raw values at or above this are saturated and rejected (default: the type's max).
    #[arg(long, value_name = "DN")]
    pub saturation: Option<f64>,
    /// Upper end of the DoLP colour scale of the views, in (0, 1], or `auto` (a round
    /// value above the 99th percentile, for weakly polarized scenes).
    #[arg(long, value_name = "DOLP|auto", default_value = "1", value_parser = views::parse_dolp_scale)]
    pub dolp_max: DolpScale,
    /// The AoLP view: `hue` (AoLP as hue) or `hsv` (hue, with DoLP as brightness).
    #[arg(long, value_enum, default_value_t = AolpView::Hue)]
    pub aolp_view: AolpView,
    /// Output directory.
    #[arg(short = 'o', long, value_name = "DIR")]
    pub output: PathBuf,
}

/// Renders an RGB view: (width, height, bytes).
type Render<'a> = Box<dyn Fn() -> (usize, usize, Vec<u8>) + Send + Sync + 'a>;

/// One output file of `polarid stokes`.
enum OutFile<'a> {
    /// A float32 TIFF of the output's size.
    Tiff(&'a [f32]),
    /// An RGB PNG view, rendered when it is written.
    Png(Render<'a>),
}

impl<'a> OutFile<'a> {
    fn png(f: impl Fn() -> (usize, usize, Vec<u8>) + Send + Sync + 'a) -> Self {
        OutFile::Png(Box::new(f))
    }
}

/// Stage `files` in `output` (none may overwrite one of `inputs`), render, encode and
/// write them in parallel (TIFFs `w × h`; PNG views with fast compression,
/// [`views::write_png_fast`]), and commit; returns how many were written.
fn write_files(
    output: &Path,
    ctx: &Ctx,
    inputs: &[PathBuf],
    (w, h): (usize, usize),
    files: Vec<(String, OutFile<'_>)>,
) -> Result<usize, IoError> {
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let staged = StagedDir::new(output, ctx.force)?;
    for (name, _) in &files {
        check_output(&staged.final_path(name), ctx.force, &inputs)?;
    }
    let paths: Vec<PathBuf> = files
        .iter()
        .map(|(name, _)| staged.path(name))
        .collect::<Result<_, _>>()?;
    files
        .par_iter()
        .zip(paths.par_iter())
        .try_for_each(|((_, file), path)| match file {
            OutFile::Tiff(data) => image::write_tiff_f32(path, true, w, h, data),
            OutFile::Png(render) => {
                let (vw, vh, px) = render();
                views::write_png_fast(path, vw, vh, &px)
            }
        })?;
    staged.commit()?;
    Ok(files.len())
}

/// An entry `L=NM` of `--bands` as (letter, nm) (the pipeline checks them).
fn band_entry(item: &str) -> Result<(String, f64), String> {
    let bad = || format!("expected LETTER=NM (e.g. R=650), got {item:?}");
    let (k, v) = item.split_once('=').ok_or_else(bad)?;
    Ok((k.to_string(), v.trim().parse().map_err(|_| bad())?))
}

/// The pipeline's configuration from the command line (names translated only).
fn config(args: &Args) -> anyhow::Result<StokesConfig> {
    let source = match (&args.dofp, args.frames.is_empty()) {
        (Some(file), true) => StokesSource::Dofp {
            file: file.clone(),
            pattern_deg: args.pattern.clone(),
            demosaic: args.demosaic.into(),
            colour: args.color.clone().map(|c| (c, args.bands.clone())),
        },
        (None, false) => StokesSource::Frames {
            files: args.frames.clone(),
            angles_deg: args.angles.clone(),
        },
        (Some(_), false) => {
            return Err(BadInput("give either --frames or --dofp, not both".into()).into());
        }
        (None, true) => {
            return Err(
                BadInput("give --frames F... with --angles A,... or --dofp RAW".into()).into(),
            );
        }
    };
    Ok(StokesConfig {
        source,
        dark_level: args.dark_level,
        saturation: args.saturation,
    })
}

/// Run `polarid stokes`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let cfg = config(&args)?;
    cfg.validate().cli()?;
    let r = polarid_pipeline::stokes::stokes(&cfg).cli()?;
    warn_all(ctx, &r.warnings);
    // ok: the pipeline returns at least one band.
    if r.bands[0].letter.is_some() {
        return colour::write(&args, &r, ctx);
    }
    let (w, h) = (r.width, r.height);
    let b = &r.bands[0];
    let (img, dolp, aolp) = (&b.images, &b.dolp, &b.aolp);
    let dolp_max = args.dolp_max.resolve(dolp);
    let (mode, m) = (args.aolp_view, Some(&img.mask[..]));
    let files: Vec<(String, OutFile)> = vec![
        (
            "s0.png".into(),
            OutFile::png(|| (w, h, views::s0_view(w, h, &img.s0, m))),
        ),
        (
            "dolp.png".into(),
            OutFile::png(|| views::dolp_view(w, h, dolp, m, dolp_max)),
        ),
        (
            "aolp.png".into(),
            OutFile::png(|| views::aolp_view(w, h, aolp, dolp, m, dolp_max, mode)),
        ),
        ("s0.tif".into(), OutFile::Tiff(&img.s0)),
        ("s1.tif".into(), OutFile::Tiff(&img.s1)),
        ("s2.tif".into(), OutFile::Tiff(&img.s2)),
        ("dolp.tif".into(), OutFile::Tiff(dolp)),
        ("aolp.tif".into(), OutFile::Tiff(aolp)),
    ];
    let n_files = write_files(&args.output, ctx, &r.inputs, (w, h), files)?;
    let c = img.counts;
    ctx.info(format!(
        "polarid stokes: wrote {} files ({w}x{h}) to {}; pixels valid {}, saturated {}, dark {}, invalid {}",
        n_files,
        args.output.display(),
        c.valid,
        c.saturated,
        c.dark,
        c.invalid
    ));
    Ok(())
}
