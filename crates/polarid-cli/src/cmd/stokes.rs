//! `polarid stokes`: Stokes, DoLP and AoLP images from rotating-polarizer frames or a
//! division-of-focal-plane (DoFP) mosaic.
//!
//! Writes `s0.tif`, `s1.tif`, `s2.tif`, `dolp.tif`, `aolp.tif` (float32; DoLP and AoLP are
//! NaN where a pixel is rejected) and the views `s0.png`, `dolp.png`, `aolp.png`
//! ([`crate::render::views`]) into the output directory, all or nothing. The files are
//! rendered, encoded and written in parallel ([`write_files`]). The Stokes images of frames come from
//! [`polarid_io::measure`]; those of a DoFP mosaic, with DoLP and AoLP, from the fused
//! kernel [`polarid_core::mosaic::dofp_polar`] in one pass over the mosaic (the same
//! numbers as [`polarid_io::measure::dofp_stokes`] followed by
//! [`polarid_core::stokes::dolp_aolp`]). A colour polarization mosaic (`--color`) gives
//! these per band (`stokes_colour.rs`).

use std::path::{Path, PathBuf};

use polarid_core::mosaic::{self, DofpMethod, DofpOutputs, Pattern};
use polarid_core::region::Sampling;
use polarid_core::stokes::{self, PixelRules, StokesSolver};
use polarid_io::IoError;
use polarid_io::atomic::{StagedDir, check_output};
use polarid_io::image::{self, Frame};
use polarid_io::measure::{self, StokesImages, frames_stokes, rules_for};
use rayon::prelude::*;

use polarid_pipeline::map::rules::check_levels;

#[path = "stokes_colour.rs"]
mod colour;

use super::common::PipeResult;
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
        requires = "color"
    )]
    pub bands: Vec<String>,
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

/// Stokes images with mask and counts, DoLP and AoLP of a DoFP mosaic in one pass
/// ([`mosaic::dofp_polar`]); errors name the raw file, as [`measure::dofp_stokes`]'s.
fn dofp_images(
    raw: &Frame,
    pattern: &Pattern,
    rules: &PixelRules,
    demosaic: Demosaic,
    round: bool,
) -> Result<(StokesImages, Vec<f32>, Vec<f32>), IoError> {
    let (method, sampling) = match demosaic {
        Demosaic::Bilinear => (DofpMethod::Bilinear { round }, Sampling::BilinearDofp),
        Demosaic::Superpixel => (DofpMethod::Superpixel, Sampling::Independent),
    };
    let (w, h) = method.output_size(raw.width, raw.height);
    let mut img = StokesImages::alloc(w, h, sampling);
    let (mut dolp, mut aolp) = (vec![0f32; w * h], vec![0f32; w * h]);
    let out = DofpOutputs {
        s0: Some(&mut img.s0),
        s1: Some(&mut img.s1),
        s2: Some(&mut img.s2),
        mask: Some(&mut img.mask),
        dolp: Some(&mut dolp),
        aolp: Some(&mut aolp),
    };
    img.counts = mosaic::dofp_polar(&raw.data, raw.width, pattern, method, rules, out).map_err(
        |source| IoError::Core {
            path: raw.path.clone(),
            source,
        },
    )?;
    Ok((img, dolp, aolp))
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

/// Render, encode and write `files` into `staged`, in parallel (TIFFs `w × h`; PNG
/// views with fast compression, [`views::write_png_fast`]).
fn write_files(
    staged: &StagedDir,
    w: usize,
    h: usize,
    files: Vec<(String, OutFile<'_>)>,
) -> Result<(), IoError> {
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
        })
}

