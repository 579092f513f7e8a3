//! `polarid demo [-o DIR]`: the paper's experiment (section 7) in simulation, end to end.
//!
//! Five capture sets are simulated from the pBRDF (paper eq. 3) with a 12-bit camera:
//! the training plates green paint (1.39 + 0.34i), aluminum (1.24 + 6.60i) and copper
//! (0.40 + 2.95i) at θr = 60° over the θi ranges of the paper's Table 1, and a test
//! aluminum plate of another roughness at θr = 60° and 50° over θi = 35…80° (Table 2).
//! Then the whole pipeline runs from the image files, as the commands would:
//! `measure` (every manifest) → `fit` (eq. 9) → `train` (prototypes from the training
//! fits) → `classify` (nearest neighbour in (n, k), § 6). The analogues of Tables 1 and 2
//! go to standard output; `DIR` receives the captures, the CSVs, `model.json`, the plots
//! and `report.html` / `report.md`. Deterministic (fixed seeds); a failure leaves nothing.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use polarid_core::classify::{Classifier, ClassifierConfig};
use polarid_io::atomic::{StagedDir, write_atomic};
use polarid_io::manifest;
use polarid_io::table::classification::{self, ClassificationRow};
use polarid_io::table::fits::{self, FitRow};
use polarid_io::table::measurements::{self, Measurement};
use polarid_pipeline::classify::{classification_row, estimate_of, explain, read_fits};
use polarid_pipeline::train::train;

use super::common::PipeResult;
use super::simulate::simulate_into;
use crate::render::plots::{self, PlotSize};
use crate::render::report::{self, Figure, Report};
use crate::{BadInput, Ctx};

/// Arguments of `polarid demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory (captures, CSVs, model, plots, report).
    #[arg(short, long, value_name = "DIR", default_value = "polarid-demo")]
    pub output: PathBuf,
}

/// One simulated plate of the demo.
struct DemoPlate {
    /// Target name.
    target: &'static str,
    /// Material (class).
    class: &'static str,
    /// Display name.
    label: &'static str,
    /// Index of refraction (paper Table 1 references).
    n: f64,
    k: f64,
    /// Roughness σ.
    sigma: f64,
    /// Camera zenith, degrees.
    theta_r: f64,
    /// Source zeniths: first, last (5° steps), degrees.
    theta_i: (f64, f64),
    /// Training plate (else test).
    training: bool,
}

const PLATES: [DemoPlate; 5] = [
    DemoPlate {
        target: "green_paint",
        class: "green_paint",
        label: "Green paint",
        n: 1.39,
        k: 0.34,
        sigma: 0.25,
        theta_r: 60.0,
        theta_i: (40.0, 80.0),
        training: true,
    },
    DemoPlate {
        target: "aluminum",
        class: "aluminum",
        label: "Aluminum",
        n: 1.24,
        k: 6.60,
        sigma: 0.20,
        theta_r: 60.0,
        theta_i: (35.0, 80.0),
        training: true,
    },
    DemoPlate {
        target: "copper",
        class: "copper",
        label: "Copper",
        n: 0.40,
        k: 2.95,
        sigma: 0.15,
        theta_r: 60.0,
        theta_i: (35.0, 70.0),
        training: true,
    },
    DemoPlate {
        target: "test_plate_60",
        class: "aluminum",
        label: "Test plate",
        n: 1.24,
        k: 6.60,
        sigma: 0.30,
        theta_r: 60.0,
        theta_i: (35.0, 80.0),
        training: false,
    },
    DemoPlate {
        target: "test_plate_50",
        class: "aluminum",
        label: "Test plate",
        n: 1.24,
        k: 6.60,
        sigma: 0.30,
        theta_r: 50.0,
        theta_i: (35.0, 80.0),
        training: false,
    },
];

