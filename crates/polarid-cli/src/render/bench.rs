//! The bench demo's figures, map files and report (from a [`BenchOutput`] of
//! `polarid demo --bench`): DoLP against β per training plate, the (n, k) plane, β maps
//! of two captures (where each plate sits on the DoLP curve) and the test set's
//! material map.

use std::path::Path;

use anyhow::Context;
use polarid_io::image;
use polarid_pipeline::demo::bench::{BenchOutput, MAP_BIN, TEST_PREFIX};
use polarid_pipeline::map::MapResult;

use super::colour_demo::{ColourFigure, report_figures};
use super::demo::common;
use super::plots::{self, PlotSize};
use super::report::{self, Report};

/// One figure: the drawing, its file stem under `plots/`, title and caption.
pub type BenchFigure = ColourFigure;

fn is_test(t: &str) -> bool {
    t.starts_with(TEST_PREFIX)
}

/// The figures of the bench report.
pub fn figures(out: &BenchOutput) -> anyhow::Result<Vec<BenchFigure>> {
    let size = PlotSize::REPORT;
    let fit_of = |t: &str| out.fits.iter().map(|(_, f)| f).find(|f| f.target == t);
    let by_target = common::by_target(out.measurements.iter().map(|(_, m)| m));
    let series: Vec<plots::DolpSeries> = by_target
        .iter()
        .filter(|(t, _)| !is_test(t))
        .filter_map(|(t, ms)| {
            let f = fit_of(t)?;
            Some(common::dolp_series(t.to_string(), Some(f), ms))
        })
        .collect();
    let mut figs = vec![BenchFigure {
        plot: plots::dolp_vs_beta("DoLP against β, training plates (bench)", &series, size)?,
        stem: "dolp_training".into(),
        title: "DoLP against β, training plates".into(),
        caption: "Each plate's region DoLP per lamp position (points, ±1 standard error) \
                  against the region's β, and the fitted eq. (9) curve."
            .into(),
    }];
    let protos = common::prototypes(&out.model.prototypes);
    let clf = super::demo::classifier_of(&out.model, &out.classification);
    let ests: Vec<plots::NkEstimate> = out
        .fits
        .iter()
        .filter(|(_, f)| is_test(&f.target))
        .map(|(_, f)| {
            plots::NkEstimate::from_fit(f.target.clone(), f, &out.classification, clf.as_ref())
        })
        .collect();
    figs.push(BenchFigure {
        plot: plots::nk_plane(
            "Test plates in the (n, k) plane, 95% confidence regions",
            &protos,
            &ests,
            size,
        )?,
        stem: "nk_plane".into(),
        title: "The (n, k) plane".into(),
        caption: "Training prototypes, the nearest-neighbour decision regions (shaded), and \
                  each test estimate's confidence region at the set's confidence: a prototype \
                  is in the consistent set exactly when it lies inside the region drawn for \
                  it (dashed: with that prototype's own covariance added). The legend gives \
                  each plate's answer."
            .into(),
    });
    let (w, h) = out.size;
    for (name, beta) in &out.beta_maps {
        figs.push(BenchFigure {
            plot: plots::scalar_map(
                &format!("β per pixel, training capture {name}"),
                w,
                h,
                beta,
                None,
                "β (°)",
                size,
            )?,
            stem: format!("beta_{name}"),
            title: format!("β map, capture {name}"),
            caption: "Each pixel's own β (eq. 5) from where its ray meets the table and the \
                      lamp's position: the spread across a plate is the spread of its \
                      region along the DoLP curve (grey: no plate)."
                .into(),
        });
    }
    let m = &out.map;
    figs.push(BenchFigure {
        plot: plots::answer_map(
            &format!("Material map of the test set ({MAP_BIN}x{MAP_BIN} binning)"),
            &super::map_figures::class_map(m),
            size,
        )?,
        stem: "class_map".into(),
        title: "Material map".into(),
        caption: format!(
            "Per-pixel (4 × 4 block) fit of (n, k) over the nine lamp positions, answered \
             by the {} against the trained model: a material, `ambiguous` (dark grey) or \
             `unknown` (light greys: no material consistent, or no usable fit, e.g. the \
             background; pink-magenta: saturated; dark slate: dark). The plate regions \
             are outlined.",
            polarid_pipeline::demo::map_rule(m)
        ),
    });
    Ok(figs)
}

