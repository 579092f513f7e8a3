//! The Priest–Meier microfacet polarimetric BRDF, paper eq. (3), for any geometry:
//!
//! ```text
//!              M(β) · exp(−tan²θ / (2σ²))
//! F = ───────────────────────────────────────      [sr⁻¹]     (eq. 3)
//!      8π σ² cos⁴θ · cos θi · cos θr
//! ```
//!
//! with `M(β)` the Fresnel reflection Mueller matrix ([`crate::fresnel`]) at the local
//! incidence angle `β` (eq. 5), `θ` the facet tilt (eq. 4) and `σ` the standard
//! deviation of the facet slope along one axis. No shadowing or masking.
//!
//! Two polarization frames are provided (SCATMECH's `"plane"` and `"psps"`; see
//! `data/oracles/README.md`):
//!
//! - **local** (facet) frame: for both beams `s` is perpendicular to the plane that
//!   contains the incident and reflected directions (`s ∥ u_i × u_r`) and `p = k × s`,
//!   `k` the propagation direction. This is eq. (3) as written: `m01 = m10`,
//!   `m11 = m00`, `m02 = m12 = m20 = m21 = 0`.
//! - **global** s/p frame: for each beam `s = unit(z × k)` (perpendicular to the plane
//!   of that beam and the mean normal) and `p = k × s`. For a beam along `z` the
//!   limit `θ → 0` at the beam's azimuth is used: `s = (−sin ψ, cos ψ, 0)` for a beam
//!   towards azimuth `ψ` (the incident beam comes from azimuth 0 and propagates
//!   towards azimuth π). Where the source and camera directions coincide (exact
//!   retro-reflection, `β = 0`) the local plane is undefined; `M(0)` is invariant under
//!   a common rotation of both bases, so any `s ⊥ u_i` is used.
//!
//! Stokes vectors: `S1 = I_s − I_p`, `S2 = I(s+p) − I(s−p)` (SCATMECH). A change of
//! basis `s' = cos η s + sin η p` acts on `(S0, S1, S2)` as
//! `R(η) = [[1,0,0],[0,cos 2η, sin 2η],[0,−sin 2η, cos 2η]]`, and
//! `F_global = R(η_r) · F_local · R(−η_i)`. The angles are never formed: `cos 2η`
//! and `sin 2η` come from dot products of the basis vectors.

use crate::dop::{self, BetaTerms};
use crate::error::{CoreError, Result, ensure_finite};
use crate::fresnel::Fresnel;
use crate::geometry::ScatterGeometry;
use crate::geometry::vec3::{cross, dot};

/// A 3×3 linear-polarization Mueller matrix (row-major, `[row][column]`).
pub type Mueller3 = [[f64; 3]; 3];

/// The pBRDF of one material at one geometry.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pbrdf {
    /// Eq. (3) in the local facet frame, sr⁻¹.
    pub local: Mueller3,
    /// Eq. (3) in the global s/p (`psps`) frame, sr⁻¹.
    pub global: Mueller3,
    /// Local incidence angle `β` on the facets, radians (eq. 5).
    pub beta: f64,
    /// Facet tilt `θ` from the mean normal, radians (eq. 4).
    pub facet_tilt: f64,
    /// Degree of linear polarization for unpolarized input,
    /// `√(m10² + m20²)/m00` — eq. (9) at `β`, frame-invariant.
    pub dolp: f64,
}

/// The scalar factor of eq. (3) that multiplies `M(β)`:
/// `exp(−tan²θ/(2σ²)) / (8π σ² cos⁴θ cos θi cos θr)`, sr⁻¹.
///
/// Returns 0 for grazing geometries (`cos θi cos θr = 0` or `θ = 90°`).
#[inline]
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn facet_factor(sigma: f64, g: &ScatterGeometry) -> f64 {
    let s2 = sigma * sigma;
    let den = 8.0 * std::f64::consts::PI * s2 * g.cos2_tilt * g.cos2_tilt * g.cos_i * g.cos_r;
    if !(den > 0.0) || !g.tan2_tilt.is_finite() {
        return 0.0;
    }
    (-g.tan2_tilt / (2.0 * s2)).exp() / den
}

