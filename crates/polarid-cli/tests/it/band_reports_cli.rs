//! Per-band figures of a user's own data (issue 17, docs/BANDS.md "Per-band plots of
//! your data"): `fit --report`, `classify --report` and `map` on colour captures, end
//! to end from a colour scene rendered by `polarid simulate`; single-band reports draw
//! the single-band figures, and a colour map's extra figures are absent from mono maps.

use crate::common;

use common::{csv_rows, polarid_in, text};

use std::path::Path;
use std::process::Output;

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "status {:?}\nstderr: {}",
        o.status,
        text(&o.stderr)
    );
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Copper and gold plates, 32 × 32 pixels each, under an IMX250MYR-type colour DoFP
/// (the colour demo's camera), θr = 60°, θi = 30…79° in 8 captures.
const SCENE: &str = r#"name = "cu_au"
width = 64
height = 32
theta_r_deg = 60.0
theta_i_deg = [30.0, 37.0, 44.0, 51.0, 58.0, 65.0, 72.0, 79.0]
seed = 7
bands = { R = 650.0, G = 550.0, B = 450.0 }

[sensor]
bit_depth = 12
full_well_e = 10000.0
read_noise_e = 3.0
dark_level_dn = 64.0
band_response = { R = 1.0, G = 1.0, B = 0.5 }

[capture]
kind = "dofp"
pattern = [90, 45, 135, 0]
color = "RGGB"

[[plate]]
name = "plate_cu"
material = "copper"
sigma = 0.2
rect = [0, 0, 32, 32]

[[plate]]
name = "plate_au"
material = "gold"
sigma = 0.2
rect = [32, 0, 32, 32]
"#;

#[test]
fn colour_captures_get_per_band_figures_through_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    ok(&polarid_in(d, &["simulate", "scene.toml", "-o", "sim"]));
    ok(&polarid_in(
        d,
        &["measure", "sim/manifest.toml", "-o", "meas.csv"],
    ));
    ok(&polarid_in(
        d,
        &[
            "fit",
            "meas.csv",
            "-o",
            "fits.csv",
            "--film-sd-nm",
            "0",
            "--report",
            "fit_report",
        ],
    ));
    let fits = csv_rows(&d.join("fits.csv"));
    assert_eq!(fits.len(), 6, "two plates, three bands");

    // fit: DoLP against β, the (n, k) plane per band, n(λ) and k(λ).
    let r = d.join("fit_report");
    for f in ["report.html", "report.md"] {
        assert!(r.join(f).is_file(), "{f}");
    }
    for stem in ["dolp_bands", "nk_bands", "nk_spectra"] {
        for ext in ["png", "svg"] {
            assert!(
                r.join(format!("plots/{stem}.{ext}")).is_file(),
                "{stem}.{ext}"
            );
        }
    }
    assert!(!r.join("plots/dolp_vs_beta.png").exists());
    let dolp = read(&r.join("plots/dolp_bands.svg"));
    let nk = read(&r.join("plots/nk_bands.svg"));
    for w in ["450", "550", "650"] {
        assert_eq!(dolp.matches(&format!("λ = {w} nm")).count(), 1, "{w}");
        assert!(dolp.contains(&format!("DoLP at {w} nm")), "{w}");
        assert_eq!(nk.matches(&format!("λ = {w} nm")).count(), 1, "{w}");
        assert!(nk.contains(&format!("n at {w} nm")), "{w}");
    }
    let spectra = read(&r.join("plots/nk_spectra.svg"));
    for name in ["plate_cu", "plate_au", "copper", "gold", "wavelength (nm)"] {
        assert!(spectra.contains(name), "{name}");
    }
    let md = read(&r.join("report.md"));
    assert!(md.contains("plots/nk_spectra.png"), "{md}");
    assert!(md.contains(r"plate\_cu @ 450 nm"), "{md}");
    // A second run without --force does not overwrite the report.
    let again = polarid_in(
        d,
        &[
            "fit",
            "meas.csv",
            "-o",
            "fits2.csv",
            "--report",
            "fit_report",
        ],
    );
    assert!(!again.status.success(), "{}", text(&again.stderr));
    assert!(!d.join("fits2.csv").exists());

    // classify: the (n, k) plane per band and the spectra against the library.
    ok(&polarid_in(
        d,
        &[
            "classify",
            "fits.csv",
            "--library",
            "builtin-rgb",
            "-o",
            "class.csv",
            "--report",
            "class_report",
        ],
    ));
    let rows = csv_rows(&d.join("class.csv"));
    assert_eq!(rows.len(), 2);
    let c = d.join("class_report");
    for stem in ["nk_bands", "nk_spectra"] {
        assert!(c.join(format!("plots/{stem}.svg")).is_file(), "{stem}");
    }
    assert!(!c.join("plots/dolp_bands.svg").exists(), "no measurements");
    let nk = read(&c.join("plots/nk_bands.svg"));
    for r in &rows {
        // The legend gives each plate's answer; its answer is a drawn reference.
        assert!(
            nk.contains(&format!("{}: ", r["target"])),
            "{}",
            r["target"]
        );
        if r["predicted"] != "unknown" {
            assert!(nk.contains(r["predicted"].as_str()), "{}", r["predicted"]);
        }
    }

    // map: n and k images per band, the regions' (n, k) per band and spectra.
    ok(&polarid_in(
        d,
        &[
            "map",
            "sim/manifest.toml",
            "--library",
            "builtin-rgb",
            "--bin",
            "4",
            "-o",
            "map",
        ],
    ));
    let m = d.join("map");
    for w in ["450", "550", "650"] {
        for q in ["n", "k"] {
            for ext in ["png", "svg"] {
                let f = m.join(format!("{q}_{w}.{ext}"));
                assert!(f.is_file(), "{}", f.display());
            }
            assert!(read(&m.join(format!("{q}_{w}.svg"))).contains(&format!("{q} at {w} nm")));
        }
    }
    let nk = read(&m.join("nk_bands.svg"));
    assert_eq!(nk.matches("λ = ").count(), 3);
    let spectra = read(&m.join("nk_spectra.svg"));
    for name in ["plate_cu", "plate_au", "copper", "gold"] {
        assert!(spectra.contains(name), "{name}");
    }
    // Mapping again into the same directory without --force is refused before any work.
    let again = polarid_in(
        d,
        &[
            "map",
            "sim/manifest.toml",
            "--library",
            "builtin-rgb",
            "--bin",
            "4",
            "-o",
            "map",
        ],
    );
    assert!(!again.status.success(), "{}", text(&again.stderr));
}

