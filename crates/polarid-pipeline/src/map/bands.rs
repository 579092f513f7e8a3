//! Per-band maps of colour captures (docs/BANDS.md, "Maps per band").
//!
//! A manifest with colour captures (a `dofp` with `color`) is mapped per band: each
//! colour mosaic is read and reconstructed once per capture into per-band Stokes images
//! (bilinear per lattice, `polarid_core::mosaic::colour`, raw pixel coordinates), whose
//! binned DoLP goes to that band's images; a single-band capture goes to the band of its
//! `wavelength_nm`. Every band is then fitted per pixel as a single-band map is (the
//! same dark and saturation flags, calibrated geometry, noise weights), giving its own
//! `n`, `k`, standard errors and RMS residual ([`BandMap`]). Last, every pixel is
//! decided once on all its bands whose fit is `ok` (module `decide`, the decision of
//! single-band maps too): against a model on the bands it shares with the prototypes,
//! against a library by the hypothesis tests on the pixel's rows of every band.

use std::collections::BTreeSet;
use std::path::Path;
use std::time::Instant;

use polarid_core::classify::{
    AMBIGUOUS, Classifier, ClassifierConfig, MultiPrototype, Prototype, Reject, same_band,
};
use polarid_core::fit::{FitOptions, FitPlan, PixelBetaPlan};
use polarid_core::map::noise::{NoiseAnalyzer, NoiseEstimate, estimate_noise};
use polarid_core::map::sets::MapErrorModel;
use polarid_core::map::{
    self, Betas, MapCounts, MapNoise, MapOutputs, NoiseOut, PixelClassifier, flag, reason,
};
use polarid_core::mosaic::ColourMethod;
use polarid_io::IoError;
use polarid_io::bands::colour_stokes;
use polarid_io::image;
use polarid_io::manifest::{CaptureSource, Manifest};
use polarid_io::measure::rules_for;

use super::capture::{self, Dims, check_dims};
use super::rules::min_s0_for;
use super::{
    MapConfig, MapPrototypes, MapResult, Rule, beta_degrees, decide, error_model, geometry,
    mean_deg, summary,
};
use crate::error::{PipelineError, Result};
use crate::progress::{Progress, Warning};

/// The fit of one band of a colour map: images of the map's size, row-major.
#[derive(Debug, Clone)]
pub struct BandMap {
    /// The band's wavelength, nm.
    pub wavelength_nm: f64,
    /// The captures measured in this band (indices into `Manifest::captures`).
    pub captures: Vec<usize>,
    /// Fitted `n` (NaN where not fitted).
    pub n: Vec<f32>,
    /// Fitted `k`.
    pub k: Vec<f32>,
    /// Standard error of `n`.
    pub n_se: Vec<f32>,
    /// Standard error of `k`.
    pub k_se: Vec<f32>,
    /// RMS DoLP residual of the fit.
    pub rms_residual: Vec<f32>,
    /// Why the band's fit of a pixel is not usable ([`reason`]; `classified`: fitted
    /// with status `ok`, used by the multi-band classification).
    pub reason: Vec<u8>,
    /// Pixels per reason of the band's fit.
    pub reasons: [u64; reason::COUNT],
    /// The noise model estimated on the band (weighted fits only).
    pub noise: Option<NoiseEstimate>,
}

/// The file-name tag of a band: its wavelength in nm, `450` or `632.8` (`n_450.tif`).
pub fn band_tag(wavelength_nm: f64) -> String {
    polarid_io::manifest::colour::wavelength_label(wavelength_nm)
}

pub use super::summary::BAND_IMAGES;

