//! The forward model: degree of linear polarization of specular reflection, paper
//! eq. (9), and its gradient, on numpy arrays with broadcasting.

use ndarray::{ArrayD, ArrayViewD};
use polarid_core::CoreError;
use polarid_core::dop::{BetaTerms, dop_grad_terms, dop_terms};
use polarid_core::error::{ensure_finite, ensure_range};
use pyo3::prelude::*;

use crate::arrays::{F64Like, broadcast_all, check_each, map3, to_python};
use crate::errors::PyResultExt;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dolp_model, m)?)?;
    m.add_function(wrap_pyfunction!(dolp_model_grad, m)?)?;
    Ok(())
}

/// Validate the model's inputs: `n` finite and `> 0`, `k` finite and `>= 0`, `beta_deg`
/// in `[0, 90]`. The messages are `CoreError`'s (`k = -0.1 is out of range (expected
/// k >= 0)`, `n must be finite, got NaN`).
fn check_inputs(
    n: &ArrayViewD<'_, f64>,
    k: &ArrayViewD<'_, f64>,
    beta_deg: &ArrayViewD<'_, f64>,
) -> Result<(), CoreError> {
    check_each(n, |x| {
        ensure_finite("n", x)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(CoreError::OutOfRange {
                name: "n",
                value: x,
                expected: "n > 0",
            })
        }
    })?;
    check_each(k, |x| ensure_range("k", x, 0.0, f64::INFINITY, "k >= 0"))?;
    check_each(beta_deg, |x| {
        ensure_range("beta_deg", x, 0.0, 90.0, "0 <= beta_deg <= 90")
    })
}

/// Degree of linear polarization of specular reflection, paper eq. (9).
///
/// P = (Rs - Rp) / (Rs + Rp) for unpolarized light reflected by a medium of complex
/// index N = n + ik at the local incidence angle beta (degrees):
///
///     P = 2 A sin²β cos β / (A² cos²β + sin⁴β + B² cos²β)
///
/// with A, B the real and imaginary parts of sqrt(N² - sin²β) (eqs. 12-15).
///
/// Parameters
/// ----------
/// n, k, beta_deg : float or array_like
///     Real part n > 0, extinction coefficient k >= 0, and the local incidence angle in
///     degrees, 0 <= beta_deg <= 90. The three are broadcast together (numpy rules) and
///     converted to float64.
///
/// Returns
/// -------
/// float or numpy.ndarray
///     P in [0, 1], of the broadcast shape; a float when every argument is a scalar.
///     P = 1 at Brewster's angle (k = 0, beta = atan n), P = 0 at beta = 0 and 90 and
///     under total reflection (n < 1, k = 0, sin beta > n).
///
/// Raises
/// ------
/// ValueError
///     A value is NaN or infinite, n <= 0, k < 0 or beta_deg outside [0, 90] (the
///     message names the argument and the value), or the shapes do not broadcast.
///
/// Notes
/// -----
/// The GIL is released during the computation; large arrays use all cores.
#[pyfunction]
pub fn dolp_model<'py>(
    n: F64Like<'py>,
    k: F64Like<'py>,
    beta_deg: F64Like<'py>,
) -> PyResult<Bound<'py, PyAny>> {
    let [p] = eval(&n, &k, &beta_deg, |n, k, b| [dop_terms(n, k, b)])?;
    to_python(n.py(), p)
}

/// `f(n, k, β)` of every element of the broadcast inputs (checked by [`check_inputs`]),
/// the GIL released.
fn eval<const M: usize>(
    n: &F64Like<'_>,
    k: &F64Like<'_>,
    beta_deg: &F64Like<'_>,
    f: fn(f64, f64, &BetaTerms) -> [f64; M],
) -> PyResult<[ArrayD<f64>; M]> {
    let (nv, kv, bv) = (n.as_array(), k.as_array(), beta_deg.as_array());
    let (shape, b) = broadcast_all(&[("n", &nv), ("k", &kv), ("beta_deg", &bv)])?;
    n.py()
        .detach(|| -> Result<_, CoreError> {
            check_inputs(&nv, &kv, &bv)?;
            Ok(map3(&shape, [&b[0], &b[1], &b[2]], |n, k, b| {
                f(n, k, &BetaTerms::new(b.to_radians()))
            }))
        })
        .py_err()
}

/// Eq. (9) and its analytic gradient: returns (P, dP/dn, dP/dk).
///
/// Same arguments, broadcasting, validation and errors as `dolp_model`. The
/// derivatives are the exact partial derivatives of eq. (9) with respect to n and k
/// (per unit of n and k), evaluated without cancellation near index matching, at
/// Brewster's angle and for large k. At the critical angle of a transparent medium
/// (k = 0, n = sin beta exactly) dP/dn is unbounded and 0 is returned.
///
/// Returns
/// -------
/// tuple of three floats or three numpy.ndarray
///     P, dP/dn, dP/dk, each of the broadcast shape.
#[pyfunction]
pub fn dolp_model_grad<'py>(
    n: F64Like<'py>,
    k: F64Like<'py>,
    beta_deg: F64Like<'py>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let [p, dn, dk] = eval(&n, &k, &beta_deg, |n, k, b| {
        let g = dop_grad_terms(n, k, b);
        [g.p, g.dp_dn, g.dp_dk]
    })?;
    let py = n.py();
    Ok((to_python(py, p)?, to_python(py, dn)?, to_python(py, dk)?))
}
