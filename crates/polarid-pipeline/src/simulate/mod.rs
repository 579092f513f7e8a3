//! Scene → simulated captures (`polarid simulate`, the demo's capture sets), and the
//! frame renderer shared with `polarid.simulate` (Python).
//!
//! For every source zenith of the scene, the radiance Stokes vector of each plate
//! follows from the Priest–Meier pBRDF (paper eq. 3) plus an optional Lambertian
//! depolarized term (`polarid_core::simulate::plate_radiance`); the sensor model adds
//! shot and read noise, quantizes and saturates. The output is the frames, a capture
//! manifest (`docs/FORMATS.md`) that `polarid measure` reads, `truth.csv` (the
//! noise-free DoLP and S0 of every plate per capture) and a copy of the scene.
//!
//! **Files.** Simulation inherently produces files (the manifest names them), and a set
//! of 2048×2448 frames does not fit in memory, so [`simulate_into`] writes each frame as
//! soon as it is rendered into a [`StagedDir`] *given by the caller*, under a prefix:
//! the caller decides where the set goes and commits the staging directory (or drops it,
//! leaving nothing behind). The in-memory renderer [`render_into`] serves callers that
//! want arrays (the Python binding).
//!
//! **Calibrated scenes** (`[camera]`, plates on planes, lamps or the sun) are rendered
//! per pixel by `polarid_core::simulate::perspective` (module `calibrated`): one Stokes
//! map per capture, frames from it, a calibrated manifest (`[camera]`, `[[plane]]`,
//! `[site]`, a `source` per capture, regions on their planes) and a `truth.csv` with
//! each plate's (n, k) and the spread of β over its region ([`CalibratedTruth`]).
//! [`beta_map`] gives a capture's per-pixel β for reports.
//!
//! **Colour scenes** (`[capture] color`; module `colour`): one raw colour polarization
//! mosaic per capture from each plate's per-band optics, a manifest with `bands` and
//! `dofp.color`, and one `truth.csv` row per plate, capture and band (with `band`,
//! `wavelength_nm`, `n`, `k`); [`render_colour_set`] renders the same frames in memory.
//! A calibrated colour scene (`[camera]` and `color`, module `calibrated`) traces every
//! pixel once per capture and renders each band from the same per-pixel geometry
//! (`PerspectiveScene::render_bands`); its manifest is calibrated and colour at once.
//!
//! Units: with relative exposure `x`, a radiance `I` behind the polarizer gives
//! `x · I · full_well` expected electrons; the manifest records `x` as the capture's
//! `exposure`, so `S0 / exposure` in DN (what `measure` writes) equals the radiance times
//! `2^bits − 1 − dark_level` whatever the exposure; `truth.csv`'s `s0` is in these units.

mod calibrated;
mod colour;
mod files;

use polarid_core::CoreError;
use polarid_core::dop::dop;
use polarid_core::geometry;
use polarid_core::simulate::{
    Analyzer, ColourRect, Exposure, PlateOptics, Sensor, UniformRect, frame_seed, peak_intensity,
    plate_radiance, render_frame, stokes_dolp,
};
use polarid_io::IoError;
use polarid_io::atomic::{StagedDir, write_atomic};
use polarid_io::image;
use polarid_io::scene::{CaptureKind, Geometry, Plate, Scene, SceneBand};
use polarid_io::table::fmt_f64;
use rayon::prelude::*;

pub use calibrated::beta_map;
pub use colour::render_colour_set;
pub use files::{manifest_text, write_truth};

use crate::error::Result;
use crate::progress::{Progress, Warning};

