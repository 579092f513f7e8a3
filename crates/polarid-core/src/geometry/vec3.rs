//! Small 3-vector helpers for the calibrated geometry (private).

use crate::error::{CoreError, Result};

pub(crate) type V3 = [f64; 3];

#[inline]
pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
pub(crate) fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
pub(crate) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// `a / |a|`, or `None` when `a` is zero or not finite.
#[inline]
pub(crate) fn unit(a: V3) -> Option<V3> {
    let n = norm(a);
    (n.is_finite() && n > 0.0).then(|| scale(a, 1.0 / n))
}

/// Check that every component of `a` is finite.
pub(crate) fn finite(name: &'static str, a: V3) -> Result<V3> {
    if a.iter().all(|x| x.is_finite()) {
        Ok(a)
    } else {
        Err(CoreError::InvalidVector { name, value: a })
    }
}

/// `a / |a|`, or [`CoreError::InvalidVector`] naming `name`.
pub(crate) fn unit_named(name: &'static str, a: V3) -> Result<V3> {
    finite(name, a)?;
    unit(a).ok_or(CoreError::InvalidVector { name, value: a })
}

/// `m · a` for a matrix given row by row.
#[inline]
pub(crate) fn mul(m: &[V3; 3], a: V3) -> V3 {
    [dot(m[0], a), dot(m[1], a), dot(m[2], a)]
}

/// `mᵀ · a` for a matrix given row by row.
#[inline]
pub(crate) fn mul_t(m: &[V3; 3], a: V3) -> V3 {
    add(add(scale(m[0], a[0]), scale(m[1], a[1])), scale(m[2], a[2]))
}

/// Angle between unit vectors `a` and `b` (radians, `[0, π]`), accurate near 0 and π.
#[inline]
pub(crate) fn angle(a: V3, b: V3) -> f64 {
    norm(cross(a, b)).atan2(dot(a, b))
}
