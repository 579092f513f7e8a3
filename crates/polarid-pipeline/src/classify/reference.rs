//! In-scene references in `polarid classify MEASUREMENTS.csv` (docs/CLASSIFY.md
//! "In-scene reference"): the rows of regions of known material (the measurements'
//! `reference` column) calibrate the polarimeter scale and the common angle offset
//! (`polarid_core::classify::reference`), and the other targets are tested with those
//! nuisances' boxes shrunk to what the references leave.
//!
//! A measurements file is one scene: one camera and one polarimeter, the source moved
//! between captures. The scale and the camera's direction error are shared by every
//! region of every capture, so the references calibrate every target of the file.
//! Several references are combined (inverse-variance means). A reference whose material
//! does not explain its rows (`p`-value below [`REJECT_P`]) or whose estimate leaves no
//! box (a scale above 1 beyond its errors, an offset beyond the search) is not used, and
//! a warning says why; so is a calibration outside the error model's own boxes.

use polarid_core::classify::reference::{
    Bounds, Calibration, REFERENCE_SIGMAS, calibrate, combine,
};
use polarid_core::classify::{CandidateModel, HypRow, MultiPrototype, Nuisances};
use polarid_io::table::measurements::Reference;

use super::PrototypeSource;
use crate::{PipelineError, Result, Warning};

/// A reference whose material explains its rows with a `p`-value below this is not used
/// (its rows say it is not that material, or not clean).
pub const REJECT_P: f64 = 1e-3;

/// One reference region's fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceFit {
    /// The region (target) name.
    pub target: String,
    /// Its declared material.
    pub reference: Reference,
    /// What its rows measured (`None`: they could not be fitted, too few usable rows).
    pub calibration: Option<Calibration>,
    /// Whether it calibrates the targets (see the module documentation).
    pub used: bool,
}

/// The scene's calibration by its references.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneCalibration {
    /// Every reference region, in file order.
    pub references: Vec<ReferenceFit>,
    /// The used references combined ([`combine`]); `None` when none is used.
    pub combined: Option<Calibration>,
    /// The targets' boxes ([`Calibration::bounds`] with [`REFERENCE_SIGMAS`]); `None`
    /// when no reference is used (then the error model's boxes apply).
    pub bounds: Option<Bounds>,
    /// The error model's boxes the calibration replaces.
    pub prior: Nuisances,
}

