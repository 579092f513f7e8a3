//! The `(n, k)` fit of paper section 5 (eq. 16) for one target or a stack of pixels,
//! through the public API of `polarid_core::fit` (`FitPlan`, `fit`, `fit_batch`), and
//! the table-level fit of `polarid fit` (`polarid_pipeline::fit`).

use std::path::PathBuf;
use std::sync::{Arc, LazyLock, Mutex};

use ndarray::{ArrayD, IxDyn};
use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use polarid_core::CoreError;
use polarid_core::fit::{
    FitOptions, FitPlan, FitStatus, NkFit, PixelBetaPlan, fit_batch, fit_batch_pixel_beta,
};
use polarid_core::mixed::Shadowing;
use polarid_pipeline::fit::{
    FitConfig, PlanCache, Reflectance, check_range, parse_shadowing, read_measurements,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{FloatArray, f64_contiguous, float_array, fmt_shape, to_numpy};
use crate::errors::{PyResultExt, value_error};
use crate::set_fields;

/// Register this module's functions and constants.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_nk, m)?)?;
    m.add_function(wrap_pyfunction!(fit_table, m)?)?;
    m.add(
        "FIT_STATUS",
        FitStatus::ALL
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>(),
    )?;
    Ok(())
}

/// The last few plans (building one costs a 32 × 32 grid of model curves, ~0.2 ms at
/// T = 10: noticeable against a batch of 1000 pixels, so repeated calls with the same
/// β set reuse it).
static PLANS: LazyLock<Mutex<PlanCache>> =
    LazyLock::new(|| Mutex::new(PlanCache::with_capacity(PLAN_CACHE)));
const PLAN_CACHE: usize = 8;

fn plan_for(betas: &[f64], opts: FitOptions) -> Result<Arc<FitPlan>, CoreError> {
    match PLANS.lock() {
        Ok(mut cache) => cache.get(betas, opts),
        Err(_) => FitPlan::new(betas, opts).map(Arc::new),
    }
}

/// The per-pixel-β plan of the last options used (its column cache serves the next
/// calls with the same options).
static PIXEL_PLAN: LazyLock<Mutex<Option<Arc<PixelBetaPlan>>>> = LazyLock::new(|| Mutex::new(None));

fn pixel_plan_for(opts: FitOptions) -> Result<Arc<PixelBetaPlan>, CoreError> {
    let mut slot = PIXEL_PLAN.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(p) = slot.as_ref()
        && *p.options() == opts
    {
        return Ok(Arc::clone(p));
    }
    let p = Arc::new(PixelBetaPlan::new(opts)?);
    *slot = Some(Arc::clone(&p));
    Ok(p)
}

fn single_dict<'py>(py: Python<'py>, f: &NkFit) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    set_fields!(d, f, n, k, n_se, k_se, nk_corr, rms_residual);
    set_fields!(d, f, cost, iterations, evaluations, starts);
    d.set_item("status", f.status.as_str())?;
    d.set_item("reason", f.reason)?;
    Ok(d)
}

