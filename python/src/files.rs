//! Capture-set manifests: `load_manifest` (the validated manifest as a dict) and
//! `measure` (each region's DoLP per capture, the numbers of `polarid measure`).
//!
//! `measure` re-implements the thin orchestration of the CLI's `measure_manifest`
//! (crates/polarid-cli/src/cmd/measure.rs) on the io/core APIs, step for step, so that
//! it produces the same numbers without depending on the CLI crate: frames → Stokes
//! (`StokesSolver::compute`, rules from the capture's dark level and saturation),
//! DoFP → bilinear Stokes without rounding (`mosaic::bilinear_stokes`, sampling
//! `BilinearDofp`), Stokes TIFFs → `stokes::mask_stokes`; then `region::region_stats` per
//! region and `geometry::beta`. The test suite compares it with the CLI's CSV.

use std::ffi::CString;
use std::path::{Path, PathBuf};

use ndarray::{ArrayD, IxDyn};
use polarid_core::geometry;
use polarid_core::mosaic;
use polarid_core::region::{Sampling, region_stats};
use polarid_core::stokes::{self, PixelCounts, PixelRules, StokesSolver};
use polarid_io::IoError;
use polarid_io::image::{self, Frame};
use polarid_io::manifest::{self, Capture, CaptureSource, Manifest};
use polarid_io::table::measurements::Measurement;
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{str_array, to_numpy};
use crate::errors::{IntoPyErr, PyResultExt, value_error};

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load_manifest, m)?)?;
    m.add_function(wrap_pyfunction!(measure, m)?)?;
    Ok(())
}

fn path_arg(obj: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    let s: String = obj
        .py()
        .import("os")?
        .call_method1("fspath", (obj,))?
        .extract()?;
    Ok(PathBuf::from(s))
}

fn warn_all(py: Python<'_>, m: &Manifest) -> PyResult<()> {
    let cat = py.get_type::<PyUserWarning>();
    for w in &m.warnings {
        let msg = CString::new(w.replace('\0', " ")).map_err(|e| value_error(e.to_string()))?;
        PyErr::warn(py, cat.as_any(), &msg, 2)?;
    }
    Ok(())
}

/// Read and validate a capture-set manifest (TOML, shared/FORMATS.md).
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
///     ``exposure``, ``dark_level``, ``saturation``, ``beta_deg`` (derived, eq. 5),
///     ``kind`` = ``"frames"`` | ``"dofp"`` | ``"stokes"`` and, by kind, ``frames``
///     (list of dicts ``angle_deg``, ``file``), ``dofp`` (dict ``file``, ``pattern``)
///     or ``stokes`` (dict ``s0``, ``s1``, ``s2``)), ``warnings`` (unknown keys, also
///     issued as ``UserWarning``). File paths are resolved against the manifest's
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
    d.set_item("theta_r_deg", m.theta_r_deg)?;
    d.set_item("phi_deg", m.phi_deg)?;
    d.set_item("dark_level", m.dark_level)?;
    d.set_item("saturation", m.saturation)?;
    d.set_item("wavelength_nm", m.wavelength_nm)?;
    let regions = PyList::empty(py);
    for r in &m.regions {
        let rd = PyDict::new(py);
        rd.set_item("name", &r.name)?;
        rd.set_item("rect", (r.rect.x, r.rect.y, r.rect.width, r.rect.height))?;
        rd.set_item("class", r.class.as_deref())?;
        rd.set_item("line", r.line)?;
        rd.set_item("index", r.index)?;
        regions.append(rd)?;
    }
    d.set_item("regions", regions)?;
    let captures = PyList::empty(py);
    for c in &m.captures {
        let cd = PyDict::new(py);
        cd.set_item("index", c.index)?;
        cd.set_item("line", c.line)?;
        cd.set_item("name", c.name.as_deref())?;
        cd.set_item("theta_i_deg", c.theta_i_deg)?;
        cd.set_item("theta_r_deg", c.theta_r_deg)?;
        cd.set_item("phi_deg", c.phi_deg)?;
        cd.set_item("exposure", c.exposure)?;
        cd.set_item("dark_level", c.dark_level)?;
        cd.set_item("saturation", c.saturation)?;
        cd.set_item("beta_deg", beta_deg(c))?;
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

fn beta_deg(c: &Capture) -> f64 {
    geometry::beta(
        c.theta_i_deg.to_radians(),
        c.theta_r_deg.to_radians(),
        c.phi_deg.to_radians(),
    )
    .to_degrees()
}

/// Stokes images of one capture (the CLI's `StokesImages`).
struct Images {
    width: usize,
    height: usize,
    s0: Vec<f32>,
    s1: Vec<f32>,
    s2: Vec<f32>,
    mask: Vec<u8>,
    sampling: Sampling,
}

impl Images {
    fn alloc(width: usize, height: usize, sampling: Sampling) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            s0: vec![0.0; n],
            s1: vec![0.0; n],
            s2: vec![0.0; n],
            mask: vec![0; n],
            sampling,
        }
    }
}

