//! A minimal in-memory simulator: plates of known `(n, k, σ)` lit from several source
//! zeniths and seen by a noisy polarization camera (`polarid_core::simulate`), rendered
//! by the renderer of `polarid simulate` (`polarid_pipeline::simulate::render_into`).

use ndarray::{ArrayD, IxDyn};
use polarid_core::CoreError;
use polarid_core::simulate::{Analyzer, PlateOptics, Sensor, UniformRect, plate_radiance};
use polarid_pipeline::progress::no_progress;
use polarid_pipeline::simulate::{RenderSpec, render_into};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{f64_contiguous, to_numpy};
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

/// Broadcast a per-capture angle argument (scalar or length C) to length C.
fn per_capture(name: &'static str, obj: &Bound<'_, PyAny>, c: usize) -> PyResult<Vec<f64>> {
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
///     Automatic exposure: per capture, the brightest plate's brightest polarizer
///     reading is ``fill`` × full well.
/// electrons_per_unit : float, optional
///     Fixed exposure instead (electrons per unit of radiance, all captures).
/// seed : int
///     Random seed; the output is deterministic for a given seed.
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
    let tr = match theta_r_deg {
        Some(o) => per_capture("theta_r_deg", o, c)?,
        None => vec![45.0; c],
    };
    let ph = match phi_deg {
        Some(o) => per_capture("phi_deg", o, c)?,
        None => vec![180.0; c],
    };
    let sensor = Sensor {
        bit_depth,
        full_well_e,
        read_noise_e,
        dark_level_dn,
        shot_noise,
    };
    if !(fill > 0.0 && fill.is_finite()) {
        return Err(CoreError::OutOfRange {
            name: "fill",
            value: fill,
            expected: "> 0",
        })
        .py_err();
    }
    let analyzers: Vec<Analyzer> = if dofp {
        let p = polarid_core::mosaic::Pattern::new(&pattern).py_err()?;
        let a = p.angles_deg().map(f64::to_radians);
        if !tile.is_multiple_of(2) || !gap.is_multiple_of(2) {
            return Err(value_error(format!(
                "a DoFP mosaic needs an even tile and gap, got tile = {tile}, gap = {gap}"
            )));
        }
        vec![Analyzer::Mosaic(a)]
    } else {
        for &a in &angles_deg {
            polarid_core::error::ensure_finite("polarizer angle", a).py_err()?;
        }
        angles_deg
            .iter()
            .map(|a| Analyzer::Uniform(a.to_radians()))
            .collect()
    };
    if tile == 0 {
        return Err(value_error("tile must be at least 1 pixel"));
    }
    let np_ = optics.len();
    let (w, h) = (gap + np_ * (tile + gap), tile + 2 * gap);
    let rects_xy: Vec<(usize, usize)> = (0..np_).map(|p| (gap + p * (tile + gap), gap)).collect();
    let na = analyzers.len();

    let out = py
        .detach(|| -> Result<_, CoreError> {
            {
                let tiv = ndarray::ArrayView1::from(&ti[..]).into_dyn();
                let trv = ndarray::ArrayView1::from(&tr[..]).into_dyn();
                check_zenith("theta_i_deg", &tiv)?;
                check_zenith("theta_r_deg", &trv)?;
            }
            sensor.validate()?;
            let mut radiance = vec![0f64; c * np_ * 3];
            let mut dolp = vec![0f64; c * np_];
            let mut beta = vec![0f64; c];
            let mut epus = vec![0f64; c];
            let mut all_rects = Vec::with_capacity(c);
            for ci in 0..c {
                polarid_core::error::ensure_finite("phi_deg", ph[ci])?;
                let (a, b, p) = (
                    ti[ci].to_radians(),
                    tr[ci].to_radians(),
                    ph[ci].to_radians(),
                );
                beta[ci] = polarid_core::geometry::beta(a, b, p).to_degrees();
                let mut rects = Vec::with_capacity(np_);
                let mut peak = 0f64;
                for (pi, o) in optics.iter().enumerate() {
                    let s = plate_radiance(o, a, b, p)?;
                    radiance[(ci * np_ + pi) * 3..(ci * np_ + pi) * 3 + 3].copy_from_slice(&s);
                    let l = s[1].hypot(s[2]);
                    dolp[ci * np_ + pi] = if s[0] > 0.0 { l / s[0] } else { f64::NAN };
                    peak = peak.max(0.5 * (s[0] + l));
                    let (x, y) = rects_xy[pi];
                    rects.push(UniformRect {
                        x,
                        y,
                        width: tile,
                        height: tile,
                        stokes: s,
                    });
                }
                let epu = match electrons_per_unit {
                    Some(e) => e,
                    None if peak > 0.0 => fill * full_well_e / peak,
                    None => 0.0,
                };
                epus[ci] = epu;
                all_rects.push(rects);
            }
            // The frames: the pipeline's renderer (parallel, one seed per frame).
            let spec = RenderSpec {
                width: w,
                height: h,
                background: [0.0; 3],
                rects: all_rects,
                electrons_per_unit: epus.clone(),
                analyzers,
                sensor,
            };
            let mut frames = vec![0u16; c * na * w * h];
            let frame_seed = |ci: usize, ai: usize| {
                seed ^ ((ci * na + ai) as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03)
            };
            render_into(&spec, &frame_seed, &mut frames, &no_progress)?;
            Ok((radiance, dolp, beta, epus, frames))
        })
        .py_err()?;
    let (radiance, dolp, beta, epus, frames) = out;
    let arr = |shape: &[usize], v: Vec<f64>| -> PyResult<Bound<'py, PyAny>> {
        Ok(to_numpy(
            py,
            ArrayD::from_shape_vec(IxDyn(shape), v).map_err(|e| value_error(e.to_string()))?,
        ))
    };
    let d = PyDict::new(py);
    if dofp {
        let a = ArrayD::from_shape_vec(IxDyn(&[c, h, w]), frames)
            .map_err(|e| value_error(e.to_string()))?;
        d.set_item("raw", to_numpy(py, a))?;
        d.set_item("pattern", pattern)?;
    } else {
        let a = ArrayD::from_shape_vec(IxDyn(&[c, na, h, w]), frames)
            .map_err(|e| value_error(e.to_string()))?;
        d.set_item("frames", to_numpy(py, a))?;
        d.set_item("angles_deg", angles_deg)?;
    }
    let rects = PyList::empty(py);
    for &(x, y) in &rects_xy {
        rects.append((x, y, tile, tile))?;
    }
    d.set_item("rects", rects)?;
    d.set_item("radiance", arr(&[c, np_, 3], radiance)?)?;
    d.set_item("dolp", arr(&[c, np_], dolp)?)?;
    d.set_item("theta_i_deg", arr(&[c], ti)?)?;
    d.set_item("theta_r_deg", arr(&[c], tr)?)?;
    d.set_item("phi_deg", arr(&[c], ph)?)?;
    d.set_item("beta_deg", arr(&[c], beta)?)?;
    d.set_item("electrons_per_unit", arr(&[c], epus)?)?;
    Ok(d)
}
