//! The nearest-neighbour classifier: the paper's rule (`k = 1`, Euclidean distance), k-NN
//! voting, the Mahalanobis distance and the reject option, over one band or several.
//!
//! ```text
//! d_E = √((n̂ − n_p)² + (k̂ − k_p)²)
//! d_M = √(Δᵀ (Σ_est + Σ_proto)⁻¹ Δ),   Δ = (n̂ − n_p, k̂ − k_p)
//! several bands: d = √(Σ_b d_b²) over the bands in common (see `bands`)
//! ```
//!
//! Votes among the `k` nearest prototypes; a tie goes to the tied class whose nearest member
//! is closest. The χ² gate rejects when `d_M² > χ²_{2m}(p)` (`m` bands compared; one band:
//! `−2 ln(1 − p)`, 2 degrees of freedom).
//!
//! The consistent set: every class whose nearest prototype (by the set distance, the
//! Mahalanobis distance in `(n, k)`, or in `(n, u = k²)` when the estimate's `k_se` is
//! one-sided or either point is within `NEAR_ZERO_SIGMAS` k_se of `k = 0`, band by band)
//! has `d_M² ≤ χ²_{2m}(confidence)`, ranked by distance, ties in the prototypes' order.
//!
//! # Reference
//! Thilak, Creusere & Voelz, ICIP 2007, section 6 (Tables 1 and 2 in the tests).

use super::bands::{
    BandPoint, EstimateBand, JointBand, MultiEstimate, MultiPrototype, chi2_quantile, common_bands,
    joint_distance2, strip_film,
};
use super::{
    AMBIGUOUS, Candidate, ClassifierConfig, Cov2, Decision, Estimate, Metric, Neighbour, Prototype,
    Reject, Rule, Status, UNKNOWN, check_class_name,
};
use crate::error::{CoreError, Result};

/// The consistency test is done in `(n, u = k²)` when the estimate or the prototype is
/// within this many of the estimate's `k_se` of `k = 0` (or the `k_se` is one-sided):
/// there the DoLP is linear in `u`, not in `k` (paper eq. 14–15).
pub const NEAR_ZERO_SIGMAS: f64 = 3.0;

/// Nearest-neighbour classifier over a set of prototypes (one band or several).
#[derive(Debug, Clone)]
pub struct Classifier {
    /// The first band of each profile, as a single-band prototype.
    prototypes: Vec<Prototype>,
    profiles: Vec<MultiPrototype>,
    config: ClassifierConfig,
}

/// A distance over the bands an estimate and a prototype have in common.
enum BandDistance {
    /// No band in common: the prototype is not compared.
    NoBand,
    /// A band lacks the covariance the distance needs.
    NoCovariance,
    /// The distance and the number of bands it is over.
    Distance(f64, usize),
}

/// `f` over the bands in common: one band → `f` itself, several → `√(Σ f²)`.
fn over_bands(
    est: &[&EstimateBand],
    p: &MultiPrototype,
    f: impl Fn(&Estimate, &BandPoint) -> Option<f64>,
) -> BandDistance {
    let pairs = common_bands(est, &p.bands);
    match pairs.as_slice() {
        [] => BandDistance::NoBand,
        [(i, j)] => match f(&est[*i].estimate, &p.bands[*j]) {
            Some(d) => BandDistance::Distance(d, 1),
            None => BandDistance::NoCovariance,
        },
        _ => {
            let mut s = 0.0;
            for (i, j) in &pairs {
                match f(&est[*i].estimate, &p.bands[*j]) {
                    Some(d) => s += d * d,
                    None => return BandDistance::NoCovariance,
                }
            }
            BandDistance::Distance(s.sqrt(), pairs.len())
        }
    }
}

/// Euclidean distance in one band.
fn euclidean(est: &Estimate, p: &BandPoint) -> Option<f64> {
    Some((est.n - p.n).hypot(est.k - p.k))
}