/// Noise-free values of one plate in one capture (a row of `truth.csv`).
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    /// Plate (target) name.
    pub target: String,
    /// Plate class, if any.
    pub class: Option<String>,
    /// Source zenith, degrees.
    pub theta_i_deg: f64,
    /// Camera zenith, degrees.
    pub theta_r_deg: f64,
    /// `phi_r − phi_i`, degrees.
    pub phi_deg: f64,
    /// β (eq. 5), degrees.
    pub beta_deg: f64,
    /// Noise-free DoLP of the plate's radiance.
    pub dolp: f64,
    /// Noise-free S0, DN per unit exposure (the units of `measure`'s `s0`).
    pub s0: f64,
    /// Eq. (9) DoLP of the plate's index at β (equals `dolp` when `rho_d = 0`).
    pub dolp_eq9_specular: f64,
    /// The capture's relative exposure.
    pub exposure: f64,
    /// Expected electrons of the plate's brightest polarizer angle.
    pub peak_electrons: f64,
    /// Calibrated scenes: the capture, the plate's optics and the spread of the
    /// region's geometry (`None` for far-field scenes).
    pub calibrated: Option<CalibratedTruth>,
    /// Colour scenes: the band of the row and the plate's index in it (`None` for
    /// single-band scenes); `dolp`, `s0` and `dolp_eq9_specular` are then the band's.
    pub band: Option<TruthBand>,
}

/// The band of a colour scene's truth row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthBand {
    /// Colour letter.
    pub letter: char,
    /// Wavelength, nm.
    pub wavelength_nm: f64,
    /// Real part of the plate's index in the band.
    pub n: f64,
    /// Imaginary part.
    pub k: f64,
}

/// The extra truth of a plate in a capture of a calibrated scene. The angles of
/// [`TruthRow`] are then the means over the region's pixels (φ a circular mean), `dolp`
/// the DoLP of the region's summed noise-free Stokes vector (what `measure` estimates),
/// `s0` the region's mean S0, and `dolp_eq9_specular` eq. (9) at the mean β.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibratedTruth {
    /// The capture's directory name (its source `name`, or `c01`, `c02`, ...).
    pub capture: String,
    /// Real part of the plate's index.
    pub n: f64,
    /// Imaginary part of the plate's index.
    pub k: f64,
    /// The plate's roughness σ.
    pub sigma: f64,
    /// The plate's diffuse albedo.
    pub rho_d: f64,
    /// Standard deviation of β over the region's pixels, degrees.
    pub beta_sd_deg: f64,
    /// Smallest β over the region, degrees.
    pub beta_min_deg: f64,
    /// Largest β over the region, degrees.
    pub beta_max_deg: f64,
    /// Mean over the region's pixels of their own eq. (9) DoLP.
    pub dolp_eq9_mean: f64,
    /// Pixels of the region.
    pub pixels: usize,
}

/// What [`simulate_into`] wrote.
#[derive(Debug, Clone)]
pub struct Simulated {
    /// Staged name of the manifest (`PREFIX/manifest.toml`).
    pub manifest: String,
    /// Number of captures.
    pub captures: usize,
    /// Number of image files.
    pub frames: usize,
    /// The noise-free values, per capture then per plate (also in `truth.csv`).
    pub truth: Vec<TruthRow>,
    /// Dim or saturated plates.
    pub warnings: Vec<Warning>,
}

/// Uniform plates seen by a sensor: what [`render_into`] renders, `C` captures ×
/// `A` analyzers frames of `width × height` pixels.
#[derive(Debug, Clone)]
pub struct RenderSpec {
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Background radiance Stokes vector.
    pub background: [f64; 3],
    /// The plates of every capture (radiance per unit exposure).
    pub rects: Vec<Vec<UniformRect>>,
    /// Expected electrons per unit radiance of every capture.
    pub electrons_per_unit: Vec<f64>,
    /// The analyzers of every capture (polarizer angles, or one DoFP mosaic).
    pub analyzers: Vec<Analyzer>,
    /// The sensor.
    pub sensor: Sensor,
}

