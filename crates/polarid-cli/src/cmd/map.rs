//! `polarid map MANIFEST.toml --model model.json -o DIR [--bin 1|2|4]`: per-pixel
//! (n, k) and material maps.
//!
//! Pipeline (`polarid_core::map`): for each capture in turn, the frames are read, the
//! per-pixel (or per `b × b` block) Stokes vector and DoLP computed, and only the DoLP
//! (f32) kept, with the signal flags (saturated, dark, invalid) ORed over the captures.
//! Then every unflagged pixel's DoLP values over the captures are fitted for (n, k)
//! (eq. 9, `fit_batch`, in tiles of pixels) and classified by the nearest prototype of
//! the model. Peak memory is about `T` DoLP images plus one capture's frames (see the
//! README for the figure measured on 10 captures of 2048×2448 frames).
//!
//! Outputs (shared/FORMATS.md): float32 TIFF `n.tif`, `k.tif`, `n_se.tif`, `k_se.tif`,
//! `rms_residual.tif` (NaN where not fitted); `class.tif` (u8, or u16 above 255
//! classes; 0 = not classified); `classes.json` (index → name, `"0": "unknown"`);
//! `class.png` (+ `class.svg`, colours with a legend); `reason.tif` (u8, why a pixel is
//! not classified: the indices of `reasons` in the summary); `map_summary.json`
//! (size, binning, thresholds, pixel counts per class and per reason, and per labelled
//! region of the manifest the share of its pixels given each class).
//!
//! Dark threshold: a pixel (block) is "dark" when its mean dark-subtracted `S0` in DN is
//! at or below `--min-s0` in any capture; by default 1 % of the range from the dark
//! level to the saturation level of integer frames (0 for float frames). For Stokes
//! captures (float TIFF, `S0` in DN / exposure) the threshold is divided by the
//! capture's exposure.

use std::path::{Path, PathBuf};

use anyhow::Context;
use polarid_core::classify::{Classifier, ClassifierConfig, UNKNOWN};
use polarid_core::fit::{FitOptions, FitPlan};
use polarid_core::geometry;
use polarid_core::map::{self, MapCounts, MapOutputs, PixelClassifier, reason};
use polarid_core::mosaic;
use polarid_core::stokes::{PixelRules, StokesSolver};
use polarid_io::IoError;
use polarid_io::atomic::{StagedDir, check_output};
use polarid_io::image::{self, Frame};
use polarid_io::manifest::{self, Capture, CaptureSource, Manifest};
use polarid_io::measure::rules_for;
use polarid_io::model::Model;

use crate::render::plots::{PlotSize, class_map};
use crate::{BadInput, Ctx};

/// Arguments of `polarid map`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The capture-set manifest (TOML, shared/FORMATS.md).
    pub manifest: PathBuf,
    /// Trained model (JSON) written by `polarid train`.
    #[arg(long, value_name = "MODEL.json")]
    pub model: PathBuf,
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
    #[arg(long, value_name = "PIXELS", default_value_t = 65536, hide = true)]
    pub tile: usize,
}

/// The map's geometry: frame size, binned size.
#[derive(Debug, Clone, Copy)]
struct Dims {
    width: usize,
    height: usize,
    out_w: usize,
    out_h: usize,
}

fn core_err(path: &Path) -> impl FnOnce(polarid_core::CoreError) -> IoError + '_ {
    move |e| IoError::Core {
        path: path.to_path_buf(),
        source: e,
    }
}

/// Check that a capture's frame has the map's size (set by the first capture).
fn check_dims(dims: &mut Option<Dims>, f: &Frame, bin: usize) -> anyhow::Result<Dims> {
    match dims {
        Some(d) => {
            if (d.width, d.height) != (f.width, f.height) {
                return Err(IoError::Image {
                    path: f.path.clone(),
                    reason: format!(
                        "is {}x{} pixels but the first capture's frames are {}x{}: every capture of a map must have the same size",
                        f.width, f.height, d.width, d.height
                    ),
                }
                .into());
            }
            Ok(*d)
        }
        None => {
            let (out_w, out_h) = map::binned_size(f.width, f.height, bin).map_err(|e| {
                BadInput(format!(
                    "--bin {bin} does not fit the {}x{} frames of {}: {e}",
                    f.width,
                    f.height,
                    f.path.display()
                ))
            })?;
            let d = Dims {
                width: f.width,
                height: f.height,
                out_w,
                out_h,
            };
            *dims = Some(d);
            Ok(d)
        }
    }
}

