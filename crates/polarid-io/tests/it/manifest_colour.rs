//! Colour polarization captures in the manifest: `bands`, `dofp.color`, per-capture
//! `wavelength_nm`, their validation errors (field and value named), and the per-band
//! Stokes images of `polarid_io::bands::capture_band_images`.

use std::path::{Path, PathBuf};

use polarid_core::mosaic::ColourPattern;
use polarid_io::IoError;
use polarid_io::bands::capture_band_images;
use polarid_io::manifest::{self, CaptureSource};

/// A 16×16 IMX250MYR mosaic (RGGB, 90/45/135/0) of uniform unpolarized-plus-linear
/// light at AoLP 0 with DoLP 0.1 (R), 0.2 (G), 0.3 (B): `I0 = 1000 (1 + P)`,
/// `I90 = 1000 (1 − P)`, `I45 = I135 = 1000`.
fn colour_raw(w: usize, h: usize) -> Vec<u16> {
    let p = ColourPattern::imx250myr();
    let dolp = [0.1f64, 0.2, 0.3];
    (0..w * h)
        .map(|i| {
            let (band, k) = p.channel_at(i / w, i % w);
            let c: f64 = [1.0, 0.0, -1.0, 0.0][k];
            (1000.0 * (1.0 + dolp[band] * c)).round() as u16
        })
        .collect()
}

fn setup(w: usize, h: usize) -> (tempfile::TempDir, PathBuf) {
    let d = tempfile::tempdir().unwrap();
    let raw = colour_raw(w, h);
    polarid_io::image::write_gray16(&d.path().join("raw.tif"), true, w, h, &raw).unwrap();
    polarid_io::image::write_gray16(&d.path().join("mono.tif"), true, w, h, &raw).unwrap();
    (d, PathBuf::new())
}

fn manifest_text(top: &str, dofp: &str, extra: &str) -> String {
    format!(
        "theta_r_deg = 60.0\n{top}\n[[region]]\nname = \"A\"\nrect = [4, 4, 8, 8]\n\n\
         [[capture]]\ntheta_i_deg = 40.0\ndofp = {dofp}\n\n\
         [[capture]]\ntheta_i_deg = 50.0\ndofp = {{ file = \"mono.tif\" }}\n{extra}\n"
    )
}

fn load(dir: &Path, text: &str) -> Result<manifest::Manifest, IoError> {
    let m = dir.join("scene.toml");
    std::fs::write(&m, text).unwrap();
    manifest::load(&m)
}

#[test]
fn colour_capture_with_bands_parses_and_measures_per_band() {
    let (d, _) = setup(16, 16);
    let text = manifest_text(
        "wavelength_nm = 632.8\nbands = { R = 650.0, G = 550.0, B = 450.0 }",
        r#"{ file = "raw.tif", pattern = [90, 45, 135, 0], color = "RGGB" }"#,
        "wavelength_nm = 600.0",
    );
    let m = load(d.path(), &text).unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    assert_eq!(
        m.bands.given,
        vec![('B', 450.0), ('G', 550.0), ('R', 650.0)]
    );
    let CaptureSource::ColourDofp {
        pattern,
        wavelengths_nm,
        ..
    } = &m.captures[0].source
    else {
        panic!("not a colour capture: {:?}", m.captures[0].source);
    };
    assert_eq!(pattern, &ColourPattern::imx250myr());
    assert_eq!(wavelengths_nm, &vec![650.0, 550.0, 450.0]);
    assert_eq!(m.captures[0].wavelength_nm, None);
    // the single-band capture's own wavelength overrides the top-level one
    assert_eq!(m.captures[1].wavelength_nm, Some(600.0));

    let bands = capture_band_images(&m, &m.captures[0]).unwrap();
    let got: Vec<(Option<f64>, Option<char>)> =
        bands.iter().map(|b| (b.wavelength_nm, b.band)).collect();
    assert_eq!(
        got,
        vec![
            (Some(450.0), Some('B')),
            (Some(550.0), Some('G')),
            (Some(650.0), Some('R'))
        ]
    );
    for (b, want) in bands.iter().zip([0.3f32, 0.2, 0.1]) {
        let img = &b.images;
        assert_eq!((img.width, img.height), (16, 16));
        assert_eq!(img.counts.valid, 256);
        for i in 0..256 {
            let d = (img.s1[i].hypot(img.s2[i])) / img.s0[i];
            assert!((d - want).abs() < 1e-6, "band {:?}: {d} vs {want}", b.band);
        }
    }
    let mono = capture_band_images(&m, &m.captures[1]).unwrap();
    assert_eq!(mono.len(), 1);
    assert_eq!((mono[0].wavelength_nm, mono[0].band), (Some(600.0), None));
}

#[test]
fn default_bands_and_top_level_wavelength() {
    let (d, _) = setup(16, 16);
    let text = manifest_text(
        "wavelength_nm = 632.8",
        r#"{ file = "raw.tif", color = "rggb" }"#,
        "",
    );
    let m = load(d.path(), &text).unwrap();
    let CaptureSource::ColourDofp { wavelengths_nm, .. } = &m.captures[0].source else {
        panic!("not a colour capture");
    };
    assert_eq!(wavelengths_nm, &vec![650.0, 550.0, 450.0]);
    assert_eq!(m.captures[1].wavelength_nm, Some(632.8));
}

