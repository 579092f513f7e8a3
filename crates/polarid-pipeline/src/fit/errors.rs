//! The error model of the specular table fit (docs/ERRORS.md): the systematic DoLP
//! covariance of a target's rows propagated into `(n, k)` by the sandwich
//! `Cov = Cov_noise + A Σ Aᵀ` ([`polarid_core::systematic`]), and the model checks —
//! a χ² goodness of fit of the residuals against the total (noise + systematic)
//! covariance and the AoLP relative to the plane of incidence — that turn an `ok` fit
//! into `model_mismatch`.
//!
//! It also writes the **sample** covariance of a row (`n_se_sample`, `k_se_sample`,
//! `nk_corr_sample`): the noise plus the surface layer's variation from plate to plate of
//! one material. For a class named as a built-in material with a native layer
//! (`polarid_io::surfaces`: Al₂O₃ 2–5 nm on aluminum, …) that is its own layer, of the
//! standard deviation of the difference of two thicknesses drawn uniformly from its
//! range, `(max − min)/√6`, plus the error model's generic layers at
//! [`SAMPLE_RESIDUAL_RATIO`]` · film_sd_nm`; for any other class (and for fits of the
//! mixed reflectance model) the generic layers at [`SAMPLE_LAYER_RATIO`]` · film_sd_nm`
//! (same three indices, same propagation). It is what differs between two plates of one
//! material measured on one bench, where the bench's own errors (angles, DoLP floor,
//! extinction) are shared and cancel (docs/ERRORS.md "Same bench"): a model's prototypes
//! carry it, and a test plate is compared with them on its noise alone.

use polarid_core::FitStatus;
use polarid_core::dop::dop;
use polarid_core::film::thin_film;
use polarid_core::fit::NkFit;
use polarid_core::systematic::{
    FilmShifts, Gof, aolp_deviation, chi2_sf, film_shifts, propagate, systematic_covariance,
};

use super::{FitConfig, Group};

/// The standard thickness of the layer's variation between two plates of one material,
/// as a fraction of the fit's `film_sd_nm` (the allowance for a layer of unknown
/// thickness on one plate). Native layers of one material span about 3 nm (Al₂O₃ on
/// aluminum 2–5 nm, Cu₂O on copper 0.5–3 nm, SiO₂ on silicon 1–2 nm): two plates' layers,
/// each anywhere in such a span, differ by a standard deviation of `span/√6` ≈ 0.4–1.2 nm
/// (uniform), at most by the span. Half the 3 nm default, 1.5 nm, covers that (the
/// largest difference, 3 nm, at 2 standard deviations) and is 0 with `--film-sd-nm 0`.
pub const SAMPLE_LAYER_RATIO: f64 = 0.5;

/// For a class with a known native layer (a built-in material's name,
/// `polarid_io::surfaces::builtin_surface`), the generic layers' share of the sample
/// covariance beside the native layer's own variation: `0.3 · film_sd_nm` (0.9 nm of each
/// generic index at the default), for what the native layer's range does not describe —
/// adsorbed contamination over the oxide, the oxide's own index, a plate's layer outside
/// the literature's range. Without it the native layer alone moves the estimate along one
/// direction, and two plates whose layers differ by a few nm (the effective index is not
/// linear in the thickness) fall outside the resulting needle-thin ellipse.
pub const SAMPLE_RESIDUAL_RATIO: f64 = 0.3;

