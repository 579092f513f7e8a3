//! Manifest → per-pixel `(n, k)` and material maps (`polarid map`, `polarid.map_manifest`).
//!
//! Pipeline (`polarid_core::map`), one path for every map: a map has one or more bands
//! (module `bands`: a single-band map is one band, a colour map one per wavelength).
//! For each capture in turn, the frames are read, the per-pixel (or per `b × b` block)
//! Stokes vector and DoLP of each of its bands computed, and only the DoLP (f32) kept,
//! with the signal flags (saturated, dark, invalid) ORed over the band's captures
//! (progress stage `"captures (DoLP)"`). Then every band's unflagged pixels are fitted
//! for (n, k) over the band's captures (eq. 9, in tiles of pixels; stage `"pixels
//! (fit)"`, `"pixels (fit, 450 nm)"` per band of a colour map) and every pixel decided
//! once on its bands as `polarid classify` decides a target (stage `"pixels
//! (classify)"`, module `decide`): against a model the set rule on the same bench (the pixel's noise covariance against the prototypes'
//! sample covariance) or another (`MapConfig::with_bench`: both totals), against a
//! library the hypothesis tests on the pixel's rows; or the paper's nearest prototype
//! (`Rule::Nearest`; a single-band map answers it in the fit). With calibrated geometry (and for a library)
//! the fits are weighted by the per-pixel noise model estimated on the map
//! (`polarid_core::map::noise`; [`Weights`]). Peak memory is about `T`
//! DoLP images plus one capture's frames (and `T` β images with calibrated geometry).
//!
//! # Angles
//! - **Far field** (a manifest with angles per capture): one β per capture (eq. 5 from
//!   `theta_i_deg`, `theta_r_deg`, `phi_deg`), shared by every pixel (`fit_batch`).
//! - **Calibrated geometry** (a manifest with `[camera]` and a `source` per capture): a
//!   β per pixel and capture (stage `"captures (geometry)"`, module `geometry`), from
//!   where the ray through the centre of the pixel's `b × b` block (coordinates of the
//!   files as stored: the raw mosaic for DoFP; pixel centres at integers) meets the
//!   pixel's plane: the plane of the first region (manifest order) whose rectangle
//!   contains that centre, else the first `[[plane]]`. The fit is
//!   `fit_batch_pixel_beta`. A pixel without geometry in some capture (its ray misses
//!   its plane, or the source is below the plane's horizon) is not classified: reason
//!   `no_geometry`. The summary gives each capture's β range (`beta_range_deg`).
//!
//! Dark threshold: a pixel (block) is "dark" when its mean dark-subtracted `S0` in DN is
//! at or below `min_s0` in any capture; by default 1 % of the range from the dark level
//! to the saturation level of integer frames (0 for float frames). For Stokes captures
//! (float TIFF, `S0` in DN / exposure) the threshold is divided by the capture's
//! exposure.
//!
//! Nothing is written here: [`map_manifest`] returns the images and counts
//! ([`MapResult`]), and the caller writes them (`polarid map` writes TIFFs, PNG/SVG and
//! JSON; the Python binding returns numpy arrays).

mod bands;
mod capture;
mod decide;
mod frames;
mod geometry;
pub mod noise_sample;
pub mod rules;
mod summary;

use std::path::Path;
use std::time::Instant;

use polarid_core::classify::{Bench, Classifier, ClassifierConfig, UNKNOWN};
use polarid_core::map::noise::NoiseEstimate;
use polarid_core::map::sets::MapErrorModel;
use polarid_core::map::{MapCounts, PixelClassifier, reason};
use polarid_core::systematic::Polarimetric;
use polarid_io::IoError;
use polarid_io::manifest::Manifest;
use polarid_io::model::Model;

