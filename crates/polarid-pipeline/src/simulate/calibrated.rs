//! Simulation of a calibrated scene: a pinhole camera, plates on planes, one light per
//! capture (`polarid_core::simulate::perspective`).
//!
//! Per capture, in turn ([`trace_capture`]): the radiance Stokes vector of every pixel
//! (f32) in every band and the plate it sees are rendered from one traced geometry
//! (`PerspectiveScene::render_bands`; a single-band scene is one band with the plates'
//! own optics and response 1); the exposure is resolved from the brightest plate pixel
//! (noise-free, over bands weighted by their responses `r_b` and polarizer angles), as
//! for far-field scenes, and band `b` gets `exposure · full_well · r_b` electrons per
//! unit radiance; the frames are rendered from the Stokes maps with the sensor model (one
//! frame per analyzer, in parallel, or one raw colour mosaic,
//! `render_colour_frame_stokes`) and written; the truth of every plate's region is
//! computed per band from its pixels (f64). Memory: one Stokes map per band (12 bytes a
//! pixel), one plate map (2 bytes a pixel) and the frames of one capture.

use polarid_core::CoreError;
use polarid_core::dop::dop;
use polarid_core::mosaic::ColourPattern;
use polarid_core::simulate::{
    BandStokesMaps, PerspectiveScene, PlanarPlate, PlateOptics, frame_seed, plate_stokes,
    polarizer_intensity, render_colour_frame_stokes, render_frame_stokes, stokes_dolp,
};
use polarid_io::IoError;
use polarid_io::atomic::StagedDir;
use polarid_io::scene::{Calibrated, CaptureKind, Plate, Scene};
use rayon::prelude::*;

use super::{
    CalibratedTruth, ColourFrames, Simulated, TruthBand, TruthRow, capture_dir, exposure_warning,
    frame_file, manifest_text, plate_bands, write_frame, write_text_files,
};
use crate::error::Result;
use crate::progress::{Progress, Warning};

/// The core scene of a calibrated scene's plates.
pub(crate) fn perspective_scene(
    scene: &Scene,
    cal: &Calibrated,
) -> std::result::Result<PerspectiveScene, CoreError> {
    let plates = scene
        .plates
        .iter()
        .map(|p| planar_plate(p, cal))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    PerspectiveScene::new(cal.camera.to_camera(), plates)
}

fn planar_plate(p: &Plate, cal: &Calibrated) -> std::result::Result<PlanarPlate, CoreError> {
    let pl = p.placement.as_ref().ok_or(CoreError::InvalidVector {
        name: "plate placement (missing in a calibrated scene)",
        value: [f64::NAN; 3],
    })?;
    let plane = cal
        .planes
        .get(pl.plane)
        .ok_or(CoreError::InvalidVector {
            name: "plate plane (unknown)",
            value: [f64::NAN; 3],
        })?
        .to_plane()?;
    PlanarPlate::new(plane, pl.center, pl.axis, pl.size, p.optics)
}

/// Mean, standard deviation, min and max of `xs`.
fn stats(xs: &[f64]) -> (f64, f64, f64, f64) {
    let n = xs.len().max(1) as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n;
    let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (mean, var.sqrt(), lo, hi)
}