/// Mahalanobis distance in one band, when a covariance is available (the estimate's plus
/// the prototype's).
fn mahalanobis(est: &Estimate, p: &BandPoint) -> Option<f64> {
    let cov = match (est.cov, p.cov) {
        (Some(a), Some(b)) => a + b,
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => return None,
    };
    cov.mahalanobis2(est.n - p.n, est.k - p.k).map(f64::sqrt)
}

/// Whether the set rule compares `est` and `p` in `(n, u = k²)` (see
/// [`Classifier::set_distance`]).
fn near_zero(est: &Estimate, p: &BandPoint) -> bool {
    est.cov.is_some_and(|c| {
        let k_se = c.kk.sqrt();
        c.k_is_one_sided(est.k)
            || est.k <= NEAR_ZERO_SIGMAS * k_se
            || p.k <= NEAR_ZERO_SIGMAS * k_se
    })
}

/// The set rule's distance in one band (see [`Classifier::set_distance`]).
fn set_distance_band(est: &Estimate, p: &BandPoint) -> Option<f64> {
    if !near_zero(est, p) {
        return mahalanobis(est, p);
    }
    let ce = est.cov.map(|c| c.to_nu(est.k));
    let cp = p.cov.map(|c: Cov2| c.to_nu(p.k));
    let cov = match (ce, cp) {
        (Some(a), Some(b)) => a + b,
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => return None,
    };
    cov.mahalanobis2(est.n - p.n, est.k * est.k - p.k * p.k)
        .map(f64::sqrt)
}

/// The Mahalanobis distance (`set_rule`: the set rule's distance) over the bands in
/// common with ONE surface layer per side: when several bands are compared and some carry
/// the fit's layer shifts ([`super::FilmShifts`]), each side's per-band layer blocks are
/// replaced by the rank-3 term `H Hᵀ` of its shifts stacked over the bands
/// ([`joint_distance2`]; see `bands`). Bands compared in `(n, u = k²)` by the set rule
/// keep their own allowance and add their squares. Otherwise (one band, or no shifts) the
/// block-diagonal distance of [`over_bands`], bit for bit.
fn correlated(est: &[&EstimateBand], p: &MultiPrototype, set_rule: bool) -> BandDistance {
    let single = if set_rule {
        set_distance_band
    } else {
        mahalanobis
    };
    let pairs = common_bands(est, &p.bands);
    let any_film = pairs.len() > 1
        && pairs
            .iter()
            .any(|&(i, j)| est[i].film.is_some() || p.bands[j].film.is_some());
    if !any_film {
        return over_bands(est, p, single);
    }
    let mut apart = 0.0;
    let mut joint = Vec::with_capacity(pairs.len());
    for &(i, j) in &pairs {
        let (e, b) = (&est[i].estimate, &p.bands[j]);
        if set_rule && near_zero(e, b) {
            match set_distance_band(e, b) {
                Some(d) => apart += d * d,
                None => return BandDistance::NoCovariance,
            }
            continue;
        }
        let se = e.cov.map(|c| strip_film(c, est[i].film));
        let sp = b.cov.map(|c| strip_film(c, b.film));
        let (base, est_film, proto_film) = match (se, sp) {
            (Some((a, fa)), Some((c, fc))) => ([a[0] + c[0], a[1] + c[1], a[2] + c[2]], fa, fc),
            (Some((a, fa)), None) => (a, fa, None),
            (None, Some((c, fc))) => (c, None, fc),
            (None, None) => return BandDistance::NoCovariance,
        };
        joint.push(JointBand {
            delta: [e.n - b.n, e.k - b.k],
            base,
            est_film,
            proto_film,
        });
    }
    let q = if joint.is_empty() {
        Some(0.0)
    } else {
        joint_distance2(&joint)
    };
    match q {
        Some(q) => BandDistance::Distance((apart + q).sqrt(), pairs.len()),
        // Not positive definite (it should be): the block-diagonal distance.
        None => over_bands(est, p, single),
    }
}

