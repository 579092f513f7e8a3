//! Issue 15 acceptance on independent renders of a calibrated lamp-and-lens bench
//! (Mitsuba 3, `tools/render/render_bench.py`), kept outside the repository.
//!
//! Runs when `POLARID_RENDERS` names a directory holding `bench_450/` and/or
//! `bench_550/` (tools/render/README.md, "Calibrated bench"): a 40° pinhole camera 0.8 m
//! from six plates (aluminum, copper, gold, nickel, N-BK7 glass on the bench, a second
//! aluminum plate on a wedge tilted 20°), a point lamp 0.55–1 m away in ten positions, six
//! in the camera's plane of incidence and four 25–40° out of it. Each set holds a
//! calibrated manifest (`manifest.toml`: rotating-polarizer frames; `manifest_dofp.toml`:
//! the DoFP mosaics), `truth.json` (the plates' (n, k) at the band, which plates are well
//! lit, projection markers and per-pixel geometry computed independently in Python) and
//! `labels.tif` (the plate under each pixel). Without the variable, or without the sets,
//! every test prints why it did nothing and passes.
//!
//! The acceptance (issue 15): each well-lit plate's fitted (n, k) lies within
//! max(0.03, 3 SE) in n and max(0.06, 3 SE) in k of the truth at 450 and 550 nm, from
//! the frames and from the DoFP mosaics; and `polarid map --bin 4` classifies ≥ 95 % of
//! the plates' classified pixels right while classifying at least half of them. The map
//! uses the model `polarid train` builds from the same set's region fits: the issue asks
//! for `map --bin 4` on the bench, whose plates are the labelled reference samples (the
//! paper's train-then-map workflow, as in `map_cmd.rs`); a library model would test the
//! literature's spread between datasets, not the geometry.

use crate::common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use common::{csv_rows, polarid, text};
use polarid_core::geometry::ViewGeometry;

const SETS: [&str; 2] = ["bench_450", "bench_550"];
const N_TOL: f64 = 0.03;
const K_TOL: f64 = 0.06;

/// The bench sets under `POLARID_RENDERS`, or `None` (with a note) when there are none.
fn bench_sets(test: &str) -> Option<Vec<PathBuf>> {
    let Some(root) = std::env::var_os("POLARID_RENDERS").map(PathBuf::from) else {
        polarid_testkit::note!(
            "{test}: skipped: set POLARID_RENDERS to the directory holding bench_450/ and \
             bench_550/ (tools/render/README.md, \"Calibrated bench\")"
        );
        return None;
    };
    let mut sets = Vec::new();
    for s in SETS {
        let d = root.join(s);
        if d.join("manifest.toml").is_file() && d.join("truth.json").is_file() {
            sets.push(d);
        } else {
            eprintln!("{test}: note: {} is missing", d.display());
        }
    }
    if sets.is_empty() {
        eprintln!(
            "{test}: skipped: no bench set under {} (render them with \
             tools/render/render_bench.py)",
            root.display()
        );
        return None;
    }
    Some(sets)
}

fn truth(set: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(set.join("truth.json")).expect("truth.json"))
        .expect("truth.json is JSON")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

fn run_ok(args: &[&str]) {
    let o = polarid(args);
    assert!(
        o.status.success(),
        "polarid {args:?} failed ({:?}): {}",
        o.status.code(),
        text(&o.stderr)
    );
}

/// `measure` + `fit` of a manifest; the fits as rows.
fn measure_fit(manifest: &Path, dir: &Path, tag: &str) -> Vec<HashMap<String, String>> {
    let meas = dir.join(format!("{tag}_meas.csv"));
    let fits = dir.join(format!("{tag}_fits.csv"));
    run_ok(&["measure", s(manifest), "-o", s(&meas), "-q"]);
    run_ok(&["fit", s(&meas), "-o", s(&fits), "-q"]);
    csv_rows(&fits)
}

fn num(row: &HashMap<String, String>, col: &str) -> f64 {
    row.get(col)
        .and_then(|v| v.parse().ok())
        .unwrap_or(f64::NAN)
}

