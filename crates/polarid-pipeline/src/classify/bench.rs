//! Trained models compared with estimates from the same bench (docs/CLASSIFY.md
//! "Trained models: the same bench", `polarid_core::classify::Bench`): the estimate on
//! its noise covariance, each prototype on its sample covariance (its noise and the
//! surface layer's variation between plates of its material),
//!
//! ```text
//! d_M² = Δᵀ (Σ_est,noise + Σ_proto,sample)⁻¹ Δ
//! ```
//!
//! instead of both sides' total covariance (`--bench other`), which counts the bench's
//! shared errors (angles, DoLP floor, extinction, the layer's unknown mean) twice.

use polarid_core::classify::{Bench, Estimate, EstimateBand, MultiEstimate, MultiPrototype};
use std::path::Path;

use polarid_io::model::Model;
use polarid_io::table::fits::FitRow;

use super::{PrototypeSource, estimate_of};
use crate::{Result, Warning};
use polarid_core::classify::Cov2;

/// The sample covariance of a fit row (`n_se_sample`, `k_se_sample`, `nk_corr_sample`:
/// the noise and the surface layer's variation between plates), when it has a usable one.
pub fn sample_cov(f: &FitRow) -> Option<Cov2> {
    let corr = f.nk_corr_sample.filter(|c| !c.is_nan()).unwrap_or(0.0);
    Cov2::from_se(f.n_se_sample?, f.k_se_sample?, corr)
}

/// The noise covariance of a fit row (`n_se_noise`, `k_se_noise`, `nk_corr_noise`), when
/// it has a usable one.
pub fn noise_cov(f: &FitRow) -> Option<Cov2> {
    let corr = f.nk_corr_noise.filter(|c| !c.is_nan()).unwrap_or(0.0);
    Cov2::from_se(f.n_se_noise?, f.k_se_noise?, corr)
}

/// How the estimates are compared with the prototypes: `same` when a model's prototypes
/// carry their sample covariance and the estimates are taken on their noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Comparison {
    /// The bench asked for.
    pub bench: Bench,
    /// The same-bench comparison is in force (a model with sample covariances, `Same`).
    pub same: bool,
}

/// The estimate of fit row `f` for `cmp`: on the same bench its noise covariance
/// (`n_se_noise`, `k_se_noise`, `nk_corr_noise`; the total when the row has none), else
/// [`estimate_of`].
pub fn estimate_for(f: &FitRow, cmp: Comparison) -> Estimate {
    let mut e = estimate_of(f);
    if cmp.same
        && let Some(c) = noise_cov(f)
    {
        e.cov = Some(c);
    }
    e
}

/// The estimate of a target's fit rows for `cmp` (see [`estimate_for`]); on the same
/// bench without the layer shifts (the noise has no layer part).
pub fn multi_estimate_for<'a>(
    rows: impl IntoIterator<Item = &'a FitRow>,
    cmp: Comparison,
) -> MultiEstimate {
    MultiEstimate {
        bands: rows
            .into_iter()
            .map(|f| {
                let same = cmp.same && noise_cov(f).is_some();
                EstimateBand {
                    wavelength_nm: f.wavelength_nm,
                    estimate: estimate_for(f, cmp),
                    film: if same { None } else { f.film },
                }
            })
            .collect(),
    }
}

/// A model's prototypes and the comparison `polarid classify --model` makes by default
/// (`--bench same`): the prototypes on their sample covariances and the estimates on
/// their noise when the model has sample covariances, else both on their totals.
pub fn same_bench(model: &Model) -> (Vec<MultiPrototype>, Comparison) {
    let same = model.has_sample_covariances();
    let bench = if same { Bench::Same } else { Bench::Other };
    let cmp = Comparison {
        bench: Bench::Same,
        same,
    };
    (model.multi_prototypes_on(bench), cmp)
}

/// The warning when the same bench is asked for a model at `path` without sample
/// covariances (it is then compared as a model from another bench).
pub(crate) fn no_sample_covariances(path: &Path) -> Warning {
    Warning(format!(
        "model {} has no sample covariances (trained on fits without n_se_sample, \
         k_se_sample, nk_corr_sample): compared as a model from another bench, with the \
         systematic errors on both sides; retrain it on fits from this polarid for the \
         same-bench comparison",
        path.display()
    ))
}

/// The prototypes of `source` for `bench`: a model's on the same bench with their sample
/// covariances ([`Model::multi_prototypes_on`]) when every prototype has one; otherwise
/// `protos` as loaded, with a warning when the same bench was asked for a model that
/// cannot give it (trained on fits without the sample columns). Libraries have no
/// bench: always `protos`.
pub fn prototypes_for(
    source: &PrototypeSource,
    protos: Vec<MultiPrototype>,
    bench: Bench,
    fits: &[&FitRow],
    warnings: &mut Vec<Warning>,
) -> Result<(Vec<MultiPrototype>, Comparison)> {
    let other = Comparison { bench, same: false };
    let PrototypeSource::Model(path) = source else {
        return Ok((protos, other));
    };
    if bench == Bench::Other {
        return Ok((protos, other));
    }
    let model = Model::read(path)?;
    if !model.has_sample_covariances() {
        warnings.push(no_sample_covariances(path));
        return Ok((protos, other));
    }
    let without: Vec<&str> = fits
        .iter()
        .filter(|f| f.status.is_ok() && noise_cov(f).is_none())
        .map(|f| f.target.as_str())
        .collect();
    if !without.is_empty() {
        warnings.push(Warning(format!(
            "{} fit row(s) have no noise-only standard errors (n_se_noise, k_se_noise): \
             compared with model {} on their total covariance ({}{})",
            without.len(),
            path.display(),
            without[..without.len().min(3)].join(", "),
            if without.len() > 3 { ", ..." } else { "" }
        )));
    }
    Ok((
        model.multi_prototypes_on(Bench::Same),
        Comparison { bench, same: true },
    ))
}