impl RenderSpec {
    /// Far-field captures of uniform plates (`polarid simulate`'s far-field scenes and
    /// `polarid.simulate`): capture `c` lit from source zenith `geometry[c][0]` and seen
    /// from camera zenith `geometry[c][1]` at azimuth difference `geometry[c][2]`
    /// (degrees). Each plate (optics, `[x, y, width, height]`) has the radiance per unit irradiance
    /// of `plate_radiance`; a capture's relative exposure is `exposure` resolved on its
    /// brightest noise-free reading through the analyzers (`Exposure::resolve`).
    /// Returns the spec and every capture's relative exposure.
    pub fn far_field(
        [width, height]: [usize; 2],
        background: [f64; 3],
        plates: &[(PlateOptics, [usize; 4])],
        geometry: &[[f64; 3]],
        analyzers: Vec<Analyzer>,
        exposure: Exposure,
        sensor: Sensor,
    ) -> std::result::Result<(Self, Vec<f64>), CoreError> {
        let angles: Vec<f64> = analyzers
            .iter()
            .flat_map(|a| match *a {
                Analyzer::Uniform(x) => vec![x],
                Analyzer::Mosaic(m) => m.to_vec(),
            })
            .collect();
        let (mut rects, mut exposures) = (Vec::new(), Vec::new());
        for g in geometry {
            let [ti, tr, phi] = g.map(f64::to_radians);
            let caps = plates
                .iter()
                .map(|&(o, [x, y, width, height])| {
                    let stokes = plate_radiance(&o, ti, tr, phi)?;
                    Ok(UniformRect {
                        x,
                        y,
                        width,
                        height,
                        stokes,
                    })
                })
                .collect::<std::result::Result<Vec<_>, CoreError>>()?;
            let stokes: Vec<[f64; 3]> = caps.iter().map(|r| r.stokes).collect();
            exposures.push(exposure.resolve(peak_intensity(&stokes, &angles))?);
            rects.push(caps);
        }
        let spec = RenderSpec {
            width,
            height,
            background,
            electrons_per_unit: exposures
                .iter()
                .map(|&x| sensor.electrons_per_unit(x))
                .collect(),
            rects,
            analyzers,
            sensor,
        };
        Ok((spec, exposures))
    }

    /// Render frame `analyzer` of capture `capture` of a simulation seeded `seed` into
    /// `buf` (`width × height`; the frame's noise seed `frame_seed(seed, capture,
    /// analyzer)`).
    fn render(
        &self,
        capture: usize,
        analyzer: usize,
        seed: u64,
        buf: &mut [u16],
    ) -> std::result::Result<(), CoreError> {
        let (Some(rects), Some(&epu), Some(&an)) = (
            self.rects.get(capture),
            self.electrons_per_unit.get(capture),
            self.analyzers.get(analyzer),
        ) else {
            return Err(CoreError::LengthMismatch {
                name: "captures or analyzers of the render",
                expected: self.rects.len(),
                got: capture + 1,
            });
        };
        render_frame(
            self.width,
            self.height,
            rects,
            self.background,
            an,
            &self.sensor,
            epu,
            frame_seed(seed, capture as u64, analyzer as u64),
            buf,
        )
    }
}

/// Render every frame of `spec` into `out` (`C × A × height × width`, capture-major),
/// in parallel, with the frames' noise seeds of `polarid simulate` (`frame_seed(seed,
/// capture, analyzer)`), so the output is the same for a given seed. Progress stage
/// `"frames"`.
pub fn render_into(
    spec: &RenderSpec,
    seed: u64,
    out: &mut [u16],
    progress: Progress<'_>,
) -> std::result::Result<(), CoreError> {
    let npix = spec.width * spec.height;
    let na = spec.analyzers.len();
    let total = (spec.rects.len() * na) as u64;
    if out.len() != total as usize * npix {
        return Err(CoreError::LengthMismatch {
            name: "frames buffer",
            expected: total as usize * npix,
            got: out.len(),
        });
    }
    if npix == 0 || na == 0 {
        return Ok(());
    }
    let done = std::sync::atomic::AtomicU64::new(0);
    out.par_chunks_mut(npix)
        .enumerate()
        .try_for_each(|(fi, buf)| {
            let (ci, ai) = (fi / na, fi % na);
            spec.render(ci, ai, seed, buf)?;
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress("frames", d, total);
            Ok(())
        })
}

