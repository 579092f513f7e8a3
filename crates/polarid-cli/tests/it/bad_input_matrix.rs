//! The bad-input matrix (issue 9): one test per kind of bad input the readers and
//! commands can meet. Each builds its inputs in a temporary directory, runs `polarid`,
//! and checks the exit status (2: bad input or usage), the key words of the message
//! (file, field or line, value) and that no output — not even a temporary file — was
//! left behind.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use polarid_io::image;

// ---------------------------------------------------------------------------------------
// Harness

struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    fn new() -> Self {
        Self {
            dir: tempfile::tempdir().unwrap(),
        }
    }

    fn p(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn s(&self, name: &str) -> String {
        self.p(name).display().to_string()
    }

    fn write(&self, name: &str, text: &str) -> String {
        let p = self.p(name);
        if let Some(parent) = p.parent() {
            fs::create_dir_all(parent).unwrap();
        }
        fs::write(&p, text).unwrap();
        p.display().to_string()
    }

    fn bytes(&self, name: &str, b: &[u8]) -> String {
        fs::write(self.p(name), b).unwrap();
        self.s(name)
    }

    /// A `w x h` 16-bit PNG/TIFF frame with a smooth ramp.
    fn gray16(&self, name: &str, w: usize, h: usize) -> String {
        let v: Vec<u16> = (0..w * h).map(|i| 1000 + (i % 97) as u16 * 10).collect();
        image::write_gray16(&self.p(name), false, w, h, &v).unwrap();
        self.s(name)
    }

    fn gray8(&self, name: &str, w: usize, h: usize) -> String {
        let v: Vec<u8> = (0..w * h).map(|i| 50 + (i % 50) as u8).collect();
        image::write_gray8(&self.p(name), false, w, h, &v).unwrap();
        self.s(name)
    }

    fn f32(&self, name: &str, w: usize, h: usize, value: f32) -> String {
        image::write_tiff_f32(&self.p(name), false, w, h, &vec![value; w * h]).unwrap();
        self.s(name)
    }

    /// Run polarid inside the case directory.
    fn run(&self, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_polarid"))
            .args(args)
            .current_dir(self.dir.path())
            .output()
            .unwrap()
    }

    /// The set of entries of the case directory (recursively), for "nothing appeared".
    fn listing(&self) -> Vec<PathBuf> {
        fn walk(d: &Path, out: &mut Vec<PathBuf>) {
            for e in fs::read_dir(d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    walk(&p, out);
                }
                out.push(p);
            }
        }
        let mut v = Vec::new();
        walk(self.dir.path(), &mut v);
        v.sort();
        v
    }
}