pub use bands::{
    BAND_IMAGES, BandDolp, BandMap, BandsFit, FitGeometry, band_class_names, band_tag, fit_bands,
    is_colour, output_files,
};
pub use decide::MapPrototypes;
pub use frames::{Frames, FramesSource, band_order, frames_bands, frames_class_names, map_frames};
pub use polarid_core::map::reason::NAMES as REASON_NAMES;
pub use summary::RegionSummary;

use crate::error::{PipelineError, Result, ensure};
use crate::progress::{Progress, Warning};

/// Distance to the prototypes: the classifier's metric (Euclidean in `(n, k)`, the
/// paper's rule; or Mahalanobis with each pixel's fit covariance plus the prototype's,
/// `max_distance` then being in standard deviations).
pub use polarid_core::classify::Metric;

pub use crate::options::{parse_metric, parse_rule};

/// Default pixels per fitting tile.
pub const DEFAULT_TILE: usize = 65536;

/// How a pixel's answer is chosen: [`Rule::Set`] (the default: a material, `ambiguous`
/// or unknown, docs/CLASSIFY.md) or [`Rule::Nearest`] (the paper's nearest prototype).
pub use polarid_core::classify::Rule;

/// Whether the per-pixel fits are weighted by the noise model
/// (`polarid_core::map::noise`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Weights {
    /// Weighted with calibrated geometry, unweighted in the far field (the paper's fit,
    /// kept as it was).
    #[default]
    Auto,
    /// Weighted by each pixel's DoLP standard errors from the noise model estimated on
    /// the map.
    Noise,
    /// Unweighted, each pixel's covariance scaled by its own reduced χ².
    None,
}

impl Weights {
    /// Name used on the command line and in the summary.
    pub fn name(self) -> &'static str {
        match self {
            Weights::Auto => "auto",
            Weights::Noise => "noise",
            Weights::None => "none",
        }
    }
}

/// Parse `auto`, `noise` or `none` (error naming `--weights`).
pub fn parse_weights(s: &str) -> Result<Weights> {
    match s {
        "auto" => Ok(Weights::Auto),
        "noise" => Ok(Weights::Noise),
        "none" => Ok(Weights::None),
        _ => Err(PipelineError::config(
            "--weights",
            format!("{s:?}"),
            "must be \"auto\", \"noise\" or \"none\"",
        )),
    }
}

/// The systematic error model of the set rule (docs/ERRORS.md; the defaults of `fit`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapErrors {
    /// Angle uncertainty of captures without their own `angle_sd_deg`, degrees.
    pub angle_sd_deg: f64,
    /// Additive DoLP error.
    pub dolp_floor: f64,
    /// Lowest extinction ratio of the analyzer (`inf`: ideal).
    pub extinction_ratio: f64,
    /// Largest retardance ahead of the analyzer, degrees.
    pub retardance_deg: f64,
}

impl Default for MapErrors {
    fn default() -> Self {
        Self {
            angle_sd_deg: crate::fit::DEFAULT_ANGLE_SD_DEG,
            dolp_floor: crate::fit::DEFAULT_DOLP_FLOOR,
            extinction_ratio: crate::fit::DEFAULT_EXTINCTION_RATIO,
            retardance_deg: crate::fit::DEFAULT_RETARDANCE_DEG,
        }
    }
}

/// The validated options of a map (built by [`MapConfig::new`] before any work).
#[derive(Debug, Clone, PartialEq)]
pub struct MapConfig {
    bin: usize,
    min_s0: Option<f64>,
    max_distance: Option<f64>,
    metric: Metric,
    tile: usize,
    rule: Rule,
    confidence: f64,
    errors: MapErrors,
    weights: Weights,
    bench: Bench,
}