/// Fit the complex index N = n + ik to DoLP measurements (paper section 5, eq. 16).
///
/// Minimises ``Σ_t w_t (P(n, k, β_t) - dolp_t)²`` (P: eq. 9; ``w_t = 1/dolp_se_t²``, or
/// 1) over the box ``n_range × k_range``: a global grid scan, Gauss–Newton /
/// Levenberg–Marquardt polish and a second basin check, exactly as ``polarid fit``
/// (same Rust code, same numbers).
///
/// Parameters
/// ----------
/// dolp : array_like, shape (T,) or (..., T)
///     DoLP values in [0, 1] measured at the T angles ``beta_deg``. 1-D: one target.
///     float32 stacks (``polarid.dolp``'s dtype) are read as they are (no float64 copy;
///     the same numbers as their float64 values), other dtypes converted to float64.
///     More dimensions: a stack of pixels (e.g. (P, T) or (H, W, T)), each fitted
///     independently in parallel with the GIL released.
/// beta_deg : array_like, shape (T,) or broadcastable to ``dolp.shape``
///     Local incidence angles β (eq. 5), degrees, in (0, 90); T >= 3. 1-D: one angle
///     per measurement, shared by every pixel (the far field). More dimensions: a β per
///     pixel and measurement (calibrated geometry: a lens and a lamp at a finite
///     distance give every pixel its own angles), broadcast to the shape of ``dolp``
///     (e.g. ``(H, W, T)`` for a ``(H, W, T)`` stack, or ``(1, W, T)`` for angles
///     that only vary along the columns). A pixel with an angle that is not finite or
///     outside (0, 90) gets status ``invalid_input``; one with fewer than 3 distinct
///     angles or a range below 3° ``ill_conditioned``.
/// dolp_se : array_like, optional
///     Standard errors of ``dolp`` (> 0), broadcastable to its shape. When given the
///     fit is weighted and the standard errors follow from them; otherwise they are
///     scaled by the residual (reduced χ²).
/// n_range, k_range : (float, float)
///     The search box, ``0 <= MIN < MAX`` (defaults: the CLI's ``--n-range 0.01,10
///     --k-range 0,15``).
/// status_strings : bool, default False
///     Stacks only: also return ``status`` as a str array (one word per pixel).
///
/// Returns
/// -------
/// dict
///     One target (1-D ``dolp``): floats ``n``, ``k``, ``n_se``, ``k_se``, ``nk_corr``,
///     ``rms_residual``, ``cost``; ints ``iterations``, ``evaluations``, ``starts``;
///     strings ``status`` (``ok``, ``not_converged``, ``ill_conditioned``,
///     ``at_bound``) and ``reason`` (empty when ok).
///
///     A stack (``dolp`` of shape (..., T)): arrays of shape ``dolp.shape[:-1]``:
///     ``n``, ``k``, ``n_se``, ``k_se``, ``nk_corr``, ``rms_residual``, ``cost``
///     (float64), ``iterations``, ``evaluations``, ``starts`` (uint32);
///     ``status_code`` (uint8) with ``status_names`` (list of str, equal to
///     ``polarid.FIT_STATUS``): the status of pixel i is
///     ``status_names[status_code[i]]`` (``status_code == FIT_STATUS.index("ok")``
///     selects the good fits); ``reason_code`` (uint8) with ``reasons`` (list of str,
///     ``reasons[0] == ""``): the reason of pixel i is ``reasons[reason_code[i]]``.
///     Codes rather than str arrays keep large stacks small and fast; with
///     ``status_strings=True`` the dict also holds ``status``, a str array of the
///     words. A pixel whose data are unusable (NaN, DoLP outside [0, 1], se <= 0)
///     gets status ``invalid_input`` and NaN values instead of an error.
///
/// Raises
/// ------
/// ValueError
///     Fewer than 3 angles, an angle outside (0, 90), a bad range, mismatched shapes;
///     for one target also unusable data (e.g. ``dolp = 1.2 is out of range (expected
///     [0, 1])``).
///
/// Notes
/// -----
/// The plan (grid of model curves) depends only on ``beta_deg`` and the box; the last
/// few are cached, so repeated calls with the same angles do not rebuild it.
///
/// With a β per pixel the grid scan that picks each pixel's basin reads model curves
/// at the angles rounded to 0.25° (cached per angle, so they serve every pixel), and
/// the Levenberg–Marquardt polish uses each pixel's exact angles
/// (``polarid_core::fit::fit_batch_pixel_beta``); the statuses and standard errors
/// follow the same rules. It runs at 40–60% of the speed of the shared-angle fit.
#[pyfunction]
#[pyo3(signature = (dolp, beta_deg, dolp_se = None, *, n_range = (0.01, 10.0), k_range = (0.0, 15.0), status_strings = false))]
pub fn fit_nk<'py>(
    py: Python<'py>,
    dolp: &Bound<'py, PyAny>,
    beta_deg: &Bound<'py, PyAny>,
    dolp_se: Option<&Bound<'py, PyAny>>,
    n_range: (f64, f64),
    k_range: (f64, f64),
    status_strings: bool,
) -> PyResult<Bound<'py, PyDict>> {
    check_range("n_range", n_range).py_err()?;
    check_range("k_range", k_range).py_err()?;
    let opts = FitConfig {
        n_range,
        k_range,
        ..FitConfig::default()
    }
    .fit_options();
    // float32 DoLP (the dtype of polarid.dolp) is read as it is and converted chunk by
    // chunk in the workers; every other dtype becomes one float64 array.
    let y = float_array("dolp", dolp)?;
    let shape = match &y {
        FloatArray::F32(a) => a.shape().to_vec(),
        FloatArray::F64(a) => a.shape().to_vec(),
    };
    let (betas, beta_full) = read_beta(beta_deg, &shape)?;
    let t = match &beta_full {
        Some(_) => shape.last().copied().unwrap_or(0),
        None => betas.len(),
    };
    if shape.last() != Some(&t) || (beta_full.is_some() && shape.len() < 2) {
        return Err(value_error(format!(
            "dolp of shape {} does not match beta_deg: its last axis must have {t} values (one per angle)",
            fmt_shape(&shape)
        )));
    }
    let se = dolp_se
        .map(|s| broadcast_f64("dolp_se", s, &shape))
        .transpose()?;
    let ys = match &y {
        FloatArray::F32(a) => Ys::F32(a.as_slice()?),
        FloatArray::F64(a) => Ys::F64(a.as_slice()?),
    };
    let ses = se.as_ref().map(|s| s.as_slice()).transpose()?;
    let lead = shape[..shape.len() - 1].to_vec();
    let pixels: usize = lead.iter().product();
    if let Some(bf) = &beta_full {
        if t < 3 {
            return Err(value_error(format!(
                "beta_deg needs at least 3 angles per pixel, got {t}"
            )));
        }
        let bs = bf.as_slice()?;
        let out = py
            .detach(|| {
                let plan = pixel_plan_for(opts)?;
                // β in radians chunk by chunk (no full-size copy of the angles).
                let fit = |y: &[f64], se: Option<&[f64]>, first: usize, out: &mut [NkFit]| {
                    let b: Vec<f64> = bs[first * t..(first + out.len()) * t]
                        .iter()
                        .map(|b| b.to_radians())
                        .collect();
                    fit_batch_pixel_beta(&plan, &b, y, se, out)
                };
                ys.batch(t, &fit, ses, pixels)
            })
            .py_err()?;
        return batch_dict(py, &lead, out, status_strings);
    }
    let plan = py.detach(|| plan_for(&betas, opts)).py_err()?;
    if shape.len() == 1 {
        let y1 = ys.to_f64();
        let f = py.detach(|| plan.fit(&y1, ses)).py_err()?;
        return single_dict(py, &f);
    }
    let fit =
        |y: &[f64], se: Option<&[f64]>, _: usize, out: &mut [NkFit]| fit_batch(&plan, y, se, out);
    let out = py.detach(|| ys.batch(t, &fit, ses, pixels)).py_err()?;
    batch_dict(py, &lead, out, status_strings)
}

