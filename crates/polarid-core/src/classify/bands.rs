//! Several spectral bands at once (colour polarization cameras, multi-band libraries): a
//! target's feature is its `(n, k)` at every band it was measured in, each with its own
//! covariance.
//!
//! # Distances over bands
//!
//! An estimate and a prototype are compared on the bands they have in common, `C` (matched
//! by wavelength within [`BAND_TOLERANCE_NM`]; a single band without a wavelength matches
//! the other side's single band, so single-band files without `wavelength_nm` work as
//! before). With `d_b` the single-band distance of band `b` (Euclidean, Mahalanobis, or the
//! set rule's distance, see [`Classifier`](super::Classifier)):
//!
//! ```text
//! d = √(Σ_{b ∈ C} d_b²)                 (one band: d = d_b, bit for bit)
//! d_M² = Σ_b Δ_bᵀ (Σ_est,b + Σ_proto,b)⁻¹ Δ_b      (block-diagonal covariance)
//! ```
//!
//! The covariance is block-diagonal across bands: each band's `(n, k)` is fitted from its
//! own DoLP images, whose noise is independent between colour channels. The bands do share
//! the geometry (β), whose systematic error makes the bands' errors correlated; neglecting
//! that correlation makes the test slightly too strict, not too lenient, only when the
//! geometry error dominates (docs/BANDS.md).
//!
//! Under the block-diagonal model `d_M²` is χ² with `2·|C|` degrees of freedom, so the set
//! rule and the χ² gate compare it with [`chi2_quantile`]`(p, 2·|C|)`, each prototype at
//! its own `|C|`.
//!
//! Bands of an estimate whose fit is not `ok` are left out (the target is compared on the
//! others, and [`Decision::bands_used`](super::Decision::bands_used) says which were used);
//! an estimate with no `ok` band is not classified.

use super::{Cov2, Estimate, Prototype};
use crate::status::FitStatus;

/// Two wavelengths closer than this (nm) are the same band.
pub const BAND_TOLERANCE_NM: f64 = 0.5;

/// Whether two band wavelengths are the same band: both known and within
/// [`BAND_TOLERANCE_NM`].
pub fn same_band(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => (a - b).abs() <= BAND_TOLERANCE_NM,
        _ => false,
    }
}

/// A prototype's `(n, k)` in one band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandPoint {
    /// Centre wavelength of the band, nm (`None`: not given, single-band data).
    pub wavelength_nm: Option<f64>,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index (`k >= 0`).
    pub k: f64,
    /// Covariance of `(n, k)` when the prototype is itself an estimate.
    pub cov: Option<Cov2>,
}

/// A labelled point measured in one or several bands: a multi-band training target or a
/// multi-band library material.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiPrototype {
    /// Class (material) name.
    pub class: String,
    /// Broad category (`metal`, `dielectric`, `semiconductor`, `other`) when known.
    pub category: Option<String>,
    /// Where the prototype came from.
    pub source: String,
    /// Its `(n, k)` per band (at least one; no two the same band).
    pub bands: Vec<BandPoint>,
}

impl From<Prototype> for MultiPrototype {
    /// A single-band prototype (band without a wavelength).
    fn from(p: Prototype) -> Self {
        Self {
            class: p.class,
            category: p.category,
            source: p.source,
            bands: vec![BandPoint {
                wavelength_nm: None,
                n: p.n,
                k: p.k,
                cov: p.cov,
            }],
        }
    }
}

impl MultiPrototype {
    /// Band `i` as a single-band [`Prototype`] (class, category and source copied).
    /// `None` when there is no band `i`.
    pub fn band_prototype(&self, i: usize) -> Option<Prototype> {
        self.bands.get(i).map(|b| Prototype {
            class: self.class.clone(),
            n: b.n,
            k: b.k,
            cov: b.cov,
            category: self.category.clone(),
            source: self.source.clone(),
        })
    }
}

/// One band of a [`MultiEstimate`].
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateBand {
    /// Centre wavelength of the band, nm (`None`: not given).
    pub wavelength_nm: Option<f64>,
    /// The band's estimate (with its covariance and fit status).
    pub estimate: Estimate,
}

/// A target's estimates in one or several bands.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiEstimate {
    /// The bands (at least one to be classified).
    pub bands: Vec<EstimateBand>,
}

impl From<Estimate> for MultiEstimate {
    /// A single-band estimate (band without a wavelength).
    fn from(estimate: Estimate) -> Self {
        Self {
            bands: vec![EstimateBand {
                wavelength_nm: None,
                estimate,
            }],
        }
    }
}

impl MultiEstimate {
    /// `ok` when some band's fit is `ok`, else the first band's status
    /// ([`FitStatus::InvalidInput`] without bands).
    pub fn fit_status(&self) -> FitStatus {
        if self.bands.iter().any(|b| b.estimate.fit_status.is_ok()) {
            FitStatus::Ok
        } else {
            self.bands
                .first()
                .map_or(FitStatus::InvalidInput, |b| b.estimate.fit_status)
        }
    }

