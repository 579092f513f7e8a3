//! Scattering geometry: the local incidence angle `β` (eq. 5) and the facet tilt `θ`
//! (eq. 4), for any azimuth difference `φ = φr − φi` (`φ = π`: in the plane of
//! incidence, on the far side from the source — the paper's geometry).
//!
//! Frame: the target's mean surface normal is `+z`. The source lies at zenith `θi` and
//! azimuth `φi = 0` (in the `+x` half of the `xz` plane), the camera at zenith `θr` and
//! azimuth `φ`. [`direction`] gives the unit vector towards a direction of given zenith
//! and azimuth; the incident light propagates along `−u_i`, the reflected light along
//! `+u_r`.
//!
//! `β` and `θ` are computed from the half-vector `h = u_i + u_r` and the difference
//! `u_i − u_r`, which is exact to a few ulps for every geometry (no `acos` near ±1):
//! `cos β = |u_i + u_r|/2`, `sin β = |u_i − u_r|/2`,
//! `tan θ = |h_xy| / h_z`.
//!
//! Calibrated geometry (a real camera, a lamp at a finite distance, a distant source):
//! [`camera::PinholeCamera`] turns a pixel into a ray, [`scene_geometry::ViewGeometry`]
//! meets it with a [`scene_geometry::Plane`] and gives every pixel its own `θi`, `θr`,
//! `φ` and `β` ([`scene_geometry::PixelGeometry`], [`scene_geometry::ViewGeometry::fill`]).

pub mod camera;
pub mod scene_geometry;
pub(crate) mod vec3;

pub use camera::{Distortion, Intrinsics, PinholeCamera};
pub use scene_geometry::{GeometryMaps, PixelGeometry, Plane, RayHit, Source, ViewGeometry};

/// Unit vector of zenith angle `zenith` (from `+z`) and azimuth `azimuth` (from `+x`
/// towards `+y`), radians: `(sin θ cos φ, sin θ sin φ, cos θ)`.
#[inline]
pub fn direction(zenith: f64, azimuth: f64) -> [f64; 3] {
    let (st, ct) = zenith.sin_cos();
    let (sp, cp) = azimuth.sin_cos();
    [st * cp, st * sp, ct]
}

/// Unit vector from the surface towards the source (`φi = 0`), radians.
#[inline]
pub fn source_dir(theta_i: f64) -> [f64; 3] {
    direction(theta_i, 0.0)
}

/// Unit vector from the surface towards the camera (azimuth `φ = φr − φi`), radians.
#[inline]
pub fn camera_dir(theta_r: f64, phi: f64) -> [f64; 3] {
    direction(theta_r, phi)
}

/// Everything about one source/camera geometry that the pBRDF needs, computed once
/// (one `sin_cos` per angle, no inverse trigonometry except for the reported angles).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ScatterGeometry {
    /// `θi`, radians.
    pub theta_i: f64,
    /// `θr`, radians.
    pub theta_r: f64,
    /// `φ = φr − φi`, radians.
    pub phi: f64,
    /// Unit vector towards the source.
    pub u_i: [f64; 3],
    /// Unit vector towards the camera.
    pub u_r: [f64; 3],
    /// `cos θi`.
    pub cos_i: f64,
    /// `cos θr`.
    pub cos_r: f64,
    /// `sin²β`.
    pub sin2_beta: f64,
    /// `cos β`.
    pub cos_beta: f64,
    /// `tan²θ` of the facet tilt (`+∞` when `cos θi + cos θr = 0`).
    pub tan2_tilt: f64,
    /// `cos²θ` of the facet tilt.
    pub cos2_tilt: f64,
}

