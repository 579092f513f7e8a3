//! The per-pixel angles of a calibrated map: for every map pixel and capture, `β`
//! (eq. 5) where the pixel's ray meets its plane, lit by the capture's source
//! ([`ViewGeometry::pixel`]).
//!
//! - A map pixel's geometry is that of the centre of its `b × b` block in the
//!   coordinates of the files as stored (the raw mosaic for DoFP captures):
//!   `(x·b + (b − 1)/2, y·b + (b − 1)/2)`, pixel centres at integers.
//! - Its plane is the plane of the first region (in manifest order) whose rectangle
//!   contains that centre (pixel `i` covering `[i − ½, i + ½)`), else the first
//!   `[[plane]]`.
//! - Where the geometry fails (the ray misses the plane or meets it behind the camera,
//!   the source is below the plane's horizon, a lamp on the point) the β is NaN: the
//!   map leaves the pixel unclassified with reason `no_geometry`.

use polarid_core::geometry::{RayHit, ViewGeometry};
use polarid_io::IoError;
use polarid_io::manifest::Manifest;
use rayon::prelude::*;

use super::capture::Dims;
use crate::error::{PipelineError, Result};

/// The β images of a calibrated map, one per capture (radians, f32, NaN where the pixel
/// has no geometry), and each capture's β range over the pixels that have one
/// (radians; NaN when none has).
#[derive(Debug, Clone, Default)]
pub(crate) struct BetaMaps {
    pub beta: Vec<Vec<f32>>,
    pub range: Vec<[f64; 2]>,
}

/// The β images of the captures of calibrated manifest `m` for a map of size `d`
/// binned by `bin`; `progress(i)` after capture `i`.
///
/// Errors: the manifest has no `[camera]`, a capture has no `source` (a manifest that
/// was loaded and checked has both), a camera behind a plane.
pub(crate) fn beta_maps(
    m: &Manifest,
    d: Dims,
    bin: usize,
    progress: &dyn Fn(usize),
) -> Result<BetaMaps> {
    let core = |e| PipelineError::from(IoError::core(&m.path, e));
    let data = |reason: String| PipelineError::Data {
        path: m.path.display().to_string(),
        reason,
    };
    let Some(cam) = &m.camera else {
        return Err(data("per-pixel angles need a [camera] table".into()));
    };
    let camera = cam.to_camera();
    let views = m
        .planes
        .iter()
        .map(|p| ViewGeometry::new(camera, p.to_plane().map_err(core)?).map_err(core))
        .collect::<Result<Vec<_>>>()?;
    let plane = plane_of_pixels(m, d, bin);
    let half = (bin as f64 - 1.0) / 2.0;
    // Every pixel's ray is undistorted and met with its plane once, not once per
    // capture (`ViewGeometry::ray_hit`; the same β as `ViewGeometry::pixel`, bit for bit).
    let mut hits: Vec<Option<RayHit>> = vec![None; d.out_w * d.out_h];
    hits.par_chunks_mut(d.out_w)
        .zip(plane.par_chunks(d.out_w))
        .enumerate()
        .for_each(|(y, (row, prow))| {
            let v = (y * bin) as f64 + half;
            for (x, (h, &pi)) in row.iter_mut().zip(prow).enumerate() {
                let u = (x * bin) as f64 + half;
                *h = views.get(pi as usize).and_then(|g| g.ray_hit(u, v).ok());
            }
        });
    let mut out = BetaMaps::default();
    for (i, c) in m.captures.iter().enumerate() {
        let Some(source) = c.illumination.as_ref().and_then(|s| s.to_source()) else {
            return Err(data(format!(
                "capture {} (line {}) has no source: a manifest with [camera] needs one per capture",
                c.index, c.line
            )));
        };
        let mut beta = vec![f32::NAN; d.out_w * d.out_h];
        beta.par_chunks_mut(d.out_w)
            .zip(plane.par_chunks(d.out_w))
            .zip(hits.par_chunks(d.out_w))
            .for_each(|((row, prow), hrow)| {
                for ((b, &pi), h) in row.iter_mut().zip(prow).zip(hrow) {
                    *b = match (views.get(pi as usize), h) {
                        (Some(g), Some(h)) => g
                            .pixel_at_hit(h, &source)
                            .map_or(f32::NAN, |g| g.beta as f32),
                        _ => f32::NAN,
                    };
                }
            });
        out.range.push(range(&beta));
        out.beta.push(beta);
        progress(i + 1);
    }
    Ok(out)
}

/// The smallest and largest finite β of an image (NaN, NaN when none).
fn range(beta: &[f32]) -> [f64; 2] {
    let (lo, hi) = beta
        .iter()
        .filter(|b| b.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &b| {
            (l.min(b as f64), h.max(b as f64))
        });
    if lo <= hi {
        [lo, hi]
    } else {
        [f64::NAN, f64::NAN]
    }
}

