//! The walkthrough of docs/CAPTURE.md, step by step, on simulated frames: `polarid
//! simulate` renders examples/scenes/capture_walkthrough.toml (three plates, a
//! calibrated camera, a lamp in nine positions); its frames are copied into a plain
//! folder (what a camera leaves behind), with a dark frame and the OpenCV calibration
//! file of the camera. Then, as the guide says: `init --opencv`, fill in the
//! placeholders (positions from the "tape measure" — the scene's, rounded to the
//! millimetre —, exposures from the "lab notes", rectangles read off the S0 view,
//! classes of the reference plates), `measure`, `fit`, `train`, `classify`, `map`. Each
//! step must work and the map must name the plates. Also: `init` on the layouts it
//! knows and refusing the folders it does not.

use crate::common;

use std::path::{Path, PathBuf};

use common::{csv_rows, polarid, polarid_in, text};
use polarid_io::manifest::{self, SourceSpec};

fn ok_in(dir: &Path, args: &[&str]) -> String {
    let o = polarid_in(dir, args);
    assert!(
        o.status.success(),
        "polarid {args:?} failed: {}",
        text(&o.stderr)
    );
    text(&o.stderr)
}

fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes/capture_walkthrough.toml")
}

/// The camera's OpenCV calibration as `cv::FileStorage` writes it (YAML), with the
/// scene's intrinsics (what `calibrateCamera` would recover).
const CALIB_YML: &str = "%YAML:1.0
---
calibration_time: \"Thu Dec  3 09:41:07 2026\"
nframes: 15
image_width: 320
image_height: 240
board_width: 9
board_height: 6
square_size: 2.5000000000000000e+01
flags: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 4.3960000000000000e+02, 0., 1.5950000000000000e+02, 0.,
       4.3960000000000000e+02, 1.1950000000000000e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -8.0000000000000002e-02, 2.0000000000000000e-02, 0., 0.,
       0. ]
avg_reprojection_error: 1.8000000000000000e-01
";

fn mm(x: f64) -> String {
    format!("{:.3}", x)
}

fn vec3(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", mm(v[0]), mm(v[1]), mm(v[2]))
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
    }
}

