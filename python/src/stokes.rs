//! Stokes images from polarizer frames and DoFP mosaics, and the DoLP / AoLP images
//! (`polarid_core::stokes`, `polarid_core::mosaic`), on numpy arrays.

use ndarray::{ArrayD, Axis, IxDyn, Zip};
use numpy::PyUntypedArrayMethods;
use polarid_core::CoreError;
use polarid_core::mosaic::{self, Pattern};
use polarid_core::stokes::{self as core_stokes, PixelRules, Sample, StokesSolver};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{FloatArray, PAR_MIN_LEN, float_array, fmt_shape, raw_array, to_numpy};
use crate::errors::{PyResultExt, value_error};
use crate::with_raw;
use polarid_pipeline::map::rules::check_levels;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(stokes, m)?)?;
    m.add_function(wrap_pyfunction!(demosaic, m)?)?;
    m.add_function(wrap_pyfunction!(dolp, m)?)?;
    m.add_function(wrap_pyfunction!(aolp, m)?)?;
    m.add_function(wrap_pyfunction!(dolp_aolp, m)?)?;
    Ok(())
}

/// Pixel rules as the CLI builds them (`polarid stokes --dark-level --saturation`),
/// with the CLI's checks (`polarid_pipeline::map::rules::check_levels`).
pub fn pixel_rules(
    dark_level: f64,
    saturation: Option<f64>,
    type_max: f32,
    min_s0: f64,
) -> PyResult<PixelRules> {
    check_levels(dark_level, saturation).py_err()?;
    if !min_s0.is_finite() {
        return Err(CoreError::NonFinite {
            name: "min_s0",
            value: min_s0,
        })
        .py_err();
    }
    Ok(PixelRules {
        dark_level: dark_level as f32,
        saturation: saturation.map_or(type_max, |s| s as f32),
        min_s0: min_s0 as f32,
    })
}

/// Stokes planes `(3, npix)` plus mask, as owned buffers.
struct Planes {
    s: Vec<f32>,
    mask: Vec<u8>,
}

impl Planes {
    fn new(npix: usize) -> Self {
        Self {
            s: vec![0.0; 3 * npix],
            mask: vec![0; npix],
        }
    }

    fn split(&mut self) -> (&mut [f32], &mut [f32], &mut [f32], &mut [u8]) {
        let npix = self.mask.len();
        let (s0, rest) = self.s.split_at_mut(npix);
        let (s1, s2) = rest.split_at_mut(npix);
        (s0, s1, s2, &mut self.mask)
    }

    /// `(3, *shape)` Stokes array, and the `shape` mask if asked for.
    fn into_python<'py>(
        self,
        py: Python<'py>,
        shape: &[usize],
        return_mask: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mut full = vec![3];
        full.extend_from_slice(shape);
        let s =
            ArrayD::from_shape_vec(IxDyn(&full), self.s).map_err(|e| value_error(e.to_string()))?;
        let s = to_numpy(py, s);
        if return_mask {
            let m = ArrayD::from_shape_vec(IxDyn(shape), self.mask)
                .map_err(|e| value_error(e.to_string()))?;
            Ok(PyTuple::new(py, [s, to_numpy(py, m)])?.into_any())
        } else {
            Ok(s)
        }
    }
}

