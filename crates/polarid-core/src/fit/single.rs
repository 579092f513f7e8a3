//! Fitting one target: [`FitPlan::fit`], [`FitPlan::fit_with`] (caller-owned scratch)
//! and the one-call convenience [`fit_nk`]. A single fit is a chunk of one pixel
//! (`chunk.rs`), so it gives the same result as the same pixel in a batch.

use super::validate::check_pixel;
use super::{FitPlan, FitWorkspace, NkFit};
use crate::error::{Result, check_len};

impl FitPlan {
    /// Fit one target (allocates a workspace; see [`FitPlan::fit_with`]).
    pub fn fit(&self, dolp: &[f64], dolp_se: Option<&[f64]>) -> Result<NkFit> {
        let mut ws = self.workspace();
        self.fit_with(dolp, dolp_se, &mut ws)
    }

    /// Fit one target with caller-owned scratch memory.
    ///
    /// `dolp[t]` is measured at `betas[t]`; `dolp_se[t]`, when given, is its standard
    /// error (weights `1/se²`). Errors: wrong lengths, non-finite values, DoLP outside
    /// `[0, 1]`, standard errors that are not positive.
    pub fn fit_with(
        &self,
        dolp: &[f64],
        dolp_se: Option<&[f64]>,
        ws: &mut FitWorkspace,
    ) -> Result<NkFit> {
        let t_len = self.len();
        check_len("dolp", dolp.len(), t_len)?;
        if let Some(se) = dolp_se {
            check_len("dolp_se", se.len(), t_len)?;
        }
        check_pixel(dolp, dolp_se)?;
        let mut out = [NkFit::default()];
        self.fit_chunk(dolp, dolp_se, &mut out, ws);
        Ok(out[0])
    }
}

/// Fit one target with the default options: convenience over
/// [`FitPlan::with_defaults`] + [`FitPlan::fit`] (builds the grid: for many targets
/// with the same β set, build the plan once).
pub fn fit_nk(betas: &[f64], dolp: &[f64], dolp_se: Option<&[f64]>) -> Result<NkFit> {
    check_len("dolp", dolp.len(), betas.len())?;
    FitPlan::with_defaults(betas)?.fit(dolp, dolp_se)
}
