//! A minimal in-memory simulator: plates of known `(n, k, σ)` lit from several source
//! zeniths and seen by a noisy polarization camera, planned and rendered as `polarid
//! simulate` plans and renders a far-field scene (`polarid_pipeline::simulate`:
//! `RenderSpec::far_field`, `render_into`; the same exposure and frame seeds).

use ndarray::ArrayView1;
use polarid_core::CoreError;
use polarid_core::simulate::{Analyzer, Exposure, PlateOptics, Sensor, stokes_dolp};
use polarid_io::scene::CaptureKind;
use polarid_pipeline::progress::no_progress;
use polarid_pipeline::simulate::{RenderSpec, analyzers as capture_analyzers, render_into};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{f64_contiguous, shaped};
use crate::errors::{PyResultExt, value_error};
use crate::pbrdf::check_zenith;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    Ok(())
}

fn plate_of(i: usize, item: &Bound<'_, PyAny>) -> PyResult<PlateOptics> {
    if let Ok(d) = item.cast::<PyDict>() {
        let get = |key: &str, default: Option<f64>| -> PyResult<f64> {
            match d.get_item(key)? {
                Some(v) => v.extract(),
                None => default
                    .ok_or_else(|| value_error(format!("plate {}: missing key {key:?}", i + 1))),
            }
        };
        return Ok(PlateOptics {
            n: get("n", None)?,
            k: get("k", None)?,
            sigma: get("sigma", None)?,
            rho_d: get("rho_d", Some(0.0))?,
        });
    }
    if let Ok((n, k, sigma)) = item.extract::<(f64, f64, f64)>() {
        return Ok(PlateOptics {
            n,
            k,
            sigma,
            rho_d: 0.0,
        });
    }
    if let Ok((n, k, sigma, rho_d)) = item.extract::<(f64, f64, f64, f64)>() {
        return Ok(PlateOptics { n, k, sigma, rho_d });
    }
    Err(value_error(format!(
        "plate {} must be (n, k, sigma), (n, k, sigma, rho_d) or a dict with those keys",
        i + 1
    )))
}

/// Broadcast a per-capture angle argument (scalar or length C; None: `default`) to
/// length C.
fn per_capture(
    name: &'static str,
    obj: Option<&Bound<'_, PyAny>>,
    default: f64,
    c: usize,
) -> PyResult<Vec<f64>> {
    let Some(obj) = obj else {
        return Ok(vec![default; c]);
    };
    let a = f64_contiguous(name, obj)?;
    let v: Vec<f64> = a.as_array().iter().copied().collect();
    match v.len() {
        1 => Ok(vec![v[0]; c]),
        l if l == c => Ok(v),
        l => Err(value_error(format!(
            "{name} has {l} values; give one value or one per capture ({c})"
        ))),
    }
}

