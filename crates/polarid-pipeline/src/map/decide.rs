//! The decision of every map pixel, the same for single-band and colour maps: after the
//! fit of every band, each pixel is decided once on its bands whose fit is `ok`, as
//! `polarid classify` decides a target (docs/CLASSIFY.md):
//!
//! - **a trained model** (`--model`), set rule: on the same bench (the default,
//!   `--bench same`) the pixel's noise covariance (its fit's `n_se`, `k_se`, `nk_corr`)
//!   against each prototype's sample covariance (the prototypes `classify` takes,
//!   [`prototypes_for`](crate::classify::prototypes_for), from the model in memory); on
//!   another bench
//!   (`--bench other`, or a model without sample covariances) the pixel's total
//!   covariance (noise plus the systematic error model, `polarid_core::map::sets`)
//!   against the prototypes' total ([`SetDecider`]);
//! - **a library** (`--library`), set rule: each material as it is found tested against
//!   the pixel's own rows — its β, DoLP and DoLP standard error per capture, the
//!   error model's DoLP floor and angle uncertainty ([`HypothesisDecider`],
//!   `polarid_core::classify::classify_rows`);
//! - `--rule nearest`: the paper's nearest prototype (colour maps here; single-band maps
//!   answer it in the fit, `polarid_core::map::fit_and_classify`).
//!
//! A band whose total one-sigma interval on `n` reaches 0 (set rule against
//! prototypes) is not placed by the data and says nothing; a pixel with no other band
//! is `ambiguous` (`polarid_core::map::sets`).

use std::path::Path;

use polarid_core::classify::pixel_decision::{
    HypothesisDecider, PixelAnswer, PixelBand, SetDecider, fit_covariance,
};
use polarid_core::classify::{
    AMBIGUOUS, Bench, Classifier, ClassifierConfig, Estimate, EstimateBand, HypRow, MultiEstimate,
    MultiPrototype, Nuisances, Reject, Status,
};
use polarid_core::fit::FitStatus;
use polarid_core::map::noise::NoiseModel;
use polarid_core::map::sets::{CovScratch, MapErrorModel, PixelRow, total_covariance};
use polarid_core::map::{MapCounts, reason};
use polarid_io::IoError;
use polarid_io::model::Model;
use rayon::prelude::*;

use super::{MapConfig, Rule};
use crate::classify::bench::no_sample_covariances;
use crate::classify::{PrototypeSource, same_bench};
use crate::error::{PipelineError, Result};
use crate::progress::Warning;

/// Where a map's prototypes come from.
#[derive(Debug, Clone, Copy)]
pub enum MapPrototypes<'a> {
    /// A trained model (`path` names it in messages).
    Model {
        /// The model.
        model: &'a Model,
        /// Its file.
        path: &'a Path,
    },
    /// A material library (`builtin`, `builtin-rgb`, a library CSV).
    Library(&'a str),
    /// Prototypes as given (`label` names them): the set rule with the pixels' total
    /// covariance.
    Given {
        /// The prototypes.
        profiles: &'a [MultiPrototype],
        /// Their name in messages.
        label: &'a str,
    },
}

impl MapPrototypes<'_> {
    /// The name of the prototypes in messages (`model.json`, `library builtin`).
    pub fn label(&self) -> String {
        match self {
            MapPrototypes::Model { path, .. } => path.display().to_string(),
            MapPrototypes::Library(spec) => format!("library {spec}"),
            MapPrototypes::Given { label, .. } => label.to_string(),
        }
    }

    /// Whether the pixels are tested against their rows (a library under the set rule).
    /// A catalogue shipped with polarid (an open world), not the user's own list.
    pub(super) fn is_catalogue(&self) -> bool {
        matches!(self, MapPrototypes::Library(s) if polarid_io::library::BUILTIN_NAMES.contains(s))
    }

    pub(super) fn tests_rows(&self, cfg: &MapConfig) -> bool {
        matches!(self, MapPrototypes::Library(_)) && cfg.rule == Rule::Set
    }
}