/// Run `args` and check: exit status 2, every word of `words` in the message, and the
/// case directory unchanged (no output, no temporary or staging file).
#[track_caller]
fn bad(c: &Case, args: &[&str], words: &[&str]) -> String {
    let before = c.listing();
    let o = c.run(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(2),
        "expected exit status 2 for {args:?}\nstderr: {err}"
    );
    assert!(err.contains("polarid: error:"), "{err}");
    for w in words {
        assert!(err.contains(w), "message lacks {w:?}: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(c.listing(), before, "files appeared or vanished: {err}");
    assert!(o.stdout.is_empty(), "stdout not empty: {:?}", o.stdout);
    err
}

const MEAS_HEADER: &str = "target,class,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,dolp_se\n";

/// Three good measurement rows of target `A` (lines 2-4).
fn meas_rows() -> String {
    "A,al,30,60,180,45,0.2,0.01\nA,al,40,60,180,50,0.3,0.01\nA,al,50,60,180,55,0.4,0.01\n"
        .to_string()
}

/// A manifest with one region and one capture of four frames `a.png` … `d.png`.
fn manifest(region: &str, capture: &str) -> String {
    format!("theta_r_deg = 60.0\n\n[[region]]\n{region}\n\n[[capture]]\n{capture}\n")
}

const REGION: &str = "name = \"A\"\nrect = [1, 1, 4, 4]";
const FRAMES: &str = "theta_i_deg = 30.0\nframes = [\n  { angle_deg = 0.0, file = \"a.png\" },\n  { angle_deg = 45.0, file = \"b.png\" },\n  { angle_deg = 90.0, file = \"c.png\" },\n  { angle_deg = 135.0, file = \"d.png\" },\n]";

fn four_frames(c: &Case, w: usize, h: usize) {
    for n in ["a.png", "b.png", "c.png", "d.png"] {
        c.gray16(n, w, h);
    }
}

fn fits_csv(c: &Case, name: &str, body: &str) -> String {
    c.write(
        name,
        &format!("target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n{body}"),
    )
}

// ---------------------------------------------------------------------------------------
// Missing and unreadable files

#[test]
fn missing_frame_file() {
    let c = Case::new();
    let a = c.gray16("a.png", 8, 8);
    let b = c.gray16("b.png", 8, 8);
    bad(
        &c,
        &[
            "stokes",
            "--frames",
            &a,
            &b,
            "nothere.png",
            "--angles",
            "0,60,120",
            "-o",
            "out",
        ],
        &["nothere.png", "No such file"],
    );
}

#[test]
fn missing_manifest() {
    let c = Case::new();
    bad(
        &c,
        &["measure", "nothere.toml", "-o", "m.csv"],
        &["nothere.toml", "No such file"],
    );
}

#[test]
fn manifest_names_missing_frame() {
    let c = Case::new();
    for n in ["a.png", "b.png", "d.png"] {
        c.gray16(n, 8, 8);
    }
    let m = c.write("m.toml", &manifest(REGION, FRAMES));
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &[
            "m.toml",
            "line 12",
            "capture[1].frames[3].file",
            "c.png",
            "not found",
        ],
    );
}

#[test]
fn unreadable_frame_is_a_directory() {
    let c = Case::new();
    fs::create_dir(c.p("dir.png")).unwrap();
    let a = c.gray16("a.png", 8, 8);
    let b = c.gray16("b.png", 8, 8);
    bad(
        &c,
        &[
            "stokes", "--frames", &a, &b, "dir.png", "--angles", "0,60,120", "-o", "out",
        ],
        &["dir.png", "directory"],
    );
}

#[test]
fn missing_measurements_file() {
    let c = Case::new();
    bad(
        &c,
        &["fit", "nothere.csv"],
        &["nothere.csv", "No such file"],
    );
}

#[test]
fn missing_model_file() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,,1.5,0.1,,,,,3,ok\n");
    bad(
        &c,
        &["classify", &f, "--model", "nomodel.json"],
        &["nomodel.json", "No such file"],
    );
}

// ---------------------------------------------------------------------------------------
// Frames of one capture

#[test]
fn frames_of_different_sizes() {
    let c = Case::new();
    let a = c.gray16("a.png", 8, 8);
    let b = c.gray16("b.png", 8, 8);
    let d = c.gray16("d.png", 10, 8);
    bad(
        &c,
        &[
            "stokes", "--frames", &a, &b, &d, "--angles", "0,60,120", "-o", "out",
        ],
        &["d.png", "10x8", "8x8", "same size"],
    );
}

#[test]
fn frames_of_different_types() {
    let c = Case::new();
    let a = c.gray16("a.png", 8, 8);
    let b = c.gray16("b.png", 8, 8);
    let d = c.gray8("d.png", 8, 8);
    bad(
        &c,
        &[
            "stokes", "--frames", &a, &b, &d, "--angles", "0,60,120", "-o", "out",
        ],
        &["d.png", "8-bit", "16-bit", "same type"],
    );
}

#[test]
fn manifest_frames_of_different_types() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    fs::remove_file(c.p("c.png")).unwrap();
    c.gray8("c.png", 8, 8);
    let m = c.write("m.toml", &manifest(REGION, FRAMES));
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["c.png", "8-bit", "a.png", "16-bit"],
    );
}

#[test]
fn integer_stokes_images() {
    let c = Case::new();
    c.gray16("s0.tif", 8, 8);
    c.f32("s1.tif", 8, 8, 0.0);
    c.f32("s2.tif", 8, 8, 0.0);
    let m = c.write(
        "m.toml",
        &manifest(
            REGION,
            "theta_i_deg = 30.0\nstokes = { s0 = \"s0.tif\", s1 = \"s1.tif\", s2 = \"s2.tif\" }",
        ),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["s0.tif", "16-bit integer", "float"],
    );
}

