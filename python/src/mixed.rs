//! The depolarization-aware inversion of `polarid_core::mixed`: the
//! Priest–Meier specular term plus a Lambertian depolarized term, fitted to a target's
//! DoLP and exposure-normalised S0 across captures, with selection against the paper's
//! pure-specular model.

use polarid_core::mixed::{MixedCapture, MixedFit, MixedOptions, fit_mixed as core_fit};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{PyResultExt, value_error};
use crate::fit::shadowing_arg;
use crate::set_fields;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_mixed, m)?)?;
    Ok(())
}

fn fit_dict<'py>(py: Python<'py>, f: &MixedFit) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("model", f.model.as_str())?;
    set_fields!(d, f, n, k, sigma, rho_d, scale);
    d.set_item("theta_r_deg", f.theta_r.to_degrees())?;
    set_fields!(d, f, theta_r_estimated, n_se, k_se, sigma_se, rho_d_se);
    d.set_item("theta_r_se_deg", f.theta_r_se.to_degrees())?;
    set_fields!(d, f, nk_corr, chi2, aic, bic, rms_dolp, rms_s0_rel);
    d.set_item("status", f.status.as_str())?;
    d.set_item("reason", f.reason.as_str())?;
    Ok(d)
}

/// Fit the mixed (specular + Lambertian diffuse) model and the pure-specular model to one
/// target, and select between them by BIC — the library form of
/// `polarid fit --reflectance mixed`.
///
/// Parameters
/// ----------
/// theta_i_deg, theta_r_deg : sequences of float
///     Source and camera zenith angles of each capture (degrees, in [0, 90)).
/// dolp : sequence of float
///     Region DoLP of each capture, in [0, 1].
/// s0 : sequence of float
///     Region mean S0 divided by the capture's exposure (consistent relative units), > 0.
/// phi_deg : float
///     Azimuth difference φr − φi (default 180: the plane of incidence).
/// dolp_se : sequence of float, optional
///     Standard errors of `dolp`.
/// estimate_theta_r : bool
///     Also estimate one θr shared by the captures (the source–camera angles are kept).
/// shadowing : {"none", "smith"}
///     Add the Smith–Beckmann shadowing factor to the specular term.
/// s0_rel_sd : float
///     Relative standard deviation assumed for S0 (default 0.02).
///
/// Returns
/// -------
/// dict
///     ``selected`` ("specular" or "mixed"), ``delta_bic``, ``delta_aic`` and the two
///     fits ``specular`` and ``mixed`` (dicts with n, k, sigma, rho_d, theta_r_deg,
///     standard errors, chi2, aic, bic, status and reason).
///
/// Raises
/// ------
/// ValueError
///     Lengths differ, fewer than 3 captures, or values out of range.
#[pyfunction]
#[pyo3(signature = (theta_i_deg, theta_r_deg, dolp, s0, *, phi_deg=180.0, dolp_se=None, estimate_theta_r=false, shadowing="none", s0_rel_sd=0.02))]
#[allow(clippy::too_many_arguments)]
fn fit_mixed<'py>(
    py: Python<'py>,
    theta_i_deg: Vec<f64>,
    theta_r_deg: Vec<f64>,
    dolp: Vec<f64>,
    s0: Vec<f64>,
    phi_deg: f64,
    dolp_se: Option<Vec<f64>>,
    estimate_theta_r: bool,
    shadowing: &str,
    s0_rel_sd: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let t = theta_i_deg.len();
    if theta_r_deg.len() != t || dolp.len() != t || s0.len() != t {
        return Err(value_error(format!(
            "theta_i_deg, theta_r_deg, dolp and s0 must have the same length (got {t}, {}, {}, {})",
            theta_r_deg.len(),
            dolp.len(),
            s0.len()
        )));
    }
    if let Some(se) = &dolp_se
        && se.len() != t
    {
        return Err(value_error(format!(
            "dolp_se has length {}, expected {t}",
            se.len()
        )));
    }
    let shadowing = shadowing_arg(shadowing)?;
    let caps: Vec<MixedCapture> = (0..t)
        .map(|i| {
            MixedCapture::new(
                theta_i_deg[i].to_radians(),
                theta_r_deg[i].to_radians(),
                phi_deg.to_radians(),
                dolp[i],
                dolp_se.as_ref().map(|se| se[i]),
                s0[i],
            )
        })
        .collect();
    let opts = MixedOptions {
        estimate_theta_r,
        shadowing,
        s0_rel_sd,
        ..MixedOptions::default()
    };
    let report = py.detach(|| core_fit(&caps, &opts)).py_err()?;
    let d = PyDict::new(py);
    d.set_item("selected", report.selected.as_str())?;
    d.set_item("delta_bic", report.delta_bic)?;
    d.set_item("delta_aic", report.delta_aic)?;
    d.set_item("specular", fit_dict(py, &report.specular)?)?;
    d.set_item("mixed", fit_dict(py, &report.mixed)?)?;
    Ok(d)
}