/// The truth of plate `p` (index `pi`) in capture `ci`: its region's pixels, traced in
/// f64, one row per band ([`plate_bands`]), each with the band's optics, its S0 times the
/// band's response and `peak_electrons[b]`.
fn region_truth(
    scene: &Scene,
    ps: &PerspectiveScene,
    cal: &Calibrated,
    ci: usize,
    pi: usize,
    exposure: f64,
    peak_electrons: &[f64],
) -> std::result::Result<Vec<TruthRow>, CoreError> {
    let p = &scene.plates[pi];
    let light = cal.sources[ci].light();
    let r = p.region;
    let pixels: Vec<(f64, f64)> = (r.y..r.y + r.height)
        .flat_map(|y| (r.x..r.x + r.width).map(move |x| (x as f64, y as f64)))
        .collect();
    let hits = pixels
        .par_iter()
        .map(|&(u, v)| ps.pixel(u, v, &light))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let hits: Vec<_> = hits.iter().flatten().filter(|h| h.plate == pi).collect();
    let (mut ti, mut tr, mut beta) = (vec![], vec![], vec![]);
    let (mut phs, mut phc) = (0.0, 0.0);
    for h in &hits {
        let g = &h.geometry;
        ti.push(g.theta_i.to_degrees());
        tr.push(g.theta_r.to_degrees());
        beta.push(g.beta.to_degrees());
        phs += g.phi.sin();
        phc += g.phi.cos();
    }
    let npx = beta.len();
    let (b_mean, b_sd, b_lo, b_hi) = stats(&beta);
    let sensor = &scene.sensor;
    let rows = plate_bands(p, scene.capture.bands());
    let mut out = Vec::with_capacity(rows.len());
    for (ri, (o, band, response)) in rows.into_iter().enumerate() {
        let mut sum = [0.0f64; 3];
        let mut eq9 = Vec::with_capacity(npx);
        for h in &hits {
            // The band's Stokes vector: `plate_stokes` with the band's optics.
            let st = if h.irradiance > 0.0 {
                plate_stokes(&o, &h.geometry, h.irradiance)?
            } else {
                [0.0; 3]
            };
            for (s, x) in sum.iter_mut().zip(st) {
                *s += x;
            }
            eq9.push(dop(o.n, o.k, h.geometry.beta));
        }
        out.push(TruthRow {
            target: p.name.clone(),
            class: p.class.clone(),
            theta_i_deg: stats(&ti).0,
            theta_r_deg: stats(&tr).0,
            phi_deg: phs.atan2(phc).to_degrees().rem_euclid(360.0),
            beta_deg: b_mean,
            dolp: stokes_dolp(&sum),
            s0: sum[0] / npx.max(1) as f64 * sensor.dn_per_unit() * response,
            dolp_eq9_specular: dop(o.n, o.k, b_mean.to_radians()),
            exposure,
            peak_electrons: peak_electrons.get(ri).copied().unwrap_or(f64::NAN),
            band: band.map(|b| TruthBand {
                letter: b.letter,
                wavelength_nm: b.wavelength_nm,
                n: o.n,
                k: o.k,
            }),
            calibrated: Some(CalibratedTruth {
                capture: capture_dir(scene, ci),
                n: o.n,
                k: o.k,
                sigma: o.sigma,
                rho_d: o.rho_d,
                beta_sd_deg: b_sd,
                beta_min_deg: b_lo,
                beta_max_deg: b_hi,
                dolp_eq9_mean: stats(&eq9).0,
                pixels: npx,
            }),
        });
    }
    Ok(out)
}

/// One capture of a calibrated scene, traced ([`trace_capture`]).
struct Capture {
    exposure: f64,
    /// Expected electrons per unit radiance of each band.
    epu: Vec<f64>,
    truth: Vec<TruthRow>,
    warnings: Vec<Warning>,
}

/// Scratch maps of a calibrated scene: one Stokes map per band and the plate map.
struct Maps {
    stokes: Vec<Vec<[f32; 3]>>,
    plate: Vec<u16>,
}

