//! Fitting a batch of pixels in parallel: [`fit_batch`] cuts the batch into chunks of
//! 1024 pixels, each run by the chunk driver (`chunk.rs`) with one workspace per rayon
//! worker.

use rayon::prelude::*;

use super::{FitPlan, NkFit};
use crate::error::{Result, check_len};

/// Fit every pixel of a batch in parallel (rayon).
///
/// `dolp` holds `pixels × T` values, row-major (pixel `p`'s measurements at
/// `dolp[p*T .. (p+1)*T]`, in the plan's β order); `dolp_se`, when given, has the same
/// layout; `out` receives one [`NkFit`] per pixel. Pixels with unusable data get the
/// status [`FitStatus::InvalidInput`](super::FitStatus::InvalidInput) (and NaN values)
/// rather than failing the batch.
/// Errors: inconsistent lengths.
pub fn fit_batch(
    plan: &FitPlan,
    dolp: &[f64],
    dolp_se: Option<&[f64]>,
    out: &mut [NkFit],
) -> Result<()> {
    let t_len = plan.len();
    check_len("dolp", dolp.len(), out.len() * t_len)?;
    if let Some(se) = dolp_se {
        check_len("dolp_se", se.len(), dolp.len())?;
    }
    const CHUNK: usize = 1024;
    match dolp_se {
        None => out
            .par_chunks_mut(CHUNK)
            .zip(dolp.par_chunks(CHUNK * t_len))
            .for_each_init(
                || plan.workspace(),
                |ws, (o, y)| plan.fit_chunk(y, None, o, ws),
            ),
        Some(se) => out
            .par_chunks_mut(CHUNK)
            .zip(dolp.par_chunks(CHUNK * t_len))
            .zip(se.par_chunks(CHUNK * t_len))
            .for_each_init(
                || plan.workspace(),
                |ws, ((o, y), s)| plan.fit_chunk(y, Some(s), o, ws),
            ),
    }
    Ok(())
}
