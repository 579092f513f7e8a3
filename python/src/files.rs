//! Capture-set manifests: `load_manifest` (the validated manifest as a dict) and
//! `measure` (each region's DoLP per capture, the numbers of `polarid measure`); image
//! files: `read_image` (a grayscale PNG/TIFF through the readers of the CLI,
//! `polarid_io::image::read_frame`).
//!
//! `beta_map` gives the per-pixel β of a capture with calibrated geometry.
//!
//! `measure` calls `polarid_pipeline::measure::measure`, the pipeline `polarid
//! measure` runs (crates/polarid-cli/src/cmd/measure.rs), so it produces the same
//! numbers. The test suite compares it with the CLI's CSV.

use std::ffi::CString;
use std::path::{Path, PathBuf};

use ndarray::Array1;
use polarid_io::manifest::{self, CaptureSource, Manifest};
use polarid_io::measure::beta_deg;
use polarid_io::table::measurements::Measurement;
use polarid_pipeline::progress::no_progress;
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{NameTable, shaped, str_array};
use crate::errors::{PyResultExt, value_error};
use crate::set_fields;

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load_manifest, m)?)?;
    m.add_function(wrap_pyfunction!(measure, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    m.add_function(wrap_pyfunction!(beta_map, m)?)?;
    Ok(())
}

/// A path argument (`str` or `os.PathLike`).
pub(crate) fn path_arg(obj: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    let s: String = obj
        .py()
        .import("os")?
        .call_method1("fspath", (obj,))?
        .extract()?;
    Ok(PathBuf::from(s))
}

/// Issue the manifest's warnings as `UserWarning`.
pub(crate) fn warn_all(py: Python<'_>, m: &Manifest) -> PyResult<()> {
    warn_texts(py, m.warnings.iter().map(String::as_str))
}

/// Issue each text as a `UserWarning` (the CLI prints the same texts on standard error).
pub(crate) fn warn_texts<'a>(
    py: Python<'_>,
    texts: impl IntoIterator<Item = &'a str>,
) -> PyResult<()> {
    let cat = py.get_type::<PyUserWarning>();
    for w in texts {
        let msg = CString::new(w.replace('\0', " ")).map_err(|e| value_error(e.to_string()))?;
        PyErr::warn(py, cat.as_any(), &msg, 2)?;
    }
    Ok(())
}

/// Read a grayscale PNG or TIFF image as the ``polarid`` command-line program does.
///
/// The same reader and limits as the CLI (``polarid_io::image``): 8- or 16-bit PNG,
/// 8/16/32-bit integer or 32-bit float grayscale TIFF; regular files only, at most
/// 2**28 pixels, within the memory budget, no decompression bombs.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///
/// Returns
/// -------
/// numpy.ndarray
///     float32, shape (height, width): the samples as stored (DN for integer files,
///     no scaling), e.g. a raw DoFP mosaic for ``demosaic`` or the ``s0.tif`` ...
///     ``aolp.tif`` of ``polarid stokes``.
///
/// Raises
/// ------
/// FileNotFoundError
///     The file does not exist.
/// ValueError
///     The file is not a readable grayscale PNG/TIFF or exceeds a limit (the message
///     names the file, as the CLI's).
#[pyfunction]
pub fn read_image<'py>(py: Python<'py>, path: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let p = path_arg(path)?;
    let frame = py.detach(|| polarid_io::image::read_frame(&p)).py_err()?;
    shaped(py, &[frame.height, frame.width], frame.data)
}