// ---------------------------------------------------------------------------------------
// Image files: colour, pages, corruption

#[test]
fn colour_png() {
    let c = Case::new();
    image::write_rgb8_png(&c.p("rgb.png"), false, 8, 8, &[100u8; 8 * 8 * 3]).unwrap();
    bad(
        &c,
        &["stokes", "--dofp", &c.s("rgb.png"), "-o", "out"],
        &["rgb.png", "colour image", "grayscale"],
    );
}

#[test]
fn grayscale_alpha_png() {
    let c = Case::new();
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, 4, 4);
        enc.set_color(png::ColorType::GrayscaleAlpha);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[7u8; 32]).unwrap();
    }
    let f = c.bytes("ga.png", &bytes);
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["ga.png", "alpha channel"],
    );
}

#[test]
fn colour_tiff() {
    let c = Case::new();
    let mut f = fs::File::create(c.p("rgb.tif")).unwrap();
    tiff::encoder::TiffEncoder::new(&mut f)
        .unwrap()
        .write_image::<tiff::encoder::colortype::RGB8>(4, 4, &[9u8; 48])
        .unwrap();
    drop(f);
    bad(
        &c,
        &["stokes", "--dofp", &c.s("rgb.tif"), "-o", "out"],
        &["rgb.tif", "colour image"],
    );
}

#[test]
fn multi_page_tiff() {
    let c = Case::new();
    let mut f = fs::File::create(c.p("pages.tif")).unwrap();
    let mut enc = tiff::encoder::TiffEncoder::new(&mut f).unwrap();
    for _ in 0..3 {
        enc.write_image::<tiff::encoder::colortype::Gray16>(4, 4, &[100u16; 16])
            .unwrap();
    }
    drop(f);
    bad(
        &c,
        &["stokes", "--dofp", &c.s("pages.tif"), "-o", "out"],
        &["pages.tif", "multi-page TIFF", "3 pages"],
    );
}

#[test]
fn truncated_png() {
    let c = Case::new();
    c.gray16("full.png", 16, 16);
    let b = fs::read(c.p("full.png")).unwrap();
    let f = c.bytes("cut.png", &b[..b.len() / 2]);
    fs::remove_file(c.p("full.png")).unwrap();
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["cut.png", "truncated or corrupt PNG"],
    );
}

#[test]
fn corrupt_png_checksum() {
    let c = Case::new();
    c.gray8("full.png", 16, 16);
    let mut b = fs::read(c.p("full.png")).unwrap();
    // Flip a byte inside the IHDR chunk: its CRC no longer matches.
    b[20] ^= 0x55;
    let f = c.bytes("crc.png", &b);
    fs::remove_file(c.p("full.png")).unwrap();
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["crc.png", "corrupt PNG"],
    );
}

#[test]
fn truncated_tiff() {
    let c = Case::new();
    c.gray16("full.tif", 16, 16);
    let b = fs::read(c.p("full.tif")).unwrap();
    let f = c.bytes("cut.tif", &b[..b.len() / 3]);
    fs::remove_file(c.p("full.tif")).unwrap();
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["cut.tif", "corrupt TIFF"],
    );
}

#[test]
fn tiff_header_only() {
    let c = Case::new();
    // A TIFF signature whose first directory offset points past the end.
    let f = c.bytes("hdr.tif", b"II*\0\xff\x00\x00\x00");
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["hdr.tif", "TIFF"],
    );
}

#[test]
fn not_an_image() {
    let c = Case::new();
    let f = c.write("notes.png", "this is text, not a PNG\n");
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["notes.png", "not a PNG or TIFF"],
    );
}

#[test]
fn empty_image_file() {
    let c = Case::new();
    let f = c.write("empty.tif", "");
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["empty.tif", "is empty"],
    );
}

