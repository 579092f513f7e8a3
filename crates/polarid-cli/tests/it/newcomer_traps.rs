//! What a newcomer runs into on their own bench, end to end through the `polarid`
//! binary: frames of another size in one capture set, the saturation level of 12-bit
//! data, `-` and pipes for tables, a manifest given to `fit`, scenes `simulate` must not
//! write, wavelengths reaching the fits, `train` refusing fits that are not `ok`, and a
//! colour mosaic with a partial period.

use crate::common;

use std::fs;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use common::{csv_rows, polarid_cmd, polarid_in, text};
use polarid_io::image;

fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "status {:?}: {}",
        o.status.code(),
        text(&o.stderr)
    );
    text(&o.stderr)
}

/// The error message of a run that must end with exit status 2.
fn bad(o: &Output) -> String {
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    text(&o.stderr)
}

/// A small monochrome DoFP scene (two plates, six captures) with a wavelength.
fn dofp_scene(width: usize, height: usize) -> String {
    format!(
        r#"name = "small"
width = {width}
height = {height}
theta_r_deg = 60.0
theta_i_deg = [35, 45, 55, 65, 75, 80]
wavelength_nm = 650.0
seed = 3
format = "png"
[sensor]
bit_depth = 12
[capture]
kind = "dofp"
[[plate]]
name = "al"
class = "aluminum"
n = 1.24
k = 6.6
sigma = 0.2
rect = [0, 0, 24, 24]
[[plate]]
name = "cu"
class = "copper"
n = 0.4
k = 2.95
sigma = 0.2
rect = [24, 0, 24, 24]
"#
    )
}

/// Simulate the 48x24 scene into `dir/sim`.
fn simulate(dir: &Path) {
    fs::write(dir.join("scene.toml"), dofp_scene(48, 24)).unwrap();
    ok(&polarid_in(
        dir,
        &["--quiet", "simulate", "scene.toml", "-o", "sim"],
    ));
}

#[test]
fn tables_flow_through_pipes_and_carry_the_wavelength() {
    let d = tempfile::tempdir().unwrap();
    simulate(d.path());
    // measure -o - | fit - -o fits.csv
    let bin = env!("CARGO_BIN_EXE_polarid");
    let o = Command::new("sh")
        .current_dir(d.path())
        .arg("-c")
        .arg(format!(
            "'{bin}' --quiet measure sim/manifest.toml -o - | '{bin}' fit - -o fits.csv"
        ))
        .output()
        .unwrap();
    ok(&o);
    let fits = csv_rows(&d.path().join("fits.csv"));
    assert_eq!(fits.len(), 2);
    // The manifest's wavelength reached the measurements and the fits.
    assert!(fits.iter().all(|r| r["wavelength_nm"] == "650"), "{fits:?}");
    // ... so classify compares at that wavelength without a warning about it.
    let o = polarid_in(
        d.path(),
        &["classify", "fits.csv", "--library", "builtin", "-o", "-"],
    );
    let err = ok(&o);
    assert!(!err.contains("no wavelength"), "{err}");
    assert!(
        text(&o.stdout).starts_with("target,"),
        "{}",
        text(&o.stdout)
    );
    // /dev/stdin, fed by a pipe.
    let meas = polarid_in(d.path(), &["--quiet", "measure", "sim/manifest.toml"]);
    ok(&meas);
    let mut child = polarid_cmd()
        .current_dir(d.path())
        .args(["fit", "/dev/stdin", "-o", "fits2.csv"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().unwrap();
        stdin.write_all(&meas.stdout).unwrap();
    }
    ok(&child.wait_with_output().unwrap());
    assert_eq!(
        fs::read(d.path().join("fits.csv")).unwrap(),
        fs::read(d.path().join("fits2.csv")).unwrap()
    );
    // A named pipe.
    let fifo = d.path().join("pipe");
    if Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        let bytes = meas.stdout.clone();
        let writer = {
            let fifo = fifo.clone();
            std::thread::spawn(move || fs::write(&fifo, bytes).unwrap())
        };
        ok(&polarid_in(d.path(), &["fit", "pipe", "-o", "fits3.csv"]));
        writer.join().unwrap();
        assert_eq!(
            fs::read(d.path().join("fits.csv")).unwrap(),
            fs::read(d.path().join("fits3.csv")).unwrap()
        );
    }
}