/// Stokes images (S0, S1, S2) from frames taken through a linear polarizer.
///
/// Least-squares solution of ``I(a) = (S0 + S1 cos 2a + S2 sin 2a) / 2`` over the N
/// frames (for 0/45/90/135: ``S0 = (ΣI)/2``, ``S1 = I(0) - I(90)``,
/// ``S2 = I(45) - I(135)``), exactly as ``polarid stokes --frames ... --angles ...``
/// computes it (same kernel, same float32 numbers).
///
/// Parameters
/// ----------
/// frames : array_like, shape (N, H, W)
///     N >= 3 frames, one per angle. uint8, uint16 and float32 are used as they are
///     (no copy when C-contiguous); other real dtypes are converted to float32. Any
///     shape (N, ...) works: the last axis is the image row.
/// angles_deg : sequence of float, length N
///     Polarizer angle of each frame, degrees, counter-clockwise from the image +x axis
///     (CONVENTIONS). At least 3 distinct angles modulo 180.
/// dark_level : float, default 0
///     DN subtracted from every raw value.
/// saturation : float, optional
///     Raw values at or above it are flagged saturated (default: 255 for uint8, 65535
///     for uint16, none for floats).
/// min_s0 : float, default 0
///     Pixels whose dark-subtracted S0 is at or below it are flagged dark.
/// return_mask : bool, default False
///     Also return the pixel mask.
///
/// Returns
/// -------
/// numpy.ndarray of float32, shape (3, H, W)
///     ``S[0] = S0``, ``S[1] = S1``, ``S[2] = S2``. Rejected pixels still hold their
///     values (see the mask).
/// (numpy.ndarray, numpy.ndarray of uint8, shape (H, W))
///     With ``return_mask=True``: the Stokes array and the mask, 0 valid, 1 saturated,
///     2 dark, 3 invalid (a non-finite value).
///
/// Raises
/// ------
/// ValueError
///     Fewer than 3 angles, singular angles (``polarizer angles [0.0, 90.0, 180.0]
///     (degrees) are singular: ...``), one angle per frame not given, bad rules.
///
/// Notes
/// -----
/// polanalyser's ``calcStokes(frames, angles_rad)`` gives the same S0, S1, S2 (to
/// float32 rounding); it returns them on the last axis, (H, W, 3), here they are on
/// the first. The GIL is released; rows are processed in parallel.
#[pyfunction]
#[pyo3(signature = (frames, angles_deg, *, dark_level = 0.0, saturation = None, min_s0 = 0.0, return_mask = false))]
#[allow(clippy::too_many_arguments)]
pub fn stokes<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyAny>,
    angles_deg: Vec<f64>,
    dark_level: f64,
    saturation: Option<f64>,
    min_s0: f64,
    return_mask: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let raw = raw_array("frames", frames)?;
    let shape = raw.shape();
    if shape.len() < 2 {
        return Err(value_error(format!(
            "frames must have shape (N, H, W) (one image per angle), got shape {}",
            fmt_shape(&shape)
        )));
    }
    let n = shape[0];
    if angles_deg.len() != n {
        return Err(value_error(format!(
            "angles_deg gives {} angle(s) for {n} frame(s); give one angle per frame",
            angles_deg.len()
        )));
    }
    let solver = StokesSolver::from_degrees(&angles_deg).py_err()?;
    let rules = pixel_rules(dark_level, saturation, raw.type_max(), min_s0)?;
    let img_shape = shape[1..].to_vec();
    let width = *img_shape.last().unwrap_or(&0);
    let npix: usize = img_shape.iter().product();
    let mut planes = Planes::new(npix);
    with_raw!(&raw, |data| {
        py.detach(|| -> Result<(), CoreError> {
            let views: Vec<_> = if npix == 0 {
                vec![&data[..0]; n]
            } else {
                data.chunks_exact(npix).collect()
            };
            let (s0, s1, s2, m) = planes.split();
            solver.compute(&views, width, &rules, s0, s1, s2, m)?;
            Ok(())
        })
        .py_err()?
    });
    planes.into_python(py, &img_shape, return_mask)
}