#[test]
fn walkthrough_from_a_folder_of_frames_to_a_map() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let scene = scene();
    // Step 0: plan the lamp positions on the bench's scene before any capture. The
    // scene's nine positions tell aluminum and polycarbonate from the other candidates;
    // silicon and gallium arsenide agree within the noise in one band.
    let o = polarid_in(
        root,
        &[
            "plan",
            scene.to_str().unwrap(),
            "--materials",
            "aluminum,silicon,polycarbonate,copper,gallium_arsenide",
            "--step-deg",
            "10",
            "-o",
            "plan",
        ],
    );
    assert!(o.status.success(), "plan: {}", text(&o.stderr));
    let table = text(&o.stdout);
    for line in [
        "aluminum: aluminum identifiable",
        "polycarbonate: polycarbonate identifiable",
        "silicon: silicon NOT identifiable",
    ] {
        assert!(table.contains(line), "{line:?} not in:\n{table}");
    }
    assert!(root.join("plan/scene.toml").is_file());
    // The "camera": simulated captures, stripped to a folder of frames.
    ok_in(
        root,
        &["simulate", scene.to_str().unwrap(), "-o", "sim", "-q"],
    );
    let sim = manifest::load(&root.join("sim/manifest.toml")).unwrap();
    let frames = root.join("frames");
    for c in 1..=9 {
        copy_dir(
            &root.join(format!("sim/c{c:02}")),
            &frames.join(format!("c{c:02}")),
        );
    }
    // A dark frame (lens capped): the sensor's 64 DN black level.
    polarid_io::image::write_gray16(
        &frames.join("dark_01.png"),
        false,
        320,
        240,
        &vec![64; 320 * 240],
    )
    .unwrap();
    std::fs::write(root.join("calib.yml"), CALIB_YML).unwrap();

    // Step 1: polarid init.
    let err = ok_in(root, &["init", "frames", "--opencv", "calib.yml"]);
    assert!(
        err.contains("9 capture(s), 36 frame(s) of 320x240"),
        "{err}"
    );
    let skeleton = std::fs::read_to_string(frames.join("manifest.toml")).unwrap();
    assert!(skeleton.contains("dark_level = 64.0"), "{skeleton}");
    assert!(skeleton.contains("saturation = 4095.0"), "{skeleton}");
    assert!(skeleton.contains("opencv = \"../calib.yml\""), "{skeleton}");
    assert_eq!(skeleton.matches("[[capture]]").count(), 9);
    assert_eq!(
        skeleton
            .matches("source = { position = [nan, nan, nan] }")
            .count(),
        9
    );
    assert!(
        skeleton.contains("{ angle_deg = 135.0, file = \"c09/pol135.png\" }"),
        "{skeleton}"
    );
    // A second run does not overwrite it.
    let o = polarid_in(root, &["init", "frames", "--opencv", "calib.yml"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));

    // The placeholders refuse to be measured.
    let o = polarid_in(root, &["measure", "frames/manifest.toml"]);
    assert_eq!(o.status.code(), Some(2));
    let e = text(&o.stderr);
    assert!(e.contains("camera.position") && e.contains("nan"), "{e}");

    // Step 2: the S0 view of one capture, to read the targets' rectangles off.
    ok_in(
        root,
        &[
            "stokes",
            "--frames",
            "frames/c01/pol000.png",
            "frames/c01/pol045.png",
            "frames/c01/pol090.png",
            "frames/c01/pol135.png",
            "--angles",
            "0,45,90,135",
            "-o",
            "view",
            "-q",
        ],
    );
    assert!(root.join("view/s0.tif").is_file() && root.join("view/dolp.png").is_file());

    // Step 3: fill in the placeholders.
    let cam = sim.camera.as_ref().unwrap();
    let mut m = skeleton.replacen(
        "position = [nan, nan, nan]",
        &format!("position = {}", vec3(cam.position)),
        1,
    );
    m = m.replacen(
        "look_at = [nan, nan, nan]",
        "look_at = [0.000, 0.000, 0.000]",
        1,
    );
    // Positions to the millimetre: directions good to about 0.3 degrees.
    m = m.replacen("# angle_sd_deg = 0.2 ", "angle_sd_deg = 0.3   ", 1);
    m = m.replacen("# wavelength_nm = 650.0 ", "wavelength_nm = 650.0   ", 1);
    for c in &sim.captures {
        let Some(SourceSpec::Position(p)) = &c.illumination else {
            panic!("a lamp position");
        };
        m = m.replacen(
            "source = { position = [nan, nan, nan] }",
            &format!("source = {{ position = {} }}", vec3(*p)),
            1,
        );
        m = m.replacen(
            "exposure = 1.0 ",
            &format!("exposure = {:.4} ", c.exposure),
            1,
        );
    }
    let start = m.find("[[region]]").unwrap();
    let end = m.find("# --- Captures").unwrap();
    let mut regions = String::new();
    for (i, r) in sim.regions.iter().enumerate() {
        regions += &format!(
            "[[region]]\nname = \"plate{}\"\nrect = [{}, {}, {}, {}]\nclass = \"{}\"\n\n",
            i + 1,
            r.rect.x,
            r.rect.y,
            r.rect.width,
            r.rect.height,
            r.class.as_deref().unwrap()
        );
    }
    m.replace_range(start..end, &regions);
    assert!(!m.contains("[nan") && !m.contains("= nan"), "{m}");
    std::fs::write(frames.join("manifest.toml"), &m).unwrap();

    // Step 4: measure, fit, train, classify, map.
    ok_in(
        root,
        &[
            "measure",
            "frames/manifest.toml",
            "-o",
            "measurements.csv",
            "-q",
        ],
    );
    let rows = csv_rows(&root.join("measurements.csv"));
    assert_eq!(rows.len(), 27);
    ok_in(root, &["fit", "measurements.csv", "-o", "fits.csv", "-q"]);
    let fits = csv_rows(&root.join("fits.csv"));
    for f in &fits {
        assert_eq!(f["status"], "ok", "{f:?}");
    }
    for f in &fits {
        eprintln!(
            "fit {}: n {} ± {}, k {} ± {} ({} rows)",
            f["class"], f["n"], f["n_se"], f["k"], f["k_se"], f["measurements"]
        );
    }
    let find = |class: &str| fits.iter().find(|f| f["class"] == class).unwrap();
    let n = |f: &std::collections::HashMap<String, String>| f["n"].parse::<f64>().unwrap();
    assert!(
        (n(find("polycarbonate")) - 1.579).abs() < 0.1,
        "{:?}",
        find("polycarbonate")
    );
    assert!(
        (n(find("silicon")) - 3.852).abs() < 0.3,
        "{:?}",
        find("silicon")
    );
    let k_al = find("aluminum")["k"].parse::<f64>().unwrap();
    assert!(k_al > 4.0, "aluminum k {k_al}");
    ok_in(root, &["train", "fits.csv", "-o", "model.json", "-q"]);
    ok_in(
        root,
        &[
            "classify",
            "fits.csv",
            "--model",
            "model.json",
            "-o",
            "classes.csv",
            "-q",
        ],
    );
    for r in csv_rows(&root.join("classes.csv")) {
        assert_eq!(r["predicted"], r["class"], "{r:?}");
    }
    // Against the literature: each plate's family.
    ok_in(
        root,
        &[
            "classify",
            "fits.csv",
            "--library",
            "builtin",
            "--wavelength-nm",
            "650",
            "-o",
            "library.csv",
            "-q",
        ],
    );
    for r in csv_rows(&root.join("library.csv")) {
        eprintln!(
            "library {}: {} {}",
            r["class"], r["status"], r["candidates"]
        );
        let cands: Vec<&str> = r["candidates"].split(';').collect();
        assert!(cands.contains(&r["class"].as_str()), "{r:?}");
    }
    ok_in(
        root,
        &[
            "map",
            "frames/manifest.toml",
            "--model",
            "model.json",
            "--bin",
            "4",
            "-o",
            "map",
            "-q",
        ],
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("map/map_summary.json")).unwrap())
            .unwrap();
    let regions = summary["regions"].as_array().unwrap();
    assert_eq!(regions.len(), 3);
    for r in regions {
        let class = r["class"].as_str().unwrap();
        let counts = r["classes"].as_object().unwrap();
        let total: f64 = counts.values().map(|v| v.as_f64().unwrap()).sum();
        let own = counts.get(class).and_then(|v| v.as_f64()).unwrap_or(0.0);
        eprintln!("map {class}: {counts:?}");
        assert!(own / total >= 0.7, "{class}: {counts:?}");
        for (other, v) in counts {
            if other != class && other != "ambiguous" && other != "unknown" {
                assert!(v.as_f64().unwrap() / total < 0.05, "{class}: {counts:?}");
            }
        }
    }
}

