//! Perspective rendering of a calibrated scene: a [`PinholeCamera`], flat rectangular
//! plates lying on planes, and one light (a lamp at a finite distance, or a distant
//! source such as the sun).
//!
//! For pixel `(u, v)` the camera's ray (with the lens distortion inverted,
//! [`PinholeCamera::ray`]) is met with every plate's plane; the nearest plate whose
//! rectangle holds the hit point `X` is the one seen (plates may hide each other; no
//! plate casts a shadow on another). At `X` the per-pixel geometry is that of
//! [`ViewGeometry::pixel`]: `θi`, `θr`, `φ` about the plate's normal, `β` of eq. (5) and
//! the image angle `γ` of the trace of the plane of incidence.
//!
//! **Radiometry.** With `E⊥` the irradiance on a surface facing the light — `I / r²` for
//! a lamp of radiant intensity `I` at distance `r` from `X`, or the given irradiance of
//! a distant source — the radiance Stokes vector leaving `X` towards the camera is
//!
//! ```text
//! L = E⊥ cos θi · ( f00 + ρd/π ,  f10 cos 2ψ ,  f10 sin 2ψ ),    ψ = γ + 90°
//! ```
//!
//! with `f` the Priest–Meier pBRDF (paper eq. 3) in its local facet frame, where the
//! Mueller matrix of eq. (3) applied to unpolarized light gives `(f00, f10, 0)` with
//! `S1 = I_s − I_p` and `s` perpendicular to the plane of incidence (the plane holding
//! the directions to the source and to the camera), and `f10 ≥ 0` (`Rs ≥ Rp`). The
//! reflected light is therefore s-polarized: its angle of linear polarization in the
//! image is the trace of the plane of incidence plus 90° (docs/CONVENTIONS.md), and its
//! DoLP is `f10 / (f00 + ρd/π)`, which with `ρd = 0` is the paper's eq. (9) at the
//! pixel's own `β`. `ρd` is the albedo of an optional Lambertian, depolarizing component.
//! Pixels that see no plate, or a plate whose plane has the light at or below its
//! horizon, get the `background` Stokes vector.
//!
//! Far field: with the camera and the light far away (a long focal length, a lamp at a
//! large distance with `I = r²`), every pixel of a plate has the same `θi`, `θr`, `φ`,
//! and `L` tends to [`super::plate_radiance`] (same DoLP and S0; the test
//! `far_field_limit_matches_plate_radiance`).

use rayon::prelude::*;

use crate::error::{CoreError, Result, check_len, ensure_range};
use crate::geometry::vec3::{V3, cross, dot, sub};
use crate::geometry::{PinholeCamera, PixelGeometry, Plane, Source, ViewGeometry};
use crate::pbrdf;

use super::{PlateOptics, check_frame_size};

#[inline]
fn axpy(a: V3, s: f64, b: V3) -> V3 {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

fn unit(name: &'static str, a: V3) -> Result<V3> {
    let n = dot(a, a).sqrt();
    if n.is_finite() && n > 0.0 && a.iter().all(|x| x.is_finite()) {
        Ok([a[0] / n, a[1] / n, a[2] / n])
    } else {
        Err(CoreError::InvalidVector { name, value: a })
    }
}

/// A flat rectangular plate on a plane: its centre, two in-plane unit axes, half-sizes
/// along them, and its optics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarPlate {
    plane: Plane,
    center: V3,
    axis_u: V3,
    axis_v: V3,
    half: [f64; 2],
    optics: PlateOptics,
}

impl PlanarPlate {
    /// A plate of `size = [width, height]` (scene length units) on `plane`, centred on
    /// `center` projected onto the plane along the normal; `axis` gives the direction of
    /// its width (its component along the normal is removed), the height runs along
    /// `normal × axis`.
    ///
    /// Errors: [`CoreError::InvalidVector`] (a non-finite centre, an axis that is zero,
    /// not finite or parallel to the normal), [`CoreError::OutOfRange`] (a size that is
    /// not finite and > 0), and those of [`PlateOptics::validate`].
    pub fn new(
        plane: Plane,
        center: V3,
        axis: V3,
        size: [f64; 2],
        optics: PlateOptics,
    ) -> Result<Self> {
        if !center.iter().all(|x| x.is_finite()) {
            return Err(CoreError::InvalidVector {
                name: "plate center",
                value: center,
            });
        }
        let n = plane.normal();
        let axis_u = unit("plate axis", axis)?;
        let in_plane = axpy(axis_u, -dot(axis_u, n), n);
        if dot(in_plane, in_plane) < 1e-12 {
            return Err(CoreError::InvalidVector {
                name: "plate axis (parallel to the plane's normal)",
                value: axis,
            });
        }
        let axis_u = unit("plate axis", in_plane)?;
        let axis_v = cross(n, axis_u);
        for s in size {
            ensure_range(
                "plate size",
                s,
                f64::MIN_POSITIVE,
                f64::MAX,
                "finite and > 0",
            )?;
        }
        optics.validate()?;
        let center = axpy(center, -plane.height(center), n);
        Ok(Self {
            plane,
            center,
            axis_u,
            axis_v,
            half: [0.5 * size[0], 0.5 * size[1]],
            optics,
        })
    }