/// The β (eq. 5, degrees) of every pixel of a capture with calibrated geometry.
///
/// Where each pixel's ray meets its plane, lit by the capture's ``source``: the plane of
/// the first region (in manifest order) that contains the pixel, else the first
/// ``[[plane]]`` (as ``polarid map`` and ``polarid measure`` do). Pixels in the
/// coordinates of the files as stored (the raw mosaic for DoFP captures), centres at
/// integers. The image size is that of the capture's first file.
///
/// Parameters
/// ----------
/// manifest_path : str or os.PathLike
/// capture : int, optional
///     The capture's position in ``load_manifest(...)["captures"]`` (0-based; the first
///     capture, whose ``index`` is 1, is 0).
///
/// Returns
/// -------
/// numpy.ndarray
///     float32, shape (height, width), degrees; NaN where a pixel has no geometry (its
///     ray misses the plane, or the source is below the plane's horizon there).
///
/// Raises
/// ------
/// FileNotFoundError
///     A missing manifest or image.
/// ValueError
///     An invalid manifest, a capture index out of range, or a far-field capture (one β
///     for every pixel: ``load_manifest(...)["captures"][i]["beta_deg"]``).
#[pyfunction]
#[pyo3(signature = (manifest_path, capture = 0))]
pub fn beta_map<'py>(
    py: Python<'py>,
    manifest_path: &Bound<'py, PyAny>,
    capture: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let p = path_arg(manifest_path)?;
    let m = py.detach(|| manifest::load(&p)).py_err()?;
    warn_all(py, &m)?;
    let Some(c) = m.captures.get(capture) else {
        return Err(value_error(format!(
            "capture {capture} is out of range: {} has {} captures (0-based)",
            p.display(),
            m.captures.len()
        )));
    };
    if c.illumination.is_none() {
        return Err(value_error(format!(
            "capture {capture} of {} has far-field angles (one beta_deg for every pixel: \
             load_manifest(...)[\"captures\"][{capture}][\"beta_deg\"]); beta_map is for \
             captures with a source",
            p.display()
        )));
    }
    let first = c
        .files()
        .first()
        .map(|f| f.to_path_buf())
        .ok_or_else(|| value_error(format!("capture {capture} has no file")))?;
    let (w, h, data) = py
        .detach(|| -> Result<_, polarid_io::IoError> {
            let f = polarid_io::image::read_frame(&first)?;
            let b = polarid_io::measure::beta_map(&m, c, f.width, f.height)?;
            Ok((f.width, f.height, b.unwrap_or_default()))
        })
        .py_err()?;
    shaped(py, &[h, w], data)
}