/// How the pixels are decided.
#[derive(Debug, Clone)]
pub(crate) enum Decider {
    /// The paper's nearest prototype (with the pixel's noise covariance for the
    /// Mahalanobis metric).
    Nearest(Classifier),
    /// The set rule against prototypes; `noise`: on the pixel's noise covariance (same
    /// bench), else on its total.
    Set { decider: SetDecider, noise: bool },
    /// The hypothesis tests against the pixel's rows, with the DoLP floor of every row.
    Hypothesis {
        decider: HypothesisDecider,
        floor: f64,
    },
}

/// A map's decision and its class names (sorted, then `ambiguous` under the set rule).
#[derive(Debug, Clone)]
pub(crate) struct Decision {
    pub decider: Decider,
    pub class_names: Vec<String>,
    /// The prototypes (at the bands' wavelengths for a library).
    pub profiles: Vec<MultiPrototype>,
    pub warnings: Vec<Warning>,
}

impl Decision {
    /// The number of material classes (without `ambiguous`).
    fn materials(&self) -> usize {
        match self.decider {
            Decider::Nearest(_) => self.class_names.len(),
            _ => self.class_names.len() - 1,
        }
    }
}

/// The decision of a map under `cfg` against `src`, for bands of wavelengths `bands`
/// (`None`: single-band data without a wavelength). A library is taken at the bands'
/// wavelengths (`PrototypeSource::load_multi_for`; a band without a wavelength at the
/// built-in library's 650 nm, with a warning).
pub(crate) fn decision(
    cfg: &MapConfig,
    src: MapPrototypes<'_>,
    bands: &[Option<f64>],
) -> Result<Decision> {
    let label = src.label();
    let core_err = |e| PipelineError::from(IoError::core(&label, e));
    let mut warnings = Vec::new();
    let (profiles, same) = match src {
        MapPrototypes::Model { model, path } => {
            // `classify`'s choice (`prototypes_for`), on the model in memory.
            if cfg.rule == Rule::Set && cfg.bench == Bench::Same {
                let (protos, cmp) = same_bench(model);
                if !cmp.same {
                    warnings.push(no_sample_covariances(path));
                }
                (protos, cmp.same)
            } else {
                (model.multi_prototypes(), false)
            }
        }
        MapPrototypes::Library(spec) => {
            let known: Vec<f64> = bands.iter().flatten().copied().collect();
            let without = bands.iter().filter(|b| b.is_none()).count();
            let (p, _, w) = PrototypeSource::Library(spec.to_string()).load_multi_for(
                &if without > 0 {
                    vec![polarid_io::library::BUILTIN_WAVELENGTH_NM]
                } else {
                    known
                },
                without,
            )?;
            warnings.extend(w);
            (p, false)
        }
        MapPrototypes::Given { profiles, .. } => (profiles.to_vec(), false),
    };
    let decider = match cfg.rule {
        Rule::Nearest => Decider::Nearest(
            Classifier::multi(
                profiles.clone(),
                ClassifierConfig {
                    metric: cfg.metric,
                    reject: cfg.max_distance.map_or(Reject::Never, Reject::MaxDistance),
                    ..ClassifierConfig::default()
                },
            )
            .map_err(core_err)?,
        ),
        Rule::Set if src.tests_rows(cfg) => {
            let e = &cfg.errors;
            let n =
                Nuisances::from_error_model(e.extinction_ratio, e.retardance_deg.to_radians(), 0.0);
            Decider::Hypothesis {
                decider: HypothesisDecider::new(
                    &profiles,
                    cfg.confidence,
                    n.scale_min,
                    src.is_catalogue(),
                )
                .map_err(core_err)?,
                floor: e.dolp_floor,
            }
        }
        Rule::Set => {
            let d = SetDecider::new(&profiles, bands, cfg.confidence).map_err(core_err)?;
            Decider::Set {
                decider: d,
                noise: same,
            }
        }
    };
    let mut class_names: Vec<String> = match &decider {
        Decider::Nearest(_) => {
            let mut v: Vec<String> = profiles.iter().map(|p| p.class.clone()).collect();
            v.sort();
            v.dedup();
            v
        }
        Decider::Set { decider, .. } => decider.classes().to_vec(),
        Decider::Hypothesis { decider, .. } => decider.classes().to_vec(),
    };
    if cfg.rule == Rule::Set {
        class_names.push(AMBIGUOUS.to_string());
    }
    Ok(Decision {
        decider,
        class_names,
        profiles,
        warnings,
    })
}

