//! The one-paragraph explanation of a decision (`polarid classify`'s messages, the demo's
//! notes), and the confidence regions that decide the consistent set, for the
//! explanation and the (n, k) plots.
//!
//! # The confidence region
//!
//! A prototype `p` is consistent with an estimate when its set distance (see
//! [`Classifier::set_distance`]) is within `√χ²₂(confidence)` (`docs/CLASSIFY.md`):
//!
//! ```text
//! d_M² = Δᵀ (Σ_est + Σ_proto)⁻¹ Δ ≤ χ²₂(p) = −2 ln(1 − p),   Δ = (n̂ − n_p, k̂ − k_p)
//! ```
//!
//! in `(n, k)`, or in `(n, u = k²)` (`Δ = (n̂ − n_p, k̂² − k_p²)`, covariances through
//! `Cov2::to_nu`) near `k = 0`. The region of an estimate is the set of points `(n, k ≥ 0)`
//! where a prototype with a given covariance (none for a literature value) would pass that
//! test: an ellipse in `(n, k)`, its image under `k = √u` in `(n, u)`, or the two joined at
//! `k = 3 k_se` when the plane changes there. [`confidence_region`] finds it by evaluating
//! [`Classifier::set_distance`] itself along rays from the estimate, so the drawn region is
//! the one that decides membership.

use polarid_core::classify::{
    Classifier, Cov2, Decision, Estimate, NEAR_ZERO_SIGMAS, Prototype, chi2_2dof_quantile,
};

/// Which plane the consistency test of a region is done in (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RegionPlane {
    /// `(n, k)` everywhere in the region: an ellipse.
    Nk,
    /// `(n, u = k²)` everywhere (the estimate is near `k = 0`).
    Nu,
    /// `(n, k)` above `k = below_k` (`NEAR_ZERO_SIGMAS · k_se`), `(n, u = k²)` below it.
    Mixed {
        /// Where the plane changes.
        below_k: f64,
    },
}

impl RegionPlane {
    /// Short text: `(n, k)`, `(n, u = k²)`, `(n, k); (n, u = k²) below k = 0.123`.
    pub fn describe(&self) -> String {
        match self {
            RegionPlane::Nk => "(n, k)".into(),
            RegionPlane::Nu => "(n, u = k²)".into(),
            RegionPlane::Mixed { below_k } => {
                format!("(n, k); (n, u = k²) below k = {below_k:.4}")
            }
        }
    }
}

/// The boundary of an estimate's confidence region in the `(n, k)` plane (`k ≥ 0`).
#[derive(Debug, Clone, PartialEq)]
pub struct ConfidenceRegion {
    /// Closed boundary, the first point repeated last, in order of angle about the
    /// estimate.
    pub boundary: Vec<(f64, f64)>,
    /// Per boundary point: `true` where the set distance equals the threshold there;
    /// `false` where the region is cut by the axis `k = 0` or where the test's plane
    /// changes (the distance jumps).
    pub on_contour: Vec<bool>,
    /// The threshold `√χ²₂(confidence)` on the set distance.
    pub threshold: f64,
    /// The confidence.
    pub confidence: f64,
    /// The covariance added to the estimate's (a prototype's), if any.
    pub proto_cov: Option<Cov2>,
    /// The plane(s) of the test.
    pub plane: RegionPlane,
}

impl ConfidenceRegion {
    /// Smallest and largest `n` of the region.
    pub fn n_range(&self) -> (f64, f64) {
        span(self.boundary.iter().map(|p| p.0))
    }

    /// Smallest and largest `k` of the region.
    pub fn k_range(&self) -> (f64, f64) {
        span(self.boundary.iter().map(|p| p.1))
    }

    /// `n 1.021–1.463, k 6.127–7.071 in (n, k)`.
    pub fn describe(&self) -> String {
        let (n0, n1) = self.n_range();
        let (k0, k1) = self.k_range();
        format!(
            "n {n0:.3}–{n1:.3}, k {k0:.3}–{k1:.3} in {}",
            self.plane.describe()
        )
    }
}

fn span(v: impl Iterator<Item = f64>) -> (f64, f64) {
    v.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    })
}

