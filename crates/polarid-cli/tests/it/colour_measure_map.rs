//! Colour polarization captures through `measure`, `fit`, `classify` and `map` (issue 17):
//! simulated IMX250MYR-type mosaics (RGGB blocks of 90/45/135/0 polarizers) of copper,
//! gold and aluminum plates whose (n, k) at 450, 550 and 650 nm are the built-in
//! three-band library's. Each band's four polarizer frames are rendered with
//! `polarid_core::simulate` (shot and read noise, 12 bits) from that band's Stokes
//! radiance, and the colour mosaic takes every raw pixel from the frame of its colour and
//! polarizer. The surfaces are clean, so the fits use `--film-sd-nm 0`.
//!
//! Print the figures with `cargo test --release -p polarid-cli --test it colour_measure_map::
//! -- --nocapture`.

use crate::common;

use common::{csv_rows, polarid_in, text};

use std::path::{Path, PathBuf};
use std::process::Output;

use polarid_core::mosaic::ColourPattern;
use polarid_core::simulate::{
    Analyzer, PlateOptics, Sensor, UniformRect, plate_radiance, render_frame,
};
use polarid_io::library::Library;

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "status {:?}\nstderr: {}",
        o.status,
        text(&o.stderr)
    );
}

const SIZE: usize = 48;
const GAP: usize = 12;
const WIDTH: usize = 3 * SIZE + 4 * GAP;
const HEIGHT: usize = SIZE + 2 * GAP;
const BANDS: [f64; 3] = [450.0, 550.0, 650.0];

/// A plate: name (= class), column of its left edge, `(n, k)` at 450, 550, 650 nm.
struct Plate {
    name: &'static str,
    x: usize,
    nk: [(f64, f64); 3],
}

fn plates() -> Vec<Plate> {
    let lib = Library::builtin_rgb().unwrap();
    ["copper", "gold", "aluminum"]
        .iter()
        .enumerate()
        .map(|(i, &name)| {
            let nk = BANDS.map(|w| {
                let m = lib
                    .materials
                    .iter()
                    .find(|m| m.name == name && m.wavelength_nm == Some(w))
                    .unwrap();
                (m.n, m.k)
            });
            Plate {
                name,
                x: GAP + i * (SIZE + GAP),
                nk,
            }
        })
        .collect()
}

