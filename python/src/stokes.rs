//! Stokes images from polarizer frames and DoFP mosaics, and the DoLP / AoLP images
//! (`polarid_core::stokes`, `polarid_core::mosaic`), on numpy arrays.

use ndarray::{Axis, IxDyn};
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use polarid_core::CoreError;
use polarid_core::mosaic::{self, DofpMethod, DofpOutputs, IntSample, Pattern};
use polarid_core::stokes::{self as core_stokes, PixelRules, Sample, StokesSolver};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use rayon::prelude::*;

use crate::arrays::{FloatArray, RawArray, float_array, fmt_shape, map3, raw_array, to_numpy};
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
    m.add_function(wrap_pyfunction!(dofp_dolp_aolp, m)?)?;
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
    let mut full = vec![3];
    full.extend_from_slice(&img_shape);
    let st = new_array::<f32>(py, &full);
    let mask = new_array::<u8>(py, &img_shape);
    {
        let (mut sw, mut mw) = (st.try_readwrite()?, mask.try_readwrite()?);
        let (ss, mm) = (sw.as_slice_mut()?, mw.as_slice_mut()?);
        with_raw!(&raw, |data| {
            py.detach(|| -> Result<(), CoreError> {
                let views: Vec<_> = if npix == 0 {
                    vec![&data[..0]; n]
                } else {
                    data.chunks_exact(npix).collect()
                };
                let (s0, rest) = ss.split_at_mut(npix);
                let (s1, s2) = rest.split_at_mut(npix);
                solver.compute(&views, width, &rules, s0, s1, s2, mm)?;
                Ok(())
            })
            .py_err()?
        });
    }
    if return_mask {
        Ok(PyTuple::new(py, [st.into_any(), mask.into_any()])?.into_any())
    } else {
        Ok(st.into_any())
    }
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
/// dtype : {None, "float32", "uint8", "uint16"} or numpy dtype, optional
///     ``output="angles"`` only: the dtype of the images. Default float32 (or the dtype
///     of ``out``). The raw dtype (uint8 / uint16) keeps the images in whole DN, in a
///     half or a quarter of the memory: it needs ``dark_level=0`` and, for ``bilinear``,
///     rounding; the values are then OpenCV's / polanalyser's exactly.
/// out : numpy.ndarray, optional
///     A C-contiguous array to write the result into (and return): shape (4, H, W) /
///     (4, H/2, W/2) of ``dtype`` for ``output="angles"``, (3, H, W) / (3, H/2, W/2)
///     float32 for ``output="stokes"``. Reusing it across frames saves allocating (and
///     the operating system zeroing) a new array per frame.
///
/// Returns
/// -------
/// numpy.ndarray
///     ``output="stokes"``: float32 (3, H, W) for ``bilinear``, (3, H/2, W/2) for
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
///     small dimensions, an unknown method or output, a dtype or ``out`` that does not
///     fit.
///
/// Notes
/// -----
/// The GIL is released; rows are processed in parallel in strips that stay in the CPU
/// cache. For DoLP and AoLP of a mosaic, `dofp_dolp_aolp` is faster than ``demosaic``
/// followed by `dolp_aolp` (no Stokes images are made).
#[pyfunction]
#[pyo3(signature = (raw, pattern = vec![90.0, 45.0, 135.0, 0.0], method = "bilinear", output = "stokes", *, dark_level = 0.0, saturation = None, min_s0 = 0.0, round = None, return_mask = false, dtype = None, out = None))]
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
    dtype: Option<&Bound<'py, PyAny>>,
    out: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let bilinear = method_is_bilinear(method)?;
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
    if !angles && dtype.is_some() {
        return Err(value_error(
            "dtype needs output=\"angles\" (Stokes images are float32)",
        ));
    }
    let pattern = Pattern::new(&pattern).py_err()?;
    let raw = raw_array("raw", raw)?;
    let (h, w) = mosaic_shape(&raw)?;
    let rules = pixel_rules(dark_level, saturation, raw.type_max(), min_s0)?;
    let round = round.unwrap_or(raw.is_integer() && bilinear) && bilinear;
    let (oh, ow) = if bilinear { (h, w) } else { (h / 2, w / 2) };
    let npix = oh * ow;
    if angles {
        let shape = [4, oh, ow];
        let name = out_dtype(dtype, out)?;
        return match name.as_str() {
            "float32" => with_raw!(&raw, |data| {
                with_output::<f32>(py, "out", out, &shape, |buf| {
                    let planes = split4(buf, npix);
                    let dark = dark_level as f32;
                    if bilinear {
                        mosaic::demosaic_bilinear_dark(data, w, &pattern, round, dark, planes)
                    } else {
                        superpixel_angles(data, w, h, &pattern, planes, |v| v.to_f32() - dark)
                    }
                })
            }),
            want @ ("uint8" | "uint16") => {
                int_output(want, &raw, dark_level, !bilinear || round)?;
                match &raw {
                    RawArray::U8(a) => int_angles(py, out, a.as_slice()?, w, h, bilinear, &pattern),
                    RawArray::U16(a) => {
                        int_angles(py, out, a.as_slice()?, w, h, bilinear, &pattern)
                    }
                    RawArray::F32(_) => unreachable!("checked by int_output"),
                }
            }
            other => Err(value_error(format!(
                "dtype must be float32, or uint8 / uint16 for a raw mosaic of that dtype, got {other}"
            ))),
        };
    }
    let mask = new_array::<u8>(py, &[oh, ow]);
    let s = {
        let mut mw = mask.try_readwrite()?;
        let mm = mw.as_slice_mut()?;
        with_raw!(&raw, |data| {
            with_output::<f32>(py, "out", out, &[3, oh, ow], |buf| {
                let (s0, rest) = buf.split_at_mut(npix);
                let (s1, s2) = rest.split_at_mut(npix);
                let o = DofpOutputs {
                    s0: Some(s0),
                    s1: Some(s1),
                    s2: Some(s2),
                    mask: Some(mm),
                    ..Default::default()
                };
                let method = dofp_method(bilinear, round);
                mosaic::dofp_polar(data, w, &pattern, method, &rules, o).map(|_| ())
            })
        })?
    };
    if return_mask {
        Ok(PyTuple::new(py, [s, mask.into_any()])?.into_any())
    } else {
        Ok(s)
    }
}

