//! `polarid map MANIFEST.toml --model model.json -o DIR [--bin 1|2|4]`: per-pixel
//! (n, k) and material maps.
//!
//! The workflow (DoLP per capture, fit and classify every pixel, region summary) is
//! [`polarid_pipeline::map`], shared with the Python package (`polarid.map_manifest`);
//! this command parses the options, calls it and writes the outputs. A manifest with
//! calibrated geometry (`[camera]`, a `source` per capture) is mapped with a β per
//! pixel and capture (pixels without geometry: reason `no_geometry`).
//!
//! Outputs (docs/FORMATS.md): float32 TIFF `n.tif`, `k.tif`, `n_se.tif`, `k_se.tif`,
//! `rms_residual.tif` (NaN where not fitted); `class.tif` (u8, or u16 above 255
//! classes; 0 = not classified); `classes.json` (index → name, `"0": "unknown"`);
//! `class.png` (+ `class.svg`, colours with a legend); `reason.tif` (u8, why a pixel is
//! not classified: the indices of `reasons` in the summary); `map_summary.json`
//! (size, binning, thresholds, pixel counts per class and per reason, and per labelled
//! region of the manifest the share of its pixels given each class). Everything is
//! staged, so a failure leaves nothing behind.
//!
//! A manifest with colour captures is mapped per band (docs/BANDS.md): `n_450.tif`,
//! `k_450.tif`, `n_se_450.tif`, `k_se_450.tif`, `rms_residual_450.tif` per band (named
//! by its wavelength) instead of `n.tif` ..., and one `class.tif` from the
//! classification of each pixel on all its bands (`--model` trained on multi-band fits,
//! or `--library builtin-rgb`), with per band `n_450.png`, `k_450.png` (+ `.svg`) and,
//! for labelled regions, `nk_bands` and `nk_spectra` figures (`render::map_figures`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use polarid_io::atomic::{StagedDir, check_output};
use polarid_io::image;
use polarid_io::library::Library;
use polarid_io::manifest;
use polarid_io::model::Model;
use polarid_pipeline::map::{self, MapConfig, MapResult, Metric};

use super::common::{Bars, PipeResult, warn_all};
use crate::Ctx;
use crate::render::map_figures;
use crate::render::table_report::References;