/// The files a map of `m` writes: `single` (the single-band map's files, of which the
/// first five are its fit images `n.tif` ... `rms_residual.tif`) as they are, or for a
/// manifest with colour captures the [`BAND_IMAGES`] of every band instead of the first
/// five.
pub fn output_files(m: &Manifest, single: &[&str]) -> Vec<String> {
    if !is_colour(m) {
        return single.iter().map(|f| f.to_string()).collect();
    }
    let mut bands: Vec<f64> = m
        .captures
        .iter()
        .flat_map(|c| match &c.source {
            CaptureSource::ColourDofp { wavelengths_nm, .. } => wavelengths_nm.clone(),
            _ => c.wavelength_nm.into_iter().collect(),
        })
        .collect();
    bands.sort_by(f64::total_cmp);
    bands.dedup_by(|a, b| same_band(Some(*a), Some(*b)));
    let per_band = bands.iter().flat_map(|&w| {
        BAND_IMAGES
            .iter()
            .map(move |f| format!("{f}_{}.tif", band_tag(w)))
    });
    per_band
        .chain(single.iter().skip(BAND_IMAGES.len()).map(|f| f.to_string()))
        .collect()
}

impl MapResult {
    /// The fit images and their file names: `n.tif`, `k.tif`, `n_se.tif`, `k_se.tif`,
    /// `rms_residual.tif` of a single-band map, or those of every band
    /// (`n_450.tif`, ..., [`BAND_IMAGES`]) of a colour map.
    pub fn fit_images(&self) -> Vec<(String, &[f32])> {
        if self.bands.is_empty() {
            let all = [&self.n, &self.k, &self.n_se, &self.k_se, &self.rms_residual];
            return BAND_IMAGES
                .iter()
                .zip(all)
                .map(|(f, d)| (format!("{f}.tif"), d.as_slice()))
                .collect();
        }
        let mut out = Vec::with_capacity(self.bands.len() * BAND_IMAGES.len());
        for b in &self.bands {
            let all = [&b.n, &b.k, &b.n_se, &b.k_se, &b.rms_residual];
            let tag = band_tag(b.wavelength_nm);
            out.extend(
                BAND_IMAGES
                    .iter()
                    .zip(all)
                    .map(|(f, d)| (format!("{f}_{tag}.tif"), d.as_slice())),
            );
        }
        out
    }
}

/// Whether `m` has a colour capture (its map is then per band).
pub use polarid_io::measure::has_colour as is_colour;

/// One band's binned DoLP images over its captures (stage 1 of a colour map), the input
/// of [`fit_bands`]: built by [`map_manifest_bands`] from the manifest's files, or from
/// frames in memory by the blocks of `polarid.dask.material_map`.
#[derive(Debug, Clone)]
pub struct BandDolp {
    wavelength_nm: f64,
    captures: Vec<usize>,
    dolp: Vec<Vec<f32>>,
    flags: Vec<u8>,
    dropped: Vec<u8>,
    read: Vec<Vec<f32>>,
    shot: Vec<Vec<f32>>,
}

impl BandDolp {
    /// A band at `wavelength_nm` measured in `captures` (indices of the map's captures,
    /// in the order their DoLP images will be pushed).
    pub fn new(wavelength_nm: f64, captures: Vec<usize>) -> Self {
        Self {
            wavelength_nm,
            captures,
            dolp: Vec::new(),
            flags: Vec::new(),
            dropped: Vec::new(),
            read: Vec::new(),
            shot: Vec::new(),
        }
    }

    /// Add one capture's DoLP `d` with its flags `cf` and, for weighted fits, its noise
    /// terms (the far-field rule: a flag in any capture flags the pixel; calibrated
    /// geometry: a dark or saturated capture is left out of the pixel's fit, as in
    /// single-band maps).
    pub fn push(
        &mut self,
        calibrated: bool,
        mut d: Vec<f32>,
        cf: &[u8],
        noise: Option<(Vec<f32>, Vec<f32>)>,
    ) {
        if self.flags.is_empty() {
            self.flags.resize(cf.len(), 0);
            self.dropped.resize(cf.len(), 0);
        }
        if calibrated {
            let drop = flag::DARK | flag::SATURATED;
            for (((f, g), c), v) in self
                .flags
                .iter_mut()
                .zip(self.dropped.iter_mut())
                .zip(cf)
                .zip(d.iter_mut())
            {
                if c & drop != 0 {
                    *v = f32::NAN;
                }
                *g |= c & drop;
                *f |= c & !drop;
            }
        } else {
            for (f, c) in self.flags.iter_mut().zip(cf) {
                *f |= c;
            }
        }
        self.dolp.push(d);
        if let Some((a, b)) = noise {
            self.read.push(a);
            self.shot.push(b);
        }
    }
}