/// Simulate captures of flat plates: frames through a rotating polarizer or DoFP mosaics.
///
/// Each plate is a uniform square of the frame (a row of ``tile`` × ``tile`` squares
/// separated by ``gap`` pixels of black background). For every capture (source zenith
/// ``theta_i_deg[c]``) the radiance Stokes vector of each plate is
/// ``cos θi · (f00 + ρd/π, f10, f20)`` with f the Priest–Meier pBRDF (paper eq. 3), in
/// the camera's image frame; the sensor adds Poisson shot noise and Gaussian read noise,
/// quantizes and clips (``polarid_core::simulate``).
///
/// Parameters
/// ----------
/// plates : sequence
///     ``(n, k, sigma)``, ``(n, k, sigma, rho_d)`` or dicts with those keys (rho_d: albedo
///     of a depolarized Lambertian component, default 0).
/// theta_i_deg : float or array_like, shape (C,)
///     Source zenith of each capture, degrees in [0, 90).
/// theta_r_deg, phi_deg : float or array_like (C,)
///     Camera zenith (degrees, [0, 90)) and azimuth difference phi_r - phi_i (180: the
///     paper's in-plane geometry), one value or one per capture.
/// angles_deg : sequence of float, default (0, 45, 90, 135)
///     Polarizer angles of the frames (rotating polarizer).
/// dofp : bool, default False
///     Render one raw DoFP mosaic per capture instead (``pattern``, row by row).
/// pattern : sequence of 4 float, default (90, 45, 135, 0)
/// tile, gap : int
///     Plate size and spacing in pixels (even for DoFP).
/// bit_depth, full_well_e, read_noise_e, dark_level_dn, shot_noise
///     The sensor (defaults: 12 bits, 10 000 e⁻, 3 e⁻ rms, no offset, shot noise on).
/// fill : float, default 0.8
///     Automatic exposure (a scene's ``[exposure]`` ``fraction``, in (0, 1]): per
///     capture, the brightest plate's brightest reading through the analyzer is
///     ``fill`` × full well.
/// electrons_per_unit : float, optional
///     Fixed exposure instead (electrons per unit of radiance, all captures).
/// seed : int
///     Random seed (a scene's ``seed``): a scene of the same plates, angles, sensor and
///     exposure gives the same frames in ``polarid simulate``.
///
/// Returns
/// -------
/// dict
///     ``frames``: uint16 (C, A, H, W) (rotating polarizer) or ``raw``: uint16 (C, H, W)
///     (DoFP); ``angles_deg`` (list, A); ``rects``: list of (x, y, width, height), one
///     per plate; ``radiance``: float64 (C, P, 3) expected Stokes vector of each plate
///     per unit irradiance; ``dolp``: float64 (C, P), its DoLP (= eq. 9 at beta without
///     diffuse light); ``theta_i_deg``, ``theta_r_deg``, ``phi_deg``, ``beta_deg``
///     (eq. 5), ``electrons_per_unit``: float64 (C,).
///
/// Raises
/// ------
/// ValueError
///     Invalid optics, angles, sensor settings or layout (the core's message).
#[pyfunction]
#[pyo3(signature = (plates, theta_i_deg, theta_r_deg = None, phi_deg = None, *, angles_deg = vec![0.0, 45.0, 90.0, 135.0], dofp = false, pattern = vec![90.0, 45.0, 135.0, 0.0], tile = 16, gap = 4, bit_depth = 12, full_well_e = 10000.0, read_noise_e = 3.0, dark_level_dn = 0.0, shot_noise = true, fill = 0.8, electrons_per_unit = None, seed = 0))]
#[allow(clippy::too_many_arguments)]
pub fn simulate<'py>(
    py: Python<'py>,
    plates: &Bound<'py, PyAny>,
    theta_i_deg: &Bound<'py, PyAny>,
    theta_r_deg: Option<&Bound<'py, PyAny>>,
    phi_deg: Option<&Bound<'py, PyAny>>,
    angles_deg: Vec<f64>,
    dofp: bool,
    pattern: Vec<f64>,
    tile: usize,
    gap: usize,
    bit_depth: u32,
    full_well_e: f64,
    read_noise_e: f64,
    dark_level_dn: f64,
    shot_noise: bool,
    fill: f64,
    electrons_per_unit: Option<f64>,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let optics: Vec<PlateOptics> = plates
        .try_iter()?
        .enumerate()
        .map(|(i, p)| plate_of(i, &p?))
        .collect::<PyResult<_>>()?;
    if optics.is_empty() {
        return Err(value_error(
            "plates is empty: give at least one (n, k, sigma)",
        ));
    }
    let ti = f64_contiguous("theta_i_deg", theta_i_deg)?;
    let ti: Vec<f64> = ti.as_array().iter().copied().collect();
    let c = ti.len();
    if c == 0 {
        return Err(value_error(
            "theta_i_deg is empty: give at least one capture",
        ));
    }
    let tr = per_capture("theta_r_deg", theta_r_deg, 45.0, c)?;
    let ph = per_capture("phi_deg", phi_deg, 180.0, c)?;
    let analyzers = analyzers(dofp, &pattern, &angles_deg, tile, gap)?;
    let (plates, [w, h]) = layout(&optics, tile, gap)?;
    let geometry: Vec<[f64; 3]> = (0..c).map(|i| [ti[i], tr[i], ph[i]]).collect();
    let sensor = Sensor {
        bit_depth,
        full_well_e,
        read_noise_e,
        dark_level_dn,
        shot_noise,
    };
    let exposure = match electrons_per_unit {
        Some(e) => Exposure::Fixed(e / full_well_e),
        None => Exposure::Auto { fraction: fill },
    };
    let na = analyzers.len();
    let (spec, frames) = py
        .detach(|| -> Result<_, CoreError> {
            check_zenith("theta_i_deg", &ArrayView1::from(&ti[..]).into_dyn())?;
            check_zenith("theta_r_deg", &ArrayView1::from(&tr[..]).into_dyn())?;
            for &p in &ph {
                polarid_core::error::ensure_finite("phi_deg", p)?;
            }
            sensor.validate()?;
            let (spec, _) = RenderSpec::far_field(
                [w, h],
                [0.0; 3],
                &plates,
                &geometry,
                analyzers,
                exposure,
                sensor,
            )?;
            let mut frames = vec![0u16; c * na * w * h];
            render_into(&spec, seed, &mut frames, &no_progress)?;
            Ok((spec, frames))
        })
        .py_err()?;
    let np_ = plates.len();
    let stokes = spec.rects.iter().flatten().map(|r| r.stokes);
    let d = PyDict::new(py);
    if dofp {
        d.set_item("raw", shaped(py, &[c, h, w], frames)?)?;
        d.set_item("pattern", pattern)?;
    } else {
        d.set_item("frames", shaped(py, &[c, na, h, w], frames)?)?;
        d.set_item("angles_deg", angles_deg)?;
    }
    let rects = plates.iter().map(|(_, [x, y, w, h])| (*x, *y, *w, *h));
    d.set_item("rects", rects.collect::<Vec<_>>())?;
    let radiance = stokes.clone().flatten().collect();
    d.set_item("radiance", shaped(py, &[c, np_, 3], radiance)?)?;
    let dolp = stokes.map(|s| stokes_dolp(&s)).collect();
    d.set_item("dolp", shaped(py, &[c, np_], dolp)?)?;
    let beta = geometry.iter().map(|g| {
        let [a, b, p] = g.map(f64::to_radians);
        polarid_core::geometry::beta(a, b, p).to_degrees()
    });
    d.set_item("beta_deg", shaped(py, &[c], beta.collect())?)?;
    d.set_item("theta_i_deg", shaped(py, &[c], ti)?)?;
    d.set_item("theta_r_deg", shaped(py, &[c], tr)?)?;
    d.set_item("phi_deg", shaped(py, &[c], ph)?)?;
    d.set_item(
        "electrons_per_unit",
        shaped(py, &[c], spec.electrons_per_unit)?,
    )?;
    Ok(d)
}