/// Check that `demosaic(output="angles")` can write `want` (an integer dtype): a raw
/// mosaic of that dtype, no dark level, whole-DN values (`whole`: superpixel, or
/// bilinear with rounding).
fn int_output(want: &str, raw: &RawArray<'_>, dark_level: f64, whole: bool) -> PyResult<()> {
    if raw_dtype(raw) != want {
        return Err(value_error(format!(
            "dtype {want} needs a {want} raw mosaic (got {})",
            raw_dtype(raw)
        )));
    }
    if dark_level != 0.0 {
        return Err(value_error(format!(
            "dtype {want} needs dark_level=0 (got {dark_level}): dark-subtracted values are not whole DN"
        )));
    }
    if !whole {
        return Err(value_error(format!(
            "dtype {want} needs round=True with method=\"bilinear\": unrounded means are not whole DN"
        )));
    }
    Ok(())
}

/// DoLP and AoLP straight from a raw division-of-focal-plane (DoFP) mosaic.
///
/// The fused form of ``dolp_aolp(demosaic(raw, pattern, method))``: the mosaic is
/// read once and only the images asked for are written (no Stokes or per-angle images
/// unless requested), in parallel strips of rows that stay in the CPU cache. Values are
/// those of ``polarid stokes --dofp`` (same kernel, same float32 numbers):
/// ``DoLP = sqrt(S1² + S2²) / S0`` clamped to [0, 1], ``AoLP = atan2(S2, S1) / 2`` in
/// degrees in [0, 180) (a polynomial atan2, error below 4e-8 rad).
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
///     As in `demosaic`: full resolution (polanalyser's bilinear interpolation) or one
///     value per 2x2 cell (half resolution).
/// dark_level, saturation, min_s0
///     As in `stokes`: the dark level is subtracted; pixels whose 3x3 raw neighbourhood
///     (bilinear) or cell (superpixel) holds a saturated or non-finite value, or whose
///     S0 is at or below ``min_s0``, are rejected.
/// round : bool, optional
///     As in `demosaic` (default: True for integer input with ``bilinear``, as
///     polanalyser / OpenCV).
/// return_stokes : bool, default False
///     Also return the Stokes images (3, H, W) float32, as ``demosaic`` gives them.
/// return_mask : bool, default False
///     Also return the pixel mask (0 valid, 1 saturated, 2 dark, 3 invalid).
/// out : tuple of two numpy.ndarray, optional
///     ``(dolp, aolp)`` arrays to write into (and return), C-contiguous float32 of the
///     output shape, as numpy's ``out=`` of two-output functions. Reusing them across
///     frames saves allocating (and the operating system zeroing) new arrays per frame.
///
/// Returns
/// -------
/// tuple of numpy.ndarray
///     ``(dolp, aolp)``, float32, (H, W) for ``bilinear`` and (H/2, W/2) for
///     ``superpixel``, NaN where the mask rejects the pixel; then the Stokes images if
///     ``return_stokes``, then the mask if ``return_mask``.
///
/// Raises
/// ------
/// ValueError
///     As `demosaic`: an invalid pattern, odd or too small dimensions, an unknown
///     method, bad rules.
///
/// Notes
/// -----
/// Where the mask accepts the pixel the values equal ``dolp_aolp(demosaic(raw, ...))``
/// bit for bit; ``dolp_aolp`` of Stokes images has no mask, so there it gives numbers
/// for saturated pixels too (it is NaN only where S0 <= 0). polanalyser's
/// ``cvtStokesToAoLP`` returns radians in [0, pi) and ``cvtStokesToDoLP`` does not clamp.
#[pyfunction]
#[pyo3(signature = (raw, pattern = vec![90.0, 45.0, 135.0, 0.0], method = "bilinear", *, dark_level = 0.0, saturation = None, min_s0 = 0.0, round = None, return_stokes = false, return_mask = false, out = None))]
#[allow(clippy::too_many_arguments)]
pub fn dofp_dolp_aolp<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    pattern: Vec<f64>,
    method: &str,
    dark_level: f64,
    saturation: Option<f64>,
    min_s0: f64,
    round: Option<bool>,
    return_stokes: bool,
    return_mask: bool,
    out: Option<(Bound<'py, PyAny>, Bound<'py, PyAny>)>,
) -> PyResult<Bound<'py, PyTuple>> {
    let bilinear = method_is_bilinear(method)?;
    let pattern = Pattern::new(&pattern).py_err()?;
    let raw = raw_array("raw", raw)?;
    let (h, w) = mosaic_shape(&raw)?;
    let rules = pixel_rules(dark_level, saturation, raw.type_max(), min_s0)?;
    let round = round.unwrap_or(raw.is_integer() && bilinear) && bilinear;
    let method = dofp_method(bilinear, round);
    let (ow, oh) = method.output_size(w, h);
    let n = ow * oh;
    let (d, a) = match &out {
        Some((d, a)) => (
            out_array::<f32>("out[0]", d, &[oh, ow])?,
            out_array::<f32>("out[1]", a, &[oh, ow])?,
        ),
        None => (
            new_array::<f32>(py, &[oh, ow]),
            new_array::<f32>(py, &[oh, ow]),
        ),
    };
    if d.is(&a) {
        return Err(value_error(
            "out[0] and out[1] must be two different arrays",
        ));
    }
    let s = return_stokes.then(|| new_array::<f32>(py, &[3, oh, ow]));
    let m = return_mask.then(|| new_array::<u8>(py, &[oh, ow]));
    {
        let (mut dw, mut aw) = (d.try_readwrite()?, a.try_readwrite()?);
        let mut sw = s.as_ref().map(|s| s.try_readwrite()).transpose()?;
        let mut mw = m.as_ref().map(|m| m.try_readwrite()).transpose()?;
        let (dd, aa) = (dw.as_slice_mut()?, aw.as_slice_mut()?);
        let ss = sw.as_mut().map(|s| s.as_slice_mut()).transpose()?;
        let mm = mw.as_mut().map(|m| m.as_slice_mut()).transpose()?;
        with_raw!(&raw, |data| {
            py.detach(|| {
                let (s0, s1, s2) = match ss {
                    Some(ss) => {
                        let (s0, rest) = ss.split_at_mut(n);
                        let (s1, s2) = rest.split_at_mut(n);
                        (Some(s0), Some(s1), Some(s2))
                    }
                    None => (None, None, None),
                };
                let o = DofpOutputs {
                    s0,
                    s1,
                    s2,
                    mask: mm,
                    dolp: Some(dd),
                    aolp: Some(aa),
                };
                mosaic::dofp_polar(data, w, &pattern, method, &rules, o)
            })
            .py_err()?
        });
    }
    let mut items = vec![d.into_any(), a.into_any()];
    items.extend(s.map(Bound::into_any));
    items.extend(m.map(Bound::into_any));
    PyTuple::new(py, items)
}