impl MapConfig {
    /// Check the options: `bin` in `1..=64` (sum of `bin × bin` blocks before the DoLP),
    /// `min_s0` (dark threshold, DN) finite, `max_distance` (reject pixels whose nearest
    /// prototype is farther) finite and > 0, `tile` (pixels per fitting tile) >= 1.
    /// Errors are [`PipelineError::Config`] naming the CLI option (`--bin`, ...).
    pub fn new(
        bin: usize,
        min_s0: Option<f64>,
        max_distance: Option<f64>,
        metric: Metric,
        tile: usize,
    ) -> Result<Self> {
        ensure((1..=64).contains(&bin), "--bin", bin, "must be in 1..=64")?;
        if let Some(v) = min_s0 {
            ensure(v.is_finite(), "--min-s0", v, "must be a finite number")?;
        }
        if let Some(d) = max_distance {
            let ok = d.is_finite() && d > 0.0;
            ensure(ok, "--max-distance", d, "must be finite and > 0")?;
        }
        ensure(tile > 0, "--tile", tile, "must be at least 1")?;
        Ok(Self {
            bin,
            min_s0,
            max_distance,
            metric,
            tile,
            rule: Rule::Set,
            confidence: polarid_core::classify::DEFAULT_CONFIDENCE,
            errors: MapErrors::default(),
            weights: Weights::Auto,
            bench: Bench::Same,
        })
    }

    /// The decision rule and the set's confidence (in `(0, 1)`; error naming
    /// `--confidence`). The set rule ignores `max_distance` and `metric`.
    pub fn with_rule(mut self, rule: Rule, confidence: f64) -> Result<Self> {
        let ok = confidence > 0.0 && confidence < 1.0;
        ensure(ok, "--confidence", confidence, "must be in (0, 1)")?;
        self.rule = rule;
        self.confidence = confidence;
        Ok(self)
    }

    /// The systematic error model of the set rule; checked as `fit` checks it (errors
    /// naming `--angle-sd-deg`, `--dolp-floor`, `--extinction-ratio`,
    /// `--retardance-deg`).
    pub fn with_errors(mut self, e: MapErrors) -> Result<Self> {
        let bad = |o: &str, v: f64, why: &str| Err(PipelineError::config(o, v, why));
        if !(e.angle_sd_deg.is_finite() && (0.0..90.0).contains(&e.angle_sd_deg)) {
            return bad("--angle-sd-deg", e.angle_sd_deg, "must be in [0, 90)");
        }
        if !(e.dolp_floor.is_finite() && (0.0..1.0).contains(&e.dolp_floor)) {
            return bad("--dolp-floor", e.dolp_floor, "must be in [0, 1)");
        }
        if !(e.extinction_ratio > 1.0) {
            return bad("--extinction-ratio", e.extinction_ratio, "must be > 1");
        }
        if !(e.retardance_deg.is_finite() && (0.0..=90.0).contains(&e.retardance_deg)) {
            return bad("--retardance-deg", e.retardance_deg, "must be in [0, 90]");
        }
        self.errors = e;
        Ok(self)
    }

    /// Whether the per-pixel fits are weighted by the noise model.
    pub fn with_weights(mut self, w: Weights) -> Self {
        self.weights = w;
        self
    }

    /// Where a model's prototypes were measured (docs/CLASSIFY.md "Trained models: the
    /// same bench"): `Same` (the default) compares a pixel's noise covariance with the
    /// prototypes' sample covariance, `Other` both totals. Libraries have no bench.
    pub fn with_bench(mut self, bench: Bench) -> Self {
        self.bench = bench;
        self
    }

    /// The bench of a model's prototypes.
    pub fn bench(&self) -> Bench {
        self.bench
    }

    /// The decision rule.
    pub fn rule(&self) -> Rule {
        self.rule
    }

    /// The binning factor.
    pub fn bin(&self) -> usize {
        self.bin
    }

    /// The metric.
    pub fn metric(&self) -> Metric {
        self.metric
    }
}