/// One plate's fit against the truth: (n error, n tolerance, k error, k tolerance).
fn compare(row: &HashMap<String, String>, n: f64, k: f64) -> (f64, f64, f64, f64) {
    let tol = |se: f64, floor: f64| {
        if se.is_finite() {
            floor.max(3.0 * se)
        } else {
            floor
        }
    };
    (
        num(row, "n") - n,
        tol(num(row, "n_se"), N_TOL),
        num(row, "k") - k,
        tol(num(row, "k_se"), K_TOL),
    )
}

/// Fits of the well-lit plates of a set compared with the truth; returns the lines of
/// the plates outside the tolerance (empty: all within).
fn check_fits(set: &Path, fits: &[HashMap<String, String>], label: &str) -> Vec<String> {
    let t = truth(set);
    let mut misses = Vec::new();
    let mut checked = 0;
    for p in t["plates"].as_array().expect("plates") {
        let name = p["name"].as_str().expect("name");
        let (n, k) = (p["n"].as_f64().unwrap(), p["k"].as_f64().unwrap());
        let well_lit = p["well_lit"].as_bool().unwrap_or(false);
        let Some(row) = fits
            .iter()
            .find(|r| r.get("target").map(String::as_str) == Some(name))
        else {
            if well_lit {
                misses.push(format!("{label} {name}: no fit"));
            }
            continue;
        };
        let (dn, tn, dk, tk) = compare(row, n, k);
        let ok = dn.abs() <= tn && dk.abs() <= tk;
        let line = format!(
            "{label} {name:15} truth {n:.3}+{k:.3}i fit {:.3}+{:.3}i (se {:.4}, {:.4}; {}) \
             dn {dn:+.4} (tol {tn:.3}) dk {dk:+.4} (tol {tk:.3}){}{}",
            num(row, "n"),
            num(row, "k"),
            num(row, "n_se"),
            num(row, "k_se"),
            row.get("status").map(String::as_str).unwrap_or("?"),
            if well_lit { "" } else { " [not well lit]" },
            if ok { "" } else { "  MISS" }
        );
        eprintln!("{line}");
        if well_lit {
            checked += 1;
            if !ok {
                misses.push(line);
            }
        }
    }
    assert!(checked > 0, "{label}: no well-lit plate");
    misses
}