#[test]
fn absurd_image_dimensions() {
    let c = Case::new();
    // A PNG header announcing 100000 x 100000 pixels, with valid CRCs, and an empty
    // IDAT chunk.
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(100_000u32.to_be_bytes());
    ihdr.extend(100_000u32.to_be_bytes());
    ihdr.extend([16, 0, 0, 0, 0]);
    let crc = crc32(&ihdr);
    let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
    b.extend(13u32.to_be_bytes());
    b.extend(&ihdr);
    b.extend(crc.to_be_bytes());
    b.extend(0u32.to_be_bytes());
    b.extend(b"IDAT");
    b.extend(crc32(b"IDAT").to_be_bytes());
    let f = c.bytes("huge.png", &b);
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["huge.png", "100000x100000"],
    );
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

// ---------------------------------------------------------------------------------------
// Polarizer angle sets and DoFP

#[test]
fn duplicate_polarizer_angles() {
    let c = Case::new();
    let a = c.gray16("a.png", 8, 8);
    let b = c.gray16("b.png", 8, 8);
    let d = c.gray16("d.png", 8, 8);
    bad(
        &c,
        &[
            "stokes", "--frames", &a, &b, &d, "--angles", "0,45,45", "-o", "out",
        ],
        &["45"],
    );
}

#[test]
fn singular_angle_set_in_manifest() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    // 0 and 180 degrees are the same polarizer orientation: only two distinct angles.
    let cap = "theta_i_deg = 30.0\nframes = [\n  { angle_deg = 0.0, file = \"a.png\" },\n  { angle_deg = 180.0, file = \"b.png\" },\n  { angle_deg = 90.0, file = \"c.png\" },\n]";
    let m = c.write("m.toml", &manifest(REGION, cap));
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["m.toml", "line 9", "capture[1].frames", "180", "singular"],
    );
}

#[test]
fn too_few_polarizer_angles() {
    let c = Case::new();
    let a = c.gray16("a.png", 8, 8);
    let b = c.gray16("b.png", 8, 8);
    bad(
        &c,
        &[
            "stokes", "--frames", &a, &b, "--angles", "0,90", "-o", "out",
        ],
        &["at least 3"],
    );
}

#[test]
fn angle_count_differs_from_frame_count() {
    let c = Case::new();
    let a = c.gray16("a.png", 8, 8);
    let b = c.gray16("b.png", 8, 8);
    let d = c.gray16("d.png", 8, 8);
    bad(
        &c,
        &[
            "stokes",
            "--frames",
            &a,
            &b,
            &d,
            "--angles",
            "0,45,90,135",
            "-o",
            "out",
        ],
        &["4 angle(s)", "3 frame(s)"],
    );
}

#[test]
fn dofp_odd_width() {
    let c = Case::new();
    let f = c.gray16("raw.png", 9, 8);
    bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["raw.png", "9x8", "even width and height"],
    );
}

#[test]
fn dofp_odd_height_in_manifest() {
    let c = Case::new();
    c.gray16("raw.tif", 8, 7);
    let m = c.write(
        "m.toml",
        &manifest(REGION, "theta_i_deg = 30.0\ndofp = { file = \"raw.tif\" }"),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["raw.tif", "8x7", "even width and height"],
    );
}

#[test]
fn dofp_pattern_with_repeated_angle() {
    let c = Case::new();
    let f = c.gray16("raw.png", 8, 8);
    bad(
        &c,
        &[
            "stokes",
            "--dofp",
            &f,
            "--pattern",
            "0,0,90,135",
            "-o",
            "out",
        ],
        &["[0.0, 0.0, 90.0, 135.0]", "distinct"],
    );
}

#[test]
fn dofp_pattern_not_multiples_of_45_in_manifest() {
    let c = Case::new();
    c.gray16("raw.tif", 8, 8);
    let m = c.write(
        "m.toml",
        &manifest(
            REGION,
            "theta_i_deg = 30.0\ndofp = { file = \"raw.tif\", pattern = [0, 30, 90, 135] }",
        ),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &[
            "m.toml",
            "line 9",
            "capture[1].dofp.pattern",
            "[0, 30, 90, 135]",
        ],
    );
}