/// The maps of [`map_manifest`]: images of `width × height` pixels, row-major.
#[derive(Debug, Clone)]
pub struct MapResult {
    /// Frame width, pixels.
    pub frame_width: usize,
    /// Frame height, pixels.
    pub frame_height: usize,
    /// Binning factor.
    pub bin: usize,
    /// Map width (`frame_width / bin`).
    pub width: usize,
    /// Map height.
    pub height: usize,
    /// Class index: 0 not classified, `i >= 1` is `class_names[i - 1]`.
    pub class: Vec<u16>,
    /// Why a pixel is (not) classified: index into [`REASON_NAMES`].
    pub reason: Vec<u8>,
    /// Class names, sorted (map index `i >= 1` is `class_names[i - 1]`).
    pub class_names: Vec<String>,
    /// Pixel counts per reason and per class index.
    pub counts: MapCounts,
    /// Whether the angles are per pixel (calibrated geometry) rather than per capture
    /// (far field).
    pub calibrated: bool,
    /// β (eq. 5) of every capture, degrees; with calibrated geometry the mean over the
    /// map's pixels that have one (NaN when none has).
    pub beta_deg: Vec<f64>,
    /// Calibrated geometry: the smallest and largest β of every capture over the map's
    /// pixels, degrees (NaN when no pixel has a geometry); empty in the far field.
    pub beta_range_deg: Vec<[f64; 2]>,
    /// Calibrated geometry: β of every map pixel, one image per capture, degrees
    /// (NaN where the pixel has no geometry); empty in the far field. f64 so that
    /// converting back to radians and to f32 gives the fit's own β bit for bit.
    pub beta_maps_deg: Vec<Vec<f64>>,
    /// The dark threshold used for every capture, DN.
    pub min_s0_dn: Vec<f32>,
    /// The maximum distance of the configuration.
    pub max_distance: Option<f64>,
    /// The metric of the configuration.
    pub metric: Metric,
    /// The decision rule.
    pub rule: Rule,
    /// The confidence of the set rule.
    pub confidence: f64,
    /// The systematic error model of the set rule.
    pub errors: MapErrors,
    /// Whether the fits were weighted by the noise model.
    pub weighted: bool,
    /// The noise model estimated on the map (weighted fits only).
    pub noise: Option<NoiseEstimate>,
    /// Per labelled region of the manifest, its pixels per class.
    pub regions: Vec<RegionSummary>,
    /// Seconds spent on the DoLP stage.
    pub seconds_dolp: f64,
    /// Seconds spent fitting and classifying.
    pub seconds_fit: f64,
    /// The manifest's warnings (unknown keys ...).
    pub warnings: Vec<Warning>,
    /// The fit of every band (module `bands`): the one unnamed band of a single-band map
    /// (`n.tif` ...), or one per wavelength, increasing, of a map of colour captures
    /// (`n_450.tif` ...). `class` and `reason` are those of the decision on all bands.
    pub bands: Vec<BandMap>,
}

impl MapResult {
    /// The name of class index `i` (`unknown` for 0).
    pub fn class_name(&self, i: usize) -> &str {
        match i {
            0 => UNKNOWN,
            i => self.class_names.get(i - 1).map_or(UNKNOWN, String::as_str),
        }
    }

    /// Number of classified pixels.
    pub fn classified(&self) -> u64 {
        self.counts.reasons[reason::CLASSIFIED as usize]
    }

    /// The reasons a pixel can have ([`REASON_NAMES`], index = code).
    pub fn reason_names(&self) -> &'static [&'static str] {
        &REASON_NAMES
    }

    /// The map class of `ambiguous` pixels (set rule), if any.
    pub fn ambiguous_class(&self) -> Option<usize> {
        (self.rule == Rule::Set).then_some(self.class_names.len())
    }
}

/// The per-pixel classifier of a model (read from `model_path`) under a configuration.
pub fn pixel_classifier(
    cfg: &MapConfig,
    model: &Model,
    model_path: &Path,
) -> Result<PixelClassifier> {
    let classifier = Classifier::new(model.prototypes(), ClassifierConfig::default())
        .map_err(capture::core_err(model_path))?;
    let pc = PixelClassifier::new(classifier, cfg.max_distance)
        .map_err(capture::core_err(model_path))?;
    Ok(pc.with_mahalanobis(cfg.metric == Metric::Mahalanobis))
}

