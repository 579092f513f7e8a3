//! Per-pixel decisions of material maps: the decisions of `classify`, made for millions
//! of estimates.
//!
//! - [`SetDecider`]: the set rule against prototypes with covariances (a model on the
//!   same bench with the estimate's noise and the prototypes' sample covariance, or on
//!   another bench with both totals; docs/CLASSIFY.md "The consistent set" and "Trained
//!   models: the same bench"). The distance of one band is
//!   [`Classifier::set_distance`] (`Δᵀ(Σ_est + Σ_proto)⁻¹Δ`, in `(n, u = k²)` near
//!   `k = 0`); over several bands the squares add and the threshold is `χ²_{2m}(p)`
//!   (`m` bands in common), each class tested at its nearest prototype — what
//!   [`Classifier::classify_multi`] decides under [`Rule::Set`](super::Rule::Set),
//!   without building a [`Decision`](super::Decision) per pixel (tested equal below).
//!   Prototypes whose surface-layer shifts correlate several bands are decided by
//!   [`Classifier::classify_multi`] itself.
//! - [`HypothesisDecider`]: each material as it is found tested against the pixel's
//!   own rows ([`classify_rows`](super::classify_rows), docs/CLASSIFY.md "Testing each material against the
//!   rows").
//!
//! The answer of a pixel is a [`PixelAnswer`]: one material, `ambiguous`, or none.

use std::collections::BTreeSet;

use super::hypothesis::pixel::{PixelTests, Verdict};
use super::{
    Classifier, ClassifierConfig, Cov2, Estimate, EstimateBand, HypRow, HypothesisConfig,
    MultiEstimate, MultiPrototype, Prototype, Status, chi2_quantile, same_band,
};
use crate::error::{CoreError, Result};
use crate::status::FitStatus;

/// The answer for one pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelAnswer {
    /// One material: its index into the decider's `classes()` (sorted names).
    One(u16),
    /// Several materials.
    Ambiguous,
    /// No material (`unknown`).
    Unknown,
    /// The test needs a covariance that neither side has.
    NoCovariance,
    /// No prototype has a band of the pixel.
    NoBand,
}

/// One band of a pixel's estimate: the band's index in the decider's bands, `(n, k)`
/// and its covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelBand {
    /// Index into the decider's bands.
    pub band: usize,
    /// Fitted `n`.
    pub n: f64,
    /// Fitted `k`.
    pub k: f64,
    /// The estimate's covariance for the comparison.
    pub cov: Option<Cov2>,
    /// Degrees of freedom of the estimate's covariance when it is estimated from the
    /// pixel's own residuals (an unweighted fit: `s² (JᵀJ)⁻¹`, `ν = T − 2`); infinite
    /// when it is known (a fit weighted by the noise model).
    pub dof: f64,
}

/// The threshold of `d²` for a single-band estimate whose covariance is estimated with
/// `ν` degrees of freedom, at confidence `p`: `d²/2` then follows Snedecor's `F(2, ν)`
/// (Hotelling's `T²` with a known mean, Anderson, *An Introduction to Multivariate
/// Statistical Analysis*, 3rd ed., §5.2), whose survival function for 2 numerator
/// degrees of freedom is `(1 + 2x/ν)^(−ν/2)`, so
///
/// ```text
/// q = ν ((1 − p)^(−2/ν) − 1)          → −2 ln(1 − p) = χ²₂(p) as ν → ∞
/// ```
///
/// (conservative when a prototype's known covariance is part of the sum). NaN for
/// `ν ≤ 0`.
pub fn estimated_cov_quantile(p: f64, nu: f64) -> f64 {
    if !(nu > 0.0) {
        return f64::NAN;
    }
    if nu.is_infinite() {
        return -2.0 * (1.0 - p).ln();
    }
    nu * ((1.0 - p).powf(-2.0 / nu) - 1.0)
}