#[test]
fn dofp_pattern_of_three_angles() {
    let c = Case::new();
    let f = c.gray16("raw.png", 8, 8);
    bad(
        &c,
        &["stokes", "--dofp", &f, "--pattern", "0,45,90", "-o", "out"],
        &["exactly four angles"],
    );
}

// ---------------------------------------------------------------------------------------
// Regions

#[test]
fn region_outside_the_frame() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest("name = \"A\"\nrect = [6, 1, 4, 4]", FRAMES),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["m.toml", "line 5", "region[1].rect", "[6, 1, 4, 4]", "8x8"],
    );
}

#[test]
fn empty_region() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest("name = \"A\"\nrect = [1, 1, 0, 4]", FRAMES),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["m.toml", "line 5", "region[1].rect", "[1, 1, 0, 4]"],
    );
}

#[test]
fn duplicate_region_names() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest(
            "name = \"A\"\nrect = [1, 1, 2, 2]\n\n[[region]]\nname = \"A\"\nrect = [3, 3, 2, 2]",
            FRAMES,
        ),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["line 8", "region[2].name", "\"A\"", "duplicate"],
    );
}

#[test]
fn region_name_with_a_newline() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest("name = \"A\\nB\"\nrect = [1, 1, 2, 2]", FRAMES),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["line 4", "region[1].name", "control character"],
    );
}

// ---------------------------------------------------------------------------------------
// Angles: NaN, Inf, negative, >= 90

#[test]
fn nan_angle_in_manifest() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest(
            REGION,
            &FRAMES.replace("theta_i_deg = 30.0", "theta_i_deg = nan"),
        ),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &[
            "m.toml",
            "line 8",
            "capture[1].theta_i_deg",
            "nan",
            "finite",
        ],
    );
}

#[test]
fn infinite_angle_in_measurements() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        &format!("{MEAS_HEADER}{}A,al,inf,60,180,,0.5,0.01\n", meas_rows()),
    );
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "line 5", "`theta_i_deg`", "\"inf\"", "finite"],
    );
}

#[test]
fn negative_angle_in_manifest() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest(
            REGION,
            &FRAMES.replace("theta_i_deg = 30.0", "theta_i_deg = -5.0"),
        ),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["line 8", "capture[1].theta_i_deg", "-5.0", "[0, 90)"],
    );
}

#[test]
fn camera_angle_of_90_in_manifest() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest(REGION, FRAMES).replace("theta_r_deg = 60.0", "theta_r_deg = 90.0"),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["line 1", "theta_r_deg", "90.0", "[0, 90)"],
    );
}

#[test]
fn beta_of_95_in_measurements() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        &format!("{MEAS_HEADER}{}A,al,,,,95,0.5,0.01\n", meas_rows()),
    );
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "line 5", "`beta_deg`", "\"95\"", "[0, 90)"],
    );
}

#[test]
fn negative_angle_in_model_rows() {
    let c = Case::new();
    let f = c.write(
        "rows.csv",
        "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1.5,0,0.1,30,60,180\n1.5,0,0.1,-1,60,180\n",
    );
    bad(
        &c,
        &["model", "--input", &f, "-o", "out.csv"],
        &["rows.csv", "line 3", "`theta_i_deg`", "\"-1\""],
    );
}

// ---------------------------------------------------------------------------------------
// DoLP values and measurement counts

#[test]
fn dolp_above_one() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        &format!("{MEAS_HEADER}{}A,al,60,60,180,,1.2,0.01\n", meas_rows()),
    );
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "line 5", "`dolp`", "\"1.2\"", "[0, 1]"],
    );
}

#[test]
fn negative_dolp() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        &format!("{MEAS_HEADER}A,al,30,60,180,45,-0.1,0.01\n{}", meas_rows()),
    );
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "line 2", "`dolp`", "\"-0.1\"", "[0, 1]"],
    );
}

#[test]
fn nan_dolp() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        &format!("{MEAS_HEADER}{}A,al,60,60,180,,NaN,0.01\n", meas_rows()),
    );
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "line 5", "`dolp`", "\"NaN\"", "finite"],
    );
}

