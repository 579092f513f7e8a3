//! The bands of a map (docs/BANDS.md, "Maps per band"): a single-band map is one band
//! (its wavelength the captures' `wavelength_nm` when they share one, and unnamed: its
//! images are `n.tif` ...), a manifest with colour captures one band per wavelength
//! (named by it: `n_450.tif` ...). Stage 1 puts every capture's DoLP per band into its
//! band ([`BandDolp`]; a colour mosaic is reconstructed once per capture, bilinear per
//! lattice, `polarid_core::mosaic::colour`, raw pixel coordinates; a single-band capture
//! goes to the band of its `wavelength_nm`). Every band is then fitted per pixel (the
//! same dark and saturation flags, calibrated geometry, noise weights), giving its own
//! `n`, `k`, standard errors and RMS residual ([`BandMap`]). Last, every pixel is
//! decided once on all its bands whose fit is `ok` (module `decide`): against a model on
//! the bands it shares with the prototypes, against a library by the hypothesis tests
//! on the pixel's rows of every band. A single-band map under `--rule nearest` answers
//! in the fit instead (the paper's nearest prototype, `polarid_core::map`).

use std::path::Path;

use polarid_core::classify::{Classifier, ClassifierConfig, MultiPrototype, Prototype, same_band};
use polarid_core::fit::{FitOptions, FitPlan, PixelBetaPlan};
use polarid_core::map::noise::{NoiseEstimate, NoiseModel, estimate_noise};
use polarid_core::map::sets::MapErrorModel;
use polarid_core::map::{
    self, Betas, MapCounts, MapNoise, MapOutputs, PixelClassifier, flag, reason,
};
use polarid_io::IoError;
use polarid_io::manifest::{Capture, CaptureSource, Manifest};

use super::capture::core_err;
use super::{MapConfig, MapPrototypes, MapResult, decide};
use crate::error::{PipelineError, Result};
use crate::progress::{Progress, Warning};

/// The fit of one band of a map: images of the map's size, row-major.
#[derive(Debug, Clone)]
pub struct BandMap {
    /// The band's wavelength, nm (NaN for a single-band map whose captures give none).
    pub wavelength_nm: f64,
    /// The band's file-name tag (`450`: `n_450.tif` ...); `None` for the one band of a
    /// single-band map (`n.tif` ...).
    pub tag: Option<String>,
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

/// The fit images of every band, written as `{name}.tif` for a single-band map and
/// `{name}_{tag}.tif` ([`band_tag`]) per band of a colour map: `n_450.tif`, ...
pub const BAND_IMAGES: [&str; 5] = ["n", "k", "n_se", "k_se", "rms_residual"];

/// The files a map of `m` writes: the fit images ([`BAND_IMAGES`]: `n.tif` ... of a
/// single-band map, or `n_450.tif` ... of every band of a manifest with colour captures),
/// then `others` (the map's other files).
pub fn output_files(m: &Manifest, others: &[&str]) -> Vec<String> {
    let tags = if is_colour(m) {
        let per_capture: Vec<Vec<f64>> = m.captures.iter().map(capture_wavelengths).collect();
        wavelengths(&per_capture)
            .into_iter()
            .map(|w| Some(band_tag(w)))
            .collect()
    } else {
        vec![None]
    };
    tags.into_iter()
        .flat_map(image_files)
        .chain(others.iter().map(|f| f.to_string()))
        .collect()
}

/// The fit images' file names of a band: `n.tif` ... ([`BAND_IMAGES`]) for the unnamed
/// band of a single-band map, `n_450.tif` ... for a band tagged `450`.
pub(super) fn image_files(tag: Option<String>) -> impl Iterator<Item = String> {
    let tag = tag.map_or(String::new(), |t| format!("_{t}"));
    BAND_IMAGES.iter().map(move |f| format!("{f}{tag}.tif"))
}

/// The wavelengths capture `c` is measured in: a colour capture's bands, else its own
/// `wavelength_nm` if any.
fn capture_wavelengths(c: &Capture) -> Vec<f64> {
    match &c.source {
        CaptureSource::ColourDofp { wavelengths_nm, .. } => wavelengths_nm.clone(),
        _ => c.wavelength_nm.into_iter().collect(),
    }
}

/// The bands of captures measured in `per_capture`: their wavelengths, increasing, one
/// per band.
fn wavelengths(per_capture: &[Vec<f64>]) -> Vec<f64> {
    let mut all: Vec<f64> = per_capture.iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    all.dedup_by(|a, b| same_band(Some(*a), Some(*b)));
    all
}

impl MapResult {
    /// The fit images and their file names: `n.tif`, `k.tif`, `n_se.tif`, `k_se.tif`,
    /// `rms_residual.tif` of a single-band map, or those of every band
    /// (`n_450.tif`, ..., [`BAND_IMAGES`]) of a colour map.
    pub fn fit_images(&self) -> Vec<(String, &[f32])> {
        self.bands
            .iter()
            .flat_map(|b| {
                let all = [&b.n, &b.k, &b.n_se, &b.k_se, &b.rms_residual];
                image_files(b.tag.clone()).zip(all.map(Vec::as_slice))
            })
            .collect()
    }

