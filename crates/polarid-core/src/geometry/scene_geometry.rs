//! Per-pixel scattering geometry of a calibrated scene: a [`PinholeCamera`], the
//! [`Plane`] a pixel looks at, and a [`Source`] (a lamp at a point, or a distant source
//! in a direction).
//!
//! For pixel `(u, v)` the ray from the camera meets the plane at `X`. There, with `n`
//! the plane's unit normal (on the camera's side), `u_i` the unit vector from `X`
//! towards the source and `u_r` the unit vector from `X` towards the camera:
//!
//! - `θi = ∠(n, u_i)`, `θr = ∠(n, u_r)` (zenith angles, both `< 90°`);
//! - `φ = φr − φi`: the angle from the projection of `u_i` on the plane to that of `u_r`,
//!   counter-clockwise about `n` (right-handed), in `[0, 2π)`. `φ = π` is the forward
//!   in-plane geometry of the paper (camera on the far side of the normal from the
//!   source), `φ = 0` backscatter. When `θi` or `θr` is zero the azimuth is undefined and
//!   `φ = π` is reported (`β` does not depend on it then);
//! - `β` from eq. (5) with those three angles, via [`ScatterGeometry`] (the exact
//!   half-vector form), so that the reported `θi`, `θr`, `φ`, `β` are consistent;
//! - the angle of the trace of the plane of incidence (the plane holding `u_i` and `u_r`)
//!   in the image, measured like polarizer angles and the AoLP: from the image's +x axis
//!   (increasing column) towards −y (decreasing row), in `[0, π)`; NaN when `u_i` and
//!   `u_r` are parallel (`β = 0`).
//!
//! All angles are radians (f64). The kernel [`ViewGeometry::fill`] writes f64 maps
//! (f64 so that the far-field limit and eq. (5) checks hold to 1e-9 and better; a
//! region of 10⁵ pixels costs 4 MB for all five maps).

use rayon::prelude::*;

use crate::error::{CoreError, Result, check_len};
use crate::region::Rect;

use super::ScatterGeometry;
use super::camera::PinholeCamera;
use super::vec3::{self, V3};

/// Rays closer to parallel with the plane than this cosine are treated as parallel.
const PARALLEL_COS: f64 = 1e-12;

/// A target plane: a point on it and its unit normal, on the camera's side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    point: V3,
    normal: V3,
}

impl Plane {
    /// The plane through `point` with normal `normal` (normalized here).
    ///
    /// Errors: [`CoreError::InvalidVector`] for a non-finite point or a non-finite or
    /// zero normal.
    pub fn new(point: V3, normal: V3) -> Result<Self> {
        Ok(Self {
            point: vec3::finite("plane point", point)?,
            normal: vec3::unit_named("plane normal", normal)?,
        })
    }

    /// The default plane: through the origin, normal `+z`.
    pub fn horizontal() -> Self {
        Self {
            point: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
        }
    }

    /// A point on the plane.
    pub fn point(&self) -> V3 {
        self.point
    }

    /// The unit normal.
    pub fn normal(&self) -> V3 {
        self.normal
    }

    /// Signed distance of `p` from the plane along the normal.
    pub fn height(&self, p: V3) -> f64 {
        vec3::dot(self.normal, vec3::sub(p, self.point))
    }

    /// Where the ray `origin + t dir` (`t > 0`) meets the plane: `(t, point)`, or `None`
    /// when it is parallel to the plane (within 1e-12 in cosine, for a unit `dir`) or
    /// meets it at `t <= 0`.
    pub fn intersect(&self, origin: V3, dir: V3) -> Option<(f64, V3)> {
        let denom = vec3::dot(self.normal, dir);
        if denom.abs() < PARALLEL_COS * vec3::norm(dir) {
            return None;
        }
        let t = vec3::dot(self.normal, vec3::sub(self.point, origin)) / denom;
        (t > 0.0 && t.is_finite()).then(|| (t, vec3::add(origin, vec3::scale(dir, t))))
    }
}

/// Where the light comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Source {
    /// A point source (a lamp) at this position in the scene frame.
    Position(V3),
    /// A distant source (the sun, resolved by the caller) in this direction: the vector
    /// from the scene towards the source (normalized when used).
    Direction(V3),
}