/// The manifest error of `text`: (field, value, reason).
fn manifest_err(dir: &Path, text: &str) -> (String, String, String) {
    match load(dir, text) {
        Err(IoError::Manifest {
            field,
            value,
            reason,
            ..
        }) => (field, value, reason),
        other => panic!("expected a manifest error, got {other:?}"),
    }
}

#[test]
fn bad_colour_fields_are_named_with_their_values() {
    let (d, _) = setup(16, 16);
    let rgb = "bands = { R = 650.0, G = 550.0, B = 450.0 }";
    let cases: Vec<(String, &str, &str, &str)> = vec![
        // unknown colour letter
        (
            manifest_text(rgb, r#"{ file = "raw.tif", color = "RG1B" }"#, ""),
            "capture[1].dofp.color",
            "\"RG1B\"",
            "unknown colour letter `1`",
        ),
        // band missing
        (
            manifest_text(rgb, r#"{ file = "raw.tif", color = "RGGW" }"#, ""),
            "capture[1].dofp.color",
            "\"RGGW\"",
            "band missing: colour `W`",
        ),
        // no bands and a letter without a default band
        (
            manifest_text("", r#"{ file = "raw.tif", color = "RGBY" }"#, ""),
            "capture[1].dofp.color",
            "\"RGBY\"",
            "band missing: colour `Y`",
        ),
        // non-positive wavelength
        (
            manifest_text(
                "bands = { R = 650.0, G = 0.0, B = 450.0 }",
                r#"{ file = "raw.tif", color = "RGGB" }"#,
                "",
            ),
            "bands.G",
            "0.0",
            "wavelength must be > 0",
        ),
        (
            manifest_text(
                "bands = { R = -650, G = 550.0, B = 450.0 }",
                r#"{ file = "raw.tif", color = "RGGB" }"#,
                "",
            ),
            "bands.R",
            "-650",
            "wavelength must be > 0",
        ),
        // pattern period mismatch
        (
            manifest_text(rgb, r#"{ file = "raw.tif", color = "RGB" }"#, ""),
            "capture[1].dofp.color",
            "\"RGB\"",
            "do not match the 4x4 period",
        ),
        (
            manifest_text(rgb, r#"{ file = "raw.tif", color = "RGGBRGGB" }"#, ""),
            "capture[1].dofp.color",
            "\"RGGBRGGB\"",
            "do not match the 4x4 period",
        ),
        // band names
        (
            manifest_text(
                "bands = { RG = 650.0 }",
                r#"{ file = "raw.tif", color = "RGGB" }"#,
                "",
            ),
            "bands.RG",
            "RG",
            "single colour letters",
        ),
        // a colour capture's wavelength comes from bands
        (
            manifest_text(
                rgb,
                r#"{ file = "raw.tif", color = "RGGB" }
wavelength_nm = 550.0"#,
                "",
            ),
            "capture[1].wavelength_nm",
            "550.0",
            "come from the top-level `bands`",
        ),
        // a single-band capture's wavelength must be positive
        (
            manifest_text(rgb, r#"{ file = "raw.tif" }"#, "wavelength_nm = -1.0"),
            "capture[2].wavelength_nm",
            "-1.0",
            "wavelength must be > 0",
        ),
    ];
    for (text, field, value, reason) in cases {
        let (f, v, r) = manifest_err(d.path(), &text);
        assert_eq!((f.as_str(), v.as_str()), (field, value), "{text}\n{r}");
        assert!(r.contains(reason), "{field}: {r}");
    }
}

#[test]
fn a_raw_frame_that_is_not_whole_periods_is_measured_on_its_whole_periods() {
    // 18x16: the partial period (2 columns) is dropped, with a warning naming the file.
    let (d, _) = setup(18, 16);
    let text = manifest_text("", r#"{ file = "raw.tif", color = "RGGB" }"#, "");
    let m = load(d.path(), &text).unwrap();
    let bands = capture_band_images(&m, &m.captures[0]).unwrap();
    for b in &bands {
        assert_eq!((b.images.width, b.images.height), (16, 16));
        assert!(
            b.images.warnings.iter().any(|w| w.contains("raw.tif")
                && w.contains("18x16 pixels, not a whole number of 4x4 colour periods")),
            "{:?}",
            b.images.warnings
        );
    }
    // Not one whole period left: refused, naming the file.
    let (d, _) = setup(3, 16);
    let m = load(d.path(), &text).unwrap();
    match capture_band_images(&m, &m.captures[0]) {
        Err(IoError::Core { path, source }) => {
            assert!(path.ends_with("raw.tif"), "{path:?}");
            assert!(source.to_string().contains("whole period"), "{source}");
        }
        other => panic!("expected a Core error naming raw.tif, got {other:?}"),
    }
}