/// What the error model adds to a fit row.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ErrorReport {
    /// Total standard errors and correlation `(n_se, k_se, nk_corr)` (NaN when the fit
    /// has none).
    pub total: (f64, f64, f64),
    /// The sample covariance `(n_se, k_se, nk_corr)`: the noise plus the layer's
    /// variation between plates ([`SAMPLE_LAYER_RATIO`]); `None` when the fit has no
    /// standard errors.
    pub sample: Option<(f64, f64, f64)>,
    /// p-value of the χ² goodness of fit (weighted fits).
    pub gof_p: Option<f64>,
    /// p-value of the AoLP test (rows with `aolp_poi_deg`).
    pub aolp_p: Option<f64>,
    /// Why the data contradict the model (empty when they do not at `mismatch_p`).
    pub mismatch: Vec<String>,
    /// The AoLP test failed: the data contradict a single interface whatever the fit
    /// did, so `model_mismatch` takes precedence over the fit's own troubles
    /// ([`overrides`]).
    pub aolp_failed: bool,
    /// The fit's surface-layer shifts ([`film_shifts`]): for rows with a `wavelength_nm`
    /// (one band of a multi-band target), a layer allowance and a covariance in `(n, k)`
    /// (not `(n, k²)`), so that classification can correlate the layer across the bands.
    pub film: Option<FilmShifts>,
}

/// Whether a failed AoLP test replaces the fit status `s`: an `ok` fit, and the fit's
/// own troubles (`not_converged`, `ill_conditioned`, `at_bound`) — not `depolarized` or
/// `invalid_input`.
pub fn overrides(s: FitStatus) -> bool {
    matches!(
        s,
        FitStatus::Ok | FitStatus::NotConverged | FitStatus::IllConditioned | FitStatus::AtBound
    )
}

/// The error model of one target fitted as `f` from its rows, with the spread
/// corrections `corr` subtracted from the DoLP (all zero without `beta_sd_deg`).
pub(crate) fn assess(g: &Group, f: &NkFit, corr: &[f64], cfg: &FitConfig) -> ErrorReport {
    let mut rep = ErrorReport {
        total: (f.n_se, f.k_se, f.nk_corr),
        ..Default::default()
    };
    if !(f.n.is_finite() && f.k.is_finite()) || f.status == FitStatus::InvalidInput {
        return rep;
    }
    let pol = cfg.polarimetric_at(g.wavelength_nm);
    let t_len = g.rows.len();
    let betas: Vec<f64> = g
        .rows
        .iter()
        .map(|(_, m)| m.beta_deg.to_radians())
        .collect();
    let angle_sd: Vec<f64> = g
        .rows
        .iter()
        .map(|(_, m)| m.angle_sd_deg.unwrap_or(cfg.angle_sd_deg).to_radians())
        .collect();
    let residual: Vec<f64> = g
        .rows
        .iter()
        .zip(&betas)
        .zip(corr)
        .map(|(((_, m), &b), c)| m.dolp - c - dop(f.n, f.k, b))
        .collect();
    let se: Option<Vec<f64>> = g.rows.iter().map(|(_, m)| m.dolp_se).collect();
    let mut sys = vec![0.0; t_len * t_len];
    let prop = systematic_covariance(f.n, f.k, &betas, &angle_sd, &pol, &mut sys).and_then(|()| {
        propagate(
            f.n,
            f.k,
            &betas,
            &residual,
            se.as_deref(),
            &sys,
            cfg.k_range.0 == 0.0,
        )
    });
    let Ok(prop) = prop else {
        return rep;
    };
    // A fit without standard errors (singular) keeps them unknown.
    if f.n_se.is_finite() && f.k_se.is_finite() {
        rep.total = (prop.total.n_se, prop.total.k_se, prop.total.nk_corr);
        let own = own_layer(g, cfg);
        rep.sample = sample_covariance(f, &betas, &residual, se.as_deref(), &pol, own, cfg);
        if g.wavelength_nm.is_some() && !prop.total.in_u {
            rep.film = film_shifts(f.n, f.k, &betas, se.as_deref(), &pol)
                .ok()
                .flatten();
        }
    }
    if let Some(gof) = &prop.gof {
        rep.gof_p = Some(gof.p_value);
        if gof.p_value < cfg.mismatch_p {
            rep.mismatch.push(residual_reason(g, gof));
        }
    } else if se.is_none() && cfg.dolp_floor > 0.0 {
        // No stated noise (some row lacks dolp_se): the residuals are tested against the
        // systematic error alone, whose DoLP floor is the least error any row can have
        // (docs/ERRORS.md "Rows without dolp_se"). Residuals beyond it are a model
        // mismatch, or noise the file does not state.
        let tiny = vec![1e-9; t_len];
        if let Ok(p2) = propagate(
            f.n,
            f.k,
            &betas,
            &residual,
            Some(&tiny),
            &sys,
            cfg.k_range.0 == 0.0,
        ) && let Some(gof) = &p2.gof
        {
            rep.gof_p = Some(gof.p_value);
            if gof.p_value < cfg.mismatch_p {
                rep.mismatch.push(format!(
                    "{} (the rows have no dolp_se: tested against the systematic error \
                     alone; give dolp_se if the data are noisier)",
                    residual_reason(g, gof).replace(
                        "against noise + systematic error",
                        "against the systematic error"
                    )
                ));
            }
        }
    }
    let (aolp_p, why) = aolp_check(g, cfg);
    rep.aolp_p = aolp_p;
    rep.aolp_failed = why.is_some();
    rep.mismatch.extend(why);
    rep
}

