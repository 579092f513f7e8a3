//! Fitting with a β per pixel: every pixel of a batch has its own local incidence
//! angle at every source position (calibrated geometry: a real lens and a lamp at a
//! finite distance give every pixel of a capture its own β, eq. 5), so no [`FitPlan`]
//! (one β set) can serve the batch.
//!
//! # Method
//! The steps and rules of the shared-β fit (module documentation of [`crate::fit`]),
//! with two changes:
//!
//! 1. **Scan and starts from quantised columns.** The grid scan only has to pick the
//!    basin, so it does not need the exact angles: the node curves of a pixel are read,
//!    one source position at a time, from *columns*: the DoLP and Jacobian of every
//!    grid node at a quantised angle `β_q = q·Δ` (`Δ` = [`BETA_QUANTUM_DEG`] = 0.25° by
//!    default). Rounding β by at most `Δ/2` moves the DoLP by `|∂P/∂β|·Δ/2`: at most
//!    0.007 for `n ≥ 1.2` or `k ≥ 0.5` at β in 10–80° (more only near the critical
//!    angle of `n < 1`, `k ≈ 0`). A column depends on one angle, not on the β set, so
//!    the cache holds a few hundred columns at most for a whole map (one per `Δ` of the
//!    angles it contains, 16 kB each at the default grid), built once (~30 µs each) and
//!    reused by every pixel and capture; a cache keyed by the quantised *set* of `T`
//!    angles would need a new plan (the whole grid at `T` angles, ~0.3 ms, the time of
//!    ~300 fits) every few pixels, as the angles of different captures change in
//!    different directions across the image. The scan is [`Scan::scan_rows`] (the
//!    weighted scan with rows gathered from the columns, unit weights when unweighted),
//!    then the grid refinement and the stored-Jacobian Gauss–Newton start with the
//!    columns' Jacobians.
//! 2. **Polish with the exact angles.** The Levenberg–Marquardt polish
//!    (`engine.rs`) loads each pixel's own β terms into its lane when the lane takes
//!    the pixel's job, lane-major like the measurements, and evaluates eq. (9) at the
//!    pixel's exact angles. The covariance and the status follow the same rules, with
//!    the ill-conditioning test (fewer than 3 distinct β, or a span below
//!    [`MIN_BETA_SPAN`](super::MIN_BETA_SPAN)) made per pixel.
//!
//! A pixel's result does not depend on the batch it is in, with one exception: a
//! batch in which every pixel has the same angles (bit for bit) is fitted with the
//! [`FitPlan`] of those angles, so it gives exactly the results of [`fit_batch`]
//! (a start from the exact grid; otherwise the same minimum to the polish's
//! tolerance).
//!
//! Throughput (`examples/pixel_beta_throughput.rs`, T = 10, angles drifting by ±5°
//! across the image, one thread of a busy 2-core machine): ~1.7–2.2 µs of CPU per fit
//! against ~0.8–1.0 µs for the shared-β fit, i.e. 40–60% of its throughput, with 6.3
//! model evaluations per fit instead of 5.9. The difference is the scan (no curve read
//! serves four pixels, as it does with one β set), the cache misses of gathering each
//! pixel's node from `T` columns, and the sines and cosines of every pixel's angles.
//! A quantum of 0.1° gives 6.2 evaluations but 2.5× the columns and more cache
//! misses (slower); 0.5° gives 6.4.
//!
//! [`Scan::scan_rows`]: super::scan::Scan

mod chunk;
mod columns;

use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use super::grid::Grid;
use super::plan::check_beta;
use super::{FitOptions, FitPlan, NkFit, fit_batch};
use crate::error::{CoreError, Result, check_len};
use chunk::PixelWorkspace;
use columns::{ColumnCache, ColumnView};

/// Default quantum of the angles of the per-pixel fit's scan columns, degrees.
pub const BETA_QUANTUM_DEG: f64 = 0.25;

/// Pixels per parallel task.
const CHUNK: usize = 1024;