/// Distances to the comparable prototypes, ranked (ties in the prototypes' order), and the
/// number of bands of each prototype's comparison (0: not compared).
struct Ranking {
    ranked: Vec<Neighbour>,
    bands: Vec<usize>,
}

impl Classifier {
    /// A classifier over single-band prototypes; fails when there are no prototypes, a
    /// prototype has a non-finite or negative index or a reserved/empty class name, or the
    /// settings are invalid.
    pub fn new(prototypes: Vec<Prototype>, config: ClassifierConfig) -> Result<Self> {
        let profiles = prototypes.into_iter().map(MultiPrototype::from).collect();
        Self::multi(profiles, config)
    }

    /// A classifier over prototypes measured in one or several bands (see
    /// [`super::bands`]); fails as [`Classifier::new`], and when a prototype has no band,
    /// two bands with the same wavelength, or a band without a wavelength next to others.
    pub fn multi(profiles: Vec<MultiPrototype>, config: ClassifierConfig) -> Result<Self> {
        config.validate()?;
        if profiles.is_empty() {
            return Err(CoreError::TooFew {
                what: "prototypes",
                needed: 1,
                got: 0,
            });
        }
        let mut prototypes = Vec::with_capacity(profiles.len());
        for p in &profiles {
            check_class_name(&p.class)?;
            let Some(first) = p.band_prototype(0) else {
                return Err(CoreError::TooFew {
                    what: "bands of a prototype",
                    needed: 1,
                    got: 0,
                });
            };
            for (i, b) in p.bands.iter().enumerate() {
                crate::error::ensure_finite("prototype n", b.n)?;
                crate::error::ensure_range("prototype k", b.k, 0.0, f64::INFINITY, ">= 0")?;
                let bad = (p.bands.len() > 1 && b.wavelength_nm.is_none())
                    || p.bands[..i]
                        .iter()
                        .any(|o| super::same_band(o.wavelength_nm, b.wavelength_nm));
                if bad {
                    return Err(CoreError::InvalidName {
                        what: "prototype bands",
                        name: format!("{} ({})", p.class, p.source),
                        reason: format!(
                            "band {} is repeated or has no wavelength next to other bands",
                            b.wavelength_nm
                                .map_or("without wavelength".into(), |w| format!("{w} nm"))
                        ),
                    });
                }
            }
            prototypes.push(first);
        }
        Ok(Self {
            prototypes,
            profiles,
            config,
        })
    }

    /// The prototypes (the first band of each, for a multi-band classifier; index `i` is
    /// [`Classifier::profiles`]`()[i]`).
    pub fn prototypes(&self) -> &[Prototype] {
        &self.prototypes
    }

    /// The prototypes with all their bands.
    pub fn profiles(&self) -> &[MultiPrototype] {
        &self.profiles
    }

    /// The settings.
    pub fn config(&self) -> &ClassifierConfig {
        &self.config
    }

    /// Index and Euclidean distance of the nearest prototype to `(n, k)` — the paper's
    /// rule without allocation, for per-pixel use, on the prototypes' first band. `None`
    /// when `n` or `k` is not finite.
    #[inline]
    pub fn nearest_euclidean(&self, n: f64, k: f64) -> Option<(usize, f64)> {
        if !(n.is_finite() && k.is_finite()) {
            return None;
        }
        let mut best = (usize::MAX, f64::INFINITY);
        for (i, p) in self.prototypes.iter().enumerate() {
            let (dn, dk) = (n - p.n, k - p.k);
            let d2 = dn * dn + dk * dk;
            if d2 < best.1 {
                best = (i, d2);
            }
        }
        (best.0 != usize::MAX).then(|| (best.0, best.1.sqrt()))
    }