/// A material's own native layer as it varies between two plates: its index at the
/// band and the standard deviation of the difference of two thicknesses drawn uniformly
/// from the material's range, `(max − min)/√6`, in wavelengths.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OwnLayer {
    index: (f64, f64),
    sd_waves: f64,
}

/// The own layer of `g`'s class when it is a built-in material with a native surface
/// whose index is known at the band (`polarid_io::surfaces`); `None` otherwise (the
/// generic layers of the error model apply).
fn own_layer(g: &Group, cfg: &FitConfig) -> Option<OwnLayer> {
    let class = g
        .rows
        .iter()
        .find_map(|(_, m)| m.class.as_deref().filter(|c| !c.is_empty()))?;
    let s = polarid_io::surfaces::builtin_surface(class)?;
    let wl = g
        .wavelength_nm
        .filter(|w| w.is_finite() && *w > 0.0)
        .unwrap_or(cfg.wavelength_nm);
    let index = polarid_io::surfaces::layer_index_builtin_band(s.layer, wl).ok()??;
    let sd_nm = (s.max_nm - s.min_nm) / 6f64.sqrt();
    Some(OwnLayer {
        index,
        sd_waves: sd_nm / wl,
    })
}

/// The error model of the sample covariance: the generic surface layers alone, of
/// standard thickness `ratio` times `pol`'s ([`SAMPLE_LAYER_RATIO`], or
/// [`SAMPLE_RESIDUAL_RATIO`] beside a native layer; no floor, no scale error; the angle
/// errors are left out by the caller).
pub(crate) fn sample_polarimetric(
    pol: &polarid_core::systematic::Polarimetric,
    ratio: f64,
) -> polarid_core::systematic::Polarimetric {
    polarid_core::systematic::Polarimetric {
        dolp_floor: 0.0,
        extinction_ratio: f64::INFINITY,
        retardance: 0.0,
        film_sd_waves: ratio * pol.film_sd_waves,
    }
}