/// The region of `est` at `confidence` where a prototype with covariance `proto_cov`
/// (`None`: a literature value) is consistent with it, traced along `rays` rays from the
/// estimate (at least 8).
///
/// The rays are `r L (cos t, sin t)` for `t` evenly spaced, `L` the Cholesky factor of
/// `Σ_est + Σ_proto` in `(n, k)`. Along each ray the set distance
/// ([`Classifier::set_distance`]) is stepped outwards in 1/64 of the threshold (in units
/// of `r`) to the first point beyond the threshold, then bisected; a ray that reaches `k = 0` inside the
/// region ends there. Each point of the boundary where the distance is continuous has
/// distance equal to the threshold to 1e-9 (relative). A region that is not star-shaped
/// about the estimate is drawn to its first boundary along each ray.
///
/// `None` when the estimate has no usable covariance, is not finite, or `confidence` is
/// not in `(0, 1)`.
pub fn confidence_region(
    est: &Estimate,
    proto_cov: Option<Cov2>,
    confidence: f64,
    rays: usize,
) -> Option<ConfidenceRegion> {
    let cov = est.cov?;
    if !(est.n.is_finite() && est.k.is_finite() && confidence > 0.0 && confidence < 1.0) {
        return None;
    }
    let threshold = chi2_2dof_quantile(confidence).sqrt();
    // Rays r·L (cos t, sin t), L the Cholesky factor of Σ_est + Σ_proto in (n, k): on an
    // (n, k) ellipse the boundary is at r = threshold for every t, and the points are
    // spread evenly around it however strong the correlation.
    let total = proto_cov.map_or(cov, |p| cov + p);
    let l11 = total.nn.sqrt();
    let l21 = total.nk / l11;
    let l22 = (total.kk - l21 * l21).sqrt();
    if !(l11 > 0.0 && l22 > 0.0 && l11.is_finite() && l21.is_finite() && l22.is_finite()) {
        return None;
    }
    let k_se = cov.kk.sqrt();
    let dist = |n: f64, k: f64| {
        let p = Prototype {
            class: String::new(),
            n,
            k,
            cov: proto_cov,
            category: None,
            source: String::new(),
        };
        Classifier::set_distance(est, &p).unwrap_or(f64::INFINITY)
    };
    if !(dist(est.n, est.k) <= threshold) {
        return None;
    }
    let rays = rays.max(8);
    let step = threshold / 64.0;
    let r_cap = 64.0 * threshold;
    let mut boundary = Vec::with_capacity(rays + 1);
    let mut on_contour = Vec::with_capacity(rays + 1);
    for i in 0..rays {
        let t = std::f64::consts::TAU * i as f64 / rays as f64;
        let (c, sn) = (t.cos(), t.sin());
        let (dn, dk) = (l11 * c, l21 * c + l22 * sn);
        let at = |r: f64| (est.n + r * dn, (est.k + r * dk).max(0.0));
        // Where the ray meets k = 0 (it is not followed below the axis).
        let r_axis = if dk < 0.0 { est.k / -dk } else { f64::INFINITY };
        let inside = |r: f64| {
            let (n, k) = at(r);
            dist(n, k) <= threshold
        };
        let (mut lo, mut hi) = (0.0, f64::NAN);
        let mut r = 0.0;
        while r < r_cap {
            let next = (r + step).min(r_axis);
            if !inside(next) {
                hi = next;
                break;
            }
            lo = next;
            if next >= r_axis {
                break;
            }
            r = next;
        }
        let point = if hi.is_nan() {
            // Inside up to the axis (or the cap): the boundary is there.
            (at(lo), false)
        } else {
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if inside(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let (n, k) = at(lo);
            let d = dist(n, k);
            ((n, k), (d - threshold).abs() <= 1e-9 * threshold)
        };
        boundary.push(point.0);
        on_contour.push(point.1);
    }
    boundary.push(boundary[0]);
    on_contour.push(on_contour[0]);
    let est_near = cov.k_is_one_sided(est.k) || est.k <= NEAR_ZERO_SIGMAS * k_se;
    let below_k = NEAR_ZERO_SIGMAS * k_se;
    let plane = if est_near {
        RegionPlane::Nu
    } else if boundary.iter().any(|p| p.1 <= below_k * (1.0 + 1e-9)) {
        RegionPlane::Mixed { below_k }
    } else {
        RegionPlane::Nk
    };
    Some(ConfidenceRegion {
        boundary,
        on_contour,
        threshold,
        confidence,
        proto_cov,
        plane,
    })
}

/// A region that decides part of an estimate's consistent set.
#[derive(Debug, Clone, PartialEq)]
pub struct DecisionRegion {
    /// The prototypes (indices into the classifier's) tested with this region, nearest
    /// first: the candidates' nearest prototypes and the nearest prototype of a class
    /// that is not a candidate, among those sharing this region's covariance.
    pub prototypes: Vec<usize>,
    /// The region.
    pub region: ConfidenceRegion,
}

/// The prototypes that matter for `est`'s consistent set under `clf` (each candidate
/// class's nearest prototype, and the nearest prototype of the nearest class that is not a
/// candidate), grouped by their covariance, nearest first.
fn deciding_prototypes(est: &Estimate, clf: &Classifier) -> Vec<(Option<Cov2>, Vec<usize>)> {
    let protos = clf.prototypes();
    let threshold = chi2_2dof_quantile(clf.config().confidence).sqrt();
    let mut ranked: Vec<(usize, f64)> = protos
        .iter()
        .enumerate()
        .filter_map(|(i, p)| Classifier::set_distance(est, p).map(|d| (i, d)))
        .collect();
    ranked.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    let mut groups: Vec<(Option<Cov2>, Vec<usize>)> = Vec::new();
    let mut classes: Vec<&str> = Vec::new();
    for &(i, d) in &ranked {
        let class = protos[i].class.as_str();
        if classes.contains(&class) {
            continue;
        }
        classes.push(class);
        let pc = protos[i].cov;
        match groups.iter_mut().find(|g| g.0 == pc) {
            Some(g) => g.1.push(i),
            None => groups.push((pc, vec![i])),
        }
        if d > threshold {
            // The nearest class outside the set: the last one that matters.
            break;
        }
    }
    groups
}

/// The regions that decide `est`'s consistent set under `clf`'s confidence: one per
/// distinct prototype covariance among the prototypes that matter (each candidate
/// class's nearest prototype, and the nearest prototype of the nearest class that is not a
/// candidate); a single region when those prototypes have no covariance (a library).
/// A prototype is a candidate exactly when it lies inside its region. Empty when the
/// estimate has no usable covariance or is not finite.
pub fn decision_regions(est: &Estimate, clf: &Classifier, rays: usize) -> Vec<DecisionRegion> {
    let confidence = clf.config().confidence;
    deciding_prototypes(est, clf)
        .into_iter()
        .filter_map(|(pc, prototypes)| {
            confidence_region(est, pc, confidence, rays)
                .map(|region| DecisionRegion { prototypes, region })
        })
        .collect()
}

/// The plane and the ranges of `n` and `k` of [`confidence_region`]`(est, proto_cov,
/// confidence, ·)`: in closed form when the region is an `(n, k)` ellipse
/// (`n̂ ± √q √Σ_nn`, `k̂ ± √q √Σ_kk`, `Σ = Σ_est + Σ_proto`, `q = χ²₂(confidence)`),
/// else from the region traced along 128 rays.
pub fn region_extent(
    est: &Estimate,
    proto_cov: Option<Cov2>,
    confidence: f64,
) -> Option<(RegionPlane, (f64, f64), (f64, f64))> {
    let cov = est.cov?;
    if !(est.n.is_finite() && est.k.is_finite() && confidence > 0.0 && confidence < 1.0) {
        return None;
    }
    let total = proto_cov.map_or(cov, |p| cov + p);
    let threshold = chi2_2dof_quantile(confidence).sqrt();
    let (hn, hk) = (threshold * total.nn.sqrt(), threshold * total.kk.sqrt());
    let k_se = cov.kk.sqrt();
    let est_near = cov.k_is_one_sided(est.k) || est.k <= NEAR_ZERO_SIGMAS * k_se;
    if !est_near
        && est.k - hk > NEAR_ZERO_SIGMAS * k_se * (1.0 + 1e-9)
        && hn.is_finite()
        && hk.is_finite()
        && total.nn * total.kk - total.nk * total.nk > 0.0
    {
        return Some((
            RegionPlane::Nk,
            (est.n - hn, est.n + hn),
            (est.k - hk, est.k + hk),
        ));
    }
    let r = confidence_region(est, proto_cov, confidence, 128)?;
    Some((r.plane, r.n_range(), r.k_range()))
}

/// The explanation's region text: `95% region (Mahalanobis <= 2.448): n …, k … in (n, k)`,
/// one clause per region of [`decision_regions`] (`region_extent`) naming the
/// prototypes it tests when they carry a covariance (`with aluminum's covariance n …`).
/// `None` when the estimate has no usable covariance.
pub fn regions_text(est: &Estimate, clf: &Classifier) -> Option<String> {
    let confidence = clf.config().confidence;
    let protos = clf.prototypes();
    let parts: Vec<String> = deciding_prototypes(est, clf)
        .into_iter()
        .filter_map(|(pc, idx)| {
            let (plane, (n0, n1), (k0, k1)) = region_extent(est, pc, confidence)?;
            let text = format!(
                "n {n0:.3}–{n1:.3}, k {k0:.3}–{k1:.3} in {}",
                plane.describe()
            );
            Some(match pc {
                None => text,
                Some(_) => {
                    let names: Vec<&str> = idx.iter().map(|&i| protos[i].class.as_str()).collect();
                    format!("with {}'s covariance {text}", names.join(", "))
                }
            })
        })
        .collect();
    if parts.is_empty() {
        return None;
    }
    Some(format!(
        "{}% region (Mahalanobis <= {:.3}): {}",
        confidence * 100.0,
        chi2_2dof_quantile(confidence).sqrt(),
        parts.join("; ")
    ))
}

/// ` (metal)` for a category, nothing without one.
fn in_parentheses(category: Option<&str>) -> String {
    category.map(|c| format!(" ({c})")).unwrap_or_default()
}

/// A one-paragraph explanation of a decision: nearest prototypes (at most `top`), when
/// categories are known the nearest prototype of another category, and the consistent
/// set (every candidate with its Mahalanobis distance and the test's threshold) when it
/// was tested, with the confidence region(s) that decide it ([`decision_regions`]: the
/// range of `n` and `k` they span and the plane of the test).
pub fn explain(target: &str, est: &Estimate, d: &Decision, clf: &Classifier, top: usize) -> String {
    // ok (indexing `protos` below): every index in a decision is one of `clf`'s
    // prototypes, produced by `clf.classify`.
    let protos = clf.prototypes();
    let unit = clf.config().distance_metric().name();
    let cat = |i: usize| in_parentheses(protos[i].category.as_deref());
    let mut s = format!("{target}: ");
    match (&d.nearest_class, d.nearest) {
        (Some(c), Some(nb)) => {
            if d.predicted == *c {
                s.push_str(c);
            } else {
                s.push_str(&format!("{} (nearest {c})", d.predicted));
            }
            if let Some(category) = &protos[nb.index].category {
                let article = if category.starts_with(['a', 'e', 'i', 'o', 'u']) {
                    "an"
                } else {
                    "a"
                };
                if d.predicted == *c {
                    s.push_str(&format!(", classified as {article} {category}"));
                }
            }
            s.push_str(&format!(" [{unit} distance {:.4}", d.distance));
            if let Some(r) = &d.runner_up {
                s.push_str(&format!(
                    "; runner-up {r} at {:.4}, margin {:.4}",
                    d.runner_up_distance, d.margin
                ));
            }
            s.push(']');
            let near: Vec<String> = d
                .ranked
                .iter()
                .take(top)
                .map(|nb| {
                    format!(
                        "{}{} {:.4}",
                        protos[nb.index].class,
                        cat(nb.index),
                        nb.distance
                    )
                })
                .collect();
            if !near.is_empty() {
                s.push_str(&format!("; nearest: {}", near.join(", ")));
            }
            if let Some(category) = &protos[nb.index].category
                && let Some(other) = d.ranked.iter().find(|o| {
                    protos[o.index]
                        .category
                        .as_ref()
                        .is_some_and(|c| c != category)
                })
            {
                s.push_str(&format!(
                    "; nearest non-{category}: {}{} {:.4}",
                    protos[other.index].class,
                    cat(other.index),
                    other.distance
                ));
            }
            if d.set_tested {
                let cfg = clf.config();
                let list: Vec<String> = d
                    .candidates
                    .iter()
                    .map(|c| {
                        let cat = in_parentheses(c.category.as_deref());
                        format!("{}{cat} {:.3}", c.class, c.distance)
                    })
                    .collect();
                s.push_str(&format!(
                    "; consistent at {}% (Mahalanobis <= {:.3}): {}",
                    cfg.confidence * 100.0,
                    polarid_core::classify::chi2_2dof_quantile(cfg.confidence).sqrt(),
                    if list.is_empty() {
                        "none".to_string()
                    } else {
                        list.join(", ")
                    }
                ));
                if d.candidates.len() > 1
                    && let Some(cat) = &d.set_category
                {
                    s.push_str(&format!(", all {cat}"));
                }
                if let Some(r) = regions_text(est, clf) {
                    s.push_str(&format!("; {r}"));
                }
            }
            // An ambiguous set's reason repeats the list; one candidate's says why (an
            // index, not a name).
            if !d.reason.is_empty()
                && (d.status != polarid_core::classify::Status::Ambiguous
                    || d.candidates.len() == 1)
            {
                s.push_str(&format!("; {}", d.reason));
            }
        }
        _ => s.push_str(&format!("{} ({})", d.predicted, d.reason)),
    }
    s
}

#[cfg(test)]
mod tests {
    use polarid_core::FitStatus;
    use polarid_core::classify::{ClassifierConfig, ONE_SIDED_RATIO};

    use super::*;

    fn est(n: f64, k: f64, n_se: f64, k_se: f64, rho: f64) -> Estimate {
        Estimate {
            n,
            k,
            cov: Cov2::from_se(n_se, k_se, rho),
            fit_status: FitStatus::Ok,
        }
    }

    fn proto(class: &str, n: f64, k: f64, cov: Option<Cov2>) -> Prototype {
        Prototype {
            class: class.into(),
            n,
            k,
            cov,
            category: Some("metal".into()),
            source: "test".into(),
        }
    }

    /// Closed-form squared Mahalanobis length with `[[a, b], [b, c]]`.
    fn m2(a: f64, b: f64, c: f64, dx: f64, dy: f64) -> f64 {
        (c * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / (a * c - b * b)
    }

    /// Even-odd rule.
    fn inside_polygon(poly: &[(f64, f64)], p: (f64, f64)) -> bool {
        let mut inside = false;
        for w in poly.windows(2) {
            let ((x0, y0), (x1, y1)) = (w[0], w[1]);
            if (y0 > p.1) != (y1 > p.1) && p.0 < x0 + (p.1 - y0) * (x1 - x0) / (y1 - y0) {
                inside = !inside;
            }
        }
        inside
    }

    #[test]
    fn nk_region_is_the_chi2_ellipse_of_the_total_covariance() {
        for (conf, rho) in [(0.95, 0.0), (0.95, -0.7), (0.8, 0.6), (0.99, 0.95)] {
            let e = est(1.3, 6.6, 0.23, 0.66, rho);
            let r = confidence_region(&e, None, conf, 180).unwrap();
            assert_eq!(r.plane, RegionPlane::Nk);
            let q = -2.0 * (1.0f64 - conf).ln();
            assert!((r.threshold * r.threshold - q).abs() < 1e-12);
            assert!(r.on_contour.iter().all(|&c| c), "{rho}");
            let (a, b, c) = (0.23f64.powi(2), rho * 0.23 * 0.66, 0.66f64.powi(2));
            for &(n, k) in &r.boundary {
                let d2 = m2(a, b, c, 1.3 - n, 6.6 - k);
                assert!((d2 - q).abs() < 1e-8 * q, "{conf} {rho}: {d2} vs {q}");
            }
            // The extent along n is ±√q n_se (the ellipse's tangent box), to the rays'
            // resolution.
            let (n0, n1) = r.n_range();
            let half = q.sqrt() * 0.23;
            assert!((n1 - 1.3 - half).abs() < 0.01 * half && (1.3 - n0 - half).abs() < 0.01 * half);
        }
    }

    #[test]
    fn prototype_covariance_adds_to_the_estimates() {
        let e = est(1.24, 6.6, 0.23, 0.66, 0.3);
        let pc = Cov2::from_se(0.2, 0.5, -0.2).unwrap();
        let r = confidence_region(&e, Some(pc), 0.95, 120).unwrap();
        let q = chi2_2dof_quantile(0.95);
        let t = e.cov.unwrap() + pc;
        for &(n, k) in &r.boundary {
            let d2 = m2(t.nn, t.nk, t.kk, 1.24 - n, 6.6 - k);
            assert!((d2 - q).abs() < 1e-8 * q, "{d2}");
        }
    }

    #[test]
    fn near_zero_region_is_drawn_in_n_u_and_cut_at_k_0() {
        // One-sided k_se (the fit's upper deviation), estimate just above k = 0.
        let (n, k, n_se, k_se, rho) = (1.49, 0.004, 0.02, 0.03, 0.4);
        assert!(k_se >= ONE_SIDED_RATIO * k);
        let e = est(n, k, n_se, k_se, rho);
        let r = confidence_region(&e, None, 0.95, 256).unwrap();
        assert_eq!(r.plane, RegionPlane::Nu);
        let q = chi2_2dof_quantile(0.95);
        let se_u = (k + k_se) * (k + k_se) - k * k;
        let (a, b, c) = (n_se * n_se, rho * n_se * se_u, se_u * se_u);
        let mut contour = 0;
        let mut axis = 0;
        for (&(pn, pk), &on) in r.boundary.iter().zip(&r.on_contour) {
            assert!(pk >= 0.0);
            if on {
                contour += 1;
                let d2 = m2(a, b, c, n - pn, k * k - pk * pk);
                assert!((d2 - q).abs() < 1e-8 * q, "{d2} vs {q}");
            } else {
                // Cut by the axis: on it and inside the (n, u) ellipse.
                axis += 1;
                assert_eq!(pk, 0.0);
                assert!(m2(a, b, c, n - pn, k * k) <= q * (1.0 + 1e-9));
            }
        }
        assert!(contour > 100 && axis > 20, "{contour} {axis}");
        // Not the symmetric ellipse of k_se: the top reaches √(k² + √q se_u)-ish, far
        // above k + √q k_se · (1 − ρ²)... and certainly not below zero.
        let (_, k1) = r.k_range();
        let top = (k * k + q.sqrt() * se_u).sqrt();
        assert!((k1 - top).abs() < 0.02 * top, "{k1} vs {top}");
    }

    #[test]
    fn region_joins_both_planes_where_the_test_changes_plane() {
        // k = 4 k_se: the estimate is in (n, k), but prototypes below 3 k_se are tested
        // in (n, u).
        let e = est(1.5, 0.2, 0.05, 0.05, 0.0);
        let r = confidence_region(&e, None, 0.95, 360).unwrap();
        match r.plane {
            RegionPlane::Mixed { below_k } => assert!((below_k - 0.15).abs() < 1e-12),
            other => panic!("{other:?}"),
        }
        let on = r.on_contour.iter().filter(|&&c| c).count();
        assert!(on >= 300, "{on}");
        for (&(pn, pk), &c) in r.boundary.iter().zip(&r.on_contour) {
            if c {
                let p = proto("x", pn, pk, None);
                let d = Classifier::set_distance(&e, &p).unwrap();
                assert!((d - r.threshold).abs() < 1e-9 * r.threshold);
            }
        }
    }

    #[test]
    fn a_prototype_is_a_candidate_exactly_when_inside_its_drawn_region() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut checked = 0;
        for trial in 0..40 {
            let (n_se, k_se) = (0.05 + 0.3 * uniform(), 0.05 + 0.3 * uniform());
            let rho = 1.6 * uniform() - 0.8;
            let e = est(
                1.0 + 2.0 * uniform(),
                0.2 + 4.0 * uniform(),
                n_se,
                k_se,
                rho,
            );
            let with_cov = trial % 2 == 1;
            let protos: Vec<Prototype> = (0..12)
                .map(|i| {
                    let cov = with_cov.then(|| Cov2::from_se(0.1, 0.2, 0.1).unwrap());
                    proto(
                        &format!("m{i}"),
                        e.n + (uniform() - 0.5) * 6.0 * n_se,
                        (e.k + (uniform() - 0.5) * 6.0 * k_se).max(0.0),
                        cov,
                    )
                })
                .collect();
            let clf = Classifier::new(protos.clone(), ClassifierConfig::set(0.95)).unwrap();
            let d = clf.classify(&e);
            let regions = decision_regions(&e, &clf, 720);
            assert!(!regions.is_empty());
            assert_eq!(regions.len(), 1, "one covariance for all prototypes");
            let r = &regions[0].region;
            for (i, p) in protos.iter().enumerate() {
                let dist = Classifier::set_distance(&e, p).unwrap();
                // Points very near the boundary are left out (polygon resolution).
                if (dist - r.threshold).abs() < 0.02 * r.threshold {
                    continue;
                }
                let candidate = d.candidates.iter().any(|c| c.index == i);
                assert_eq!(
                    inside_polygon(&r.boundary, (p.n, p.k)),
                    candidate,
                    "trial {trial} prototype {i} at distance {dist}"
                );
                checked += 1;
            }
            // The regions' prototypes: every candidate and the nearest other class.
            let listed = &regions[0].prototypes;
            assert_eq!(listed.len(), (d.candidates.len() + 1).min(protos.len()));
            for c in &d.candidates {
                assert!(listed.contains(&c.index));
            }
        }
        assert!(checked > 300, "{checked}");
    }

    #[test]
    fn region_extent_is_the_traced_regions_span() {
        let pc = Cov2::from_se(0.02, 0.05, 0.3);
        for (e, pc) in [
            (est(1.3, 6.6, 0.23, 0.66, 0.99), None),
            (est(1.3, 6.6, 0.23, 0.66, -0.4), pc),
            (est(1.5, 0.2, 0.05, 0.05, 0.0), None),
            (est(1.49, 0.004, 0.02, 0.03, 0.4), pc),
        ] {
            let (plane, n, k) = region_extent(&e, pc, 0.95).unwrap();
            let r = confidence_region(&e, pc, 0.95, 2048).unwrap();
            assert_eq!(plane, r.plane);
            let (tn, tk) = (r.n_range(), r.k_range());
            for (a, b) in [(n.0, tn.0), (n.1, tn.1), (k.0, tk.0), (k.1, tk.1)] {
                assert!(
                    (a - b).abs() < 2e-3 * (n.1 - n.0).max(k.1 - k.0),
                    "{a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn explanation_lists_candidates_region_and_answer() {
        let protos = vec![
            proto("gold", 0.2, 3.3, None),
            proto("copper", 0.25, 3.4, None),
            proto("silver", 0.05, 4.3, None),
        ];
        let clf = Classifier::new(protos, ClassifierConfig::set(0.95)).unwrap();
        let e = est(0.22, 3.35, 0.05, 0.1, 0.2);
        let d = clf.classify(&e);
        let s = explain("t1", &e, &d, &clf, 3);
        assert!(s.starts_with("t1: ambiguous"), "{s}");
        assert!(
            s.contains("consistent at 95% (Mahalanobis <= 2.448): gold (metal)")
                && s.contains("copper (metal)")
                && s.contains("all metal"),
            "{s}"
        );
        assert!(s.contains("95% region (Mahalanobis <= 2.448): n "), "{s}");
        assert!(s.contains("in (n, k)"), "{s}");
        // n range of the region: 0.22 ± 2.448 · 0.05.
        assert!(s.contains("n 0.098–0.342"), "{s}");
        let far = est(2.0, 1.0, 0.05, 0.1, 0.0);
        let d = clf.classify(&far);
        let s = explain("t2", &far, &d, &clf, 3);
        assert!(s.starts_with("t2: unknown") && s.contains(": none"), "{s}");
        assert!(s.contains("region"), "{s}");
    }
}