#[test]
fn fit_says_what_a_manifest_is() {
    let d = tempfile::tempdir().unwrap();
    simulate(d.path());
    let e = bad(&polarid_in(d.path(), &["fit", "sim/manifest.toml"]));
    assert!(
        e.contains("sim/manifest.toml")
            && e.contains("capture-set manifest")
            && e.contains("run `polarid measure sim/manifest.toml"),
        "{e}"
    );
    assert!(!e.contains("column"), "{e}");
}

#[test]
fn measure_refuses_captures_of_another_size() {
    let d = tempfile::tempdir().unwrap();
    simulate(d.path());
    // Capture 3's raw frame replaced by a narrower one (40 of its 48 columns).
    let m = fs::read_to_string(d.path().join("sim/manifest.toml")).unwrap();
    let files: Vec<&str> = m
        .lines()
        .filter_map(|l| l.split("file = \"").nth(1))
        .map(|r| r.split('"').next().unwrap())
        .collect();
    let third = d.path().join("sim").join(files[2]);
    let raw = image::read_frame(&third).unwrap();
    let narrow: Vec<u16> = raw
        .data
        .chunks(48)
        .flat_map(|row| row[..40].iter().map(|&v| v as u16))
        .collect();
    image::write_gray16(&third, true, 40, 24, &narrow).unwrap();
    // Regions inside both sizes, so that only the size tells.
    let m = m.replace("rect = [24, 0, 24, 24]", "rect = [24, 0, 16, 24]");
    fs::write(d.path().join("sim/manifest.toml"), m).unwrap();
    let o = polarid_in(
        d.path(),
        &["measure", "sim/manifest.toml", "-o", "meas.csv"],
    );
    let e = bad(&o);
    assert!(
        e.contains(files[2])
            && e.contains(files[0])
            && e.contains("40x24")
            && e.contains("48x24")
            && e.contains("same size"),
        "{e}"
    );
    assert!(!d.path().join("meas.csv").exists());
}

#[test]
fn simulate_refuses_dofp_scenes_measure_cannot_demosaic() {
    let d = tempfile::tempdir().unwrap();
    for (w, h, field) in [(49, 24, "width"), (48, 25, "height"), (2, 24, "width")] {
        fs::write(d.path().join("odd.toml"), dofp_scene(w, h)).unwrap();
        let o = polarid_in(d.path(), &["simulate", "odd.toml", "-o", "odd"]);
        let e = bad(&o);
        assert!(
            e.contains(&format!("field `{field}`")) && e.contains("even"),
            "{e}"
        );
        assert!(!d.path().join("odd").exists());
    }
}

/// A rotating-polarizer capture set of 12-bit data in 16-bit PNGs (`bits`: recorded in
/// the files' sBIT chunk, or not), plate A's left half clipped at 4095.
fn twelve_bit_set(dir: &Path, bits: Option<u8>) {
    let (w, h) = (32, 16);
    let mut manifest = String::from(
        "theta_r_deg = 60.0\n[[region]]\nname = \"A\"\nrect = [0, 0, 16, 16]\n\
         [[region]]\nname = \"B\"\nrect = [16, 0, 16, 16]\n",
    );
    for (c, ti) in [40.0, 50.0, 60.0].iter().enumerate() {
        manifest += &format!("[[capture]]\ntheta_i_deg = {ti}\nframes = [\n");
        for a in [0u32, 45, 90, 135] {
            let v: Vec<u16> = (0..w * h)
                .map(|i| {
                    let x = i % w;
                    if x < 8 {
                        4095
                    } else {
                        1000 + 10 * a as u16 + 100 * c as u16
                    }
                })
                .collect();
            let name = format!("c{c}_{a}.png");
            let p = dir.join(&name);
            match bits {
                Some(b) => image::write_gray16_bits(&p, false, w, h, &v, b).unwrap(),
                None => image::write_gray16(&p, false, w, h, &v).unwrap(),
            }
            manifest += &format!("  {{ angle_deg = {a}, file = \"{name}\" }},\n");
        }
        manifest += "]\n";
    }
    fs::write(dir.join("m.toml"), manifest).unwrap();
}