/// `beta_deg` as the fit takes it: one angle per measurement (1-D, radians), or a β
/// per pixel broadcast to dolp's `shape` (degrees).
type Betas<'py> = (Vec<f64>, Option<PyReadonlyArrayDyn<'py, f64>>);

fn read_beta<'py>(beta_deg: &Bound<'py, PyAny>, shape: &[usize]) -> PyResult<Betas<'py>> {
    let np = beta_deg.py().import("numpy")?;
    let ndim: usize = np.call_method1("ndim", (beta_deg,))?.extract()?;
    if ndim > 1 {
        return Ok((
            Vec::new(),
            Some(broadcast_f64("beta_deg", beta_deg, shape)?),
        ));
    }
    let beta = f64_contiguous("beta_deg", beta_deg)?;
    if beta.ndim() != 1 {
        return Err(value_error(format!(
            "beta_deg must be 1-D (one angle per measurement) or broadcastable to dolp, got shape {}",
            fmt_shape(beta.shape())
        )));
    }
    Ok((
        beta.as_slice()?.iter().map(|b| b.to_radians()).collect(),
        None,
    ))
}

/// `obj` as float64 broadcast to dolp's `shape`, contiguous.
fn broadcast_f64<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
    shape: &[usize],
) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let np = obj.py().import("numpy")?;
    let a = np.call_method1("asarray", (obj, "float64"))?;
    let b = np
        .call_method1("broadcast_to", (&a, shape.to_vec()))
        .map_err(|_| {
            let s: Vec<usize> = a
                .getattr("shape")
                .and_then(|s| s.extract())
                .unwrap_or_default();
            value_error(format!(
                "{name} cannot be broadcast to the shape {} of dolp (its shape is {})",
                fmt_shape(shape),
                fmt_shape(&s)
            ))
        })?;
    f64_contiguous(name, &b)
}