/// The grid and column cache of fits with a β per pixel: built once per set of options,
/// shared (`Sync`) by every batch, whatever its angles and its number of source
/// positions. See the module documentation.
#[derive(Debug)]
pub struct PixelBetaPlan {
    grid: Grid,
    /// The quantum of the columns' angles, radians.
    quantum: f64,
    cache: ColumnCache,
    /// The plan of the last batch whose pixels all had the same angles.
    shared: Mutex<Option<Arc<FitPlan>>>,
}

impl PixelBetaPlan {
    /// A plan with options `opts` (the box, grid and solver settings of
    /// [`FitOptions`]) and the default quantum [`BETA_QUANTUM_DEG`].
    ///
    /// Errors: invalid options (as [`FitPlan::new`]).
    pub fn new(opts: FitOptions) -> Result<Self> {
        Ok(Self {
            grid: Grid::new(opts)?,
            quantum: BETA_QUANTUM_DEG.to_radians(),
            cache: ColumnCache::default(),
            shared: Mutex::new(None),
        })
    }

    /// A plan with the default options.
    pub fn with_defaults() -> Result<Self> {
        Self::new(FitOptions::default())
    }

    /// The same plan with the scan columns' angles quantised to `deg` degrees (finite,
    /// in `[0.01, 1]`): finer costs more columns (memory, build time), coarser gives
    /// worse starts. Errors: `deg` out of range.
    pub fn with_beta_quantum_deg(mut self, deg: f64) -> Result<Self> {
        crate::error::ensure_range("beta quantum (degrees)", deg, 0.01, 1.0, "[0.01, 1]")?;
        self.quantum = deg.to_radians();
        self.cache = ColumnCache::default();
        Ok(self)
    }

    /// The quantum of the scan columns' angles, degrees.
    pub fn beta_quantum_deg(&self) -> f64 {
        self.quantum.to_degrees()
    }

    /// The options.
    pub fn options(&self) -> &FitOptions {
        &self.grid.opts
    }

    /// Number of columns in the cache.
    pub fn cached_columns(&self) -> usize {
        self.cache.len()
    }

    /// The column of angle `beta` (radians, in `(0, π/2)`).
    #[inline]
    fn column_index(&self, beta: f64) -> usize {
        (beta / self.quantum).round() as usize
    }

    /// Number of column indices (angles in `(0, π/2)`).
    fn column_count(&self) -> usize {
        self.column_index(std::f64::consts::FRAC_PI_2) + 1
    }

    /// The columns of every valid angle of `betas`.
    fn view(&self, betas: &[f64]) -> ColumnView {
        let mut needed = vec![false; self.column_count()];
        for &b in betas {
            if check_beta(b).is_ok()
                && let Some(n) = needed.get_mut(self.column_index(b))
            {
                *n = true;
            }
        }
        let q = self.quantum;
        self.cache.view(&self.grid, &needed, |i| i as f64 * q)
    }

    /// The [`FitPlan`] of `betas` (cached: the last one).
    fn shared_plan(&self, betas: &[f64]) -> Result<Arc<FitPlan>> {
        let mut slot = self.shared.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = slot.as_ref()
            && p.betas().len() == betas.len()
            && p.betas()
                .iter()
                .zip(betas)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        {
            return Ok(Arc::clone(p));
        }
        let p = Arc::new(FitPlan::new(betas, self.grid.opts)?);
        *slot = Some(Arc::clone(&p));
        Ok(p)
    }

    /// Fit one target (`T` angles and measurements; see [`fit_batch_pixel_beta`]).
    /// Errors: wrong lengths, fewer than 3 measurements, unusable data.
    pub fn fit(&self, betas: &[f64], dolp: &[f64], dolp_se: Option<&[f64]>) -> Result<NkFit> {
        super::validate::check_pixel(dolp, dolp_se)?;
        for &b in betas {
            check_beta(b)?;
        }
        let mut out = [NkFit::default()];
        fit_batch_pixel_beta(self, betas, dolp, dolp_se, &mut out)?;
        Ok(out[0])
    }