/// Write the map's files into `dir` (as `polarid map` names them): `n.tif`, `k.tif`,
/// `class.tif`, `classes.json`, `map_summary.json`.
pub fn write_map(dir: &Path, m: &MapResult) -> anyhow::Result<()> {
    let (w, h) = (m.width, m.height);
    for (name, data) in m.fit_images().into_iter().take(2) {
        image::write_tiff_f32(&dir.join(name), true, w, h, data)?;
    }
    let c8: Vec<u8> = m.class.iter().map(|&c| c.min(255) as u8).collect();
    image::write_gray8(&dir.join("class.tif"), true, w, h, &c8)?;
    for (name, v) in [
        ("classes.json", m.classes_json()),
        ("map_summary.json", m.summary_json()),
    ] {
        std::fs::write(dir.join(name), serde_json::to_string_pretty(&v)? + "\n")
            .with_context(|| format!("cannot write {name}"))?;
    }
    Ok(())
}

/// The bench report.
pub fn report(out: &BenchOutput, figs: &[BenchFigure]) -> Report {
    let clf = super::demo::classifier_of(&out.model, &out.classification);
    Report {
        title: "polarid demo --bench: a lamp-and-lens bench with calibrated geometry".into(),
        summary: summary(out),
        inputs: inputs(out),
        manifest: manifest_rows(out),
        geometry: geometry_rows(out),
        references: reference_rows(out),
        estimates: out
            .fits
            .iter()
            .map(|(_, f)| common::estimate_row(f, None))
            .collect(),
        classification: super::demo::report_classification(
            &out.fits,
            &out.classification,
            clf.as_ref(),
            None,
        ),
        tables: vec![spread_table(out)],
        figures: report_figures(figs),
        generator: format!("polarid {} demo --bench", env!("CARGO_PKG_VERSION")),
    }
}

/// Each plate's angles over its captures (ranges, and the mean θr and φ).
fn geometry_rows(out: &BenchOutput) -> Vec<report::GeometryRow> {
    let mut targets: Vec<&str> = Vec::new();
    for t in &out.truth {
        if !targets.contains(&t.target.as_str()) {
            targets.push(&t.target);
        }
    }
    targets
        .iter()
        .map(|&t| {
            let rows: Vec<_> = out.truth.iter().filter(|r| r.target == t).collect();
            let r = |f: &dyn Fn(&&polarid_pipeline::simulate::TruthRow) -> f64| {
                let v = rows.iter().map(f);
                (
                    v.clone().fold(f64::MAX, f64::min),
                    v.fold(f64::MIN, f64::max),
                )
            };
            let (s, c) = rows.iter().fold((0.0, 0.0), |(s, c), x| {
                let p = x.phi_deg.to_radians();
                (s + p.sin(), c + p.cos())
            });
            report::GeometryRow {
                target: t.to_string(),
                class: rows.first().and_then(|x| x.class.clone()),
                theta_r_deg: rows.iter().map(|x| x.theta_r_deg).sum::<f64>() / rows.len() as f64,
                theta_i_deg: r(&|x| x.theta_i_deg),
                phi_deg: f64::atan2(s, c).to_degrees().rem_euclid(360.0),
                beta_deg: r(&|x| x.beta_deg),
                captures: rows.len(),
            }
        })
        .collect()
}

/// The per-pixel geometry over each training plate's region.
fn spread_table(out: &BenchOutput) -> report::Table {
    let rows: Vec<Vec<String>> = out
        .truth
        .iter()
        .filter(|t| !is_test(&t.target))
        .filter_map(|t| {
            let c = t.calibrated.as_ref()?;
            Some(vec![
                t.target.clone(),
                c.capture.clone(),
                format!("{:.1}", t.phi_deg),
                format!("{:.2}", t.beta_deg),
                format!("{:.2}–{:.2}", c.beta_min_deg, c.beta_max_deg),
                format!("{:.3}", c.beta_sd_deg),
                format!("{:.4}", t.dolp),
            ])
        })
        .collect();
    report::Table::new(
        "Per-pixel geometry over each training plate's region (degrees): φ and β are \
         region means; the region's β range and standard deviation; the noise-free DoLP of \
         the region's summed Stokes vector.",
        &["target", "capture", "φ", "β", "β range", "β sd", "DoLP"],
        rows,
    )
}

