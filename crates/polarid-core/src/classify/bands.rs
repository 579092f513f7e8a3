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
//! **One surface layer over all bands.** The fit's error model allows an unmodelled surface
//! layer (docs/ERRORS.md), and folds it into each band's covariance. A layer has one
//! thickness in nanometres and one index however many bands see it, so its part is NOT
//! independent between bands. When a band carries the fit's layer shifts
//! ([`FilmShifts`]: `h_bj`, the `(n, k)` shift in band `b` of a layer of index `N_j` of
//! one standard thickness), each side's layer blocks `Σ_j h_bj h_bjᵀ` are taken out of
//! its band covariances and replaced by ONE rank-3 term over the stacked bands:
//!
//! ```text
//! d_M² = Δᵀ (B + H_est H_estᵀ + H_proto H_protoᵀ)⁻¹ Δ,   B = blockdiag_b(Σ_b − Σ_j h_bj h_bjᵀ)
//! ```
//!
//! (`H`: `2|C| × 3`, column `j` the shifts `h_bj` stacked over the bands; exact under the
//! fit's linearisation). One band is the per-band covariance again, bit for bit (the
//! single-band path is taken). The set rule's bands compared in `(n, u = k²)` keep their
//! own allowance.
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
pub use crate::systematic::FilmShifts;
use crate::systematic::{cholesky, forward};

/// Two wavelengths closer than this (nm) are the same band.
pub const BAND_TOLERANCE_NM: f64 = 0.5;

/// The extinction coefficient below which a material is transparent: told by its index
/// alone (`hypothesis`, "Transparent materials and the open world").
pub const TRANSPARENT_K: f64 = 0.01;

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
    /// The fit's surface-layer shifts when the prototype is an estimate whose fit wrote
    /// them (part of `cov`; correlated across the prototype's bands, see
    /// [`FilmShifts`]).
    pub film: Option<FilmShifts>,
    /// The index `(n, k)` of the material's native surface layer in this band (library
    /// materials as they are found, [`NativeLayer`]); `None`: no layer known.
    pub layer: Option<(f64, f64)>,
}

/// A material's native surface layer as it is found (an oxide or adsorbed
/// contamination): its name and the range of thicknesses it has on real surfaces. Its
/// index per band is [`BandPoint::layer`]. Hypothesis tests take the thickness as a
/// bounded nuisance within `[min_nm, max_nm]`.
#[derive(Debug, Clone, PartialEq)]
pub struct NativeLayer {
    /// Layer material, e.g. `Al2O3`, `Cu2O`, `contamination`.
    pub name: String,
    /// Thinnest layer found on real surfaces, nm (`≥ 0`).
    pub min_nm: f64,
    /// Thickest layer found on real surfaces, nm (`≥ min_nm`).
    pub max_nm: f64,
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
    /// Its native surface layer (library materials as they are found), when known.
    pub surface: Option<NativeLayer>,
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
                film: None,
                layer: None,
            }],
            surface: None,
        }
    }
}

impl MultiPrototype {
    /// Its bands at `wavelengths` (nm; a band without a wavelength is at every one).
    pub fn bands_at<'a>(&'a self, wavelengths: &'a [f64]) -> impl Iterator<Item = &'a BandPoint> {
        self.bands.iter().filter(|b| {
            b.wavelength_nm.is_none()
                || wavelengths
                    .iter()
                    .any(|&x| same_band(b.wavelength_nm, Some(x)))
        })
    }

    /// Whether the material is transparent (`k <` [`TRANSPARENT_K`])
    /// in each of its bands at `wavelengths` ([`MultiPrototype::bands_at`]).
    pub fn transparent_at(&self, wavelengths: &[f64]) -> bool {
        self.bands_at(wavelengths).all(|b| b.k < TRANSPARENT_K)
    }

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
    /// The fit's surface-layer shifts of this band, when the fit wrote them (part of the
    /// estimate's covariance; correlated across the target's bands, see [`FilmShifts`]).
    pub film: Option<FilmShifts>,
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
                film: None,
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
                    film: b.film,
                    layer: None,
                })
                .collect(),
            surface: None,
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

/// One band of a comparison with correlated surface layers ([`joint_distance2`]).
pub(super) struct JointBand {
    /// `Δ = (n̂ − n_p, k̂ − k_p)`.
    pub delta: [f64; 2],
    /// The band's covariance without the layers' blocks `Σ_j h_j h_jᵀ` of the sides whose
    /// shifts are given (`[nn, nk, kk]`; estimate's plus prototype's).
    pub base: [f64; 3],
    /// The estimate's layer shifts in this band (`None`: its layer allowance, if any, is
    /// in `base`, independent of the other bands).
    pub est_film: Option<FilmShifts>,
    /// The prototype's layer shifts in this band.
    pub proto_film: Option<FilmShifts>,
}