/// The covariance of a fit's `n_se`, `k_se`, `nk_corr` as `classify` reads a fit row: a
/// NaN correlation counts as 0 (`polarid_pipeline::classify::estimate_of`).
pub fn fit_covariance(n_se: f64, k_se: f64, nk_corr: f64) -> Option<Cov2> {
    let corr = if nk_corr.is_nan() { 0.0 } else { nk_corr };
    Cov2::from_se(n_se, k_se, corr)
}

/// The sorted class names of `profiles`.
fn class_names(profiles: &[MultiPrototype]) -> Result<Vec<String>> {
    let names: Vec<String> = profiles
        .iter()
        .map(|p| p.class.clone())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    if names.len() >= u16::MAX as usize {
        return Err(CoreError::OutOfRange {
            name: "number of classes",
            value: names.len() as f64,
            expected: "< 65535",
        });
    }
    Ok(names)
}

/// The band of `p` matching band `w` of `bands` (the matching of
/// `Classifier::classify_multi`: by [`same_band`], or a single band on each side when
/// either has no wavelength).
fn matching_band(p: &MultiPrototype, bands: &[Option<f64>], w: Option<f64>) -> Option<usize> {
    if bands.len() == 1 && p.bands.len() == 1 && (w.is_none() || p.bands[0].wavelength_nm.is_none())
    {
        return Some(0);
    }
    p.bands.iter().position(|b| same_band(w, b.wavelength_nm))
}

/// The set rule against prototypes, per pixel (module documentation).
#[derive(Debug, Clone)]
pub struct SetDecider {
    classes: Vec<String>,
    bands: Vec<Option<f64>>,
    /// Per prototype: its class index and, per band of the decider, that band as a
    /// [`Prototype`].
    protos: Vec<(u16, Vec<Option<Prototype>>)>,
    /// `χ²_{2m}(p)` for `m = 1 ..= bands`.
    quantiles: Vec<f64>,
    confidence: f64,
    /// The classifier itself, when prototypes' layer shifts correlate several bands.
    joint: Option<Classifier>,
}

impl SetDecider {
    /// The set rule at `confidence` against `profiles`, for estimates in `bands` (their
    /// wavelengths, `None` for single-band data without one). Errors: no prototype, a
    /// confidence outside `(0, 1)`, bad prototypes (as [`Classifier::multi`]).
    pub fn new(
        profiles: &[MultiPrototype],
        bands: &[Option<f64>],
        confidence: f64,
    ) -> Result<Self> {
        let classifier = Classifier::multi(profiles.to_vec(), ClassifierConfig::set(confidence))?;
        let classes = class_names(profiles)?;
        let protos = profiles
            .iter()
            .map(|p| {
                let c = classes.iter().position(|n| *n == p.class).unwrap_or(0) as u16;
                let per_band = bands
                    .iter()
                    .map(|&w| matching_band(p, bands, w).and_then(|i| p.band_prototype(i)))
                    .collect();
                (c, per_band)
            })
            .collect();
        let quantiles = (1..=bands.len().max(1))
            .map(|m| chi2_quantile(confidence, 2 * m))
            .collect();
        let joint = (bands.len() > 1
            && profiles
                .iter()
                .any(|p| p.bands.iter().any(|b| b.film.is_some())))
        .then_some(classifier);
        Ok(Self {
            classes,
            bands: bands.to_vec(),
            protos,
            quantiles,
            confidence,
            joint,
        })
    }

    /// The class names, sorted ([`PixelAnswer::One`] indexes them).
    pub fn classes(&self) -> &[String] {
        &self.classes
    }