/// Write 10 colour captures (θi = 35…80°, θr = 60°, 12-bit, dark level 64 DN) and the
/// manifest (regions: the plates' interiors, 6-pixel margin); returns the manifest.
fn write_scene(dir: &Path) -> PathBuf {
    let sensor = Sensor {
        bit_depth: 12,
        full_well_e: 32_000.0,
        read_noise_e: 16.0,
        dark_level_dn: 64.0,
        shot_noise: true,
    };
    let pattern = ColourPattern::imx250myr();
    // Band index of the pattern (R, G, B) -> index into BANDS.
    let band_of: Vec<usize> = pattern
        .bands()
        .iter()
        .map(|c| match c {
            'B' => 0,
            'G' => 1,
            _ => 2,
        })
        .collect();
    let plates = plates();
    let theta_r = 60f64.to_radians();
    let mut text = String::from(
        "theta_r_deg = 60.0\nphi_deg = 180.0\ndark_level = 64.0\nsaturation = 4095.0\n\
         bands = { R = 650.0, G = 550.0, B = 450.0 }\n",
    );
    for p in &plates {
        text += &format!(
            "\n[[region]]\nname = \"{0}\"\nrect = [{1}, {2}, {3}, {3}]\nclass = \"{0}\"\n",
            p.name,
            p.x + 6,
            GAP + 6,
            SIZE - 12
        );
    }
    let mut frame = vec![0u16; WIDTH * HEIGHT];
    for (ci, ti) in (0..10).map(|i| 35.0 + 5.0 * i as f64).enumerate() {
        let theta_i = f64::to_radians(ti);
        // rects[band][plate]
        let rects: Vec<Vec<UniformRect>> = (0..3)
            .map(|b| {
                plates
                    .iter()
                    .map(|p| {
                        let optics = PlateOptics {
                            n: p.nk[b].0,
                            k: p.nk[b].1,
                            sigma: 0.15,
                            rho_d: 0.0,
                        };
                        UniformRect {
                            x: p.x,
                            y: GAP,
                            width: SIZE,
                            height: SIZE,
                            stokes: plate_radiance(&optics, theta_i, theta_r, std::f64::consts::PI)
                                .unwrap(),
                        }
                    })
                    .collect()
            })
            .collect();
        let brightest = rects
            .iter()
            .flatten()
            .map(|r| 0.5 * (r.stokes[0] + r.stokes[1].hypot(r.stokes[2])))
            .fold(0.0, f64::max);
        let e_per_unit = 0.7 * sensor.full_well_e / brightest;
        // frames[band][angle index: 0, 45, 90, 135]
        let mut frames = vec![vec![vec![0u16; WIDTH * HEIGHT]; 4]; 3];
        for (b, band_rects) in rects.iter().enumerate() {
            for (a, out) in frames[b].iter_mut().enumerate() {
                let angle = (45.0 * a as f64).to_radians();
                let seed = 10_000 * ci as u64 + 100 * b as u64 + a as u64;
                render_frame(
                    WIDTH,
                    HEIGHT,
                    band_rects,
                    [0.0; 3],
                    Analyzer::Uniform(angle),
                    &sensor,
                    e_per_unit,
                    seed,
                    out,
                )
                .unwrap();
            }
        }
        for (i, v) in frame.iter_mut().enumerate() {
            let (band, angle) = pattern.channel_at(i / WIDTH, i % WIDTH);
            *v = frames[band_of[band]][angle][i];
        }
        let name = format!("raw_{ti}.tif");
        polarid_io::image::write_gray16(&dir.join(&name), true, WIDTH, HEIGHT, &frame).unwrap();
        text += &format!(
            "\n[[capture]]\ntheta_i_deg = {ti}\n\
             dofp = {{ file = \"{name}\", pattern = [90, 45, 135, 0], color = \"RGGB\" }}\n"
        );
    }
    let m = dir.join("colour.toml");
    std::fs::write(&m, text).unwrap();
    m
}

fn num(r: &std::collections::HashMap<String, String>, key: &str) -> f64 {
    r[key].parse().unwrap_or(f64::NAN)
}

