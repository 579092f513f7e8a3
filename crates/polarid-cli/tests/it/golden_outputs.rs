//! Byte-identical outputs (issue 14): `polarid demo`, the README's step-by-step example
//! and `polarid map` on simulated sets (full resolution, `--bin 2`, a DoFP set) must
//! produce exactly the files they produced before the workflows moved into
//! `polarid-pipeline`. The SHA-256 of every output file is kept in
//! `tests/golden/hashes.txt` (`map_summary.json` normalised by serde_json; it holds no
//! wall-clock time).
//!
//! A deliberate change of an output regenerates the list:
//! `POLARID_BLESS=1 cargo test --release -p polarid-cli --test it golden_outputs::`, and the
//! commit says why the bytes changed.
//!
//! The fit kernels give bit-identical results with AVX-512 and AVX2 + FMA; the portable
//! path agrees only to ~1e-9, so on a CPU without AVX2 + FMA the test is skipped.

use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use common::{polarid_in, text};
use sha2::{Digest, Sha256};

const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/hashes.txt");
const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/scenes");

fn run(dir: &Path, args: &[&str]) {
    let out = polarid_in(dir, args);
    assert!(
        out.status.success(),
        "polarid {args:?} failed: {}",
        text(&out.stderr)
    );
}

/// Every file under `root`, as `relative path -> bytes to hash`.
fn files(root: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("read output directory")
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            files(root, &p, out);
            continue;
        }
        let rel = p
            .strip_prefix(root)
            .expect("under root")
            .to_string_lossy()
            .replace('\\', "/");
        let mut bytes = std::fs::read(&p).expect("read output");
        if p.file_name().is_some_and(|n| n == "map_summary.json") {
            let v: serde_json::Value = serde_json::from_slice(&bytes).expect("JSON");
            // Since issue 19 the file holds no wall-clock time (it used to be removed
            // here before hashing); the hash is of the same normalised JSON as before.
            assert!(
                v.get("seconds").is_none(),
                "{}: map_summary.json must not hold wall-clock seconds",
                p.display()
            );
            bytes = serde_json::to_vec_pretty(&v).expect("JSON");
        }
        out.insert(rel, bytes);
    }
}

fn simd_fit_path() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[test]
fn demo_example_and_maps_are_byte_identical() {
    if !simd_fit_path() {
        eprintln!("skipped: the golden hashes were made with the AVX2/AVX-512 fit kernels");
        return;
    }
    let tmp = tempfile::tempdir().expect("temp dir");
    let d = tmp.path();
    let scene = |s: &str| format!("{SCENES}/{s}.toml");
    run(d, &["demo", "-o", "demo", "-q"]);
    // The README's step-by-step example.
    run(
        d,
        &[
            "simulate",
            &scene("paper_training_60"),
            "-o",
            "sim/train",
            "-q",
        ],
    );
    run(
        d,
        &[
            "measure",
            "sim/train/manifest.toml",
            "-o",
            "sim/train/measurements.csv",
            "-q",
        ],
    );
    run(
        d,
        &[
            "fit",
            "sim/train/measurements.csv",
            "-o",
            "sim/train/fits.csv",
            "-q",
        ],
    );
    run(
        d,
        &["train", "sim/train/fits.csv", "-o", "sim/model.json", "-q"],
    );
    run(
        d,
        &[
            "simulate",
            &scene("aluminum_test_60"),
            "-o",
            "sim/test60",
            "-q",
        ],
    );
    run(
        d,
        &[
            "measure",
            "sim/test60/manifest.toml",
            "-o",
            "sim/test60/measurements.csv",
            "-q",
        ],
    );
    run(
        d,
        &[
            "fit",
            "sim/test60/measurements.csv",
            "-o",
            "sim/test60/fits.csv",
            "-q",
        ],
    );
    let out = polarid_in(
        d,
        &[
            "classify",
            "sim/test60/fits.csv",
            "--model",
            "sim/model.json",
            "-q",
        ],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    std::fs::write(d.join("sim/classify.csv"), &out.stdout).expect("write");
    // A DoFP set, and maps.
    run(
        d,
        &["simulate", &scene("dofp_plates"), "-o", "sim/dofp", "-q"],
    );
    run(
        d,
        &[
            "measure",
            "sim/dofp/manifest.toml",
            "-o",
            "sim/dofp/measurements.csv",
            "-q",
        ],
    );
    run(
        d,
        &[
            "fit",
            "sim/dofp/measurements.csv",
            "-o",
            "sim/dofp/fits.csv",
            "-q",
        ],
    );
    let model = "sim/model.json";
    run(
        d,
        &[
            "map",
            "sim/test60/manifest.toml",
            "--model",
            model,
            "-o",
            "map1",
            "-q",
        ],
    );
    run(
        d,
        &[
            "map",
            "sim/train/manifest.toml",
            "--model",
            model,
            "-o",
            "map2",
            "--bin",
            "2",
            "-q",
        ],
    );
    run(
        d,
        &[
            "map",
            "sim/dofp/manifest.toml",
            "--model",
            model,
            "-o",
            "map3",
            "-q",
        ],
    );

    let mut all = BTreeMap::new();
    for sub in ["demo", "sim", "map1", "map2", "map3"] {
        files(d, &d.join(sub), &mut all);
    }
    let listing: String = all
        .iter()
        .map(|(name, bytes)| format!("{:x}  {name}\n", Sha256::digest(bytes)))
        .collect();
    if std::env::var_os("POLARID_BLESS").is_some() {
        std::fs::create_dir_all(Path::new(GOLDEN).parent().expect("parent")).expect("mkdir");
        std::fs::write(GOLDEN, &listing).expect("write golden hashes");
        return;
    }
    let golden = std::fs::read_to_string(GOLDEN).expect("tests/golden/hashes.txt");
    let want: BTreeMap<&str, &str> = golden
        .lines()
        .filter_map(|l| l.split_once("  ").map(|(h, n)| (n, h)))
        .collect();
    let got: BTreeMap<&str, &str> = listing
        .lines()
        .filter_map(|l| l.split_once("  ").map(|(h, n)| (n, h)))
        .collect();
    let mut diffs = Vec::new();
    for (name, h) in &want {
        match got.get(name) {
            None => diffs.push(format!("missing: {name}")),
            Some(g) if g != h => diffs.push(format!("changed: {name}")),
            _ => {}
        }
    }
    for name in got.keys().filter(|n| !want.contains_key(*n)) {
        diffs.push(format!("new: {name}"));
    }
    assert!(
        diffs.is_empty(),
        "outputs differ from tests/golden/hashes.txt:\n{}",
        diffs.join("\n")
    );
}