/// The training plates' rendered indices.
fn reference_rows(out: &BenchOutput) -> Vec<report::ReferenceRow> {
    let mut references: Vec<report::ReferenceRow> = Vec::new();
    for t in out.truth.iter().filter(|t| !is_test(&t.target)) {
        if let (Some(c), Some(cls)) = (&t.calibrated, &t.class)
            && !references.iter().any(|r| &r.material == cls)
        {
            references.push(report::ReferenceRow {
                material: cls.clone(),
                n: c.n,
                k: c.k,
                source: "the rendered plate's index (650 nm, data/materials)".into(),
            });
        }
    }
    references
}

/// The scenes, manifests and tables the bench demo wrote.
fn inputs(out: &BenchOutput) -> Vec<report::InputItem> {
    common::inputs(
        &out.scenes,
        &out.manifests,
        |_| "calibrated bench: camera, table plane, nine lamp positions, five plates".into(),
        "[camera], [[plane]], regions on the plane, a lamp position per capture",
        &[
            (
                "measurements",
                "measurements.csv",
                "region DoLP per capture (measure)",
            ),
            ("fits", "fits.csv", "n, k with standard errors (fit)"),
            (
                "model",
                "model.json",
                "prototypes: the training fits (train)",
            ),
            (
                "classification",
                "classification.csv",
                "the test plates (classify)",
            ),
            (
                "map",
                "map/",
                "the test set's per-pixel maps (map, 4 × 4 binning)",
            ),
        ],
    )
}

/// The report's summary: the bench, and the result of the plates and the map.
fn summary(out: &BenchOutput) -> Vec<String> {
    let correct = common::correct(&out.classification);
    let (mut px, mut ok) = (0u64, 0u64);
    for r in &out.map.regions {
        px += r.pixels;
        ok += r.correct;
    }
    vec![
        "A lamp-and-lens bench in simulation, with calibrated geometry: five 10 cm plates \
         (aluminum, copper, brass, green paint, polycarbonate) on a table, a camera with a \
         40° lens 0.8 m away, a lamp 0.55–0.9 m away moved through nine positions, three of \
         them out of the plane of incidence. Every pixel has its own θi, θr, φ and β; the \
         manifest describes the camera, the table plane and the lamp positions instead of \
         angles. A training render and a test render (another noise seed, the lamp \
         mirrored) are measured and fitted; the training fits become the model that \
         classifies the test plates and maps the test set pixel by pixel."
            .to_string(),
        format!(
            "Result: {correct} of {} test plates classified correctly; in the map, {ok} of \
             {px} plate-region blocks ({:.1} %) get their plate's class.",
            out.classification.len(),
            if px > 0 {
                100.0 * ok as f64 / px as f64
            } else {
                f64::NAN
            }
        ),
    ]
}

/// The bench's settings.
fn manifest_rows(out: &BenchOutput) -> Vec<(String, String)> {
    vec![
        ("wavelength".into(), "650 nm (informational)".into()),
        (
            "camera".into(),
            format!(
                "{} × {} pixels, fx = 659.4 px (40° across), mild barrel distortion, \
                 0.8 m from the table at 50° zenith; 12 bit, 10 500 e⁻ full well, \
                 2.5 e⁻ read noise, dark level 64 DN",
                out.size.0, out.size.1
            ),
        ),
        (
            "exposure".into(),
            "auto per capture: brightest plate pixel at 70 % of full scale".into(),
        ),
        (
            "regions".into(),
            "the largest rectangle of each plate's pixels, inset by 1/8".into(),
        ),
        (
            "classifier".into(),
            format!(
                "test plates: {}; map: {} (answers: a material, `ambiguous` or \
                 `unknown`)",
                polarid_pipeline::demo::rows_rule(&out.classification),
                polarid_pipeline::demo::map_rule(&out.map)
            ),
        ),
    ]
}
