//! `polarid stokes` end to end: generated frames in a tempdir, outputs, exit codes,
//! messages, and no partial output on failure.

use crate::common;

use common::polarid;

use std::path::{Path, PathBuf};
use std::process::Output;

use polarid_io::image;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// I(a) for S = (1000, 200, -300) + a small ramp so that pixels differ.
fn frame_value(x: usize, y: usize, a_deg: f64) -> u16 {
    let s0 = 1000.0 + 10.0 * x as f64 + 4.0 * y as f64;
    let (s1, s2) = (200.0, -300.0);
    let a = 2.0 * a_deg.to_radians();
    (0.5 * (s0 + s1 * a.cos() + s2 * a.sin())).round() as u16
}

fn write_frames(dir: &Path, angles: &[f64], w: usize, h: usize) -> Vec<PathBuf> {
    angles
        .iter()
        .map(|&a| {
            let p = dir.join(format!("pol{a:03}.png"));
            let data: Vec<u16> = (0..w * h).map(|i| frame_value(i % w, i / w, a)).collect();
            image::write_gray16(&p, false, w, h, &data).unwrap();
            p
        })
        .collect()
}

#[test]
fn frames_give_stokes_dolp_aolp_and_views() {
    let d = tempfile::tempdir().unwrap();
    let (w, h) = (12, 8);
    let frames = write_frames(d.path(), &[0.0, 45.0, 90.0, 135.0], w, h);
    let out = d.path().join("out");
    let mut args = vec!["stokes", "--frames"];
    let fs: Vec<String> = frames.iter().map(|p| p.display().to_string()).collect();
    args.extend(fs.iter().map(String::as_str));
    let outs = out.display().to_string();
    args.extend(["--angles", "0,45,90,135", "-o", &outs]);
    let o = polarid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in [
        "s0.tif", "s1.tif", "s2.tif", "dolp.tif", "aolp.tif", "dolp.png", "aolp.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let s0 = image::read_frame(&out.join("s0.tif")).unwrap();
    let s1 = image::read_frame(&out.join("s1.tif")).unwrap();
    let dolp = image::read_frame(&out.join("dolp.tif")).unwrap();
    let aolp = image::read_frame(&out.join("aolp.tif")).unwrap();
    assert_eq!((s0.width, s0.height), (w, h));
    // Pixel (0,0): S0 = 1000 up to the rounding of the frames to whole DN.
    assert!((s0.data[0] - 1000.0).abs() <= 1.0, "{}", s0.data[0]);
    assert!((s1.data[0] - 200.0).abs() <= 1.0, "{}", s1.data[0]);
    let want = (200f32.hypot(300.0)) / 1000.0;
    assert!((dolp.data[0] - want).abs() < 2e-3, "{}", dolp.data[0]);
    let want_a = (0.5 * (-300f32).atan2(200.0)).to_degrees() + 180.0;
    assert!(
        (aolp.data[0] - want_a).abs() < 0.2,
        "{} vs {want_a}",
        aolp.data[0]
    );
    // A second run without --force refuses to overwrite, with exit status 2.
    let o = polarid(&args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("exists"), "{}", stderr(&o));
}

#[test]
fn bad_inputs_exit_2_and_leave_nothing() {
    let d = tempfile::tempdir().unwrap();
    let frames = write_frames(d.path(), &[0.0, 45.0, 90.0], 6, 4);
    let f: Vec<String> = frames.iter().map(|p| p.display().to_string()).collect();
    let out = d.path().join("out");
    let outs = out.display().to_string();
    let run = |angles: &str, files: &[&str]| {
        let mut a = vec!["stokes", "--frames"];
        a.extend_from_slice(files);
        a.extend(["--angles", angles, "-o", &outs]);
        polarid(&a)
    };
    let all: Vec<&str> = f.iter().map(String::as_str).collect();
    // Wrong number of angles.
    let o = run("0,45", &all);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("one angle per frame"), "{}", stderr(&o));
    // Singular angle set.
    let o = run("0,90,180", &all);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("singular"), "{}", stderr(&o));
    // Frames of different sizes: the message names the odd file.
    let odd = d.path().join("odd.tif");
    image::write_gray8(&odd, false, 5, 4, &[1; 20]).unwrap();
    let odds = odd.display().to_string();
    let o = run("0,45,90", &[all[0], all[1], &odds]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("odd.tif") && stderr(&o).contains("same size"),
        "{}",
        stderr(&o)
    );
    // Odd-sized DoFP mosaic.
    let o = polarid(&["stokes", "--dofp", &odds, "-o", &outs]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("even"), "{}", stderr(&o));
    // Bad pattern.
    let o = polarid(&[
        "stokes",
        "--dofp",
        all[0],
        "--pattern",
        "0,45,90,90",
        "-o",
        &outs,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("pattern"), "{}", stderr(&o));
    assert!(!out.exists(), "partial output left behind");
    let leftovers: Vec<_> = std::fs::read_dir(d.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".polarid"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    // Ill-conditioned angles: a warning, but it works.
    let o = run("0,4,8", &all);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning") && stderr(&o).contains("condition number"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn dofp_frames_bilinear_and_superpixel() {
    let d = tempfile::tempdir().unwrap();
    let (w, h) = (16, 12);
    // Uniform scene S = (1000, 200, -300): pattern 90,45,135,0.
    let pat = [90.0, 45.0, 135.0, 0.0];
    let raw: Vec<u16> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let a = pat[2 * (y % 2) + x % 2];
            let a2 = 2.0f64 * f64::to_radians(a);
            (0.5 * (1000.0 + 200.0 * a2.cos() - 300.0 * a2.sin())).round() as u16
        })
        .collect();
    let rp = d.path().join("raw.tif");
    image::write_gray16(&rp, false, w, h, &raw).unwrap();
    let rps = rp.display().to_string();
    for (mode, ow, oh) in [("bilinear", w, h), ("superpixel", w / 2, h / 2)] {
        let out = d.path().join(mode);
        let o = polarid(&[
            "-q",
            "stokes",
            "--dofp",
            &rps,
            "--demosaic",
            mode,
            "-o",
            &out.display().to_string(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let s0 = image::read_frame(&out.join("s0.tif")).unwrap();
        let dolp = image::read_frame(&out.join("dolp.tif")).unwrap();
        assert_eq!((s0.width, s0.height), (ow, oh));
        for (&s, &p) in s0.data.iter().zip(&dolp.data) {
            assert!((s - 1000.0).abs() <= 1.0, "{mode}: S0 {s}");
            assert!((p - 0.36056).abs() < 2e-3, "{mode}: DoLP {p}");
        }
    }
}