/// `method` of `demosaic` / `dofp_dolp_aolp`: true for bilinear.
pub(crate) fn method_is_bilinear(method: &str) -> PyResult<bool> {
    match method {
        "bilinear" => Ok(true),
        "superpixel" => Ok(false),
        _ => Err(value_error(format!(
            "method must be \"bilinear\" or \"superpixel\", got {method:?}"
        ))),
    }
}

/// The core's method for `bilinear` / `round`.
fn dofp_method(bilinear: bool, round: bool) -> DofpMethod {
    if bilinear {
        DofpMethod::Bilinear { round }
    } else {
        DofpMethod::Superpixel
    }
}

/// `(H, W)` of a 2-D raw mosaic.
pub(crate) fn mosaic_shape(raw: &RawArray<'_>) -> PyResult<(usize, usize)> {
    let shape = raw.shape();
    let [h, w] = shape[..] else {
        return Err(value_error(format!(
            "raw must be a 2-D mosaic (H, W), got shape {}",
            fmt_shape(&shape)
        )));
    };
    Ok((h, w))
}

/// The numpy name of a raw array's dtype.
fn raw_dtype(raw: &RawArray<'_>) -> &'static str {
    match raw {
        RawArray::U8(_) => "uint8",
        RawArray::U16(_) => "uint16",
        RawArray::F32(_) => "float32",
    }
}

/// The dtype name of `demosaic`'s per-angle images: `dtype` (any numpy dtype-like),
/// else that of `out`, else float32.
fn out_dtype(dtype: Option<&Bound<'_, PyAny>>, out: Option<&Bound<'_, PyAny>>) -> PyResult<String> {
    let name_of = |d: &Bound<'_, PyAny>| -> PyResult<String> {
        let np = d.py().import("numpy")?;
        np.call_method1("dtype", (d,))?.getattr("name")?.extract()
    };
    match (dtype, out) {
        (Some(d), _) => name_of(d),
        (None, Some(o)) => match o.getattr("dtype") {
            Ok(d) => name_of(&d),
            Err(_) => Err(value_error("out must be a numpy array")),
        },
        (None, None) => Ok("float32".into()),
    }
}

