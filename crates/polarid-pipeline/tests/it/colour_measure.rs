//! `measure` of colour captures, per band (issue 17): rows per (target, capture, band)
//! with `wavelength_nm`, the dark threshold and saturation per band, HDR brackets of
//! colour mosaics, and manifests without colour captures unchanged.
//!
//! The mosaics are built here: each raw pixel of an IMX250MYR-type pattern (RGGB blocks
//! of 90/45/135/0 polarizers) holds `dark + b·(1 + P cos 2a)` for its band's brightness
//! `b` and DoLP `P` (AoLP 0) at its polarizer angle `a`.

use std::path::{Path, PathBuf};

use polarid_core::mosaic::ColourPattern;
use polarid_io::manifest;
use polarid_io::table::measurements::RowStatus;
use polarid_pipeline::measure;

const W: usize = 32;
const H: usize = 16;
const DARK: f64 = 64.0;

/// Two targets: A (columns 0..16) and B (16..32). Per target and band (R, G, B of the
/// pattern): brightness (DN above dark) and DoLP.
type Scene = [[(f64, f64); 3]; 2];

fn mosaic(scene: &Scene, scale: f64) -> Vec<u16> {
    let p = ColourPattern::imx250myr();
    assert_eq!(p.bands(), &['R', 'G', 'B']);
    (0..W * H)
        .map(|i| {
            let (y, x) = (i / W, i % W);
            let (band, k) = p.channel_at(y, x);
            let (b, dolp) = scene[usize::from(x >= 16)][band];
            let c = [1.0, 0.0, -1.0, 0.0][k];
            (DARK + scale * b * (1.0 + dolp * c)).round().min(4095.0) as u16
        })
        .collect()
}

fn write(dir: &Path, name: &str, data: &[u16]) {
    polarid_io::image::write_gray16(&dir.join(name), true, W, H, data).unwrap();
}

fn manifest_text(captures: &str) -> String {
    format!(
        "theta_r_deg = 60.0\ndark_level = 64.0\nsaturation = 4095.0\n\
         bands = {{ R = 650.0, G = 550.0, B = 450.0 }}\n\
         [[region]]\nname = \"A\"\nrect = [4, 4, 8, 8]\n\
         [[region]]\nname = \"B\"\nrect = [20, 4, 8, 8]\n{captures}"
    )
}

fn load(dir: &Path, text: &str) -> manifest::Manifest {
    let p: PathBuf = dir.join("m.toml");
    std::fs::write(&p, text).unwrap();
    manifest::load(&p).unwrap()
}

const SCENE: Scene = [
    // A: bright in R (saturates at 4x), dark in B
    [(900.0, 0.30), (600.0, 0.20), (10.0, 0.10)],
    // B
    [(500.0, 0.15), (400.0, 0.25), (300.0, 0.35)],
];

