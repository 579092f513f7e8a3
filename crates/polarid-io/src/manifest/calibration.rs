//! Calibrated geometry in a capture-set manifest: `[camera]`, `[[plane]]`, `[site]`, a
//! region's `plane` and a capture's `source`.
//!
//! ```toml
//! [camera]                              # pinhole model, OpenCV conventions
//! focal_px = [1350.0, 1350.0]           # fx, fy (one number: fx = fy)
//! principal_point_px = [239.5, 179.5]   # cx, cy; pixel centres at integers
//! distortion = [0.0, 0.0, 0.0, 0.0, 0.0] # optional: k1, k2, p1, p2[, k3]
//! position = [0.459, 0.0, 0.655]
//! look_at = [0.0, 0.0, 0.0]             # look_at + up, or
//! up = [0.0, 0.0, 1.0]
//! # rotation = [[..], [..], [..]]       # world-to-camera, row by row
//!
//! [[plane]]                             # default: one plane "default", [0,0,0], +z
//! name = "bench"
//! point = [0.0, 0.0, 0.0]
//! normal = [0.0, 0.0, 1.0]              # on the camera's side
//!
//! [site]                                # needed by `sun` sources
//! latitude_deg = 39.742476
//! longitude_deg = -105.1786
//! elevation_m = 1830.14                 # default 0
//! pressure_mbar = 820.0                 # default 1013.25
//! temperature_c = 11.0                  # default 10
//!
//! [[region]]
//! plane = "bench"                       # default: the first plane
//!
//! [[capture]]
//! source = { position = [-0.35, 0.0, 0.606] }   # or { direction = [..] } or { sun = "RFC 3339" }
//! ```
//!
//! Rules: with `[camera]` every capture gives `source` and no `theta_i_deg`,
//! `theta_r_deg` or `phi_deg` (nor the top level `theta_r_deg`, `phi_deg`); a `source`
//! without `[camera]`, and a `sun` source without `[site]`, are errors. The geometry is
//! checked at load time (`Parser::check_geometry`): the camera must be in front of
//! every plane, the rays of every region's corners and centre must meet its plane, and
//! every source must be above the plane's horizon. A `sun` time is parsed (RFC 3339,
//! [`crate::time::parse_rfc3339`]) and resolved at load time to the sun's apparent
//! direction seen from `[site]` ([`polarid_core::sun::solar_position`] with the site's
//! pressure and temperature for refraction and the estimated ΔT); a sun at or below the
//! horizon (refracted elevation ≤ 0) is an error naming `capture[i].source.sun`.

use std::ops::Range;

use polarid_core::CoreError;
use polarid_core::geometry::{Distortion, Intrinsics, PinholeCamera, Plane, Source, ViewGeometry};
use polarid_core::sun::{Site, solar_position, sun_direction};
use toml::de::DeValue;

use super::{Capture, Parser, Region, Result, Table, Val};
use crate::error::IoError;
use crate::time::parse_rfc3339;

/// How the camera is oriented.
#[derive(Debug, Clone, PartialEq)]
pub enum CameraOrientation {
    /// Looking at a point, with `up` towards decreasing image rows.
    LookAt {
        /// The point looked at (scene frame).
        look_at: [f64; 3],
        /// The up direction.
        up: [f64; 3],
    },
    /// A world-to-camera rotation matrix, row by row.
    Rotation([[f64; 3]; 3]),
}

/// The `[camera]` table: a validated pinhole camera.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraSpec {
    /// `fx`, `fy`, pixels.
    pub focal_px: [f64; 2],
    /// `cx`, `cy`, pixels (pixel centres at integers).
    pub principal_point_px: [f64; 2],
    /// `k1, k2, p1, p2, k3` (OpenCV), zeros when not given.
    pub distortion: [f64; 5],
    /// Centre of projection (scene frame).
    pub position: [f64; 3],
    /// Orientation.
    pub orientation: CameraOrientation,
    /// Line of the `[camera]` table in the manifest.
    pub line: usize,
    /// The core camera built from the above (validated when the manifest was loaded).
    pub camera: PinholeCamera,
    /// The OpenCV calibration file the intrinsics were read from (`opencv`), if any.
    pub opencv: Option<super::opencv::OpenCvCalibration>,
}

