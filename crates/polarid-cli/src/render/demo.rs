//! The demo's figures and report: DoLP against β per plate set, the (n, k) plane with
//! the prototypes and the test estimates, and the report laying them out with the
//! demo's inputs, geometry and tables (from a [`DemoOutput`]).

pub(super) mod common;

use std::fmt::Write as _;

use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;
use polarid_pipeline::demo::{DemoOutput, DemoPlate, PLATES, SIDE, paper_estimate};

use super::Rendered;
use super::plots::{self, PlotSize};
use super::report::{self, Figure, Report};

/// The three figures: DoLP against β (training plates, test plate) and the (n, k) plane.
pub fn figures(out: &DemoOutput) -> anyhow::Result<[Rendered; 3]> {
    let is_training = |t: &str| PLATES.iter().any(|p| p.training && p.target == t);
    let fit_of = |t: &str| out.fits.iter().map(|(_, f)| f).find(|f| f.target == t);
    let by_target = common::by_target(out.measurements.iter().map(|(_, m)| m));
    let series = |training: bool| -> Vec<plots::DolpSeries> {
        PLATES
            .iter()
            .filter(|p| p.training == training)
            .filter_map(|p| {
                let f = fit_of(p.target)?;
                let ms = by_target.get(p.target)?;
                let label = if training {
                    p.label.to_string()
                } else {
                    format!("test plate, θr = {:.0}°", p.theta_r)
                };
                Some(common::dolp_series(label, Some(f), ms))
            })
            .collect()
    };
    let size = PlotSize::REPORT;
    let dolp_train = plots::dolp_vs_beta(
        "DoLP against β, training plates (θr = 60°)",
        &series(true),
        size,
    )?;
    let dolp_test = plots::dolp_vs_beta(
        "DoLP against β, test aluminum plate (θr = 60° and 50°)",
        &series(false),
        size,
    )?;
    let protos = common::prototypes(&out.model.prototypes);
    let clf = same_bench_classifier_of(&out.model, &out.classification);
    let ests: Vec<plots::NkEstimate> = out
        .fits
        .iter()
        .filter(|(_, f)| !is_training(&f.target))
        .map(|(_, f)| {
            let f = &decisive(f, &out.model);
            plots::NkEstimate::from_fit(
                format!(
                    "test, θr = {}°",
                    PLATES
                        .iter()
                        .find(|p| p.target == f.target)
                        .map_or(f64::NAN, |p| p.theta_r)
                ),
                f,
                &out.classification,
                clf.as_ref(),
            )
        })
        .collect();
    let nk = plots::nk_plane(
        "Test plate in the (n, k) plane, 95% confidence regions",
        &protos,
        &ests,
        size,
    )?;
    Ok([dolp_train, dolp_test, nk])
}

/// A classifier over `model`'s prototypes at the confidence of the classification rows
/// (the default 95% when they carry none), to draw the regions that decide their sets.
/// `None` when the model's prototypes are unusable.
pub fn classifier_of(
    model: &polarid_io::model::Model,
    rows: &[ClassificationRow],
) -> Option<polarid_core::classify::Classifier> {
    polarid_core::classify::Classifier::new(model.prototypes(), set_rule_of(rows)).ok()
}

/// The set rule at the confidence of the classification rows (the default 95% when
/// they carry none).
fn set_rule_of(rows: &[ClassificationRow]) -> polarid_core::classify::ClassifierConfig {
    let confidence = rows
        .iter()
        .find_map(|c| c.confidence)
        .unwrap_or(polarid_core::classify::DEFAULT_CONFIDENCE);
    polarid_core::classify::ClassifierConfig::set(confidence)
}

/// [`classifier_of`] as `classify --model` compares the demo's test plate with its
/// model, from the same bench: each prototype with its sample covariance (the paper
/// demo; see [`decisive`] for the estimate's side).
pub fn same_bench_classifier_of(
    model: &polarid_io::model::Model,
    rows: &[ClassificationRow],
) -> Option<polarid_core::classify::Classifier> {
    use polarid_core::classify::Bench;
    let bench = if model.has_sample_covariances() {
        Bench::Same
    } else {
        Bench::Other
    };
    polarid_core::classify::Classifier::multi(model.multi_prototypes_on(bench), set_rule_of(rows))
        .ok()
}

