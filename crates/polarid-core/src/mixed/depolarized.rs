//! The `depolarized` rule of the specular (DoLP-only) fit: when every measured DoLP is
//! below a small threshold, eq. (9) can only "explain" the data with an extreme `k`, and
//! DoLP alone cannot tell the surface from a depolarizing one (see `docs/MIXED.md`).
//!
//! # Reference
//! Thilak, Creusere & Voelz, ICIP 2007, eq. (9).

/// Below this largest DoLP (over all captures) a target is flagged `depolarized` by the
/// specular (DoLP-only) fit: see [`depolarized_reason`].
pub const DEPOLARIZED_MAX_DOLP: f64 = 0.02;

/// The reason a DoLP-only (specular) fit must not be trusted because the light is
/// depolarized: every DoLP below `threshold` (default [`DEPOLARIZED_MAX_DOLP`]).
///
/// Rule (documented in `docs/MIXED.md`): a diffuse (Lambertian) surface has DoLP 0 at
/// every geometry; among specular surfaces only the most weakly polarizing metals
/// (silver: DoLP ≤ 0.011 for β ≤ 75°) stay below 0.02 everywhere, while aluminum
/// exceeds 0.027 at β ≥ 40°. Below the threshold at every capture, eq. (9) can only
/// "explain" the data with an extreme `k`, and DoLP alone cannot tell the surface from a
/// depolarizing one; the mixed model (which uses `S0`) can.
pub fn depolarized_reason(dolp: &[f64], threshold: f64) -> Option<String> {
    let max = dolp.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !dolp.is_empty() && max < threshold {
        Some(format!(
            "DoLP below {threshold} at every source position (max {max:.4}): indistinguishable from a depolarizing diffuse surface; try --reflectance mixed"
        ))
    } else {
        None
    }
}