/// The bands of `m`, in increasing wavelength, each with its captures.
fn band_list(m: &Manifest) -> Result<Vec<BandDolp>> {
    let mut per_capture: Vec<Vec<f64>> = Vec::with_capacity(m.captures.len());
    for c in &m.captures {
        per_capture.push(match (&c.source, c.wavelength_nm) {
            (CaptureSource::ColourDofp { wavelengths_nm, .. }, _) => wavelengths_nm.clone(),
            (_, Some(w)) => vec![w],
            (_, None) => {
                return Err(IoError::Manifest {
                    path: m.path.clone(),
                    line: c.line,
                    field: format!("capture[{}].wavelength_nm", c.index),
                    value: String::new(),
                    reason: "a manifest with colour captures is mapped per band: give this \
                             single-band capture its wavelength_nm (or the top-level one)"
                        .into(),
                }
                .into());
            }
        });
    }
    let mut all: Vec<f64> = per_capture.iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    all.dedup_by(|a, b| same_band(Some(*a), Some(*b)));
    let mut out = Vec::with_capacity(all.len());
    for w in all {
        let captures: Vec<usize> = (0..m.captures.len())
            .filter(|&i| per_capture[i].iter().any(|&x| same_band(Some(x), Some(w))))
            .collect();
        if captures.len() < 3 {
            return Err(PipelineError::Data {
                path: m.path.display().to_string(),
                reason: format!(
                    "band {} nm is in {} capture(s); a per-pixel fit needs at least 3",
                    band_tag(w),
                    captures.len()
                ),
            });
        }
        out.push(BandDolp::new(w, captures));
    }
    Ok(out)
}

fn capture_err(c: &polarid_io::manifest::Capture) -> impl Fn(PipelineError) -> PipelineError + '_ {
    move |e| match e {
        e @ PipelineError::Config { .. } => e,
        e => PipelineError::Data {
            path: format!("capture {} (line {})", c.index, c.line),
            reason: e.to_string(),
        },
    }
}

/// Map a manifest with colour captures per band and classify every pixel on all its
/// bands against `profiles` (a multi-band model's or library's prototypes; `label`
/// names them in errors). Progress stages: `"captures (DoLP)"`, `"captures
/// (geometry)"` (calibrated geometry), `"pixels (fit)"` (per band), `"pixels
/// (classify)"`.
///
/// The [`MapResult`] has the class and reason images of the multi-band classification,
/// empty single-band `n`, `k`, `n_se`, `k_se`, `rms_residual`, and one [`BandMap`] per
/// band in `bands`.
///
/// Errors: a single-band capture without a wavelength ([`IoError::Manifest`] naming
/// `capture[i].wavelength_nm`), a band in fewer than 3 captures, the errors of the
/// single-band map (files, sizes, `--bin`), bad prototypes (naming `label`).
pub fn map_manifest_bands(
    cfg: &MapConfig,
    m: &Manifest,
    profiles: &[MultiPrototype],
    label: &str,
    progress: Progress<'_>,
) -> Result<MapResult> {
    map_manifest_bands_from(cfg, m, MapPrototypes::Given { profiles, label }, progress)
}

