//! The paper's experiment (section 7) in simulation, end to end: the workflow of
//! `polarid demo`.
//!
//! Five capture sets are simulated from the pBRDF (paper eq. 3) with a 12-bit camera:
//! the training plates green paint (1.39 + 0.34i), aluminum (1.24 + 6.60i) and copper
//! (0.40 + 2.95i) at θr = 60° over the θi ranges of the paper's Table 1, and a test
//! aluminum plate of another roughness at θr = 60° and 50° over θi = 35…80° (Table 2).
//! Then the whole pipeline runs from the image files, as the commands would:
//! measure (every manifest) → fit (eq. 9) → train (prototypes from the training fits) →
//! classify (as `polarid classify --model` does by default: the materials consistent
//! with the estimate at 95%, the model from the same bench; docs/CLASSIFY.md). Table 2
//! gives the paper's nearest-neighbour answer (§ 6) beside it. Every plate carries its
//! material's native surface layer, of its own thickness (see `plates`).
//!
//! The demo is about files: [`run`] writes the captures (scene, frames, manifest, truth
//! per plate), `measurements.csv`, `fits.csv`, `model.json` and `classification.csv`
//! into a staging directory the caller owns (and commits or drops), and re-reads each
//! file as the next command would. What it returns — the rows, the model, the
//! explanations, the text of Tables 1 and 2 — is what a front end needs for its plots,
//! report and printout. Deterministic (fixed seeds).
//!
//! [`bench`](mod@bench) is the second demo (`polarid demo --bench`): a lamp-and-lens bench with
//! calibrated geometry, from renders to a material map. [`colour`] is the third
//! (`polarid demo --color`): a colour polarization camera telling copper from gold.

pub mod bench;
mod bench_tables;
pub mod colour;
mod plates;
mod steps;
mod tables;

use polarid_io::atomic::{StagedDir, write_atomic};
use polarid_io::model::Model;
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;

pub use bench_tables::{map_rule, rows_rule};
pub use plates::{
    DemoPlate, PLATES, SIDE, WAVELENGTH_NM, native_layer, paper_estimate, scene_text, scene_text_at,
};
pub use steps::same_bench_classifier;
pub use tables::{paper_tables, pm, text_table};

use crate::Result;
use crate::progress::{Progress, Warning};

/// Everything the demo produced, besides the files in the staging directory.
#[derive(Debug, Clone)]
pub struct DemoOutput {
    /// Staged names of the scene files (`captures/TARGET/scene.toml`), one per plate.
    pub scenes: Vec<String>,
    /// Staged names of the manifests (`captures/TARGET/manifest.toml`), one per plate.
    pub manifests: Vec<String>,
    /// The measurements as re-read from `measurements.csv` (with their line numbers).
    pub measurements: Vec<(u64, Measurement)>,
    /// The fits as re-read from `fits.csv` (with their line numbers).
    pub fits: Vec<(u64, FitRow)>,
    /// The model trained on the training plates.
    pub model: Model,
    /// The test plate's classification rows (one per view angle).
    pub classification: Vec<ClassificationRow>,
    /// One explanation per test view (nearest prototypes and distances).
    pub notes: Vec<String>,
    /// Table 1 (training set) as text.
    pub table1: String,
    /// Table 2 (test plate) as text.
    pub table2: String,
    /// Simulation, saturation and training warnings, in the order they arose.
    pub warnings: Vec<Warning>,
}

/// Write `write`'s output to the staged file `name`.
fn stage(
    staged: &StagedDir,
    name: &str,
    write: impl FnOnce(&mut dyn std::io::Write) -> polarid_io::Result<()>,
) -> Result<std::path::PathBuf> {
    let p = staged.path(name)?;
    write_atomic(&p, false, write)?;
    Ok(p)
}

/// Run the demo into `staged` (see the module documentation). Progress stages:
/// `simulating` (per plate), `captures` (per capture measured), `fitting` (per target).
pub fn run(staged: &StagedDir, progress: Progress) -> Result<DemoOutput> {
    let mut warnings = Vec::new();

    // 1. Simulate the five capture sets.
    let mut manifests = Vec::new();
    let mut scenes = Vec::new();
    for (i, p) in PLATES.iter().enumerate() {
        progress("simulating", i as u64, PLATES.len() as u64);
        let dir = format!("captures/{}/", p.target);
        let text = scene_text(p, 2007 + i as u64);
        let scene_path = staged.final_path(&format!("{dir}scene.toml"));
        let scene = steps::parse_scene(&scene_path, &text)?;
        let sim = crate::simulate::simulate_into(&scene, staged, &dir, progress)?;
        warnings.extend(sim.warnings);
        manifests.push(sim.manifest);
        scenes.push(format!("{dir}scene.toml"));
    }
    progress("simulating", PLATES.len() as u64, PLATES.len() as u64);

    // 2. measure every manifest, from the image files just written; 3. fit.
    let fitted = steps::measure_and_fit(staged, &manifests, progress, &mut warnings)?;
    let (meas, all_fits) = (fitted.measurements, fitted.fits);

    // 4. train on the training plates' fits, 5. classify the test fits.
    let is_training = |t: &str| PLATES.iter().any(|p| p.training && p.target == t);
    let (training, tests): (Vec<(u64, FitRow)>, Vec<(u64, FitRow)>) = all_fits
        .iter()
        .cloned()
        .partition(|(_, f)| is_training(&f.target));
    let steps::Classified {
        model,
        rows: class_rows,
        notes,
    } = steps::train_and_classify(staged, &training, &tests, &mut warnings)?;

    let (table1, table2) = paper_tables(&all_fits, &class_rows);
    Ok(DemoOutput {
        scenes,
        manifests,
        measurements: meas,
        fits: all_fits,
        model,
        classification: class_rows,
        notes,
        table1,
        table2,
        warnings,
    })
}