/// Demosaic a raw division-of-focal-plane (DoFP) frame: Stokes images or per-angle images.
///
/// Parameters
/// ----------
/// raw : array_like, shape (H, W)
///     The raw mosaic (uint8, uint16 or float32; other real dtypes become float32);
///     H and W even (at least 4 for ``bilinear``).
/// pattern : sequence of 4 float, default (90, 45, 135, 0)
///     The 2x2 super-pixel's polarizer angles, degrees, row by row from the top-left
///     (Sony IMX250MZR / IMX253MZR: ``90, 45, 135, 0``).
/// method : {"bilinear", "superpixel"}
///     ``bilinear``: full resolution, each channel interpolated bilinearly (OpenCV's /
///     polanalyser's interpolation). ``superpixel``: half resolution, one value per 2x2
///     cell.
/// output : {"stokes", "angles"}
///     What to return (below).
/// dark_level, saturation, min_s0, return_mask
///     As in `stokes` (``output="stokes"`` only for the mask). For ``output="angles"``
///     the dark level is subtracted from the images.
/// round : bool, optional
///     Round interpolated values to whole DN (halves up) as OpenCV does for integer
///     input. Default: True for integer input with ``bilinear`` (the output is then
///     identical to polanalyser's demosaicing, as ``polarid stokes --dofp`` does), else
///     False. ``polarid measure`` does not round.
///
/// Returns
/// -------
/// numpy.ndarray of float32
///     ``output="stokes"``: (3, H, W) for ``bilinear``, (3, H/2, W/2) for
///     ``superpixel`` (S0, S1, S2 on the first axis); with ``return_mask=True`` a tuple
///     (stokes, mask) as in `stokes`. ``output="angles"``: (4, H, W) or (4, H/2, W/2),
///     the images behind the 0, 45, 90 and 135 degree polarizers in that order (the
///     order of polanalyser's ``demosaicing(raw, COLOR_PolarMono)``, whose output is
///     (H, W, 4)).
///
/// Raises
/// ------
/// ValueError
///     An invalid pattern (``invalid 2x2 polarizer pattern [...]: ...``), odd or too
///     small dimensions, an unknown method or output.
#[pyfunction]
#[pyo3(signature = (raw, pattern = vec![90.0, 45.0, 135.0, 0.0], method = "bilinear", output = "stokes", *, dark_level = 0.0, saturation = None, min_s0 = 0.0, round = None, return_mask = false))]
#[allow(clippy::too_many_arguments)]
pub fn demosaic<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    pattern: Vec<f64>,
    method: &str,
    output: &str,
    dark_level: f64,
    saturation: Option<f64>,
    min_s0: f64,
    round: Option<bool>,
    return_mask: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let bilinear = match method {
        "bilinear" => true,
        "superpixel" => false,
        _ => {
            return Err(value_error(format!(
                "method must be \"bilinear\" or \"superpixel\", got {method:?}"
            )));
        }
    };
    let angles = match output {
        "stokes" => false,
        "angles" => true,
        _ => {
            return Err(value_error(format!(
                "output must be \"stokes\" or \"angles\", got {output:?}"
            )));
        }
    };
    if angles && return_mask {
        return Err(value_error(
            "return_mask=True needs output=\"stokes\" (per-angle images have no mask)",
        ));
    }
    let pattern = Pattern::new(&pattern).py_err()?;
    let raw = raw_array("raw", raw)?;
    let shape = raw.shape();
    let [h, w] = shape[..] else {
        return Err(value_error(format!(
            "raw must be a 2-D mosaic (H, W), got shape {}",
            fmt_shape(&shape)
        )));
    };
    let rules = pixel_rules(dark_level, saturation, raw.type_max(), min_s0)?;
    let round = round.unwrap_or(raw.is_integer() && bilinear) && bilinear;
    let out_shape = if bilinear {
        vec![h, w]
    } else {
        vec![h / 2, w / 2]
    };
    let npix = out_shape[0] * out_shape[1];
    if angles {
        let mut buf = vec![0f32; 4 * npix];
        with_raw!(&raw, |data| {
            py.detach(|| -> Result<(), CoreError> {
                let (a, rest) = buf.split_at_mut(npix);
                let (b, rest) = rest.split_at_mut(npix);
                let (c, d) = rest.split_at_mut(npix);
                if bilinear {
                    mosaic::demosaic_bilinear(data, w, &pattern, round, [a, b, c, d])?;
                } else {
                    superpixel_angles(data, w, h, &pattern, [a, b, c, d])?;
                }
                if dark_level != 0.0 {
                    let dark = dark_level as f32;
                    buf.iter_mut().for_each(|v| *v -= dark);
                }
                Ok(())
            })
            .py_err()?
        });
        let mut full = vec![4];
        full.extend_from_slice(&out_shape);
        let a =
            ArrayD::from_shape_vec(IxDyn(&full), buf).map_err(|e| value_error(e.to_string()))?;
        return Ok(to_numpy(py, a));
    }
    let mut planes = Planes::new(npix);
    with_raw!(&raw, |data| {
        py.detach(|| -> Result<(), CoreError> {
            let (s0, s1, s2, m) = planes.split();
            if bilinear {
                mosaic::bilinear_stokes(data, w, &pattern, &rules, round, s0, s1, s2, m)?;
            } else {
                mosaic::superpixel_stokes(data, w, &pattern, &rules, s0, s1, s2, m)?;
            }
            Ok(())
        })
        .py_err()?
    });
    planes.into_python(py, &out_shape, return_mask)
}

/// Half-resolution per-angle images: channel `k` (k × 45°) is the raw pixel at the
/// polarizer's position in each 2×2 cell.
fn superpixel_angles<T: Sample>(
    raw: &[T],
    w: usize,
    h: usize,
    pattern: &Pattern,
    out: [&mut [f32]; 4],
) -> Result<(), CoreError> {
    if w == 0 || h == 0 || !w.is_multiple_of(2) || !h.is_multiple_of(2) || raw.len() != w * h {
        return Err(CoreError::InvalidDimensions {
            width: w,
            height: h,
            reason: "a 2x2 polarizer mosaic needs an even width and height".into(),
        });
    }
    let (w2, h2) = (w / 2, h / 2);
    for (k, o) in out.into_iter().enumerate() {
        let (pr, pc) = pattern.position(k);
        for y in 0..h2 {
            let row = &raw[(2 * y + pr) * w..(2 * y + pr + 1) * w];
            for (x, v) in o[y * w2..(y + 1) * w2].iter_mut().enumerate() {
                *v = row[2 * x + pc].to_f32();
            }
        }
    }
    Ok(())
}