/// The fit row with the covariance that decides its comparison with `model`'s
/// prototypes: on the same bench its noise covariance (`_noise` columns) in place of
/// `n_se`, `k_se`, `nk_corr` (see `polarid_pipeline::classify::estimate_for`).
pub fn decisive(f: &FitRow, model: &polarid_io::model::Model) -> FitRow {
    let cmp = polarid_pipeline::classify::Comparison {
        bench: polarid_core::classify::Bench::Same,
        same: model.has_sample_covariances(),
    };
    let mut g = f.clone();
    if let Some(c) = polarid_pipeline::classify::estimate_for(f, cmp).cov {
        let (n_se, k_se, corr) = c.to_se();
        g.n_se = n_se;
        g.k_se = k_se;
        g.nk_corr = corr;
    }
    g
}

/// The report's classification rows: each classification row with its consistent set and
/// the confidence region(s) that decide it (from the fit of the same target, under
/// `clf`'s prototypes and confidence), with the estimates' covariance for `model`'s
/// comparison ([`decisive`]; `None`: the fit's total).
pub fn report_classification(
    fits: &[(u64, FitRow)],
    class_rows: &[ClassificationRow],
    clf: Option<&polarid_core::classify::Classifier>,
    model: Option<&polarid_io::model::Model>,
) -> Vec<report::ClassificationRow> {
    class_rows
        .iter()
        .map(|c| {
            let region = clf.and_then(|clf| {
                let (_, f) = fits.iter().find(|(_, f)| f.target == c.target)?;
                let est = match model {
                    Some(m) => polarid_pipeline::classify::estimate_of(&decisive(f, m)),
                    None => polarid_pipeline::classify::estimate_of(f),
                };
                polarid_pipeline::classify::regions_text(&est, clf)
            });
            report::ClassificationRow {
                target: c.target.clone(),
                truth: c.class.clone(),
                predicted: c.predicted.clone(),
                distance: c.distance.unwrap_or(f64::NAN),
                runner_up: c.runner_up.clone(),
                runner_up_distance: c.runner_up_distance,
                status: c.status.clone(),
                candidates: c.confidence.map(|_| c.candidates.clone()),
                confidence: c.confidence,
                region,
                rule: c.rule.clone(),
            }
        })
        .collect()
}

/// The demo's report.
pub fn report(out: &DemoOutput, figs: &[Rendered; 3]) -> Report {
    let clf = same_bench_classifier_of(&out.model, &out.classification);
    let fits = &out.fits;
    let class_rows = &out.classification;
    Report {
        title: "polarid demo: material classification from polarization, the paper's \
                experiment in simulation"
            .into(),
        summary: summary(class_rows),
        inputs: inputs(&out.scenes, &out.manifests),
        manifest: manifest_rows(),
        geometry: geometry_rows(&out.measurements),
        references: reference_rows(),
        estimates: fits
            .iter()
            .map(|(_, f)| common::estimate_row(f, plate(&f.target).map(|p| p.theta_r)))
            .collect(),
        classification: report_classification(fits, class_rows, clf.as_ref(), Some(&out.model)),
        tables: vec![paper_table(fits)],
        figures: figures_of(figs),
        generator: format!("polarid {} demo", env!("CARGO_PKG_VERSION")),
    }
}

/// The demo plate of target `t`.
fn plate(t: &str) -> Option<&'static DemoPlate> {
    PLATES.iter().find(|p| p.target == t)
}