#[test]
fn fewer_than_three_measurements() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        &format!(
            "{MEAS_HEADER}{}B,,30,60,180,45,0.2,0.01\nB,,40,60,180,50,0.3,0.01\n",
            meas_rows()
        ),
    );
    // Without --strict the target becomes an invalid_input row (tests/it/partial_failure.rs).
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv", "--strict"],
        &[
            "m.csv",
            "\"B\"",
            "2 measurement(s)",
            "lines 5, 6",
            "at least 3",
        ],
    );
}

#[test]
fn no_measurements_at_all() {
    let c = Case::new();
    let f = c.write("m.csv", MEAS_HEADER);
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "no measurements"],
    );
}

#[test]
fn empty_csv_file() {
    let c = Case::new();
    let f = c.write("m.csv", "");
    bad(&c, &["fit", &f, "-o", "fits.csv"], &["m.csv", "no header"]);
}

#[test]
fn ragged_csv_row() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        &format!("{MEAS_HEADER}{}A,al,60,60\n", meas_rows()),
    );
    bad(&c, &["fit", &f, "-o", "fits.csv"], &["m.csv", "line 5"]);
}

// ---------------------------------------------------------------------------------------
// Required columns

#[test]
fn measurements_without_dolp_column() {
    let c = Case::new();
    let f = c.write("m.csv", "target,beta_deg\nA,45\nA,50\nA,55\n");
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "missing required column `dolp`", "target,beta_deg"],
    );
}

#[test]
fn measurements_without_any_angle_column() {
    let c = Case::new();
    let f = c.write(
        "m.csv",
        "target,dolp,theta_i_deg\nA,0.1,30\nA,0.2,40\nA,0.3,50\n",
    );
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["m.csv", "beta_deg", "theta_r_deg"],
    );
}

#[test]
fn fits_without_k_column() {
    let c = Case::new();
    let f = c.write("fits.csv", "target,class,n\nA,al,1.2\n");
    bad(
        &c,
        &["classify", &f, "--library", "builtin", "-o", "out.csv"],
        &["fits.csv", "missing required column `k`"],
    );
}

#[test]
fn model_rows_without_beta_column() {
    let c = Case::new();
    let f = c.write("rows.csv", "n,k\n1.5,0\n");
    bad(
        &c,
        &["model", "--input", &f, "-o", "out.csv"],
        &["rows.csv", "beta_deg"],
    );
}

#[test]
fn library_without_name_column() {
    let c = Case::new();
    let fits = fits_csv(&c, "fits.csv", "A,,1.5,0.1,,,,,3,ok\n");
    let lib = c.write("lib.csv", "material,n,k\nglass,1.5,0\n");
    bad(
        &c,
        &["classify", &fits, "--library", &lib, "-o", "out.csv"],
        &["lib.csv", "name"],
    );
}

#[test]
fn negative_k_in_fits() {
    let c = Case::new();
    let f = fits_csv(
        &c,
        "fits.csv",
        "A,al,1.5,0.1,,,,,3,ok\nB,al,1.5,-0.2,,,,,3,ok\n",
    );
    bad(
        &c,
        &["train", &f, "-o", "model.json"],
        &["fits.csv", "line 3", "`k`", "\"-0.2\"", ">= 0"],
    );
}

#[test]
fn non_positive_n_in_fits() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,al,0,0.1,,,,,3,ok\n");
    bad(
        &c,
        &["train", &f, "-o", "model.json"],
        &["fits.csv", "line 2", "`n`", "\"0\"", "> 0"],
    );
}

// ---------------------------------------------------------------------------------------
// Training sets, class names, models

#[test]
fn empty_training_set() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,,1.5,0.1,,,,,3,ok\nB,,1.2,6.6,,,,,3,ok\n");
    bad(
        &c,
        &["train", &f, "-o", "model.json"],
        &["fits.csv", "nothing to train on", "2 without a class"],
    );
}

#[test]
fn training_set_of_failed_fits() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,al,nan,nan,,,,,3,not_converged\n");
    // (Without --allow-not-ok, train refuses the failed fit itself: newcomer_traps.rs.)
    bad(
        &c,
        &["train", &f, "-o", "model.json", "--allow-not-ok"],
        &[
            "fits.csv",
            "nothing to train on",
            "A (not_converged, line 2)",
        ],
    );
}