/// A new zeroed numpy array: numpy's allocator asks the kernel for huge pages on large
/// arrays, which makes first writes several times cheaper than into a fresh `Vec`.
pub(crate) fn new_array<'py, O: numpy::Element>(
    py: Python<'py>,
    shape: &[usize],
) -> Bound<'py, PyArrayDyn<O>> {
    PyArrayDyn::<O>::zeros(py, IxDyn(shape), false)
}

/// The caller's array `o` for the output `name`, checked: a C-contiguous numpy array of
/// element type `O` and shape `shape` (its writeability is checked when it is borrowed).
pub(crate) fn out_array<'py, O: numpy::Element>(
    name: &str,
    o: &Bound<'py, PyAny>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<O>>> {
    let dtype = O::get_dtype(o.py()).to_string();
    let want = || {
        format!(
            "{name} must be a C-contiguous, writeable numpy array of dtype {dtype} and shape {}",
            fmt_shape(shape)
        )
    };
    let arr = o.cast::<PyArrayDyn<O>>().map_err(|_| {
        let got = o.repr().map_or_else(|_| "?".into(), |r| r.to_string());
        value_error(format!("{}, got {got}", want()))
    })?;
    if arr.shape() != shape {
        return Err(value_error(format!(
            "{}, got shape {}",
            want(),
            fmt_shape(arr.shape())
        )));
    }
    if !arr.is_c_contiguous() {
        return Err(value_error(format!(
            "{}, got a non-contiguous array",
            want()
        )));
    }
    Ok(arr.clone())
}

