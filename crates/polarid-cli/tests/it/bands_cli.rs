//! Multi-band data through the command line (issue 17): `fit` writes one row per target
//! per band with `wavelength_nm`; `train` writes per-band prototypes; `classify` answers
//! once per target on all its bands (`bands_used`), on fewer bands when the target has
//! fewer, and against the built-in three-band library; `evaluate` leaves whole targets
//! out; `library --band ... --band ...` writes one row per material per band and rebuilds
//! `builtin-rgb`.

use crate::common;

use common::{csv_rows, polarid_in, text};

use std::fmt::Write as _;
use std::fs;
use std::path::PathBuf;
use std::process::Output;

use polarid_core::dop::dop;
use polarid_io::library::Library;

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "status {:?}\nstderr: {}",
        o.status,
        text(&o.stderr)
    );
}

/// (n, k) of copper, gold and aluminum at 450, 550, 650 nm (the built-in three-band
/// library).
/// `(wavelength_nm, n, k)` per band.
type Bands = Vec<(f64, f64, f64)>;

fn truth() -> Vec<(&'static str, Bands)> {
    let lib = Library::builtin_rgb().unwrap();
    ["copper", "gold", "aluminum"]
        .iter()
        .map(|&name| {
            let bands = lib
                .materials
                .iter()
                .filter(|m| m.name == name)
                .map(|m| (m.wavelength_nm.unwrap(), m.n, m.k))
                .collect::<Vec<_>>();
            assert_eq!(bands.len(), 3, "{name}");
            (name, bands)
        })
        .collect()
}

/// Exact DoLP rows (dolp_se 0.002, a deterministic ±0.001 wiggle) for targets
/// `{material}{suffix}`, with `class` when `labelled`; only the bands in `keep`.
fn rows(csv: &mut String, suffix: &str, labelled: bool, keep: &[f64], wiggle: f64) {
    for (name, bands) in truth() {
        for (i, beta) in [30.0f64, 38.0, 46.0, 54.0, 62.0, 70.0, 78.0]
            .iter()
            .enumerate()
        {
            for &(wl, n, k) in &bands {
                if !keep.contains(&wl) {
                    continue;
                }
                let sign = if (i + wl as usize / 100).is_multiple_of(2) {
                    1.0
                } else {
                    -1.0
                };
                let p = dop(n, k, beta.to_radians()) + sign * wiggle;
                let class = if labelled { name } else { "" };
                writeln!(csv, "{name}{suffix},{class},{beta},{p},0.002,{wl}").unwrap();
            }
        }
    }
}

