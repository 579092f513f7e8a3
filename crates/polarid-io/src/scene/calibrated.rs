//! Calibrated scenes: a `[camera]` table (and optional `[[plane]]`, `[site]`) read by the
//! manifest's own parser ([`crate::manifest::shared`]), `[[source]]` tables (one capture
//! each: `position`, `direction` or `sun`, optional `intensity` and `name`), and plates
//! placed on planes by `center`, `size` and `axis`.
//!
//! Each plate's `rect` is the bounding box of the pixels that see it (rays traced through
//! every pixel, the nearest plate wins), and its measured `region` is by default the
//! largest rectangle of such pixels, inset as [`super::default_region`] insets a
//! far-field plate. Every source must be above the horizon of every plate's plane.

use std::collections::HashSet;

use polarid_core::geometry::{Plane, ViewGeometry};
use polarid_core::region::Rect;
use polarid_core::simulate::{PerspectiveScene, PlanarPlate};
use toml::Spanned;

use super::context::Ctx;
use super::plates::{PlateContext, default_region};
use super::raw::{RawPlate, RawScene};
use super::types::{Calibrated, Placement, Plate, SceneSource};
use crate::error::Result;
use crate::manifest::SourceSpec;
use crate::manifest::shared::{parse_geometry_tables, parse_sources};

/// Most light sources (captures) of a scene.
const MAX_SOURCES: usize = 10_000;

/// The largest rectangle of pixels equal to `value` in a `width × height` map
/// (row-major), by the histogram method (`O(width × height)`); `None` when no pixel is.
pub(super) fn largest_rect(map: &[u16], width: usize, height: usize, value: u16) -> Option<Rect> {
    let mut heights = vec![0usize; width];
    let mut best: Option<(usize, Rect)> = None;
    let mut stack: Vec<usize> = Vec::with_capacity(width + 1);
    for row in 0..height {
        for (col, h) in heights.iter_mut().enumerate() {
            *h = if map[row * width + col] == value {
                *h + 1
            } else {
                0
            };
        }
        stack.clear();
        for col in 0..=width {
            let h = if col < width { heights[col] } else { 0 };
            while let Some(&top) = stack.last() {
                if heights[top] <= h {
                    break;
                }
                stack.pop();
                let ht = heights[top];
                let left = stack.last().map_or(0, |&l| l + 1);
                let w = col - left;
                let area = w * ht;
                if best.as_ref().is_none_or(|(a, _)| area > *a) {
                    best = Some((
                        area,
                        Rect {
                            x: left,
                            y: row + 1 - ht,
                            width: w,
                            height: ht,
                        },
                    ));
                }
            }
            stack.push(col);
        }
    }
    best.map(|(_, r)| r)
}

