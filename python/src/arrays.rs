//! numpy helpers shared by the bindings: array-like arguments, broadcasting, output.
//!
//! Pattern of an element-wise binding (see `model.rs`):
//!
//! 1. take every numeric argument as [`F64Like`] (a float, a sequence, or an array of
//!    any real dtype, converted to float64 by numpy only when needed);
//! 2. compute the common shape with [`broadcast_shape`] and get zero-copy broadcast views
//!    with [`broadcast_to`] while still attached to the interpreter;
//! 3. inside `py.detach(|| ...)` (the GIL released): validate the inputs, allocate the
//!    outputs as owned `ndarray` arrays and fill them with an `ndarray::Zip`, in parallel
//!    (`par_for_each`) when the output has at least [`PAR_MIN_LEN`] elements;
//! 4. convert the `CoreError` with `errors::PyResultExt::py_err` and hand the outputs to
//!    numpy without a copy with [`to_python`] (a Python `float` when the result is 0-d).

use ndarray::{ArrayD, ArrayViewD, IxDyn};
use numpy::{AllowTypeChange, IntoPyArray, PyArrayLikeDyn};
use polarid_core::CoreError;
use pyo3::prelude::*;

use crate::errors::value_error;

/// A float64 array-like argument: numpy array of any real dtype, nested sequence or scalar.
pub type F64Like<'py> = PyArrayLikeDyn<'py, f64, AllowTypeChange>;

/// Outputs with at least this many elements are computed in parallel with rayon.
pub const PAR_MIN_LEN: usize = 1 << 14;

/// numpy's broadcasting rule for the named argument shapes: align the shapes on the
/// right; along each axis the sizes must be equal or 1.
pub fn broadcast_shape(args: &[(&str, &[usize])]) -> PyResult<Vec<usize>> {
    let ndim = args.iter().map(|(_, s)| s.len()).max().unwrap_or(0);
    let mut out = vec![1usize; ndim];
    for (_, shape) in args {
        for (o, &d) in out.iter_mut().rev().zip(shape.iter().rev()) {
            if *o == 1 {
                *o = d;
            } else if d != 1 && d != *o {
                return Err(value_error(format!(
                    "shapes {} cannot be broadcast together",
                    describe(args)
                )));
            }
        }
    }
    Ok(out)
}

/// A zero-copy view of `view` broadcast to `shape` (which came from [`broadcast_shape`]).
pub fn broadcast_to<'a>(
    name: &str,
    view: &'a ArrayViewD<'a, f64>,
    shape: &[usize],
) -> PyResult<ArrayViewD<'a, f64>> {
    view.broadcast(IxDyn(shape)).ok_or_else(|| {
        value_error(format!(
            "{name} of shape {} cannot be broadcast to shape {}",
            fmt_shape(view.shape()),
            fmt_shape(shape)
        ))
    })
}

/// Apply a check (e.g. `polarid_core::error::ensure_range`) to every element; the first
/// failure is returned.
pub fn check_each(
    view: &ArrayViewD<'_, f64>,
    check: impl Fn(f64) -> Result<f64, CoreError>,
) -> Result<(), CoreError> {
    view.iter().try_for_each(|&x| check(x).map(|_| ()))
}

/// Hand an owned result to Python: a `float` when it is 0-d (all inputs were scalars),
/// else a numpy array that takes over the buffer without copying.
pub fn to_python<'py>(py: Python<'py>, a: ArrayD<f64>) -> PyResult<Bound<'py, PyAny>> {
    if a.ndim() == 0 {
        let x = a.first().copied().unwrap_or(f64::NAN);
        Ok(x.into_pyobject(py)?.into_any())
    } else {
        Ok(a.into_pyarray(py).into_any())
    }
}

/// `(2, 3)`-style text of a shape, as numpy prints it.
pub fn fmt_shape(shape: &[usize]) -> String {
    match shape {
        [d] => format!("({d},)"),
        _ => {
            let parts: Vec<String> = shape.iter().map(usize::to_string).collect();
            format!("({})", parts.join(", "))
        }
    }
}

fn describe(args: &[(&str, &[usize])]) -> String {
    let parts: Vec<String> = args
        .iter()
        .map(|(name, s)| format!("{name} {}", fmt_shape(s)))
        .collect();
    parts.join(", ")
}