    /// [`fit_batch_pixel_beta`] with the instruction set `isa`, one thread, one chunk
    /// (tests compare them), without the shortcut for equal angles.
    #[cfg(test)]
    fn fit_isa(
        &self,
        isa: crate::cpu::Isa,
        betas: &[f64],
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
    ) {
        let view = self.view(betas);
        let mut ws = PixelWorkspace::default();
        self.fit_chunk_isa(isa, &view, betas, y, se, out, &mut ws);
    }
}

/// Fit every pixel of a batch in parallel (rayon), each at its own angles.
///
/// `betas`, `dolp` (and `dolp_se`, when given) hold `pixels × T` values, row-major
/// (pixel `p`'s at `[p*T .. (p+1)*T]`; `T = dolp.len() / out.len()`, at least 3):
/// `dolp[p*T + t]` was measured at the local incidence angle `betas[p*T + t]`
/// (radians). `out` receives one [`NkFit`] per pixel, with the options, statuses and
/// covariance rules of [`fit_batch`]; a pixel with unusable data (DoLP outside
/// `[0, 1]`, a standard error that is not positive, an angle outside `(0, π/2)`) gets
/// the status [`FitStatus::InvalidInput`](super::FitStatus::InvalidInput), one with
/// fewer than 3 distinct angles or a span below [`MIN_BETA_SPAN`](super::MIN_BETA_SPAN)
/// [`FitStatus::IllConditioned`](super::FitStatus::IllConditioned). See the module
/// documentation for the method.
///
/// Errors: inconsistent lengths, fewer than 3 measurements per pixel.
pub fn fit_batch_pixel_beta(
    plan: &PixelBetaPlan,
    betas: &[f64],
    dolp: &[f64],
    dolp_se: Option<&[f64]>,
    out: &mut [NkFit],
) -> Result<()> {
    if out.is_empty() {
        check_len("dolp", dolp.len(), 0)?;
        return check_len("betas", betas.len(), 0);
    }
    let t_len = dolp.len() / out.len();
    if dolp.len() != out.len() * t_len || t_len == 0 {
        return Err(CoreError::LengthMismatch {
            name: "dolp",
            expected: out.len() * t_len.max(3),
            got: dolp.len(),
        });
    }
    if t_len < 3 {
        return Err(CoreError::TooFew {
            what: "DoLP measurements (source positions)",
            needed: 3,
            got: t_len,
        });
    }
    for (name, len) in [
        ("betas", Some(betas.len())),
        ("dolp_se", dolp_se.map(<[f64]>::len)),
    ] {
        if let Some(len) = len {
            check_len(name, len, dolp.len())?;
        }
    }
    // Every pixel at the same angles: the shared-β fit of those angles.
    let first = &betas[..t_len];
    if betas
        .chunks_exact(t_len)
        .all(|r| r.iter().zip(first).all(|(a, b)| a.to_bits() == b.to_bits()))
        && let Ok(shared) = plan.shared_plan(first)
    {
        return fit_batch(&shared, dolp, dolp_se, out);
    }
    let view = plan.view(betas);
    let rows = CHUNK * t_len;
    match dolp_se {
        None => out
            .par_chunks_mut(CHUNK)
            .zip(dolp.par_chunks(rows))
            .zip(betas.par_chunks(rows))
            .for_each_init(PixelWorkspace::default, |ws, ((o, y), b)| {
                plan.fit_chunk(&view, b, y, None, o, ws)
            }),
        Some(se) => out
            .par_chunks_mut(CHUNK)
            .zip(dolp.par_chunks(rows))
            .zip(betas.par_chunks(rows))
            .zip(se.par_chunks(rows))
            .for_each_init(PixelWorkspace::default, |ws, (((o, y), b), s)| {
                plan.fit_chunk(&view, b, y, Some(s), o, ws)
            }),
    }
    Ok(())
}

#[cfg(test)]
mod tests;