#[test]
fn single_band_reports_draw_the_single_band_figures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Eq. (9) DoLP of two targets at eight β, no wavelength_nm.
    let mut csv = String::from("target,class,beta_deg,dolp,dolp_se\n");
    for (t, n, k) in [("a", 1.4, 3.9), ("b", 1.5, 0.0)] {
        for j in 0..8 {
            let beta = 40.0 + 4.0 * j as f64;
            let p = polarid_core::dop::dop(n, k, f64::to_radians(beta));
            csv += &format!("{t},,{beta},{p:.6},0.003\n");
        }
    }
    std::fs::write(d.join("meas.csv"), csv).unwrap();
    ok(&polarid_in(d, &["fit", "meas.csv", "-o", "plain.csv"]));
    ok(&polarid_in(
        d,
        &["fit", "meas.csv", "-o", "fits.csv", "--report", "rep"],
    ));
    // The report changes nothing in the fits.
    assert_eq!(read(&d.join("plain.csv")), read(&d.join("fits.csv")));
    for stem in ["dolp_vs_beta", "nk_plane"] {
        let svg = read(&d.join(format!("rep/plots/{stem}.svg")));
        assert!(!svg.contains("λ = "), "{stem}");
    }
    assert!(!d.join("rep/plots/nk_spectra.svg").exists());
    // A library that does not load is refused before the fit writes anything.
    let bad = polarid_in(
        d,
        &[
            "fit",
            "meas.csv",
            "-o",
            "x.csv",
            "--report",
            "r2",
            "--report-library",
            "nope.csv",
        ],
    );
    assert_eq!(bad.status.code(), Some(2), "{}", text(&bad.stderr));
    assert!(
        text(&bad.stderr).contains("nope.csv"),
        "{}",
        text(&bad.stderr)
    );
    assert!(!d.join("x.csv").exists() && !d.join("r2").exists());
    ok(&polarid_in(
        d,
        &[
            "classify",
            "fits.csv",
            "--library",
            "builtin",
            "--report",
            "crep",
        ],
    ));
    assert!(d.join("crep/plots/nk_plane.png").is_file());
    assert!(d.join("crep/report.html").is_file());
}