    /// The answer for a pixel's bands (those whose fit is `ok`; at least one).
    /// `best` is scratch memory (one entry per class).
    pub fn decide(&self, est: &[PixelBand], best: &mut Vec<(f64, usize)>) -> PixelAnswer {
        if est.is_empty() {
            return PixelAnswer::NoBand;
        }
        if let Some(c) = &self.joint {
            return self.decide_joint(c, est);
        }
        best.clear();
        best.resize(self.classes.len(), (f64::INFINITY, 0));
        let mut any = false;
        for (class, per_band) in &self.protos {
            let (mut d2, mut m) = (0.0, 0usize);
            for b in est {
                let Some(p) = per_band.get(b.band).and_then(Option::as_ref) else {
                    continue;
                };
                let e = Estimate {
                    n: b.n,
                    k: b.k,
                    cov: b.cov,
                    fit_status: FitStatus::Ok,
                };
                match Classifier::set_distance(&e, p) {
                    Some(d) => d2 += d * d,
                    None => return PixelAnswer::NoCovariance,
                }
                m += 1;
            }
            if m == 0 {
                continue;
            }
            any = true;
            // The class at its nearest prototype (ties: the first).
            let slot = &mut best[*class as usize];
            if d2 < slot.0 {
                *slot = (d2, m);
            }
        }
        if !any {
            return PixelAnswer::NoBand;
        }
        // Covariances estimated from the pixels' own residuals widen the threshold
        // (`estimated_cov_quantile`; over several bands its inflation of the one-band
        // threshold is applied to `χ²_{2m}`, an approximation).
        let nu = est.iter().map(|b| b.dof).fold(f64::INFINITY, f64::min);
        let inflate = if nu.is_finite() {
            estimated_cov_quantile(self.confidence, nu) / self.quantiles[0]
        } else {
            1.0
        };
        let mut found: Option<u16> = None;
        for (c, &(d2, m)) in best.iter().enumerate() {
            if m > 0 && d2 <= self.quantiles[m - 1] * inflate {
                if found.is_some() {
                    return PixelAnswer::Ambiguous;
                }
                found = Some(c as u16);
            }
        }
        found.map_or(PixelAnswer::Unknown, PixelAnswer::One)
    }

    /// The classifier's own decision (layer shifts correlated across bands).
    fn decide_joint(&self, c: &Classifier, est: &[PixelBand]) -> PixelAnswer {
        let e = MultiEstimate {
            bands: est
                .iter()
                .map(|b| EstimateBand {
                    wavelength_nm: self.bands.get(b.band).copied().flatten(),
                    estimate: Estimate {
                        n: b.n,
                        k: b.k,
                        cov: b.cov,
                        fit_status: FitStatus::Ok,
                    },
                    film: None,
                })
                .collect(),
        };
        answer_of(&self.classes, &c.classify_multi(&e))
    }
}

/// The [`PixelAnswer`] of a [`Decision`](super::Decision).
fn answer_of(classes: &[String], d: &super::Decision) -> PixelAnswer {
    match d.status {
        Status::Ok => classes
            .iter()
            .position(|c| *c == d.predicted)
            .map_or(PixelAnswer::Unknown, |i| PixelAnswer::One(i as u16)),
        Status::Ambiguous => PixelAnswer::Ambiguous,
        Status::Rejected => PixelAnswer::Unknown,
        Status::NoCommonBand => PixelAnswer::NoBand,
        Status::NoCovariance => PixelAnswer::NoCovariance,
        _ => PixelAnswer::Unknown,
    }
}

/// The hypothesis tests against a pixel's rows (module documentation).
#[derive(Debug, Clone)]
pub struct HypothesisDecider {
    classes: Vec<String>,
    confidence: f64,
    scale_min: f64,
    open_world: bool,
    tests: PixelTests,
    /// Per prototype: its class index and the prototype (for the transparency test).
    materials: Vec<(u16, MultiPrototype)>,
}