/// Read and validate a capture-set manifest (TOML, docs/FORMATS.md).
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///
/// Returns
/// -------
/// dict
///     The manifest after validation and defaults, mirroring the file: ``path``,
///     ``theta_r_deg`` (None if not given at the top level), ``phi_deg``,
///     ``dark_level``, ``saturation`` (None: the frames' type maximum),
///     ``wavelength_nm``, ``regions`` (list of dicts ``name``, ``rect`` = (x, y, width,
///     height), ``class`` (or None), ``line``, ``index``), ``captures`` (list of dicts
///     ``index``, ``line``, ``name``, ``theta_i_deg``, ``theta_r_deg``, ``phi_deg``,
///     ``exposure``, ``dark_level``, ``saturation``, ``beta_deg`` (derived, eq. 5;
///     ``None`` for a capture with calibrated geometry, whose β differs from pixel to
///     pixel: ``polarid.beta_map(path, index)`` gives it), ``calibrated`` (bool),
///     ``kind`` = ``"frames"`` | ``"dofp"`` | ``"stokes"`` and, by kind, ``frames``
///     (list of dicts ``angle_deg``, ``file``), ``dofp`` (dict ``file``, ``pattern``)
///     or ``stokes`` (dict ``s0``, ``s1``, ``s2``)), ``calibrated`` (bool: the manifest
///     has a ``[camera]`` and every capture a ``source``), ``warnings`` (unknown keys,
///     also issued as ``UserWarning``). File paths are resolved against the manifest's
///     directory.
///
/// Raises
/// ------
/// FileNotFoundError
///     The manifest does not exist.
/// ValueError
///     An invalid manifest; the message names the file, line, field and value, as
///     ``polarid measure`` prints it.
#[pyfunction]
pub fn load_manifest<'py>(
    py: Python<'py>,
    path: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let p = path_arg(path)?;
    let m = py.detach(|| manifest::load(&p)).py_err()?;
    warn_all(py, &m)?;
    let d = PyDict::new(py);
    d.set_item("path", m.path.display().to_string())?;
    set_fields!(d, m, theta_r_deg, phi_deg);
    set_fields!(d, m, dark_level, saturation, wavelength_nm);
    d.set_item("calibrated", m.camera.is_some())?;
    let regions = PyList::empty(py);
    for r in &m.regions {
        let rd = PyDict::new(py);
        rd.set_item("name", &r.name)?;
        rd.set_item("rect", (r.rect.x, r.rect.y, r.rect.width, r.rect.height))?;
        rd.set_item("class", r.class.as_deref())?;
        set_fields!(rd, r, line, index);
        regions.append(rd)?;
    }
    d.set_item("regions", regions)?;
    let captures = PyList::empty(py);
    for c in &m.captures {
        let cd = PyDict::new(py);
        set_fields!(cd, c, index, line, name, theta_i_deg, theta_r_deg, phi_deg);
        set_fields!(cd, c, exposure, dark_level, saturation);
        // A calibrated capture has no single β (the far-field angles are not set).
        let calibrated = c.illumination.is_some();
        cd.set_item("beta_deg", (!calibrated).then(|| beta_deg(c)))?;
        cd.set_item("calibrated", calibrated)?;
        cd.set_item("wavelength_nm", c.wavelength_nm)?;
        let show = |p: &Path| p.display().to_string();
        match &c.source {
            CaptureSource::Frames(frames) => {
                cd.set_item("kind", "frames")?;
                let l = PyList::empty(py);
                for f in frames {
                    let fd = PyDict::new(py);
                    fd.set_item("angle_deg", f.angle_deg)?;
                    fd.set_item("file", show(&f.file))?;
                    l.append(fd)?;
                }
                cd.set_item("frames", l)?;
            }
            CaptureSource::Dofp { file, pattern } => {
                cd.set_item("kind", "dofp")?;
                let dd = PyDict::new(py);
                dd.set_item("file", show(file))?;
                dd.set_item("pattern", pattern.angles_deg().to_vec())?;
                cd.set_item("dofp", dd)?;
            }
            CaptureSource::ColourDofp {
                file,
                pattern,
                wavelengths_nm,
            } => {
                cd.set_item("kind", "colour_dofp")?;
                let dd = PyDict::new(py);
                dd.set_item("file", show(file))?;
                dd.set_item("pattern", pattern.polar().angles_deg().to_vec())?;
                dd.set_item("color", pattern.color())?;
                let bands: Vec<String> = pattern.bands().iter().map(|c| c.to_string()).collect();
                dd.set_item("bands", bands)?;
                dd.set_item("wavelengths_nm", wavelengths_nm.clone())?;
                cd.set_item("dofp", dd)?;
            }
            CaptureSource::Stokes { s0, s1, s2 } => {
                cd.set_item("kind", "stokes")?;
                let sd = PyDict::new(py);
                sd.set_item("s0", show(s0))?;
                sd.set_item("s1", show(s1))?;
                sd.set_item("s2", show(s2))?;
                cd.set_item("stokes", sd)?;
            }
        }
        captures.append(cd)?;
    }
    d.set_item("captures", captures)?;
    d.set_item("warnings", m.warnings.clone())?;
    Ok(d)
}