/// The angles of one band's captures.
#[derive(Debug, Clone, Copy)]
pub(crate) enum BandBetas<'a> {
    /// One β per capture (radians).
    Shared(&'a [f64]),
    /// One β image per capture (radians).
    PerPixel(&'a [&'a [f32]]),
}

/// One band's fit, as the decision reads it (images of the map's size).
#[derive(Debug, Clone, Copy)]
pub(crate) struct BandInput<'a> {
    /// The band's wavelength (`None`: single-band data without one); for the
    /// hypothesis tests the wavelength the library was taken at.
    pub wavelength_nm: Option<f64>,
    /// The fit's reason per pixel (`classified`: fitted with status `ok`).
    pub reason: &'a [u8],
    pub n: &'a [f32],
    pub k: &'a [f32],
    pub n_se: &'a [f32],
    pub k_se: &'a [f32],
    pub nk_corr: &'a [f32],
    pub rms: &'a [f32],
    /// The DoLP of each capture of the band (NaN: left out of the pixel's fit).
    pub dolp: &'a [&'a [f32]],
    /// The band's captures (indices into the error model's `angle_sd`).
    pub captures: &'a [usize],
    pub betas: BandBetas<'a>,
    /// The noise model and the noise terms of each capture (weighted fits).
    pub noise: Option<(NoiseModel, &'a [&'a [f32]], &'a [&'a [f32]])>,
}

/// Scratch memory of one thread.
#[derive(Default)]
struct Scratch {
    cov: CovScratch,
    rows: Vec<PixelRow>,
    bands: Vec<PixelBand>,
    best: Vec<(f64, usize)>,
    hyp: Vec<HypRow>,
    wl: Vec<f64>,
}

/// The rows of pixel `p` in band `b` (captures with a DoLP).
fn band_rows(b: &BandInput<'_>, p: usize, rows: &mut Vec<PixelRow>) {
    rows.clear();
    for (j, &ci) in b.captures.iter().enumerate() {
        let y = b.dolp[j][p];
        if y.is_nan() {
            continue;
        }
        let beta = match b.betas {
            BandBetas::Shared(v) => v[j],
            BandBetas::PerPixel(v) => v[j][p] as f64,
        };
        let se = match &b.noise {
            Some((m, read, shot)) => m.dolp_se(read[j][p], shot[j][p]),
            None => 1.0,
        };
        rows.push(PixelRow {
            capture: ci,
            beta,
            y: y as f64,
            se,
        });
    }
}

/// What one band of a pixel gives its decision.
enum BandSays {
    /// Its estimate or rows are part of the decision.
    Used,
    /// Its interval on `n` reaches 0 (set rule): not placed by the data.
    Valley,
    /// Left out, for this reason.
    Left(u8),
}

/// The decision of one pixel on every band (`decide_pixels`).
struct PixelDecider<'a> {
    d: &'a Decision,
    bands: &'a [BandInput<'a>],
    /// The systematic error model, one angle uncertainty per capture of the map.
    errors: &'a MapErrorModel,
    /// No systematic error (the nearest prototype's covariance).
    none: MapErrorModel,
    /// The fits' bounds allow `k = 0`.
    k_can_be_zero: bool,
    /// The class code of `ambiguous`.
    ambiguous: u16,
}