/// The CLI's `rules_for`: the capture's dark level and saturation (default: the type max).
fn rules_for(frame: &Frame, dark_level: f64, saturation: Option<f64>) -> PixelRules {
    PixelRules {
        dark_level: dark_level as f32,
        saturation: saturation.map_or(frame.type_max(), |s| s as f32),
        min_s0: 0.0,
    }
}

/// Errors of one capture: IoError (file, or a CoreError wrapped with the file), or a
/// bare CoreError (the angle set), as the CLI reports them.
enum MeasureError {
    Io(IoError),
    Core(polarid_core::CoreError),
}

impl From<IoError> for MeasureError {
    fn from(e: IoError) -> Self {
        MeasureError::Io(e)
    }
}

impl From<polarid_core::CoreError> for MeasureError {
    fn from(e: polarid_core::CoreError) -> Self {
        MeasureError::Core(e)
    }
}

impl IntoPyErr for MeasureError {
    fn into_py_err(self) -> PyErr {
        match self {
            MeasureError::Io(e) => e.into_py_err(),
            MeasureError::Core(e) => e.into_py_err(),
        }
    }
}

fn capture_images(c: &Capture) -> Result<Images, MeasureError> {
    Ok(match &c.source {
        CaptureSource::Frames(frames) => {
            let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
            let solver = StokesSolver::from_degrees(&angles)?;
            let paths: Vec<&Path> = frames.iter().map(|f| f.file.as_path()).collect();
            let imgs = image::read_frames(&paths)?;
            let Some(first) = imgs.first() else {
                return Err(polarid_core::CoreError::TooFew {
                    what: "frames",
                    needed: 3,
                    got: 0,
                }
                .into());
            };
            let rules = rules_for(first, c.dark_level, c.saturation);
            let mut o = Images::alloc(first.width, first.height, Sampling::Independent);
            let views: Vec<&[f32]> = imgs.iter().map(|f| f.data.as_slice()).collect();
            solver
                .compute(
                    &views,
                    first.width,
                    &rules,
                    &mut o.s0,
                    &mut o.s1,
                    &mut o.s2,
                    &mut o.mask,
                )
                .map_err(|e| IoError::Core {
                    path: first.path.clone(),
                    source: e,
                })?;
            o
        }
        CaptureSource::Dofp { file, pattern } => {
            let raw = image::read_frame(file)?;
            let rules = rules_for(&raw, c.dark_level, c.saturation);
            let mut o = Images::alloc(raw.width, raw.height, Sampling::BilinearDofp);
            mosaic::bilinear_stokes(
                &raw.data,
                raw.width,
                pattern,
                &rules,
                false,
                &mut o.s0,
                &mut o.s1,
                &mut o.s2,
                &mut o.mask,
            )
            .map_err(|e| IoError::Core {
                path: raw.path.clone(),
                source: e,
            })?;
            o
        }
        CaptureSource::Stokes { s0, s1, s2 } => {
            let imgs = image::read_frames(&[s0, s1, s2])?;
            let (w, h) = (imgs[0].width, imgs[0].height);
            let mut it = imgs.into_iter().map(|f| f.data);
            let (Some(d0), Some(d1), Some(d2)) = (it.next(), it.next(), it.next()) else {
                return Err(polarid_core::CoreError::TooFew {
                    what: "Stokes images",
                    needed: 3,
                    got: 0,
                }
                .into());
            };
            let mut mask = vec![0u8; w * h];
            let _: PixelCounts =
                stokes::mask_stokes(w, &d0, &d1, &d2, 0.0, &mut mask).map_err(|e| {
                    IoError::Core {
                        path: s0.clone(),
                        source: e,
                    }
                })?;
            Images {
                width: w,
                height: h,
                s0: d0,
                s1: d1,
                s2: d2,
                mask,
                sampling: Sampling::Independent,
            }
        }
    })
}

