//! The lamp-and-lens bench demo (`polarid demo --bench`): calibrated geometry end to end.
//!
//! The bench of `examples/scenes/bench_lamp_lens.toml` — five 10 cm plates (aluminum,
//! copper, brass, green paint, polycarbonate at their 650 nm index), a camera with a
//! 40° lens 0.8 m away, a lamp 0.55–0.9 m away moved through nine positions, three of
//! them out of the plane of incidence — is rendered twice with the perspective renderer:
//! a training set (the example scene itself) and a test set (another noise seed, the lamp
//! positions mirrored across the camera's plane of incidence, target names prefixed with
//! `test_`). Then, from the image files, as the commands would: measure (both
//! manifests, per-pixel geometry) → fit → train (prototypes from the training fits) →
//! classify (the test fits) → map (the test set, 4 × 4 binning, with the trained model).
//!
//! Like the paper demo ([`super::run`]) everything is written into a staging directory
//! the caller owns: `captures/{train,test}/` (scene, frames, manifest, truth),
//! `measurements.csv`, `fits.csv`, `model.json`, `classification.csv`; the map itself is
//! returned ([`BenchOutput::map`]) for the front end to write. Deterministic.

use std::path::Path;

use polarid_io::atomic::StagedDir;
use polarid_io::model::Model;
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;

use super::steps;
use crate::map::{self, MapConfig, MapResult, Metric};
use crate::progress::{Progress, Warning};
use crate::simulate::TruthRow;
use crate::{PipelineError, Result};

/// The bench scene (the training set): `examples/scenes/bench_lamp_lens.toml`.
pub const BENCH_SCENE: &str = include_str!("../../../../examples/scenes/bench_lamp_lens.toml");

pub use super::bench_tables::{MAP_BIN, TEST_PREFIX};

/// The training captures whose β maps the report shows: the lamp in the plane of
/// incidence (capture 1) and out of it (capture 6).
pub const BETA_MAP_CAPTURES: [usize; 2] = [0, 5];

/// The test set's scene: [`BENCH_SCENE`] with seed + 1, the lamp positions mirrored
/// across the camera's plane of incidence (`y → −y`) and the plates' names prefixed
/// with [`TEST_PREFIX`] (classes unchanged).
pub fn test_scene_text() -> String {
    let mut out = String::from(
        "# The test set of `polarid demo --bench`: the bench of bench_lamp_lens.toml with\n\
         # another noise seed, the lamp positions mirrored (y -> -y) and test_ names.\n",
    );
    let mut section = "";
    for line in BENCH_SCENE.lines() {
        let t = line.trim_start();
        if t.starts_with('[') {
            section = if t.starts_with("[[source]]") {
                "source"
            } else if t.starts_with("[[plate]]") {
                "plate"
            } else {
                "other"
            };
        }
        let new = if section.is_empty() && t.starts_with("seed = ") {
            line.replacen("seed = 15", "seed = 16", 1)
        } else if section.is_empty() && t.starts_with("name = \"") {
            line.replacen("\"bench_lamp_lens\"", "\"bench_lamp_lens_test\"", 1)
        } else if section == "plate" && t.starts_with("name = \"") {
            line.replacen("name = \"", &format!("name = \"{TEST_PREFIX}"), 1)
        } else if section == "source" && t.starts_with("position = [") {
            mirror_y(line)
        } else {
            line.to_string()
        };
        out.push_str(&new);
        out.push('\n');
    }
    out
}

/// `position = [x, y, z]  # ...` with `y` negated (text otherwise kept).
fn mirror_y(line: &str) -> String {
    let (Some(a), Some(b)) = (line.find('['), line.find(']')) else {
        return line.to_string();
    };
    let parts: Vec<&str> = line[a + 1..b].split(',').map(str::trim).collect();
    let [x, y, z] = parts[..] else {
        return line.to_string();
    };
    let y = match y.strip_prefix('-') {
        Some(pos) => pos.to_string(),
        None if y.parse::<f64>().is_ok_and(|v| v == 0.0) => y.to_string(),
        None => format!("-{y}"),
    };
    format!("{}[{x}, {y}, {z}]{}", &line[..a], &line[b + 1..])
}

/// Everything the bench demo produced, besides the files in the staging directory.
#[derive(Debug, Clone)]
pub struct BenchOutput {
    /// Staged names of the two scene files (training, test).
    pub scenes: Vec<String>,
    /// Staged names of the two manifests (training, test).
    pub manifests: Vec<String>,
    /// The noise-free truth of both sets (training rows first).
    pub truth: Vec<TruthRow>,
    /// The measurements as re-read from `measurements.csv`.
    pub measurements: Vec<(u64, Measurement)>,
    /// The fits as re-read from `fits.csv`.
    pub fits: Vec<(u64, FitRow)>,
    /// The model trained on the training set's fits.
    pub model: Model,
    /// The test plates' classification rows.
    pub classification: Vec<ClassificationRow>,
    /// One explanation per test plate.
    pub notes: Vec<String>,
    /// The test set's map (4 × 4 binning, the trained model).
    pub map: MapResult,
    /// Frame size of the renders, pixels.
    pub size: (usize, usize),
    /// β maps (degrees, NaN off the plates) of two training captures: the capture's
    /// directory name and the map (`size.0 × size.1`, row-major).
    pub beta_maps: Vec<(String, Vec<f32>)>,
    /// The tables (fits against the truth, classification, map) as text.
    pub tables: String,
    /// Simulation, measurement and training warnings.
    pub warnings: Vec<Warning>,
}