impl HypothesisDecider {
    /// Each material of `protos` tested at `confidence` with the polarimeter's lowest
    /// scale `scale_min` ([`super::Nuisances::from_error_model`]); the offset's bound is
    /// taken per pixel from its rows' angle uncertainty, as `classify` takes it per
    /// target. `open_world`: the materials are a catalogue, not the scene's own list (a
    /// transparent material alone is ambiguous, [`super::Decision::open_world`]).
    /// Errors: no prototype, bad settings.
    pub fn new(
        protos: &[MultiPrototype],
        confidence: f64,
        scale_min: f64,
        open_world: bool,
    ) -> Result<Self> {
        if protos.is_empty() {
            return Err(CoreError::TooFew {
                what: "materials",
                needed: 1,
                got: 0,
            });
        }
        let classes = class_names(protos)?;
        let materials = protos
            .iter()
            .map(|p| {
                let c = classes.iter().position(|n| *n == p.class).unwrap_or(0) as u16;
                (c, p.clone())
            })
            .collect();
        let d = Self {
            tests: PixelTests::new(protos, &classes),
            materials,
            classes,
            confidence,
            scale_min,
            open_world,
        };
        d.config(0.0).validate()?;
        Ok(d)
    }

    /// The class names, sorted ([`PixelAnswer::One`] indexes them).
    pub fn classes(&self) -> &[String] {
        &self.classes
    }

    fn config(&self, angle_sd: f64) -> HypothesisConfig {
        let mut n = super::Nuisances::from_error_model(f64::INFINITY, 0.0, angle_sd);
        n.scale_min = self.scale_min;
        HypothesisConfig {
            confidence: self.confidence,
            nuisances: n,
            open_world: self.open_world,
        }
    }