/// The geometry of each plate: its angles and the range of β of its measurements.
fn geometry_rows(meas: &[(u64, Measurement)]) -> Vec<report::GeometryRow> {
    PLATES
        .iter()
        .map(|p| {
            let ms: Vec<&Measurement> = meas
                .iter()
                .map(|(_, m)| m)
                .filter(|m| m.target == p.target)
                .collect();
            let b = ms.iter().map(|m| m.beta_deg);
            report::GeometryRow {
                target: p.target.into(),
                class: Some(p.class.into()),
                theta_r_deg: p.theta_r,
                theta_i_deg: p.theta_i,
                phi_deg: 180.0,
                beta_deg: (
                    b.clone().fold(f64::MAX, f64::min),
                    b.fold(f64::MIN, f64::max),
                ),
                captures: ms.len(),
            }
        })
        .collect()
}

/// The training plates' reference indices.
fn reference_rows() -> Vec<report::ReferenceRow> {
    PLATES
        .iter()
        .filter(|p| p.training)
        .map(|p| report::ReferenceRow {
            material: p.class.into(),
            n: p.n,
            k: p.k,
            source: "paper Table 1 (refs. [8, 10]); the simulated plates' bulk index, under \
                         their native layer (Table 1)"
                .into(),
        })
        .collect()
}

/// The scenes, manifests and tables the demo wrote.
fn inputs(scenes: &[String], manifests: &[String]) -> Vec<report::InputItem> {
    let scene_detail = |s: &str| {
        let t = s
            .trim_start_matches("captures/")
            .trim_end_matches("/scene.toml");
        plate(t)
            .map(|p| {
                format!(
                    "{} (n = {}, k = {}, σ = {}), θr = {}°, θi = {}–{}° in 5° steps, \
                     rotating polarizer 0/45/90/135°",
                    p.label, p.n, p.k, p.sigma, p.theta_r, p.theta_i.0, p.theta_i.1
                )
            })
            .unwrap_or_default()
    };
    common::inputs(
        scenes,
        manifests,
        scene_detail,
        "written by the simulator, read by measure",
        &[
            (
                "measurements",
                "measurements.csv",
                "DoLP per target per capture (measure)",
            ),
            ("fits", "fits.csv", "n, k with standard errors (fit, eq. 9)"),
            (
                "model",
                "model.json",
                "prototypes: the three training fits (train)",
            ),
            (
                "classification",
                "classification.csv",
                "the test plate: the consistent set at 95%, one bench (classify)",
            ),
        ],
    )
}

/// The paper's own estimates beside the simulation's.
fn paper_table(fits: &[(u64, FitRow)]) -> report::Table {
    let paper_rows: Vec<Vec<String>> = fits
        .iter()
        .filter_map(|(_, f)| {
            let (pn, pk) = paper_estimate(&f.target)?;
            let p = plate(&f.target)?;
            Some(vec![
                f.target.clone(),
                format!("{:.0}", p.theta_r),
                format!("{:.3} ± {:.3}", f.n, f.n_se),
                format!("{:.3} ± {:.3}", f.k, f.k_se),
                format!("{pn:.2}"),
                format!("{pk:.2}"),
            ])
        })
        .collect();
    report::Table::new(
        "The paper's own estimates (Tables 1 and 2, real plates) beside the simulation's. \
         The simulated plates carry a native layer of a few nanometres, so their estimates \
         land on the index a single-interface fit sees on the layered surface, not on the \
         bulk reference (for aluminum under Al₂O₃, lower n and k); the paper's differ from \
         the references by the model error of real surfaces.",
        &[
            "target",
            "θr (°)",
            "n̂ (here)",
            "k̂ (here)",
            "paper n̂",
            "paper k̂",
        ],
        paper_rows,
    )
}