#[test]
fn reserved_class_name_in_training_set() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,unknown,1.5,0.1,,,,,3,ok\n");
    bad(
        &c,
        &["train", &f, "-o", "model.json"],
        &["fits.csv", "line 2", "`class`", "\"unknown\"", "reserved"],
    );
}

#[test]
fn unknown_library_name() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,,1.5,0.1,,,,,3,ok\n");
    bad(
        &c,
        &["classify", &f, "--library", "paper2077", "-o", "out.csv"],
        &["paper2077", "No such file"],
    );
}

#[test]
fn model_class_name_reserved() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,,1.5,0.1,,,,,3,ok\n");
    let m = c.write(
        "model.json",
        r#"{"format":"polarid-model","format_version":1,"created_by":"x","prototypes":[
            {"class":"unknown","n":1.5,"k":0.0,"covariance":null,
             "source":{"file":"f.csv","line":2,"target":"A"}}]}"#,
    );
    bad(
        &c,
        &["classify", &f, "--model", &m, "-o", "out.csv"],
        &["model.json", "prototypes[0]", "\"unknown\""],
    );
}

#[test]
fn model_of_another_version() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,,1.5,0.1,,,,,3,ok\n");
    let m = c.write(
        "model.json",
        r#"{"format":"polarid-model","format_version":2,"created_by":"polarid 9","prototypes":[]}"#,
    );
    bad(
        &c,
        &["classify", &f, "--model", &m, "-o", "out.csv"],
        &["model.json", "version 2", "version 1"],
    );
}

#[test]
fn model_that_is_not_json() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,al,1.5,0.1,,,,,3,ok\n");
    let m = c.write("model.json", "{\"format\": \"polarid-model\",");
    bad(
        &c,
        &["evaluate", &f, "--model", &m, "-o", "conf.csv"],
        &["model.json", "not valid JSON"],
    );
}

#[test]
fn evaluate_without_labels() {
    let c = Case::new();
    let f = fits_csv(&c, "fits.csv", "A,,1.5,0.1,,,,,3,ok\n");
    bad(
        &c,
        &["evaluate", &f, "-o", "conf.csv"],
        &["fits.csv", "no labelled fits"],
    );
}

// ---------------------------------------------------------------------------------------
// Manifest syntax

#[test]
fn invalid_toml() {
    let c = Case::new();
    let m = c.write("m.toml", "theta_r_deg = 60.0\n[[region]\nname = \"A\"\n");
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["m.toml", "line 2", "invalid TOML"],
    );
}

#[test]
fn manifest_value_of_wrong_type() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let m = c.write(
        "m.toml",
        &manifest(
            REGION,
            &FRAMES.replace("theta_i_deg = 30.0", "theta_i_deg = \"30\""),
        ),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &[
            "line 8",
            "capture[1].theta_i_deg",
            "\"30\"",
            "expected a number",
        ],
    );
}

// ---------------------------------------------------------------------------------------
// Outputs: existing, inputs, directories, failures half-way

#[test]
fn existing_output_kept_without_force() {
    let c = Case::new();
    let f = c.write("m.csv", &format!("{MEAS_HEADER}{}", meas_rows()));
    c.write("fits.csv", "old\n");
    bad(
        &c,
        &["fit", &f, "-o", "fits.csv"],
        &["fits.csv", "output exists", "--force"],
    );
    assert_eq!(fs::read_to_string(c.p("fits.csv")).unwrap(), "old\n");
    // With --force it is replaced.
    let o = c.run(&["--force", "fit", &f, "-o", "fits.csv"]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        fs::read_to_string(c.p("fits.csv"))
            .unwrap()
            .starts_with("target,")
    );
}

#[test]
fn output_is_the_input_even_with_force() {
    let c = Case::new();
    let text = format!("{MEAS_HEADER}{}", meas_rows());
    let f = c.write("m.csv", &text);
    bad(
        &c,
        &["--force", "fit", &f, "-o", "./m.csv"],
        &["m.csv", "refusing to overwrite an input"],
    );
    assert_eq!(fs::read_to_string(c.p("m.csv")).unwrap(), text);
}

