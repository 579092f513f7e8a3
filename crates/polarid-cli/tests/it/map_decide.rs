//! `polarid map` decides every block as `polarid classify` decides a target: against the
//! built-in library by the hypothesis tests on the block's own rows (single-band
//! captures with a wavelength), and against a model trained on the same bench by the
//! same-bench test. The bench: `polarid simulate` of six plates (aluminum, copper, gold,
//! PMMA, N-BK7, silicon at 550 nm, their library indices) under a perspective camera and a
//! lamp 0.7 m away at nine positions, frames of 240×180 mapped at `--bin 4`; the training
//! set is the same bench with another noise seed. The full-size bench (480×360) is
//! measured in docs/BANDS.md ("Maps decide as classify").

use crate::common;

use common::{polarid, text};

use std::path::Path;

/// The bench's scene (`seed` the noise seed, `scale` 1 for 240×180 frames).
fn scene(seed: u64, scale: usize) -> String {
    let (w, h) = (240 * scale, 180 * scale);
    let f = 329.7 * scale as f64;
    let lamps: String = [
        (35.0, 0.0),
        (42.0, 0.0),
        (50.0, 0.0),
        (58.0, 0.0),
        (66.0, 0.0),
        (45.0, 25.0),
        (55.0, -20.0),
        (70.0, 12.0),
        (40.0, -30.0),
    ]
    .iter()
    .map(|&(t, a): &(f64, f64)| {
        let (t, a) = (t.to_radians(), a.to_radians());
        format!(
            "[[source]]\nposition = [{:.5}, {:.5}, {:.5}]\n",
            0.7 * t.sin() * a.cos(),
            0.7 * t.sin() * a.sin(),
            0.7 * t.cos()
        )
    })
    .collect();
    let plates: String = [
        ("aluminum", 0.2, 0.065, -0.13),
        ("copper", 0.15, 0.065, 0.0),
        ("gold", 0.15, 0.065, 0.13),
        ("PMMA", 0.2, -0.065, -0.13),
        ("N-BK7", 0.2, -0.065, 0.0),
        ("silicon", 0.15, -0.065, 0.13),
    ]
    .iter()
    .map(|&(m, s, x, y)| {
        format!(
            "[[plate]]\nname = \"{m}\"\nmaterial = \"{m}\"\nsigma = {s}\ncenter = [{x}, {y}, 0.0]\n\
             size = [0.1, 0.1]\naxis = [0.0, 1.0, 0.0]\n"
        )
    })
    .collect();
    format!(
        "name = \"bench6\"\nwidth = {w}\nheight = {h}\nwavelength_nm = 550.0\nbackground = 0.0\n\
         seed = {seed}\nformat = \"png\"\n\n[sensor]\nbit_depth = 12\nfull_well_e = 10500.0\n\
         read_noise_e = 2.5\ndark_level_dn = 64.0\nshot_noise = true\n\n[exposure]\n\
         mode = \"auto\"\nfraction = 0.7\n\n[capture]\nkind = \"frames\"\n\
         angles_deg = [0, 45, 90, 135]\n\n[camera]\nfocal_px = {f}\n\
         principal_point_px = [{:.1}, {:.1}]\ndistortion = [-0.08, 0.02, 0.0, 0.0, 0.0]\n\
         position = [-0.6128, 0.0, 0.5142]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, 1.0]\n\n\
         [[plane]]\nname = \"table\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n\n\
         {lamps}\n{plates}",
        (w as f64 - 1.0) / 2.0,
        (h as f64 - 1.0) / 2.0,
    )
}

/// Simulate the bench into `dir` (its manifest).
pub fn simulate_bench(dir: &Path, seed: u64, scale: usize) -> std::path::PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let toml = dir.join("scene.toml");
    std::fs::write(&toml, scene(seed, scale)).unwrap();
    let out = dir.join("sim");
    let o = polarid(&[
        "simulate",
        toml.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    out.join("manifest.toml")
}

/// Per labelled region of a map's summary: (name, blocks, classified as one material,
/// right).
pub fn region_scores(summary: &Path) -> Vec<(String, u64, u64, u64)> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(summary).unwrap()).unwrap();
    v["regions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            let pixels = r["pixels"].as_u64().unwrap();
            let classes = r["classes"].as_object().unwrap();
            let none: u64 = ["unknown", "ambiguous"]
                .iter()
                .filter_map(|c| classes.get(*c).and_then(|x| x.as_u64()))
                .sum();
            (
                r["name"].as_str().unwrap().to_string(),
                pixels,
                pixels - none,
                r["correct"].as_u64().unwrap_or(0),
            )
        })
        .collect()
}

/// Map `manifest` with `args` into `dir/name`; the per-region scores.
fn map(manifest: &Path, dir: &Path, name: &str, args: &[&str]) -> Vec<(String, u64, u64, u64)> {
    let out = dir.join(name);
    let mut a = vec![
        "map",
        manifest.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(args);
    let o = polarid(&a);
    assert!(o.status.success(), "{name}: {}", text(&o.stderr));
    region_scores(&out.join("map_summary.json"))
}

#[test]
fn bench_plates_are_decided_per_block_against_a_library_and_a_same_bench_model() {
    let dir = std::env::temp_dir().join(format!("polarid-map-decide-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let test = simulate_bench(&dir.join("test"), 27, 1);
    let train = simulate_bench(&dir.join("train"), 28, 1);

    // Against the built-in library at the captures' 550 nm: the hypothesis tests.
    let lib = map(&test, &dir, "lib", &["--library", "builtin", "--bin", "4"]);
    // Against a model trained on the same bench.
    let (m, f, model) = (dir.join("m.csv"), dir.join("f.csv"), dir.join("model.json"));
    for args in [
        vec![
            "measure",
            train.to_str().unwrap(),
            "-o",
            m.to_str().unwrap(),
        ],
        vec!["fit", m.to_str().unwrap(), "-o", f.to_str().unwrap()],
        vec!["train", f.to_str().unwrap(), "-o", model.to_str().unwrap()],
    ] {
        let o = polarid(&args);
        assert!(o.status.success(), "{args:?}: {}", text(&o.stderr));
    }
    let mdl = map(
        &test,
        &dir,
        "model",
        &["--model", model.to_str().unwrap(), "--bin", "4"],
    );
    for (what, scores) in [("library", &lib), ("model", &mdl)] {
        assert_eq!(scores.len(), 6, "{what}: {scores:?}");
        for (name, blocks, classified, right) in scores {
            eprintln!("{what} {name}: {blocks} blocks, {classified} classified, {right} right");
            assert!(*blocks >= 20, "{what} {name}: {blocks} blocks");
            // No block is given a wrong material.
            assert_eq!(classified, right, "{what} {name}: {scores:?}");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