    /// Distance of the consistency test between the estimate and prototype `p`: the
    /// Mahalanobis distance with `Σ_est + Σ_proto` in `(n, k)`, or in `(n, u = k²)` (both
    /// covariances through [`Cov2::to_nu`](super::Cov2::to_nu),
    /// `Δ = (n̂ − n_p, k̂² − k_p²)`) near `k = 0`: when the estimate's `k_se` is one-sided,
    /// or the estimate or the prototype is within [`NEAR_ZERO_SIGMAS`]` · k_se` of `k = 0`.
    /// The choice does not depend on the confidence, so a higher confidence never shrinks
    /// the set. `None` without a usable covariance. (One band; over several bands the
    /// squares add.)
    pub fn set_distance(est: &Estimate, p: &Prototype) -> Option<f64> {
        set_distance_band(
            est,
            &BandPoint {
                wavelength_nm: None,
                n: p.n,
                k: p.k,
                cov: p.cov,
                film: None,
                layer: None,
            },
        )
    }

    /// Distances by `f` to every prototype with a band in common, ranked (ties in the
    /// prototypes' order); `Err` with the first prototype lacking a usable covariance.
    fn rank(
        &self,
        est: &[&EstimateBand],
        f: impl Fn(&[&EstimateBand], &MultiPrototype) -> BandDistance,
    ) -> std::result::Result<Ranking, usize> {
        let mut ranked = Vec::with_capacity(self.profiles.len());
        let mut bands = vec![0; self.profiles.len()];
        for (index, p) in self.profiles.iter().enumerate() {
            match f(est, p) {
                BandDistance::NoBand => {}
                BandDistance::NoCovariance => return Err(index),
                BandDistance::Distance(distance, m) => {
                    bands[index] = m;
                    ranked.push(Neighbour { index, distance });
                }
            }
        }
        ranked.sort_by(|a, b| {
            a.distance
                .total_cmp(&b.distance)
                .then(a.index.cmp(&b.index))
        });
        Ok(Ranking { ranked, bands })
    }

    /// The wavelengths of the estimate's bands compared with prototype `index`.
    fn bands_used(&self, est: &[&EstimateBand], index: usize) -> Vec<Option<f64>> {
        common_bands(est, &self.profiles[index].bands)
            .into_iter()
            .map(|(i, _)| est[i].wavelength_nm)
            .collect()
    }

    /// The consistent classes among `ranked` (set distances): each class once, at its
    /// nearest prototype, kept when `d² ≤ χ²_{2m}(confidence)` (`m` bands compared); and
    /// their common category.
    fn candidates(&self, r: &Ranking) -> (Vec<Candidate>, Option<String>) {
        let mut quantiles: Vec<f64> = Vec::new();
        let mut q = |m: usize| {
            if quantiles.len() < m {
                quantiles.resize(m, f64::NAN);
            }
            if quantiles[m - 1].is_nan() {
                quantiles[m - 1] = chi2_quantile(self.config.confidence, 2 * m);
            }
            quantiles[m - 1]
        };
        let mut out: Vec<Candidate> = Vec::new();
        for nb in &r.ranked {
            let p = &self.profiles[nb.index];
            if out.iter().any(|c| c.class == p.class) {
                continue;
            }
            if nb.distance * nb.distance > q(r.bands[nb.index].max(1)) {
                continue;
            }
            let category = self
                .profiles
                .iter()
                .filter(|o| o.class == p.class)
                .find_map(|o| o.category.clone());
            out.push(Candidate {
                class: p.class.clone(),
                index: nb.index,
                distance: nb.distance,
                category,
                probability: None,
                fit: None,
            });
        }
        let common = match out.first().and_then(|c| c.category.clone()) {
            Some(cat) if out.iter().all(|c| c.category.as_ref() == Some(&cat)) => Some(cat),
            _ => None,
        };
        (out, common)
    }

    /// Classify one single-band estimate with the configured [`Rule`].
    pub fn classify(&self, est: &Estimate) -> Decision {
        self.classify_multi(&MultiEstimate::from(est.clone()))
    }