/// Pixels per parallel task of [`batch`].
const CHUNK: usize = 1024;

/// The float64 columns of a batch fit, in the order of its dict.
const F64_COLUMNS: [&str; 7] = ["n", "k", "n_se", "k_se", "nk_corr", "rms_residual", "cost"];
/// The integer columns of a batch fit, in the order of its dict.
const U32_COLUMNS: [&str; 3] = ["iterations", "evaluations", "starts"];

/// The columns of a batch fit (struct of arrays).
struct BatchOut {
    /// [`F64_COLUMNS`].
    f64s: [Column<f64>; 7],
    /// [`U32_COLUMNS`].
    u32s: [Column<u32>; 3],
    status: Column<u8>,
    reason: Column<u8>,
    /// `reason` codes index this table; 0 is "".
    reasons: Vec<&'static str>,
}

/// One pixel's values of the [`F64_COLUMNS`] and [`U32_COLUMNS`].
fn columns_of(f: &NkFit) -> ([f64; 7], [u32; 3]) {
    let floats = [f.n, f.k, f.n_se, f.k_se, f.nk_corr, f.rms_residual, f.cost];
    (floats, [f.iterations, f.evaluations, f.starts])
}

/// A batch fit of `out.len()` pixels starting at pixel `first` of the stack, `y` (and
/// `se`) their rows: [`fit_batch`] or [`fit_batch_pixel_beta`].
/// The DoLP values of a stack as given: float64, or float32 converted chunk by chunk.
#[derive(Clone, Copy)]
enum Ys<'a> {
    F64(&'a [f64]),
    F32(&'a [f32]),
}

impl Ys<'_> {
    /// [`batch`] on these values.
    fn batch(
        self,
        t: usize,
        fit: &FitFn<'_>,
        ses: Option<&[f64]>,
        pixels: usize,
    ) -> Result<BatchOut, CoreError> {
        match self {
            Ys::F64(y) => batch(t, fit, y, ses, pixels),
            Ys::F32(y) => batch(t, fit, y, ses, pixels),
        }
    }

    /// The values as float64 (one target).
    fn to_f64(self) -> Vec<f64> {
        match self {
            Ys::F64(y) => y.to_vec(),
            Ys::F32(y) => y.iter().map(|&v| f64::from(v)).collect(),
        }
    }
}

/// A DoLP sample type that [`batch`] reads: float64 rows are used in place, float32
/// rows converted into a per-worker buffer (exact), so no full-size float64 copy of a
/// float32 stack is made.
trait DolpSample: Copy + Sync {
    /// `rows` as float64, in `buf` when a conversion is needed.
    fn as_f64<'a>(rows: &'a [Self], buf: &'a mut Vec<f64>) -> &'a [f64];
}

impl DolpSample for f64 {
    fn as_f64<'a>(rows: &'a [f64], _: &'a mut Vec<f64>) -> &'a [f64] {
        rows
    }
}

impl DolpSample for f32 {
    fn as_f64<'a>(rows: &'a [f32], buf: &'a mut Vec<f64>) -> &'a [f64] {
        buf.clear();
        buf.extend(rows.iter().map(|&v| f64::from(v)));
        buf
    }
}

type FitFn<'a> =
    dyn Fn(&[f64], Option<&[f64]>, usize, &mut [NkFit]) -> Result<(), CoreError> + Sync + 'a;

