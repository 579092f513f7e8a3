//! The PNG views of `polarid stokes`: which files, the fixed DoLP scale, the AoLP
//! modes and the colours of saturated and dark pixels (docs/FORMATS.md).

use crate::common;

use common::polarid;

use std::path::Path;

/// viridis(0.5), viridis(0) and viridis(1) of the colour map (matplotlib's anchors).
const VIRIDIS_MID: [u8; 3] = [35, 144, 140];
const VIRIDIS_LOW: [u8; 3] = [68, 1, 84];
const VIRIDIS_TOP: [u8; 3] = [253, 231, 37];
/// The documented colours of saturated and of dark pixels.
const SATURATED: [u8; 3] = [255, 96, 255];
const DARK: [u8; 3] = [40, 56, 72];

/// An 8-bit DoFP mosaic (pattern 90,45 / 135,0) of four 2×2 blocks, side by side:
/// DoLP 0.5 at AoLP 0 (S0 200), saturated (I90 = 255), unpolarized (S0 200), dark (0).
fn write_raw(path: &Path) {
    // (I90, I45, I135, I0) per block
    let blocks = [
        [50, 100, 100, 150],
        [255, 100, 100, 100],
        [100, 100, 100, 100],
        [0, 0, 0, 0],
    ];
    let w = 8;
    let mut raw = vec![0u8; w * 2];
    for (b, v) in blocks.iter().enumerate() {
        raw[2 * b] = v[0];
        raw[2 * b + 1] = v[1];
        raw[w + 2 * b] = v[2];
        raw[w + 2 * b + 1] = v[3];
    }
    polarid_io::image::write_gray8(path, false, w, 2, &raw).unwrap();
}

/// An 8-bit RGB PNG view: width, height and the RGB bytes, row by row.
struct Rgb {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

fn rgb(path: &Path) -> Rgb {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    buf.truncate(info.buffer_size());
    Rgb {
        width: info.width,
        height: info.height,
        data: buf,
    }
}

/// Pixel `x` of the first row.
fn px(img: &Rgb, x: u32) -> [u8; 3] {
    let i = 3 * x as usize;
    [img.data[i], img.data[i + 1], img.data[i + 2]]
}

fn run(dir: &Path, out: &str, extra: &[&str]) -> std::path::PathBuf {
    let raw = dir.join("raw.png");
    if !raw.exists() {
        write_raw(&raw);
    }
    let o = dir.join(out);
    let (r, os) = (raw.display().to_string(), o.display().to_string());
    let mut args = vec![
        "stokes",
        "--dofp",
        &r,
        "--demosaic",
        "superpixel",
        "-o",
        &os,
    ];
    args.extend(extra);
    let res = polarid(&args);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    o
}

#[test]
fn views_use_fixed_scale_and_flag_colours() {
    let d = tempfile::tempdir().unwrap();
    let o = run(d.path(), "out", &[]);
    for f in [
        "s0.tif", "s1.tif", "s2.tif", "dolp.tif", "aolp.tif", "s0.png", "dolp.png", "aolp.png",
    ] {
        assert!(o.join(f).is_file(), "{f} missing");
    }
    // S0: the image alone, white at the valid pixels' S0 (both 200).
    let s0 = rgb(&o.join("s0.png"));
    assert_eq!((s0.width, s0.height), (4, 1));
    assert_eq!(
        [px(&s0, 0), px(&s0, 1), px(&s0, 2), px(&s0, 3)],
        [[255; 3], SATURATED, [255; 3], DARK]
    );
    // DoLP on the fixed 0..1 scale: 0.5 is the colour map's middle; a bar underneath.
    let dolp = rgb(&o.join("dolp.png"));
    assert_eq!(dolp.width, 4);
    assert!(dolp.height > 1);
    assert_eq!(
        [px(&dolp, 0), px(&dolp, 1), px(&dolp, 2), px(&dolp, 3)],
        [VIRIDIS_MID, SATURATED, VIRIDIS_LOW, DARK]
    );
    // AoLP as hue: 0° is red at any DoLP (the unpolarized block's AoLP is 0 too).
    let aolp = rgb(&o.join("aolp.png"));
    assert_eq!(
        [px(&aolp, 0), px(&aolp, 1), px(&aolp, 3)],
        [[255, 0, 0], SATURATED, DARK]
    );
}

#[test]
fn auto_scale_and_hsv_aolp() {
    let d = tempfile::tempdir().unwrap();
    let o = run(
        d.path(),
        "auto",
        &["--dolp-max", "auto", "--aolp-view", "hsv"],
    );
    // The 99th percentile is 0.5: the scale ends there.
    let dolp = rgb(&o.join("dolp.png"));
    assert_eq!(px(&dolp, 0), VIRIDIS_TOP);
    // DoLP as brightness: DoLP 0.5 of 0.5 is full red, the unpolarized block black.
    let aolp = rgb(&o.join("aolp.png"));
    assert_eq!([px(&aolp, 0), px(&aolp, 2)], [[255, 0, 0], [0, 0, 0]]);

    let o = run(d.path(), "half", &["--aolp-view", "hsv"]);
    let aolp = rgb(&o.join("aolp.png"));
    assert_eq!(px(&aolp, 0), [128, 0, 0]);
}

#[test]
fn bad_dolp_max_exits_2_and_writes_nothing() {
    let d = tempfile::tempdir().unwrap();
    let raw = d.path().join("raw.png");
    write_raw(&raw);
    let o = d.path().join("out");
    let (r, os) = (raw.display().to_string(), o.display().to_string());
    for bad in ["0", "1.5", "x"] {
        let res = polarid(&["stokes", "--dofp", &r, "--dolp-max", bad, "-o", &os]);
        assert_eq!(res.status.code(), Some(2), "--dolp-max {bad}");
        assert!(
            String::from_utf8_lossy(&res.stderr).contains("--dolp-max"),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        assert!(!o.exists());
    }
}