    /// Classify an estimate of one or several bands with the configured [`Rule`]: on the
    /// bands whose fit is `ok`, against each prototype on the bands they have in common
    /// ([`Decision::bands_used`] lists those of the nearest prototype).
    pub fn classify_multi(&self, est: &MultiEstimate) -> Decision {
        let ok: Vec<&EstimateBand> = est
            .bands
            .iter()
            .filter(|b| b.estimate.fit_status.is_ok())
            .collect();
        if ok.is_empty() {
            let status = est.fit_status();
            return Decision::unclassified(
                Status::FitNotOk(status),
                format!("not classified: the fit's status is `{status}`, not `ok`"),
            );
        }
        if let Some(b) = ok
            .iter()
            .find(|b| !(b.estimate.n.is_finite() && b.estimate.k.is_finite()))
        {
            return Decision::unclassified(
                Status::InvalidEstimate,
                format!(
                    "not classified: the estimate n = {}, k = {} is not finite",
                    b.estimate.n, b.estimate.k
                ),
            );
        }
        if !self
            .profiles
            .iter()
            .any(|p| !common_bands(&ok, &p.bands).is_empty())
        {
            let wl: Vec<String> = ok
                .iter()
                .map(|b| {
                    b.wavelength_nm
                        .map_or("no wavelength".into(), |w| format!("{w} nm"))
                })
                .collect();
            return Decision::unclassified(
                Status::NoCommonBand,
                format!(
                    "not classified: no prototype has a band of the estimate ({})",
                    wl.join(", ")
                ),
            );
        }
        let mut d = match self.config.rule {
            Rule::Nearest => {
                let mut d = self.classify_nearest(&ok);
                if d.status != Status::NoCovariance
                    && let Ok(r) = self.rank(&ok, |e, p| correlated(e, p, true))
                {
                    let (c, cat) = self.candidates(&r);
                    d.candidates = c;
                    d.set_category = cat;
                    d.set_tested = true;
                }
                d
            }
            Rule::Set => self.classify_set(&ok),
        };
        if let Some(nb) = d.nearest {
            d.bands_used = self.bands_used(&ok, nb.index);
        }
        d
    }