impl Ctx<'_> {
    fn vec3(&self, v: &Spanned<Vec<f64>>, field: &str) -> Result<[f64; 3]> {
        match v.get_ref()[..] {
            [a, b, c] if [a, b, c].iter().all(|x| x.is_finite()) => Ok([a, b, c]),
            _ => Err(self.err(&v.span(), field, "expected an array of 3 finite numbers")),
        }
    }

    fn plate_size(&self, v: &Spanned<toml::Value>, field: &str) -> Result<[f64; 2]> {
        let num = |x: &toml::Value| match x {
            toml::Value::Integer(i) => Some(*i as f64),
            toml::Value::Float(f) => Some(*f),
            _ => None,
        };
        let size = match v.get_ref() {
            toml::Value::Array(a) if a.len() == 2 => [num(&a[0]), num(&a[1])],
            x => [num(x), num(x)],
        };
        match size {
            [Some(w), Some(h)] if [w, h].iter().all(|s| s.is_finite() && *s > 0.0) => Ok([w, h]),
            _ => Err(self.err(
                &v.span(),
                field,
                "size must be [width, height] (or one number for a square), finite and > 0",
            )),
        }
    }

    /// The calibrated geometry and the placed plates of a scene with a `[camera]`.
    pub(super) fn calibrated(
        &self,
        raw: &RawScene,
        width: usize,
        height: usize,
        cx: &PlateContext<'_>,
    ) -> Result<(Calibrated, Vec<Plate>)> {
        self.refuse(
            [
                ("theta_r_deg", raw.theta_r_deg.as_ref().map(|v| v.span())),
                ("phi_deg", raw.phi_deg.as_ref().map(|v| v.span())),
                ("theta_i_deg", raw.theta_i_deg.as_ref().map(|v| v.span())),
            ],
            &str::to_string,
            "with [camera], the angles come from the calibrated geometry: give the light \
             sources as [[source]] tables (position, direction or sun) instead",
        )?;
        let tables = parse_geometry_tables(self.path, self.text)?;
        let Some(camera) = tables.camera else {
            return Err(self.missing(None, "camera", "[camera] table"));
        };
        let sources = self.sources(raw, tables.site.as_ref())?;
        let planes = tables.planes;
        let plates = self.placed_plates(&raw.plate, &camera.camera, &planes, cx)?;
        let calibrated = Calibrated {
            camera,
            planes,
            site: tables.site,
            sources,
        };
        let plates = self.locate_plates(raw, plates, &calibrated, width, height)?;
        Ok((calibrated, plates))
    }

    fn sources(
        &self,
        raw: &RawScene,
        site: Option<&crate::manifest::SiteSpec>,
    ) -> Result<Vec<SceneSource>> {
        let entries = parse_sources(self.path, self.text, "source", site)?;
        let raw_sources = raw.source.as_ref().map_or(&[][..], |s| &s.get_ref()[..]);
        if entries.is_empty() {
            return Err(self.missing(
                None,
                "source",
                "[[source]] tables: a calibrated scene needs at least one light source \
                 (position, direction or sun)",
            ));
        }
        if entries.len() > MAX_SOURCES {
            let span = raw.source.as_ref().map_or(0..0, |s| s.span());
            return Err(self.err(&span, "source", "more than 10000 light sources"));
        }
        let mut names = HashSet::new();
        let mut out = Vec::with_capacity(entries.len());
        for (i, (e, r)) in entries.into_iter().zip(raw_sources).enumerate() {
            let f = |k: &str| format!("source[{}].{k}", i + 1);
            let intensity = match &r.intensity {
                Some(v) => self.num_in(v, &f("intensity"), |x| x > 0.0, "> 0")?,
                None => 1.0,
            };
            let name = match &r.name {
                Some(v) => {
                    let n = self.name(v, &f("name"))?;
                    if n.starts_with('.') || n.contains(char::is_whitespace) {
                        return Err(self.err(
                            &v.span(),
                            &f("name"),
                            "a source name is a directory name: no leading dot, no spaces",
                        ));
                    }
                    if !names.insert(n.clone()) {
                        return Err(self.err(&v.span(), &f("name"), "duplicate source name"));
                    }
                    Some(n)
                }
                None => None,
            };
            out.push(SceneSource {
                spec: e.spec,
                intensity,
                name,
                line: e.line,
            });
        }
        Ok(out)
    }

    /// Name, optics and placement of every plate (not yet located in the image).
    fn placed_plates(
        &self,
        raw: &[RawPlate],
        camera: &polarid_core::geometry::PinholeCamera,
        planes: &[crate::manifest::PlaneSpec],
        cx: &PlateContext<'_>,
    ) -> Result<Vec<(Plate, PlanarPlate)>> {
        self.each_plate(raw, cx, |_, p, b, f| {
            let near = Some(b.name_span.clone());
            let near = near.as_ref();
            if let Some(v) = &p.rect {
                return Err(self.err(
                    &v.span(),
                    &f("rect"),
                    "in a calibrated scene a plate is placed by `center` and `size` (and \
                     `plane`, `axis`); its place in the image follows from the camera",
                ));
            }
            let plane = match &p.plane {
                None => 0,
                Some(v) => planes
                    .iter()
                    .position(|q| &q.name == v.get_ref())
                    .ok_or_else(|| {
                        let known: Vec<&str> = planes.iter().map(|q| q.name.as_str()).collect();
                        self.err(
                            &v.span(),
                            &f("plane"),
                            format!("unknown plane (planes: {})", known.join(", ")),
                        )
                    })?,
            };
            let spec = &planes[plane];
            let core_plane = spec
                .to_plane()
                .map_err(|e| self.missing(near, &f("plane"), &e.to_string()))?;
            let cv = p
                .center
                .as_ref()
                .ok_or_else(|| self.missing(near, &f("center"), "plate centre `center`"))?;
            let center = self.vec3(cv, &f("center"))?;
            let sv = p
                .size
                .as_ref()
                .ok_or_else(|| self.missing(near, &f("size"), "plate size `size`"))?;
            let size = self.plate_size(sv, &f("size"))?;
            let off = core_plane.height(center);
            if off.abs() > 1e-6 * size[0].max(size[1]) {
                return Err(self.err(
                    &cv.span(),
                    &f("center"),
                    format!(
                        "the centre is not on plane {:?} (it is {off} away along the normal)",
                        spec.name
                    ),
                ));
            }
            let axis = match &p.axis {
                Some(v) => self.vec3(v, &f("axis"))?,
                None => default_axis(camera, &core_plane),
            };
            let planar =
                PlanarPlate::new(core_plane, center, axis, size, b.optics).map_err(|e| match &p
                    .axis
                {
                    Some(v) => self.err(&v.span(), &f("axis"), e.to_string()),
                    None => self.err(&sv.span(), &f("size"), e.to_string()),
                })?;
            let [u, _] = planar.axes();
            let placement = Placement {
                plane,
                center: planar.center(),
                axis: u,
                size,
            };
            // The box and the region are found in the image later (`locate_plates`).
            let unit = Rect {
                x: 0,
                y: 0,
                width: 1,
                height: 1,
            };
            Ok((b.into_plate(unit, unit, Some(placement)), planar))
        })
    }

    /// Trace every pixel: each plate's bounding box and measured region; check that every
    /// source lights every plate's plane.
    fn locate_plates(
        &self,
        raw: &RawScene,
        plates: Vec<(Plate, PlanarPlate)>,
        cal: &Calibrated,
        width: usize,
        height: usize,
    ) -> Result<Vec<Plate>> {
        let cam_span = raw.camera.as_ref().map_or(0..0, |c| c.span());
        let planar: Vec<PlanarPlate> = plates.iter().map(|(_, p)| *p).collect();
        let scene = PerspectiveScene::new(cal.camera.camera, planar)
            .map_err(|e| self.err(&cam_span, "camera.position", e.to_string()))?;
        let mut map = vec![0u16; width * height];
        scene.plate_map(width, height, &mut map).map_err(|e| {
            self.err(
                &cam_span,
                "camera.distortion",
                format!("cannot trace the frame's pixels: {e}"),
            )
        })?;
        let mut out = Vec::with_capacity(plates.len());
        for (i, ((mut plate, pp), rp)) in plates.into_iter().zip(&raw.plate).enumerate() {
            let f = |k: &str| format!("plate[{}].{k}", i + 1);
            let id = i as u16 + 1;
            let cspan = rp.center.as_ref().map_or(0..0, |v| v.span());
            let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
            for (j, _) in map.iter().enumerate().filter(|(_, m)| **m == id) {
                let (x, y) = (j % width, j / width);
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
            }
            if x0 == usize::MAX {
                return Err(self.err(
                    &cspan,
                    &f("center"),
                    "the camera does not see this plate (outside the frame, or hidden by \
                     another plate)",
                ));
            }
            plate.rect = Rect {
                x: x0,
                y: y0,
                width: x1 + 1 - x0,
                height: y1 + 1 - y0,
            };
            plate.region = match &rp.region {
                Some(v) => {
                    let r = self.rect(v, &f("region"))?;
                    if let Err(e) = r.check(width, height) {
                        return Err(self.err(&v.span(), &f("region"), e.to_string()));
                    }
                    let off = (r.y..r.y + r.height)
                        .flat_map(|y| (r.x..r.x + r.width).map(move |x| (x, y)))
                        .filter(|&(x, y)| map[y * width + x] != id)
                        .count();
                    if off > 0 {
                        return Err(self.err(
                            &v.span(),
                            &f("region"),
                            format!(
                                "{off} of the region's {} pixels do not see the plate",
                                r.width * r.height
                            ),
                        ));
                    }
                    r
                }
                None => largest_rect(&map, width, height, id)
                    .and_then(default_region)
                    .ok_or_else(|| {
                        let span = rp.size.as_ref().map_or(0..0, |v| v.span());
                        self.err(
                            &span,
                            &f("size"),
                            "the plate is too small in the image for a default region; \
                             give `region` or a larger plate",
                        )
                    })?,
            };
            // Every source above the plate plane's horizon (then every point of the
            // plane sees it at an incidence below 90°).
            let view = ViewGeometry::new(cal.camera.camera, *pp.plane())
                .map_err(|e| self.err(&cam_span, "camera.position", e.to_string()))?;
            for (j, s) in cal.sources.iter().enumerate() {
                if let Err(e) = view.check_rect(plate.region, &s.light().source) {
                    let value = match &s.spec {
                        SourceSpec::Position(p) | SourceSpec::Direction(p) => format!("{p:?}"),
                        SourceSpec::Sun { time, .. } => format!("{time:?}"),
                    };
                    return Err(crate::IoError::Manifest {
                        path: self.path.to_path_buf(),
                        line: s.line,
                        field: format!("source[{}].{}", j + 1, s.spec.key()),
                        value,
                        reason: format!(
                            "for plate {:?} on plane {:?}: {e}",
                            plate.name,
                            cal.planes[plate.placement.as_ref().map_or(0, |p| p.plane)].name
                        ),
                    });
                }
            }
            out.push(plate);
        }
        Ok(out)
    }
}