    /// The plane the plate lies on.
    pub fn plane(&self) -> &Plane {
        &self.plane
    }

    /// The centre (on the plane).
    pub fn center(&self) -> V3 {
        self.center
    }

    /// The unit axes of the width and the height (in the plane; `v = normal × u`).
    pub fn axes(&self) -> [V3; 2] {
        [self.axis_u, self.axis_v]
    }

    /// Width and height.
    pub fn size(&self) -> [f64; 2] {
        [2.0 * self.half[0], 2.0 * self.half[1]]
    }

    /// The optics.
    pub fn optics(&self) -> &PlateOptics {
        &self.optics
    }

    /// The four corners, in order around the rectangle.
    pub fn corners(&self) -> [V3; 4] {
        let [a, b] = self.half;
        let c = |s: f64, t: f64| axpy(axpy(self.center, s * a, self.axis_u), t * b, self.axis_v);
        [c(-1.0, -1.0), c(1.0, -1.0), c(1.0, 1.0), c(-1.0, 1.0)]
    }

    /// Whether point `p` of the plane lies on the plate (edges included).
    pub fn contains(&self, p: V3) -> bool {
        let d = sub(p, self.center);
        dot(d, self.axis_u).abs() <= self.half[0] && dot(d, self.axis_v).abs() <= self.half[1]
    }
}

/// The light of a capture: where it is and how strong.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// A lamp at a point, or a distant source in a direction.
    pub source: Source,
    /// For a lamp, its radiant intensity `I` (the irradiance on a surface facing it at
    /// distance `r` is `I / r²`); for a distant source, the irradiance on a surface
    /// facing it. Any linear unit; > 0.
    pub power: f64,
}

impl Light {
    /// Check the source and the power.
    pub fn validate(&self) -> Result<Self> {
        ensure_range(
            "light power",
            self.power,
            f64::MIN_POSITIVE,
            f64::MAX,
            "> 0",
        )?;
        Ok(Self {
            source: self.source.validate()?,
            power: self.power,
        })
    }

    /// `E⊥` at point `x`: `I / r²` for a lamp, the power for a distant source.
    pub fn irradiance_at(&self, x: V3) -> f64 {
        match self.source {
            Source::Position(p) => {
                let d = sub(p, x);
                self.power / dot(d, d)
            }
            Source::Direction(_) => self.power,
        }
    }
}

/// What one pixel sees (see [`PerspectiveScene::pixel`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelHit {
    /// Index of the plate seen.
    pub plate: usize,
    /// The pixel's geometry on that plate.
    pub geometry: PixelGeometry,
    /// `E⊥` at the hit point (0 when the light is below the plane's horizon: unlit).
    pub irradiance: f64,
    /// Radiance Stokes vector `(S0, S1, S2)` in the image frame (module documentation).
    pub stokes: [f64; 3],
}

/// A camera and the plates it sees (validated: the camera is in front of every plate's
/// plane).
#[derive(Debug, Clone)]
pub struct PerspectiveScene {
    camera: PinholeCamera,
    plates: Vec<PlanarPlate>,
    views: Vec<ViewGeometry>,
}

/// Caller-owned outputs of [`PerspectiveScene::render_bands`]: per band, and for the
/// plate seen, one value per pixel of the `width × height` frame, row-major.
#[derive(Debug)]
pub struct BandStokesMaps<'a> {
    /// One radiance Stokes map `(S0, S1, S2)` per band (f32).
    pub stokes: Vec<&'a mut [[f32; 3]]>,
    /// Plate seen: 0 for the background, `i + 1` for plate `i`.
    pub plate: &'a mut [u16],
}