/// The camera polarid builds from each set's manifest projects the rendered markers
/// (emitting disks at known 3-D points, centroids measured on Mitsuba's image) to their
/// pixels, and polarid's per-pixel geometry equals the one computed independently in
/// Python for the sampled plate pixels. Independent of `measure`.
#[test]
fn bench_camera_and_pixel_geometry_match_the_renders() {
    let Some(sets) = bench_sets("bench_camera_and_pixel_geometry_match_the_renders") else {
        return;
    };
    for set in sets {
        let t = truth(&set);
        // Every manifest of the set reads without a warning (unknown keys) or an error.
        let mut names = vec![
            "manifest.toml".to_string(),
            "manifest_dofp.toml".into(),
            "manifest_stokes.toml".into(),
            "farfield_center.toml".into(),
        ];
        for p in t["plates"].as_array().unwrap() {
            names.push(format!("farfield/{}.toml", p["name"].as_str().unwrap()));
        }
        for name in &names {
            let m = polarid_io::manifest::load(&set.join(name))
                .unwrap_or_else(|e| panic!("{}/{name}: {e}", set.display()));
            assert!(m.warnings.is_empty(), "{name}: {:?}", m.warnings);
            assert_eq!(m.captures.len(), t["captures"].as_array().unwrap().len());
        }
        let m = polarid_io::manifest::load(&set.join("manifest.toml")).expect("manifest loads");
        let camera = m.camera.as_ref().expect("[camera]").to_camera();
        let mut worst_px: f64 = 0.0;
        let markers = t["projection_check"]["markers"]
            .as_array()
            .expect("markers");
        for mk in markers {
            let p: Vec<f64> = serde_json::from_value(mk["point"].clone()).unwrap();
            let r: Vec<f64> = serde_json::from_value(mk["rendered_px"].clone()).unwrap();
            let [u, v] = camera.project([p[0], p[1], p[2]]).expect("in front");
            worst_px = worst_px.max((u - r[0]).hypot(v - r[1]));
        }
        eprintln!(
            "{}: {} markers, max |polarid projection - rendered centroid| {worst_px:.3} px",
            set.display(),
            markers.len()
        );
        assert!(worst_px < 0.1, "projection off by {worst_px} px");

        let mut worst_deg: f64 = 0.0;
        let mut n = 0;
        for (ci, cap) in t["captures"].as_array().unwrap().iter().enumerate() {
            let mc = &m.captures[ci];
            assert_eq!(mc.name.as_deref(), cap["name"].as_str());
            let source = mc
                .illumination
                .as_ref()
                .expect("source")
                .to_source()
                .expect("resolved");
            for (plate, rec) in cap["plates"].as_object().unwrap() {
                let region = m.regions.iter().find(|r| &r.name == plate).expect("region");
                let plane = m.planes[region.plane].to_plane().expect("plane");
                let view = ViewGeometry::new(camera, plane).expect("camera in front");
                for c in rec["pixel_checks"].as_array().unwrap() {
                    let (u, v) = (c["u"].as_f64().unwrap(), c["v"].as_f64().unwrap());
                    let g = view.pixel(u, v, &source).expect("pixel geometry");
                    for (got, key) in [
                        (g.theta_i, "theta_i_deg"),
                        (g.theta_r, "theta_r_deg"),
                        (g.phi, "phi_deg"),
                        (g.beta, "beta_deg"),
                        (g.poi_angle, "poi_angle_projected_deg"),
                    ] {
                        let want = c[key].as_f64().unwrap();
                        let mut d = (got.to_degrees() - want).abs();
                        if key == "poi_angle_projected_deg" {
                            d = d.min(180.0 - d);
                        }
                        assert!(
                            d < 1e-6,
                            "{} {} {plate} pixel ({u}, {v}): {key} polarid {} Python {want}",
                            set.display(),
                            cap["name"],
                            got.to_degrees()
                        );
                        worst_deg = worst_deg.max(d);
                    }
                    n += 1;
                }
            }
        }
        eprintln!(
            "{}: {n} plate pixels, max |polarid - Python| over θi, θr, φ, β, plane-of-incidence \
             angle {worst_deg:.1e} deg",
            set.display()
        );
        assert!(n > 0);
    }
}

/// Acceptance: every well-lit plate's (n, k) within max(0.03, 3 SE) in n and
/// max(0.06, 3 SE) in k of the truth, from the frames and from the DoFP mosaics.
#[test]
fn bench_fits_within_tolerance_of_the_truth() {
    let Some(sets) = bench_sets("bench_fits_within_tolerance_of_the_truth") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let mut misses = Vec::new();
    for set in &sets {
        for (manifest, tag) in [("manifest.toml", "frames"), ("manifest_dofp.toml", "dofp")] {
            let name = set.file_name().unwrap().to_string_lossy().to_string();
            let label = format!("{name}/{tag}");
            let fits = measure_fit(&set.join(manifest), tmp.path(), &format!("{name}_{tag}"));
            misses.extend(check_fits(set, &fits, &label));
        }
    }
    assert!(
        misses.is_empty(),
        "plates outside the tolerance:\n{}",
        misses.join("\n")
    );
}

