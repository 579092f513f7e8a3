//! numpy helpers shared by the bindings: array-like arguments, broadcasting, output.
//!
//! Pattern of an element-wise binding (see `model.rs`):
//!
//! 1. take every numeric argument as [`F64Like`] (a float, a sequence, or an array of
//!    any real dtype, converted to float64 by numpy only when needed);
//! 2. compute the common shape with [`broadcast_shape`] and get zero-copy broadcast views
//!    with [`broadcast_to`] while still attached to the interpreter;
//! 3. inside `py.detach(|| ...)` (the GIL released): validate the inputs, then compute
//!    the outputs as owned `ndarray` arrays with [`map3`] (an `ndarray::Zip`, in parallel
//!    (`par_for_each`) when the output has at least [`PAR_MIN_LEN`] elements);
//! 4. convert the `CoreError` with `errors::PyResultExt::py_err` and hand the outputs to
//!    numpy without a copy with [`to_python`] (a Python `float` when the result is 0-d).

use std::collections::HashMap;

use ndarray::{ArrayD, ArrayViewD, IxDyn, Zip};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArrayLikeDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
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

/// The named views broadcast together: their common shape ([`broadcast_shape`]) and
/// the zero-copy views ([`broadcast_to`]), in the order of `args`.
pub fn broadcast_all<'a>(
    args: &[(&str, &'a ArrayViewD<'a, f64>)],
) -> PyResult<(Vec<usize>, Vec<ArrayViewD<'a, f64>>)> {
    let shapes: Vec<(&str, &[usize])> = args.iter().map(|(n, v)| (*n, v.shape())).collect();
    let shape = broadcast_shape(&shapes)?;
    let views = args.iter().map(|(n, v)| broadcast_to(n, v, &shape));
    let views = views.collect::<PyResult<_>>()?;
    Ok((shape, views))
}

/// `f(a, b, c)` of every element of three views of `shape`: its `M` results as `M` new
/// arrays, computed in parallel when they have at least [`PAR_MIN_LEN`] elements.
pub fn map3<const M: usize>(
    shape: &[usize],
    [a, b, c]: [&ArrayViewD<'_, f64>; 3],
    f: impl Fn(f64, f64, f64) -> [f64; M] + Sync + Send,
) -> [ArrayD<f64>; M] {
    let mut out = ArrayD::from_elem(IxDyn(shape), [0.0; M]);
    let len = out.len();
    let z = Zip::from(&mut out).and(a).and(b).and(c);
    let g = |o: &mut [f64; M], &a: &f64, &b: &f64, &c: &f64| *o = f(a, b, c);
    if len >= PAR_MIN_LEN {
        z.par_for_each(g);
    } else {
        z.for_each(g);
    }
    std::array::from_fn(|j| out.map(|o| o[j]))
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

/// A raw image stack as the Stokes kernels take it: C-contiguous `u8`, `u16` or `f32`
/// (any other real dtype is converted to `float32` by numpy).
pub enum RawArray<'py> {
    /// 8-bit frames.
    U8(PyReadonlyArrayDyn<'py, u8>),
    /// 16-bit frames.
    U16(PyReadonlyArrayDyn<'py, u16>),
    /// Float frames.
    F32(PyReadonlyArrayDyn<'py, f32>),
}

impl RawArray<'_> {
    /// Shape of the array.
    pub fn shape(&self) -> Vec<usize> {
        match self {
            RawArray::U8(a) => a.shape().to_vec(),
            RawArray::U16(a) => a.shape().to_vec(),
            RawArray::F32(a) => a.shape().to_vec(),
        }
    }

    /// True for the integer dtypes.
    pub fn is_integer(&self) -> bool {
        !matches!(self, RawArray::F32(_))
    }

    /// The saturation default of the CLI: the dtype's largest value (255, 65535), or
    /// `+inf` for floats.
    pub fn type_max(&self) -> f32 {
        match self {
            RawArray::U8(_) => 255.0,
            RawArray::U16(_) => 65535.0,
            RawArray::F32(_) => f32::INFINITY,
        }
    }
}

/// Call `$body` with `$s` bound to the contiguous slice of a [`RawArray`], whatever its
/// sample type.
#[macro_export]
macro_rules! with_raw {
    ($raw:expr, |$s:ident| $body:expr) => {
        match $raw {
            $crate::arrays::RawArray::U8(a) => {
                let $s: &[u8] = a.as_slice()?;
                $body
            }
            $crate::arrays::RawArray::U16(a) => {
                let $s: &[u16] = a.as_slice()?;
                $body
            }
            $crate::arrays::RawArray::F32(a) => {
                let $s: &[f32] = a.as_slice()?;
                $body
            }
        }
    };
}

fn numpy(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    py.import("numpy")
}

/// The numpy dtype kind character of an array-like (`'u'`, `'f'`, ...), after
/// `numpy.asarray`.
fn check_real<'py>(name: &str, a: &Bound<'py, PyAny>) -> PyResult<()> {
    let dtype = a.getattr("dtype")?;
    let kind: String = dtype.getattr("kind")?.extract()?;
    if matches!(kind.as_str(), "b" | "i" | "u" | "f") {
        Ok(())
    } else {
        Err(value_error(format!(
            "{name} must hold real numbers, got an array of dtype {}",
            dtype.str()?
        )))
    }
}

/// `obj` as a C-contiguous [`RawArray`] (no copy when it already is one).
pub fn raw_array<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<RawArray<'py>> {
    let np = numpy(obj.py())?;
    let a = np.call_method1("ascontiguousarray", (obj,))?;
    if let Ok(x) = a.extract::<PyReadonlyArrayDyn<'py, u8>>() {
        return Ok(RawArray::U8(x));
    }
    if let Ok(x) = a.extract::<PyReadonlyArrayDyn<'py, u16>>() {
        return Ok(RawArray::U16(x));
    }
    if let Ok(x) = a.extract::<PyReadonlyArrayDyn<'py, f32>>() {
        return Ok(RawArray::F32(x));
    }
    check_real(name, &a)?;
    let a = np.call_method1("ascontiguousarray", (a, "float32"))?;
    Ok(RawArray::F32(a.extract()?))
}