impl CameraSpec {
    /// The core camera.
    pub fn to_camera(&self) -> PinholeCamera {
        self.camera
    }
}

/// One `[[plane]]` table (or the default plane).
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneSpec {
    /// Unique name (`default` for the default plane).
    pub name: String,
    /// A point on the plane.
    pub point: [f64; 3],
    /// Its normal (as written; on the camera's side).
    pub normal: [f64; 3],
    /// Line of the plane's `name` in the manifest (0 for the default plane).
    pub line: usize,
}

impl PlaneSpec {
    /// The core plane.
    ///
    /// Errors: [`CoreError::InvalidVector`] (not for a loaded manifest's planes, which
    /// were checked).
    pub fn to_plane(&self) -> std::result::Result<Plane, CoreError> {
        Plane::new(self.point, self.normal)
    }
}

/// The `[site]` table: where the scene is on Earth (for `sun` sources).
#[derive(Debug, Clone, PartialEq)]
pub struct SiteSpec {
    /// Geodetic latitude, degrees north, in [-90, 90].
    pub latitude_deg: f64,
    /// Longitude, degrees east, in [-180, 180].
    pub longitude_deg: f64,
    /// Elevation above sea level, metres (default 0).
    pub elevation_m: f64,
    /// Mean pressure, millibars (default 1013.25).
    pub pressure_mbar: f64,
    /// Mean temperature, °C (default 10).
    pub temperature_c: f64,
}

/// A capture's `source`.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceSpec {
    /// A lamp at this position (scene frame).
    Position([f64; 3]),
    /// A distant source in this direction (unit vector, normalized at load time).
    Direction([f64; 3]),
    /// The sun at this time, seen from `[site]`, resolved when the manifest was loaded.
    Sun {
        /// The time as written (RFC 3339).
        time: String,
        /// The time as Unix seconds (UTC).
        unix_seconds: f64,
        /// The sun's apparent (refracted) topocentric zenith angle, degrees, in (0, 90).
        zenith_deg: f64,
        /// The sun's topocentric azimuth, degrees from north eastward, in [0, 360).
        azimuth_deg: f64,
        /// Unit vector towards the sun, scene frame x east, y north, z up:
        /// `(sin z sin az, sin z cos az, cos z)`.
        direction: [f64; 3],
    },
}

impl SourceSpec {
    /// The core source: a [`SourceSpec::Sun`] gives [`Source::Direction`] towards the
    /// sun. Always `Some` (kept an `Option` for callers written against earlier versions,
    /// where the sun was not resolved).
    pub fn to_source(&self) -> Option<Source> {
        Some(match self {
            SourceSpec::Position(p) => Source::Position(*p),
            SourceSpec::Direction(d) => Source::Direction(*d),
            SourceSpec::Sun { direction, .. } => Source::Direction(*direction),
        })
    }

    /// The key it was given with (`position`, `direction`, `sun`).
    pub fn key(&self) -> &'static str {
        match self {
            SourceSpec::Position(_) => "position",
            SourceSpec::Direction(_) => "direction",
            SourceSpec::Sun { .. } => "sun",
        }
    }
}

