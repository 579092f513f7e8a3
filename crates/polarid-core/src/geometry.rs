//! Scattering geometry: the local incidence angle `β` (eq. 5) and the facet tilt `θ`
//! (eq. 4), for any azimuth difference `φ = φr − φi` (`φ = π`: in the plane of
//! incidence, on the far side from the source — the paper's geometry).

/// Half the angle between the source and camera directions, eq. (5):
/// `cos 2β = cos θi cos θr + sin θi sin θr cos φ`. All angles in radians.
///
/// In the plane of incidence (`φ = π`) this is eq. (10), `β = (θi + θr)/2`.
#[inline]
pub fn beta(theta_i: f64, theta_r: f64, phi: f64) -> f64 {
    let c2b = (theta_i.cos() * theta_r.cos() + theta_i.sin() * theta_r.sin() * phi.cos())
        .clamp(-1.0, 1.0);
    0.5 * c2b.acos()
}