/// DoLP and AoLP (degrees) of Stokes images with S0, S1, S2 on the first axis.
fn polar<'py>(
    py: Python<'py>,
    s: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let arr = float_array("s", s)?;
    macro_rules! shape_of {
        ($a:expr) => {{
            let shape = $a.shape().to_vec();
            if shape.first() != Some(&3) {
                return Err(value_error(format!(
                    "s must hold S0, S1, S2 on its first axis, shape (3, ...), got shape {}",
                    fmt_shape(&shape)
                )));
            }
            shape[1..].to_vec()
        }};
    }
    match arr {
        FloatArray::F32(a) => {
            let shape = shape_of!(a);
            let data = a.as_slice()?;
            let npix: usize = shape.iter().product();
            let width = shape.last().copied().unwrap_or(1).max(1);
            let mut d = vec![0f32; npix];
            let mut g = vec![0f32; npix];
            if npix > 0 {
                py.detach(|| {
                    let (s0, rest) = data.split_at(npix);
                    let (s1, s2) = rest.split_at(npix);
                    core_stokes::dolp_aolp(width, s0, s1, s2, None, &mut d, &mut g)
                })
                .py_err()?;
            }
            let d =
                ArrayD::from_shape_vec(IxDyn(&shape), d).map_err(|e| value_error(e.to_string()))?;
            let g =
                ArrayD::from_shape_vec(IxDyn(&shape), g).map_err(|e| value_error(e.to_string()))?;
            Ok((to_numpy(py, d), to_numpy(py, g)))
        }
        FloatArray::F64(a) => {
            let shape = shape_of!(a);
            let v = a.as_array();
            let (d, g) = py.detach(|| {
                let mut d = ArrayD::<f64>::zeros(IxDyn(&shape));
                let mut g = ArrayD::<f64>::zeros(IxDyn(&shape));
                let (s0, s1, s2) = (
                    v.index_axis(Axis(0), 0),
                    v.index_axis(Axis(0), 1),
                    v.index_axis(Axis(0), 2),
                );
                let len = d.len();
                let z = Zip::from(&mut d).and(&mut g).and(&s0).and(&s1).and(&s2);
                let f = |d: &mut f64, g: &mut f64, &s0: &f64, &s1: &f64, &s2: &f64| {
                    (*d, *g) = dolp_aolp_f64(s0, s1, s2);
                };
                if len >= PAR_MIN_LEN {
                    z.par_for_each(f);
                } else {
                    z.for_each(f);
                }
                (d, g)
            });
            Ok((to_numpy(py, d), to_numpy(py, g)))
        }
    }
}

/// The float64 DoLP / AoLP of one pixel, with the conventions of
/// `polarid_core::stokes::dolp_aolp_pixel` (DoLP clamped to [0, 1], AoLP in [0, 180),
/// NaN where S0 <= 0 or a component is not finite).
#[inline]
pub fn dolp_aolp_f64(s0: f64, s1: f64, s2: f64) -> (f64, f64) {
    if !(s0 > 0.0 && s0.is_finite() && s1.is_finite() && s2.is_finite()) {
        return (f64::NAN, f64::NAN);
    }
    let d = (s1.hypot(s2) / s0).clamp(0.0, 1.0);
    let mut a = 0.5 * s2.atan2(s1).to_degrees();
    if a < 0.0 {
        a += 180.0;
    }
    if a >= 180.0 {
        a -= 180.0;
    }
    (d, a)
}

/// Degree of linear polarization, ``sqrt(S1² + S2²) / S0``, clamped to [0, 1].
///
/// Parameters
/// ----------
/// s : array_like, shape (3, ...)
///     S0, S1, S2 on the first axis (the output of `stokes` / `demosaic`).
///
/// Returns
/// -------
/// numpy.ndarray, shape s.shape[1:]
///     float32 for float32 input (the CLI's kernel: ``polarid stokes`` writes these very
///     numbers to ``dolp.tif``), float64 for any other dtype. NaN where S0 <= 0 or a
///     component is not finite.
///
/// Notes
/// -----
/// polanalyser's ``cvtStokesToDoLP`` does not clamp: noisy pixels can exceed 1 there.
#[pyfunction]
pub fn dolp<'py>(py: Python<'py>, s: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    Ok(polar(py, s)?.0)
}

/// Angle of linear polarization in **degrees**, ``atan2(S2, S1) / 2`` in [0, 180).
///
/// Same input, dtype rule and NaN rule as `dolp`. Angles are counter-clockwise from the
/// image +x axis, as the polarizer angles (CONVENTIONS).
///
/// Notes
/// -----
/// polanalyser's ``cvtStokesToAoLP`` returns radians in [0, pi): it equals
/// ``numpy.radians(polarid.aolp(s))`` (mod pi: values within rounding of 180 degrees
/// may come out near 0 in one and near pi in the other).
#[pyfunction]
pub fn aolp<'py>(py: Python<'py>, s: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    Ok(polar(py, s)?.1)
}

/// ``(dolp(s), aolp(s))`` in one pass.
#[pyfunction]
pub fn dolp_aolp<'py>(py: Python<'py>, s: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyTuple>> {
    let (d, a) = polar(py, s)?;
    PyTuple::new(py, [d, a])
}