    /// The answer for a pixel's rows (bands indexing `wavelengths`, nm): the materials
    /// that pass ([`classify_rows`](super::classify_rows), uniform priors; in an open
    /// world a transparent material alone is ambiguous), without testing those that cannot
    /// pass (`hypothesis::pixel`). Errors: bad rows (as [`classify_rows`](super::classify_rows)).
    pub fn decide(&self, rows: &[HypRow], wavelengths: &[f64]) -> Result<PixelAnswer> {
        let angle = rows.iter().map(|r| r.angle_sd).fold(0.0, f64::max);
        Ok(
            match self.tests.decide(rows, wavelengths, &self.config(angle))? {
                Verdict::NoBand => PixelAnswer::NoBand,
                Verdict::None => PixelAnswer::Unknown,
                // A transparent material is told by its index alone (open world).
                Verdict::One(c)
                    if self.open_world
                        && self
                            .materials
                            .iter()
                            .filter(|(i, _)| *i == c)
                            .all(|(_, p)| p.transparent_at(wavelengths)) =>
                {
                    PixelAnswer::Ambiguous
                }
                Verdict::One(c) => PixelAnswer::One(c),
                Verdict::Several => PixelAnswer::Ambiguous,
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::{BandPoint, Rule};
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    fn band(w: Option<f64>, n: f64, k: f64, cov: Option<Cov2>) -> BandPoint {
        BandPoint {
            wavelength_nm: w,
            n,
            k,
            cov,
            film: None,
            layer: None,
        }
    }

    fn proto(class: &str, bands: Vec<BandPoint>) -> MultiPrototype {
        MultiPrototype {
            class: class.into(),
            category: None,
            source: "test".into(),
            bands,
            surface: None,
        }
    }

    /// The per-pixel set rule answers as `Classifier::classify_multi` does, over random
    /// estimates near prototypes (one and two bands, prototypes with and without
    /// covariances, several prototypes per class, estimates near k = 0).
    #[test]
    fn set_decider_agrees_with_the_classifier() {
        let mut rng = StdRng::seed_from_u64(7);
        for bands in [vec![None], vec![Some(450.0), Some(650.0)]] {
            let cov = |rng: &mut StdRng, s: f64| {
                Cov2::from_se(
                    s * (0.2 + rng.random::<f64>()),
                    s * (0.2 + rng.random::<f64>()),
                    rng.random::<f64>() * 1.6 - 0.8,
                )
            };
            let centres = [
                ("aluminum", 1.2, 6.6),
                ("copper", 0.4, 2.9),
                ("copper", 0.5, 3.0),
                ("glass", 1.5, 0.0),
                ("paint", 1.4, 0.3),
            ];
            let profiles: Vec<MultiPrototype> = centres
                .iter()
                .enumerate()
                .map(|(i, &(c, n, k))| {
                    let bs = bands
                        .iter()
                        .map(|&w| {
                            let pc = (i % 2 == 0).then(|| cov(&mut rng, 0.05)).flatten();
                            band(w, n, k, pc)
                        })
                        .collect();
                    proto(c, bs)
                })
                .collect();
            let dec = SetDecider::new(&profiles, &bands, 0.95).unwrap();
            let clf = Classifier::multi(profiles.clone(), ClassifierConfig::set(0.95)).unwrap();
            assert_eq!(clf.config().rule, Rule::Set);
            let mut scratch = Vec::new();
            let mut seen = [0usize; 3];
            for _ in 0..3000 {
                let &(_, n0, k0) = &centres[rng.random_range(0..centres.len())];
                let s = 0.02 + 0.3 * rng.random::<f64>();
                let est: Vec<PixelBand> = (0..bands.len())
                    .map(|b| PixelBand {
                        band: b,
                        n: n0 + s * (rng.random::<f64>() - 0.5) * 4.0,
                        k: (k0 + s * (rng.random::<f64>() - 0.5) * 4.0).max(0.0),
                        cov: cov(&mut rng, s),
                        dof: f64::INFINITY,
                    })
                    .collect();
                let got = dec.decide(&est, &mut scratch);
                let me = MultiEstimate {
                    bands: est
                        .iter()
                        .map(|b| EstimateBand {
                            wavelength_nm: bands[b.band],
                            estimate: Estimate {
                                n: b.n,
                                k: b.k,
                                cov: b.cov,
                                fit_status: FitStatus::Ok,
                            },
                            film: None,
                        })
                        .collect(),
                };
                let want = answer_of(dec.classes(), &clf.classify_multi(&me));
                assert_eq!(got, want, "{est:?}");
                match got {
                    PixelAnswer::One(_) => seen[0] += 1,
                    PixelAnswer::Ambiguous => seen[1] += 1,
                    _ => seen[2] += 1,
                }
            }
            // Every kind of answer was exercised.
            assert!(seen.iter().all(|&s| s > 50), "{seen:?}");
        }
    }

    /// The threshold for estimated covariances: `P(2F(2, ν) > q) = 1 − p` (checked
    /// against draws of `Δᵀ(s² C)⁻¹Δ`, `s² ~ χ²_ν/ν`, in both directions) and `χ²₂` in
    /// the limit.
    #[test]
    fn estimated_covariance_threshold_covers_at_its_confidence() {
        use rand_distr::{ChiSquared, Distribution, StandardNormal};
        let mut rng = StdRng::seed_from_u64(11);
        for &nu in &[3.0, 8.0, 20.0] {
            for &p in &[0.8, 0.95] {
                let q = estimated_cov_quantile(p, nu);
                let chi = ChiSquared::new(nu).unwrap();
                let n = 40_000;
                let mut inside = 0;
                for _ in 0..n {
                    let (a, b): (f64, f64) = (
                        StandardNormal.sample(&mut rng),
                        StandardNormal.sample(&mut rng),
                    );
                    let s2 = chi.sample(&mut rng) / nu;
                    if (a * a + b * b) / s2 <= q {
                        inside += 1;
                    }
                }
                let cover = inside as f64 / n as f64;
                // 4 binomial standard errors.
                let tol = 4.0 * (p * (1.0 - p) / n as f64).sqrt();
                assert!((cover - p).abs() < tol, "nu {nu} p {p}: {cover}");
            }
        }
        assert!((estimated_cov_quantile(0.95, f64::INFINITY) - 5.991_464_547).abs() < 1e-6);
        assert!((estimated_cov_quantile(0.95, 1e7) - 5.991_464_547).abs() < 1e-4);
        assert!(estimated_cov_quantile(0.95, 0.0).is_nan());
    }
}