    /// The set rule (estimate already checked).
    fn classify_set(&self, est: &[&EstimateBand]) -> Decision {
        let r = match self.rank(est, |e, p| correlated(e, p, true)) {
            Ok(r) => r,
            Err(i) => {
                let p = &self.profiles[i];
                return Decision::unclassified(
                    Status::NoCovariance,
                    format!(
                        "not classified: the consistency test needs a covariance and neither \
                         the estimate nor prototype `{}` ({}) has a usable one",
                        p.class, p.source
                    ),
                );
            }
        };
        let (candidates, set_category) = self.candidates(&r);
        // ok: some prototype shares a band with the estimate (checked by the caller), so
        // `ranked` is not empty.
        let nearest = r.ranked[0];
        let class = self.profiles[nearest.index].class.clone();
        let runner = r
            .ranked
            .iter()
            .find(|nb| self.profiles[nb.index].class != class)
            .copied();
        let runner_up_distance = runner.map_or(f64::NAN, |n| n.distance);
        let pct = self.config.confidence * 100.0;
        let (predicted, status, reason) = match candidates.len() {
            0 => (
                UNKNOWN.to_string(),
                Status::Rejected,
                format!(
                    "rejected: no material is consistent at {pct}% confidence (Mahalanobis \
                     distance <= {:.3}); nearest `{class}` at {:.3}",
                    chi2_quantile(self.config.confidence, 2 * r.bands[nearest.index].max(1)).sqrt(),
                    nearest.distance
                ),
            ),
            1 => (class.clone(), Status::Ok, String::new()),
            n => (
                AMBIGUOUS.to_string(),
                Status::Ambiguous,
                format!(
                    "ambiguous: {n} materials are consistent at {pct}% confidence: {}",
                    candidates
                        .iter()
                        .map(|c| format!("{} ({:.3})", c.class, c.distance))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ),
        };
        Decision {
            predicted,
            nearest_class: Some(class),
            nearest: Some(nearest),
            distance: nearest.distance,
            runner_up: runner.map(|r| self.profiles[r.index].class.clone()),
            runner_up_distance,
            margin: runner_up_distance - nearest.distance,
            gate: Some(nearest.distance),
            votes: 1,
            status,
            reason,
            ranked: r.ranked,
            candidates,
            set_tested: true,
            set_category,
            bands_used: Vec::new(),
        }
    }

    /// The paper's nearest-neighbour rule with k-NN votes and the reject option
    /// (estimate already checked).
    fn classify_nearest(&self, est: &[&EstimateBand]) -> Decision {
        let ranking = match self.config.metric {
            Metric::Euclidean => self.rank(est, |e, p| over_bands(e, p, euclidean)),
            Metric::Mahalanobis => self.rank(est, |e, p| correlated(e, p, false)),
        };
        let r = match ranking {
            Ok(r) => r,
            Err(i) => {
                let p = &self.profiles[i];
                return Decision::unclassified(
                    Status::NoCovariance,
                    format!(
                        "not classified: the Mahalanobis distance needs a covariance \
                         and neither the estimate nor prototype `{}` ({}) has a usable one",
                        p.class, p.source
                    ),
                );
            }
        };
        let ranked = r.ranked;

        // Vote among the k nearest; ties go to the class whose nearest member is closest
        // (classes are visited in order of their nearest member, so the first class to
        // reach the maximum vote wins).
        let kk = self.config.k.min(ranked.len());
        let mut votes: Vec<(&str, usize, f64)> = Vec::new();
        for nb in &ranked[..kk] {
            let class = self.profiles[nb.index].class.as_str();
            match votes.iter_mut().find(|v| v.0 == class) {
                Some(v) => v.1 += 1,
                None => votes.push((class, 1, nb.distance)),
            }
        }
        let mut winner = votes[0];
        for v in &votes[1..] {
            if v.1 > winner.1 {
                winner = *v;
            }
        }
        let class = winner.0.to_string();
        let nearest = ranked
            .iter()
            .find(|nb| self.profiles[nb.index].class == class)
            .copied();
        let runner = ranked
            .iter()
            .find(|nb| self.profiles[nb.index].class != class)
            .copied();
        let distance = nearest.map_or(f64::NAN, |n| n.distance);
        let runner_up_distance = runner.map_or(f64::NAN, |n| n.distance);
        let mut decision = Decision {
            predicted: class.clone(),
            nearest_class: Some(class.clone()),
            nearest,
            distance,
            runner_up: runner.map(|r| self.profiles[r.index].class.clone()),
            runner_up_distance,
            margin: runner_up_distance - distance,
            gate: None,
            votes: winner.1,
            status: Status::Ok,
            reason: String::new(),
            ranked,
            candidates: Vec::new(),
            set_tested: false,
            set_category: None,
            bands_used: Vec::new(),
        };

        // Reject option.
        if let Some(near) = nearest {
            self.reject(est, near, &r.bands, &mut decision);
        }
        decision
    }

    /// The reject option of [`Self::classify_nearest`] on `decision`, whose nearest
    /// member of the winning class is `near` (`bands[i]`: bands compared with prototype
    /// `i`).
    fn reject(
        &self,
        est: &[&EstimateBand],
        near: Neighbour,
        bands: &[usize],
        decision: &mut Decision,
    ) {
        let distance = near.distance;
        let class = &self.profiles[near.index].class;
        match self.config.reject {
            Reject::Never => {}
            Reject::MaxDistance(dmax) => {
                decision.gate = Some(distance);
                if distance > dmax {
                    decision.predicted = UNKNOWN.into();
                    decision.status = Status::Rejected;
                    decision.reason = format!(
                        "rejected: nearest class `{class}` is at distance {distance:.4} > {dmax}"
                    );
                }
            }
            Reject::Chi2 { p } => {
                let proto = &self.profiles[near.index];
                let dm = match self.config.metric {
                    Metric::Mahalanobis => Some(distance),
                    Metric::Euclidean => match correlated(est, proto, false) {
                        BandDistance::Distance(d, _) => Some(d),
                        _ => None,
                    },
                };
                match dm {
                    None => {
                        decision.predicted = UNKNOWN.into();
                        decision.status = Status::NoCovariance;
                        decision.reason = format!(
                            "not classified: the chi-square gate needs a covariance and neither \
                             the estimate nor prototype `{class}` has a usable one"
                        );
                    }
                    Some(dm) => {
                        decision.gate = Some(dm);
                        let dof = 2 * bands[near.index].max(1);
                        let q = chi2_quantile(p, dof);
                        if dm * dm > q {
                            decision.predicted = UNKNOWN.into();
                            decision.status = Status::Rejected;
                            decision.reason = format!(
                                "rejected: nearest class `{class}` has Mahalanobis distance \
                                 {dm:.3} > {:.3} (chi-square gate, {dof} dof, p = {p})",
                                q.sqrt()
                            );
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::Cov2;
    use crate::status::FitStatus;

    fn proto(class: &str, n: f64, k: f64) -> Prototype {
        Prototype {
            class: class.into(),
            n,
            k,
            cov: None,
            category: None,
            source: "test".into(),
        }
    }

    /// Paper, Table 1 (estimated training values) and Table 2 (test estimates).
    fn paper_training() -> Vec<Prototype> {
        vec![
            proto("green paint", 1.47, 0.47),
            proto("aluminum", 1.64, 4.56),
            proto("copper", 0.54, 3.19),
        ]
    }

    #[test]
    fn paper_table2_is_aluminum() {
        let clf = Classifier::new(paper_training(), ClassifierConfig::default()).unwrap();
        for (n, k) in [(1.37, 3.97), (1.60, 4.34)] {
            let d = clf.classify(&Estimate::point(n, k));
            assert_eq!(d.predicted, "aluminum", "{n}+{k}i");
            assert_eq!(d.status, Status::Ok);
            let expect = (n - 1.64f64).hypot(k - 4.56);
            assert!((d.distance - expect).abs() < 1e-12);
            assert_eq!(d.runner_up.as_deref(), Some("copper"));
            let ru = (n - 0.54f64).hypot(k - 3.19);
            assert!((d.runner_up_distance - ru).abs() < 1e-12);
            assert!((d.margin - (ru - expect)).abs() < 1e-12);
        }
    }

    #[test]
    fn knn_majority_and_tie_by_distance() {
        let protos = vec![
            proto("a", 0.0, 0.0),
            proto("b", 1.0, 0.0),
            proto("b", 1.1, 0.0),
            proto("a", 5.0, 0.0),
        ];
        let cfg = ClassifierConfig {
            k: 3,
            ..Default::default()
        };
        let clf = Classifier::new(protos.clone(), cfg).unwrap();
        // Nearest is `a` at 0.4 but `b` has two of the three votes.
        let d = clf.classify(&Estimate::point(0.4, 0.0));
        assert_eq!(d.predicted, "b");
        assert_eq!(d.votes, 2);
        assert!((d.distance - 0.6).abs() < 1e-12);
        assert_eq!(d.runner_up.as_deref(), Some("a"));
        // k = 2: one vote each; the tie goes to the nearer class.
        let clf = Classifier::new(protos, ClassifierConfig { k: 2, ..cfg }).unwrap();
        let d = clf.classify(&Estimate::point(0.4, 0.0));
        assert_eq!(d.predicted, "a");
        let d = clf.classify(&Estimate::point(0.6, 0.0));
        assert_eq!(d.predicted, "b");
    }

    #[test]
    fn mahalanobis_uses_both_covariances() {
        let cov = Cov2::from_se(0.1, 0.2, 0.5).unwrap();
        let mut p = proto("x", 1.0, 2.0);
        p.cov = Some(Cov2::from_se(0.1, 0.1, 0.0).unwrap());
        let est = Estimate {
            n: 1.2,
            k: 2.3,
            cov: Some(cov),
            fit_status: FitStatus::Ok,
        };
        let clf = Classifier::new(
            vec![p],
            ClassifierConfig {
                metric: Metric::Mahalanobis,
                ..Default::default()
            },
        )
        .unwrap();
        let d = clf.classify(&est);
        // Σ = [[0.02, 0.01], [0.01, 0.05]], Δ = (0.2, 0.3)
        let (a, b, c) = (0.02, 0.01, 0.05);
        let det: f64 = a * c - b * b;
        let q = (c * 0.04 - 2.0 * b * 0.06 + a * 0.09) / det;
        assert!((d.distance - q.sqrt()).abs() < 1e-12, "{}", d.distance);
        // No covariance anywhere: not classified.
        let clf2 = Classifier::new(
            vec![proto("x", 1.0, 2.0)],
            ClassifierConfig {
                metric: Metric::Mahalanobis,
                ..Default::default()
            },
        )
        .unwrap();
        let d = clf2.classify(&Estimate::point(1.0, 2.0));
        assert_eq!(d.predicted, UNKNOWN);
        assert_eq!(d.status, Status::NoCovariance);
    }

    #[test]
    fn chi2_gate_rejects_far_estimates() {
        assert!((super::super::chi2_2dof_quantile(0.99) - 9.210340371976182).abs() < 1e-12);
        let cfg = ClassifierConfig {
            reject: Reject::Chi2 { p: 0.99 },
            ..Default::default()
        };
        let clf = Classifier::new(paper_training(), cfg).unwrap();
        let mut est = Estimate {
            n: 1.60,
            k: 4.34,
            cov: Cov2::from_se(0.05, 0.05, 0.0),
            fit_status: FitStatus::Ok,
        };
        // d_M = |(0.04, 0.22)| / 0.05 = 4.47 > 3.035: rejected.
        let d = clf.classify(&est);
        assert_eq!(d.predicted, UNKNOWN);
        assert_eq!(d.status, Status::Rejected);
        assert_eq!(d.nearest_class.as_deref(), Some("aluminum"));
        assert!((d.gate.unwrap() - 0.04f64.hypot(0.22) / 0.05).abs() < 1e-9);
        // Larger uncertainty: accepted.
        est.cov = Cov2::from_se(0.2, 0.2, 0.0);
        let d = clf.classify(&est);
        assert_eq!(d.predicted, "aluminum");
        assert_eq!(d.status, Status::Ok);
        // Euclidean threshold.
        let clf = Classifier::new(
            paper_training(),
            ClassifierConfig {
                reject: Reject::MaxDistance(0.2),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(
            clf.classify(&Estimate::point(1.60, 4.34)).predicted,
            UNKNOWN
        );
        assert_eq!(
            clf.classify(&Estimate::point(1.60, 4.50)).predicted,
            "aluminum"
        );
    }

    #[test]
    fn non_ok_fits_are_never_classified() {
        let clf = Classifier::new(paper_training(), ClassifierConfig::default()).unwrap();
        let mut est = Estimate::point(1.64, 4.56);
        est.fit_status = FitStatus::NotConverged;
        let d = clf.classify(&est);
        assert_eq!(d.predicted, UNKNOWN);
        assert_eq!(d.status.label(), "fit_not_converged");
        assert!(d.ranked.is_empty());
        let d = clf.classify(&Estimate::point(f64::NAN, 1.0));
        assert_eq!(d.status, Status::InvalidEstimate);
    }

    #[test]
    fn reserved_class_names_are_refused() {
        let e = Classifier::new(
            vec![proto("Unknown", 1.0, 1.0)],
            ClassifierConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("Unknown") && e.contains("reserved"), "{e}");
    }
}