/// Fit `pixels` pixels of `t` measurements with `fit`, `CHUNK` at a time in parallel,
/// writing the results straight into the output columns (no per-pixel intermediate of
/// the whole stack: large stacks would otherwise spend their time in page faults).
///
/// The columns are fresh memory (numpy takes them over), so their first touch costs
/// page faults: [`column`] asks for transparent huge pages. Each chunk codes its
/// reasons in a table of its own (no lock shared by the workers); the tables are then
/// merged in pixel order, so `reasons` lists the reasons in the order of their first
/// pixel whatever the scheduling.
fn batch<Y: DolpSample>(
    t: usize,
    fit: &FitFn<'_>,
    ys: &[Y],
    ses: Option<&[f64]>,
    pixels: usize,
) -> Result<BatchOut, CoreError> {
    use rayon::prelude::*;
    if ys.len() != pixels * t {
        return Err(CoreError::LengthMismatch {
            name: "dolp",
            expected: pixels * t,
            got: ys.len(),
        });
    }
    let mut o = BatchOut {
        f64s: std::array::from_fn(|_| Column::new(pixels)),
        u32s: std::array::from_fn(|_| Column::new(pixels)),
        status: Column::new(pixels),
        reason: Column::new(pixels),
        reasons: Vec::new(),
    };
    let c = CHUNK;
    // Every column cut into chunks of `c` pixels, gathered per chunk.
    let mut f64s = o.f64s.each_mut().map(|v| v.as_mut_slice().chunks_mut(c));
    let mut u32s = o.u32s.each_mut().map(|v| v.as_mut_slice().chunks_mut(c));
    let status = o.status.as_mut_slice().chunks_mut(c);
    let reason = o.reason.as_mut_slice().chunks_mut(c);
    // ok (`next()`): every column has as many chunks as `status`.
    let chunks: Vec<_> = status
        .zip(reason)
        .map(|(st, rc)| {
            let f: [&mut [f64]; 7] = std::array::from_fn(|j| f64s[j].next().unwrap());
            let u: [&mut [u32]; 3] = std::array::from_fn(|j| u32s[j].next().unwrap());
            (f, u, st, rc)
        })
        .collect();
    // Per chunk: its reasons; local code i + 1 is `table[i]` (0 is "").
    let tables: Vec<Vec<&'static str>> = chunks
        .into_par_iter()
        .enumerate()
        .map_init(
            || (vec![NkFit::default(); c], Vec::new()),
            |(buf, ybuf), (i, (mut fc, mut uc, code, rc))| {
                let len = code.len();
                let y = Y::as_f64(&ys[i * c * t..(i * c + len) * t], ybuf);
                let se = ses.map(|s| &s[i * c * t..(i * c + len) * t]);
                let buf = &mut buf[..len];
                fit(y, se, i * c, buf)?;
                let mut table: Vec<&'static str> = Vec::new();
                // The last reason seen and its code (runs of one reason are common).
                let mut last: (&'static str, u8) = ("", 0);
                for (j, f) in buf.iter().enumerate() {
                    let (floats, ints) = columns_of(f);
                    for (col, v) in fc.iter_mut().zip(floats) {
                        col[j] = v;
                    }
                    for (col, v) in uc.iter_mut().zip(ints) {
                        col[j] = v;
                    }
                    code[j] = f.status.code();
                    rc[j] = if f.reason.is_empty() {
                        0
                    } else if std::ptr::eq(f.reason, last.0) {
                        last.1
                    } else {
                        let r = match table.iter().position(|x| *x == f.reason) {
                            Some(p) => p as u8 + 1,
                            None if table.len() < 255 => {
                                table.push(f.reason);
                                table.len() as u8
                            }
                            None => 0,
                        };
                        last = (f.reason, r);
                        r
                    };
                }
                Ok(table)
            },
        )
        .collect::<Result<_, CoreError>>()?;
    // Merge the chunk tables in pixel order; recode the chunks whose codes differ.
    let mut reasons: Vec<&'static str> = vec![""];
    let mut map: Vec<u8> = Vec::new();
    for (table, rc) in tables.iter().zip(o.reason.as_mut_slice().chunks_mut(c)) {
        map.clear();
        map.push(0);
        for r in table {
            let g = match reasons.iter().position(|x| x == r) {
                Some(p) => p as u8,
                None if reasons.len() < 255 => {
                    reasons.push(r);
                    (reasons.len() - 1) as u8
                }
                None => 0,
            };
            map.push(g);
        }
        if map.iter().enumerate().any(|(i, &g)| usize::from(g) != i) {
            for x in rc.iter_mut() {
                *x = map[usize::from(*x)];
            }
        }
    }
    o.reasons = reasons;
    Ok(o)
}

/// Size of a transparent huge page (x86-64, aarch64 with 4 KiB pages).
const HUGE_PAGE: usize = 2 << 20;

/// A zeroed output column of `len` values: `vec[off..off + len]`.
///
/// The column is fresh memory (numpy takes it over), so the workers' first writes
/// cost page faults. A column of at least one huge page starts at a 2 MiB boundary
/// inside a slightly larger zeroed allocation (fresh, untouched memory) and its whole
/// 2 MiB pages are asked to be backed by transparent huge pages
/// (`madvise(MADV_HUGEPAGE)`, before any write): one page fault per 2 MiB rather than
/// per 4 KiB. Only a hint: where the kernel declines (THP disabled, no huge page free)
/// or elsewhere than Linux nothing changes but the alignment. numpy receives the
/// column as an array over `vec` at offset `off` (no copy).
struct Column<T> {
    vec: Vec<T>,
    off: usize,
    len: usize,
}

impl<T: Clone + Default> Column<T> {
    fn new(len: usize) -> Self {
        let size = std::mem::size_of::<T>().max(1);
        let bytes = len * size;
        if !cfg!(target_os = "linux") || bytes < HUGE_PAGE || !HUGE_PAGE.is_multiple_of(size) {
            return Self {
                vec: vec![T::default(); len],
                off: 0,
                len,
            };
        }
        let vec = vec![T::default(); len + HUGE_PAGE / size];
        let start = vec.as_ptr() as usize;
        let a = start.next_multiple_of(HUGE_PAGE);
        if !(a - start).is_multiple_of(size) {
            return Self { vec, off: 0, len };
        }
        let off = (a - start) / size;
        // [a, a + whole pages) lies inside the allocation: a - start < HUGE_PAGE.
        advise_huge_pages(a, bytes / HUGE_PAGE * HUGE_PAGE);
        Self { vec, off, len }
    }

    fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.vec[self.off..self.off + self.len]
    }
}