#[test]
fn twelve_bit_data_saturate_at_4095() {
    // The bit depth recorded in the files: saturation defaults to 4095.
    let d = tempfile::tempdir().unwrap();
    twelve_bit_set(d.path(), Some(12));
    let err = ok(&polarid_in(
        d.path(),
        &["measure", "m.toml", "-o", "meas.csv"],
    ));
    let rows = csv_rows(&d.path().join("meas.csv"));
    let a: Vec<_> = rows.iter().filter(|r| r["target"] == "A").collect();
    assert!(a.iter().all(|r| r["saturated"] == "128"), "{rows:?}");
    assert!(!err.contains("records no bit depth"), "{err}");
    // Not recorded: 65535 as the file says, but a warning naming the 12-bit ceiling.
    let d = tempfile::tempdir().unwrap();
    twelve_bit_set(d.path(), None);
    let err = ok(&polarid_in(
        d.path(),
        &["measure", "m.toml", "-o", "meas.csv"],
    ));
    assert!(
        err.contains("warning: capture 1")
            && err.contains("2^12 - 1")
            && err.contains("saturation = 4095"),
        "{err}"
    );
    let rows = csv_rows(&d.path().join("meas.csv"));
    assert!(rows.iter().all(|r| r["saturated"] == "0"), "{rows:?}");
}

#[test]
fn train_refuses_labelled_fits_that_are_not_ok() {
    let d = tempfile::tempdir().unwrap();
    fs::write(
        d.path().join("fits.csv"),
        "target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n\
         al1,aluminum,1.24,6.6,0.8,2.6,0.9,0.001,10,ok\n\
         al2,aluminum,5.56,13.9,44,25,0.9,0.001,10,ill_conditioned\n\
         cu1,copper,0.4,2.95,0.1,0.7,0.9,0.001,8,ok\n",
    )
    .unwrap();
    let e = bad(&polarid_in(
        d.path(),
        &["train", "fits.csv", "-o", "model.json"],
    ));
    assert!(e.contains("al2 (ill_conditioned, line 3)"), "{e}");
    assert!(!d.path().join("model.json").exists());
    let err = ok(&polarid_in(
        d.path(),
        &["train", "fits.csv", "-o", "model.json", "--allow-not-ok"],
    ));
    assert!(err.contains("skipped labelled fit al2"), "{err}");
}

#[test]
fn a_colour_mosaic_with_a_partial_period_is_measured_on_its_whole_periods() {
    let d = tempfile::tempdir().unwrap();
    let scene = r#"name = "rgb"
width = 32
height = 16
theta_r_deg = 60.0
theta_i_deg = [40, 55, 70]
seed = 5
format = "png"
[capture]
kind = "dofp"
color = "RGGB"
[[plate]]
name = "cu"
n = 0.4
k = 2.95
sigma = 0.2
rect = [0, 0, 16, 16]
[[plate]]
name = "al"
n = 1.24
k = 6.6
sigma = 0.2
rect = [16, 0, 16, 16]
"#;
    fs::write(d.path().join("rgb.toml"), scene).unwrap();
    ok(&polarid_in(
        d.path(),
        &["--quiet", "simulate", "rgb.toml", "-o", "sim"],
    ));
    let whole = polarid_in(d.path(), &["--quiet", "measure", "sim/manifest.toml"]);
    ok(&whole);
    // Every raw frame grown by 2 columns and 3 rows (a partial period at the right and
    // bottom edges).
    for entry in fs::read_dir(d.path().join("sim")).unwrap() {
        let p = entry.unwrap().path().join("raw.png");
        if !p.exists() {
            continue;
        }
        let raw = image::read_frame(&p).unwrap();
        let (w, h) = (raw.width + 2, raw.height + 3);
        let grown: Vec<u16> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w).min(raw.width - 1), (i / w).min(raw.height - 1));
                raw.data[y * raw.width + x] as u16
            })
            .collect();
        image::write_gray16(&p, true, w, h, &grown).unwrap();
    }
    let o = polarid_in(d.path(), &["measure", "sim/manifest.toml"]);
    let err = ok(&o);
    assert!(
        err.contains("34x19 pixels, not a whole number of 4x4 colour periods")
            && err.contains("32x16 whole periods"),
        "{err}"
    );
    // The same rows as the whole-period frames gave.
    assert_eq!(text(&o.stdout), text(&whole.stdout));
}