/// The plane (index into [`Manifest::planes`]) of every map pixel: the plane of the
/// first region whose rectangle contains the centre of the pixel's block, else 0.
fn plane_of_pixels(m: &Manifest, d: Dims, bin: usize) -> Vec<u16> {
    let mut plane = vec![0u16; d.out_w * d.out_h];
    if m.regions.iter().all(|r| r.plane == 0) {
        return plane;
    }
    let half = (bin as f64 - 1.0) / 2.0;
    // Pixel i covers [i - 1/2, i + 1/2): a centre c lies in [x, x + w) pixels when
    // x - 1/2 <= c < x + w - 1/2.
    let inside = |c: f64, x: usize, w: usize| c >= x as f64 - 0.5 && c < (x + w) as f64 - 0.5;
    for (y, row) in plane.chunks_mut(d.out_w).enumerate() {
        let v = (y * bin) as f64 + half;
        for (x, p) in row.iter_mut().enumerate() {
            let u = (x * bin) as f64 + half;
            if let Some(r) = m
                .regions
                .iter()
                .find(|r| inside(u, r.rect.x, r.rect.width) && inside(v, r.rect.y, r.rect.height))
            {
                *p = r.plane as u16;
            }
        }
    }
    plane
}

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_core::geometry::Source;

    /// A calibrated manifest (camera 0.8 m from the bench, looking at it 60° from the
    /// normal, principal point high in the frame so that the top rows see the sky), a
    /// second plane tilted by 20° holding region `tilted`, and two lamps.
    fn manifest(dir: &std::path::Path) -> Manifest {
        std::fs::write(dir.join("s.tif"), b"").unwrap();
        let text = r#"
[camera]
focal_px = 100.0
principal_point_px = [31.5, 60.0]
position = [0.69282032302755, 0.0, 0.4]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]

[[plane]]
name = "bench"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[[plane]]
name = "tilted"
point = [0.0, 0.0, 0.0]
normal = [0.34202014332567, 0.0, 0.93969262078591]

[[region]]
name = "a"
rect = [4, 70, 20, 10]

[[region]]
name = "t"
rect = [40, 70, 20, 10]
plane = "tilted"

[[capture]]
source = { position = [-0.35, 0.0, 0.6] }
stokes = { s0 = "s.tif", s1 = "s.tif", s2 = "s.tif" }

[[capture]]
source = { position = [-0.5, 0.1, 0.45] }
stokes = { s0 = "s.tif", s1 = "s.tif", s2 = "s.tif" }
"#;
        polarid_io::manifest::parse(&dir.join("m.toml"), text).unwrap()
    }

    /// β of every map pixel is the geometry of its block centre on its plane (the
    /// region's plane inside a region's rectangle, else the first); rays that miss the
    /// plane give NaN; the ranges are those of the finite values.
    #[test]
    fn beta_maps_follow_block_centres_and_planes() {
        let tmp = tempfile::tempdir().unwrap();
        let m = manifest(tmp.path());
        let cam = m.camera.as_ref().unwrap().to_camera();
        let views: Vec<ViewGeometry> = m
            .planes
            .iter()
            .map(|p| ViewGeometry::new(cam, p.to_plane().unwrap()).unwrap())
            .collect();
        let (w, h) = (64usize, 96usize);
        for bin in [1usize, 2, 4] {
            let d = Dims {
                width: w,
                height: h,
                out_w: w / bin,
                out_h: h / bin,
            };
            let done = std::sync::Mutex::new(vec![]);
            let b = beta_maps(&m, d, bin, &|i| done.lock().unwrap().push(i)).unwrap();
            assert_eq!(*done.lock().unwrap(), vec![1, 2]);
            assert_eq!(b.beta.len(), 2);
            let half = (bin as f64 - 1.0) / 2.0;
            let mut sky = 0;
            for (ci, c) in m.captures.iter().enumerate() {
                let src = c.illumination.as_ref().unwrap().to_source().unwrap();
                for y in 0..d.out_h {
                    for x in 0..d.out_w {
                        let (u, v) = ((x * bin) as f64 + half, (y * bin) as f64 + half);
                        // Region "t" (columns 40..60, rows 70..80) is on the tilted plane.
                        let on_t = (39.5..59.5).contains(&u) && (69.5..79.5).contains(&v);
                        let g = views[usize::from(on_t)].pixel(u, v, &src);
                        let got = b.beta[ci][y * d.out_w + x];
                        match g {
                            Ok(g) => assert_eq!(got, g.beta as f32, "bin {bin} ({x}, {y})"),
                            Err(_) => {
                                assert!(got.is_nan(), "bin {bin} ({x}, {y}): {got}");
                                sky += 1;
                            }
                        }
                    }
                }
                let finite: Vec<f64> = b.beta[ci]
                    .iter()
                    .filter(|v| v.is_finite())
                    .map(|&v| v as f64)
                    .collect();
                let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                assert_eq!(b.range[ci], [lo, hi]);
            }
            // The top rows look above the horizon (in both captures).
            assert!(
                sky >= 2 * d.out_w,
                "bin {bin}: {sky} pixels without geometry"
            );
            // The tilted plane changes β inside region "t".
            let (x, y) = (50 / bin, 75 / bin);
            let (u, v) = ((x * bin) as f64 + half, (y * bin) as f64 + half);
            let src = Source::Position([-0.35, 0.0, 0.6]);
            let bench = views[0].pixel(u, v, &src).unwrap().beta as f32;
            assert!((b.beta[0][y * d.out_w + x] - bench).abs() > 0.01);
        }
    }
}