#[test]
fn fit_train_classify_evaluate_on_three_bands() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let all = [450.0, 550.0, 650.0];
    let mut train = String::from("target,class,beta_deg,dolp,dolp_se,wavelength_nm\n");
    rows(&mut train, "_a", true, &all, 0.001);
    rows(&mut train, "_b", true, &all, -0.001);
    fs::write(d.join("train_m.csv"), &train).unwrap();
    let mut test = String::from("target,class,beta_deg,dolp,dolp_se,wavelength_nm\n");
    rows(&mut test, "_t", false, &all, 0.0005);
    // A target seen only in the green band.
    rows(&mut test, "_green", false, &[550.0], 0.0);
    fs::write(d.join("test_m.csv"), &test).unwrap();

    // Clean simulated surfaces: no surface-layer allowance (its default, 3 nm compared
    // with one 550 nm wavelength for every band, makes the sets ambiguous; docs/BANDS.md).
    let no_film = ["--film-sd-nm", "0"];
    ok(&polarid_in(
        d,
        &[&["fit", "train_m.csv", "-o", "train_f.csv"][..], &no_film].concat(),
    ));
    ok(&polarid_in(
        d,
        &[&["fit", "test_m.csv", "-o", "test_f.csv"][..], &no_film].concat(),
    ));
    let header = fs::read_to_string(d.join("train_f.csv")).unwrap();
    assert!(
        header.starts_with("target,class,wavelength_nm,n,k,"),
        "{header}"
    );
    let fits = csv_rows(&d.join("train_f.csv"));
    assert_eq!(fits.len(), 18, "6 targets x 3 bands");
    // Bands of a target in their order of first appearance, targets together.
    let order: Vec<(String, String)> = fits
        .iter()
        .take(3)
        .map(|r| (r["target"].clone(), r["wavelength_nm"].clone()))
        .collect();
    assert_eq!(
        order,
        vec![
            ("copper_a".into(), "450".into()),
            ("copper_a".into(), "550".into()),
            ("copper_a".into(), "650".into())
        ]
    );
    // Each band's fit recovers that band's index.
    for r in &fits {
        let (name, bands) = truth()
            .into_iter()
            .find(|(n, _)| r["target"].starts_with(n))
            .unwrap();
        let wl: f64 = r["wavelength_nm"].parse().unwrap();
        let (_, n, k) = bands.into_iter().find(|b| b.0 == wl).unwrap();
        let (nf, kf): (f64, f64) = (r["n"].parse().unwrap(), r["k"].parse().unwrap());
        assert!(
            (nf - n).abs() < 0.05 && (kf - k).abs() < 0.2,
            "{name} {wl}: {nf} {kf} vs {n} {k}"
        );
        assert_eq!(r["status"], "ok", "{r:?}");
    }

    ok(&polarid_in(
        d,
        &["train", "train_f.csv", "-o", "model.json"],
    ));
    let model = fs::read_to_string(d.join("model.json")).unwrap();
    assert_eq!(model.matches("\"wavelength_nm\"").count(), 18, "{model}");

    ok(&polarid_in(
        d,
        &[
            "classify",
            "test_f.csv",
            "--model",
            "model.json",
            "-o",
            "c.csv",
        ],
    ));
    let c = csv_rows(&d.join("c.csv"));
    assert_eq!(c.len(), 6, "one row per target: {c:?}");
    for r in &c {
        let t = &r["target"];
        let material = t.split('_').next().unwrap();
        if t.ends_with("_green") {
            assert_eq!(r["bands_used"], "550", "{r:?}");
        } else {
            assert_eq!(r["bands_used"], "450;550;650", "{r:?}");
        }
        assert_eq!(r["predicted"], material, "{r:?}");
    }

    // The built-in three-band library.
    ok(&polarid_in(
        d,
        &[
            "classify",
            "test_f.csv",
            "--library",
            "builtin-rgb",
            "-o",
            "lib.csv",
        ],
    ));
    for r in csv_rows(&d.join("lib.csv")) {
        let material = r["target"].split('_').next().unwrap().to_string();
        assert_eq!(r["nearest"], material, "{r:?}");
    }
    // The single-band built-in library is evaluated at the fits' wavelengths (its own
    // 650 nm band, the others from its refractiveindex.info data; docs/CLASSIFY.md
    // "Wavelength"): a three-band target is compared on all three, a green-only one at 550.
    ok(&polarid_in(
        d,
        &[
            "classify",
            "test_f.csv",
            "--library",
            "builtin",
            "-o",
            "b.csv",
        ],
    ));
    for r in csv_rows(&d.join("b.csv")) {
        let material = r["target"].split('_').next().unwrap().to_string();
        if r["target"].ends_with("_green") {
            assert_eq!(r["bands_used"], "550", "{r:?}");
        } else {
            assert_eq!(r["bands_used"], "450;550;650", "{r:?}");
            assert_eq!(r["nearest"], material, "{r:?}");
        }
    }

    // Leave-one-out on whole targets: every target right.
    let o = polarid_in(d, &["evaluate", "train_f.csv"]);
    ok(&o);
    let out = text(&o.stdout);
    assert!(out.contains("accuracy: 1.0000 (6/6)"), "{out}");
}

#[test]
fn a_target_cannot_mix_rows_with_and_without_bands() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fs::write(
        d.join("m.csv"),
        "target,beta_deg,dolp,wavelength_nm\nA,40,0.1,550\nA,50,0.2,\nA,60,0.3,550\nA,70,0.2,550\n",
    )
    .unwrap();
    let o = polarid_in(d, &["fit", "m.csv", "-o", "f.csv"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    let e = text(&o.stderr);
    assert!(e.contains("wavelength_nm") && e.contains("line 3"), "{e}");
    assert!(!d.join("f.csv").exists());
}

/// `polarid library` with the three colour bands and the names map of the built-in
/// library rebuilds `builtin-rgb` exactly (its 650 nm rows are `builtin`'s band means).
#[test]
fn library_with_three_bands_rebuilds_builtin_rgb() {
    let data = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../data"));
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = polarid_in(
        d,
        &[
            "library",
            data.join("materials/refractiveindex").to_str().unwrap(),
            "--band",
            "410:490",
            "--band",
            "510:590",
            "--band",
            "610:690",
            "--names",
            data.join("materials/builtin_names.csv").to_str().unwrap(),
            "--skip-missing",
            "-o",
            "rgb.csv",
        ],
    );
    ok(&o);
    let ours = Library::read_csv(&d.join("rgb.csv")).unwrap();
    let builtin = Library::builtin_rgb().unwrap();
    assert_eq!(ours.materials.len(), builtin.materials.len());
    for (a, b) in ours.materials.iter().zip(&builtin.materials) {
        assert_eq!(
            (&a.name, a.wavelength_nm, a.n, a.k),
            (&b.name, b.wavelength_nm, b.n, b.k)
        );
    }
    // Its 650 nm rows are the single-band built-in library's values.
    let one = Library::builtin().unwrap();
    for m in one.materials {
        let r = builtin
            .materials
            .iter()
            .find(|x| x.name == m.name && x.wavelength_nm == Some(650.0))
            .unwrap_or_else(|| panic!("{} at 650", m.name));
        assert!(
            (r.n - m.n).abs() < 1e-5 && (r.k - m.k).abs() <= 1e-4 * m.k.max(1e-6),
            "{}",
            m.name
        );
    }
    let csv = fs::read_to_string(d.join("rgb.csv")).unwrap();
    assert!(
        csv.contains("name,category,wavelength_nm,n,k,reference"),
        "{csv}"
    );
}
