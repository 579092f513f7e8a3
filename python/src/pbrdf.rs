//! The Priest–Meier polarimetric BRDF, paper eq. (3), with numpy broadcasting.

use ndarray::{ArrayD, ArrayViewD, IxDyn, Zip};
use polarid_core::CoreError;
use polarid_core::error::ensure_finite;
use polarid_core::geometry::ScatterGeometry;
use polarid_core::pbrdf::{Pbrdf, pbrdf_geometry, validate};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::arrays::{F64Like, PAR_MIN_LEN, broadcast_all, check_each, to_python};
use crate::errors::PyResultExt;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(pbrdf, m)?)?;
    Ok(())
}

/// Check a zenith angle in degrees: finite, in `[0, 90)`.
pub fn check_zenith(name: &'static str, v: &ArrayViewD<'_, f64>) -> Result<(), CoreError> {
    check_each(v, |x| {
        ensure_finite(name, x)?;
        if (0.0..90.0).contains(&x) {
            Ok(x)
        } else {
            Err(CoreError::OutOfRange {
                name,
                value: x,
                expected: "0 <= value < 90 degrees",
            })
        }
    })
}

/// The Priest–Meier microfacet pBRDF, paper eq. (3), in sr⁻¹:
///
///     F = M(β) exp(-tan²θ / (2σ²)) / (8π σ² cos⁴θ cos θi cos θr)
///
/// with M(β) the Fresnel reflection Mueller matrix at the local incidence angle β
/// (eq. 5) and θ the facet tilt (eq. 4). No shadowing or masking.
///
/// Parameters
/// ----------
/// n, k : float or array_like
///     Complex index N = n + ik, n > 0, k >= 0.
/// sigma : float or array_like
///     Facet slope standard deviation (per axis), > 0.
/// theta_i, theta_r : float or array_like
///     Source and camera zenith angles, **degrees**, in [0, 90).
/// phi : float or array_like
///     Azimuth difference phi_r - phi_i, degrees (180: the paper's in-plane forward
///     geometry).
///
/// All six broadcast together (numpy rules).
///
/// Returns
/// -------
/// dict
///     ``local``: eq. (3) in the local facet frame (s perpendicular to the plane of the
///     incident and reflected beams), shape ``(*B, 3, 3)`` where B is the broadcast
///     shape (a (3, 3) array for scalar arguments), row-major Mueller matrices on the
///     linear Stokes vector (S0, S1, S2);
///     ``global``: the same in the global s/p frame of each beam (SCATMECH "psps";
///     ``S1 = I_s - I_p``);
///     ``beta``: local incidence angle β, degrees (eq. 5);
///     ``facet_tilt``: θ, degrees (eq. 4);
///     ``dolp``: DoLP for unpolarized light, sqrt(m10² + m20²)/m00 = eq. (9) at β.
///     The last three are floats for scalar arguments, else arrays of shape B.
///
/// Raises
/// ------
/// ValueError
///     n <= 0, k < 0, sigma <= 0, a zenith angle outside [0, 90), a non-finite value
///     (the message names the argument and value, in degrees), shapes that do not
///     broadcast.
#[pyfunction]
pub fn pbrdf<'py>(
    py: Python<'py>,
    n: F64Like<'py>,
    k: F64Like<'py>,
    sigma: F64Like<'py>,
    theta_i: F64Like<'py>,
    theta_r: F64Like<'py>,
    phi: F64Like<'py>,
) -> PyResult<Bound<'py, PyDict>> {
    let views = [
        n.as_array(),
        k.as_array(),
        sigma.as_array(),
        theta_i.as_array(),
        theta_r.as_array(),
        phi.as_array(),
    ];
    let names = ["n", "k", "sigma", "theta_i", "theta_r", "phi"];
    let named: Vec<_> = names.into_iter().zip(&views).collect();
    let (shape, b) = broadcast_all(&named)?;
    let (local, global, beta, tilt, dolp) = py
        .detach(|| -> Result<_, CoreError> {
            check_zenith("theta_i_deg", &views[3])?;
            check_zenith("theta_r_deg", &views[4])?;
            // Remaining checks (n, k, sigma, phi) by the core, in radians (the zeniths
            // are already known to be valid, so its messages name n, k, sigma, phi).
            Zip::from(&b[0]).and(&b[1]).and(&b[2]).and(&b[5]).fold(
                Ok(()),
                |acc: Result<(), CoreError>, &n, &k, &s, &p| {
                    acc?;
                    ensure_finite("phi", p)?;
                    validate(n, k, s, 0.0, 0.0, p.to_radians())
                },
            )?;
            // Flat row-major walk over the broadcast inputs.
            let len: usize = shape.iter().product();
            let mut args: Vec<[f64; 6]> = vec![[0.0; 6]; len];
            for (j, v) in b.iter().enumerate() {
                for (a, &x) in args.iter_mut().zip(v.iter()) {
                    a[j] = x;
                }
            }
            let eval = |a: &[f64; 6]| {
                let g =
                    ScatterGeometry::new(a[3].to_radians(), a[4].to_radians(), a[5].to_radians());
                let mut out = Pbrdf::default();
                pbrdf_geometry(a[0], a[1], a[2], &g, &mut out);
                out
            };
            let res: Vec<Pbrdf> = if len >= PAR_MIN_LEN / 16 {
                args.par_iter().map(eval).collect()
            } else {
                args.iter().map(eval).collect()
            };
            let mut m_shape = shape.clone();
            m_shape.extend([3, 3]);
            let flat = |f: &dyn Fn(&Pbrdf) -> &[[f64; 3]; 3]| -> Vec<f64> {
                res.iter()
                    .flat_map(|r| f(r).iter().flatten().copied())
                    .collect()
            };
            let mk = |sh: &[usize], v: Vec<f64>| {
                ArrayD::from_shape_vec(IxDyn(sh), v).map_err(|_| CoreError::LengthMismatch {
                    name: "pbrdf output",
                    expected: len,
                    got: 0,
                })
            };
            let local = mk(&m_shape, flat(&|r| &r.local))?;
            let global = mk(&m_shape, flat(&|r| &r.global))?;
            let beta = mk(&shape, res.iter().map(|r| r.beta.to_degrees()).collect())?;
            let tilt = mk(
                &shape,
                res.iter().map(|r| r.facet_tilt.to_degrees()).collect(),
            )?;
            let dolp = mk(&shape, res.iter().map(|r| r.dolp).collect())?;
            Ok((local, global, beta, tilt, dolp))
        })
        .py_err()?;
    let d = PyDict::new(py);
    d.set_item("local", crate::arrays::to_numpy(py, local))?;
    d.set_item("global", crate::arrays::to_numpy(py, global))?;
    d.set_item("beta", to_python(py, beta)?)?;
    d.set_item("facet_tilt", to_python(py, tilt)?)?;
    d.set_item("dolp", to_python(py, dolp)?)?;
    Ok(d)
}