/// The paper's own estimates (Tables 1 and 2), for comparison: target → (n̂, k̂).
fn paper_estimate(target: &str) -> Option<(f64, f64)> {
    match target {
        "green_paint" => Some((1.47, 0.47)),
        "aluminum" => Some((1.64, 4.56)),
        "copper" => Some((0.54, 3.19)),
        "test_plate_60" => Some((1.37, 3.97)),
        "test_plate_50" => Some((1.60, 4.34)),
        _ => None,
    }
}

/// Frame side, pixels (one plate per frame; the measured region is the central 96²).
const SIDE: usize = 128;

/// The scene file of one demo plate (see docs/SCENE.md).
fn scene_text(p: &DemoPlate, seed: u64) -> String {
    format!(
        r#"# polarid demo: {label} ({target}), the paper's section 7 in simulation.
# Re-run it alone with: polarid simulate scene.toml -o DIR
name = "{target}"
width = {SIDE}
height = {SIDE}
theta_r_deg = {tr:.1}
phi_deg = 180.0
theta_i_deg = {{ start = {i0:.1}, stop = {i1:.1}, step = 5.0 }}
wavelength_nm = 650.0
seed = {seed}
format = "png"

[sensor]                  # a 12-bit machine-vision camera
bit_depth = 12
full_well_e = 10500.0
read_noise_e = 2.5
dark_level_dn = 64.0
shot_noise = true

[exposure]                # brightest plate pixel at 70 % of full scale
mode = "auto"
fraction = 0.7

[capture]
kind = "frames"
angles_deg = [0, 45, 90, 135]

[[plate]]
name = "{target}"
class = "{class}"
n = {n}
k = {k}
sigma = {sigma}
rect = [0, 0, {SIDE}, {SIDE}]
region = [16, 16, 96, 96]
"#,
        label = p.label,
        target = p.target,
        class = p.class,
        tr = p.theta_r,
        i0 = p.theta_i.0,
        i1 = p.theta_i.1,
        n = p.n,
        k = p.k,
        sigma = p.sigma,
    )
}

/// `v ± se` with at least 3 decimals, more (up to 5) so that `se` shows two
/// significant digits.
fn pm(v: f64, se: f64) -> String {
    if se.is_finite() && se > 0.0 {
        let d = (1.0 - se.log10().floor()).clamp(3.0, 5.0) as usize;
        format!("{v:.d$} ± {se:.d$}")
    } else {
        format!("{v:.3} ± —")
    }
}

/// Pad `s` to `w` characters (by chars, not bytes).
fn pad(s: &str, w: usize) -> String {
    let n = s.chars().count();
    format!("{s}{}", " ".repeat(w.saturating_sub(n)))
}

/// Render a text table with a title.
fn text_table(title: &str, headers: &[&str], rows: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = headers.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate() {
            if let Some(w) = widths.get_mut(i) {
                *w = (*w).max(c.chars().count());
            }
        }
    }
    let mut s = format!("{title}\n");
    let line = |cells: Vec<String>| -> String {
        cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| pad(c, *w))
            .collect::<Vec<_>>()
            .join("  ")
            .trim_end()
            .to_string()
    };
    s.push_str(&line(headers.iter().map(|h| h.to_string()).collect()));
    s.push('\n');
    s.push_str(&"-".repeat(widths.iter().sum::<usize>() + 2 * (widths.len() - 1)));
    s.push('\n');
    for r in rows {
        s.push_str(&line(r.clone()));
        s.push('\n');
    }
    s
}

/// Write a text file into the staging directory.
fn stage_text(staged: &StagedDir, name: &str, text: &str) -> anyhow::Result<PathBuf> {
    let p = staged.path(name)?;
    write_atomic(&p, false, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| polarid_io::IoError::io(&p, e))
    })?;
    Ok(p)
}