impl Source {
    /// Check the source: a finite position, or a finite non-zero direction.
    ///
    /// Errors: [`CoreError::InvalidVector`] naming `source position` or
    /// `source direction`.
    pub fn validate(&self) -> Result<Self> {
        match *self {
            Source::Position(p) => Ok(Source::Position(vec3::finite("source position", p)?)),
            Source::Direction(d) => Ok(Source::Direction(vec3::unit_named("source direction", d)?)),
        }
    }

    /// Unit vector from `x` towards the source (`None`: the lamp is at `x`).
    fn towards(&self, x: V3) -> Option<V3> {
        match *self {
            Source::Position(p) => vec3::unit(vec3::sub(p, x)),
            Source::Direction(d) => vec3::unit(d),
        }
    }
}

/// The geometry of one pixel (see the module's documentation). Angles in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelGeometry {
    /// Where the pixel's ray meets the plane (scene frame).
    pub point: V3,
    /// Unit vector from the point towards the source.
    pub u_i: V3,
    /// Unit vector from the point towards the camera.
    pub u_r: V3,
    /// Source zenith about the plane's normal.
    pub theta_i: f64,
    /// Camera zenith about the plane's normal.
    pub theta_r: f64,
    /// `φ = φr − φi` about the normal, in `[0, 2π)` (`π`: forward in-plane).
    pub phi: f64,
    /// `β` of eq. (5).
    pub beta: f64,
    /// Angle of the trace of the plane of incidence in the image, from +x towards −y,
    /// in `[0, π)`; NaN when undefined (`β = 0`).
    pub poi_angle: f64,
}

/// Caller-owned output maps of [`ViewGeometry::fill`]: one f64 per pixel of the
/// rectangle, row-major, radians.
#[derive(Debug)]
pub struct GeometryMaps<'a> {
    /// `β`.
    pub beta: &'a mut [f64],
    /// `θi`.
    pub theta_i: &'a mut [f64],
    /// `θr`.
    pub theta_r: &'a mut [f64],
    /// `φ`.
    pub phi: &'a mut [f64],
    /// Angle of the plane of incidence's trace (optional).
    pub poi_angle: Option<&'a mut [f64]>,
}

/// Where a pixel's ray meets the plane of a [`ViewGeometry`]: the source-independent
/// part of its geometry ([`ViewGeometry::ray_hit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Pixel coordinates (centres at integers).
    u: f64,
    v: f64,
    /// Normalized (undistorted) image coordinates.
    x: f64,
    y: f64,
    /// Unit direction of the ray (scene frame).
    d: V3,
    /// Where it meets the plane.
    point: V3,
}

impl RayHit {
    /// Where the ray meets the plane (scene frame).
    pub fn point(&self) -> V3 {
        self.point
    }
}

/// A camera and the plane it looks at, checked: the camera is in front of the plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewGeometry {
    camera: PinholeCamera,
    plane: Plane,
}

impl ViewGeometry {
    /// Pair `camera` with `plane`.
    ///
    /// Errors: [`CoreError::CameraBehindPlane`] when the camera is not strictly on the
    /// side the normal points to.
    pub fn new(camera: PinholeCamera, plane: Plane) -> Result<Self> {
        let height = plane.height(camera.position());
        if height.is_nan() || height <= 0.0 {
            return Err(CoreError::CameraBehindPlane {
                position: camera.position(),
                height,
            });
        }
        Ok(Self { camera, plane })
    }

    /// The camera.
    pub fn camera(&self) -> &PinholeCamera {
        &self.camera
    }

    /// The plane.
    pub fn plane(&self) -> &Plane {
        &self.plane
    }

    /// The geometry of pixel `(u, v)` (pixel centres at integers) lit by `source`.
    ///
    /// Errors: those of [`PinholeCamera::ray`], [`CoreError::RayMissesPlane`] (the ray
    /// is parallel to the plane or leaves it), [`CoreError::InvalidVector`] (a bad
    /// source, or a lamp on the hit point), [`CoreError::SourceBelowHorizon`] (`θi >=
    /// 90°` at the hit point).
    pub fn pixel(&self, u: f64, v: f64, source: &Source) -> Result<PixelGeometry> {
        let source = source.validate()?;
        self.pixel_checked(u, v, &source)
    }

    fn pixel_checked(&self, u: f64, v: f64, source: &Source) -> Result<PixelGeometry> {
        let hit = self.ray_hit(u, v)?;
        self.pixel_at_hit_checked(&hit, source)
    }