#[test]
fn measure_output_is_a_frame() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    let before = fs::read(c.p("b.png")).unwrap();
    let m = c.write("m.toml", &manifest(REGION, FRAMES));
    bad(
        &c,
        &["--force", "measure", &m, "-o", "b.png"],
        &["b.png", "refusing to overwrite an input"],
    );
    assert_eq!(fs::read(c.p("b.png")).unwrap(), before);
}

#[test]
fn stokes_into_directory_holding_an_output() {
    let c = Case::new();
    let f = c.gray16("raw.png", 8, 8);
    c.write("out/dolp.tif", "old");
    let err = bad(
        &c,
        &["stokes", "--dofp", &f, "-o", "out"],
        &["dolp.tif", "output exists"],
    );
    assert!(!err.contains("s0.tif"), "{err}");
    assert_eq!(fs::read_to_string(c.p("out/dolp.tif")).unwrap(), "old");
}

#[test]
fn stokes_output_directory_is_an_input() {
    let c = Case::new();
    let f = c.gray16("raw.png", 8, 8);
    let before = fs::read(c.p("raw.png")).unwrap();
    bad(
        &c,
        &["--force", "stokes", "--dofp", &f, "-o", &f],
        &["raw.png", "not a directory"],
    );
    assert_eq!(fs::read(c.p("raw.png")).unwrap(), before);
}

#[test]
fn stokes_writing_over_its_input_in_the_output_directory() {
    let c = Case::new();
    fs::create_dir(c.p("out")).unwrap();
    let f = c.f32("out/s0.tif", 8, 8, 1000.0);
    let a = c.f32("a.tif", 8, 8, 500.0);
    let b = c.f32("b.tif", 8, 8, 400.0);
    let before = fs::read(c.p("out/s0.tif")).unwrap();
    bad(
        &c,
        &[
            "--force", "stokes", "--frames", &f, &a, &b, "--angles", "0,60,120", "-o", "out",
        ],
        &["s0.tif", "refusing to overwrite an input"],
    );
    assert_eq!(fs::read(c.p("out/s0.tif")).unwrap(), before);
}

#[test]
fn failure_in_a_later_capture_leaves_no_output() {
    let c = Case::new();
    four_frames(&c, 8, 8);
    c.gray16("raw.tif", 9, 8);
    let m = c.write(
        "m.toml",
        &format!(
            "{}\n[[capture]]\ntheta_i_deg = 40.0\ndofp = {{ file = \"raw.tif\" }}\n",
            manifest(REGION, FRAMES)
        ),
    );
    bad(
        &c,
        &["measure", &m, "-o", "m.csv"],
        &["raw.tif", "9x8", "even width"],
    );
}

#[test]
fn usage_error_is_status_2() {
    let c = Case::new();
    let o = c.run(&["fit"]);
    assert_eq!(o.status.code(), Some(2));
    let o = c.run(&["stokes", "-o", "out"]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!c.p("out").exists());
}

// ---------------------------------------------------------------------------------------
// Valid but doubtful: saturation is reported

#[test]
fn saturated_pixels_are_counted_and_warned_about() {
    let c = Case::new();
    let (w, h) = (8, 8);
    for (k, n) in ["a.png", "b.png", "c.png", "d.png"].into_iter().enumerate() {
        let mut v: Vec<u16> = (0..w * h).map(|_| 1000 + 100 * k as u16).collect();
        if k == 0 {
            // Two saturated pixels inside the region, one outside.
            v[2 * w + 2] = 65535;
            v[3 * w + 3] = 65535;
            v[7 * w + 7] = 65535;
        }
        image::write_gray16(&c.p(n), false, w, h, &v).unwrap();
    }
    let m = c.write("m.toml", &manifest(REGION, FRAMES));
    let o = c.run(&["measure", &m, "-o", "m.csv"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("target \"A\"") && err.contains("2 of 16 pixels") && err.contains("12.5%"),
        "{err}"
    );
    let rows = polarid_io::table::measurements::read(&c.p("m.csv")).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].saturated, Some(2));
    assert_eq!(rows[0].rejected, Some(2));
    assert_eq!(rows[0].pixels, Some(14));
}