/// The dark threshold (DN) for a capture's frames.
fn min_s0_for(rules: &PixelRules, is_integer: bool, arg: Option<f64>) -> f32 {
    match arg {
        Some(v) => v as f32,
        None if is_integer && rules.saturation.is_finite() => {
            0.01 * (rules.saturation - rules.dark_level).max(0.0)
        }
        None => 0.0,
    }
}

/// DoLP (binned) of one capture, ORing its signal flags into `flags`; returns the
/// dark threshold used (DN).
fn capture_dolp(
    c: &Capture,
    args: &Args,
    dims: &mut Option<Dims>,
    dolp: &mut Vec<f32>,
    flags: &mut Vec<u8>,
) -> anyhow::Result<f32> {
    let bin = args.bin;
    let alloc = |d: Dims, dolp: &mut Vec<f32>, flags: &mut Vec<u8>| {
        let n = d.out_w * d.out_h;
        dolp.resize(n, 0.0);
        if flags.is_empty() {
            flags.resize(n, 0);
        }
    };
    match &c.source {
        CaptureSource::Frames(frames) => {
            let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
            let solver = StokesSolver::from_degrees(&angles)?;
            let paths: Vec<&Path> = frames.iter().map(|f| f.file.as_path()).collect();
            let imgs = image::read_frames(&paths)?;
            let d = check_dims(dims, &imgs[0], bin)?;
            alloc(d, dolp, flags);
            let mut rules = rules_for(&imgs[0], c.dark_level, c.saturation);
            rules.min_s0 = min_s0_for(&rules, imgs[0].kind.is_integer(), args.min_s0);
            let views: Vec<&[f32]> = imgs.iter().map(|f| f.data.as_slice()).collect();
            map::frames_dolp(&solver, &views, d.width, &rules, bin, dolp, flags)
                .map_err(core_err(&imgs[0].path))?;
            Ok(rules.min_s0)
        }
        CaptureSource::Dofp { file, pattern } => {
            let raw = image::read_frame(file)?;
            let d = check_dims(dims, &raw, bin)?;
            alloc(d, dolp, flags);
            let mut rules = rules_for(&raw, c.dark_level, c.saturation);
            let min_s0 = min_s0_for(&rules, raw.kind.is_integer(), args.min_s0);
            // The dark test is made on the block mean by stokes_dolp.
            rules.min_s0 = f32::MIN;
            let n = raw.width * raw.height;
            let (mut s0, mut s1, mut s2, mut m) =
                (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0u8; n]);
            mosaic::bilinear_stokes(
                &raw.data, raw.width, pattern, &rules, false, &mut s0, &mut s1, &mut s2, &mut m,
            )
            .map_err(core_err(file))?;
            drop(raw);
            map::stokes_dolp(d.width, &s0, &s1, &s2, Some(&m), min_s0, bin, dolp, flags)
                .map_err(core_err(file))?;
            Ok(min_s0)
        }
        CaptureSource::Stokes { s0, s1, s2 } => {
            let imgs = image::read_frames(&[s0, s1, s2])?;
            let d = check_dims(dims, &imgs[0], bin)?;
            alloc(d, dolp, flags);
            let min_s0 = args.min_s0.unwrap_or(0.0) / c.exposure;
            map::stokes_dolp(
                d.width,
                &imgs[0].data,
                &imgs[1].data,
                &imgs[2].data,
                None,
                min_s0 as f32,
                bin,
                dolp,
                flags,
            )
            .map_err(core_err(s0))?;
            Ok(min_s0 as f32)
        }
    }
}