#[test]
fn colour_plates_measure_fit_classify_and_map_per_band() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let manifest = write_scene(d);
    let plates = plates();
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();

    // measure: one row per (target, capture, band), with the band's wavelength.
    ok(&polarid_in(
        d,
        &["measure", &p("colour.toml"), "-o", &p("meas.csv")],
    ));
    let rows = csv_rows(&d.join("meas.csv"));
    assert_eq!(rows.len(), 3 * 10 * 3);
    for (i, r) in rows.iter().enumerate() {
        // capture by capture, band by band (increasing wavelength), targets in order
        let want_band = BANDS[(i / 3) % 3];
        assert_eq!(num(r, "wavelength_nm"), want_band, "{r:?}");
        assert_eq!(r["target"], plates[i % 3].name);
        assert!(num(r, "pixels") > 1000.0, "{r:?}");
    }

    // fit: one row per target per band, each band within 3 SE (+ a small floor) of truth.
    ok(&polarid_in(
        d,
        &[
            "fit",
            &p("meas.csv"),
            "-o",
            &p("fits.csv"),
            "--film-sd-nm",
            "0",
        ],
    ));
    let fits = csv_rows(&d.join("fits.csv"));
    assert_eq!(fits.len(), 9);
    for f in &fits {
        let plate = plates.iter().find(|pl| pl.name == f["target"]).unwrap();
        let b = BANDS
            .iter()
            .position(|&w| w == num(f, "wavelength_nm"))
            .unwrap();
        let (n0, k0) = plate.nk[b];
        let (n, k, n_se, k_se) = (num(f, "n"), num(f, "k"), num(f, "n_se"), num(f, "k_se"));
        println!(
            "fit {:9} {:.0} nm: n {n:.4} ± {n_se:.4} (true {n0:.4}, {:+.2} SE)  k {k:.4} ± {k_se:.4} (true {k0:.4}, {:+.2} SE)",
            plate.name,
            BANDS[b],
            (n - n0) / n_se,
            (k - k0) / k_se
        );
        assert!((n - n0).abs() <= 3.0 * n_se + 0.01, "{f:?}");
        assert!((k - k0).abs() <= 3.0 * k_se + 0.02, "{f:?}");
    }

    // classify on all bands against the built-in three-band library.
    ok(&polarid_in(
        d,
        &[
            "classify",
            &p("fits.csv"),
            "--library",
            "builtin-rgb",
            "-o",
            &p("classes.csv"),
        ],
    ));
    for r in csv_rows(&d.join("classes.csv")) {
        println!(
            "classify {}: {} ({}; bands {})",
            r["target"], r["predicted"], r["status"], r["bands_used"]
        );
        assert_eq!(r["predicted"], r["target"], "{r:?}");
        assert_eq!(r["bands_used"], "450;550;650", "{r:?}");
    }

    // map, 4x4 bins, against the library: per-band fits and one class per pixel.
    let out = d.join("map");
    ok(&polarid_in(
        d,
        &[
            "map",
            manifest.to_str().unwrap(),
            "--library",
            "builtin-rgb",
            "--bin",
            "4",
            "-o",
            out.to_str().unwrap(),
        ],
    ));
    check_map(&out, &plates, "library");

    // map with a model trained on the three-band fits: the same answers.
    ok(&polarid_in(
        d,
        &["train", &p("fits.csv"), "-o", &p("model.json")],
    ));
    let out2 = d.join("map_model");
    ok(&polarid_in(
        d,
        &[
            "map",
            manifest.to_str().unwrap(),
            "--model",
            &p("model.json"),
            // The systematic error model on both sides (the same-bench default:
            // `map_decide`).
            "--bench",
            "other",
            "--bin",
            "4",
            "-o",
            out2.to_str().unwrap(),
        ],
    ));
    check_map(&out2, &plates, "model");
}

/// The per-band maps' `(n, k)` on the plates' interior blocks are within 3 SE of the
/// truth (≥ 90% of blocks, per band and plate), ≥ 90% of those blocks get their
/// material and none another material (the rest are `ambiguous` or unknown).
fn check_map(out: &Path, plates: &[Plate], what: &str) {
    assert!(!out.join("n.tif").exists(), "a colour map has no n.tif");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("map_summary.json")).unwrap())
            .unwrap();
    let bands: Vec<f64> = summary["bands"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["wavelength_nm"].as_f64().unwrap())
        .collect();
    assert_eq!(bands, BANDS.to_vec(), "{summary}");
    let classes: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("classes.json")).unwrap()).unwrap();
    let class = polarid_io::image::read_frame(&out.join("class.tif")).unwrap();
    let (w, h) = (class.width, class.height);
    assert_eq!((w, h), (WIDTH / 4, HEIGHT / 4));
    let read = |name: String| polarid_io::image::read_frame(&out.join(name)).unwrap().data;
    for p in plates {
        // interior blocks of the plate (one block of margin)
        let blocks: Vec<usize> = ((GAP / 4 + 1)..((GAP + SIZE) / 4 - 1))
            .flat_map(|y| ((p.x / 4 + 1)..((p.x + SIZE) / 4 - 1)).map(move |x| y * w + x))
            .collect();
        let answer = |i: usize| classes[class.data[i].to_string()].as_str().unwrap_or("");
        let right = blocks.iter().filter(|&&i| answer(i) == p.name).count();
        let others: Vec<&str> = blocks
            .iter()
            .map(|&i| answer(i))
            .filter(|&a| a != p.name && a != "ambiguous" && a != "unknown")
            .collect();
        let frac = right as f64 / blocks.len() as f64;
        println!(
            "map ({what}) {}: {right}/{} blocks right ({:.1}%), {} another material",
            p.name,
            blocks.len(),
            100.0 * frac,
            others.len()
        );
        // The rest is `ambiguous` (the set rule's honest answer), never another material.
        assert!(
            frac >= 0.9 && others.is_empty(),
            "{}: {frac} {others:?}",
            p.name
        );
        for (b, &wl) in BANDS.iter().enumerate() {
            let [n, k, n_se, k_se] =
                ["n", "k", "n_se", "k_se"].map(|f| read(format!("{f}_{wl:.0}.tif")));
            let (n0, k0) = p.nk[b];
            let within = |v: &[f32], se: &[f32], t: f64| {
                blocks
                    .iter()
                    .filter(|&&i| (v[i] as f64 - t).abs() <= 3.0 * se[i] as f64)
                    .count() as f64
                    / blocks.len() as f64
            };
            let (fn_, fk) = (within(&n, &n_se, n0), within(&k, &k_se, k0));
            let mut ns: Vec<f64> = blocks.iter().map(|&i| n[i] as f64).collect();
            ns.sort_by(f64::total_cmp);
            let med_se: f64 = {
                let mut s: Vec<f64> = blocks.iter().map(|&i| n_se[i] as f64).collect();
                s.sort_by(f64::total_cmp);
                s[s.len() / 2]
            };
            println!(
                "map ({what}) {} {wl:.0} nm: median n {:.4} (true {n0:.4}, median n_se {med_se:.4}); within 3 SE: n {:.1}%, k {:.1}%",
                p.name,
                ns[ns.len() / 2],
                100.0 * fn_,
                100.0 * fk
            );
            assert!(fn_ >= 0.9 && fk >= 0.9, "{} {wl}: n {fn_}, k {fk}", p.name);
        }
    }
}

