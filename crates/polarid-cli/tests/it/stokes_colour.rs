//! `polarid stokes --dofp RAW --color RGGB`: per-band Stokes, DoLP and AoLP files and
//! colour previews of a colour polarization mosaic; bad colour options exit 2 with
//! nothing written.

use std::process::Command;

use polarid_core::mosaic::ColourPattern;

/// A 32×24 IMX250MYR mosaic of uniform light at AoLP 0 with DoLP 0.1 (R), 0.2 (G),
/// 0.3 (B).
fn write_raw(path: &std::path::Path) {
    let (w, h) = (32, 24);
    let p = ColourPattern::imx250myr();
    let dolp = [0.1f64, 0.2, 0.3];
    let raw: Vec<u16> = (0..w * h)
        .map(|i| {
            let (band, k) = p.channel_at(i / w, i % w);
            let c: f64 = [1.0, 0.0, -1.0, 0.0][k];
            (1000.0 * (1.0 + dolp[band] * c)).round() as u16
        })
        .collect();
    polarid_io::image::write_gray16(path, true, w, h, &raw).unwrap();
}

#[test]
fn colour_mosaic_gives_per_band_files_and_previews() {
    let d = tempfile::tempdir().unwrap();
    let raw = d.path().join("raw.tif");
    write_raw(&raw);
    let out = d.path().join("out");
    let st = Command::new(env!("CARGO_BIN_EXE_polarid"))
        .args(["stokes", "--dofp"])
        .arg(&raw)
        .args(["--color", "RGGB", "--bands", "R=650,G=550,B=450", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    for (nm, want) in [("450", 0.3f32), ("550", 0.2), ("650", 0.1)] {
        for q in ["s0", "s1", "s2", "aolp"] {
            assert!(out.join(format!("{q}_{nm}.tif")).is_file(), "{q}_{nm}.tif");
        }
        assert!(out.join(format!("dolp_{nm}.png")).is_file());
        let f = polarid_io::image::read_frame(&out.join(format!("dolp_{nm}.tif"))).unwrap();
        assert_eq!((f.width, f.height), (32, 24));
        for v in f.data {
            assert!((v - want).abs() < 1e-6, "dolp_{nm}: {v} vs {want}");
        }
    }
    for name in ["s0_rgb.png", "dolp_rgb.png"] {
        assert!(out.join(name).is_file(), "{name}");
    }
    // super-pixel: one output per 4x4 period
    let out2 = d.path().join("sp");
    let st = Command::new(env!("CARGO_BIN_EXE_polarid"))
        .args(["stokes", "--demosaic", "superpixel", "--dofp"])
        .arg(&raw)
        .args(["--color", "RGGB", "-o"])
        .arg(&out2)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let f = polarid_io::image::read_frame(&out2.join("dolp_550.tif")).unwrap();
    assert_eq!((f.width, f.height), (8, 6));
}

#[test]
fn bad_colour_options_exit_2_and_write_nothing() {
    let d = tempfile::tempdir().unwrap();
    let raw = d.path().join("raw.tif");
    write_raw(&raw);
    for (args, needle) in [
        (vec!["--color", "RGB"], "RGB"),
        (vec!["--color", "RG1B"], "RG1B"),
        (vec!["--color", "RGGW"], "band missing"),
        (vec!["--color", "RGGB", "--bands", "R=650,G=-5,B=450"], "-5"),
        (vec!["--color", "RGGB", "--bands", "R650"], "R650"),
    ] {
        let out = d.path().join("bad");
        let st = Command::new(env!("CARGO_BIN_EXE_polarid"))
            .args(["stokes", "--dofp"])
            .arg(&raw)
            .args(&args)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&st.stderr);
        assert_eq!(st.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?}: output written");
    }
}