/// Arguments of `polarid map`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("prototypes").required(true).args(["model", "library"])))]
pub struct Args {
    /// The capture-set manifest (TOML, docs/FORMATS.md).
    pub manifest: PathBuf,
    /// Trained model (JSON) written by `polarid train`.
    #[arg(long, value_name = "MODEL.json")]
    pub model: Option<PathBuf>,
    /// Material library (`builtin`, `builtin-rgb`, a library CSV): each material, as it is
    /// found, tested against every pixel's rows (docs/CLASSIFY.md); single-band captures
    /// are taken at their `wavelength_nm` (else 650 nm, with a warning).
    #[arg(long, value_name = "LIBRARY")]
    pub library: Option<String>,
    /// Where the model was trained: `same` (the default) — on this bench: each pixel's
    /// noise against the prototypes' sample covariance — or `other`: both sides' total
    /// covariance (docs/CLASSIFY.md "Trained models"). No effect with a library.
    #[arg(long, value_enum, default_value_t = super::classify::BenchArg::Same)]
    pub bench: super::classify::BenchArg,
    /// Output directory.
    #[arg(short = 'o', long, value_name = "DIR")]
    pub output: PathBuf,
    /// Spatial binning: sum b×b blocks of pixels before the DoLP (1 = full resolution).
    #[arg(long, value_name = "B", default_value_t = 1)]
    pub bin: usize,
    /// Dark threshold on the block's mean dark-subtracted S0, DN (default: 1 % of the
    /// range from the dark level to saturation for integer frames, 0 for float frames).
    #[arg(long, value_name = "DN")]
    pub min_s0: Option<f64>,
    /// Leave pixels unclassified (`rejected`) whose nearest prototype is farther than D
    /// in the (n, k) plane.
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
    /// Distance to the prototypes: `euclidean` (the paper's rule) or `mahalanobis`
    /// (with each pixel's fit covariance plus the prototype's; `--max-distance` is then
    /// in standard deviations).
    #[arg(long, value_enum, default_value_t = super::classify::MetricArg::Euclidean)]
    pub metric: super::classify::MetricArg,
    /// Pixels per fitting tile (memory of the fit stage ≈ 200 bytes per pixel).
    #[arg(long, value_name = "PIXELS", default_value_t = map::DEFAULT_TILE, hide = true)]
    pub tile: usize,
    /// Decision rule per pixel (docs/CLASSIFY.md): `set` (a material, `ambiguous` or
    /// unknown at --confidence, with the error model below) or `nearest` (the paper's
    /// nearest prototype, with --metric and --max-distance).
    #[arg(long, value_enum, default_value_t = super::common::RuleArg::Set)]
    pub rule: super::common::RuleArg,
    /// Confidence of the consistent set, in (0, 1).
    #[arg(long, value_name = "P", default_value_t = 0.95)]
    pub confidence: f64,
    /// Weight each pixel's fit by its DoLP standard errors from the noise model estimated
    /// on the map: `auto` (calibrated geometry only), `noise` or `none`.
    #[arg(long, value_name = "W", default_value = "auto")]
    pub weights: String,
    /// Set rule: angle uncertainty of captures without an angle_sd_deg, degrees.
    #[arg(long, value_name = "DEG", default_value_t = map::MapErrors::default().angle_sd_deg)]
    pub angle_sd_deg: f64,
    /// Set rule: additive DoLP error of the polarimeter.
    #[arg(long, value_name = "DOLP", default_value_t = map::MapErrors::default().dolp_floor)]
    pub dolp_floor: f64,
    /// Set rule: the lowest extinction ratio the polarizer may have (inf: ideal).
    #[arg(long, value_name = "ER", default_value_t = map::MapErrors::default().extinction_ratio)]
    pub extinction_ratio: f64,
    /// Set rule: the largest retardance ahead of the polarizer, degrees.
    #[arg(long, value_name = "DEG", default_value_t = map::MapErrors::default().retardance_deg)]
    pub retardance_deg: f64,
}

/// The files `polarid map` writes besides the fit images (`n.tif` ...,
/// [`map::output_files`]).
const FILES: [&str; 6] = [
    "class.tif",
    "reason.tif",
    "classes.json",
    "class.png",
    "class.svg",
    "map_summary.json",
];