    /// Whether the map is per band of colour captures (its bands named by wavelength).
    pub fn is_colour(&self) -> bool {
        self.bands.iter().any(|b| b.tag.is_some())
    }
}

/// Whether `m` has a colour capture (its map is then per band).
pub use polarid_io::measure::has_colour as is_colour;

/// One band's binned DoLP images over its captures (stage 1 of a map), the input of
/// [`fit_bands`]: built by [`super::map_manifest_from`] from the manifest's files, or
/// from frames in memory by the blocks of `polarid.dask.material_map`.
#[derive(Debug, Clone, Default)]
pub struct BandDolp {
    wavelength_nm: Option<f64>,
    /// Named by its wavelength in file names, progress and messages (a colour map's
    /// bands; not the one band of a single-band map).
    named: bool,
    captures: Vec<usize>,
    dolp: Vec<Vec<f32>>,
    flags: Vec<u8>,
    dropped: Vec<u8>,
    read: Vec<Vec<f32>>,
    shot: Vec<Vec<f32>>,
    /// The map's noise model of the band, given (a block of a map, `frames`) instead of
    /// estimated (`Some(None)`: none, unweighted fits).
    noise_model: Option<Option<NoiseModel>>,
}

impl BandDolp {
    /// A band at `wavelength_nm` measured in `captures` (indices of the map's captures,
    /// in the order their DoLP images will be pushed).
    pub fn new(wavelength_nm: f64, captures: Vec<usize>) -> Self {
        Self {
            named: true,
            ..Self::unnamed(Some(wavelength_nm), captures)
        }
    }

    /// The band's wavelength, nm (`None`: a single-band map's captures give none).
    pub fn wavelength(&self) -> Option<f64> {
        self.wavelength_nm
    }

    /// The one band of a single-band map (its wavelength, if the captures give one).
    pub(crate) fn unnamed(wavelength_nm: Option<f64>, captures: Vec<usize>) -> Self {
        Self {
            wavelength_nm,
            captures,
            ..Self::default()
        }
    }

    /// Weight the band's fits by `m` (the map's noise model of the band; `None`:
    /// unweighted) instead of estimating one.
    pub(crate) fn set_noise_model(&mut self, m: Option<NoiseModel>) {
        self.noise_model = Some(m);
    }