impl PixelDecider<'_> {
    /// Class code and reason of pixel `p`.
    fn one(&self, s: &mut Scratch, p: usize) -> (u16, u8) {
        s.bands.clear();
        s.hyp.clear();
        s.wl.clear();
        let mut nearest = MultiEstimate { bands: Vec::new() };
        let mut first_reason: Option<u8> = None;
        let mut valley = false;
        for (bi, b) in self.bands.iter().enumerate() {
            let says = if b.reason[p] != reason::CLASSIFIED {
                BandSays::Left(b.reason[p])
            } else {
                match &self.d.decider {
                    Decider::Set { noise: true, .. } => self.noise_band(s, p, bi, b),
                    Decider::Set { noise: false, .. } | Decider::Nearest(_) => {
                        self.total_band(s, p, (bi, b), &mut nearest)
                    }
                    Decider::Hypothesis { floor, .. } => self.rows_band(s, p, b, *floor),
                }
            };
            match says {
                BandSays::Used => {}
                BandSays::Valley => valley = true,
                BandSays::Left(r) => {
                    first_reason.get_or_insert(r);
                }
            }
        }
        match self.decide(s, &nearest) {
            Some(code) => code,
            None if valley => (self.ambiguous, reason::AMBIGUOUS),
            None => (0, first_reason.unwrap_or(reason::FIT_INVALID_INPUT)),
        }
    }

    /// Band `b`'s estimate with its fit's noise covariance (set rule, same bench).
    fn noise_band(&self, s: &mut Scratch, p: usize, bi: usize, b: &BandInput<'_>) -> BandSays {
        let (n, k) = (b.n[p] as f64, b.k[p] as f64);
        let cov = fit_covariance(b.n_se[p] as f64, b.k_se[p] as f64, b.nk_corr[p] as f64);
        if cov.is_some_and(|c| c.nn.sqrt() >= n) {
            return BandSays::Valley;
        }
        // An unweighted fit's covariance is its own residuals' (T − 2 dof).
        let dof = if b.noise.is_some() {
            f64::INFINITY
        } else {
            b.dolp.iter().filter(|d| !d[p].is_nan()).count() as f64 - 2.0
        };
        s.bands.push(PixelBand {
            band: bi,
            n,
            k,
            cov,
            dof,
        });
        BandSays::Used
    }

    /// Band `b`'s estimate with its total covariance (set rule, other bench) or its
    /// noise covariance from its rows (nearest prototype).
    fn total_band(
        &self,
        s: &mut Scratch,
        p: usize,
        (bi, b): (usize, &BandInput<'_>),
        nearest: &mut MultiEstimate,
    ) -> BandSays {
        let (n, k) = (b.n[p] as f64, b.k[p] as f64);
        let set = matches!(self.d.decider, Decider::Set { .. });
        band_rows(b, p, &mut s.rows);
        let model = if set { self.errors } else { &self.none };
        let w = b.noise.is_some();
        let Some(cov) = total_covariance(n, k, &s.rows, w, model, self.k_can_be_zero, &mut s.cov)
        else {
            return BandSays::Left(reason::FIT_ILL_CONDITIONED);
        };
        if set && cov.nn.sqrt() >= n {
            return BandSays::Valley;
        }
        if set {
            s.bands.push(PixelBand {
                band: bi,
                n,
                k,
                cov: Some(cov),
                dof: f64::INFINITY,
            });
        } else {
            nearest.bands.push(EstimateBand {
                wavelength_nm: b.wavelength_nm,
                estimate: Estimate {
                    n,
                    k,
                    cov: Some(cov),
                    fit_status: FitStatus::Ok,
                },
                film: None,
            });
        }
        BandSays::Used
    }

    /// Band `b`'s rows for the hypothesis tests, with the DoLP floor `floor`.
    fn rows_band(&self, s: &mut Scratch, p: usize, b: &BandInput<'_>, floor: f64) -> BandSays {
        band_rows(b, p, &mut s.rows);
        // Without a noise model the pixel's own scatter about its fit.
        let t = s.rows.len() as f64;
        let own = if t > 2.0 {
            b.rms[p] as f64 * (t / (t - 2.0)).sqrt()
        } else {
            f64::NAN
        };
        let band = s.wl.len();
        s.wl.push(
            b.wavelength_nm
                .unwrap_or(polarid_io::library::BUILTIN_WAVELENGTH_NM),
        );
        for r in &s.rows {
            let se = if b.noise.is_some() { r.se } else { own };
            s.hyp.push(HypRow {
                beta: r.beta,
                dolp: r.y,
                dolp_sd: (se * se + floor * floor).sqrt(),
                angle_sd: self.errors.angle_sd.get(r.capture).copied().unwrap_or(0.0),
                band,
            });
        }
        BandSays::Used
    }

    /// The class code and reason decided on the bands gathered in `s` and `nearest`
    /// (`None`: no band to decide on).
    fn decide(&self, s: &mut Scratch, nearest: &MultiEstimate) -> Option<(u16, u8)> {
        let answer = match &self.d.decider {
            Decider::Set { decider, .. } => {
                if s.bands.is_empty() {
                    return None;
                }
                decider.decide(&s.bands, &mut s.best)
            }
            Decider::Nearest(c) => {
                if nearest.bands.is_empty() {
                    return None;
                }
                let dec = c.classify_multi(nearest);
                return Some(match dec.status {
                    Status::Ok => match self.d.class_names.iter().position(|c| *c == dec.predicted)
                    {
                        Some(i) => (i as u16 + 1, reason::CLASSIFIED),
                        None => (0, reason::REJECTED),
                    },
                    Status::Rejected | Status::NoCommonBand => (0, reason::REJECTED),
                    Status::NoCovariance => (0, reason::FIT_ILL_CONDITIONED),
                    _ => (0, reason::FIT_INVALID_INPUT),
                });
            }
            Decider::Hypothesis { decider, .. } => {
                if s.hyp.is_empty() {
                    return None;
                }
                match decider.decide(&s.hyp, &s.wl) {
                    Ok(a) => a,
                    // Rows the test cannot take (a β outside [0, 90°)).
                    Err(_) => return Some((0, reason::FIT_INVALID_INPUT)),
                }
            }
        };
        Some(match answer {
            PixelAnswer::One(i) => (i + 1, reason::CLASSIFIED),
            PixelAnswer::Ambiguous => (self.ambiguous, reason::AMBIGUOUS),
            PixelAnswer::Unknown | PixelAnswer::NoBand => (0, reason::REJECTED),
            PixelAnswer::NoCovariance => (0, reason::FIT_ILL_CONDITIONED),
        })
    }
}