/// Run `polarid stokes`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    check_levels(args.dark_level, args.saturation).cli()?;
    if let (Some(raw_path), Some(color), true) = (&args.dofp, &args.color, args.frames.is_empty()) {
        let rules_of = |raw: &Frame| rules_for(raw, args.dark_level, args.saturation);
        return colour::run(&args, raw_path, color, rules_of, ctx);
    }
    let (img, dolp, aolp, inputs) = match (&args.dofp, args.frames.is_empty()) {
        (Some(raw_path), true) => {
            let pattern = Pattern::new(&args.pattern)?;
            let raw = image::read_frame(raw_path)?;
            let rules = rules_for(&raw, args.dark_level, args.saturation);
            let round = raw.kind.is_integer() && args.demosaic == Demosaic::Bilinear;
            let (img, dolp, aolp) = dofp_images(&raw, &pattern, &rules, args.demosaic, round)?;
            (img, dolp, aolp, vec![raw_path.clone()])
        }
        (None, false) => {
            if args.angles.len() != args.frames.len() {
                return Err(BadInput(format!(
                    "--angles gives {} angle(s) for {} frame(s); give one angle per frame",
                    args.angles.len(),
                    args.frames.len()
                ))
                .into());
            }
            if let Some(a) = args.angles.iter().find(|a| !(a.abs() <= 3600.0)) {
                return Err(BadInput(format!(
                    "--angles: a polarizer angle must be in [-3600, 3600] degrees, got {a:?}"
                ))
                .into());
            }
            let solver = StokesSolver::from_degrees(&args.angles)?;
            if solver.ill_conditioned() && !ctx.quiet {
                eprintln!(
                    "polarid: warning: polarizer angles {:?} are poorly spread (condition number {:.1}, best {:.2}): S1 and S2 will be noisy",
                    args.angles,
                    solver.condition_number(),
                    std::f64::consts::SQRT_2
                );
            }
            let frames = image::read_frames(&args.frames)?;
            // ok: one frame per angle, and the solver accepted at least three angles.
            let rules = rules_for(&frames[0], args.dark_level, args.saturation);
            let img = frames_stokes(&frames, &solver, &rules)?;
            let n = img.width * img.height;
            let (mut dolp, mut aolp) = (vec![0f32; n], vec![0f32; n]);
            let (s0, s1, s2, m) = (&img.s0, &img.s1, &img.s2, Some(&img.mask[..]));
            stokes::dolp_aolp(img.width, s0, s1, s2, m, &mut dolp, &mut aolp)?;
            (img, dolp, aolp, args.frames.clone())
        }
        (Some(_), false) => {
            return Err(BadInput("give either --frames or --dofp, not both".into()).into());
        }
        (None, true) => {
            return Err(
                BadInput("give --frames F... with --angles A,... or --dofp RAW".into()).into(),
            );
        }
    };
    let (w, h) = (img.width, img.height);
    let dolp_max = args.dolp_max.resolve(&dolp);
    let (mode, m) = (args.aolp_view, Some(&img.mask[..]));
    let files: Vec<(String, OutFile)> = vec![
        (
            "s0.png".into(),
            OutFile::png(|| (w, h, views::s0_view(w, h, &img.s0, m))),
        ),
        (
            "dolp.png".into(),
            OutFile::png(|| views::dolp_view(w, h, &dolp, m, dolp_max)),
        ),
        (
            "aolp.png".into(),
            OutFile::png(|| views::aolp_view(w, h, &aolp, &dolp, m, dolp_max, mode)),
        ),
        ("s0.tif".into(), OutFile::Tiff(&img.s0)),
        ("s1.tif".into(), OutFile::Tiff(&img.s1)),
        ("s2.tif".into(), OutFile::Tiff(&img.s2)),
        ("dolp.tif".into(), OutFile::Tiff(&dolp)),
        ("aolp.tif".into(), OutFile::Tiff(&aolp)),
    ];
    let input_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let staged = StagedDir::new(&args.output, ctx.force)?;
    for (name, _) in &files {
        check_output(&staged.final_path(name), ctx.force, &input_refs)?;
    }
    let n_files = files.len();
    write_files(&staged, w, h, files)?;
    staged.commit()?;
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