/// Check the arguments of the pBRDF: `n > 0`, `k >= 0`, `σ > 0` finite, zenith angles
/// in `[0, π/2)`, `φ` finite.
pub fn validate(n: f64, k: f64, sigma: f64, theta_i: f64, theta_r: f64, phi: f64) -> Result<()> {
    let check = |name: &'static str, v: f64, ok: bool, expected: &'static str| {
        ensure_finite(name, v)?;
        if ok {
            Ok(())
        } else {
            Err(CoreError::OutOfRange {
                name,
                value: v,
                expected,
            })
        }
    };
    check("n", n, n > 0.0, "n > 0")?;
    check("k", k, k >= 0.0, "k >= 0")?;
    check("sigma", sigma, sigma > 0.0, "sigma > 0")?;
    let half_pi = std::f64::consts::FRAC_PI_2;
    check(
        "theta_i",
        theta_i,
        (0.0..half_pi).contains(&theta_i),
        "[0, 90) degrees",
    )?;
    check(
        "theta_r",
        theta_r,
        (0.0..half_pi).contains(&theta_r),
        "[0, 90) degrees",
    )?;
    ensure_finite("phi", phi)?;
    Ok(())
}

/// Eq. (3) for `N = n + ik`, slope parameter `sigma`, source zenith `theta_i`, camera
/// zenith `theta_r` and azimuth difference `phi = φr − φi` (radians; `φ = π` is the
/// forward in-plane geometry). Validates the arguments (see [`validate`]).
pub fn pbrdf(n: f64, k: f64, sigma: f64, theta_i: f64, theta_r: f64, phi: f64) -> Result<Pbrdf> {
    validate(n, k, sigma, theta_i, theta_r, phi)?;
    let g = ScatterGeometry::new(theta_i, theta_r, phi);
    let mut out = Pbrdf::default();
    pbrdf_geometry(n, k, sigma, &g, &mut out);
    Ok(out)
}

/// Eq. (3) at a precomputed geometry, without argument checks (for simulators that
/// evaluate many materials per geometry). Never produces NaN for finite arguments with
/// `n > 0`, `k >= 0`, `sigma > 0`.
pub fn pbrdf_geometry(n: f64, k: f64, sigma: f64, g: &ScatterGeometry, out: &mut Pbrdf) {
    let fr = Fresnel::from_sin_cos(n, k, g.sin2_beta, g.cos_beta);
    let scale = facet_factor(sigma, g);
    let local = fr.mueller3().map(|r| r.map(|v| v * scale));
    out.local = local;
    out.global = to_global(&local, g);
    out.beta = g.beta();
    out.facet_tilt = g.facet_tilt();
    let t = BetaTerms {
        s2: g.sin2_beta,
        c: g.cos_beta,
        c2: g.cos_beta * g.cos_beta,
        s4: g.sin2_beta * g.sin2_beta,
    };
    out.dolp = dop::dop_terms(n, k, &t);
}

/// `(cos 2η, sin 2η)` of the basis change from the local `s` (direction `w`, not
/// normalized, `w ⊥ k`) to the global basis `(s_g, p_g)` of a beam:
/// `cos η ∝ s_g·w`, `sin η ∝ s_g·(k × w) = −p_g·w`.
#[inline]
fn rot2(w: &[f64; 3], s_g: &[f64; 3], p_g: &[f64; 3]) -> (f64, f64) {
    let c = dot(*s_g, *w);
    let s = -dot(*p_g, *w);
    let r2 = c * c + s * s;
    if r2 > 0.0 {
        ((c * c - s * s) / r2, 2.0 * c * s / r2)
    } else {
        (1.0, 0.0)
    }
}