    /// The part of pixel `(u, v)`'s geometry that does not depend on the source: where
    /// its ray meets the plane. The undistortion of the pixel (iterative with lens
    /// distortion) and the intersection are done here once; [`ViewGeometry::pixel_at_hit`]
    /// then gives the geometry under any source, bit for bit as [`ViewGeometry::pixel`]
    /// (a map with `T` captures undistorts each pixel once instead of `T` times).
    ///
    /// Errors: those of [`PinholeCamera::ray`] and [`CoreError::RayMissesPlane`].
    pub fn ray_hit(&self, u: f64, v: f64) -> Result<RayHit> {
        let (x, y) = self.camera.normalized(u, v)?;
        let d = vec3::mul_t(&self.camera.rotation(), [x, y, 1.0]);
        let d = vec3::unit(d).ok_or(CoreError::InvalidVector {
            name: "pixel ray",
            value: d,
        })?;
        let n = self.plane.normal();
        let cos_normal = vec3::dot(n, d);
        let Some((_, point)) = self
            .plane
            .intersect(self.camera.position(), d)
            .filter(|_| cos_normal < 0.0)
        else {
            return Err(CoreError::RayMissesPlane { u, v, cos_normal });
        };
        Ok(RayHit {
            u,
            v,
            x,
            y,
            d,
            point,
        })
    }

    /// The geometry of the pixel of `hit` ([`ViewGeometry::ray_hit`]) lit by `source`:
    /// equal to [`ViewGeometry::pixel`] at the same pixel.
    ///
    /// Errors: [`CoreError::InvalidVector`] (a bad source, or a lamp on the hit point),
    /// [`CoreError::SourceBelowHorizon`].
    pub fn pixel_at_hit(&self, hit: &RayHit, source: &Source) -> Result<PixelGeometry> {
        let source = source.validate()?;
        self.pixel_at_hit_checked(hit, &source)
    }

    fn pixel_at_hit_checked(&self, hit: &RayHit, source: &Source) -> Result<PixelGeometry> {
        let RayHit {
            u,
            v,
            x,
            y,
            d,
            point,
        } = *hit;
        let n = self.plane.normal();
        let u_r = vec3::scale(d, -1.0);
        let u_i = source.towards(point).ok_or(CoreError::InvalidVector {
            name: "source position (on the plane at the pixel's point)",
            value: point,
        })?;
        let cos_i = vec3::dot(n, u_i);
        let theta_i = vec3::angle(n, u_i);
        if cos_i.is_nan() || cos_i <= 0.0 {
            return Err(CoreError::SourceBelowHorizon {
                u,
                v,
                theta_i_deg: theta_i.to_degrees(),
            });
        }
        let theta_r = vec3::angle(n, u_r);
        let a_i = vec3::sub(u_i, vec3::scale(n, cos_i));
        let a_r = vec3::sub(u_r, vec3::scale(n, vec3::dot(n, u_r)));
        let phi = if vec3::norm(a_i) > 0.0 && vec3::norm(a_r) > 0.0 {
            let s = vec3::dot(n, vec3::cross(a_i, a_r));
            let c = vec3::dot(a_i, a_r);
            s.atan2(c).rem_euclid(std::f64::consts::TAU)
        } else {
            std::f64::consts::PI
        };
        let beta = ScatterGeometry::new(theta_i, theta_r, phi).beta();
        let poi_angle = self.poi_angle(x, y, u_i, u_r);
        Ok(PixelGeometry {
            point,
            u_i,
            u_r,
            theta_i,
            theta_r,
            phi,
            beta,
            poi_angle,
        })
    }

    /// Image angle of the trace of the plane holding `u_i` and `u_r` through the pixel of
    /// normalized coordinates `(x, y)`.
    fn poi_angle(&self, x: f64, y: f64, u_i: V3, u_r: V3) -> f64 {
        // A direction in the plane of incidence, perpendicular to the line of sight.
        let w = vec3::sub(u_i, vec3::scale(u_r, vec3::dot(u_i, u_r)));
        if vec3::norm(w) < 1e-12 {
            return f64::NAN;
        }
        let wc = self.camera.camera_vector(w);
        // Motion of the normalized image point when the scene point moves along w.
        let (dx, dy) = (wc[0] - x * wc[2], wc[1] - y * wc[2]);
        let j = self.camera.distortion().jacobian(x, y);
        let k = self.camera.intrinsics();
        let du = k.fx * (j[0][0] * dx + j[0][1] * dy);
        let dv = k.fy * (j[1][0] * dx + j[1][1] * dy);
        if du == 0.0 && dv == 0.0 {
            return f64::NAN;
        }
        let a = (-dv).atan2(du).rem_euclid(std::f64::consts::PI);
        // rem_euclid can round up to π itself.
        if a >= std::f64::consts::PI { 0.0 } else { a }
    }