    /// This estimate as a prototype of `class` (its `ok` bands with finite values).
    pub fn to_prototype(&self, class: &str, source: &str) -> MultiPrototype {
        MultiPrototype {
            class: class.to_string(),
            category: None,
            source: source.to_string(),
            bands: self
                .bands
                .iter()
                .filter(|b| {
                    b.estimate.fit_status.is_ok()
                        && b.estimate.n.is_finite()
                        && b.estimate.k.is_finite()
                })
                .map(|b| BandPoint {
                    wavelength_nm: b.wavelength_nm,
                    n: b.estimate.n,
                    k: b.estimate.k,
                    cov: b.estimate.cov,
                })
                .collect(),
        }
    }
}

/// The pairs `(estimate band, prototype band)` compared: a single band without a
/// wavelength on either side matches the other side's single band; otherwise bands match
/// by wavelength ([`same_band`]). In the estimate's band order.
pub(super) fn common_bands(est: &[&EstimateBand], p: &[BandPoint]) -> Vec<(usize, usize)> {
    if est.len() == 1
        && p.len() == 1
        && (est[0].wavelength_nm.is_none() || p[0].wavelength_nm.is_none())
    {
        return vec![(0, 0)];
    }
    let mut out = Vec::with_capacity(est.len());
    for (i, e) in est.iter().enumerate() {
        if let Some(j) = p
            .iter()
            .position(|b| same_band(e.wavelength_nm, b.wavelength_nm))
        {
            out.push((i, j));
        }
    }
    out
}

/// The χ² quantile with `dof` degrees of freedom, `dof` even (`2·bands`): the `x` with
/// `P(χ²_dof ≤ x) = p`, where for `dof = 2m`
///
/// ```text
/// P(χ²_2m ≤ x) = 1 − e^(−x/2) Σ_{j<m} (x/2)^j / j!
/// ```
///
/// `dof = 2` is [`chi2_2dof_quantile`](super::chi2_2dof_quantile) exactly (`−2 ln(1 − p)`);
/// larger `dof` are solved by bisection to machine precision. NaN unless `p` is in
/// `(0, 1)` and `dof` is even and positive.
pub fn chi2_quantile(p: f64, dof: usize) -> f64 {
    if !(p > 0.0 && p < 1.0) || dof == 0 || !dof.is_multiple_of(2) {
        return f64::NAN;
    }
    if dof == 2 {
        return super::chi2_2dof_quantile(p);
    }
    let m = dof / 2;
    // Upper tail Q(x) = e^(−x/2) Σ_{j<m} (x/2)^j / j!, decreasing in x.
    let upper = |x: f64| {
        let h = x / 2.0;
        let (mut term, mut sum) = (1.0f64, 1.0f64);
        for j in 1..m {
            term *= h / j as f64;
            sum += term;
        }
        (-h).exp() * sum
    };
    let target = 1.0 - p;
    let (mut lo, mut hi) = (0.0f64, dof as f64 + 10.0);
    while upper(hi) > target {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if upper(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-15 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_quantiles_match_tables() {
        // χ² tables: 95% quantiles for 2, 4, 6 dof; 99% for 6 dof.
        assert!((chi2_quantile(0.95, 2) - 5.991_464_547_107_979).abs() < 1e-12);
        assert!((chi2_quantile(0.95, 4) - 9.487_729_036_781_154).abs() < 1e-9);
        assert!((chi2_quantile(0.95, 6) - 12.591_587_243_743_977).abs() < 1e-9);
        assert!((chi2_quantile(0.99, 6) - 16.811_893_829_770_93).abs() < 1e-9);
        assert!(chi2_quantile(0.95, 3).is_nan());
        assert!(chi2_quantile(1.0, 4).is_nan());
    }

    #[test]
    fn bands_match_by_wavelength_or_single() {
        let e = |wl: Option<f64>| EstimateBand {
            wavelength_nm: wl,
            estimate: Estimate::point(1.0, 1.0),
        };
        let b = |wl: Option<f64>| BandPoint {
            wavelength_nm: wl,
            n: 1.0,
            k: 1.0,
            cov: None,
        };
        let (e450, e550, e0) = (e(Some(450.0)), e(Some(550.0)), e(None));
        assert_eq!(common_bands(&[&e0], &[b(Some(650.0))]), vec![(0, 0)]);
        assert_eq!(common_bands(&[&e450], &[b(None)]), vec![(0, 0)]);
        assert!(common_bands(&[&e450], &[b(Some(650.0))]).is_empty());
        assert_eq!(
            common_bands(
                &[&e450, &e550],
                &[b(Some(650.0)), b(Some(550.2)), b(Some(450.0))]
            ),
            vec![(0, 2), (1, 1)]
        );
        assert!(common_bands(&[&e0], &[b(Some(450.0)), b(Some(550.0))]).is_empty());
    }
}