fn measure_capture(m: &Manifest, c: &Capture) -> Result<Vec<Measurement>, MeasureError> {
    let img = capture_images(c)?;
    let beta_deg = beta_deg(c);
    let first_file = c
        .source
        .files()
        .first()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let mut rows = Vec::with_capacity(m.regions.len());
    for r in &m.regions {
        let st = region_stats(
            img.width,
            &img.s0,
            &img.s1,
            &img.s2,
            &img.mask,
            r.rect,
            img.sampling,
        )
        .map_err(|e| IoError::Manifest {
            path: m.path.clone(),
            line: r.line,
            field: format!("region[{}].rect", r.index),
            value: format!(
                "[{}, {}, {}, {}]",
                r.rect.x, r.rect.y, r.rect.width, r.rect.height
            ),
            reason: format!(
                "in capture {} (line {}, {first_file}, {}x{} pixels): {e}",
                c.index, c.line, img.width, img.height
            ),
        })?;
        rows.push(Measurement {
            target: r.name.clone(),
            class: r.class.clone(),
            theta_i_deg: Some(c.theta_i_deg),
            theta_r_deg: Some(c.theta_r_deg),
            phi_deg: c.phi_deg,
            beta_deg,
            dolp: st.dolp,
            dolp_se: st.dolp_se.filter(|se| se.is_finite() && *se > 0.0),
            s0: Some(st.s0() / c.exposure),
            pixels: Some(st.pixels),
            rejected: Some(st.rejected),
            exposure: Some(c.exposure),
            saturated: Some(st.saturated),
        });
    }
    Ok(rows)
}

/// Measure every region of every capture of a manifest: the rows of ``polarid measure``.
///
/// For every region and capture: the DoLP of the region's mean Stokes vector, its
/// standard error from the pixel scatter, the mean S0 divided by the capture's exposure,
/// the pixels used and rejected, and beta (eq. 5). Same code path and the same numbers
/// as ``polarid measure MANIFEST`` (DoFP captures: bilinear, full resolution, not
/// rounded). The GIL is released; each capture is processed in parallel.
///
/// Parameters
/// ----------
/// manifest_path : str or os.PathLike
///
/// Returns
/// -------
/// dict of numpy arrays, one entry per column of the measurements CSV, one element per
/// row (targets of capture 1 in region order, then capture 2, ...)
///     ``target``, ``class`` (str arrays; ``""`` for no class), ``theta_i_deg``,
///     ``theta_r_deg``, ``phi_deg``, ``beta_deg``, ``dolp``, ``dolp_se`` (NaN where the
///     CSV cell is empty: noiseless data), ``s0``, ``exposure`` (float64), ``pixels``,
///     ``rejected``, ``saturated`` (int64).
///
/// Raises
/// ------
/// FileNotFoundError
///     A missing manifest or image.
/// ValueError
///     An invalid manifest, an unreadable image, a region that leaves the frame or has no
///     usable pixel (the CLI's message, naming the file, line and field).
#[pyfunction]
pub fn measure<'py>(
    py: Python<'py>,
    manifest_path: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let p = path_arg(manifest_path)?;
    let m = py.detach(|| manifest::load(&p)).py_err()?;
    warn_all(py, &m)?;
    let rows = py
        .detach(|| -> Result<Vec<Measurement>, MeasureError> {
            let mut rows = Vec::with_capacity(m.captures.len() * m.regions.len());
            for c in &m.captures {
                rows.extend(measure_capture(&m, c)?);
            }
            Ok(rows)
        })
        .py_err()?;
    measurements_dict(py, &rows)
}

/// The columns of measurement rows as numpy arrays.
pub fn measurements_dict<'py>(
    py: Python<'py>,
    rows: &[Measurement],
) -> PyResult<Bound<'py, PyDict>> {
    let dim = IxDyn(&[rows.len()]);
    let f = |g: &dyn Fn(&Measurement) -> f64| -> PyResult<Bound<'py, PyAny>> {
        let a = ArrayD::from_shape_vec(dim.clone(), rows.iter().map(g).collect())
            .map_err(|e| value_error(e.to_string()))?;
        Ok(to_numpy(py, a))
    };
    let i = |g: &dyn Fn(&Measurement) -> Option<u64>| -> PyResult<Bound<'py, PyAny>> {
        let a = ArrayD::from_shape_vec(
            dim.clone(),
            rows.iter().map(|r| g(r).map_or(-1, |v| v as i64)).collect(),
        )
        .map_err(|e| value_error(e.to_string()))?;
        Ok(to_numpy(py, a))
    };
    let strs = |g: &dyn Fn(&Measurement) -> &str| -> PyResult<Bound<'py, PyAny>> {
        let mut names: Vec<&str> = Vec::new();
        let mut codes = Vec::with_capacity(rows.len());
        for r in rows {
            let s = g(r);
            let idx = names.iter().position(|n| *n == s).unwrap_or_else(|| {
                names.push(s);
                names.len() - 1
            });
            codes.push(idx as u32);
        }
        let codes =
            ArrayD::from_shape_vec(dim.clone(), codes).map_err(|e| value_error(e.to_string()))?;
        str_array(py, &names, codes)
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
    Ok(d)
}