/// The systematic error model of a manifest's captures under `errors`: a capture's own
/// `angle_sd_deg` (or the manifest's) wins over `errors.angle_sd_deg`.
fn error_model(m: &Manifest, errors: &MapErrors) -> MapErrorModel {
    MapErrorModel {
        polarimetric: Polarimetric {
            dolp_floor: errors.dolp_floor,
            extinction_ratio: errors.extinction_ratio,
            retardance: errors.retardance_deg.to_radians(),
            // The map's O(T) covariance (core map::sets) does not model surface films
            // yet; the table fit does (`--film-sd-nm`, docs/ERRORS.md).
            film_sd_waves: 0.0,
        },
        angle_sd: m
            .captures
            .iter()
            .map(|c| c.angle_sd_deg.unwrap_or(errors.angle_sd_deg).to_radians())
            .collect(),
    }
}

/// Map a loaded manifest with a model (`model_path` names it in errors): DoLP per capture
/// and band, then fit and classify every pixel (see the module documentation). Progress
/// stages: `"captures (DoLP)"` (one step per capture), `"pixels (fit)"` (pixels done;
/// `"pixels (fit, 450 nm)"` per band of a colour map), `"pixels (classify)"`.
pub fn map_manifest(
    cfg: &MapConfig,
    m: &Manifest,
    model: &Model,
    model_path: &Path,
    progress: Progress<'_>,
) -> Result<MapResult> {
    map_manifest_from(
        cfg,
        m,
        MapPrototypes::Model {
            model,
            path: model_path,
        },
        progress,
    )
}