#[test]
fn colour_manifest_errors_exit_2_naming_file_field_and_value() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let raw = vec![1000u16; 16 * 16];
    polarid_io::image::write_gray16(&d.join("raw.tif"), true, 16, 16, &raw).unwrap();
    let base = "theta_r_deg = 60.0\n[[region]]\nname = \"A\"\nrect = [4, 4, 8, 8]\n";
    let cases = [
        // a colour of the pattern with no band
        (
            "bands = { R = 650.0, G = 550.0 }\n",
            "dofp = { file = \"raw.tif\", color = \"RGGB\" }",
            "capture[1].dofp.color",
            "RGGB",
        ),
        // a colour letter without a wavelength (no `bands`: R, G and B only)
        (
            "",
            "dofp = { file = \"raw.tif\", color = \"RGGX\" }",
            "capture[1].dofp.color",
            "RGGX",
        ),
    ];
    for (top, dofp, field, value) in cases {
        let manifest = format!(
            "{top}{base}\n[[capture]]\ntheta_i_deg = 40.0\n{dofp}\n\n[[capture]]\ntheta_i_deg = 50.0\n{dofp}\n\n[[capture]]\ntheta_i_deg = 60.0\n{dofp}\n"
        );
        std::fs::write(d.join("bad.toml"), manifest).unwrap();
        for args in [
            vec!["measure", "bad.toml", "-o", "m.csv"],
            vec!["map", "bad.toml", "--library", "builtin-rgb", "-o", "out"],
        ] {
            let o = polarid_in(d, &args);
            let err = text(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
            assert!(
                err.contains("bad.toml") && err.contains(field) && err.contains(value),
                "{args:?}: {err}"
            );
            assert!(!d.join("m.csv").exists() && !d.join("out").exists());
        }
    }
    // a single-band capture without a wavelength next to colour captures
    let manifest = format!(
        "{base}\n[[capture]]\ntheta_i_deg = 40.0\ndofp = {{ file = \"raw.tif\", color = \"RGGB\" }}\n\n\
         [[capture]]\ntheta_i_deg = 50.0\ndofp = {{ file = \"raw.tif\" }}\n"
    );
    std::fs::write(d.join("mixed.toml"), manifest).unwrap();
    let o = polarid_in(d, &["measure", "mixed.toml", "-o", "m.csv"]);
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("mixed.toml") && err.contains("capture[2].wavelength_nm"),
        "{err}"
    );
    assert!(!d.join("m.csv").exists());
}