/// Share of the plates' 4×4 blocks classified, and of those the share classified
/// right, per plate and overall. A block belongs to a plate when all its 16 pixels do
/// (`labels.tif`, from ray casting in Python).
fn score_map(set: &Path, out: &Path, bin: usize) -> (usize, usize, usize, Vec<String>) {
    let t = truth(set);
    let labels = polarid_io::image::read_frame(&set.join("labels.tif")).expect("labels.tif");
    let class = polarid_io::image::read_frame(&out.join("class.tif")).expect("class.tif");
    let names: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("classes.json")).unwrap()).unwrap();
    assert_eq!(
        (class.width, class.height),
        (labels.width / bin, labels.height / bin)
    );
    let plates = t["plates"].as_array().unwrap();
    let (mut total, mut classified, mut right) = (0, 0, 0);
    let mut per = vec![(0usize, 0usize, 0usize); plates.len()];
    for by in 0..class.height {
        for bx in 0..class.width {
            let first = labels.data[by * bin * labels.width + bx * bin] as usize;
            let uniform = (0..bin).all(|dy| {
                (0..bin).all(|dx| {
                    labels.data[(by * bin + dy) * labels.width + bx * bin + dx] as usize == first
                })
            });
            if first == 0 || !uniform {
                continue;
            }
            let c = class.data[by * class.width + bx] as usize;
            let p = &mut per[first - 1];
            p.0 += 1;
            total += 1;
            // `ambiguous` (the set rule's several materials) is no single answer.
            if c != 0 && names[c.to_string()].as_str() != Some("ambiguous") {
                p.1 += 1;
                classified += 1;
                let want = plates[first - 1]["class"].as_str().unwrap();
                if names[c.to_string()].as_str() == Some(want) {
                    p.2 += 1;
                    right += 1;
                }
            }
        }
    }
    let lines = plates
        .iter()
        .zip(&per)
        .map(|(p, (t, c, r))| {
            format!(
                "{:15} {t:4} blocks, {c:4} classified ({:5.1} %), {r:4} right ({:5.1} % of classified)",
                p["name"].as_str().unwrap(),
                100.0 * *c as f64 / (*t).max(1) as f64,
                100.0 * *r as f64 / (*c).max(1) as f64
            )
        })
        .collect();
    (total, classified, right, lines)
}

/// The scoring of the map test on a map made from the labels themselves (every plate
/// block classified right), and on an empty one (nothing classified): checks the test's
/// own machinery on the renders while `map` cannot read calibrated manifests yet.
#[test]
fn bench_map_scoring_self_check() {
    let Some(sets) = bench_sets("bench_map_scoring_self_check") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    for set in &sets {
        let t = truth(set);
        let labels = polarid_io::image::read_frame(&set.join("labels.tif")).expect("labels.tif");
        let plates = t["plates"].as_array().unwrap();
        let mut classes: Vec<&str> = plates
            .iter()
            .map(|p| p["class"].as_str().unwrap())
            .collect();
        classes.sort();
        classes.dedup();
        let mut names = serde_json::Map::new();
        names.insert("0".into(), "unknown".into());
        for (i, c) in classes.iter().enumerate() {
            names.insert((i + 1).to_string(), (*c).into());
        }
        let (w, h) = (labels.width / 4, labels.height / 4);
        let perfect: Vec<u16> = (0..w * h)
            .map(|i| {
                let l = labels.data[(i / w) * 4 * labels.width + (i % w) * 4] as usize;
                if l == 0 {
                    0
                } else {
                    let c = plates[l - 1]["class"].as_str().unwrap();
                    1 + classes.iter().position(|x| *x == c).unwrap() as u16
                }
            })
            .collect();
        for (tag, data) in [("perfect", perfect), ("empty", vec![0u16; w * h])] {
            let out = tmp.path().join(tag);
            std::fs::create_dir_all(&out).unwrap();
            polarid_io::image::write_gray16(&out.join("class.tif"), true, w, h, &data).unwrap();
            std::fs::write(
                out.join("classes.json"),
                serde_json::Value::Object(names.clone()).to_string(),
            )
            .unwrap();
            let (total, classified, right, _) = score_map(set, &out, 4);
            eprintln!(
                "{} {tag}: {total} plate blocks, {classified} classified, {right} right",
                set.display()
            );
            assert!(total > 1000, "{total} plate blocks");
            if tag == "perfect" {
                assert_eq!((classified, right), (total, total));
            } else {
                assert_eq!((classified, right), (0, 0));
            }
        }
    }
}