/// Decide every pixel (in parallel): class code (0: none; `i`: `class_names[i - 1]`) and
/// reason, and the counts. `errors`: the systematic error model, one angle uncertainty
/// per capture of the map; `k_can_be_zero`: the fits' bounds allow `k = 0`.
pub(crate) fn decide_pixels(
    d: &Decision,
    bands: &[BandInput<'_>],
    errors: &MapErrorModel,
    k_can_be_zero: bool,
    npix: usize,
) -> (Vec<u16>, Vec<u8>, MapCounts) {
    let decider = PixelDecider {
        d,
        bands,
        errors,
        none: MapErrorModel::none(errors.angle_sd.len()),
        k_can_be_zero,
        ambiguous: d.materials() as u16 + 1,
    };
    // Hypothesis tests take milliseconds a pixel: no batching of pixels.
    let min_len = match d.decider {
        Decider::Hypothesis { .. } => 1,
        _ => 256,
    };
    let decided: Vec<(u16, u8)> = (0..npix)
        .into_par_iter()
        .with_min_len(min_len)
        .map_init(Scratch::default, |s, p| decider.one(s, p))
        .collect();
    let mut counts = MapCounts {
        reasons: [0; reason::COUNT],
        classes: vec![0; d.class_names.len() + 1],
    };
    let (class, why): (Vec<u16>, Vec<u8>) = decided.into_iter().unzip();
    for (&c, &r) in class.iter().zip(&why) {
        counts.reasons[r as usize] += 1;
        if let Some(n) = counts.classes.get_mut(c as usize) {
            *n += 1;
        }
    }
    (class, why, counts)
}

/// `cfg`'s weighting of the fits: `auto` weights calibrated geometry and the pixels
/// tested against their rows (their DoLP standard errors are part of the test).
pub(crate) fn weighted(cfg: &MapConfig, calibrated: bool, tests_rows: bool) -> bool {
    match cfg.weights {
        super::Weights::Auto => calibrated || tests_rows,
        super::Weights::Noise => true,
        super::Weights::None => false,
    }
}