/// The reference's bulk index (and native layer) at `bands` (nm): a material of the
/// classification's prototypes `protos`, else of the built-in library evaluated at the
/// bands, or the given index (bare, the same at every band).
///
/// Errors: [`PipelineError::Data`] naming `path`, the target and the material when
/// neither has it at every band.
pub fn reference_model(
    path: &str,
    target: &str,
    r: &Reference,
    bands: &[f64],
    protos: &[MultiPrototype],
) -> Result<CandidateModel> {
    match r {
        Reference::Index { n, k } => Ok(CandidateModel {
            bulk: vec![(*n, *k); bands.len()],
            layer: None,
        }),
        Reference::Material(name) => {
            if let Some(m) = protos
                .iter()
                .filter(|p| &p.class == name)
                .find_map(|p| CandidateModel::from_prototype(p, bands))
            {
                return Ok(m);
            }
            let (builtin, _, _) =
                PrototypeSource::Library("builtin".into()).load_multi_for(bands, 0)?;
            builtin
                .iter()
                .filter(|p| &p.class == name)
                .find_map(|p| CandidateModel::from_prototype(p, bands))
                .ok_or_else(|| PipelineError::Data {
                    path: path.to_string(),
                    reason: format!(
                        "target {target:?}: reference {name:?} is a material of neither the \
                         classification's library nor the built-in one at the band(s) {} nm \
                         (column reference); give its index as n+ki",
                        bands
                            .iter()
                            .map(|w| format!("{w}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                })
        }
    }
}

/// One reference's rows and model, as the workflow gathers them.
pub struct ReferenceRows<'a> {
    /// The region name.
    pub target: &'a str,
    /// Its declared material.
    pub reference: Reference,
    /// Its usable rows.
    pub rows: Vec<HypRow>,
    /// The rows' band wavelengths, nm.
    pub bands: Vec<f64>,
}

/// Fit every reference and combine the usable ones into the targets' boxes (module
/// documentation). `prior`: the error model's boxes; `confidence`: the tests'
/// confidence (a reference whose `p`-value is below `1 − confidence` is used, with a
/// warning). Returns `None` without references.
///
/// Errors: [`PipelineError::Data`] naming `path` and the reference when its material is
/// unknown ([`reference_model`]) or its rows cannot be fitted (too few).
pub fn calibrate_scene(
    path: &str,
    refs: &[ReferenceRows],
    protos: &[MultiPrototype],
    prior: Nuisances,
    confidence: f64,
) -> Result<(Option<SceneCalibration>, Vec<Warning>)> {
    if refs.is_empty() {
        return Ok((None, Vec::new()));
    }
    let mut warnings = Vec::new();
    let mut fits = Vec::new();
    for r in refs {
        let what = format!("reference target {:?} ({})", r.target, r.reference);
        let model = reference_model(path, r.target, &r.reference, &r.bands, protos)?;
        let cal = match calibrate(&r.rows, &r.bands, &model) {
            Ok(c) => c,
            Err(e) => {
                warnings.push(Warning(format!(
                    "{what} is not used: its {} usable row(s) cannot calibrate the                      polarimeter: {e}",
                    r.rows.len()
                )));
                fits.push(ReferenceFit {
                    target: r.target.to_string(),
                    reference: r.reference.clone(),
                    calibration: None,
                    used: false,
                });
                continue;
            }
        };
        let mut used = true;
        if cal.p_value < REJECT_P {
            warnings.push(Warning(format!(
                "{what} is not used: its material does not explain its rows (chi2 {:.1} on \
                 {:.0} dof, p-value {:.1e}); check its material, its rectangle and that it \
                 reflects specularly",
                cal.chi2, cal.dof, cal.p_value
            )));
            used = false;
        } else if cal.bounds(REFERENCE_SIGMAS).is_none() {
            warnings.push(Warning(format!(
                "{what} is not used: it measures scale {:.4} ± {:.4} and offset {:+.3} ± \
                 {:.3} deg, which leave no box (a scale above 1, or an offset at the \
                 ±{} deg search limit)",
                cal.scale,
                cal.scale_se,
                cal.offset.to_degrees(),
                cal.offset_se.to_degrees(),
                polarid_core::classify::reference::SEARCH_OFFSET_DEG
            )));
            used = false;
        } else if cal.p_value < 1.0 - confidence {
            warnings.push(Warning(format!(
                "{what}: its material explains its rows only with p-value {:.3} (chi2 {:.1} \
                 on {:.0} dof); it is used, but check it",
                cal.p_value, cal.chi2, cal.dof
            )));
        }
        fits.push(ReferenceFit {
            target: r.target.to_string(),
            reference: r.reference.clone(),
            calibration: Some(cal),
            used,
        });
    }
    let used: Vec<Calibration> = fits
        .iter()
        .filter(|f| f.used)
        .filter_map(|f| f.calibration)
        .collect();
    let combined = combine(&used);
    let bounds = combined.and_then(|c| c.bounds(REFERENCE_SIGMAS));
    if let Some(b) = bounds {
        let (lo, hi) = (b.scale.0.max(prior.scale_min), b.scale.1.min(1.0));
        let (olo, ohi) = (
            b.offset.0.max(-prior.offset_max),
            b.offset.1.min(prior.offset_max),
        );
        if lo > hi || olo > ohi {
            warnings.push(Warning(format!(
                "the in-scene reference measures scale [{:.4}, {:.4}] and offset [{:+.3}, \
                 {:+.3}] deg, outside the error model's scale [{:.4}, 1] and offset \
                 ±{:.3} deg: the bench is worse than its error model; the targets are \
                 tested with the reference's values",
                b.scale.0,
                b.scale.1,
                b.offset.0.to_degrees(),
                b.offset.1.to_degrees(),
                prior.scale_min,
                prior.offset_max.to_degrees()
            )));
        }
    }
    Ok((
        Some(SceneCalibration {
            references: fits,
            combined,
            bounds,
            prior,
        }),
        warnings,
    ))
}

/// The text of a reference's calibration: scale, offset, layer, χ².
fn calibration_text(c: &Calibration) -> String {
    format!(
        "scale {:.4} ± {:.4}, offset {:+.3} ± {:.3} deg, layer {:.2} nm, chi2 {:.2} on {:.0} \
         dof (p-value {:.3})",
        c.scale,
        c.scale_se,
        c.offset.to_degrees(),
        c.offset_se.to_degrees(),
        c.thickness_nm,
        c.chi2,
        c.dof,
        c.p_value
    )
}

/// The classification CSV row of a reference region: `predicted` its material,
/// `status` and `rule` `reference`, `distance`/`gate` its `χ²`, and in `reason` what it
/// measured (or why it is not used).
pub fn reference_row(
    f: &polarid_io::table::fits::FitRow,
    r: &ReferenceFit,
    confidence: f64,
) -> polarid_io::table::classification::ClassificationRow {
    let c = r.calibration;
    polarid_io::table::classification::ClassificationRow {
        target: f.target.clone(),
        class: f.class.clone(),
        predicted: r.reference.text(),
        distance: c.map(|c| c.chi2),
        status: "reference".into(),
        metric: "chi2".into(),
        rule: "reference".into(),
        confidence: Some(confidence),
        gate: c.map(|c| c.chi2),
        reason: match (c, r.used) {
            (Some(c), true) => format!("in-scene reference: {}", calibration_text(&c)),
            (Some(c), false) => format!("in-scene reference, not used: {}", calibration_text(&c)),
            (None, _) => "in-scene reference, not used: too few usable rows".into(),
        },
        ..Default::default()
    }
}

/// The explanation line of a reference region.
pub fn explain_reference(f: &ReferenceFit, scene: &SceneCalibration) -> String {
    let Some(c) = &f.calibration else {
        return format!(
            "{}: in-scene reference {}: not used (too few usable rows)",
            f.target, f.reference
        );
    };
    let mut s = format!(
        "{}: in-scene reference {}: {}",
        f.target,
        f.reference,
        calibration_text(c)
    );
    match (&scene.bounds, f.used) {
        (Some(b), true) => s.push_str(&format!(
            "; the other targets are tested with scale in [{:.4}, {:.4}] and offset in \
             [{:+.3}, {:+.3}] deg (error model alone: scale in [{:.4}, 1], offset within \
             ±{:.3} deg)",
            b.scale.0,
            b.scale.1,
            b.offset.0.to_degrees(),
            b.offset.1.to_degrees(),
            scene.prior.scale_min,
            scene.prior.offset_max.to_degrees()
        )),
        _ => s.push_str("; not used (see the warning)"),
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_core::classify::layered_dolp;

    #[test]
    fn references_resolve_and_calibrate() {
        let bands = [650.0];
        let bk7 = reference_model(
            "m.csv",
            "slide",
            &Reference::Material("N-BK7".into()),
            &bands,
            &[],
        )
        .unwrap();
        assert!((bk7.bulk[0].0 - 1.51).abs() < 0.01, "{bk7:?}");
        let e = reference_model(
            "m.csv",
            "slide",
            &Reference::Material("unobtainium".into()),
            &bands,
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("m.csv") && e.contains("unobtainium"), "{e}");
        let idx = reference_model(
            "m.csv",
            "slide",
            &Reference::Index { n: 1.5, k: 0.0 },
            &bands,
            &[],
        )
        .unwrap();
        assert_eq!(idx.bulk, vec![(1.5, 0.0)]);
        // Rows of a bare 1.5 glass at scale 0.9, offset +0.4°.
        let rows: Vec<HypRow> = (0..8)
            .map(|i| {
                let beta = (47.5 + 22.5 * i as f64 / 7.0f64).to_radians();
                HypRow {
                    beta,
                    dolp: 0.9
                        * layered_dolp((1.5, 0.0), (1.0, 0.0), 0.0, beta + 0.4f64.to_radians())
                        + if i % 2 == 0 { 0.001 } else { -0.001 },
                    dolp_sd: 0.003,
                    angle_sd: 0.2f64.to_radians(),
                    band: 0,
                }
            })
            .collect();
        let prior = Nuisances::from_error_model(100.0, 0.0, 0.2f64.to_radians());
        let refs = [ReferenceRows {
            target: "slide",
            reference: Reference::Index { n: 1.5, k: 0.0 },
            rows,
            bands: bands.to_vec(),
        }];
        let (scene, warnings) = calibrate_scene("m.csv", &refs, &[], prior, 0.95).unwrap();
        let scene = scene.unwrap();
        let b = scene.bounds.unwrap();
        assert!(b.scale.0 < 0.9 && 0.9 < b.scale.1, "{b:?}");
        // A scale of 0.9 is outside the 100:1 error model's [0.98, 1]: said.
        assert!(
            warnings
                .iter()
                .any(|w| w.0.contains("worse than its error model")),
            "{warnings:?}"
        );
        let line = explain_reference(&scene.references[0], &scene);
        assert!(
            line.contains("scale 0.9") && line.contains("in-scene reference"),
            "{line}"
        );
    }
}