/// [`map_manifest_bands`] against a model, a library or prototypes as given
/// ([`MapPrototypes`]; the decision of every pixel as `polarid classify` makes it,
/// module `decide`).
pub(super) fn map_manifest_bands_from(
    cfg: &MapConfig,
    m: &Manifest,
    src: MapPrototypes<'_>,
    progress: Progress<'_>,
) -> Result<MapResult> {
    let mut accs = band_list(m)?;
    // The prototypes are checked before any work.
    let wavelengths: Vec<Option<f64>> = accs.iter().map(|a| Some(a.wavelength_nm)).collect();
    let decision = decide::decision(cfg, src, &wavelengths)?;
    let calibrated = m.camera.is_some();
    let weighted = decide::weighted(cfg, calibrated, src.tests_rows(cfg));

    // Stage 1: DoLP per capture and band; a colour mosaic is reconstructed once.
    let t0 = Instant::now();
    let ncap = m.captures.len() as u64;
    progress("captures (DoLP)", 0, ncap);
    let mut dims: Option<Dims> = None;
    let mut thresholds = Vec::with_capacity(m.captures.len());
    let quad = NoiseAnalyzer::quad();
    let band_wl: Vec<f64> = accs.iter().map(|a| a.wavelength_nm).collect();
    let band_of = |w: f64| band_wl.iter().position(|&a| same_band(Some(a), Some(w)));
    for (i, c) in m.captures.iter().enumerate() {
        match &c.source {
            CaptureSource::ColourDofp {
                file,
                pattern,
                wavelengths_nm,
            } => {
                let raw = image::read_frame(file).map_err(|e| capture_err(c)(e.into()))?;
                let d = check_dims(&mut dims, &raw, cfg.bin).map_err(capture_err(c))?;
                let mut rules = rules_for(&raw, c.dark_level, c.saturation);
                let min_s0 = min_s0_for(&rules, raw.kind.is_integer(), cfg.min_s0);
                // The dark test is made on the block mean by stokes_dolp.
                rules.min_s0 = f32::MIN;
                let imgs = colour_stokes(&raw, pattern, &rules, ColourMethod::Bilinear)
                    .map_err(|e| capture_err(c)(e.into()))?;
                drop(raw);
                let npix = d.out_w * d.out_h;
                for (img, &w) in imgs.iter().zip(wavelengths_nm) {
                    let mut dl = vec![0f32; npix];
                    let mut cf = vec![0u8; npix];
                    let mut terms = weighted.then(|| (vec![0f32; npix], vec![0f32; npix]));
                    let nz = terms.as_mut().map(|(a, b)| NoiseOut {
                        analyzer: &quad,
                        scale: 1.0,
                        read: a.as_mut_slice(),
                        shot: b.as_mut_slice(),
                    });
                    map::stokes_dolp_noise(
                        d.width,
                        &img.s0,
                        &img.s1,
                        &img.s2,
                        Some(&img.mask),
                        min_s0,
                        cfg.bin,
                        &mut dl,
                        &mut cf,
                        nz,
                    )
                    .map_err(|e| {
                        capture_err(c)(
                            IoError::Core {
                                path: file.clone(),
                                source: e,
                            }
                            .into(),
                        )
                    })?;
                    if let Some(b) = band_of(w) {
                        accs[b].push(calibrated, dl, &cf, terms);
                    }
                }
                thresholds.push(min_s0);
            }
            _ => {
                let (mut dl, mut cf) = (Vec::new(), Vec::new());
                let (mut ra, mut rb) = (Vec::new(), Vec::new());
                let nz = weighted.then_some((&mut ra, &mut rb));
                let th = capture::capture_dolp(c, cfg, &mut dims, &mut dl, &mut cf, nz)
                    .map_err(capture_err(c))?;
                if let Some(b) = c.wavelength_nm.and_then(band_of) {
                    accs[b].push(calibrated, dl, &cf, weighted.then_some((ra, rb)));
                }
                thresholds.push(th);
            }
        }
        progress("captures (DoLP)", i as u64 + 1, ncap);
    }
    let Some(d) = dims else {
        return Err(PipelineError::Data {
            path: m.path.display().to_string(),
            reason: "the manifest has no capture".into(),
        });
    };
    if calibrated {
        for a in &mut accs {
            for (p, (f, g)) in a.flags.iter_mut().zip(&a.dropped).enumerate() {
                if a.dolp.iter().filter(|d| !d[p].is_nan()).count() < 3 {
                    *f |= g;
                }
            }
        }
    }
    let beta_maps = if calibrated {
        progress("captures (geometry)", 0, ncap);
        geometry::beta_maps(m, d, cfg.bin, &|i| {
            progress("captures (geometry)", i as u64, ncap)
        })?
    } else {
        geometry::BetaMaps::default()
    };
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
    let t_dolp = t0.elapsed().as_secs_f64();

    let fit = fit_bands_with(
        cfg,
        accs,
        FitGeometry {
            npix: d.out_w * d.out_h,
            far_betas: &far_betas,
            beta: &beta_maps.beta,
            errors: &error_model(m, &cfg.errors),
        },
        &decision,
        &m.path,
        progress,
    )?;
    let mut warnings: Vec<Warning> = m.warnings.iter().map(|w| Warning(w.clone())).collect();
    warnings.extend(fit.warnings);
    let (bands, class, why, class_names, counts) = (
        fit.bands,
        fit.class,
        fit.reason,
        fit.class_names,
        fit.counts,
    );
    let t_fit = t0.elapsed().as_secs_f64() - t_dolp;
    let regions = summary::region_summary(m, d, cfg.bin, &class, &class_names);
    let beta_deg: Vec<f64> = if calibrated {
        beta_maps.beta.iter().map(|b| mean_deg(b)).collect()
    } else {
        far_betas.iter().map(|b| b.to_degrees()).collect()
    };
    let (beta_range_deg, beta_maps_deg) = beta_degrees(beta_maps);
    Ok(MapResult {
        frame_width: d.width,
        frame_height: d.height,
        bin: cfg.bin,
        width: d.out_w,
        height: d.out_h,
        n: Vec::new(),
        k: Vec::new(),
        n_se: Vec::new(),
        k_se: Vec::new(),
        rms_residual: Vec::new(),
        class,
        reason: why,
        class_names,
        counts,
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
        weighted: bands.iter().any(|b| b.noise.is_some()),
        noise: bands.iter().find_map(|b| b.noise),
        regions,
        seconds_dolp: t_dolp,
        seconds_fit: t_fit,
        warnings,
        bands,
    })
}