/// The report's summary: the experiment, and the result of each test view.
fn summary(class_rows: &[ClassificationRow]) -> Vec<String> {
    let mut summary = vec![
        "The paper's laboratory experiment (Thilak, Creusere & Voelz, ICIP 2007, section 7) \
         in simulation: flat plates of known index and roughness are rendered from the \
         Priest–Meier pBRDF (eq. 3) for a lamp moved in 5° steps in the plane of incidence, \
         seen by a 12-bit camera (10 500 e⁻ full well, 2.5 e⁻ read noise, shot noise) \
         behind a polarizer at 0/45/90/135°. polarid then measures the DoLP of a 96 × 96 \
         pixel region per capture from the image files, fits n and k (eq. 9), trains \
         prototypes on the three training plates and classifies the test aluminum plate, \
         which is rougher than the training one and has its own oxide layer, at two view \
         angles, as `polarid classify --model` does: the materials consistent with the \
         estimate at 95% on one bench (the estimate's noise against each prototype's noise \
         and layer variation; docs/CLASSIFY.md). Each plate is its material under its own \
         native layer (Al₂O₃ on aluminum, Cu₂O on copper, contamination on the paint)."
            .to_string(),
    ];
    let correct = common::correct(class_rows);
    let mut result = format!(
        "Result: {correct} of {} test views classified correctly",
        class_rows.len()
    );
    for c in class_rows {
        let view = plate(&c.target).map_or(f64::NAN, |p| p.theta_r);
        let _ = write!(result, "; θr = {view:.0}°: {}", c.predicted);
        if let (Some(r), Some(m)) = (&c.runner_up, c.margin) {
            let _ = write!(result, " (runner-up {r}, margin {m:.3})");
        }
        if let Some(p) = c.confidence {
            let set = if c.candidates.is_empty() {
                "none".to_string()
            } else {
                c.candidates.join(", ")
            };
            let _ = write!(result, ", consistent set at {}%: {set}", p * 100.0);
        }
    }
    result.push('.');
    summary.push(result);
    summary
}

/// The demo's settings.
fn manifest_rows() -> Vec<(String, String)> {
    vec![
        ("wavelength".into(), "650 nm (informational)".into()),
        (
            "camera".into(),
            "12 bit, full well 10 500 e⁻, read noise 2.5 e⁻, dark level 64 DN".into(),
        ),
        (
            "exposure".into(),
            "auto per capture: brightest plate pixel at 70 % of full scale; S0 divided \
             by the exposure"
                .into(),
        ),
        (
            "frames".into(),
            format!("{SIDE} × {SIDE} pixels per capture, 16-bit PNG"),
        ),
        ("region".into(), "[16, 16, 96, 96] of each plate".into()),
        (
            "classifier".into(),
            "the consistent set at 95% (Mahalanobis distance, the estimate's noise and \
             each prototype's noise and surface-layer variation: one bench), as \
             classify --model; the paper's nearest neighbour (Euclidean in (n, k)) in \
             Table 2 beside it"
                .into(),
        ),
    ]
}

/// The report's figures, from the three rendered plots.
fn figures_of(figs: &[Rendered; 3]) -> Vec<Figure> {
    vec![
        Figure::from_rendered(
            "DoLP against β, training plates",
            "Measured DoLP of each training plate (points, ±1 standard-error bars, \
             mostly smaller than the points) and the fitted eq. (9) curve.",
            &figs[0],
            "plots/dolp_training.png",
            Some("plots/dolp_training.svg".into()),
        ),
        Figure::from_rendered(
            "DoLP against β, test plate",
            "The test aluminum plate at θr = 60° and 50°: the same material gives the \
             same DoLP(β) curve from both view angles.",
            &figs[1],
            "plots/dolp_test.png",
            Some("plots/dolp_test.svg".into()),
        ),
        Figure::from_rendered(
            "The (n, k) plane",
            "Training prototypes, the paper's nearest-neighbour decision regions (shaded; \
             Euclidean distance, § 6), and each test estimate's confidence region at the \
             set's confidence: a prototype is in the consistent set exactly when it lies \
             inside the region drawn for it (dashed: the region with that training \
             prototype's noise and surface-layer variation added to the estimate's \
             noise, Σ_est,noise + Σ_proto,sample: one bench). The legend gives each \
             view's answer.",
            &figs[2],
            "plots/nk_plane.png",
            Some("plots/nk_plane.svg".into()),
        ),
    ]
}