/// Trace capture `ci` of a calibrated scene into `maps` (module documentation): every
/// pixel's ray traced once and its radiance in each band of [`plate_bands`]
/// ([`PerspectiveScene::render_bands`]); the exposure from the brightest plate pixel over
/// bands (weighted by their responses) and polarizer angles; band `b`'s expected
/// electrons per unit radiance `exposure · full_well · r_b`; the truth and the warnings
/// per plate and band.
fn trace_capture(
    scene: &Scene,
    cal: &Calibrated,
    ps: &PerspectiveScene,
    ci: usize,
    maps: &mut Maps,
) -> std::result::Result<Capture, CoreError> {
    let sensor = &scene.sensor;
    let (w, h) = (scene.width, scene.height);
    let bands: Vec<_> = scene
        .plates
        .iter()
        .map(|p| plate_bands(p, scene.capture.bands()))
        .collect();
    let optics: Vec<Vec<PlateOptics>> = bands
        .iter()
        .map(|b| b.iter().map(|x| x.0).collect())
        .collect();
    let nb = maps.stokes.len();
    ps.render_bands(
        w,
        h,
        &cal.sources[ci].light(),
        &optics,
        &vec![[scene.background, 0.0, 0.0]; nb],
        BandStokesMaps {
            stokes: maps.stokes.iter_mut().map(|m| m.as_mut_slice()).collect(),
            plate: &mut maps.plate,
        },
    )?;
    let angles = super::angles_rad(&scene.capture);
    // Brightest noise-free polarizer intensity per plate and band.
    let mut peaks = vec![vec![0.0f64; nb]; scene.plates.len()];
    for (b, map) in maps.stokes.iter().enumerate() {
        for (s, &p) in map.iter().zip(&maps.plate) {
            if let Some(pk) = (p as usize).checked_sub(1).and_then(|i| peaks.get_mut(i)) {
                let s = s.map(f64::from);
                for &a in &angles {
                    pk[b] = pk[b].max(polarizer_intensity(&s, a));
                }
            }
        }
    }
    let resp: Vec<f64> = scene
        .capture
        .bands()
        .map_or(vec![1.0], |bs| bs.iter().map(|b| b.response).collect());
    let peak = peaks
        .iter()
        .flat_map(|pk| pk.iter().zip(&resp).map(|(x, r)| x * r))
        .fold(0.0, f64::max);
    let exposure = scene.exposure.resolve(peak)?;
    let epu: Vec<f64> = resp
        .iter()
        .map(|r| sensor.electrons_per_unit(exposure) * r)
        .collect();
    let at = format!("in capture {}", capture_dir(scene, ci));
    let (mut truth, mut warnings) = (Vec::new(), Vec::new());
    for (pi, p) in scene.plates.iter().enumerate() {
        let peak_e: Vec<f64> = peaks[pi].iter().zip(&epu).map(|(x, e)| x * e).collect();
        for ((_, band, _), &pe) in bands[pi].iter().zip(&peak_e) {
            warnings.extend(exposure_warning(&p.name, &at, *band, pe, sensor, true));
        }
        truth.extend(region_truth(scene, ps, cal, ci, pi, exposure, &peak_e)?);
    }
    Ok(Capture {
        exposure,
        epu,
        truth,
        warnings,
    })
}

/// Trace every capture of a calibrated scene in turn ([`trace_capture`]) and hand each,
/// with its Stokes maps, to `frames`; the exposures, truth and warnings of all captures.
fn each_capture(
    scene: &Scene,
    cal: &Calibrated,
    mut frames: impl FnMut(usize, &Maps, &Capture) -> Result<()>,
) -> Result<(Vec<f64>, Vec<TruthRow>, Vec<Warning>)> {
    let label = |e: CoreError| IoError::core(&scene.path, e);
    let ps = perspective_scene(scene, cal).map_err(label)?;
    let (npix, nb) = (
        scene.width * scene.height,
        scene.capture.bands().map_or(1, <[_]>::len),
    );
    let mut maps = Maps {
        stokes: vec![vec![[0f32; 3]; npix]; nb],
        plate: vec![0u16; npix],
    };
    let (mut exposures, mut truth, mut warnings) = (Vec::new(), Vec::new(), Vec::new());
    for ci in 0..cal.sources.len() {
        let c = trace_capture(scene, cal, &ps, ci, &mut maps).map_err(label)?;
        frames(ci, &maps, &c)?;
        exposures.push(c.exposure);
        truth.extend(c.truth);
        warnings.extend(c.warnings);
    }
    Ok((exposures, truth, warnings))
}

/// The raw colour mosaic of capture `ci` from its traced maps (seed
/// `frame_seed(seed, ci, 0)`).
fn colour_frame(
    scene: &Scene,
    pattern: &ColourPattern,
    ci: usize,
    maps: &Maps,
    epu: &[f64],
) -> std::result::Result<Vec<u16>, CoreError> {
    let (w, h) = (scene.width, scene.height);
    let mut frame = vec![0u16; w * h];
    let refs: Vec<&[[f32; 3]]> = maps.stokes.iter().map(Vec::as_slice).collect();
    let seed = frame_seed(scene.seed, ci as u64, 0);
    render_colour_frame_stokes(w, h, &refs, pattern, &scene.sensor, epu, seed, &mut frame)?;
    Ok(frame)
}