/// Directory name of capture `i` (0-based): for a far-field scene, after the source
/// zenith (`i35`, `i37p5`; prefixed by the capture number when two captures share a
/// zenith); for a calibrated scene, the source's `name`, or `c01`, `c02`, ...
pub fn capture_dir(scene: &Scene, i: usize) -> String {
    match &scene.geometry {
        Geometry::FarField { theta_i_deg, .. } => {
            let t = theta_i_deg.get(i).copied().unwrap_or(f64::NAN);
            let base = format!("i{}", fmt_f64(t).replace('.', "p"));
            let dup = theta_i_deg.iter().filter(|&&x| x == t).count() > 1;
            if dup {
                format!("c{:02}_{base}", i + 1)
            } else {
                base
            }
        }
        Geometry::Calibrated(c) => c
            .sources
            .get(i)
            .and_then(|s| s.name.clone())
            .unwrap_or_else(|| format!("c{:02}", i + 1)),
    }
}

/// A polarizer angle in a file name: `000`, `045`, `022p5`.
fn fmt_angle(a: f64) -> String {
    if a.fract() == 0.0 && (0.0..1000.0).contains(&a) {
        format!("{:03}", a as u32)
    } else {
        fmt_f64(a).replace(['.', '-'], "p")
    }
}

/// The file of frame `frame` of capture `capture` (relative to the set's directory):
/// `i35/pol045.png`, or `i35/raw.tif` for a DoFP mosaic.
pub fn frame_file(scene: &Scene, capture: usize, frame: usize) -> String {
    let dir = capture_dir(scene, capture);
    let ext = scene.format.extension();
    match &scene.capture {
        CaptureKind::Frames { angles_deg } => {
            let a = angles_deg.get(frame).copied().unwrap_or(f64::NAN);
            format!("{dir}/pol{}.{ext}", fmt_angle(a))
        }
        CaptureKind::Dofp { .. } | CaptureKind::ColourDofp { .. } => {
            format!("{dir}/raw.{ext}")
        }
    }
}

/// The analyzers of a monochrome capture, radians (`None`: a colour capture).
pub fn analyzers(capture: &CaptureKind) -> Option<Vec<Analyzer>> {
    match capture {
        CaptureKind::Frames { angles_deg } => Some(
            angles_deg
                .iter()
                .map(|a| Analyzer::Uniform(a.to_radians()))
                .collect(),
        ),
        CaptureKind::Dofp { pattern } => Some(vec![Analyzer::Mosaic(
            pattern.angles_deg().map(f64::to_radians),
        )]),
        CaptureKind::ColourDofp { .. } => None,
    }
}

/// Every polarizer angle of `capture`, radians.
fn angles_rad(capture: &CaptureKind) -> Vec<f64> {
    capture
        .angles_deg()
        .iter()
        .map(|a| a.to_radians())
        .collect()
}

/// `(optics, band, response)` of every band of plate `p` in a scene with bands `bands`:
/// one per band, or for a single-band scene the plate's own optics with response 1.
fn plate_bands<'a>(
    p: &'a Plate,
    bands: Option<&'a [SceneBand]>,
) -> Vec<(PlateOptics, Option<&'a SceneBand>, f64)> {
    match bands {
        None => vec![(p.optics, None, 1.0)],
        Some(bs) => p
            .bands
            .iter()
            .zip(bs)
            .map(|(o, b)| (*o, Some(b), b.response))
            .collect(),
    }
}

/// The warning for plate `plate` `at` a capture (`at theta_i = 35 deg`, `in capture c01`)
/// in `band` whose brightest pixel expects `peak_e` electrons: dim below 100, saturated
/// above the full well (`calibrated`: "at its brightest pixel").
fn exposure_warning(
    plate: &str,
    at: &str,
    band: Option<&SceneBand>,
    peak_e: f64,
    sensor: &Sensor,
    calibrated: bool,
) -> Option<Warning> {
    let in_band = band.map_or(String::new(), |b| {
        format!(" in band {} ({} nm)", b.letter, b.wavelength_nm)
    });
    let (why, open, close) = match band {
        None => (
            " (its specular lobe misses the camera, or another plate is much brighter)",
            " (",
            ")",
        ),
        Some(_) => ("", ": ", ""),
    };
    let pixel = if calibrated {
        " at its brightest pixel"
    } else {
        ""
    };
    if peak_e < 100.0 {
        Some(Warning(format!(
            "plate {plate:?} {at} is dim{in_band}: {peak_e:.0} electrons at its \
             brightest{why}; its DoLP will be noisy"
        )))
    } else if peak_e > sensor.full_well_e {
        Some(Warning(format!(
            "plate {plate:?} {at} saturates{in_band}{open}{peak_e:.0} electrons \
             expected{pixel}, full well {}{close}",
            sensor.full_well_e
        )))
    } else {
        None
    }
}