impl ScatterGeometry {
    /// Geometry for source zenith `theta_i`, camera zenith `theta_r` and azimuth
    /// difference `phi` (radians). Zenith angles are clamped to `[0, π/2]`.
    #[inline]
    pub fn new(theta_i: f64, theta_r: f64, phi: f64) -> Self {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let ti = theta_i.clamp(0.0, half_pi);
        let tr = theta_r.clamp(0.0, half_pi);
        let u_i = source_dir(ti);
        let u_r = camera_dir(tr, phi);
        let h = [u_i[0] + u_r[0], u_i[1] + u_r[1], u_i[2] + u_r[2]];
        let d = [u_i[0] - u_r[0], u_i[1] - u_r[1], u_i[2] - u_r[2]];
        let hxy2 = h[0] * h[0] + h[1] * h[1];
        let hz2 = h[2] * h[2];
        let h2 = hxy2 + hz2; // 4 cos²β
        let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]; // 4 sin²β
        let norm = h2 + d2; // 4 up to rounding
        let (sin2_beta, cos2_beta) = if norm > 0.0 {
            (d2 / norm, h2 / norm)
        } else {
            (0.0, 1.0)
        };
        let tan2_tilt = if hz2 > 0.0 { hxy2 / hz2 } else { f64::INFINITY };
        let cos2_tilt = if h2 > 0.0 { hz2 / h2 } else { 0.0 };
        Self {
            theta_i: ti,
            theta_r: tr,
            phi,
            u_i,
            u_r,
            cos_i: u_i[2],
            cos_r: u_r[2],
            sin2_beta,
            cos_beta: cos2_beta.sqrt(),
            tan2_tilt,
            cos2_tilt,
        }
    }

    /// `β`, radians, in `[0, π/2]`.
    #[inline]
    pub fn beta(&self) -> f64 {
        self.sin2_beta.sqrt().atan2(self.cos_beta)
    }

    /// Facet tilt `θ`, radians, in `[0, π/2]` (eq. 4).
    #[inline]
    pub fn facet_tilt(&self) -> f64 {
        if self.tan2_tilt.is_finite() {
            self.tan2_tilt.sqrt().atan()
        } else {
            std::f64::consts::FRAC_PI_2
        }
    }
}

/// Half the angle between the source and camera directions, eq. (5):
/// `cos 2β = cos θi cos θr + sin θi sin θr cos φ`. All angles in radians.
///
/// In the plane of incidence (`φ = π`) this is eq. (10), `β = (θi + θr)/2`.
/// Evaluated as `β = atan2(|u_i − u_r|, |u_i + u_r|)`, which is accurate also where
/// `cos 2β` is close to ±1.
#[inline]
pub fn beta(theta_i: f64, theta_r: f64, phi: f64) -> f64 {
    ScatterGeometry::new(theta_i, theta_r, phi).beta()
}

/// Tilt `θ` of the microfacets that reflect the source into the camera, measured from
/// the mean normal, eq. (4): `cos θ = (cos θi + cos θr) / (2 cos β)`. Radians, in
/// `[0, π/2]`; evaluated as `atan(|h_xy| / h_z)` with `h = u_i + u_r`.
#[inline]
pub fn facet_tilt(theta_i: f64, theta_r: f64, phi: f64) -> f64 {
    ScatterGeometry::new(theta_i, theta_r, phi).facet_tilt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_plane() {
        let (ti, tr) = (0.3, 0.7);
        let b = beta(ti, tr, std::f64::consts::PI);
        assert!((b - 0.5).abs() < 1e-15, "{b}");
        let t = facet_tilt(ti, tr, std::f64::consts::PI);
        assert!((t - 0.2).abs() < 1e-15, "{t}");
    }

    #[test]
    fn matches_eq5_and_eq4() {
        for &(ti, tr, phi) in &[(0.2, 1.1, 0.4), (1.3, 0.1, 2.5), (0.7, 0.7, 4.0)] {
            let c2b = f64::cos(ti) * f64::cos(tr) + f64::sin(ti) * f64::sin(tr) * f64::cos(phi);
            let b = 0.5 * c2b.acos();
            assert!((beta(ti, tr, phi) - b).abs() < 1e-14);
            let th = ((f64::cos(ti) + f64::cos(tr)) / (2.0 * b.cos())).acos();
            assert!((facet_tilt(ti, tr, phi) - th).abs() < 1e-13);
        }
    }

    #[test]
    fn small_beta_is_accurate() {
        // Backscatter with a tiny angle between source and camera: acos(cos 2β) would
        // lose half the digits.
        let b = beta(0.5, 0.5 + 2e-9, 0.0);
        assert!((b - 1e-9).abs() < 1e-15, "{b}");
    }

    #[test]
    fn degenerate_is_finite() {
        let g = ScatterGeometry::new(0.0, 0.0, 1.0);
        assert_eq!(g.beta(), 0.0);
        assert_eq!(g.facet_tilt(), 0.0);
        let g = ScatterGeometry::new(
            std::f64::consts::FRAC_PI_2,
            std::f64::consts::FRAC_PI_2,
            std::f64::consts::PI,
        );
        assert!(g.beta().is_finite() && g.facet_tilt().is_finite());
    }
}