/// Simulate the calibrated scene `scene` (geometry `cal`) into `staged` under `prefix`
/// (see the module documentation). Progress stage `"frames"`.
pub(super) fn simulate(
    scene: &Scene,
    cal: &Calibrated,
    staged: &StagedDir,
    prefix: &str,
    progress: Progress<'_>,
) -> Result<Simulated> {
    let label = |e: CoreError| IoError::core(&scene.path, e);
    let sensor = &scene.sensor;
    let (w, h) = (scene.width, scene.height);
    let analyzers = super::analyzers(&scene.capture).unwrap_or_default();
    let per_capture = analyzers.len().max(1);
    let ncap = cal.sources.len();
    let total = (ncap * per_capture) as u64;
    let (exposures, truth, warnings) = each_capture(scene, cal, |ci, maps, c| {
        let write = |fi: usize, buf: &[u16]| {
            let name = format!("{prefix}{}", frame_file(scene, ci, fi));
            write_frame(staged, &name, sensor, w, h, buf)
        };
        match &scene.capture {
            CaptureKind::ColourDofp { pattern, .. } => write(
                0,
                &colour_frame(scene, pattern, ci, maps, &c.epu).map_err(label)?,
            )?,
            _ => analyzers
                .par_iter()
                .enumerate()
                .try_for_each(|(fi, an)| -> Result<()> {
                    let mut buf = vec![0u16; w * h];
                    let seed = frame_seed(scene.seed, ci as u64, fi as u64);
                    render_frame_stokes(
                        w,
                        h,
                        &maps.stokes[0],
                        *an,
                        sensor,
                        c.epu[0],
                        seed,
                        &mut buf,
                    )
                    .map_err(label)?;
                    write(fi, &buf)
                })?,
        }
        progress("frames", ((ci + 1) * per_capture) as u64, total);
        Ok(())
    })?;
    let text = manifest_text(scene, &exposures);
    write_text_files(scene, staged, prefix, &text, &truth)?;
    Ok(Simulated {
        manifest: format!("{prefix}manifest.toml"),
        captures: ncap,
        frames: total as usize,
        truth,
        warnings,
    })
}

/// Render every capture of a calibrated colour scene in memory (the frames that
/// [`super::simulate_into`] writes, bit for bit).
pub(super) fn render_colour_set(
    scene: &Scene,
    cal: &Calibrated,
    pattern: &ColourPattern,
) -> Result<ColourFrames> {
    let mut frames = Vec::new();
    let (exposures, truth, warnings) = each_capture(scene, cal, |ci, maps, c| {
        let frame = colour_frame(scene, pattern, ci, maps, &c.epu);
        frames.push(frame.map_err(|e| IoError::core(&scene.path, e))?);
        Ok(())
    })?;
    Ok(ColourFrames {
        width: scene.width,
        height: scene.height,
        frames,
        exposures,
        truth,
        warnings,
    })
}