/// Per labelled region: the share of its (binned) pixels given each class.
fn region_summary(
    m: &Manifest,
    d: Dims,
    bin: usize,
    class: &[u16],
    names: &[String],
) -> Vec<serde_json::Value> {
    let mut out = Vec::new();
    for r in &m.regions {
        // Blocks entirely inside the rectangle.
        let x0 = r.rect.x.div_ceil(bin);
        let y0 = r.rect.y.div_ceil(bin);
        let x1 = ((r.rect.x + r.rect.width) / bin).min(d.out_w);
        let y1 = ((r.rect.y + r.rect.height) / bin).min(d.out_h);
        let mut counts = vec![0u64; names.len() + 1];
        for y in y0..y1.max(y0) {
            for x in x0..x1.max(x0) {
                if let Some(c) = class.get(y * d.out_w + x)
                    && let Some(n) = counts.get_mut(*c as usize)
                {
                    *n += 1;
                }
            }
        }
        let total: u64 = counts.iter().sum();
        let label = |i: usize| {
            if i == 0 {
                UNKNOWN.to_string()
            } else {
                names[i - 1].clone()
            }
        };
        let per: serde_json::Map<String, serde_json::Value> = counts
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(i, n)| (label(i), serde_json::json!(n)))
            .collect();
        let mut v = serde_json::json!({
            "name": r.name,
            "rect": [r.rect.x, r.rect.y, r.rect.width, r.rect.height],
            "pixels": total,
            "classes": per,
        });
        if let Some(cls) = &r.class {
            let correct = names
                .iter()
                .position(|n| n == cls)
                .map_or(0, |i| counts[i + 1]);
            v["class"] = serde_json::json!(cls);
            v["correct"] = serde_json::json!(correct);
            v["correct_fraction"] = if total > 0 {
                serde_json::json!(correct as f64 / total as f64)
            } else {
                serde_json::Value::Null
            };
        }
        out.push(v);
    }
    out
}