impl Parser<'_> {
    /// `N` finite numbers.
    pub(super) fn numbers<const N: usize>(&self, v: &Val<'_>, field: &str) -> Result<[f64; N]> {
        let items = self.array(v, field)?;
        if items.len() != N {
            return Err(self.err(
                &v.span(),
                field,
                format!("expected an array of {N} numbers, found {}", items.len()),
            ));
        }
        let mut out = [0.0; N];
        for (o, it) in out.iter_mut().zip(items) {
            *o = self.num(it, field)?;
        }
        Ok(out)
    }

    fn req<'t, 'i>(
        &self,
        t: &'t Table<'i>,
        key: &str,
        pre: &str,
        span: &Range<usize>,
    ) -> Result<&'t Val<'i>> {
        self.get(t, key)
            .ok_or_else(|| self.err(span, &format!("{pre}{key}"), format!("missing `{key}`")))
    }

    /// The `[camera]` table, if any.
    pub(super) fn camera(&self, root: &Table<'_>) -> Result<Option<CameraSpec>> {
        let Some(cv) = self.get(root, "camera") else {
            return Ok(None);
        };
        let t = self.table(cv, "camera")?;
        let span = cv.span();
        self.warn_unknown(
            t,
            &[
                "opencv",
                "focal_px",
                "principal_point_px",
                "distortion",
                "position",
                "look_at",
                "up",
                "rotation",
            ],
            "camera.",
        );
        // `opencv = "calib.yml"`: the intrinsics from an OpenCV calibration file (opencv.rs).
        let opencv = self.opencv_camera(t)?;
        let (focal_px, principal_point_px, distortion, fv, pv) = match &opencv {
            Some((c, v)) => (c.focal_px, c.principal_point_px, c.distortion, *v, *v),
            None => self.intrinsics(t, &span)?,
        };
        let posv = self.req(t, "position", "camera.", &span)?;
        let position = self.numbers::<3>(posv, "camera.position")?;
        let intr = Intrinsics {
            fx: focal_px[0],
            fy: focal_px[1],
            cx: principal_point_px[0],
            cy: principal_point_px[1],
        };
        let dist = Distortion::from_array(distortion);
        let (orientation, at) = self.orientation(t, &span)?;
        let built = match &orientation {
            CameraOrientation::LookAt { look_at, up } => {
                PinholeCamera::look_at(intr, dist, position, *look_at, *up)
            }
            CameraOrientation::Rotation(m) => {
                PinholeCamera::from_rotation(intr, dist, position, *m)
            }
        };
        let camera = built.map_err(|e| {
            let (field, v): (&str, &Val<'_>) = match &e {
                CoreError::InvalidFocalLength { .. } => ("camera.focal_px", fv),
                CoreError::NonFinite { name, .. } if name.starts_with("principal") => {
                    ("camera.principal_point_px", pv)
                }
                CoreError::NonFinite { .. } => ("camera.distortion", fv),
                CoreError::InvalidVector { name, .. } if *name == "camera position" => {
                    ("camera.position", posv)
                }
                CoreError::InvalidVector { name, .. } if *name == "camera up" => {
                    ("camera.up", at.1)
                }
                CoreError::DegenerateLookAt { reason, .. } if reason.contains("coincides") => {
                    ("camera.look_at", at.0)
                }
                CoreError::DegenerateLookAt { .. } => ("camera.up", at.1),
                CoreError::NotARotation { .. } => ("camera.rotation", at.0),
                _ => ("camera.look_at", at.0),
            };
            self.err(&v.span(), field, e.to_string())
        })?;
        Ok(Some(CameraSpec {
            focal_px,
            principal_point_px,
            distortion,
            position,
            orientation,
            line: self.line(span.start),
            camera,
            opencv: opencv.map(|(c, _)| c),
        }))
    }

    /// The intrinsics given in the `[camera]` table `t`: `focal_px`, `principal_point_px`,
    /// `distortion`, and the values of the first two (for the spans of later errors).
    fn intrinsics<'t, 'i>(
        &self,
        t: &'t Table<'i>,
        span: &Range<usize>,
    ) -> Result<([f64; 2], [f64; 2], [f64; 5], &'t Val<'i>, &'t Val<'i>)> {
        let fv = self.req(t, "focal_px", "camera.", span)?;
        let focal_px = match fv.get_ref() {
            DeValue::Array(_) => self.numbers::<2>(fv, "camera.focal_px")?,
            _ => {
                let f = self.num(fv, "camera.focal_px")?;
                [f, f]
            }
        };
        let pv = self.req(t, "principal_point_px", "camera.", span)?;
        let principal_point_px = self.numbers::<2>(pv, "camera.principal_point_px")?;
        let mut distortion = [0.0; 5];
        if let Some(dv) = self.get(t, "distortion") {
            let items = self.array(dv, "camera.distortion")?;
            if !(items.len() == 4 || items.len() == 5) {
                return Err(self.err(
                    &dv.span(),
                    "camera.distortion",
                    "expected [k1, k2, p1, p2] or [k1, k2, p1, p2, k3] (OpenCV order)",
                ));
            }
            for (d, it) in distortion.iter_mut().zip(items) {
                *d = self.num(it, "camera.distortion")?;
            }
        }
        Ok((focal_px, principal_point_px, distortion, fv, pv))
    }

    /// The camera's orientation (`look_at` and `up`, or `rotation`), and the values it
    /// was read from (for the spans of later errors).
    fn orientation<'t, 'i>(
        &self,
        t: &'t Table<'i>,
        span: &Range<usize>,
    ) -> Result<(CameraOrientation, (&'t Val<'i>, &'t Val<'i>))> {
        match (
            self.get(t, "look_at"),
            self.get(t, "up"),
            self.get(t, "rotation"),
        ) {
            (Some(lv), Some(uv), None) => {
                let look_at = self.numbers::<3>(lv, "camera.look_at")?;
                let up = self.numbers::<3>(uv, "camera.up")?;
                Ok((CameraOrientation::LookAt { look_at, up }, (lv, uv)))
            }
            (None, None, Some(rv)) => {
                let rows = self.array(rv, "camera.rotation")?;
                let bad = || {
                    self.err(
                        &rv.span(),
                        "camera.rotation",
                        "expected three rows of three numbers",
                    )
                };
                if rows.len() != 3 {
                    return Err(bad());
                }
                let mut m = [[0.0; 3]; 3];
                for (row, it) in m.iter_mut().zip(rows) {
                    *row = self
                        .numbers::<3>(it, "camera.rotation")
                        .map_err(|_| bad())?;
                }
                Ok((CameraOrientation::Rotation(m), (rv, rv)))
            }
            (_, _, Some(rv)) => Err(self.err(
                &rv.span(),
                "camera.rotation",
                "give either `rotation` or `look_at` and `up`, not both",
            )),
            (Some(lv), None, None) => {
                Err(self.err(&lv.span(), "camera.up", "`look_at` needs `up`"))
            }
            (None, Some(uv), None) => {
                Err(self.err(&uv.span(), "camera.look_at", "`up` needs `look_at`"))
            }
            (None, None, None) => Err(self.err(
                span,
                "camera.look_at",
                "the camera needs an orientation: `look_at` and `up`, or `rotation`",
            )),
        }
    }

    /// The `[[plane]]` tables, or the default plane; each is checked to have the camera
    /// in front of it.
    pub(super) fn planes(
        &self,
        root: &Table<'_>,
        camera: Option<&CameraSpec>,
    ) -> Result<Vec<PlaneSpec>> {
        let Some(pv) = self.get(root, "plane") else {
            let p = PlaneSpec {
                name: "default".into(),
                point: [0.0; 3],
                normal: [0.0, 0.0, 1.0],
                line: 0,
            };
            if let Some(cam) = camera
                && let Err(e) = ViewGeometry::new(cam.camera, Plane::horizontal())
            {
                return Err(IoError::Manifest {
                    path: self.path.to_path_buf(),
                    line: cam.line,
                    field: "camera.position".into(),
                    value: format!("{:?}", cam.position),
                    reason: format!("{e} (the default plane: point [0, 0, 0], normal [0, 0, 1])"),
                });
            }
            return Ok(vec![p]);
        };
        let items = self.array(pv, "plane")?;
        if items.is_empty() {
            return Err(self.err(&pv.span(), "plane", "no plane given"));
        }
        let mut out: Vec<PlaneSpec> = Vec::new();
        for (i, it) in items.iter().enumerate() {
            let pre = format!("plane[{}].", i + 1);
            let t = self.table(it, &format!("plane[{}]", i + 1))?;
            self.warn_unknown(t, &["name", "point", "normal"], &pre);
            let span = it.span();
            let nv = self.req(t, "name", &pre, &span)?;
            let name = self.string(nv, &format!("{pre}name"))?;
            if name.trim().is_empty() {
                return Err(self.err(&nv.span(), &format!("{pre}name"), "empty plane name"));
            }
            if out.iter().any(|p| p.name == name) {
                return Err(self.err(&nv.span(), &format!("{pre}name"), "duplicate plane name"));
            }
            let ptv = self.req(t, "point", &pre, &span)?;
            let point = self.numbers::<3>(ptv, &format!("{pre}point"))?;
            let normv = self.req(t, "normal", &pre, &span)?;
            let normal = self.numbers::<3>(normv, &format!("{pre}normal"))?;
            let plane = Plane::new(point, normal)
                .map_err(|e| self.err(&normv.span(), &format!("{pre}normal"), e.to_string()))?;
            if let Some(cam) = camera
                && let Err(e) = ViewGeometry::new(cam.camera, plane)
            {
                return Err(self.err(
                    &normv.span(),
                    &format!("{pre}normal"),
                    format!("{e}: the normal must point to the camera's side"),
                ));
            }
            out.push(PlaneSpec {
                name,
                point,
                normal,
                line: self.line(nv.span().start),
            });
        }
        Ok(out)
    }

    /// A region's `plane`: the index of the named plane (default 0).
    pub(super) fn region_plane(
        &self,
        t: &Table<'_>,
        pre: &str,
        planes: &[PlaneSpec],
    ) -> Result<usize> {
        let Some(v) = self.get(t, "plane") else {
            return Ok(0);
        };
        let field = format!("{pre}plane");
        let name = self.string(v, &field)?;
        planes.iter().position(|p| p.name == name).ok_or_else(|| {
            let known: Vec<&str> = planes.iter().map(|p| p.name.as_str()).collect();
            self.err(
                &v.span(),
                &field,
                format!("unknown plane (planes: {})", known.join(", ")),
            )
        })
    }

    /// The `[site]` table, if any.
    pub(super) fn site(&self, root: &Table<'_>) -> Result<Option<SiteSpec>> {
        let Some(sv) = self.get(root, "site") else {
            return Ok(None);
        };
        let t = self.table(sv, "site")?;
        let span = sv.span();
        self.warn_unknown(
            t,
            &[
                "latitude_deg",
                "longitude_deg",
                "elevation_m",
                "pressure_mbar",
                "temperature_c",
            ],
            "site.",
        );
        let ranged = |key: &str, lo: f64, hi: f64, default: Option<f64>, what: &str| match self
            .opt_num(t, key, "site.")?
        {
            Some((x, s)) if !(lo..=hi).contains(&x) => {
                Err(self.err(&s, &format!("site.{key}"), what.to_string()))
            }
            Some((x, _)) => Ok(x),
            None => default
                .ok_or_else(|| self.err(&span, &format!("site.{key}"), format!("missing `{key}`"))),
        };
        Ok(Some(SiteSpec {
            latitude_deg: ranged(
                "latitude_deg",
                -90.0,
                90.0,
                None,
                "latitude must be in [-90, 90] degrees",
            )?,
            longitude_deg: ranged(
                "longitude_deg",
                -180.0,
                180.0,
                None,
                "longitude must be in [-180, 180] degrees",
            )?,
            elevation_m: ranged(
                "elevation_m",
                -1e4,
                1e5,
                Some(0.0),
                "elevation must be in [-10000, 100000] metres",
            )?,
            pressure_mbar: ranged(
                "pressure_mbar",
                f64::MIN_POSITIVE,
                5000.0,
                Some(1013.25),
                "pressure must be in (0, 5000] millibars",
            )?,
            temperature_c: ranged(
                "temperature_c",
                -273.15,
                1000.0,
                Some(10.0),
                "temperature must be in [-273.15, 1000] degrees Celsius",
            )?,
        }))
    }

    /// A capture's `source`, with the rules of the module's documentation.
    pub(super) fn capture_source(
        &self,
        t: &Table<'_>,
        pre: &str,
        span: &Range<usize>,
        calibrated: bool,
        site: Option<&SiteSpec>,
    ) -> Result<Option<SourceSpec>> {
        let field = format!("{pre}source");
        let angle_keys = ["theta_i_deg", "theta_r_deg", "phi_deg"];
        let angle = angle_keys
            .iter()
            .find_map(|k| self.get(t, k).map(|v| (*k, v)));
        let Some(sv) = self.get(t, "source") else {
            if calibrated {
                if let Some((k, v)) = angle {
                    return Err(self.err(
                        &v.span(),
                        &format!("{pre}{k}"),
                        "with [camera], a capture gives `source` instead of angles \
                         (theta_i_deg, theta_r_deg, phi_deg)",
                    ));
                }
                return Err(self.err(
                    span,
                    &field,
                    "with [camera], a capture needs `source` ({ position = [x, y, z] }, \
                     { direction = [x, y, z] } or { sun = \"time\" })",
                ));
            }
            return Ok(None);
        };
        if !calibrated {
            return Err(self.err(
                &sv.span(),
                &field,
                "a `source` needs the calibrated camera: add a [camera] table, or give \
                 theta_i_deg instead",
            ));
        }
        if let Some((k, v)) = angle {
            return Err(self.err(
                &v.span(),
                &format!("{pre}{k}"),
                "give either `source` or the angles, not both",
            ));
        }
        let st = self.table(sv, &field)?;
        self.warn_unknown(st, &["position", "direction", "sun"], &format!("{field}."));
        Ok(Some(self.source_spec(st, &field, &sv.span(), site)?.0))
    }

    /// The source of table `t` (`field`, spanning `span`): exactly one of `position`,
    /// `direction` (normalized) or `sun` (resolved at `site`), and the line of its key.
    pub(super) fn source_spec(
        &self,
        t: &Table<'_>,
        field: &str,
        span: &Range<usize>,
        site: Option<&SiteSpec>,
    ) -> Result<(SourceSpec, usize)> {
        let kinds: Vec<(&str, &Val<'_>)> = ["position", "direction", "sun"]
            .into_iter()
            .filter_map(|k| self.get(t, k).map(|v| (k, v)))
            .collect();
        let [(kind, v)] = kinds[..] else {
            return Err(self.err(
                span,
                field,
                "a source needs exactly one of `position`, `direction` or `sun`",
            ));
        };
        let kfield = format!("{field}.{kind}");
        let spec = match kind {
            "position" => SourceSpec::Position(self.numbers::<3>(v, &kfield)?),
            "direction" => {
                let d = self.numbers::<3>(v, &kfield)?;
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if !(n.is_finite() && n > 0.0) {
                    return Err(self.err(&v.span(), &kfield, "direction must be non-zero"));
                }
                SourceSpec::Direction([d[0] / n, d[1] / n, d[2] / n])
            }
            _ => {
                let s = self.string(v, &kfield)?;
                if s.trim().is_empty() {
                    return Err(self.err(&v.span(), &kfield, "empty time"));
                }
                let Some(site) = site else {
                    return Err(self.err(
                        &v.span(),
                        &kfield,
                        "a `sun` source needs a [site] table (latitude_deg, longitude_deg, ...)",
                    ));
                };
                self.sun(s, site, v, &kfield)?
            }
        };
        Ok((spec, self.line(v.span().start)))
    }

    /// A `sun` source: parse the time and resolve the sun's direction at `site`.
    pub(super) fn sun(
        &self,
        time: String,
        site: &SiteSpec,
        v: &Val<'_>,
        field: &str,
    ) -> Result<SourceSpec> {
        let unix_seconds =
            parse_rfc3339(&time).map_err(|e| self.err(&v.span(), field, e.to_string()))?;
        let core_site = Site {
            latitude_deg: site.latitude_deg,
            longitude_deg: site.longitude_deg,
            elevation_m: site.elevation_m,
            pressure_mbar: site.pressure_mbar,
            temperature_c: site.temperature_c,
        };
        let pos = solar_position(unix_seconds, None, &core_site).map_err(|e| {
            self.err(
                &v.span(),
                field,
                format!("cannot compute the sun's position at {time:?} from [site]: {e}"),
            )
        })?;
        if !pos.is_up() {
            return Err(self.err(
                &v.span(),
                field,
                format!(
                    "the sun is below the horizon at {time} seen from [site] \
                     (elevation {:.3} degrees, zenith {:.3} degrees)",
                    pos.elevation_deg, pos.zenith_deg
                ),
            ));
        }
        Ok(SourceSpec::Sun {
            time,
            unix_seconds,
            zenith_deg: pos.zenith_deg,
            azimuth_deg: pos.azimuth_deg,
            direction: sun_direction(&pos),
        })
    }

    /// Check every region against every capture's source: the rays of its corners and
    /// centre meet its plane, and the source is above the plane's horizon there.
    pub(super) fn check_geometry(
        &self,
        cam: &CameraSpec,
        planes: &[PlaneSpec],
        regions: &[Region],
        captures: &[Capture],
        cap_vals: &[Val<'_>],
    ) -> Result<()> {
        self.check_opencv_image_size(cam.opencv.as_ref(), cam.line, captures)?;
        let views = planes
            .iter()
            .map(|p| {
                p.to_plane()
                    .and_then(|pl| ViewGeometry::new(cam.camera, pl))
                    .map_err(|e| IoError::Manifest {
                        path: self.path.to_path_buf(),
                        line: p.line,
                        field: "plane".into(),
                        value: p.name.clone(),
                        reason: e.to_string(),
                    })
            })
            .collect::<Result<Vec<_>>>()?;
        // Rays: independent of the source (probe with a source straight above).
        for r in regions {
            let Some(vg) = views.get(r.plane) else {
                continue;
            };
            let up = Source::Direction(vg.plane().normal());
            if let Err(e) = vg.check_rect(r.rect, &up) {
                let plane = planes.get(r.plane).map_or("", |p| p.name.as_str());
                return Err(r.rect_error(self.path, format!("{e} (plane {plane:?})")));
            }
        }
        for (c, cv) in captures.iter().zip(cap_vals) {
            let Some(src) = c.illumination.as_ref().and_then(SourceSpec::to_source) else {
                continue;
            };
            let key = c.illumination.as_ref().map_or("position", SourceSpec::key);
            let field = format!("capture[{}].source.{key}", c.index);
            let span = cv
                .get_ref()
                .as_table()
                .and_then(|t| self.get(t, "source"))
                .map_or(cv.span(), |v| v.span());
            for r in regions {
                let Some(vg) = views.get(r.plane) else {
                    continue;
                };
                if let Err(e) = vg.check_rect(r.rect, &src) {
                    return Err(self.err(
                        &span,
                        &field,
                        format!("for target {:?} (region[{}]): {e}", r.name, r.index),
                    ));
                }
            }
        }
        Ok(())
    }
}