/// The default direction of a plate's width: the camera's image x axis projected onto
/// the plane (or its y axis when x is along the normal).
fn default_axis(camera: &polarid_core::geometry::PinholeCamera, plane: &Plane) -> [f64; 3] {
    let n = plane.normal();
    let r = camera.rotation();
    for a in [r[0], r[1]] {
        let d = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
        let p = [a[0] - d * n[0], a[1] - d * n[1], a[2] - d * n[2]];
        if p.iter().map(|x| x * x).sum::<f64>() > 1e-6 {
            return p;
        }
    }
    r[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_rect_of_a_mask() {
        #[rustfmt::skip]
        let m: Vec<u16> = vec![
            0, 1, 1, 0, 0,
            1, 1, 1, 1, 0,
            1, 1, 1, 1, 2,
            0, 1, 1, 1, 2,
        ];
        let r = largest_rect(&m, 5, 4, 1).unwrap();
        // 3 × 3 at (1, 1) (area 9) beats 2 × 4 (8) and 4 × 2 (8).
        assert_eq!(
            r,
            Rect {
                x: 1,
                y: 1,
                width: 3,
                height: 3
            }
        );
        assert_eq!(
            largest_rect(&m, 5, 4, 2).unwrap(),
            Rect {
                x: 4,
                y: 2,
                width: 1,
                height: 2
            }
        );
        assert!(largest_rect(&m, 5, 4, 3).is_none());
    }
}

#[cfg(test)]
mod scene_tests {
    use std::path::Path;

    use crate::manifest::SourceSpec;
    use crate::scene::tests::parse_err as err;
    use crate::scene::{Geometry, parse};

    pub(crate) const BENCH: &str = r#"name = "bench"
width = 160
height = 120
seed = 1

[camera]
focal_px = 220.0
principal_point_px = [79.5, 59.5]
position = [-0.5, 0.0, 0.6]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]

[[plane]]
name = "bench"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[[source]]
position = [0.5, 0.0, 0.6]

[[source]]
position = [0.45, 0.2, 0.6]
intensity = 2.0
name = "side"

[[source]]
direction = [1.0, 0.0, 1.0]

[[plate]]
name = "al"
class = "aluminum"
n = 1.5
k = 7.6
sigma = 0.2
center = [0.0, 0.0, 0.0]
size = 0.1

[[plate]]
name = "cu"
n = 0.27
k = 3.4
sigma = 0.2
center = [0.0, 0.15, 0.0]
size = [0.1, 0.08]
"#;

    #[test]
    fn parses_a_calibrated_scene() {
        let s = parse(Path::new("b.toml"), BENCH).unwrap();
        let Geometry::Calibrated(c) = &s.geometry else {
            panic!("calibrated expected")
        };
        assert_eq!(s.captures(), 3);
        assert_eq!(c.sources[1].intensity, 2.0);
        assert_eq!(c.sources[1].name.as_deref(), Some("side"));
        assert_eq!(c.sources[1].line, 22);
        let d = 0.5f64.sqrt();
        assert!(matches!(c.sources[2].spec, SourceSpec::Direction(v)
            if (v[0] - d).abs() < 1e-15 && (v[2] - d).abs() < 1e-15));
        assert_eq!(c.planes.len(), 1);
        // The aluminum plate is centred on the optical axis: its region is about the
        // principal point; both regions lie inside their plates' boxes.
        let cam = c.camera.to_camera();
        for p in &s.plates {
            let pl = p.placement.as_ref().unwrap();
            let [u, v] = cam.project(pl.center).unwrap();
            let r = p.region;
            assert!(
                (r.x as f64) < u && u < (r.x + r.width) as f64,
                "{}: {r:?} {u}",
                p.name
            );
            assert!((r.y as f64) < v && v < (r.y + r.height) as f64);
            assert!(r.x >= p.rect.x && r.x + r.width <= p.rect.x + p.rect.width);
            assert!(r.width >= 10 && r.height >= 6, "{r:?}");
            assert_eq!((r.x % 2, r.y % 2, r.width % 2, r.height % 2), (0, 0, 0, 0));
        }
        assert_eq!(s.plates[1].placement.as_ref().unwrap().size, [0.1, 0.08]);
        // Default axis: the camera's image x projected onto the bench (here −y).
        let ax = s.plates[0].placement.as_ref().unwrap().axis;
        assert!((ax[1] + 1.0).abs() < 1e-12, "{ax:?}");
    }

    #[test]
    fn calibrated_scene_errors_name_the_field() {
        let e = err(&BENCH.replace("seed = 1", "seed = 1\ntheta_i_deg = [40, 50]"));
        assert!(e.contains("theta_i_deg") && e.contains("[[source]]"), "{e}");
        let e = err(&BENCH.replace("position = [0.5, 0.0, 0.6]", "position = [0.5, 0.0, -0.1]"));
        assert!(
            e.contains("source[1].position") && e.contains("line 19") && e.contains("horizon"),
            "{e}"
        );
        let e = err(&BENCH.replace("center = [0.0, 0.15, 0.0]", "center = [0.0, 0.15, 0.01]"));
        assert!(
            e.contains("plate[2].center") && e.contains("not on plane"),
            "{e}"
        );
        let e = err(&BENCH.replace("center = [0.0, 0.15, 0.0]", "center = [3.0, 0.15, 0.0]"));
        assert!(
            e.contains("plate[2].center") && e.contains("does not see"),
            "{e}"
        );
        let e = err(&BENCH.replace("focal_px = 220.0", "focl_px = 220.0"));
        assert!(e.contains("focl_px") && e.contains("line 7"), "{e}");
        let e = err(&BENCH.replace("size = 0.1\n", "size = 0.1\nrect = [0, 0, 8, 8]\n"));
        assert!(e.contains("plate[1].rect") && e.contains("center"), "{e}");
        let e = err(&BENCH.replace("size = [0.1, 0.08]", "size = [0.1, 0.08]\nplane = \"wall\""));
        assert!(e.contains("plate[2].plane") && e.contains("bench"), "{e}");
        let e = err(&BENCH.replace(
            "direction = [1.0, 0.0, 1.0]",
            "sun = \"2024-06-01T12:00:00Z\"",
        ));
        assert!(e.contains("source[3].sun") && e.contains("[site]"), "{e}");
        let e = err(&BENCH.replace(
            "direction = [1.0, 0.0, 1.0]",
            "direction = [1.0, 0.0, 1.0]\nposition = [0.0, 0.0, 1.0]",
        ));
        assert!(e.contains("source[3]") && e.contains("exactly one"), "{e}");
        let e = err(&BENCH.replace("intensity = 2.0", "intensity = 0.0"));
        assert!(e.contains("source[2].intensity"), "{e}");
        let e = err(&BENCH.replace("name = \"side\"", "name = \"..\""));
        assert!(e.contains("source[2].name"), "{e}");
        let e = err(&BENCH.replace("up = [0.0, 0.0, 1.0]", "up = [0.5, 0.0, -0.6]"));
        assert!(e.contains("camera.up"), "{e}");
        let e = err(&BENCH.replace("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, -1.0]"));
        assert!(e.contains("plane[1].normal"), "{e}");
        let e = err(&BENCH.replace("size = 0.1\n", "size = 0.012\n"));
        assert!(
            e.contains("plate[1].size") && e.contains("too small"),
            "{e}"
        );
        let e = err(&BENCH.replace("size = 0.1\n", "size = 0.1\nregion = [0, 0, 10, 10]\n"));
        assert!(
            e.contains("plate[1].region") && e.contains("do not see"),
            "{e}"
        );
        let e = err(&BENCH.replace("size = 0.1\n", "size = 0.1\naxis = [0.0, 0.0, 1.0]\n"));
        assert!(e.contains("plate[1].axis"), "{e}");
        // A far-field scene with calibrated tables.
        let far = crate::scene::tests::GOOD.to_string() + "\n[[source]]\nposition = [0, 0, 1]\n";
        let e = err(&far);
        assert!(e.contains("source") && e.contains("[camera]"), "{e}");
        let far = crate::scene::tests::GOOD.replace("rect = [0, 0, 32, 32]", "center = [0, 0, 0]");
        let e = err(&far);
        assert!(
            e.contains("plate[1].center") && e.contains("calibrated"),
            "{e}"
        );
    }

    /// A calibrated scene may be a colour one: every plate gets its optics per
    /// band, the frame must still be whole 4×4 periods.
    #[test]
    fn calibrated_colour_scene_parses() {
        let text = BENCH.replace(
            "seed = 1\n",
            "seed = 1\n[capture]\nkind = \"dofp\"\ncolor = \"RGGB\"\n",
        );
        let text = text.replace(
            "n = 0.27\nk = 3.4\n",
            "n = { R = 0.25, G = 0.97, B = 1.25 }\nk = { R = 3.6, G = 2.6, B = 2.4 }\n",
        );
        let s = parse(Path::new("b.toml"), &text).unwrap();
        assert!(s.calibrated().is_some());
        let bands = s.capture.bands().unwrap();
        assert_eq!(bands.iter().map(|b| b.letter).collect::<String>(), "RGB");
        assert_eq!(s.plates[0].bands.len(), 3);
        assert!(s.plates[0].bands.iter().all(|o| (o.n, o.k) == (1.5, 7.6)));
        let cu: Vec<(f64, f64)> = s.plates[1].bands.iter().map(|o| (o.n, o.k)).collect();
        assert_eq!(cu, vec![(0.25, 3.6), (0.97, 2.6), (1.25, 2.4)]);
        let e = err(&text.replace("width = 160", "width = 162"));
        assert!(e.contains("width") && e.contains("multiples of 4"), "{e}");
    }

    #[test]
    fn sun_sources_resolve_at_the_site() {
        let text = BENCH.replace(
            "direction = [1.0, 0.0, 1.0]",
            "sun = \"2003-10-17T12:30:30-07:00\"",
        ) + "\n[site]\nlatitude_deg = 39.742476\nlongitude_deg = -105.1786\nelevation_m = 1830.14\npressure_mbar = 820.0\ntemperature_c = 11.0\n";
        let s = parse(Path::new("b.toml"), &text).unwrap();
        let c = s.calibrated().unwrap();
        let SourceSpec::Sun {
            zenith_deg,
            azimuth_deg,
            ..
        } = c.sources[2].spec
        else {
            panic!("sun expected")
        };
        // SPA's reference case (ΔT estimated: within 0.01° of 50.11162, 194.34024).
        assert!((zenith_deg - 50.11162).abs() < 0.01, "{zenith_deg}");
        assert!((azimuth_deg - 194.34024).abs() < 0.01, "{azimuth_deg}");
        // At night: an error naming the source.
        let night = text.replace("12:30:30-07:00", "23:30:30-07:00");
        let e = err(&night);
        assert!(
            e.contains("source[3].sun") && e.contains("below the horizon"),
            "{e}"
        );
    }
}