/// The squared Mahalanobis distance over several bands with ONE surface layer per side
/// seen in all its bands:
///
/// ```text
/// d² = Δᵀ (B + H_est H_estᵀ + H_proto H_protoᵀ)⁻¹ Δ
/// ```
///
/// `Δ` and `B = blockdiag(base_b)` stacked over the bands (`2m`), `H` the `2m × 3`
/// matrix of a side's layer shifts (column `j`: the layer of index `N_j` of one standard
/// thickness in nanometres, the same at every band; zero rows where a band has no
/// shifts). Solved by Cholesky; `None` when the matrix is not positive definite.
pub(super) fn joint_distance2(bands: &[JointBand]) -> Option<f64> {
    let m = 2 * bands.len();
    let mut a = vec![0.0; m * m];
    let mut d = vec![0.0; m];
    for (b, jb) in bands.iter().enumerate() {
        let (r, c) = (2 * b, 2 * b + 1);
        a[r * m + r] = jb.base[0];
        a[r * m + c] = jb.base[1];
        a[c * m + r] = jb.base[1];
        a[c * m + c] = jb.base[2];
        d[r] = jb.delta[0];
        d[c] = jb.delta[1];
    }
    for side in 0..2 {
        let col = |b: &JointBand| if side == 0 { b.est_film } else { b.proto_film };
        for j in 0..3 {
            let h: Vec<f64> = bands
                .iter()
                .flat_map(|b| col(b).map_or([0.0, 0.0], |f| f.0[j]))
                .collect();
            for r in 0..m {
                for c in 0..m {
                    a[r * m + c] += h[r] * h[c];
                }
            }
        }
    }
    // Cholesky a = L Lᵀ, then d² = |L⁻¹ Δ|².
    let l = cholesky(&a, m)?;
    let q = forward(&l, &d, m).iter().fold(0.0, |q, x| q + x * x);
    q.is_finite().then_some(q)
}

/// A covariance `c` without the layer block of `film`: `(base, film)` when `c − Σ h hᵀ`
/// stays positive definite, else `(c, None)` (the band keeps its own allowance).
pub(super) fn strip_film(c: Cov2, film: Option<FilmShifts>) -> ([f64; 3], Option<FilmShifts>) {
    let full = [c.nn, c.nk, c.kk];
    let Some(f) = film else {
        return (full, None);
    };
    let b = f.block();
    let r = [c.nn - b[0], c.nk - b[1], c.kk - b[2]];
    let det = r[0] * r[2] - r[1] * r[1];
    if r[0] > 0.0 && r[2] > 0.0 && det > 1e-9 * c.nn * c.kk && det.is_finite() {
        (r, Some(f))
    } else {
        (full, None)
    }
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
    fn one_layer_in_all_bands_is_the_joint_covariance() {
        let f = |a: f64| FilmShifts([[a, 2.0 * a], [0.5 * a, -a], [0.0, a]]);
        let band = |dn: f64, dk: f64, a: f64| JointBand {
            delta: [dn, dk],
            base: [0.01, 0.002, 0.04],
            est_film: Some(f(a)),
            proto_film: None,
        };
        // One band: base + Σ h hᵀ, the per-band covariance.
        let one = joint_distance2(&[band(0.1, 0.2, 0.1)]).unwrap();
        let b = f(0.1).block();
        let c = Cov2 {
            nn: 0.01 + b[0],
            nk: 0.002 + b[1],
            kk: 0.04 + b[2],
        };
        assert!((one - c.mahalanobis2(0.1, 0.2).unwrap()).abs() < 1e-12);
        // Two bands whose differences are ONE layer (coefficients c = (1, -0.5, 0.3)) are
        // much closer than two whose differences need opposite layers.
        let shift = |a: f64| {
            let h = f(a).0;
            let c = [1.0, -0.5, 0.3];
            [
                c[0] * h[0][0] + c[1] * h[1][0] + c[2] * h[2][0],
                c[0] * h[0][1] + c[1] * h[1][1] + c[2] * h[2][1],
            ]
        };
        let (s1, s2) = (shift(1.0), shift(2.0));
        let same = joint_distance2(&[band(s1[0], s1[1], 1.0), band(s2[0], s2[1], 2.0)]).unwrap();
        let opposite =
            joint_distance2(&[band(s1[0], s1[1], 1.0), band(-s2[0], -s2[1], 2.0)]).unwrap();
        let c1 = [1.0, -0.5, 0.3].iter().map(|x| x * x).sum::<f64>();
        assert!(same < c1 + 1e-9, "{same}");
        assert!(opposite > 10.0 * same, "{opposite} vs {same}");
    }

    #[test]
    fn bands_match_by_wavelength_or_single() {
        let e = |wl: Option<f64>| EstimateBand {
            wavelength_nm: wl,
            estimate: Estimate::point(1.0, 1.0),
            film: None,
        };
        let b = |wl: Option<f64>| BandPoint {
            wavelength_nm: wl,
            n: 1.0,
            k: 1.0,
            cov: None,
            film: None,
            layer: None,
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