    /// The pixels at which a rectangle's geometry is checked by
    /// [`ViewGeometry::check_rect`]: its four corner pixels and its centre.
    pub fn probe_points(rect: Rect) -> [(f64, f64); 5] {
        let (x0, y0) = (rect.x as f64, rect.y as f64);
        let x1 = x0 + rect.width.saturating_sub(1) as f64;
        let y1 = y0 + rect.height.saturating_sub(1) as f64;
        [
            (x0, y0),
            (x1, y0),
            (x0, y1),
            (x1, y1),
            (0.5 * (x0 + x1), 0.5 * (y0 + y1)),
        ]
    }

    /// Check that every pixel of `rect` has a geometry, from its corners and centre
    /// ([`ViewGeometry::probe_points`]); on a plane, the pixels whose rays meet it and
    /// the points that see the source above their horizon form convex sets, so this is
    /// exact without distortion.
    ///
    /// Errors: those of [`ViewGeometry::pixel`], for the first probe that fails.
    pub fn check_rect(&self, rect: Rect, source: &Source) -> Result<()> {
        let source = source.validate()?;
        for (u, v) in Self::probe_points(rect) {
            self.pixel_checked(u, v, &source)?;
        }
        Ok(())
    }

    /// Fill `maps` with the geometry of every pixel of `rect` (row-major, one value per
    /// pixel), in parallel over rows.
    ///
    /// Errors: [`CoreError::LengthMismatch`] when a map is not `width × height` long,
    /// [`CoreError::InvalidRegion`] for an empty rectangle, and the errors of
    /// [`ViewGeometry::pixel`] for the first failing pixel in row-major order (the
    /// maps are then partly written).
    pub fn fill(&self, rect: Rect, source: &Source, maps: GeometryMaps<'_>) -> Result<()> {
        let source = source.validate()?;
        let (w, h) = (rect.width, rect.height);
        if w == 0 || h == 0 {
            return Err(CoreError::InvalidRegion {
                x: rect.x,
                y: rect.y,
                width: w,
                height: h,
                reason: "is empty".into(),
            });
        }
        let n = w * h;
        let check = |name, len| check_len(name, len, n);
        check("beta map", maps.beta.len())?;
        check("theta_i map", maps.theta_i.len())?;
        check("theta_r map", maps.theta_r.len())?;
        check("phi map", maps.phi.len())?;
        let mut poi_store;
        let poi: &mut [f64] = match maps.poi_angle {
            Some(p) => {
                check("poi_angle map", p.len())?;
                p
            }
            None => {
                poi_store = Vec::new();
                &mut poi_store[..]
            }
        };
        let with_poi = !poi.is_empty();
        // Rows of the optional map: empty chunks when it is not wanted.
        let poi_rows: Vec<&mut [f64]> = if with_poi {
            poi.chunks_mut(w).collect()
        } else {
            (0..h).map(|_| &mut [][..]).collect()
        };
        let first_error = maps
            .beta
            .par_chunks_mut(w)
            .zip(maps.theta_i.par_chunks_mut(w))
            .zip(maps.theta_r.par_chunks_mut(w))
            .zip(maps.phi.par_chunks_mut(w))
            .zip(poi_rows.into_par_iter())
            .enumerate()
            .filter_map(|(row, ((((b, ti), tr), ph), po))| {
                let v = (rect.y + row) as f64;
                for col in 0..w {
                    let u = (rect.x + col) as f64;
                    match self.pixel_checked(u, v, &source) {
                        Ok(g) => {
                            b[col] = g.beta;
                            ti[col] = g.theta_i;
                            tr[col] = g.theta_r;
                            ph[col] = g.phi;
                            if let Some(p) = po.get_mut(col) {
                                *p = g.poi_angle;
                            }
                        }
                        Err(e) => return Some((row, e)),
                    }
                }
                None
            })
            .min_by_key(|(row, _)| *row);
        first_error.map_or(Ok(()), |(_, e)| Err(e))
    }
}

#[cfg(test)]
mod tests;