/// The sample covariance of the module documentation: the noise plus the layers'
/// variation between plates — `own`'s layer and the generic layers at
/// `SAMPLE_RESIDUAL_RATIO · film_sd`, or without `own` the generic layers at
/// `SAMPLE_LAYER_RATIO · film_sd` (the angle, floor and scale terms left out: a bench
/// shares them between its plates) — through the same propagation (`(n, u = k²)` near
/// `k = 0`).
fn sample_covariance(
    f: &NkFit,
    betas: &[f64],
    residual: &[f64],
    se: Option<&[f64]>,
    pol: &polarid_core::systematic::Polarimetric,
    own: Option<OwnLayer>,
    cfg: &FitConfig,
) -> Option<(f64, f64, f64)> {
    let t_len = betas.len();
    let mut sys = vec![0.0; t_len * t_len];
    let ratio = if own.is_some() {
        SAMPLE_RESIDUAL_RATIO
    } else {
        SAMPLE_LAYER_RATIO
    };
    let layer = sample_polarimetric(pol, ratio);
    let zero = vec![0.0; t_len];
    systematic_covariance(f.n, f.k, betas, &zero, &layer, &mut sys).ok()?;
    if let Some(l) = own.filter(|_| pol.film_sd_waves > 0.0) {
        // g_t: the DoLP change of one standard thickness of the material's own layer,
        // Σ += g gᵀ (one thickness, every row).
        let g: Vec<f64> = betas
            .iter()
            .map(|&b| {
                thin_film(l.index, l.sd_waves, (f.n, f.k), b, 1.0)
                    .map_or(0.0, |r| r.signed_dolp() - dop(f.n, f.k, b))
            })
            .collect();
        for (i, gi) in g.iter().enumerate() {
            for (j, gj) in g.iter().enumerate() {
                sys[i * t_len + j] += gi * gj;
            }
        }
    }
    let p = propagate(f.n, f.k, betas, residual, se, &sys, cfg.k_range.0 == 0.0).ok()?;
    let c = p.total;
    (c.n_se.is_finite() && c.k_se.is_finite()).then_some((c.n_se, c.k_se, c.nk_corr))
}

/// The AoLP check of a target's rows with `aolp_poi_deg` (docs/ERRORS.md): the p-value
/// of `Σ (d/sd)²` against χ² with as many degrees of freedom as rows, and the reason when
/// it is below [`FitConfig::mismatch_p`].
pub(crate) fn aolp_check(g: &Group, cfg: &FitConfig) -> (Option<f64>, Option<String>) {
    let floor = cfg.dolp_floor;
    let mut chi2 = 0.0;
    let mut used = Vec::new();
    for (i, (line, m)) in g.rows.iter().enumerate() {
        let Some(a) = m.aolp_poi_deg else { continue };
        let b = m.beta_deg.to_radians();
        let s = m.angle_sd_deg.unwrap_or(cfg.angle_sd_deg).to_radians();
        let se = m.dolp_se.unwrap_or(0.0);
        if let Some((d, sd)) = aolp_deviation(a.to_radians(), m.dolp, se, floor, s, b)
            && sd > 0.0
        {
            chi2 += (d / sd).powi(2);
            used.push((i + 1, *line, a, d.to_degrees(), d / sd));
        }
    }
    if used.is_empty() {
        return (None, None);
    }
    let p = chi2_sf(chi2, used.len() as f64);
    if p >= cfg.mismatch_p {
        return (Some(p), None);
    }
    used.sort_by(|x, y| y.4.abs().total_cmp(&x.4.abs()));
    let worst: Vec<String> = used
        .iter()
        .take(3)
        .map(|(c, line, a, d, z)| {
            format!("capture {c} (line {line}) aolp_poi {a:.1} deg ({d:+.1} deg, {z:+.1} sd)")
        })
        .collect();
    (
        Some(p),
        Some(format!(
            "aolp: not perpendicular to the plane of incidence (p = {p:.2e}): {}; \
             a coating, a film, birefringence or a wrong geometry",
            worst.join(", ")
        )),
    )
}

/// `residuals: ...` naming the worst rows.
fn residual_reason(g: &Group, gof: &Gof) -> String {
    let mut idx: Vec<usize> = (0..gof.z.len()).collect();
    idx.sort_by(|&a, &b| gof.z[b].abs().total_cmp(&gof.z[a].abs()));
    let worst: Vec<String> = idx
        .iter()
        .enumerate()
        .take_while(|&(rank, &i)| rank == 0 || gof.z[i].abs() >= 2.0)
        .take(3)
        .map(|(_, &i)| {
            let (line, m) = g.rows[i];
            format!(
                "capture {} (line {line}, beta {:.1} deg) {:+.1} sd",
                i + 1,
                m.beta_deg,
                gof.z[i]
            )
        })
        .collect();
    format!(
        "residuals: chi2 = {:.1} on {} dof against noise + systematic error (p = {:.2e}): {}",
        gof.chi2,
        gof.dof,
        gof.p_value,
        worst.join(", ")
    )
}