/// [`map_manifest`] against a model, a library or prototypes as given ([`MapPrototypes`]):
/// under the set rule every pixel is decided as `polarid classify` decides a target
/// (module `decide`: a model on the same bench or another, a library by the hypothesis
/// tests against the pixel's rows — single-band captures then need their
/// `wavelength_nm`, else the built-in library's 650 nm is used with a warning). The
/// [`MapResult`] has one [`BandMap`] per band (module `bands`): one for a single-band
/// map, one per wavelength for a manifest with colour captures.
///
/// Errors: a band in fewer than 3 captures, a single-band capture without a wavelength
/// among colour captures ([`IoError::Manifest`] naming `capture[i].wavelength_nm`), the
/// files (sizes, `--bin`), bad prototypes (naming them).
pub fn map_manifest_from(
    cfg: &MapConfig,
    m: &Manifest,
    src: MapPrototypes<'_>,
    progress: Progress<'_>,
) -> Result<MapResult> {
    let mut bands = bands::band_list(m)?;
    // The prototypes and angles are checked before any work.
    let wavelengths: Vec<Option<f64>> = bands.iter().map(|b| b.wavelength()).collect();
    let decision = decide::decision(cfg, src, &wavelengths)?;
    let colour = is_colour(m);
    let answer = answer(cfg, src, &decision, colour)?;
    let calibrated = m.camera.is_some();
    let weighted = decide::weighted(cfg, calibrated, src.tests_rows(cfg));
    let far_betas: Vec<f64> = m
        .captures
        .iter()
        .map(|c| {
            polarid_core::geometry::beta(
                c.theta_i_deg.to_radians(),
                c.theta_r_deg.to_radians(),
                c.phi_deg.to_radians(),
            )
        })
        .collect();
    let plans = bands::fit_plans(&bands, &far_betas, calibrated, &m.path)?;

    let t0 = Instant::now();
    let ncap = m.captures.len() as u64;
    let (d, thresholds) = dolp_stage(cfg, m, &mut bands, weighted, progress)?;
    // Calibrated geometry: β per pixel and capture.
    let beta_maps = if calibrated {
        progress("captures (geometry)", 0, ncap);
        geometry::beta_maps(m, d, cfg.bin, &|i| {
            progress("captures (geometry)", i as u64, ncap)
        })?
    } else {
        geometry::BetaMaps::default()
    };
    let t_dolp = t0.elapsed().as_secs_f64();

    // Stages 2 and 3: every band fitted, every pixel decided.
    let fit = bands::fit_bands_with(
        cfg,
        bands,
        &plans,
        FitGeometry {
            npix: d.out_w * d.out_h,
            far_betas: &far_betas,
            beta: &beta_maps.beta,
            errors: &error_model(m, &cfg.errors),
        },
        &decision,
        answer.as_ref(),
        &m.path,
        progress,
    )?;
    let t_fit = t0.elapsed().as_secs_f64() - t_dolp;
    let mut warnings: Vec<Warning> = m.warnings.iter().map(|w| Warning(w.clone())).collect();
    warnings.extend(fit.warnings);
    let regions = summary::region_summary(m, d, cfg.bin, &fit.class, &fit.class_names);
    let beta_deg: Vec<f64> = if calibrated {
        beta_maps.beta.iter().map(|b| mean_deg(b)).collect()
    } else {
        far_betas.iter().map(|b| b.to_degrees()).collect()
    };
    let (beta_range_deg, beta_maps_deg) = beta_degrees(beta_maps);
    let noise = fit.bands.iter().find_map(|b| b.noise);
    Ok(MapResult {
        frame_width: d.width,
        frame_height: d.height,
        bin: cfg.bin,
        width: d.out_w,
        height: d.out_h,
        class: fit.class,
        reason: fit.reason,
        class_names: fit.class_names,
        counts: fit.counts,
        calibrated,
        beta_deg,
        beta_range_deg,
        beta_maps_deg,
        min_s0_dn: thresholds,
        max_distance: cfg.max_distance,
        metric: cfg.metric,
        rule: cfg.rule,
        confidence: cfg.confidence,
        errors: cfg.errors,
        weighted: noise.is_some(),
        noise,
        regions,
        seconds_dolp: t_dolp,
        seconds_fit: t_fit,
        warnings,
        bands: fit.bands,
    })
}

/// Stage 1 of a map: DoLP per capture and band into `bands` (one capture's frames in
/// memory at a time; a colour mosaic reconstructed once). Calibrated geometry: a lamp at
/// a finite distance moves the specular lobe across the scene, so a pixel is typically
/// lit in some captures and dark in others. Its dark (or saturated) captures are left
/// out of its own fit (DoLP NaN) instead of excluding the pixel ([`BandDolp::push`]);
/// the far-field rule (flagged in any capture: not fitted) is unchanged. Returns the
/// map's size and each capture's S0 threshold.
fn dolp_stage(
    cfg: &MapConfig,
    m: &Manifest,
    bands: &mut [BandDolp],
    weighted: bool,
    progress: Progress<'_>,
) -> Result<(capture::Dims, Vec<f32>)> {
    let calibrated = m.camera.is_some();
    let ncap = m.captures.len() as u64;
    progress("captures (DoLP)", 0, ncap);
    let mut dims = None;
    let mut thresholds = Vec::with_capacity(m.captures.len());
    for (i, c) in m.captures.iter().enumerate() {
        let (th, images) =
            capture::capture_bands(c, cfg, &mut dims, weighted).map_err(|e| match e {
                e @ PipelineError::Config { .. } => e,
                e => PipelineError::Data {
                    path: format!("capture {} (line {})", c.index, c.line),
                    reason: e.to_string(),
                },
            })?;
        for b in images {
            if let Some(j) = bands::band_of(bands, b.wavelength_nm) {
                bands[j].push(calibrated, b.dolp, &b.flags, b.noise);
            }
        }
        thresholds.push(th);
        progress("captures (DoLP)", i as u64 + 1, ncap);
    }
    let Some(d) = dims else {
        return Err(PipelineError::Data {
            path: m.path.display().to_string(),
            reason: "the manifest has no capture".into(),
        });
    };
    bands.iter_mut().for_each(|b| b.finish(calibrated));
    Ok((d, thresholds))
}