/// Acceptance: `polarid map --bin 4` with the model trained on the set's own region fits
/// classifies ≥ 95 % of the plates' classified blocks right and classifies at least half
/// of them (the Mahalanobis variant with a 3-SD reject is printed for information).
#[test]
fn bench_map_bin_4_classifies_the_plates() {
    let Some(sets) = bench_sets("bench_map_bin_4_classifies_the_plates") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    for set in &sets {
        let name = set.file_name().unwrap().to_string_lossy().to_string();
        let d = tmp.path().join(&name);
        std::fs::create_dir_all(&d).unwrap();
        let manifest = set.join("manifest.toml");
        measure_fit(&manifest, &d, "frames");
        let model = d.join("model.json");
        run_ok(&[
            "train",
            s(&d.join("frames_fits.csv")),
            "-o",
            s(&model),
            "-q",
        ]);
        let out = d.join("map4");
        run_ok(&[
            "map",
            s(&manifest),
            "--model",
            s(&model),
            "-o",
            s(&out),
            "--bin",
            "4",
            "-q",
        ]);
        let (total, classified, right, lines) = score_map(set, &out, 4);
        for l in &lines {
            eprintln!("{name} map --bin 4: {l}");
        }
        let (fc, fr) = (
            classified as f64 / total.max(1) as f64,
            right as f64 / classified.max(1) as f64,
        );
        eprintln!(
            "{name} map --bin 4: {total} plate blocks, {:.1} % classified, {:.1} % of those right",
            100.0 * fc,
            100.0 * fr
        );
        let out_m = d.join("map4_mahalanobis");
        let o = polarid(&[
            "map",
            s(&manifest),
            "--model",
            s(&model),
            "-o",
            s(&out_m),
            "--bin",
            "4",
            "--metric",
            "mahalanobis",
            "--max-distance",
            "3",
            "-q",
        ]);
        if o.status.success() {
            let (t2, c2, r2, _) = score_map(set, &out_m, 4);
            eprintln!(
                "{name} map --bin 4 --metric mahalanobis --max-distance 3 (information): \
                 {:.1} % classified, {:.1} % of those right",
                100.0 * c2 as f64 / t2.max(1) as f64,
                100.0 * r2 as f64 / c2.max(1) as f64
            );
        }
        assert!(total > 0, "{name}: no plate block");
        assert!(fc >= 0.5, "{name}: only {:.1} % classified", 100.0 * fc);
        assert!(
            fr >= 0.95,
            "{name}: only {:.1} % of the classified blocks right",
            100.0 * fr
        );
    }
}

/// The renders discriminate: with far-field angles taken at the bench centre (what the
/// paper's idealisation offers a user), at least one well-lit plate of each set misses
/// the acceptance tolerance. Runs on today's far-field path (`farfield_center.toml`);
/// the per-plate far-field variants (`farfield/PLATE.toml`, angles at the plate's
/// centre pixel) are printed for information.
#[test]
fn bench_far_field_treatment_misses_the_truth() {
    let Some(sets) = bench_sets("bench_far_field_treatment_misses_the_truth") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    for set in &sets {
        let name = set.file_name().unwrap().to_string_lossy().to_string();
        let fits = measure_fit(
            &set.join("farfield_center.toml"),
            tmp.path(),
            &format!("{name}_ffc"),
        );
        let misses = check_fits(set, &fits, &format!("{name}/far-field at the centre"));
        assert!(
            !misses.is_empty(),
            "{name}: the far-field treatment recovers every plate: the bench does not test the \
             calibrated geometry"
        );
        let t = truth(set);
        let mut per_plate = Vec::new();
        for p in t["plates"].as_array().unwrap() {
            let plate = p["name"].as_str().unwrap();
            let m = set.join("farfield").join(format!("{plate}.toml"));
            if m.is_file() {
                per_plate.extend(measure_fit(&m, tmp.path(), &format!("{name}_ff_{plate}")));
            }
        }
        let misses = check_fits(set, &per_plate, &format!("{name}/far-field per plate"));
        eprintln!(
            "{name}: far-field per plate (angles at each region's centre pixel): {} of the \
             well-lit plates outside the tolerance",
            misses.len()
        );
    }
}