/// Run `f` on the output buffer of `shape` (GIL released) and return the array: the
/// caller's C-contiguous array `out` (checked: a writeable numpy array of element type
/// `O` and this shape), or a new one.
fn with_output<'py, O: numpy::Element + Send>(
    py: Python<'py>,
    name: &str,
    out: Option<&Bound<'py, PyAny>>,
    shape: &[usize],
    f: impl FnOnce(&mut [O]) -> Result<(), CoreError> + Send,
) -> PyResult<Bound<'py, PyAny>> {
    let arr = match out {
        None => new_array::<O>(py, shape),
        Some(o) => out_array::<O>(name, o, shape)?,
    };
    {
        let mut rw = arr
            .try_readwrite()
            .map_err(|e| value_error(format!("{name} is not writeable: {e}")))?;
        let buf = rw.as_slice_mut()?;
        py.detach(|| f(buf)).py_err()?;
    }
    Ok(arr.into_any())
}

/// Four consecutive planes of `npix` values.
fn split4<O>(buf: &mut [O], npix: usize) -> [&mut [O]; 4] {
    let (a, rest) = buf.split_at_mut(npix);
    let (b, rest) = rest.split_at_mut(npix);
    let (c, d) = rest.split_at_mut(npix);
    [a, b, c, d]
}

/// Per-angle images of integer data (`w × h`) in its own type, written to `out` as by
/// [`with_output`]: bilinear (rounded as OpenCV) or super-pixel.
fn int_angles<'py, T: IntSample + numpy::Element>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyAny>>,
    raw: &[T],
    w: usize,
    h: usize,
    bilinear: bool,
    pattern: &Pattern,
) -> PyResult<Bound<'py, PyAny>> {
    let (oh, ow) = if bilinear { (h, w) } else { (h / 2, w / 2) };
    with_output::<T>(py, "out", out, &[4, oh, ow], |buf| {
        let planes = split4(buf, oh * ow);
        if bilinear {
            mosaic::demosaic_bilinear_int(raw, w, pattern, planes)
        } else {
            superpixel_angles(raw, w, h, pattern, planes, |v| v)
        }
    })
}

/// Half-resolution per-angle images: channel `k` (k × 45°) is `conv` of the raw pixel
/// at the polarizer's position in each 2×2 cell.
fn superpixel_angles<T: Sample, O: Send>(
    raw: &[T],
    w: usize,
    h: usize,
    pattern: &Pattern,
    out: [&mut [O]; 4],
    conv: impl Fn(T) -> O + Sync,
) -> Result<(), CoreError> {
    if w == 0 || h == 0 || !w.is_multiple_of(2) || !h.is_multiple_of(2) || raw.len() != w * h {
        return Err(CoreError::InvalidDimensions {
            width: w,
            height: h,
            reason: "a 2x2 polarizer mosaic needs an even width and height".into(),
        });
    }
    let w2 = w / 2;
    for (k, o) in out.into_iter().enumerate() {
        let (pr, pc) = pattern.position(k);
        o.par_chunks_mut(w2).enumerate().for_each(|(y, row)| {
            let src = &raw[(2 * y + pr) * w..(2 * y + pr + 1) * w];
            for (x, v) in row.iter_mut().enumerate() {
                *v = conv(src[2 * x + pc]);
            }
        });
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
            let d = new_array::<f32>(py, &shape);
            let g = new_array::<f32>(py, &shape);
            if npix > 0 {
                let (mut dw, mut gw) = (d.try_readwrite()?, g.try_readwrite()?);
                let (dd, gg) = (dw.as_slice_mut()?, gw.as_slice_mut()?);
                py.detach(|| {
                    let (s0, rest) = data.split_at(npix);
                    let (s1, s2) = rest.split_at(npix);
                    core_stokes::dolp_aolp(width, s0, s1, s2, None, dd, gg)
                })
                .py_err()?;
            }
            Ok((d.into_any(), g.into_any()))
        }
        FloatArray::F64(a) => {
            let shape = shape_of!(a);
            let v = a.as_array();
            let [d, g] = py.detach(|| {
                let s = |i| v.index_axis(Axis(0), i);
                let (s0, s1, s2) = (s(0), s(1), s(2));
                map3(&shape, [&s0, &s1, &s2], |s0, s1, s2| {
                    let (d, g) = dolp_aolp_f64(s0, s1, s2);
                    [d, g]
                })
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