/// Measure every region of every capture of a manifest: the rows of ``polarid measure``.
///
/// For every region and capture: the DoLP of the region's mean Stokes vector, its
/// standard error from the pixel scatter, the mean S0 divided by the capture's exposure,
/// the pixels used and rejected, and beta (eq. 5). Captures with calibrated geometry
/// (``[camera]`` and a ``source``) are measured with per-pixel geometry: the mean Stokes
/// vector in each pixel's plane-of-incidence frame, the S0-weighted geometry and its
/// spread ``beta_sd_deg``, ``aolp_deg`` and ``aolp_poi_deg`` (docs/GEOMETRY.md). Same
/// code path and the same numbers as ``polarid measure MANIFEST`` (DoFP captures:
/// bilinear, full resolution, not rounded). The GIL is released; each capture is
/// processed in parallel.
///
/// Parameters
/// ----------
/// manifest_path : str or os.PathLike
/// strict : bool, optional
///     Raise at the first region that is dark or has no usable pixel in a capture
///     (``polarid measure --strict``). By default such a region gets a row whose
///     ``status`` says why (``dark``, ``saturated``, ``invalid``) with the ``reason``,
///     and a ``UserWarning`` lists them.
///
/// Returns
/// -------
/// dict of numpy arrays, one entry per column of the measurements CSV, one element per
/// row (targets of capture 1 in region order, then capture 2, ...)
///     ``target``, ``class`` (str arrays; ``""`` for no class), ``theta_i_deg``,
///     ``theta_r_deg``, ``phi_deg``, ``beta_deg``, ``dolp``, ``dolp_se`` (NaN where the
///     CSV cell is empty: noiseless data), ``s0``, ``exposure`` (float64), ``pixels``,
///     ``rejected``, ``saturated`` (int64), and ``beta_sd_deg``, ``aolp_deg``,
///     ``aolp_poi_deg`` (float64; NaN for far-field captures, whose CSV has no such
///     columns), ``status`` and ``reason`` (str arrays; ``"ok"`` and ``""`` for usable
///     rows).
///
/// Raises
/// ------
/// FileNotFoundError
///     A missing manifest or image.
/// ValueError
///     An invalid manifest, an unreadable image, a region that leaves the frame, no usable
///     row at all, or with ``strict`` a dark region or one without a usable pixel (the
///     CLI's message, naming the file, line and field).
#[pyfunction]
#[pyo3(signature = (manifest_path, *, strict = false))]
pub fn measure<'py>(
    py: Python<'py>,
    manifest_path: &Bound<'py, PyAny>,
    strict: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = path_arg(manifest_path)?;
    let m = py.detach(|| manifest::load(&p)).py_err()?;
    warn_all(py, &m)?;
    let cfg = polarid_pipeline::measure::MeasureConfig { strict };
    let out = py
        .detach(|| polarid_pipeline::measure::measure_with(&m, &cfg, &no_progress))
        .py_err()?;
    warn_texts(py, out.warnings.iter().map(|w| w.0.as_str()))?;
    measurements_dict(py, &out.rows)
}

/// The columns of measurement rows as numpy arrays.
pub fn measurements_dict<'py>(
    py: Python<'py>,
    rows: &[Measurement],
) -> PyResult<Bound<'py, PyDict>> {
    let dim = [rows.len()];
    let f = |g: &dyn Fn(&Measurement) -> f64| shaped(py, &dim, rows.iter().map(g).collect());
    let i = |g: &dyn Fn(&Measurement) -> Option<u64>| {
        let v: Vec<i64> = rows.iter().map(|r| g(r).map_or(-1, |v| v as i64)).collect();
        shaped(py, &dim, v)
    };
    let strs = |g: &dyn Fn(&Measurement) -> &str| -> PyResult<Bound<'py, PyAny>> {
        let mut names = NameTable::default();
        let codes: Vec<u32> = rows.iter().map(|r| names.code(g(r))).collect();
        str_array(py, &names.refs(), Array1::from(codes).into_dyn())
    };
    let nan = f64::NAN;
    let d = PyDict::new(py);
    d.set_item("target", strs(&|r| r.target.as_str())?)?;
    d.set_item("class", strs(&|r| r.class.as_deref().unwrap_or(""))?)?;
    d.set_item("theta_i_deg", f(&|r| r.theta_i_deg.unwrap_or(nan))?)?;
    d.set_item("theta_r_deg", f(&|r| r.theta_r_deg.unwrap_or(nan))?)?;
    d.set_item("phi_deg", f(&|r| r.phi_deg)?)?;
    d.set_item("beta_deg", f(&|r| r.beta_deg)?)?;
    d.set_item("dolp", f(&|r| r.dolp)?)?;
    d.set_item("dolp_se", f(&|r| r.dolp_se.unwrap_or(nan))?)?;
    d.set_item("s0", f(&|r| r.s0.unwrap_or(nan))?)?;
    d.set_item("pixels", i(&|r| r.pixels)?)?;
    d.set_item("rejected", i(&|r| r.rejected)?)?;
    d.set_item("exposure", f(&|r| r.exposure.unwrap_or(nan))?)?;
    d.set_item("saturated", i(&|r| r.saturated)?)?;
    d.set_item("beta_sd_deg", f(&|r| r.beta_sd_deg.unwrap_or(nan))?)?;
    d.set_item("aolp_deg", f(&|r| r.aolp_deg.unwrap_or(nan))?)?;
    d.set_item("aolp_poi_deg", f(&|r| r.aolp_poi_deg.unwrap_or(nan))?)?;
    d.set_item("status", strs(&|r| r.status.as_str())?)?;
    d.set_item("reason", strs(&|r| r.reason.as_str())?)?;
    Ok(d)
}