/// The multi-band classifier of a colour map, the class names (sorted) and the map's
/// class names (those, then `ambiguous` under the set rule).
fn bands_classifier(
    cfg: &MapConfig,
    profiles: &[MultiPrototype],
    label: &str,
) -> Result<(Classifier, Vec<String>, Vec<String>)> {
    let ccfg = match cfg.rule {
        Rule::Set => ClassifierConfig::set(cfg.confidence),
        Rule::Nearest => ClassifierConfig {
            metric: cfg.metric,
            reject: cfg.max_distance.map_or(Reject::Never, Reject::MaxDistance),
            ..ClassifierConfig::default()
        },
    };
    let classifier = Classifier::multi(profiles.to_vec(), ccfg).map_err(|e| IoError::Core {
        path: label.into(),
        source: e,
    })?;
    let names: Vec<String> = profiles
        .iter()
        .map(|p| p.class.clone())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let mut class_names = names.clone();
    if cfg.rule == Rule::Set {
        class_names.push(AMBIGUOUS.to_string());
    }
    Ok((classifier, names, class_names))
}

/// The class names of a colour map against `profiles` (`label` names them in errors):
/// their classes sorted, then `ambiguous` under the set rule (class code `i` of the map is
/// name `i - 1`; 0 is not classified).
pub fn band_class_names(
    cfg: &MapConfig,
    profiles: &[MultiPrototype],
    label: &str,
) -> Result<Vec<String>> {
    Ok(bands_classifier(cfg, profiles, label)?.2)
}

/// The angles and error model of [`fit_bands`].
#[derive(Debug, Clone, Copy)]
pub struct FitGeometry<'a> {
    /// Pixels of the map (of every image of [`BandDolp`]).
    pub npix: usize,
    /// β of every capture of the map, radians (far field; unused with `beta`).
    pub far_betas: &'a [f64],
    /// β of every pixel and capture, radians (calibrated geometry; empty: far field).
    pub beta: &'a [Vec<f32>],
    /// The set rule's systematic error model, one angle uncertainty per capture.
    pub errors: &'a MapErrorModel,
}

/// What [`fit_bands`] returns.
#[derive(Debug, Clone)]
pub struct BandsFit {
    /// One fit per band.
    pub bands: Vec<BandMap>,
    /// Class code per pixel (0: not classified; `i`: `class_names[i - 1]`).
    pub class: Vec<u16>,
    /// Reason code per pixel.
    pub reason: Vec<u8>,
    /// The class names (sorted, then `ambiguous` under the set rule).
    pub class_names: Vec<String>,
    /// Pixels per class and reason.
    pub counts: MapCounts,
    /// Bands whose noise model could not be estimated.
    pub warnings: Vec<Warning>,
}