#[test]
fn init_recognises_layouts_and_refuses_what_it_cannot_read() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let px = |v: u16| vec![v; 16 * 12];
    let w = |p: &Path, v: u16| polarid_io::image::write_gray16(p, false, 16, 12, &px(v)).unwrap();
    // A flat folder of frames named by capture and angle, 10-bit values.
    let flat = root.join("flat");
    std::fs::create_dir(&flat).unwrap();
    for cap in ["i35", "i40", "i45"] {
        for (a, v) in [(0, 1000), (60, 300), (120, 500)] {
            w(&flat.join(format!("{cap}_pol{a:03}.png")), v);
        }
    }
    ok_in(root, &["init", "flat", "-o", "flat.toml"]);
    let t = std::fs::read_to_string(root.join("flat.toml")).unwrap();
    assert_eq!(t.matches("[[capture]]").count(), 3, "{t}");
    assert!(t.contains("name = \"i40\""), "{t}");
    assert!(
        t.contains("{ angle_deg = 60.0, file = \"flat/i45_pol060.png\" }"),
        "{t}"
    );
    assert!(t.contains("saturation = 1023.0"), "{t}");
    assert!(t.contains("theta_i_deg = nan"), "{t}");

    // One DoFP raw per capture, 12 bits stored in the top of 16 (multiples of 16).
    let dofp = root.join("dofp");
    std::fs::create_dir(&dofp).unwrap();
    let raw: Vec<u16> = (0..16 * 12)
        .map(|i| ((i % 200) as u16 + 100) * 16)
        .collect();
    let mut raw2 = raw.clone();
    raw2[5] = 4095 * 16;
    for (name, d) in [("lamp1.png", &raw), ("lamp2.png", &raw2)] {
        polarid_io::image::write_gray16(&dofp.join(name), false, 16, 12, d).unwrap();
    }
    std::fs::write(dofp.join("notes.txt"), "lab notes").unwrap();
    let err = ok_in(root, &["init", "dofp"]);
    assert!(err.contains("notes.txt"), "{err}");
    let t = std::fs::read_to_string(dofp.join("manifest.toml")).unwrap();
    assert!(
        t.contains("dofp = { file = \"lamp1.png\", pattern = [90, 45, 135, 0] }"),
        "{t}"
    );
    assert!(t.contains("saturation = 65520.0"), "{t}");

    // Refused, exit 2, with the reason.
    let refuse = |dir: &str, want: &str| {
        let o = polarid(&[
            "init",
            root.join(dir).to_str().unwrap(),
            "-o",
            root.join("x.toml").to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{dir}: {}", text(&o.stderr));
        let e = text(&o.stderr);
        assert!(e.contains(want), "{dir}: {e}");
        assert!(!root.join("x.toml").exists());
    };
    std::fs::create_dir(root.join("empty")).unwrap();
    refuse("empty", "holds no PNG or TIFF frames");
    refuse("missing", "no such folder");
    let two = root.join("two/c1");
    std::fs::create_dir_all(&two).unwrap();
    w(&two.join("p000.png"), 10);
    w(&two.join("p090.png"), 10);
    refuse("two", "needs at least 3");
    let noangle = root.join("noangle/c1");
    std::fs::create_dir_all(&noangle).unwrap();
    for n in ["a.png", "b.png", "c.png"] {
        w(&noangle.join(n), 10);
    }
    refuse("noangle", "give no polarizer angles");
    let hdr = root.join("hdr/c1");
    std::fs::create_dir_all(&hdr).unwrap();
    for e in [10, 40] {
        for a in [0, 45, 90, 135] {
            w(&hdr.join(format!("pol{a:03}_exp{e}.png")), 10);
        }
    }
    refuse("hdr", "HDR brackets");
    let mixed = root.join("mixed");
    std::fs::create_dir_all(mixed.join("c1")).unwrap();
    w(&mixed.join("c1/raw.png"), 10);
    w(&mixed.join("loose.png"), 10);
    refuse("mixed", "loose frames");
    let sizes = root.join("sizes");
    std::fs::create_dir_all(&sizes).unwrap();
    w(&sizes.join("a.png"), 10);
    polarid_io::image::write_gray16(&sizes.join("b.png"), false, 8, 8, &[10; 64]).unwrap();
    refuse("sizes", "different sizes");
    let odd = root.join("odd");
    std::fs::create_dir_all(&odd).unwrap();
    polarid_io::image::write_gray16(&odd.join("a.png"), false, 7, 8, &[10; 56]).unwrap();
    refuse("odd", "even width and height");
    // A bad calibration file is refused before anything is written.
    std::fs::write(root.join("bad.yml"), "%YAML:1.0\n---\nfoo: 1\n").unwrap();
    let o = polarid(&[
        "init",
        flat.to_str().unwrap(),
        "--opencv",
        root.join("bad.yml").to_str().unwrap(),
        "-o",
        root.join("x.toml").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("no camera matrix entry"),
        "{}",
        text(&o.stderr)
    );
    assert!(!root.join("x.toml").exists());

    // The real IMX250MZR frames of data/real-dofp (two 8-bit raw mosaics beside a README
    // and a LICENSE): two DoFP captures, saturation 255; filled in, they measure.
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/real-dofp");
    let out = root.join("real.toml");
    let err = ok_in(
        root,
        &["init", real.to_str().unwrap(), "-o", out.to_str().unwrap()],
    );
    assert!(
        err.contains("LICENSE") && err.contains("README.md"),
        "{err}"
    );
    assert!(err.contains("at the saturation level 255"), "{err}");
    let t = std::fs::read_to_string(&out).unwrap();
    assert_eq!(t.matches("dofp = { file = ").count(), 2, "{t}");
    assert!(
        t.contains("saturation = 255.0") && t.contains("pattern = [90, 45, 135, 0]"),
        "{t}"
    );
    let filled = t
        .replacen("theta_r_deg = nan", "theta_r_deg = 45.0", 1)
        .replacen("theta_i_deg = nan", "theta_i_deg = 30.0", 1)
        .replacen("theta_i_deg = nan", "theta_i_deg = 40.0", 1)
        .replacen("name = \"target1\"", "name = \"centre\"", 1)
        .replacen("rect = [0, 0, 0, 0]", "rect = [1200, 1000, 64, 64]", 1);
    std::fs::write(&out, filled).unwrap();
    ok_in(
        root,
        &["measure", out.to_str().unwrap(), "-o", "real.csv", "-q"],
    );
    assert_eq!(csv_rows(&root.join("real.csv")).len(), 2);
}

/// Cells of docs/CAPTURE.md's table "How many source positions, and what β span": seven
/// source positions evenly over the span, eq. (9) DoLP (`polarid model`) with standard
/// error 0.002, fitted by `polarid fit` with its defaults; the noise part
/// (`n_se_noise`, `k_se_noise`) and the total (`n_se`, `k_se`).
#[test]
fn beta_span_table_of_the_capture_guide() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    // (target, n, k, span, n_se noise, n_se total, k_se noise, k_se total) as in the guide.
    type Cell = (&'static str, f64, f64, (f64, f64), [f64; 4]);
    let cells: [Cell; 6] = [
        ("al_35_55", 1.558, 7.712, (35.0, 55.0), [3.5, 5.1, 6.1, 8.2]),
        (
            "al_50_75",
            1.558,
            7.712,
            (50.0, 75.0),
            [0.19, 1.2, 0.52, 3.3],
        ),
        (
            "cu_45_65",
            0.238,
            3.626,
            (45.0, 65.0),
            [0.06, 0.11, 0.56, 1.3],
        ),
        (
            "si_45_65",
            3.852,
            0.0165,
            (45.0, 65.0),
            [0.06, 0.13, 0.42, 0.75],
        ),
        (
            "ge_50_75",
            5.317,
            0.661,
            (50.0, 75.0),
            [0.05, 0.47, 0.15, 0.96],
        ),
        (
            "pc_50_75",
            1.579,
            0.0,
            (50.0, 75.0),
            [0.002, 0.09, 0.05, 0.29],
        ),
    ];
    let mut rows = String::from("n,k,beta_deg,target\n");
    for (t, n, k, (a, b), _) in &cells {
        for i in 0..7 {
            let beta = a + (b - a) * f64::from(i) / 6.0;
            rows += &format!("{n},{k},{beta},{t}\n");
        }
    }
    std::fs::write(root.join("rows.csv"), rows).unwrap();
    ok_in(
        root,
        &["model", "--input", "rows.csv", "-o", "dop.csv", "-q"],
    );
    let mut meas = String::from("target,beta_deg,dolp,dolp_se\n");
    for r in csv_rows(&root.join("dop.csv")) {
        meas += &format!("{},{},{},0.002\n", r["target"], r["beta_deg"], r["dop"]);
    }
    std::fs::write(root.join("meas.csv"), meas).unwrap();
    ok_in(root, &["fit", "meas.csv", "-o", "fits.csv", "-q"]);
    let fits = csv_rows(&root.join("fits.csv"));
    for (t, _, _, _, want) in &cells {
        let f = fits.iter().find(|f| f["target"] == *t).unwrap();
        let got =
            ["n_se_noise", "n_se", "k_se_noise", "k_se"].map(|c| f[c].parse::<f64>().unwrap());
        for (g, w) in got.iter().zip(want) {
            // The guide rounds to two significant figures.
            assert!(
                (g - w).abs() <= 0.06 * w + 0.0006,
                "{t}: got {got:?}, guide {want:?}"
            );
        }
    }
}