/// Run `polarid map`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    if args.bin == 0 || args.bin > 64 {
        return Err(BadInput(format!("--bin must be in 1..=64, got {}", args.bin)).into());
    }
    if let Some(v) = args.min_s0
        && !v.is_finite()
    {
        return Err(BadInput(format!("--min-s0 must be a finite number, got {v}")).into());
    }
    let m = manifest::load(&args.manifest)?;
    for w in &m.warnings {
        if !ctx.quiet {
            eprintln!("polarid: warning: {w}");
        }
    }
    let model = Model::read(&args.model)?;
    let classifier = Classifier::new(model.prototypes(), ClassifierConfig::default())
        .map_err(core_err(&args.model))?;
    let pc = PixelClassifier::new(classifier, args.max_distance)
        .map_err(|e| BadInput(format!("--max-distance: {e}")))?
        .with_mahalanobis(args.metric == super::classify::MetricArg::Mahalanobis);
    let names: Vec<String> = pc.names().to_vec();

    let mut inputs: Vec<&Path> = vec![args.manifest.as_path(), args.model.as_path()];
    for c in &m.captures {
        inputs.extend(c.source.files());
    }
    let files = [
        "n.tif",
        "k.tif",
        "n_se.tif",
        "k_se.tif",
        "rms_residual.tif",
        "class.tif",
        "reason.tif",
        "classes.json",
        "class.png",
        "class.svg",
        "map_summary.json",
    ];
    for f in files {
        check_output(&args.output.join(f), ctx.force, &inputs)?;
    }

    // Geometry: one β per capture (eq. 5), the fit plan shared by every pixel.
    let betas: Vec<f64> = m
        .captures
        .iter()
        .map(|c| {
            geometry::beta(
                c.theta_i_deg.to_radians(),
                c.theta_r_deg.to_radians(),
                c.phi_deg.to_radians(),
            )
        })
        .collect();
    let plan = FitPlan::new(&betas, FitOptions::default()).map_err(core_err(&args.manifest))?;

    // Stage 1: DoLP per capture (one capture's frames in memory at a time).
    let t0 = std::time::Instant::now();
    let pb = ctx.progress(m.captures.len() as u64, "captures (DoLP)");
    let mut dims: Option<Dims> = None;
    let mut flags: Vec<u8> = Vec::new();
    let mut dolp: Vec<Vec<f32>> = Vec::with_capacity(m.captures.len());
    let mut thresholds = Vec::with_capacity(m.captures.len());
    for c in &m.captures {
        let mut d = Vec::new();
        let th = capture_dolp(c, &args, &mut dims, &mut d, &mut flags)
            .with_context(|| format!("capture {} (line {})", c.index, c.line))?;
        thresholds.push(th);
        dolp.push(d);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let d = dims.context("the manifest has no capture")?;
    let t_dolp = t0.elapsed().as_secs_f64();

    // Stage 2: fit and classify, in tiles.
    let npix = d.out_w * d.out_h;
    let mut out: Vec<Vec<f32>> = vec![vec![0f32; npix]; 5];
    let mut class = vec![0u16; npix];
    let mut why = vec![0u8; npix];
    let pb = ctx.progress(npix as u64, "pixels (fit)");
    let counts: MapCounts = {
        let [n, k, n_se, k_se, rms] = &mut out[..] else {
            anyhow::bail!("internal error: five output images expected");
        };
        let views: Vec<&[f32]> = dolp.iter().map(|v| v.as_slice()).collect();
        let outputs = MapOutputs {
            n,
            k,
            n_se,
            k_se,
            rms_residual: rms,
            class: &mut class,
            reason: &mut why,
        };
        let progress = |done: usize| pb.set_position(done as u64);
        map::fit_and_classify(&plan, &pc, &views, &flags, args.tile, outputs, &progress)
            .map_err(core_err(&args.manifest))?
    };
    pb.finish_and_clear();
    drop(dolp);
    drop(flags);
    let t_fit = t0.elapsed().as_secs_f64() - t_dolp;

    // Outputs, staged so that a failure leaves nothing behind.
    let staged = StagedDir::new(&args.output, ctx.force)?;
    for (name, data) in ["n.tif", "k.tif", "n_se.tif", "k_se.tif", "rms_residual.tif"]
        .iter()
        .zip(&out)
    {
        image::write_tiff_f32(&staged.path(name)?, true, d.out_w, d.out_h, data)?;
    }
    drop(out);
    if names.len() <= u8::MAX as usize {
        let c8: Vec<u8> = class.iter().map(|&c| c as u8).collect();
        image::write_gray8(&staged.path("class.tif")?, true, d.out_w, d.out_h, &c8)?;
    } else {
        image::write_gray16(&staged.path("class.tif")?, true, d.out_w, d.out_h, &class)?;
    }
    image::write_gray8(&staged.path("reason.tif")?, true, d.out_w, d.out_h, &why)?;
    let mut classes_json = serde_json::Map::new();
    classes_json.insert("0".into(), serde_json::json!(UNKNOWN));
    for (i, n) in names.iter().enumerate() {
        classes_json.insert((i + 1).to_string(), serde_json::json!(n));
    }
    let text = serde_json::to_string_pretty(&serde_json::Value::Object(classes_json))?;
    std::fs::write(staged.path("classes.json")?, text + "\n")
        .context("cannot write classes.json")?;
    let title = format!(
        "Material map ({}x{}{})",
        d.out_w,
        d.out_h,
        if args.bin > 1 {
            format!(", {0}x{0} binning", args.bin)
        } else {
            String::new()
        }
    );
    let png = staged.path("class.png")?;
    let dir = png.parent().context("internal error: staging directory")?;
    class_map(&title, d.out_w, d.out_h, &class, &names, PlotSize::REPORT)?.write(dir, "class")?;

    let reasons: serde_json::Map<String, serde_json::Value> = reason::NAMES
        .iter()
        .zip(counts.reasons)
        .map(|(n, c)| (n.to_string(), serde_json::json!(c)))
        .collect();
    let class_counts: Vec<serde_json::Value> = counts
        .classes
        .iter()
        .enumerate()
        .map(|(i, c)| {
            serde_json::json!({
                "index": i,
                "name": if i == 0 { UNKNOWN } else { names[i - 1].as_str() },
                "pixels": c,
            })
        })
        .collect();
    let summary = serde_json::json!({
        "manifest": args.manifest.display().to_string(),
        "model": args.model.display().to_string(),
        "frame_width": d.width,
        "frame_height": d.height,
        "bin": args.bin,
        "width": d.out_w,
        "height": d.out_h,
        "captures": m.captures.len(),
        "beta_deg": betas.iter().map(|b| b.to_degrees()).collect::<Vec<_>>(),
        "min_s0_dn": thresholds,
        "max_distance": args.max_distance,
        "metric": format!("{:?}", args.metric).to_lowercase(),
        "pixels": npix,
        "classified": counts.reasons[reason::CLASSIFIED as usize],
        "reasons": reasons,
        "reason_codes": reason::NAMES,
        "classes": class_counts,
        "regions": region_summary(&m, d, args.bin, &class, &names),
        "seconds": {"dolp": t_dolp, "fit_classify": t_fit},
    });
    std::fs::write(
        staged.path("map_summary.json")?,
        serde_json::to_string_pretty(&summary)? + "\n",
    )
    .context("cannot write map_summary.json")?;
    staged.commit()?;
    ctx.info(format!(
        "polarid map: {}x{} pixels, {} classified, written to {} (DoLP {:.2} s, fit {:.2} s)",
        d.out_w,
        d.out_h,
        counts.reasons[reason::CLASSIFIED as usize],
        args.output.display(),
        t_dolp,
        t_fit
    ));
    Ok(())
}