/// Run the bench demo into `staged` (module documentation). Progress stages:
/// `simulating`, `frames`, `captures`, `fitting`, `captures (DoLP)`, `pixels (fit)`.
pub fn run_bench(staged: &StagedDir, progress: Progress) -> Result<BenchOutput> {
    let mut warnings = Vec::new();
    let mut manifests = Vec::new();
    let mut scenes = Vec::new();
    let mut truth = Vec::new();
    let mut beta_maps = Vec::new();
    let mut size = (0, 0);
    // 1. Simulate the training and the test sets.
    let sets = [
        ("train", BENCH_SCENE.to_string()),
        ("test", test_scene_text()),
    ];
    for (i, (set, text)) in sets.iter().enumerate() {
        progress("simulating", i as u64, sets.len() as u64);
        let dir = format!("captures/{set}/");
        let scene_path = staged.final_path(&format!("{dir}scene.toml"));
        let scene = steps::parse_scene(&scene_path, text)?;
        let sim = crate::simulate::simulate_into(&scene, staged, &dir, progress)?;
        if i == 0 {
            size = (scene.width, scene.height);
            for c in BETA_MAP_CAPTURES {
                let name = crate::simulate::capture_dir(&scene, c);
                beta_maps.push((name, crate::simulate::beta_map(&scene, c)?));
            }
        }
        warnings.extend(sim.warnings);
        truth.extend(sim.truth);
        manifests.push(sim.manifest);
        scenes.push(format!("{dir}scene.toml"));
    }
    progress("simulating", sets.len() as u64, sets.len() as u64);

    // 2. measure both sets from the image files, 3. fit.
    let fitted = steps::measure_and_fit(staged, &manifests, progress, &mut warnings)?;
    let (loaded, meas, all_fits) = (fitted.manifests, fitted.measurements, fitted.fits);

    // 4. train on the training set, 5. classify the test set.
    type Fits = Vec<(u64, FitRow)>;
    let (tests, training): (Fits, Fits) = all_fits
        .iter()
        .cloned()
        .partition(|(_, f)| f.target.starts_with(TEST_PREFIX));
    let steps::Classified {
        model,
        rows: class_rows,
        notes,
    } = steps::train_and_classify(staged, &training, &tests, &mut warnings)?;

    // 6. map the test set with the trained model.
    let cfg = MapConfig::new(MAP_BIN, None, None, Metric::Euclidean, map::DEFAULT_TILE)?;
    let test_manifest = loaded.last().ok_or_else(|| PipelineError::Data {
        path: "captures/test/manifest.toml".into(),
        reason: "internal error: no test manifest".into(),
    })?;
    let map = map::map_manifest(
        &cfg,
        test_manifest,
        &model,
        Path::new("model.json"),
        progress,
    )?;

    let tables = super::bench_tables::tables(&truth, &all_fits, &class_rows, &map);
    Ok(BenchOutput {
        scenes,
        manifests,
        truth,
        measurements: meas,
        fits: all_fits,
        model,
        classification: class_rows,
        notes,
        map,
        size,
        beta_maps,
        tables,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use polarid_io::manifest::SourceSpec;

    #[test]
    fn the_test_scene_mirrors_the_lamp_and_renames_the_plates() {
        let p = Path::new("s.toml");
        let train = polarid_io::scene::parse(p, BENCH_SCENE).unwrap();
        let test = polarid_io::scene::parse(p, &test_scene_text()).unwrap();
        assert_eq!((train.seed, test.seed), (15, 16));
        let (a, b) = (train.calibrated().unwrap(), test.calibrated().unwrap());
        assert_eq!(a.sources.len(), 9);
        assert_eq!(a.sources.len(), b.sources.len());
        let mut mirrored = 0;
        for (s, t) in a.sources.iter().zip(&b.sources) {
            let (SourceSpec::Position(s), SourceSpec::Position(t)) = (&s.spec, &t.spec) else {
                panic!("lamps expected");
            };
            assert_eq!([s[0], -s[1], s[2]], *t);
            mirrored += usize::from(s[1] != 0.0);
        }
        assert_eq!(mirrored, 4);
        for (p, q) in train.plates.iter().zip(&test.plates) {
            assert_eq!(format!("{TEST_PREFIX}{}", p.name), q.name);
            assert_eq!(
                (&p.class, p.optics, p.region),
                (&q.class, q.optics, q.region)
            );
        }
        // The example file is the scene of the demo's training set.
        let example = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/scenes/bench_lamp_lens.toml");
        assert_eq!(std::fs::read_to_string(example).unwrap(), BENCH_SCENE);
    }
}