impl<T> Column<T> {
    /// The column as an array of shape `lead` (no copy).
    fn into_array(self, lead: &[usize]) -> Result<ArrayD<T>, ndarray::ShapeError> {
        let (off, len) = (self.off, self.len);
        ndarray::Array1::from(self.vec)
            .slice_move(ndarray::s![off..off + len])
            .into_shape_with_order(IxDyn(lead))
    }
}

/// `madvise(addr, len, MADV_HUGEPAGE)`, its result ignored (a hint).
#[cfg(target_os = "linux")]
fn advise_huge_pages(addr: usize, len: usize) {
    // SAFETY: the callers pass a range inside one live allocation; MADV_HUGEPAGE
    // changes no contents and no mapping, only how later page faults are served.
    unsafe {
        libc::madvise(addr as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_: usize, _: usize) {}

/// The dict of a stack fit: numeric arrays, the status as codes with their name table
/// (``status_code``, ``status_names``) and, when `status_strings`, also a str array
/// ``status`` (numpy ``<U`` array: costs 60 bytes per pixel).
fn batch_dict<'py>(
    py: Python<'py>,
    lead: &[usize],
    o: BatchOut,
    status_strings: bool,
) -> PyResult<Bound<'py, PyDict>> {
    fn arr<'py, T: numpy::Element>(
        py: Python<'py>,
        lead: &[usize],
        v: Column<T>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let a = v.into_array(lead).map_err(|e| value_error(e.to_string()))?;
        Ok(to_numpy(py, a))
    }
    let d = PyDict::new(py);
    for (name, v) in F64_COLUMNS.iter().zip(o.f64s) {
        d.set_item(*name, arr(py, lead, v)?)?;
    }
    for (name, v) in U32_COLUMNS.iter().zip(o.u32s) {
        d.set_item(*name, arr(py, lead, v)?)?;
    }
    let codes = arr(py, lead, o.status)?;
    let words: Vec<&str> = FitStatus::ALL.iter().map(|s| s.as_str()).collect();
    if status_strings {
        let names = py
            .import("numpy")?
            .call_method1("array", (words.clone(),))?;
        d.set_item("status", names.call_method1("take", (&codes,))?)?;
    }
    d.set_item("status_code", codes)?;
    d.set_item("status_names", words)?;
    d.set_item("reason_code", arr(py, lead, o.reason)?)?;
    d.set_item("reasons", o.reasons)?;
    Ok(d)
}

/// `shadowing` of `fit_table` and `fit_mixed`: `"none"` or `"smith"`.
pub(crate) fn shadowing_arg(name: &str) -> PyResult<Shadowing> {
    parse_shadowing(name).ok_or_else(|| {
        value_error(format!(
            "shadowing must be \"none\" or \"smith\", got {name:?}"
        ))
    })
}