/// The radiance, exposure and truth of every capture of a far-field scene.
#[derive(Default)]
struct Plan {
    /// Per capture, the plates with their radiance in every band ([`plate_bands`]).
    rects: Vec<Vec<ColourRect>>,
    /// Expected electrons per unit radiance, per capture and band.
    epu: Vec<Vec<f64>>,
    /// Relative exposure of every capture.
    exposures: Vec<f64>,
    truth: Vec<TruthRow>,
    warnings: Vec<Warning>,
}

/// Plan the simulation of a far-field scene (no rendering yet): per capture, each band of
/// each plate has the radiance of `plate_radiance` (paper eq. 3) with the band's optics;
/// the exposure is resolved from the brightest plate pixel over every band (weighted by
/// its response `r_b`) and polarizer angle; band `b` gets `x · full_well · r_b` expected
/// electrons per unit radiance, and the truth's `s0` is `r_b ·` the radiance in DN per
/// unit exposure. A single-band scene is one band of response 1.
fn plan(scene: &Scene) -> Result<Plan> {
    let Geometry::FarField {
        theta_r_deg,
        phi_deg,
        theta_i_deg,
    } = &scene.geometry
    else {
        return Err(crate::PipelineError::Data {
            path: scene.path.display().to_string(),
            reason: "internal error: a calibrated scene has no far-field plan".into(),
        });
    };
    let sensor = &scene.sensor;
    let (theta_r_deg, phi_deg) = (*theta_r_deg, *phi_deg);
    let (tr, phi) = (theta_r_deg.to_radians(), phi_deg.to_radians());
    let angles = angles_rad(&scene.capture);
    let label = |e: CoreError| IoError::core(&scene.path, e);
    let bands = scene.capture.bands();
    let resp: Vec<f64> = bands.map_or(vec![1.0], |bs| bs.iter().map(|b| b.response).collect());
    let plates: Vec<_> = scene.plates.iter().map(|p| plate_bands(p, bands)).collect();
    let mut out = Plan::default();
    for &ti_deg in theta_i_deg {
        let ti = ti_deg.to_radians();
        let mut caps = Vec::with_capacity(scene.plates.len());
        for (p, pb) in scene.plates.iter().zip(&plates) {
            let stokes = pb.iter().map(|(o, ..)| plate_radiance(o, ti, tr, phi));
            caps.push(ColourRect {
                x: p.rect.x,
                y: p.rect.y,
                width: p.rect.width,
                height: p.rect.height,
                stokes: stokes
                    .collect::<std::result::Result<_, _>>()
                    .map_err(label)?,
            });
        }
        // The brightest pixel over plates, bands (weighted by their response) and angles.
        let weighted: Vec<[f64; 3]> = caps
            .iter()
            .flat_map(|r| r.stokes.iter().zip(&resp).map(|(s, &w)| s.map(|x| x * w)))
            .collect();
        let exposure = scene
            .exposure
            .resolve(peak_intensity(&weighted, &angles))
            .map_err(label)?;
        let epu: Vec<f64> = resp
            .iter()
            .map(|&w| sensor.electrons_per_unit(exposure) * w)
            .collect();
        let beta = geometry::beta(ti, tr, phi);
        let at = format!("at theta_i = {ti_deg} deg");
        for ((p, pb), r) in scene.plates.iter().zip(&plates).zip(&caps) {
            for ((o, band, response), (s, &e)) in pb.iter().zip(r.stokes.iter().zip(&epu)) {
                let peak_e = e * peak_intensity(&[*s], &angles);
                let w = exposure_warning(&p.name, &at, *band, peak_e, sensor, false);
                out.warnings.extend(w);
                out.truth.push(TruthRow {
                    target: p.name.clone(),
                    class: p.class.clone(),
                    theta_i_deg: ti_deg,
                    theta_r_deg,
                    phi_deg,
                    beta_deg: beta.to_degrees(),
                    dolp: stokes_dolp(s),
                    s0: s[0] * response * sensor.dn_per_unit(),
                    dolp_eq9_specular: dop(o.n, o.k, beta),
                    exposure,
                    peak_electrons: peak_e,
                    calibrated: None,
                    band: band.map(|b| TruthBand {
                        letter: b.letter,
                        wavelength_nm: b.wavelength_nm,
                        n: o.n,
                        k: o.k,
                    }),
                });
            }
        }
        out.rects.push(caps);
        out.epu.push(epu);
        out.exposures.push(exposure);
    }
    Ok(out)
}