    /// The band's images: every capture's DoLP (NaN: left out of the pixel's fit), the
    /// flags of every pixel, and (weighted fits) every capture's noise terms `(A, B)`.
    pub fn images(&self) -> (&[Vec<f32>], &[u8], &[Vec<f32>], &[Vec<f32>]) {
        (&self.dolp, &self.flags, &self.read, &self.shot)
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

    /// After the last capture (calibrated geometry): a pixel left with fewer than 3
    /// usable captures is not fitted, with the reason (dark, saturated) of its drops.
    pub(crate) fn finish(&mut self, calibrated: bool) {
        if !calibrated {
            return;
        }
        for (p, (f, g)) in self.flags.iter_mut().zip(&self.dropped).enumerate() {
            if self.dolp.iter().filter(|d| !d[p].is_nan()).count() < 3 {
                *f |= g;
            }
        }
    }

    /// The band's tag in file names and messages (`450`; `None` for an unnamed band).
    fn tag(&self) -> Option<String> {
        self.wavelength_nm.filter(|_| self.named).map(band_tag)
    }
}

/// The bands of `m`: one unnamed band of all captures for a single-band manifest (its
/// wavelength their common `wavelength_nm`, if any), else one per wavelength in
/// increasing order, each with its captures. Errors: a band in fewer than 3 captures
/// (a per-pixel fit needs 3), a single-band capture without a wavelength among colour
/// captures.
pub(crate) fn band_list(m: &Manifest) -> Result<Vec<BandDolp>> {
    if !is_colour(m) {
        if m.captures.len() < 3 {
            let source = polarid_core::CoreError::TooFew {
                what: "DoLP measurements (source positions)",
                needed: 3,
                got: m.captures.len(),
            };
            return Err(IoError::core(&m.path, source).into());
        }
        let captures = (0..m.captures.len()).collect();
        return Ok(vec![BandDolp::unnamed(mono_wavelength(m), captures)]);
    }
    let mut per_capture: Vec<Vec<f64>> = Vec::with_capacity(m.captures.len());
    for c in &m.captures {
        per_capture.push(match (&c.source, c.wavelength_nm) {
            (CaptureSource::ColourDofp { .. }, _) | (_, Some(_)) => capture_wavelengths(c),
            (_, None) => {
                return Err(c
                    .field_error(
                        &m.path,
                        "wavelength_nm",
                        "",
                        "a manifest with colour captures is mapped per band: give this \
                             single-band capture its wavelength_nm (or the top-level one)",
                    )
                    .into());
            }
        });
    }
    let all = wavelengths(&per_capture);
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

/// The wavelength of a single-band map: the captures' `wavelength_nm` when they all
/// have the same one.
fn mono_wavelength(m: &Manifest) -> Option<f64> {
    let first = m.captures.first()?.wavelength_nm?;
    m.captures
        .iter()
        .all(|c| same_band(c.wavelength_nm, Some(first)))
        .then_some(first)
}

/// The index of the band of a capture's band image at `wavelength_nm` (always the one
/// band of a single-band map; `None`: a band the map does not have).
pub(crate) fn band_of(bands: &[BandDolp], wavelength_nm: Option<f64>) -> Option<usize> {
    match bands {
        [b] if !b.named => Some(0),
        _ => bands
            .iter()
            .position(|b| same_band(b.wavelength_nm, wavelength_nm)),
    }
}

/// The far-field fit plan of every band (one β per capture, `far_betas`, radians); none
/// with calibrated geometry (a β per pixel). Errors name `path`.
pub(crate) fn fit_plans(
    bands: &[BandDolp],
    far_betas: &[f64],
    calibrated: bool,
    path: &Path,
) -> Result<Vec<Option<FitPlan>>> {
    bands
        .iter()
        .map(|a| {
            if calibrated {
                return Ok(None);
            }
            let b: Vec<f64> = a.captures.iter().map(|&i| far_betas[i]).collect();
            FitPlan::new(&b, FitOptions::default())
                .map(Some)
                .map_err(|e| IoError::core(path, e).into())
        })
        .collect()
}

/// The class names of a colour map against `profiles` (`label` names them in errors):
/// their classes sorted, then `ambiguous` under the set rule (class code `i` of the map is
/// name `i - 1`; 0 is not classified).
pub fn band_class_names(
    cfg: &MapConfig,
    profiles: &[MultiPrototype],
    label: &str,
) -> Result<Vec<String>> {
    let src = MapPrototypes::Given { profiles, label };
    Ok(decide::decision(cfg, src, &[])?.class_names)
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
pub fn fit_bands(
    cfg: &MapConfig,
    accs: Vec<BandDolp>,
    geo: FitGeometry<'_>,
    profiles: &[MultiPrototype],
    label: &str,
    path: &Path,
    progress: Progress<'_>,
) -> Result<BandsFit> {
    let wavelengths: Vec<Option<f64>> = accs.iter().map(|a| a.wavelength_nm).collect();
    let decision = decide::decision(cfg, MapPrototypes::Given { profiles, label }, &wavelengths)?;
    let plans = fit_plans(&accs, geo.far_betas, !geo.beta.is_empty(), path)?;
    fit_bands_with(cfg, accs, &plans, geo, &decision, None, path, progress)
}

/// What the per-pixel fit of every band shares (stage 2 of [`fit_bands_with`]).
struct BandFitter<'a> {
    cfg: &'a MapConfig,
    geo: FitGeometry<'a>,
    /// The prototypes of the decision.
    profiles: &'a [MultiPrototype],
    /// Every prototype's first band: a band's classifier when no prototype has it.
    all_first: Vec<Prototype>,
    /// The classifier that answers in the fit (`--rule nearest`, single band).
    answer: Option<&'a PixelClassifier>,
    pixel_plan: PixelBetaPlan,
    /// Whether the fits are weighted by a noise model.
    weighted: bool,
    path: &'a Path,
    progress: Progress<'a>,
}

/// One band fitted: its images, its fit's correlation of `n` and `k` per pixel (empty
/// when the fit answers), its class per pixel and counts.
struct BandFitted {
    band: BandMap,
    corr: Vec<f32>,
    class: Vec<u16>,
    counts: MapCounts,
}

impl BandFitter<'_> {
    /// The classifier a band's fit needs (its per-band answer is used only as
    /// `answer`): the prototypes' bands at its wavelength, else their first bands.
    fn band_classifier(&self, a: &BandDolp) -> Result<PixelClassifier> {
        let mut protos: Vec<Prototype> = self
            .profiles
            .iter()
            .flat_map(|p| {
                p.bands
                    .iter()
                    .enumerate()
                    .filter(|(_, b)| same_band(b.wavelength_nm, a.wavelength_nm))
                    .filter_map(|(i, _)| p.band_prototype(i))
            })
            .collect();
        if protos.is_empty() {
            protos = self.all_first.clone();
        }
        Ok(Classifier::new(protos, ClassifierConfig::default())
            .and_then(|c| PixelClassifier::new(c, None))
            .map_err(core_err(self.path))?)
    }

    /// The band's noise model: given, or estimated for weighted fits (a warning when
    /// too few pixels are usable), else none.
    fn band_noise(
        &self,
        a: &BandDolp,
        betas: Betas<'_>,
        views: &[&[f32]],
        (rv, sv): (&[&[f32]], &[&[f32]]),
        warnings: &mut Vec<Warning>,
    ) -> Result<Option<NoiseEstimate>> {
        if let Some(given) = a.noise_model {
            return Ok(given.map(|model| NoiseEstimate {
                model,
                pixels: 0,
                outliers: 0,
                reduced_chi2: f64::NAN,
            }));
        }
        if !self.weighted {
            return Ok(None);
        }
        let e = estimate_noise(betas, views, rv, sv, &a.flags).map_err(core_err(self.path))?;
        if e.is_none() {
            warnings.push(Warning(format!(
                "{}: {}too few usable pixels to estimate the noise model; the per-pixel \
                 fits are unweighted",
                self.path.display(),
                a.tag().map_or(String::new(), |t| format!("band {t} nm: "))
            )));
        }
        Ok(e)
    }

    /// Band `a` fitted per pixel (with its far-field `plan`; `None`: a β per pixel).
    fn fit(
        &self,
        a: &BandDolp,
        plan: Option<&FitPlan>,
        warnings: &mut Vec<Warning>,
    ) -> Result<BandFitted> {
        let npix = self.geo.npix;
        let beta_views = band_betas(a, self.geo.beta);
        let betas = match plan {
            Some(p) => Betas::Shared(p),
            None => Betas::PerPixel {
                plan: &self.pixel_plan,
                beta: &beta_views,
            },
        };
        let own;
        let pc = match self.answer {
            Some(pc) => pc,
            None => {
                own = self.band_classifier(a)?;
                &own
            }
        };
        let img = || vec![0f32; npix];
        let (mut n, mut k, mut n_se, mut k_se, mut rms) = (img(), img(), img(), img(), img());
        let mut class = vec![0u16; npix];
        let mut why = vec![0u8; npix];
        let (views, rv, sv) = (slices(&a.dolp), slices(&a.read), slices(&a.shot));
        let noise = self.band_noise(a, betas, &views, (&rv, &sv), warnings)?;
        let map_noise = noise.map(|e| MapNoise {
            model: e.model,
            read: &rv,
            shot: &sv,
        });
        let stage = a.tag().map_or("pixels (fit)".to_string(), |t| {
            format!("pixels (fit, {t} nm)")
        });
        let report = |done: usize| (self.progress)(&stage, done as u64, npix as u64);
        // The fit's correlation of n and k, for the decision after the fit.
        let mut corr = if self.answer.is_none() {
            vec![f32::NAN; npix]
        } else {
            Vec::new()
        };
        let counts: MapCounts = map::fit_and_classify_corr(
            betas,
            pc,
            &views,
            map_noise,
            &a.flags,
            self.cfg.tile,
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
        .map_err(core_err(self.path))?;
        let band = BandMap {
            wavelength_nm: a.wavelength_nm.unwrap_or(f64::NAN),
            tag: a.tag(),
            captures: a.captures.clone(),
            n,
            k,
            n_se,
            k_se,
            rms_residual: rms,
            reason: why,
            reasons: counts.reasons,
            noise,
        };
        Ok(BandFitted {
            band,
            corr,
            class,
            counts,
        })
    }
}

/// Every image of `v` as a slice.
pub(super) fn slices(v: &[Vec<f32>]) -> Vec<&[f32]> {
    v.iter().map(Vec::as_slice).collect()
}

/// β of every pixel of band `a`'s captures (calibrated geometry; empty: far field).
fn band_betas<'a>(a: &BandDolp, beta: &'a [Vec<f32>]) -> Vec<&'a [f32]> {
    a.captures
        .iter()
        .filter_map(|&i| beta.get(i).map(Vec::as_slice))
        .collect()
}

/// [`fit_bands`] with the map's decision and the bands' far-field plans ([`fit_plans`]).
/// With `answer` (a single-band map under `--rule nearest`) the band's fit answers with
/// that classifier and no pixel is decided after the fit.
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_bands_with(
    cfg: &MapConfig,
    accs: Vec<BandDolp>,
    plans: &[Option<FitPlan>],
    geo: FitGeometry<'_>,
    decision: &decide::Decision,
    answer: Option<&PixelClassifier>,
    path: &Path,
    progress: Progress<'_>,
) -> Result<BandsFit> {
    // Stage 2: every band fitted per pixel.
    let calibrated = !geo.beta.is_empty();
    let tests_rows = matches!(decision.decider, decide::Decider::Hypothesis { .. });
    let options = FitOptions::default();
    let fitter = BandFitter {
        cfg,
        geo,
        profiles: &decision.profiles,
        all_first: decision
            .profiles
            .iter()
            .filter_map(|p| p.band_prototype(0))
            .collect(),
        answer,
        pixel_plan: PixelBetaPlan::new(options).map_err(core_err(path))?,
        weighted: decide::weighted(cfg, calibrated, tests_rows),
        path,
        progress,
    };
    let mut warnings: Vec<Warning> = decision.warnings.clone();
    let mut bands: Vec<BandMap> = Vec::with_capacity(accs.len());
    let mut corrs: Vec<Vec<f32>> = Vec::with_capacity(accs.len());
    let mut answered = None;
    for (a, plan) in accs.iter().zip(plans) {
        let f = fitter.fit(a, plan.as_ref(), &mut warnings)?;
        corrs.push(f.corr);
        bands.push(f.band);
        if answer.is_some() {
            answered = Some((f.class, f.counts));
        }
    }
    if let (Some(pc), Some((class, counts))) = (answer, answered) {
        return Ok(BandsFit {
            reason: bands[0].reason.clone(),
            bands,
            class,
            class_names: pc.names().to_vec(),
            counts,
            warnings,
        });
    }

    // Stage 3: every pixel decided once on all its bands (module `decide`).
    let npix = geo.npix;
    progress("pixels (classify)", 0, npix as u64);
    let k_can_be_zero = options.bounds.k_min == 0.0;
    let (class, why, counts) =
        decide_bands(decision, &accs, &bands, &corrs, plans, geo, k_can_be_zero);
    progress("pixels (classify)", npix as u64, npix as u64);
    Ok(BandsFit {
        bands,
        class,
        reason: why,
        class_names: decision.class_names.clone(),
        counts,
        warnings,
    })
}

/// Stage 3 of a map: every pixel decided once on all its bands' fits (module `decide`).
fn decide_bands(
    decision: &decide::Decision,
    accs: &[BandDolp],
    bands: &[BandMap],
    corrs: &[Vec<f32>],
    plans: &[Option<FitPlan>],
    geo: FitGeometry<'_>,
    k_can_be_zero: bool,
) -> (Vec<u16>, Vec<u8>, MapCounts) {
    let views: Vec<Vec<&[f32]>> = accs.iter().map(|a| slices(&a.dolp)).collect();
    let reads: Vec<Vec<&[f32]>> = accs.iter().map(|a| slices(&a.read)).collect();
    let shots: Vec<Vec<&[f32]>> = accs.iter().map(|a| slices(&a.shot)).collect();
    let beta_views: Vec<Vec<&[f32]>> = accs.iter().map(|a| band_betas(a, geo.beta)).collect();
    let inputs: Vec<decide::BandInput<'_>> = bands
        .iter()
        .enumerate()
        .map(|(bi, b)| decide::BandInput {
            wavelength_nm: accs[bi].wavelength_nm,
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
    decide::decide_pixels(decision, &inputs, geo.errors, k_can_be_zero, geo.npix)
}