/// Run `polarid map`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let metric = match args.metric {
        super::classify::MetricArg::Euclidean => Metric::Euclidean,
        super::classify::MetricArg::Mahalanobis => Metric::Mahalanobis,
    };
    let rule = match args.rule {
        super::common::RuleArg::Set => map::Rule::Set,
        super::common::RuleArg::Nearest => map::Rule::Nearest,
    };
    let errors = map::MapErrors {
        angle_sd_deg: args.angle_sd_deg,
        dolp_floor: args.dolp_floor,
        extinction_ratio: args.extinction_ratio,
        retardance_deg: args.retardance_deg,
    };
    let cfg = MapConfig::new(args.bin, args.min_s0, args.max_distance, metric, args.tile)
        .and_then(|c| c.with_rule(rule, args.confidence))
        .and_then(|c| c.with_errors(errors))
        .and_then(|c| Ok(c.with_weights(map::parse_weights(&args.weights)?)))
        .cli()?
        .with_bench(match args.bench {
            super::classify::BenchArg::Same => polarid_core::classify::Bench::Same,
            super::classify::BenchArg::Other => polarid_core::classify::Bench::Other,
        });
    let m = manifest::load(&args.manifest)?;
    warn_all(ctx, &m.warnings);
    let model = args.model.as_ref().map(|p| Model::read(p)).transpose()?;
    let spec = args.library.as_deref().unwrap_or("builtin");
    let src = match (&model, &args.model) {
        (Some(model), Some(p)) => map::MapPrototypes::Model { model, path: p },
        _ => map::MapPrototypes::Library(spec),
    };
    let label = src.label();
    let profiles = match &model {
        Some(model) => model.multi_prototypes(),
        None => Library::load(spec)?.multi_prototypes(),
    };
    // Checked before the work, as the map itself does.
    if let (Some(model), Some(p), map::Rule::Nearest, false) =
        (&model, &args.model, rule, map::is_colour(&m))
    {
        map::pixel_classifier(&cfg, model, p).cli()?;
    }

    let mut inputs: Vec<&Path> = vec![args.manifest.as_path()];
    inputs.extend(args.model.as_deref());
    for c in &m.captures {
        inputs.extend(c.source.files());
    }
    let files = map::output_files(&m, &FILES);
    for f in files.iter().chain(&map_figures::band_files(&files)) {
        check_output(&args.output.join(f), ctx.force, &inputs)?;
    }

    let bars = Bars::new(ctx);
    let progress = |s: &str, d, t| bars.report(s, d, t);
    let r = map::map_manifest_from(&cfg, &m, src, &progress).cli()?;
    drop(bars);
    // The manifest's warnings were printed above; the others follow.
    warn_all(ctx, r.warnings.iter().skip(m.warnings.len()));
    let refs = map_figures::references(&label, &profiles, args.library.as_deref(), model.is_some());
    write_outputs(&args, &r, &refs, ctx)?;
    let a = r.answers();
    ctx.info(format!(
        "polarid map: {}x{} pixels: {} one material, {} ambiguous, {} unknown ({} rejected, {} without a usable fit); written to {} (DoLP {:.2} s, fit {:.2} s)",
        r.width,
        r.height,
        a.material,
        a.ambiguous,
        a.unknown,
        a.rejected,
        a.not_fitted(),
        args.output.display(),
        r.seconds_dolp,
        r.seconds_fit
    ));
    Ok(())
}

/// Write the maps, staged so that a failure leaves nothing behind.
fn write_outputs(args: &Args, r: &MapResult, refs: &References, ctx: &Ctx) -> anyhow::Result<()> {
    let (w, h) = (r.width, r.height);
    let staged = StagedDir::new(&args.output, ctx.force)?;
    for (name, data) in r.fit_images() {
        image::write_tiff_f32(&staged.path(&name)?, true, w, h, data)?;
    }
    if r.class_names.len() <= u8::MAX as usize {
        let c8: Vec<u8> = r.class.iter().map(|&c| c as u8).collect();
        image::write_gray8(&staged.path("class.tif")?, true, w, h, &c8)?;
    } else {
        image::write_gray16(&staged.path("class.tif")?, true, w, h, &r.class)?;
    }
    image::write_gray8(&staged.path("reason.tif")?, true, w, h, &r.reason)?;
    let text = serde_json::to_string_pretty(&r.classes_json())?;
    std::fs::write(staged.path("classes.json")?, text + "\n")
        .context("cannot write classes.json")?;
    let png = staged.path("class.png")?;
    let dir = png.parent().context("internal error: staging directory")?;
    map_figures::class_figure(r)?.write(dir, "class")?;
    for (stem, plot) in map_figures::band_figures(r, refs)? {
        plot.write(dir, &stem)?;
    }

    let mut summary = r.summary_json();
    summary["manifest"] = serde_json::json!(args.manifest.display().to_string());
    summary["model"] = match (&args.model, &args.library) {
        (Some(p), _) => serde_json::json!(p.display().to_string()),
        (None, l) => serde_json::json!(l),
    };
    // No wall-clock time in the file (identical runs give identical files): the
    // timings are printed on standard error.
    std::fs::write(
        staged.path("map_summary.json")?,
        serde_json::to_string_pretty(&summary)? + "\n",
    )
    .context("cannot write map_summary.json")?;
    staged.commit()?;
    Ok(())
}