impl Plan {
    /// The frames of a single-band scene (`None` for a colour scene): one per analyzer.
    fn spec(&self, scene: &Scene) -> Option<RenderSpec> {
        let rects = self.rects.iter().map(|caps| {
            caps.iter()
                .map(|r| UniformRect {
                    x: r.x,
                    y: r.y,
                    width: r.width,
                    height: r.height,
                    stokes: r.stokes[0],
                })
                .collect()
        });
        Some(RenderSpec {
            width: scene.width,
            height: scene.height,
            background: [scene.background, 0.0, 0.0],
            rects: rects.collect(),
            electrons_per_unit: self.epu.iter().map(|e| e[0]).collect(),
            analyzers: analyzers(&scene.capture)?,
            sensor: scene.sensor,
        })
    }
}

/// Simulate `scene` into `staged` under `prefix` (`""` or a directory name ending in
/// `/`): the frames, `manifest.toml`, `truth.csv` and `scene.toml`. Frames render in
/// parallel and are written as they come (progress stage `"frames"`); the result is
/// the same for a given scene (seeded noise). The caller commits `staged`.
pub fn simulate_into(
    scene: &Scene,
    staged: &StagedDir,
    prefix: &str,
    progress: Progress<'_>,
) -> Result<Simulated> {
    if let Geometry::Calibrated(cal) = &scene.geometry {
        return calibrated::simulate(scene, cal, staged, prefix, progress);
    }
    let plan = plan(scene)?;
    // A frame per analyzer, or one raw colour mosaic per capture.
    let spec = plan.spec(scene);
    let na = spec.as_ref().map_or(1, |s| s.analyzers.len());
    let jobs: Vec<(usize, usize)> = (0..plan.rects.len())
        .flat_map(|c| (0..na).map(move |a| (c, a)))
        .collect();
    let (w, h) = (scene.width, scene.height);
    let done = std::sync::atomic::AtomicU64::new(0);
    jobs.par_iter().try_for_each(|&(ci, fi)| -> Result<()> {
        let mut buf = vec![0u16; w * h];
        match &spec {
            Some(spec) => spec
                .render(ci, fi, scene.seed, &mut buf)
                .map_err(|e| IoError::core(&scene.path, e))?,
            None => plan.render_colour(scene, ci, &mut buf)?,
        }
        let name = format!("{prefix}{}", frame_file(scene, ci, fi));
        write_frame(staged, &name, &scene.sensor, w, h, &buf)?;
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress("frames", d, jobs.len() as u64);
        Ok(())
    })?;
    let text = manifest_text(scene, &plan.exposures);
    write_text_files(scene, staged, prefix, &text, &plan.truth)?;
    Ok(Simulated {
        manifest: format!("{prefix}manifest.toml"),
        captures: scene.captures(),
        frames: jobs.len(),
        truth: plan.truth,
        warnings: plan.warnings,
    })
}

