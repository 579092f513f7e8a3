//! Colour polarization cameras through the CLI (issue 17): `polarid simulate` on a colour
//! scene writes raw colour mosaics and a manifest with `bands` and `dofp.color` that the
//! manifest reader accepts, and whose per-band images give each band's eq. (9) DoLP;
//! bad colour keys exit 2 naming the field; `polarid demo --color` runs end to end.

use crate::common;

use common::{csv_rows, polarid, text};
use polarid_io::manifest::{self, CaptureSource};

const SCENE: &str = r#"name = "colour_test"
width = 64
height = 32
theta_r_deg = 60
theta_i_deg = [40, 55, 70]
seed = 4
bands = { R = 650.0, G = 550.0, B = 450.0 }

[sensor]
dark_level_dn = 64
band_response = { B = 0.5 }

[capture]
kind = "dofp"
color = "RGGB"

[[plate]]
name = "cu"
material = "gold"
sigma = 0.2
rect = [0, 0, 32, 32]

[[plate]]
name = "paint"
class = "paint"
n = { R = 1.39, G = 1.42, B = 1.45 }
k = { R = 0.34, G = 0.12, B = 0.30 }
sigma = 0.3
rect = [32, 0, 32, 32]
"#;

#[test]
fn simulate_writes_a_colour_capture_set_measure_can_read() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let out = dir.path().join("out");
    let o = polarid(&[
        "simulate",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let mtext = std::fs::read_to_string(out.join("manifest.toml")).unwrap();
    assert!(
        mtext.contains("bands = { R = 650.0, G = 550.0, B = 450.0 }"),
        "{mtext}"
    );
    assert!(mtext.contains("color = \"RGGB\""), "{mtext}");
    assert!(mtext.contains("class = \"gold\""), "{mtext}");
    let m = manifest::load(&out.join("manifest.toml")).unwrap();
    assert_eq!(m.captures.len(), 3);
    let CaptureSource::ColourDofp { wavelengths_nm, .. } = &m.captures[0].source else {
        panic!("colour capture expected")
    };
    assert_eq!(wavelengths_nm, &vec![650.0, 550.0, 450.0]);
    // truth.csv: one row per plate, capture and band, with the band's index.
    let truth = csv_rows(&out.join("truth.csv"));
    assert_eq!(truth.len(), 2 * 3 * 3);
    assert_eq!(truth[0]["band"], "R");
    assert_eq!(truth[2]["wavelength_nm"], "450");
    // Each band's region DoLP (bilinear per band, as measure does) is the truth's.
    for (ci, c) in m.captures.iter().enumerate() {
        let bands = polarid_io::bands::capture_band_images(&m, c).unwrap();
        for b in &bands {
            for r in &m.regions {
                let img = &b.images;
                let st = polarid_core::region::region_stats(
                    img.width,
                    &img.s0,
                    &img.s1,
                    &img.s2,
                    &img.mask,
                    r.rect,
                    img.sampling,
                )
                .unwrap();
                let wl = format!("{}", b.wavelength_nm.unwrap());
                let t = truth
                    .iter()
                    .filter(|t| t["target"] == r.name && t["wavelength_nm"] == wl)
                    .nth(ci)
                    .unwrap();
                let want: f64 = t["dolp"].parse().unwrap();
                let se = st.dolp_se.unwrap();
                assert!(
                    (st.dolp - want).abs() < 4.0 * se + 1e-3,
                    "{} {wl} capture {ci}: {} vs {want} (se {se})",
                    r.name,
                    st.dolp
                );
            }
        }
    }
}

#[test]
fn bad_colour_scenes_exit_2_naming_the_field() {
    for (from, to, field) in [
        ("color = \"RGGB\"", "color = \"RGB\"", "capture.color"),
        (
            "material = \"gold\"",
            "material = \"nosuch\"",
            "plate[1].material",
        ),
        (
            "n = { R = 1.39, G = 1.42, B = 1.45 }",
            "n = { R = 1.39 }",
            "plate[2].n.G",
        ),
        ("width = 64", "width = 62", "`width`"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene.toml");
        std::fs::write(&scene, SCENE.replace(from, to)).unwrap();
        let out = dir.path().join("out");
        let o = polarid(&[
            "simulate",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{field}: {}", text(&o.stderr));
        assert!(
            text(&o.stderr).contains(field),
            "{field}: {}",
            text(&o.stderr)
        );
        assert!(!out.exists(), "{field}: output written");
    }
}

#[test]
fn demo_color_runs_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("colour");
    let o = polarid(&[
        "demo",
        "--color",
        "--seeds",
        "2",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    for f in [
        "report.html",
        "report.md",
        "accuracy.md",
        "measurements.csv",
        "fits.csv",
        "model.json",
        "classification.csv",
        "classification_650nm.csv",
        "plots/dolp_450nm.png",
        "plots/nk_550nm.svg",
        "plots/nk_spectra.png",
        "captures/copper_test/manifest.toml",
        "captures/gold_test/truth.csv",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let class = csv_rows(&out.join("classification.csv"));
    assert_eq!(class.len(), 6);
    assert!(class.iter().all(|c| c["bands_used"] == "450;550;650"));
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for s in [
        "three bands",
        "one band (650 nm)",
        "n(λ) and k(λ)",
        "DoLP against β at 450 nm",
    ] {
        assert!(report.contains(s), "{s}");
    }
    let stdout = text(&o.stdout);
    assert!(
        stdout.contains("| three bands (450, 550, 650 nm) |"),
        "{stdout}"
    );
}