/// The plates in a row of `tile × tile` squares, `gap` pixels apart and from the edges
/// (optics, `[x, y, width, height]`), and the frame's `[width, height]`.
type Layout = (Vec<(PlateOptics, [usize; 4])>, [usize; 2]);

fn layout(optics: &[PlateOptics], tile: usize, gap: usize) -> PyResult<Layout> {
    if tile == 0 {
        return Err(value_error("tile must be at least 1 pixel"));
    }
    let plates = optics
        .iter()
        .enumerate()
        .map(|(p, &o)| (o, [gap + p * (tile + gap), gap, tile, tile]));
    let size = [gap + optics.len() * (tile + gap), tile + 2 * gap];
    Ok((plates.collect(), size))
}

/// The analyzers of a capture: one DoFP mosaic (`pattern`; even `tile` and `gap`) or a
/// rotating polarizer at `angles_deg`.
fn analyzers(
    dofp: bool,
    pattern: &[f64],
    angles_deg: &[f64],
    tile: usize,
    gap: usize,
) -> PyResult<Vec<Analyzer>> {
    let capture = if dofp {
        if !tile.is_multiple_of(2) || !gap.is_multiple_of(2) {
            return Err(value_error(format!(
                "a DoFP mosaic needs an even tile and gap, got tile = {tile}, gap = {gap}"
            )));
        }
        let pattern = polarid_core::mosaic::Pattern::new(pattern).py_err()?;
        CaptureKind::Dofp { pattern }
    } else {
        for &a in angles_deg {
            polarid_core::error::ensure_finite("polarizer angle", a).py_err()?;
        }
        let angles_deg = angles_deg.to_vec();
        CaptureKind::Frames { angles_deg }
    };
    Ok(capture_analyzers(&capture).unwrap_or_default())
}