/// Write `manifest.toml` (`text`), `truth.csv` and `scene.toml` under `prefix`.
fn write_text_files(
    scene: &Scene,
    staged: &StagedDir,
    prefix: &str,
    text: &str,
    truth: &[TruthRow],
) -> Result<()> {
    let manifest = format!("{prefix}manifest.toml");
    let mpath = staged.path(&manifest)?;
    write_atomic(&mpath, false, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| IoError::io(&mpath, e))
    })?;
    let tpath = staged.path(&format!("{prefix}truth.csv"))?;
    write_atomic(&tpath, false, |w| write_truth(w, &tpath, truth))?;
    let spath = staged.path(&format!("{prefix}scene.toml"))?;
    write_atomic(&spath, false, |w| {
        w.write_all(scene.text.as_bytes())
            .map_err(|e| IoError::io(&spath, e))
    })?;
    Ok(())
}

/// Write frame `buf` (`w × h`) to the staged file `name`: 8-bit for sensors of at most 8
/// bits, else 16-bit.
fn write_frame(
    staged: &StagedDir,
    name: &str,
    sensor: &Sensor,
    w: usize,
    h: usize,
    buf: &[u16],
) -> Result<()> {
    let path = staged.path(name)?;
    if sensor.bit_depth <= 8 {
        let b: Vec<u8> = buf.iter().map(|&v| v as u8).collect();
        image::write_gray8(&path, false, w, h, &b)?;
    } else {
        image::write_gray16(&path, false, w, h, buf)?;
    }
    Ok(())
}

/// The raw colour frames of a colour scene, in memory ([`render_colour_set`]).
#[derive(Debug, Clone)]
pub struct ColourFrames {
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// One raw mosaic per capture (`width × height`, row-major, DN).
    pub frames: Vec<Vec<u16>>,
    /// Relative exposure of every capture.
    pub exposures: Vec<f64>,
    /// Noise-free values per capture, plate and band (as `truth.csv`).
    pub truth: Vec<TruthRow>,
    /// Dim or saturated plates.
    pub warnings: Vec<Warning>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;
    use std::sync::atomic::{AtomicU64, Ordering};

    const SCENE: &str = r#"
width = 16
height = 8
theta_r_deg = 45.0
theta_i_deg = [40, 45, 50]
seed = 3
[[plate]]
name = "a"
n = 1.5
k = 0.0
sigma = 0.2
rect = [0, 0, 8, 8]
"#;

    #[test]
    fn simulate_into_writes_the_set_and_reports_progress() {
        let dir = tempfile::tempdir().unwrap();
        let scene = polarid_io::scene::parse(&dir.path().join("s.toml"), SCENE).unwrap();
        let out = dir.path().join("out");
        let staged = StagedDir::new(&out, false).unwrap();
        let calls = AtomicU64::new(0);
        let sim = simulate_into(&scene, &staged, "x/", &|s, _, t| {
            assert_eq!((s, t), ("frames", 12));
            calls.fetch_add(1, Ordering::Relaxed);
        })
        .unwrap();
        staged.commit().unwrap();
        assert_eq!((sim.captures, sim.frames, sim.truth.len()), (3, 12, 3));
        assert_eq!(calls.load(Ordering::Relaxed), 12);
        assert_eq!(sim.manifest, "x/manifest.toml");
        for f in ["manifest.toml", "truth.csv", "scene.toml", "i45/pol090.png"] {
            assert!(Path::new(&out.join("x").join(f)).is_file(), "{f}");
        }
        let m = polarid_io::manifest::load(&out.join("x/manifest.toml")).unwrap();
        assert_eq!(m.captures.len(), 3);
    }

    #[test]
    fn render_into_is_seeded_and_checks_sizes() {
        let dir = tempfile::tempdir().unwrap();
        let scene = polarid_io::scene::parse(&dir.path().join("s.toml"), SCENE).unwrap();
        let spec = plan(&scene).unwrap().spec(&scene).unwrap();
        let mut a = vec![0u16; 12 * 16 * 8];
        let mut b = a.clone();
        let seed = 7;
        render_into(&spec, seed, &mut a, &crate::progress::no_progress).unwrap();
        render_into(&spec, seed, &mut b, &crate::progress::no_progress).unwrap();
        assert_eq!(a, b);
        assert!(a.iter().any(|&v| v > 0));
        let mut short = vec![0u16; 5];
        assert!(render_into(&spec, seed, &mut short, &crate::progress::no_progress).is_err());
    }
}