/// Fit every target of a measurements CSV — the table-level form of ``polarid fit``
/// (same Rust function, ``polarid_pipeline::fit``: same rows, statuses and numbers).
///
/// Rows are grouped by ``target`` (targets keep the order of their first row); each
/// target needs at least 3 rows. ``reflectance="auto"`` (the default, as ``polarid
/// fit``) is the specular fit followed by the brightness check when the rows carry
/// ``s0`` and ``exposure``; ``"specular"`` is the paper's DoLP-only fit (eq. 16) with the
/// ``depolarized`` rule and nothing else; ``"mixed"`` the specular + Lambertian diffuse
/// radiometric fit with BIC model selection (needs ``s0``).
///
/// Parameters
/// ----------
/// measurements : str or os.PathLike
///     A measurements CSV (written by ``polarid measure``).
/// reflectance : {"auto", "specular", "mixed"}
/// n_range, k_range : (float, float)
///     The search box, ``0 <= MIN < MAX`` (``--n-range``, ``--k-range``).
/// depolarized_dolp : float
///     Specular fit: status ``depolarized`` when the DoLP stays below this at every
///     source position (in (0, 1], default 0.02).
/// estimate_theta_r : bool
///     Mixed fit: estimate the camera zenith (in-plane captures only).
/// shadowing : {"none", "smith"}
///     Mixed fit: shadowing factor of the specular term.
/// s0_rel_sd : float
///     Mixed fit: relative standard deviation of ``s0``, in (0, 1].
/// sigma_range : (float, float)
///     Mixed fit: search range of the roughness sigma.
/// angle_sd_deg : float
///     Specular fit: standard uncertainty of the source and camera directions, degrees,
///     in [0, 90), for rows without an ``angle_sd_deg`` column (``--angle-sd-deg``,
///     default 0.2; docs/ERRORS.md).
/// dolp_floor : float
///     Specular fit: additive DoLP error (standard deviation, independent per row), in
///     [0, 1) (``--dolp-floor``, default 0.002).
/// extinction_ratio : float
///     Specular fit: the lowest extinction ratio the analyzer may have, > 1
///     (``--extinction-ratio``, default 100; ``math.inf``: an ideal polarizer). The DoLP
///     scale's standard uncertainty is ``2/(ER + 1)``.
/// retardance_deg : float
///     Specular fit: the largest retardance ahead of the analyzer, degrees, in [0, 90]
///     (``--retardance-deg``, default 0).
/// mismatch_p : float
///     Specular fit: status ``model_mismatch`` when the goodness-of-fit or the AoLP test
///     has a p-value below this, in [0, 1) (``--mismatch-p``, default 0.001; 0: never).
///     ``angle_sd_deg=0, dolp_floor=0, extinction_ratio=math.inf`` gives the noise-only
///     standard errors (also in the ``*_noise`` columns).
/// film_sd_nm : float or None
///     Specular fit: standard thickness of an unmodelled surface layer (native oxide),
///     nm (``--film-sd-nm``; None: the default, 3 nm; 0: clean surfaces).
/// strict : bool
///     Raise at the first problem (a measurement row whose ``status`` is not ok, a
///     target that cannot be fitted), as ``polarid fit --strict``. By default such rows
///     are skipped and such a target gets status ``invalid_input`` with the reason.
///
/// Returns
/// -------
/// dict
///     The columns of ``polarid fit``'s CSV, in its order, as lists with one element per
///     target (one per target per band for multi-band measurements): ``target`` (str),
///     ``class`` (str or None), ``wavelength_nm`` (float; only when the measurements
///     have bands, docs/BANDS.md), ``n``, ``k``, ``n_se``,
///     ``k_se``, ``nk_corr``, ``rms_residual`` (float, NaN when unknown),
///     ``measurements`` (int), ``status`` (a word of ``polarid.FIT_STATUS``), ``reason``
///     (str, empty when ok), ``model`` (``specular`` or ``mixed``), ``sigma``, ``rho_d``,
///     ``theta_r_deg`` (float or None: mixed fit only; ``theta_r_deg`` when estimated).
///
/// Raises
/// ------
/// ValueError
///     A bad option, a bad file (the message of ``polarid fit``, naming the file, target
///     and lines).
/// FileNotFoundError
///     The file does not exist.
#[pyfunction]
#[pyo3(signature = (measurements, *, reflectance = "auto", n_range = (0.01, 10.0), k_range = (0.0, 15.0), depolarized_dolp = 0.02, estimate_theta_r = false, shadowing = "none", s0_rel_sd = 0.02, sigma_range = (0.02, 1.0), angle_sd_deg = 0.2, dolp_floor = 0.002, extinction_ratio = 100.0, retardance_deg = 0.0, mismatch_p = 0.001, film_sd_nm = None, strict = false))]
#[allow(clippy::too_many_arguments)]
pub fn fit_table<'py>(
    py: Python<'py>,
    measurements: PathBuf,
    reflectance: &str,
    n_range: (f64, f64),
    k_range: (f64, f64),
    depolarized_dolp: f64,
    estimate_theta_r: bool,
    shadowing: &str,
    s0_rel_sd: f64,
    sigma_range: (f64, f64),
    angle_sd_deg: f64,
    dolp_floor: f64,
    extinction_ratio: f64,
    retardance_deg: f64,
    mismatch_p: f64,
    film_sd_nm: Option<f64>,
    strict: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = FitConfig {
        reflectance: Reflectance::parse(reflectance).ok_or_else(|| {
            value_error(format!(
                "reflectance must be \"auto\", \"specular\" or \"mixed\", got {reflectance:?}"
            ))
        })?,
        n_range,
        k_range,
        depolarized_dolp,
        estimate_theta_r,
        shadowing: shadowing_arg(shadowing)?,
        s0_rel_sd,
        sigma_range,
        angle_sd_deg,
        dolp_floor,
        extinction_ratio,
        retardance_deg,
        mismatch_p,
        film_sd_nm: film_sd_nm.unwrap_or(polarid_pipeline::fit::DEFAULT_FILM_SD_NM),
        strict,
        ..FitConfig::default()
    };
    cfg.validate().py_err()?;
    let out = py
        .detach(|| {
            let rows = read_measurements(&measurements)?;
            polarid_pipeline::fit::fit(
                &measurements,
                &rows,
                &cfg,
                &polarid_pipeline::progress::no_progress,
            )
        })
        .py_err()?;
    let rows: Vec<_> = out.targets.iter().map(|t| &t.row).collect();
    let d = PyDict::new(py);
    macro_rules! col {
        ($name:literal, $f:expr) => {
            d.set_item($name, PyList::new(py, rows.iter().map($f))?)?;
        };
    }
    col!("target", |r| r.target.clone());
    col!("class", |r| r.class.clone());
    if rows.iter().any(|r| r.wavelength_nm.is_some()) {
        col!("wavelength_nm", |r| r.wavelength_nm);
    }
    col!("n", |r| r.n);
    col!("k", |r| r.k);
    col!("n_se", |r| r.n_se);
    col!("k_se", |r| r.k_se);
    col!("nk_corr", |r| r.nk_corr);
    col!("rms_residual", |r| r.rms_residual);
    col!("measurements", |r| r.measurements);
    col!("status", |r| r.status.as_str());
    col!("reason", |r| r.reason.clone());
    col!("model", |r| r.model.clone());
    col!("sigma", |r| r.sigma);
    col!("rho_d", |r| r.rho_d);
    col!("theta_r_deg", |r| r.theta_r_deg);
    col!("n_se_noise", |r| r.n_se_noise);
    col!("k_se_noise", |r| r.k_se_noise);
    col!("nk_corr_noise", |r| r.nk_corr_noise);
    col!("gof_p", |r| r.gof_p);
    col!("aolp_p", |r| r.aolp_p);
    col!("n_se_sample", |r| r.n_se_sample);
    col!("k_se_sample", |r| r.k_se_sample);
    col!("nk_corr_sample", |r| r.nk_corr_sample);
    if rows.iter().any(|r| r.film.is_some()) {
        for (j, name) in polarid_io::table::fits::FILM_COLUMNS.iter().enumerate() {
            let cells = rows.iter().map(|r| r.film.map(|h| h.0[j / 2][j % 2]));
            d.set_item(*name, PyList::new(py, cells)?)?;
        }
    }
    Ok(d)
}