/// The classifier that answers in the fit: a single-band map's under `--rule nearest`
/// (`map_manifest_from`, `map_frames`).
fn answer(
    cfg: &MapConfig,
    src: MapPrototypes<'_>,
    decision: &decide::Decision,
    colour: bool,
) -> Result<Option<PixelClassifier>> {
    Ok(match (colour, cfg.rule, src) {
        (false, Rule::Nearest, MapPrototypes::Model { model, path }) => {
            Some(pixel_classifier(cfg, model, path)?)
        }
        (false, Rule::Nearest, _) => Some(nearest_classifier(cfg, decision, &src.label())?),
        _ => None,
    })
}

/// The paper's nearest prototype among the first band of `decision`'s prototypes (a
/// single-band map under `--rule nearest` against a library or given prototypes), with
/// the configuration's maximum distance and metric; errors name `label`.
fn nearest_classifier(
    cfg: &MapConfig,
    decision: &decide::Decision,
    label: &str,
) -> Result<PixelClassifier> {
    let first: Vec<_> = decision
        .profiles
        .iter()
        .filter_map(|p| p.band_prototype(0))
        .collect();
    Classifier::new(first, ClassifierConfig::default())
        .and_then(|c| PixelClassifier::new(c, cfg.max_distance))
        .map(|pc| pc.with_mahalanobis(cfg.metric == Metric::Mahalanobis))
        .map_err(|e| IoError::core(label, e).into())
}

/// `MapResult::beta_range_deg` and `MapResult::beta_maps_deg` of the β maps (radians):
/// each capture's range and every pixel's β, in degrees.
fn beta_degrees(b: geometry::BetaMaps) -> (Vec<[f64; 2]>, Vec<Vec<f64>>) {
    let range = b
        .range
        .iter()
        .map(|r| [r[0].to_degrees(), r[1].to_degrees()])
        .collect();
    let maps = b
        .beta
        .into_iter()
        .map(|m| m.into_iter().map(|v| f64::from(v).to_degrees()).collect())
        .collect();
    (range, maps)
}

/// The mean of the finite values of a β image (radians), degrees (NaN when none).
fn mean_deg(b: &[f32]) -> f64 {
    let (s, n) = b
        .iter()
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), &v| (s + v as f64, n + 1));
    (s / n as f64).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_names_the_option_and_value() {
        let ok = MapConfig::new(2, Some(5.0), Some(0.5), Metric::Mahalanobis, 100).unwrap();
        assert_eq!((ok.bin(), ok.metric()), (2, Metric::Mahalanobis));
        for (r, option, value) in [
            (
                MapConfig::new(0, None, None, Metric::Euclidean, 1),
                "--bin",
                "0",
            ),
            (
                MapConfig::new(65, None, None, Metric::Euclidean, 1),
                "--bin",
                "65",
            ),
            (
                MapConfig::new(1, Some(f64::NAN), None, Metric::Euclidean, 1),
                "--min-s0",
                "NaN",
            ),
            (
                MapConfig::new(1, None, Some(-1.0), Metric::Euclidean, 1),
                "--max-distance",
                "-1",
            ),
            (
                MapConfig::new(1, None, None, Metric::Euclidean, 0),
                "--tile",
                "0",
            ),
        ] {
            match r {
                Err(PipelineError::Config {
                    option: o,
                    value: v,
                    ..
                }) => assert_eq!((o.as_str(), v.as_str()), (option, value)),
                other => panic!("{option}: {other:?}"),
            }
        }
        assert_eq!(parse_metric("euclidean").unwrap(), Metric::Euclidean);
        assert!(parse_metric("cosine").is_err());
    }
}