/// `obj` as a C-contiguous float64 array (numpy converts other real dtypes).
pub fn f64_contiguous<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let np = numpy(obj.py())?;
    let a = np.call_method1("asarray", (obj,))?;
    check_real(name, &a)?;
    let a = np.call_method1("ascontiguousarray", (a, "float64"))?;
    a.extract()
}

/// Stokes input of `dolp`/`aolp`: float32 arrays stay float32 (the CLI's kernel), every
/// other real dtype becomes float64.
pub enum FloatArray<'py> {
    /// float32 input.
    F32(PyReadonlyArrayDyn<'py, f32>),
    /// Any other real dtype, as float64.
    F64(PyReadonlyArrayDyn<'py, f64>),
}

/// `obj` as a C-contiguous [`FloatArray`].
pub fn float_array<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<FloatArray<'py>> {
    let np = numpy(obj.py())?;
    let a = np.call_method1("ascontiguousarray", (obj,))?;
    if let Ok(x) = a.extract::<PyReadonlyArrayDyn<'py, f32>>() {
        return Ok(FloatArray::F32(x));
    }
    Ok(FloatArray::F64(f64_contiguous(name, &a)?))
}

/// Hand an owned array of any element type to numpy without a copy.
pub fn to_numpy<'py, T: numpy::Element>(py: Python<'py>, a: ArrayD<T>) -> Bound<'py, PyAny> {
    a.into_pyarray(py).into_any()
}

/// `v` as a numpy array of `shape` (row-major, no copy).
pub fn shaped<'py, T: numpy::Element>(
    py: Python<'py>,
    shape: &[usize],
    v: Vec<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let a = ArrayD::from_shape_vec(IxDyn(shape), v).map_err(|e| value_error(e.to_string()))?;
    Ok(to_numpy(py, a))
}

/// A numpy array of strings `names[codes[i]]` (dtype `<U…`), built by numpy's `take`.
pub fn str_array<'py>(
    py: Python<'py>,
    names: &[&str],
    codes: ArrayD<u32>,
) -> PyResult<Bound<'py, PyAny>> {
    let np = numpy(py)?;
    let table = np.call_method1("array", (names.to_vec(),))?;
    if names.is_empty() {
        return np.call_method1("full", (codes.shape().to_vec(), ""));
    }
    table.call_method1("take", (codes.into_pyarray(py),))
}

/// Distinct strings and their codes (`""` is code 0).
#[derive(Debug)]
pub struct NameTable {
    names: Vec<String>,
    index: HashMap<String, u32>,
}

impl Default for NameTable {
    fn default() -> Self {
        Self {
            names: vec![String::new()],
            index: HashMap::from([(String::new(), 0)]),
        }
    }
}

impl NameTable {
    /// The code of `s`, added when new.
    pub fn code(&mut self, s: &str) -> u32 {
        if let Some(&i) = self.index.get(s) {
            return i;
        }
        self.names.push(s.to_string());
        let i = (self.names.len() - 1) as u32;
        self.index.insert(s.to_string(), i);
        i
    }

    /// The names, code order.
    pub fn refs(&self) -> Vec<&str> {
        self.names.iter().map(String::as_str).collect()
    }
}