impl PerspectiveScene {
    /// Pair `camera` with `plates` (at most 65534).
    ///
    /// Errors: [`CoreError::CameraBehindPlane`] when the camera is not strictly on the
    /// side a plate's normal points to; [`CoreError::OutOfRange`] for too many plates.
    pub fn new(camera: PinholeCamera, plates: Vec<PlanarPlate>) -> Result<Self> {
        if plates.len() >= u16::MAX as usize {
            return Err(CoreError::OutOfRange {
                name: "number of plates",
                value: plates.len() as f64,
                expected: "at most 65534",
            });
        }
        let views = plates
            .iter()
            .map(|p| ViewGeometry::new(camera, *p.plane()))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            camera,
            plates,
            views,
        })
    }

    /// The camera.
    pub fn camera(&self) -> &PinholeCamera {
        &self.camera
    }

    /// The plates.
    pub fn plates(&self) -> &[PlanarPlate] {
        &self.plates
    }

    /// Index of the nearest plate that the ray of pixel `(u, v)` meets, if any.
    ///
    /// Errors: those of [`PinholeCamera::ray`].
    pub fn plate_at(&self, u: f64, v: f64) -> Result<Option<usize>> {
        let d = self.camera.ray(u, v)?;
        let o = self.camera.position();
        let mut best: Option<(f64, usize)> = None;
        for (i, p) in self.plates.iter().enumerate() {
            if dot(p.plane.normal(), d) >= 0.0 {
                continue; // seen from behind (or edge-on): invisible
            }
            if let Some((t, x)) = p.plane.intersect(o, d)
                && p.contains(x)
                && best.is_none_or(|(bt, _)| t < bt)
            {
                best = Some((t, i));
            }
        }
        Ok(best.map(|(_, i)| i))
    }

    /// The plate seen by every pixel of a `width × height` frame, written into `out`
    /// (row-major; 0 for the background, `i + 1` for plate `i`), in parallel over rows.
    ///
    /// Errors: [`CoreError::InvalidDimensions`], [`CoreError::LengthMismatch`], and those
    /// of [`PinholeCamera::ray`] for the first failing row.
    pub fn plate_map(&self, width: usize, height: usize, out: &mut [u16]) -> Result<()> {
        check_frame_size(width, height, &[("plate map", out.len())])?;
        let first_error = out
            .par_chunks_mut(width)
            .enumerate()
            .filter_map(|(row, p)| {
                for (col, px) in p.iter_mut().enumerate() {
                    match self.plate_at(col as f64, row as f64) {
                        Ok(i) => *px = i.map_or(0, |i| i as u16 + 1),
                        Err(e) => return Some((row, e)),
                    }
                }
                None
            })
            .min_by_key(|(row, _)| *row);
        first_error.map_or(Ok(()), |(_, e)| Err(e))
    }

    /// What pixel `(u, v)` sees under `light` (module documentation), or `None` for the
    /// background.
    ///
    /// Errors: those of [`PinholeCamera::ray`], [`Light::validate`] and
    /// [`ViewGeometry::pixel`] other than the light being below the plane's horizon
    /// (that point is unlit: zero radiance).
    pub fn pixel(&self, u: f64, v: f64, light: &Light) -> Result<Option<PixelHit>> {
        let light = light.validate()?;
        let Some((i, g, e)) = self.hit_geometry(u, v, &light)? else {
            return Ok(None);
        };
        let stokes = if e > 0.0 {
            plate_stokes(&self.plates[i].optics, &g, e)?
        } else {
            [0.0; 3]
        };
        Ok(Some(PixelHit {
            plate: i,
            geometry: g,
            irradiance: e,
            stokes,
        }))
    }

    /// The plate pixel `(u, v)` sees, its geometry and `E⊥` there (0: unlit, the light
    /// below the plane's horizon, with the geometry of a light straight above).
    fn hit_geometry(
        &self,
        u: f64,
        v: f64,
        light: &Light,
    ) -> Result<Option<(usize, PixelGeometry, f64)>> {
        let Some(i) = self.plate_at(u, v)? else {
            return Ok(None);
        };
        let (plate, view) = (&self.plates[i], &self.views[i]);
        match view.pixel(u, v, &light.source) {
            Ok(g) => Ok(Some((i, g, light.irradiance_at(g.point)))),
            Err(CoreError::SourceBelowHorizon { .. }) => {
                // Unlit: report the geometry of a light straight above for the point.
                let up = Source::Direction(plate.plane.normal());
                Ok(Some((i, view.pixel(u, v, &up)?, 0.0)))
            }
            Err(e) => Err(e),
        }
    }

    /// Render the per-band radiance Stokes maps (one band for a single-band scene) and
    /// the plate map of a `width × height` frame: every pixel's ray is traced once
    /// ([`Self::pixel`]'s geometry) and its Stokes vector in band `b` is [`plate_stokes`]
    /// with the optics `optics[plate][b]` of the plate it sees (`background[b]` where it
    /// sees none), in parallel over rows. The plates' own optics
    /// ([`PlanarPlate::optics`]) are not used.
    ///
    /// Errors: [`CoreError::InvalidDimensions`] (an empty frame),
    /// [`CoreError::LengthMismatch`] (a map that is not `width × height` long; `optics`
    /// without one list per plate; a list, or `background`, without one entry per map),
    /// [`CoreError::NonFinite`] (a non-finite background), those of
    /// [`PlateOptics::validate`] and of [`PerspectiveScene::pixel`] for the first failing
    /// row (the maps are then partly written).
    pub fn render_bands(
        &self,
        width: usize,
        height: usize,
        light: &Light,
        optics: &[Vec<PlateOptics>],
        background: &[[f64; 3]],
        out: BandStokesMaps<'_>,
    ) -> Result<()> {
        let light = light.validate()?;
        check_frame_size(width, height, &[])?;
        let (n, nb) = (width * height, out.stokes.len());
        let mut lens: Vec<(&'static str, usize, usize)> = vec![
            ("plate map", n, out.plate.len()),
            (
                "band optics (one list per plate)",
                self.plates.len(),
                optics.len(),
            ),
            ("background (one per band)", nb, background.len()),
        ];
        lens.extend(out.stokes.iter().map(|m| ("stokes map", n, m.len())));
        lens.extend(
            optics
                .iter()
                .map(|o| ("band optics of a plate", nb, o.len())),
        );
        for (name, expected, got) in lens {
            check_len(name, got, expected)?;
        }
        for o in optics.iter().flatten() {
            o.validate()?;
        }
        for b in background.iter().flatten() {
            crate::error::ensure_finite("background", *b)?;
        }
        let bg: Vec<[f32; 3]> = background.iter().map(|b| b.map(|x| x as f32)).collect();
        // Row r of every band: rows[r][b].
        let mut rows: Vec<Vec<&mut [[f32; 3]]>> =
            (0..height).map(|_| Vec::with_capacity(nb)).collect();
        for map in out.stokes {
            for (r, chunk) in map.chunks_mut(width).enumerate() {
                rows[r].push(chunk);
            }
        }
        let first_error = rows
            .into_par_iter()
            .zip(out.plate.par_chunks_mut(width))
            .enumerate()
            .filter_map(|(row, (mut s, p))| {
                for col in 0..width {
                    match self.hit_geometry(col as f64, row as f64, &light) {
                        Ok(Some((i, g, e))) => {
                            for (b, line) in s.iter_mut().enumerate() {
                                line[col] = if e > 0.0 {
                                    match plate_stokes(&optics[i][b], &g, e) {
                                        Ok(x) => x.map(|x| x as f32),
                                        Err(e) => return Some((row, e)),
                                    }
                                } else {
                                    [0.0; 3]
                                };
                            }
                            p[col] = i as u16 + 1;
                        }
                        Ok(None) => {
                            for (line, b) in s.iter_mut().zip(&bg) {
                                line[col] = *b;
                            }
                            p[col] = 0;
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

/// The radiance Stokes vector in the image frame of a plate point of geometry `g` with
/// `E⊥ = irradiance` (module documentation):
/// `E⊥ cos θi · (f00 + ρd/π, f10 cos 2ψ, f10 sin 2ψ)` with `f` eq. (3) in the local
/// facet frame and `ψ = γ + 90°` (`γ` the image angle of the plane of incidence).
///
/// Errors: those of [`pbrdf::pbrdf`] (optics or angles out of range).
pub fn plate_stokes(optics: &PlateOptics, g: &PixelGeometry, irradiance: f64) -> Result<[f64; 3]> {
    optics.validate()?;
    let f = pbrdf::pbrdf(
        optics.n,
        optics.k,
        optics.sigma,
        g.theta_i,
        g.theta_r,
        g.phi,
    )?;
    let scale = irradiance * g.theta_i.cos();
    let f00 = f.local[0][0] + optics.rho_d / std::f64::consts::PI;
    let f10 = f.local[1][0];
    // γ is NaN where the plane of incidence is undefined (β = 0); there Rs = Rp, f10 = 0.
    let (s2, c2) = if g.poi_angle.is_finite() {
        (2.0 * (g.poi_angle + std::f64::consts::FRAC_PI_2)).sin_cos()
    } else {
        (0.0, 1.0)
    };
    Ok([scale * f00, scale * f10 * c2, scale * f10 * s2])
}

#[cfg(test)]
mod tests;