/// Run `polarid demo`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let out = &args.output;
    if out.is_file() {
        return Err(BadInput(format!(
            "{}: the output must be a directory, and this is a file",
            out.display()
        ))
        .into());
    }
    if !ctx.force && out.join("report.html").exists() {
        return Err(polarid_io::IoError::OutputExists {
            path: out.join("report.html"),
        }
        .into());
    }
    let staged = StagedDir::new(out, ctx.force)?;

    // 1. Simulate the five capture sets.
    ctx.info(format!(
        "polarid demo: simulating {} capture sets ({SIDE}x{SIDE} pixels, 12-bit) into {}",
        PLATES.len(),
        out.display()
    ));
    let mut manifests = Vec::new();
    let mut scene_names = Vec::new();
    for (i, p) in PLATES.iter().enumerate() {
        let dir = format!("captures/{}/", p.target);
        let text = scene_text(p, 2007 + i as u64);
        let scene_path = staged.final_path(&format!("{dir}scene.toml"));
        let scene = polarid_io::scene::parse(&scene_path, &text)
            .context("internal error: a demo scene is invalid")?;
        let sim = simulate_into(&scene, &staged, &dir, ctx)?;
        for w in &sim.warnings {
            ctx.info(format!("polarid: warning: {w}"));
        }
        manifests.push(sim.manifest);
        scene_names.push(format!("{dir}scene.toml"));
    }

    // 2. measure: every manifest, from the image files just written.
    let mut rows: Vec<Measurement> = Vec::new();
    for m in &manifests {
        let man = manifest::load(&staged.path(m)?)?;
        rows.extend(super::measure::measure_manifest(&man, ctx)?);
    }
    let meas_path = staged.path("measurements.csv")?;
    write_atomic(&meas_path, false, |w| {
        measurements::write(w, Path::new("measurements.csv"), &rows)
    })?;

    // 3. fit: from the measurements file, as `polarid fit` reads it.
    let meas = polarid_pipeline::fit::read_measurements(&meas_path).cli()?;
    let fit_rows = super::common::with_progress(ctx, "fitting", |p| {
        polarid_pipeline::fit::fit(
            Path::new("measurements.csv"),
            &meas,
            &polarid_pipeline::fit::FitConfig::default(),
            p,
        )
    })
    .cli()?
    .rows();
    let fits_path = staged.path("fits.csv")?;
    write_atomic(&fits_path, false, |w| {
        fits::write(w, Path::new("fits.csv"), &fit_rows)
    })?;

    // 4. train on the training plates' fits.
    let all_fits = read_fits(&fits_path).cli()?;
    let is_training = |t: &str| PLATES.iter().any(|p| p.training && p.target == t);
    let training: Vec<(u64, FitRow)> = all_fits
        .iter()
        .filter(|(_, f)| is_training(&f.target))
        .cloned()
        .collect();
    let tests: Vec<(u64, FitRow)> = all_fits
        .iter()
        .filter(|(_, f)| !is_training(&f.target))
        .cloned()
        .collect();
    let trained = train(&training, Path::new("fits.csv"), "fits.csv").cli()?;
    for w in &trained.warnings {
        ctx.info(w.to_string());
    }
    let model = trained.model;
    let model_path = staged.path("model.json")?;
    write_atomic(&model_path, false, |w| {
        model.write(w, Path::new("model.json"))
    })?;

    // 5. classify the test fits against the model.
    let clf = Classifier::new(model.prototypes(), ClassifierConfig::default())
        .context("cannot use the trained model")?;
    let mut class_rows: Vec<ClassificationRow> = Vec::new();
    let mut notes = Vec::new();
    for (_, f) in &tests {
        let d = clf.classify(&estimate_of(f));
        notes.push(explain(&f.target, &d, &clf, 3));
        class_rows.push(classification_row(f, &d, &clf));
    }
    let class_path = staged.path("classification.csv")?;
    write_atomic(&class_path, false, |w| {
        classification::write(w, Path::new("classification.csv"), &class_rows)
    })?;

    // 6. The tables.
    let fit_of = |t: &str| all_fits.iter().map(|(_, f)| f).find(|f| f.target == t);
    let mut t1 = Vec::new();
    for p in PLATES.iter().filter(|p| p.training) {
        let Some(f) = fit_of(p.target) else { continue };
        let (pn, pk) = paper_estimate(p.target).unwrap_or((f64::NAN, f64::NAN));
        t1.push(vec![
            p.label.to_string(),
            format!("{:.0}-{:.0}", p.theta_i.0, p.theta_i.1),
            format!("{:.2}", p.n),
            format!("{:.2}", p.k),
            pm(f.n, f.n_se),
            pm(f.k, f.k_se),
            f.status.to_string(),
            format!("{pn:.2}, {pk:.2}"),
        ]);
    }
    let table1 = text_table(
        "Table 1. Training set (simulated), view angle 60°. n, k: the plates' true index \
         (the paper's references); n̂, k̂: estimates ± 1 standard error.",
        &[
            "Material",
            "θi (°)",
            "n",
            "k",
            "n̂",
            "k̂",
            "fit",
            "paper n̂, k̂",
        ],
        &t1,
    );
    let mut t2 = Vec::new();
    for p in PLATES.iter().filter(|p| !p.training) {
        let Some(f) = fit_of(p.target) else { continue };
        let c = class_rows.iter().find(|c| c.target == p.target);
        let (pn, pk) = paper_estimate(p.target).unwrap_or((f64::NAN, f64::NAN));
        t2.push(vec![
            format!("{:.0}", p.theta_r),
            pm(f.n, f.n_se),
            pm(f.k, f.k_se),
            c.map(|c| c.predicted.clone()).unwrap_or_default(),
            c.and_then(|c| c.distance)
                .map(|d| format!("{d:.3}"))
                .unwrap_or_default(),
            c.and_then(|c| {
                c.runner_up
                    .as_ref()
                    .map(|r| format!("{r} ({:.3})", c.runner_up_distance.unwrap_or(f64::NAN)))
            })
            .unwrap_or_default(),
            c.and_then(|c| c.margin)
                .map(|m| format!("{m:.3}"))
                .unwrap_or_default(),
            format!("{pn:.2}, {pk:.2}"),
        ]);
    }
    let table2 = text_table(
        "Table 2. Test aluminum plate (σ = 0.30, the training aluminum has 0.20), θi = 35-80°; \
         nearest neighbour in (n, k) against the training estimates.",
        &[
            "View angle (°)",
            "n̂",
            "k̂",
            "Classification",
            "distance",
            "runner-up (distance)",
            "margin",
            "paper n̂, k̂",
        ],
        &t2,
    );

    // 7. Plots and report.
    let mut by_target: BTreeMap<&str, Vec<&Measurement>> = BTreeMap::new();
    for (_, m) in &meas {
        by_target.entry(m.target.as_str()).or_default().push(m);
    }
    let series = |training: bool| -> Vec<plots::DolpSeries> {
        PLATES
            .iter()
            .filter(|p| p.training == training)
            .filter_map(|p| {
                let f = fit_of(p.target)?;
                let ms = by_target.get(p.target)?;
                let points: Vec<plots::DolpPoint> = ms
                    .iter()
                    .map(|m| plots::DolpPoint {
                        beta_deg: m.beta_deg,
                        dolp: m.dolp,
                        dolp_se: m.dolp_se,
                    })
                    .collect();
                let lo = points.iter().map(|q| q.beta_deg).fold(f64::MAX, f64::min);
                let hi = points.iter().map(|q| q.beta_deg).fold(f64::MIN, f64::max);
                let label = if training {
                    p.label.to_string()
                } else {
                    format!("test plate, θr = {:.0}°", p.theta_r)
                };
                Some(plots::DolpSeries {
                    label,
                    points,
                    curve: plots::eq9_curve(f.n, f.k, lo - 2.0, hi + 2.0, 60),
                    curve_label: Some(format!("fit n = {:.2}, k = {:.2}", f.n, f.k)),
                })
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
    let protos: Vec<plots::Prototype> = model
        .prototypes
        .iter()
        .map(|p| plots::Prototype {
            class: p.class.clone(),
            n: p.n,
            k: p.k,
        })
        .collect();
    let ests: Vec<plots::NkEstimate> = tests
        .iter()
        .map(|(_, f)| plots::NkEstimate {
            label: format!(
                "test, θr = {}°",
                PLATES
                    .iter()
                    .find(|p| p.target == f.target)
                    .map_or(f64::NAN, |p| p.theta_r)
            ),
            n: f.n,
            k: f.k,
            n_se: f.n_se,
            k_se: f.k_se,
            corr: if f.nk_corr.is_finite() {
                f.nk_corr
            } else {
                0.0
            },
            predicted: class_rows
                .iter()
                .find(|c| c.target == f.target)
                .map(|c| c.predicted.clone()),
        })
        .collect();
    let nk = plots::nk_plane(
        "Test estimates in the (n, k) plane, nearest-neighbour regions",
        &protos,
        &ests,
        size,
    )?;
    let plot_dir = staged.path("plots/.keep")?;
    let plot_dir = plot_dir.parent().map(Path::to_path_buf).unwrap_or_default();
    let _ = std::fs::remove_file(plot_dir.join(".keep"));
    dolp_train.write(&plot_dir, "dolp_training")?;
    dolp_test.write(&plot_dir, "dolp_test")?;
    nk.write(&plot_dir, "nk_plane")?;

    let rep = build_report(
        &all_fits,
        &meas,
        &class_rows,
        &scene_names,
        &manifests,
        [&dolp_train, &dolp_test, &nk],
    );
    let stage_dir = plot_dir.parent().map(Path::to_path_buf).unwrap_or_default();
    rep.write(&stage_dir, "report")?;
    stage_text(
        &staged,
        "tables.txt",
        &format!("{table1}\n{table2}\n{}\n", notes.join("\n")),
    )?;

    staged.commit()?;

    // stdout: the tables and the decisions.
    let mut so = String::new();
    let _ = writeln!(so, "{table1}");
    let _ = writeln!(so, "{table2}");
    for n in &notes {
        let _ = writeln!(so, "{n}");
    }
    let _ = writeln!(
        so,
        "\nReport: {}  (also report.md; CSVs, model.json and the captures in {})",
        out.join("report.html").display(),
        out.display()
    );
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(so.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
        r => r?,
    }
    ctx.info(format!(
        "polarid demo: done in {:.1} s",
        start.elapsed().as_secs_f64()
    ));
    Ok(())
}

/// The demo's report.
fn build_report(
    fits: &[(u64, FitRow)],
    meas: &[(u64, Measurement)],
    class_rows: &[ClassificationRow],
    scenes: &[String],
    manifests: &[String],
    figs: [&plots::Rendered; 3],
) -> Report {
    let plate = |t: &str| PLATES.iter().find(|p| p.target == t);
    let geometry = PLATES
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
        .collect();
    let references = PLATES
        .iter()
        .filter(|p| p.training)
        .map(|p| report::ReferenceRow {
            material: p.class.into(),
            n: p.n,
            k: p.k,
            source: "paper Table 1 (refs. [8, 10]); the simulated plates' index".into(),
        })
        .collect();
    let estimates = fits
        .iter()
        .map(|(_, f)| report::EstimateRow {
            target: f.target.clone(),
            class: f.class.clone(),
            theta_r_deg: plate(&f.target).map(|p| p.theta_r),
            n: f.n,
            n_se: f.n_se,
            k: f.k,
            k_se: f.k_se,
            nk_corr: f.nk_corr,
            rms_residual: f.rms_residual,
            measurements: f.measurements as usize,
            status: f.status,
        })
        .collect();
    let classification = class_rows
        .iter()
        .map(|c| report::ClassificationRow {
            target: c.target.clone(),
            truth: c.class.clone(),
            predicted: c.predicted.clone(),
            distance: c.distance.unwrap_or(f64::NAN),
            runner_up: c.runner_up.clone(),
            runner_up_distance: c.runner_up_distance,
            status: c.status.clone(),
        })
        .collect();
    let mut inputs: Vec<report::InputItem> = Vec::new();
    for (s, m) in scenes.iter().zip(manifests) {
        let t = s
            .trim_start_matches("captures/")
            .trim_end_matches("/scene.toml");
        let detail = plate(t)
            .map(|p| {
                format!(
                    "{} (n = {}, k = {}, σ = {}), θr = {}°, θi = {}–{}° in 5° steps, \
                     rotating polarizer 0/45/90/135°",
                    p.label, p.n, p.k, p.sigma, p.theta_r, p.theta_i.0, p.theta_i.1
                )
            })
            .unwrap_or_default();
        inputs.push(report::InputItem {
            role: "scene".into(),
            path: s.clone(),
            detail,
        });
        inputs.push(report::InputItem {
            role: "manifest".into(),
            path: m.clone(),
            detail: "written by the simulator, read by measure".into(),
        });
    }
    for (role, path, detail) in [
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
            "the test plate, nearest neighbour (classify)",
        ),
    ] {
        inputs.push(report::InputItem {
            role: role.into(),
            path: path.into(),
            detail: detail.into(),
        });
    }
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
    let mut summary = vec![
        "The paper's laboratory experiment (Thilak, Creusere & Voelz, ICIP 2007, section 7) \
         in simulation: flat plates of known index and roughness are rendered from the \
         Priest–Meier pBRDF (eq. 3) for a lamp moved in 5° steps in the plane of incidence, \
         seen by a 12-bit camera (10 500 e⁻ full well, 2.5 e⁻ read noise, shot noise) \
         behind a polarizer at 0/45/90/135°. polarid then measures the DoLP of a 96 × 96 \
         pixel region per capture from the image files, fits n and k (eq. 9), trains \
         nearest-neighbour prototypes on the three training plates and classifies the test \
         aluminum plate, which is rougher than the training one, at two view angles."
            .to_string(),
    ];
    let correct = class_rows
        .iter()
        .filter(|c| c.class.as_deref() == Some(c.predicted.as_str()))
        .count();
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
    }
    result.push('.');
    summary.push(result);
    Report {
        title: "polarid demo: material classification from polarization, the paper's \
                experiment in simulation"
            .into(),
        summary,
        inputs,
        manifest: vec![
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
                "nearest neighbour, Euclidean distance in (n, k)".into(),
            ),
        ],
        geometry,
        references,
        estimates,
        classification,
        tables: vec![report::Table {
            caption: "The paper's own estimates (Tables 1 and 2, real plates) beside the \
                      simulation's. The simulation has no model error, so its estimates \
                      land on the true index; the paper's differ from the references by the \
                      model error of real surfaces."
                .into(),
            headers: [
                "target",
                "θr (°)",
                "n̂ (here)",
                "k̂ (here)",
                "paper n̂",
                "paper k̂",
            ]
            .iter()
            .map(|s| s.to_string())
            .collect(),
            rows: paper_rows,
        }],
        figures: vec![
            Figure::from_rendered(
                "DoLP against β, training plates",
                "Measured DoLP of each training plate (points, ±1 standard-error bars, \
                 mostly smaller than the points) and the fitted eq. (9) curve.",
                figs[0],
                "plots/dolp_training.png",
                Some("plots/dolp_training.svg".into()),
            ),
            Figure::from_rendered(
                "DoLP against β, test plate",
                "The test aluminum plate at θr = 60° and 50°: the same material gives the \
                 same DoLP(β) curve from both view angles.",
                figs[1],
                "plots/dolp_test.png",
                Some("plots/dolp_test.svg".into()),
            ),
            Figure::from_rendered(
                "The (n, k) plane",
                "Training prototypes, the test estimates with their 1-σ ellipses, and the \
                 nearest-neighbour decision regions (Euclidean distance, § 6).",
                figs[2],
                "plots/nk_plane.png",
                Some("plots/nk_plane.svg".into()),
            ),
        ],
        generator: format!("polarid {} demo", env!("CARGO_PKG_VERSION")),
    }
}