/// Stages 2 and 3 of a colour map on its bands' DoLP images (stage 1,
/// [`BandDolp`]): every band fitted per pixel as a single-band map is, then every pixel
/// classified once on all its bands against `profiles` (module documentation). `path`
/// names the data in errors and warnings, `label` the prototypes. Progress stages:
/// `"pixels (fit, 450 nm)"` per band, `"pixels (classify)"`.
#[allow(clippy::too_many_arguments)]
pub fn fit_bands(
    cfg: &MapConfig,
    accs: Vec<BandDolp>,
    geo: FitGeometry<'_>,
    profiles: &[MultiPrototype],
    label: &str,
    path: &Path,
    progress: Progress<'_>,
) -> Result<BandsFit> {
    let wavelengths: Vec<Option<f64>> = accs.iter().map(|a| Some(a.wavelength_nm)).collect();
    let decision = decide::decision(cfg, MapPrototypes::Given { profiles, label }, &wavelengths)?;
    fit_bands_with(cfg, accs, geo, &decision, path, progress)
}

/// [`fit_bands`] with the map's decision.
fn fit_bands_with(
    cfg: &MapConfig,
    accs: Vec<BandDolp>,
    geo: FitGeometry<'_>,
    decision: &decide::Decision,
    path: &Path,
    progress: Progress<'_>,
) -> Result<BandsFit> {
    // Stage 2: every band fitted per pixel as a single-band map.
    let npix = geo.npix;
    let calibrated = !geo.beta.is_empty();
    let tests_rows = matches!(decision.decider, decide::Decider::Hypothesis { .. });
    let weighted = decide::weighted(cfg, calibrated, tests_rows);
    let proto_err = |e| IoError::Core {
        path: path.to_path_buf(),
        source: e,
    };
    let core_err = |e| IoError::Core {
        path: path.to_path_buf(),
        source: e,
    };
    let profiles = &decision.profiles;
    let options = FitOptions::default();
    let k_can_be_zero = options.bounds.k_min == 0.0;
    let mut warnings: Vec<Warning> = decision.warnings.clone();
    let mut bands: Vec<BandMap> = Vec::with_capacity(accs.len());
    let mut corrs: Vec<Vec<f32>> = Vec::with_capacity(accs.len());
    let mut plans: Vec<Option<FitPlan>> = Vec::with_capacity(accs.len());
    let pixel_plan = PixelBetaPlan::new(options).map_err(core_err)?;
    let all_first: Vec<Prototype> = profiles
        .iter()
        .filter_map(|p| p.band_prototype(0))
        .collect();
    for a in &accs {
        let plan = if calibrated {
            None
        } else {
            let b: Vec<f64> = a.captures.iter().map(|&i| geo.far_betas[i]).collect();
            Some(FitPlan::new(&b, options).map_err(core_err)?)
        };
        let beta_views: Vec<&[f32]> = a
            .captures
            .iter()
            .filter_map(|&i| geo.beta.get(i).map(Vec::as_slice))
            .collect();
        let betas = match &plan {
            Some(p) => Betas::Shared(p),
            None => Betas::PerPixel {
                plan: &pixel_plan,
                beta: &beta_views,
            },
        };
        // The fit of a band needs a classifier; its per-band answer is not used.
        let mut protos: Vec<Prototype> = profiles
            .iter()
            .flat_map(|p| {
                p.bands
                    .iter()
                    .enumerate()
                    .filter(|(_, b)| same_band(b.wavelength_nm, Some(a.wavelength_nm)))
                    .filter_map(|(i, _)| p.band_prototype(i))
            })
            .collect();
        if protos.is_empty() {
            protos = all_first.clone();
        }
        let pc = Classifier::new(protos, ClassifierConfig::default())
            .and_then(|c| PixelClassifier::new(c, None))
            .map_err(proto_err)?;
        let img = || vec![0f32; npix];
        let (mut n, mut k, mut n_se, mut k_se, mut rms) = (img(), img(), img(), img(), img());
        let mut class = vec![0u16; npix];
        let mut why = vec![0u8; npix];
        let views: Vec<&[f32]> = a.dolp.iter().map(Vec::as_slice).collect();
        let rv: Vec<&[f32]> = a.read.iter().map(Vec::as_slice).collect();
        let sv: Vec<&[f32]> = a.shot.iter().map(Vec::as_slice).collect();
        let noise = if weighted {
            let e = estimate_noise(betas, &views, &rv, &sv, &a.flags).map_err(core_err)?;
            if e.is_none() {
                warnings.push(Warning(format!(
                    "{}: band {} nm: too few usable pixels to estimate the noise model; the \
                     per-pixel fits are unweighted",
                    path.display(),
                    band_tag(a.wavelength_nm)
                )));
            }
            e
        } else {
            None
        };
        let map_noise = noise.map(|e| MapNoise {
            model: e.model,
            read: &rv,
            shot: &sv,
        });
        let stage = format!("pixels (fit, {} nm)", band_tag(a.wavelength_nm));
        let report = |done: usize| progress(&stage, done as u64, npix as u64);
        let mut corr = vec![f32::NAN; npix];
        let counts: MapCounts = map::fit_and_classify_corr(
            betas,
            &pc,
            &views,
            map_noise,
            &a.flags,
            cfg.tile,
            MapOutputs {
                n: &mut n,
                k: &mut k,
                n_se: &mut n_se,
                k_se: &mut k_se,
                rms_residual: &mut rms,
                class: &mut class,
                reason: &mut why,
            },
            &mut corr,
            &report,
        )
        .map_err(core_err)?;
        corrs.push(corr);
        bands.push(BandMap {
            wavelength_nm: a.wavelength_nm,
            captures: a.captures.clone(),
            n,
            k,
            n_se,
            k_se,
            rms_residual: rms,
            reason: why,
            reasons: counts.reasons,
            noise,
        });
        plans.push(plan);
    }

    // Stage 3: every pixel decided once on all its bands (module `decide`).
    progress("pixels (classify)", 0, npix as u64);
    let views: Vec<Vec<&[f32]>> = accs
        .iter()
        .map(|a| a.dolp.iter().map(Vec::as_slice).collect())
        .collect();
    let reads: Vec<Vec<&[f32]>> = accs
        .iter()
        .map(|a| a.read.iter().map(Vec::as_slice).collect())
        .collect();
    let shots: Vec<Vec<&[f32]>> = accs
        .iter()
        .map(|a| a.shot.iter().map(Vec::as_slice).collect())
        .collect();
    let beta_views: Vec<Vec<&[f32]>> = accs
        .iter()
        .map(|a| {
            a.captures
                .iter()
                .filter_map(|&i| geo.beta.get(i).map(Vec::as_slice))
                .collect()
        })
        .collect();
    let inputs: Vec<decide::BandInput<'_>> = bands
        .iter()
        .enumerate()
        .map(|(bi, b)| decide::BandInput {
            wavelength_nm: Some(b.wavelength_nm),
            reason: &b.reason,
            n: &b.n,
            k: &b.k,
            n_se: &b.n_se,
            k_se: &b.k_se,
            nk_corr: &corrs[bi],
            rms: &b.rms_residual,
            dolp: &views[bi],
            captures: &accs[bi].captures,
            betas: match &plans[bi] {
                Some(plan) => decide::BandBetas::Shared(plan.betas()),
                None => decide::BandBetas::PerPixel(&beta_views[bi]),
            },
            noise: b.noise.map(|e| (e.model, &reads[bi][..], &shots[bi][..])),
        })
        .collect();
    let (class, why, counts) =
        decide::decide_pixels(decision, &inputs, geo.errors, k_can_be_zero, npix);
    progress("pixels (classify)", npix as u64, npix as u64);
    drop(inputs);
    Ok(BandsFit {
        bands,
        class,
        reason: why,
        class_names: decision.class_names.clone(),
        counts,
        warnings,
    })
}