/// Rotate a Mueller matrix from the local facet frame to the global s/p frame of
/// [`ScatterGeometry`] `g` (see the module documentation).
pub fn to_global(local: &Mueller3, g: &ScatterGeometry) -> Mueller3 {
    let (ui, ur) = (&g.u_i, &g.u_r);
    // Normal of the scattering plane (any vector ⊥ u_i when u_i ∥ u_r; (0, 1, 0) is
    // ⊥ u_i since the source is at azimuth 0).
    let mut w = cross(*ui, *ur);
    if dot(w, w) <= 1e-300 {
        w = [0.0, 1.0, 0.0];
    }
    // Incident beam: k_i = −u_i, s = unit(z × k_i) = (0, −1, 0) (also the θi → 0
    // limit), p = k_i × s = (−cos θi, 0, sin θi).
    let (si, ci) = (ui[0], ui[2]);
    let s_gi = [0.0, -1.0, 0.0];
    let p_gi = [-ci, 0.0, si];
    // Reflected beam: k_r = u_r at azimuth φ: s = (−sin φ, cos φ, 0),
    // p = k_r × s = (−cos θr cos φ, −cos θr sin φ, sin θr).
    let (sp, cp) = g.phi.sin_cos();
    let (sr, cr) = (g.theta_r.sin(), g.cos_r);
    let s_gr = [-sp, cp, 0.0];
    let p_gr = [-cr * cp, -cr * sp, sr];
    let (ci2, si2) = rot2(&w, &s_gi, &p_gi);
    let (cr2, sr2) = rot2(&w, &s_gr, &p_gr);
    // A = F · R(−η_i): R(−η) = [[1,0,0],[0,c,−s],[0,s,c]].
    let mut a = [[0.0; 3]; 3];
    for (ar, fr) in a.iter_mut().zip(local.iter()) {
        ar[0] = fr[0];
        ar[1] = fr[1] * ci2 + fr[2] * si2;
        ar[2] = -fr[1] * si2 + fr[2] * ci2;
    }
    // R(η_r) · A: R(η) = [[1,0,0],[0,c,s],[0,−s,c]].
    let mut out = [[0.0; 3]; 3];
    out[0] = a[0];
    for j in 0..3 {
        out[1][j] = cr2 * a[1][j] + sr2 * a[2][j];
        out[2][j] = -sr2 * a[1][j] + cr2 * a[2][j];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn in_plane_frames_agree() {
        let p = pbrdf(1.5, 0.2, 0.2, 0.4, 0.6, PI).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((p.local[i][j] - p.global[i][j]).abs() < 1e-14 * p.local[0][0]);
            }
        }
        assert!((p.beta - 0.5).abs() < 1e-15);
    }

    #[test]
    fn degenerate_frames_no_nan() {
        for &(ti, tr, phi) in &[
            (0.0, 0.0, 0.0),
            (0.0, 0.0, 1.0),
            (0.5, 0.5, 0.0),
            (0.0, 0.7, 2.0),
            (0.7, 0.0, 2.0),
            (1.2, 1.2, 0.0),
        ] {
            let p = pbrdf(1.5, 1.0, 0.3, ti, tr, phi).unwrap();
            assert!(
                p.local
                    .iter()
                    .chain(p.global.iter())
                    .flatten()
                    .all(|v| v.is_finite()),
                "{ti} {tr} {phi}: {p:?}"
            );
            assert!((p.global[0][0] - p.local[0][0]).abs() <= 1e-15 * p.local[0][0]);
        }
    }

    #[test]
    fn rejects_bad_arguments() {
        assert!(pbrdf(1.5, -0.1, 0.2, 0.1, 0.2, 0.0).is_err());
        assert!(pbrdf(1.5, 0.0, 0.0, 0.1, 0.2, 0.0).is_err());
        assert!(pbrdf(1.5, 0.0, 0.1, PI / 2.0, 0.2, 0.0).is_err());
        assert!(pbrdf(f64::NAN, 0.0, 0.1, 0.1, 0.2, 0.0).is_err());
    }
}