#[test]
fn rows_per_band_with_wavelength_dark_band_and_mono_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "raw.tif", &mosaic(&SCENE, 1.0));
    let caps: String = [40.0, 50.0]
        .iter()
        .map(|t| {
            format!(
                "\n[[capture]]\ntheta_i_deg = {t}\n\
                 dofp = {{ file = \"raw.tif\", color = \"RGGB\" }}\n"
            )
        })
        .collect();
    let m = load(d, &manifest_text(&caps));
    let out = measure::measure(&m, &|_, _, _| {}).unwrap();
    assert_eq!(out.rows.len(), 2 * 3 * 2);
    // per capture: 450 (A, B), 550 (A, B), 650 (A, B)
    for (i, r) in out.rows.iter().enumerate() {
        let band = [450.0, 550.0, 650.0][(i / 2) % 3];
        assert_eq!(r.wavelength_nm, Some(band), "{r:?}");
        let t = i % 2;
        assert_eq!(r.target, ["A", "B"][t]);
        let (b, dolp) = SCENE[t][[2, 1, 0][(i / 2) % 3]];
        if t == 0 && band == 450.0 {
            // S0 = 2b = 20 DN, below the default threshold (1 % of 4031 DN = 40.3 DN)
            assert_eq!(r.status, RowStatus::Dark, "{r:?}");
            assert!(r.reason.contains("band 450 nm"), "{}", r.reason);
            continue;
        }
        assert_eq!(r.status, RowStatus::Ok, "{r:?}");
        // the raw values are whole DN: the DoLP is exact
        assert!((r.dolp - dolp).abs() < 1e-4, "{r:?}: {} vs {dolp}", r.dolp);
        // S0 = (I0 + I90 + I45 + I135)/2 above dark = 2b
        assert!((r.s0.unwrap() - 2.0 * b).abs() < 0.01, "{r:?}");
    }
    // the not-ok rows are summarised in a warning naming the band
    assert!(
        out.warnings.iter().any(|w| w.0.contains("band 450 nm")),
        "{:?}",
        out.warnings
    );

    // strict: the dark band is an error naming the region's rect and the band
    let e = polarid_io::measure::measure_manifest_with(&m, true, &mut |_| {}).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("region[1].rect") && msg.contains("band 450 nm"),
        "{msg}"
    );

    // a manifest without colour captures: a capture's wavelength_nm reaches its rows
    write(d, "mono.tif", &mosaic(&SCENE, 1.0));
    let mono = load(
        d,
        &manifest_text(
            "\n[[capture]]\ntheta_i_deg = 40.0\ndofp = { file = \"mono.tif\" }\nwavelength_nm = 600.0\n",
        ),
    );
    let rows = measure::measure(&mono, &|_, _, _| {}).unwrap().rows;
    assert_eq!(rows.len(), 2);
    assert!(rows.iter().all(|r| r.wavelength_nm == Some(600.0)));
    // next to a colour capture, a single-band capture's rows carry its wavelength
    let mixed = load(
        d,
        &manifest_text(
            "\n[[capture]]\ntheta_i_deg = 40.0\ndofp = { file = \"raw.tif\", color = \"RGGB\" }\n\
             \n[[capture]]\ntheta_i_deg = 50.0\ndofp = { file = \"mono.tif\" }\nwavelength_nm = 600.0\n",
        ),
    );
    let rows = measure::measure(&mixed, &|_, _, _| {}).unwrap().rows;
    assert_eq!(rows.len(), 6 + 2);
    assert!(rows[6..].iter().all(|r| r.wavelength_nm == Some(600.0)));
}

#[test]
fn hdr_brackets_of_colour_mosaics_merge_per_band() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Long exposure (x4): A's R band saturates (900·1.3·4 > 4095); short exposure (x1).
    write(d, "long.tif", &mosaic(&SCENE, 4.0));
    write(d, "short.tif", &mosaic(&SCENE, 1.0));
    let hdr = "\n[[capture]]\ntheta_i_deg = 40.0\nbrackets = [\n\
               { exposure = 4.0, dofp = { file = \"long.tif\", color = \"RGGB\" } },\n\
               { exposure = 1.0, dofp = { file = \"short.tif\", color = \"RGGB\" } },\n]\n";
    let m = load(d, &manifest_text(hdr));
    assert_eq!(m.captures[0].brackets.len(), 2);
    let rows = measure::measure(&m, &|_, _, _| {}).unwrap().rows;
    assert_eq!(rows.len(), 6);
    for (i, r) in rows.iter().enumerate() {
        let t = i % 2;
        let (b, dolp) = SCENE[t][[2, 1, 0][i / 2]];
        // A (whose red pixels saturate in the long exposure, and every pixel within 3 of
        // them) comes from the short exposure, B from the long one; in DN of the long
        // exposure S0 = 4·2b, divided by the capture's exposure 4. A's blue band, dark
        // in one exposure, is bright enough after the merge (80 DN).
        assert_eq!(r.status, RowStatus::Ok, "{r:?}");
        assert_eq!(r.saturated, Some(0), "{r:?}");
        assert!((r.dolp - dolp).abs() < 1e-4, "{r:?}: {} vs {dolp}", r.dolp);
        assert!((r.s0.unwrap() - 2.0 * b).abs() < 0.01, "{r:?}");
    }
    // The long exposure alone: A is saturated in 650 nm only.
    let long = load(
        d,
        &manifest_text(
            "\n[[capture]]\ntheta_i_deg = 40.0\ndofp = { file = \"long.tif\", color = \"RGGB\" }\n",
        ),
    );
    let rows = measure::measure(&long, &|_, _, _| {}).unwrap().rows;
    let sat: Vec<(String, Option<f64>)> = rows
        .iter()
        .filter(|r| r.status == RowStatus::Saturated)
        .map(|r| (r.target.clone(), r.wavelength_nm))
        .collect();
    assert_eq!(sat, vec![("A".to_string(), Some(650.0))]);
}