/// β (eq. 5, degrees) of every pixel of capture `capture` (0-based) of a calibrated
/// scene, `width × height` row-major; NaN where the pixel sees no plate or an unlit one.
/// For reports: where each plate sits on the DoLP curve.
///
/// Errors: [`crate::PipelineError::Data`] for a far-field scene or a capture out of
/// range; the renderer's errors.
pub fn beta_map(scene: &Scene, capture: usize) -> Result<Vec<f32>> {
    let bad = |reason: String| crate::PipelineError::Data {
        path: scene.path.display().to_string(),
        reason,
    };
    let cal = scene
        .calibrated()
        .ok_or_else(|| bad("a β map needs a calibrated scene".into()))?;
    let src = cal
        .sources
        .get(capture)
        .ok_or_else(|| bad(format!("no capture {} in the scene", capture + 1)))?;
    let label = |e: CoreError| IoError::core(&scene.path, e);
    let ps = perspective_scene(scene, cal).map_err(label)?;
    let light = src.light();
    let (w, h) = (scene.width, scene.height);
    let mut out = vec![f32::NAN; w * h];
    out.par_chunks_mut(w)
        .enumerate()
        .try_for_each(|(row, line)| {
            for (col, b) in line.iter_mut().enumerate() {
                if let Some(hit) = ps.pixel(col as f64, row as f64, &light)?
                    && hit.irradiance > 0.0
                {
                    *b = hit.geometry.beta.to_degrees() as f32;
                }
            }
            Ok(())
        })
        .map_err(label)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_io::manifest;

    const SCENE: &str = r#"width = 96
height = 64
seed = 2
format = "tiff"
[capture]
kind = "dofp"
[camera]
focal_px = 130.0
principal_point_px = [47.5, 31.5]
distortion = [-0.1, 0.0, 0.0, 0.0]
position = [-0.5, 0.0, 0.6]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
[[source]]
position = [0.4, 0.1, 0.5]
[[source]]
direction = [0.5, 0.0, 0.8]
name = "far"
[[plate]]
name = "a"
n = 1.5
k = 0.0
sigma = 0.2
center = [0.0, 0.0, 0.0]
size = 0.2
[[plate]]
name = "b"
n = 0.3
k = 3.0
sigma = 0.2
center = [0.0, 0.25, 0.0]
size = [0.2, 0.15]
"#;

    fn run(dir: &std::path::Path) -> Simulated {
        let scene = polarid_io::scene::parse(&dir.join("s.toml"), SCENE).unwrap();
        let staged = StagedDir::new(&dir.join("out"), false).unwrap();
        let sim = super::super::simulate_into(&scene, &staged, "", &crate::progress::no_progress)
            .unwrap();
        staged.commit().unwrap();
        sim
    }

    #[test]
    fn dofp_calibrated_scene_is_deterministic_and_loads() {
        let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let sim = run(a.path());
        run(b.path());
        assert_eq!((sim.captures, sim.frames, sim.truth.len()), (2, 2, 4));
        for f in ["manifest.toml", "truth.csv", "c01/raw.tif", "far/raw.tif"] {
            let (x, y) = (a.path().join("out").join(f), b.path().join("out").join(f));
            assert_eq!(std::fs::read(x).unwrap(), std::fs::read(y).unwrap(), "{f}");
        }
        let m = manifest::load(&a.path().join("out/manifest.toml")).unwrap();
        assert_eq!(m.planes[0].name, "default");
        assert_eq!(m.captures[1].name.as_deref(), Some("far"));
        assert!(matches!(
            m.captures[0].source,
            manifest::CaptureSource::Dofp { .. }
        ));
        // Regions hold whole 2 × 2 super-pixels.
        for r in &m.regions {
            assert_eq!((r.rect.x % 2, r.rect.y % 2), (0, 0));
            assert_eq!((r.rect.width % 2, r.rect.height % 2), (0, 0));
        }
        // The distant source lights every point at the same incidence: θi over the
        // region equals the source's zenith (the table is horizontal).
        let far = &sim.truth[2];
        let zen = (0.8f64 / 0.5f64.hypot(0.8)).acos().to_degrees();
        assert!((far.theta_i_deg - zen).abs() < 1e-9, "{}", far.theta_i_deg);
        let c = far.calibrated.as_ref().unwrap();
        assert_eq!((c.capture.as_str(), c.n, c.k), ("far", 1.5, 0.0));
        let map = beta_map(
            &polarid_io::scene::parse(&a.path().join("s.toml"), SCENE).unwrap(),
            1,
        )
        .unwrap();
        let on = map.iter().filter(|b| b.is_finite()).count();
        assert!(on > 500 && on < 96 * 64, "{on}");
    }

    /// The calibrated test scene as a colour camera: RGGB, copper from the library, a
    /// second plate with per-band indices.
    fn colour_scene(dir: &std::path::Path) -> Scene {
        let text = SCENE
            .replace("kind = \"dofp\"", "kind = \"dofp\"\ncolor = \"RGGB\"")
            .replace(
                "[capture]",
                "[sensor]\nband_response = { B = 0.5 }\n[capture]",
            )
            .replace("n = 1.5\nk = 0.0\n", "material = \"copper\"\n")
            .replace(
                "n = 0.3\nk = 3.0\n",
                "n = { R = 0.2, G = 0.9, B = 1.2 }\nk = { R = 3.6, G = 2.6, B = 2.4 }\n",
            );
        polarid_io::scene::parse(&dir.join("s.toml"), &text).unwrap()
    }

    /// A calibrated colour scene: one raw mosaic per capture, the same frames in memory
    /// and on disk, a manifest that is calibrated and colour at once, and per plate,
    /// capture and band a truth row whose geometry is shared by the bands and whose DoLP
    /// is the band's (eq. 9 at the pixels' own β, rho_d = 0).
    #[test]
    fn colour_calibrated_scene_renders_every_band_from_one_geometry() {
        let dir = tempfile::tempdir().unwrap();
        let scene = colour_scene(dir.path());
        assert_eq!(scene.capture.bands().map(<[_]>::len), Some(3));
        let staged = StagedDir::new(&dir.path().join("out"), false).unwrap();
        let sim = super::super::simulate_into(&scene, &staged, "", &crate::progress::no_progress)
            .unwrap();
        staged.commit().unwrap();
        assert_eq!(
            (sim.captures, sim.frames, sim.truth.len()),
            (2, 2, 2 * 2 * 3)
        );
        let mem = super::super::render_colour_set(&scene).unwrap();
        assert_eq!(mem.truth, sim.truth);
        for (ci, f) in ["c01/raw.tif", "far/raw.tif"].iter().enumerate() {
            let raw = polarid_io::image::read_frame(&dir.path().join("out").join(f)).unwrap();
            let on_disk: Vec<u16> = raw.data.iter().map(|&v| v as u16).collect();
            assert_eq!(on_disk, mem.frames[ci], "{f}");
        }
        let m = manifest::load(&dir.path().join("out/manifest.toml")).unwrap();
        assert!(m.camera.is_some());
        assert!(m.captures.iter().all(|c| c.illumination.is_some()
            && matches!(c.source, manifest::CaptureSource::ColourDofp { .. })));
        // Rows: capture by capture, plate by plate, band by band (R, G, B).
        let copper = [(0.2514, 3.612), (0.9671, 2.6377), (1.2457, 2.3921)];
        for (i, t) in sim.truth.iter().enumerate() {
            let b = t.band.unwrap();
            let c = t.calibrated.as_ref().unwrap();
            assert_eq!(b.letter, ['R', 'G', 'B'][i % 3]);
            assert_eq!((c.n, c.k), (b.n, b.k));
            let first = &sim.truth[i - i % 3];
            assert_eq!(
                (t.beta_deg, t.theta_i_deg, c.beta_sd_deg, c.pixels),
                (
                    first.beta_deg,
                    first.theta_i_deg,
                    first.calibrated.as_ref().unwrap().beta_sd_deg,
                    first.calibrated.as_ref().unwrap().pixels
                )
            );
            // The region's DoLP is the brightness-weighted mix of its pixels' eq. (9).
            assert!(
                (t.dolp - c.dolp_eq9_mean).abs() < 0.01 * c.dolp_eq9_mean + 1e-4,
                "{t:?}"
            );
            if t.target == "a" {
                let (n, k) = copper[i % 3];
                assert!((b.n - n).abs() < 0.05 && (b.k - k).abs() < 0.05, "{b:?}");
            }
        }
        // Dispersion: copper's DoLP differs between R and B at the same geometry.
        assert!((sim.truth[0].dolp - sim.truth[2].dolp).abs() > 0.01);
        // The blue band's S0 carries its response (0.5) on top of its radiance.
        let text = std::fs::read_to_string(dir.path().join("out/truth.csv")).unwrap();
        assert!(text.lines().nth(1).unwrap().ends_with(
            "band,wavelength_nm,n,k,capture,sigma,rho_d,beta_sd_deg,beta_min_deg,beta_max_deg,dolp_eq9_mean,pixels"
        ));
    }
}
