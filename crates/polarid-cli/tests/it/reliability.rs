//! Issue 19, reliability round two: one test (at least) per defect found by the hostile
//! probe — decompression bombs and the memory budget, unbounded reads of special files,
//! `evaluate` in linear memory, atomic output directories (kill -9 at any moment,
//! concurrent writers), signals and stale staging, exit statuses of bad paths, CSV
//! injection, silent acceptance of out-of-range values and look-alike names, and the
//! messages (shortened echoes, byte-order marks). docs/RELIABILITY.md.
//!
//! Peak memory is bounded with `ulimit -v` on the child (a process over its limit
//! cannot allocate and aborts, which these tests would see as a failure, not exit 2).

use crate::common;

use std::fs;
use std::io::Cursor;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::text;
use polarid_io::image;

// ---------------------------------------------------------------------------------------
// Harness

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_polarid")
}

/// Run polarid in `dir` with its virtual memory limited to `kib` KiB (`ulimit -v`).
fn run_limited(dir: &Path, kib: u64, args: &[&str]) -> Output {
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(bin())
        .args(args)
        .current_dir(dir)
        .env_remove("POLARID_MEMORY_LIMIT");
    cmd.output().unwrap()
}

fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(bin())
        .args(args)
        .current_dir(dir)
        .env_remove("POLARID_MEMORY_LIMIT")
        .output()
        .unwrap()
}

/// Exit status 2, no panic, every word in the message; returns the message.
#[track_caller]
fn bad(o: &Output, words: &[&str]) -> String {
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert!(err.contains("polarid: error:"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for w in words {
        assert!(err.contains(w), "message lacks {w:?}: {err}");
    }
    err
}

#[track_caller]
fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "status {:?}\nstderr: {}",
        o.status.code(),
        text(&o.stderr)
    );
}

/// Entries of `dir` whose names start with `.polarid-`.
fn hidden(dir: &Path) -> Vec<String> {
    fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.starts_with(".polarid-"))
        .collect()
}

/// A TIFF of `w × h` grayscale samples of `bits` bits (8: unsigned, 64: float), deflate
/// compressed, whose strips all point at one compressed block of zeros: a few KB that
/// decode to `w × h × bits / 8` bytes (the bombs).
fn bomb_tiff(w: u32, h: u32, bits: u16) -> Vec<u8> {
    use tiff::encoder::compression::{CompressionAlgorithm, Deflate};
    use tiff::tags::Tag;
    let rows = 64u32;
    let strips = h.div_ceil(rows) as usize;
    let mut block = Vec::new();
    Deflate::default()
        .write_to(
            &mut block,
            &vec![0u8; (w * rows) as usize * usize::from(bits / 8)],
        )
        .unwrap();
    let mut buf = Cursor::new(Vec::new());
    let mut enc = tiff::encoder::TiffEncoder::new(&mut buf).unwrap();
    let mut dir = enc.image_directory().unwrap();
    let off = dir.write_data(&block[..]).unwrap() as u32;
    dir.write_tag(Tag::ImageWidth, w).unwrap();
    dir.write_tag(Tag::ImageLength, h).unwrap();
    dir.write_tag(Tag::BitsPerSample, bits).unwrap();
    dir.write_tag(Tag::Compression, 8u16).unwrap();
    dir.write_tag(Tag::PhotometricInterpretation, 1u16).unwrap();
    dir.write_tag(Tag::SamplesPerPixel, 1u16).unwrap();
    dir.write_tag(Tag::RowsPerStrip, rows).unwrap();
    dir.write_tag(Tag::SampleFormat, if bits == 64 { 3u16 } else { 1u16 })
        .unwrap();
    dir.write_tag(Tag::StripOffsets, &vec![off; strips][..])
        .unwrap();
    dir.write_tag(Tag::StripByteCounts, &vec![block.len() as u32; strips][..])
        .unwrap();
    dir.finish().unwrap();
    buf.into_inner()
}

fn gray16(dir: &Path, name: &str, w: usize, h: usize, seed: u16) -> String {
    let v: Vec<u16> = (0..w * h)
        .map(|i| 1000 + ((i as u16).wrapping_mul(7).wrapping_add(seed)) % 3000)
        .collect();
    image::write_gray16(&dir.join(name), false, w, h, &v).unwrap();
    name.to_string()
}

const FITS_HEADER: &str = "target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n";

// ---------------------------------------------------------------------------------------
// 1. Memory budget, decompression bombs, special files

#[test]
fn deflate_bomb_tiff_is_refused_before_decoding() {
    let d = tempfile::tempdir().unwrap();
    let bomb = bomb_tiff(16384, 16384, 8);
    assert!(bomb.len() < 16 << 10, "{} bytes", bomb.len());
    fs::write(d.path().join("bomb.tif"), &bomb).unwrap();
    // Peak memory under 1.5 GB (it used 7.0 GB and wrote 5.3 GB).
    let o = run_limited(
        d.path(),
        1_500_000,
        &["stokes", "--dofp", "bomb.tif", "-o", "out"],
    );
    bad(&o, &["bomb.tif", "decompression bomb", "16384x16384"]);
    assert!(!d.path().join("out").exists());
    assert!(hidden(d.path()).is_empty());
}

#[test]
fn float64_bomb_tiff_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let bomb = bomb_tiff(16384, 16384, 64);
    assert!(bomb.len() < 64 << 10, "{} bytes", bomb.len());
    fs::write(d.path().join("f64.tif"), &bomb).unwrap();
    let o = run_limited(
        d.path(),
        1_500_000,
        &["stokes", "--dofp", "f64.tif", "-o", "out"],
    );
    bad(&o, &["f64.tif", "decompression bomb"]);
}

#[test]
fn map_over_three_bombs_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let bomb = bomb_tiff(16384, 16384, 8);
    for i in 0..3 {
        fs::write(d.path().join(format!("b{i}.tif")), &bomb).unwrap();
    }
    fs::write(
        d.path().join("fits.csv"),
        format!("{FITS_HEADER}A,al,1.5,4,0.1,0.1,0,0,5,ok\nB,cu,0.5,3,0.1,0.1,0,0,5,ok\n"),
    )
    .unwrap();
    ok(&run(d.path(), &["train", "fits.csv", "-o", "model.json"]));
    let mut m =
        String::from("theta_r_deg = 45.0\n\n[[region]]\nname = \"A\"\nrect = [0, 0, 8, 8]\n");
    for (i, th) in [30.0, 45.0, 60.0].iter().enumerate() {
        m += &format!("\n[[capture]]\ntheta_i_deg = {th}\ndofp = {{ file = \"b{i}.tif\" }}\n");
    }
    fs::write(d.path().join("m.toml"), m).unwrap();
    let o = run_limited(
        d.path(),
        1_500_000,
        &["map", "m.toml", "--model", "model.json", "-o", "maps"],
    );
    bad(&o, &["b0.tif", "decompression bomb"]);
    assert!(!d.path().join("maps").exists());
}

#[test]
fn memory_budget_refuses_large_frames_and_can_be_raised() {
    let d = tempfile::tempdir().unwrap();
    // 1024 x 1024 x 16 bit, uncompressed: 2 MiB on disk, ~35 MiB of work for stokes.
    gray16(d.path(), "raw.tif", 1024, 1024, 0);
    let o = run(
        d.path(),
        &[
            "--memory-limit",
            "16M",
            "stokes",
            "--dofp",
            "raw.tif",
            "-o",
            "a",
        ],
    );
    let e = bad(
        &o,
        &[
            "raw.tif",
            "1024x1024",
            "memory limit of 16.0 MiB",
            "--memory-limit",
        ],
    );
    assert!(e.contains("POLARID_MEMORY_LIMIT"), "{e}");
    assert!(!d.path().join("a").exists());
    // The environment variable does the same; the option wins over it.
    let env = |v: &str, args: &[&str]| {
        Command::new(bin())
            .args(args)
            .current_dir(d.path())
            .env("POLARID_MEMORY_LIMIT", v)
            .output()
            .unwrap()
    };
    bad(
        &env("16M", &["stokes", "--dofp", "raw.tif", "-o", "b"]),
        &["memory limit"],
    );
    ok(&env(
        "16M",
        &[
            "--memory-limit",
            "1G",
            "stokes",
            "--dofp",
            "raw.tif",
            "-o",
            "c",
        ],
    ));
    bad(
        &env("lots", &["stokes", "--dofp", "raw.tif", "-o", "d"]),
        &["POLARID_MEMORY_LIMIT"],
    );
    // The default budget (4 GiB) takes it.
    ok(&run(d.path(), &["stokes", "--dofp", "raw.tif", "-o", "e"]));
    // A malformed size is a usage error.
    let o = run(
        d.path(),
        &[
            "--memory-limit",
            "4X",
            "stokes",
            "--dofp",
            "raw.tif",
            "-o",
            "f",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
}

#[test]
fn special_files_are_refused_at_every_entry_point() {
    let d = tempfile::tempdir().unwrap();
    let entry_points: Vec<Vec<&str>> = vec![
        vec!["fit", "SPECIAL"],
        vec!["train", "SPECIAL", "-o", "m.json"],
        vec!["classify", "SPECIAL", "--library", "builtin"],
        vec!["evaluate", "SPECIAL"],
        vec!["measure", "SPECIAL"],
        vec!["map", "SPECIAL", "--model", "SPECIAL", "-o", "maps"],
        vec!["simulate", "SPECIAL", "-o", "sim"],
        vec!["model", "--input", "SPECIAL"],
        vec!["library", "SPECIAL", "--band", "600:700"],
        vec!["stokes", "--dofp", "SPECIAL", "-o", "st"],
        vec![
            "stokes", "--frames", "SPECIAL", "SPECIAL", "SPECIAL", "--angles", "0,60,120", "-o",
            "st",
        ],
    ];
    // FIFOs are streams, read like files (tests/newcomer_traps.rs); /dev/zero is refused.
    let specials = [("/dev/zero".to_string(), "character device")];
    for (special, kind) in &specials {
        for ep in &entry_points {
            let args: Vec<&str> = ep
                .iter()
                .map(|a| if *a == "SPECIAL" { special.as_str() } else { a })
                .collect();
            // Under 1 GB of address space.
            let o = run_limited(d.path(), 1_000_000, &args);
            let e = bad(&o, &[special.as_str()]);
            assert!(
                e.contains(kind) || e.contains("not a regular file"),
                "{args:?}: {e}"
            );
        }
    }
}

// `evaluate` of 20,000 fits in linear memory (under `ulimit -v` of 1 GB; 6.1 GB before):
// `hostile_acceptance::evaluate_of_20000_rows_runs_under_1_gb_measured`, which runs it
// under that limit and measures the peak in the same run.

// ---------------------------------------------------------------------------------------
// 3. Atomic directories, concurrent writers, signals, stale staging

/// Frames for a stokes run of `w × h` pixels (seeded), and the args writing to `out`.
fn stokes_inputs(dir: &Path, w: usize, seed: u16) -> Vec<String> {
    let names: Vec<String> = (0..3)
        .map(|i| gray16(dir, &format!("f{seed}_{i}.tif"), w, w, seed + i))
        .collect();
    let mut args = vec!["stokes".to_string(), "--frames".to_string()];
    args.extend(names);
    args.extend(["--angles".to_string(), "0,60,120".to_string()]);
    args
}

const STOKES_FILES: [&str; 8] = [
    "aolp.png", "aolp.tif", "dolp.png", "dolp.tif", "s0.png", "s0.tif", "s1.tif", "s2.tif",
];

/// The files of a stokes output directory, as (name, bytes), sorted.
fn contents(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().into_string().unwrap(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

fn spawn(dir: &Path, args: &[String]) -> std::process::Child {
    Command::new(bin())
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn kill(child: &std::process::Child, sig: &str) {
    let _ = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status();
}

#[test]
fn kill_9_at_any_moment_leaves_old_or_new_directory_never_a_mixture() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let a = stokes_inputs(p, 512, 1);
    let b = stokes_inputs(p, 512, 50);
    let with_out = |args: &[String], out: &str, force: bool| {
        let mut v = args.to_vec();
        v.extend(["-o".to_string(), out.to_string()]);
        if force {
            v.push("--force".to_string());
        }
        v
    };
    // Reference outputs, and how long a run takes.
    let t0 = Instant::now();
    ok(&Command::new(bin())
        .args(with_out(&a, "ref_a", false))
        .current_dir(p)
        .output()
        .unwrap());
    let took = t0.elapsed();
    ok(&Command::new(bin())
        .args(with_out(&b, "ref_b", false))
        .current_dir(p)
        .output()
        .unwrap());
    let (ra, rb) = (contents(&p.join("ref_a")), contents(&p.join("ref_b")));
    assert_eq!(ra.len(), STOKES_FILES.len());
    assert_ne!(ra, rb);
    let trials = 24;
    let (mut saw_old, mut saw_new, mut saw_none) = (0, 0, 0);
    for t in 0..trials {
        // Kill times spread over the whole run, including its final publication.
        let at = took.mul_f64(0.15 + 1.1 * t as f64 / trials as f64);
        // A new directory: absent or complete.
        let out = format!("new{t}");
        let mut c = spawn(p, &with_out(&a, &out, false));
        std::thread::sleep(at);
        kill(&c, "-KILL");
        let _ = c.wait();
        if p.join(&out).exists() {
            assert_eq!(
                contents(&p.join(&out)),
                ra,
                "trial {t}: partial new directory"
            );
        } else {
            saw_none += 1;
        }
        // --force over an existing directory: all old or all new.
        let out = format!("old{t}");
        ok(&Command::new(bin())
            .args(with_out(&a, &out, false))
            .current_dir(p)
            .output()
            .unwrap());
        let mut c = spawn(p, &with_out(&b, &out, true));
        std::thread::sleep(at);
        kill(&c, "-KILL");
        let _ = c.wait();
        let got = contents(&p.join(&out));
        if got == ra {
            saw_old += 1;
        } else if got == rb {
            saw_new += 1;
        } else {
            panic!("trial {t}: old and new files mixed in {out}");
        }
    }
    eprintln!("kill -9: new dir absent {saw_none}/{trials}; --force old {saw_old}, new {saw_new}");
    // A later run cleans what the killed ones left.
    ok(&Command::new(bin())
        .args(with_out(&a, "after", false))
        .current_dir(p)
        .output()
        .unwrap());
    assert!(hidden(p).is_empty(), "stale staging left: {:?}", hidden(p));
}

#[test]
fn two_concurrent_writers_never_both_succeed() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let a = stokes_inputs(p, 256, 3);
    let b = stokes_inputs(p, 256, 70);
    let mut both = 0;
    for t in 0..10 {
        let out = format!("out{t}");
        let mut va = a.clone();
        va.extend(["-o".to_string(), out.clone()]);
        let mut vb = b.clone();
        vb.extend(["-o".to_string(), out.clone()]);
        let (ca, cb) = (spawn(p, &va), spawn(p, &vb));
        let (oa, ob) = (
            ca.wait_with_output().unwrap(),
            cb.wait_with_output().unwrap(),
        );
        let codes = (oa.status.code(), ob.status.code());
        match codes {
            (Some(0), Some(2)) | (Some(2), Some(0)) => {}
            (Some(0), Some(0)) => both += 1,
            other => panic!(
                "trial {t}: statuses {other:?}: {} {}",
                text(&oa.stderr),
                text(&ob.stderr)
            ),
        }
        let loser = if codes.0 == Some(2) { &oa } else { &ob };
        let e = text(&loser.stderr);
        assert!(
            e.contains("another polarid run") || e.contains("output exists"),
            "{e}"
        );
        // The directory is one run's output, complete.
        let names: Vec<String> = contents(&p.join(&out)).into_iter().map(|x| x.0).collect();
        assert_eq!(names, STOKES_FILES);
    }
    assert_eq!(both, 0);
    // Library level: two stagings of one new directory, and of one existing directory
    // with --force: the second to publish fails with the concurrent-writer error.
    use polarid_io::atomic::StagedDir;
    let dest = p.join("lib");
    let s1 = StagedDir::new(&dest, false).unwrap();
    let s2 = StagedDir::new(&dest, false).unwrap();
    fs::write(s1.path("x.txt").unwrap(), "1").unwrap();
    fs::write(s2.path("y.txt").unwrap(), "2").unwrap();
    s1.commit().unwrap();
    let e = s2.commit().unwrap_err();
    assert!(matches!(e, polarid_io::IoError::Concurrent { .. }), "{e}");
    let s1 = StagedDir::new(&dest, true).unwrap();
    let s2 = StagedDir::new(&dest, true).unwrap();
    fs::write(s1.path("x.txt").unwrap(), "3").unwrap();
    fs::write(s2.path("x.txt").unwrap(), "4").unwrap();
    s1.commit().unwrap();
    let e = s2.commit().unwrap_err();
    assert!(matches!(e, polarid_io::IoError::Concurrent { .. }), "{e}");
    assert_eq!(fs::read_to_string(dest.join("x.txt")).unwrap(), "3");
    assert!(!dest.join("y.txt").exists() || fs::read_to_string(dest.join("y.txt")).is_ok());
    assert!(hidden(p).is_empty(), "{:?}", hidden(p));
}

#[test]
fn force_over_a_directory_keeps_its_other_files_and_replaces_in_one_step() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let a = stokes_inputs(p, 32, 5);
    let mut v = a.clone();
    v.extend(["-o".to_string(), "out".to_string()]);
    ok(&Command::new(bin())
        .args(&v)
        .current_dir(p)
        .output()
        .unwrap());
    fs::write(p.join("out/notes.txt"), "mine").unwrap();
    // Without --force: refused, nothing changed.
    let o = Command::new(bin())
        .args(&v)
        .current_dir(p)
        .output()
        .unwrap();
    bad(&o, &["output exists"]);
    let before = contents(&p.join("out"));
    v.push("--force".to_string());
    ok(&Command::new(bin())
        .args(&v)
        .current_dir(p)
        .output()
        .unwrap());
    assert_eq!(contents(&p.join("out")), before, "same inputs, same files");
    assert_eq!(fs::read_to_string(p.join("out/notes.txt")).unwrap(), "mine");
    assert!(hidden(p).is_empty(), "{:?}", hidden(p));
}

#[test]
fn signals_remove_staging_and_exit_128_plus_signal() {
    for (sig, code) in [("-INT", 130), ("-TERM", 143), ("-HUP", 129)] {
        let d = tempfile::tempdir().unwrap();
        let p = d.path();
        let c = Command::new(bin())
            .args(["demo", "-o", "demo"])
            .current_dir(p)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Wait until the run is staging files.
        let t0 = Instant::now();
        let mut staged = false;
        while t0.elapsed() < Duration::from_secs(60) {
            let h = hidden(p);
            if h.iter().any(|n| n.starts_with(".polarid-staging-"))
                && fs::read_dir(p.join(&h[0])).is_ok_and(|mut r| r.next().is_some())
            {
                staged = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(staged, "demo did not start staging");
        kill(&c, sig);
        let o = c.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(code), "{sig}: {}", text(&o.stderr));
        assert!(
            text(&o.stderr).contains("interrupted"),
            "{}",
            text(&o.stderr)
        );
        assert!(hidden(p).is_empty(), "{sig}: staging left: {:?}", hidden(p));
        assert!(!p.join("demo").exists(), "{sig}");
    }
}

#[test]
fn stale_staging_of_dead_runs_is_removed_live_ones_kept() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    // A pid that is not running (pids above pid_max never are).
    let dead = (4_194_304u32..)
        .find(|pid| !Path::new(&format!("/proc/{pid}")).exists())
        .unwrap();
    let stale = p.join(format!(".polarid-staging-{dead}-abc"));
    fs::create_dir_all(stale.join("sub")).unwrap();
    fs::write(stale.join("sub/s0.tif"), "partial").unwrap();
    let stale_tmp = p.join(format!(".polarid-tmp-{dead}-xyz"));
    fs::write(&stale_tmp, "partial").unwrap();
    let live = p.join(format!(".polarid-staging-{}-live", std::process::id()));
    fs::create_dir_all(&live).unwrap();
    let other = p.join(".polarid-staging-notapid");
    fs::create_dir_all(&other).unwrap();
    let mut v = stokes_inputs(p, 16, 9);
    v.extend(["-o".to_string(), "out".to_string()]);
    ok(&Command::new(bin())
        .args(&v)
        .current_dir(p)
        .output()
        .unwrap());
    assert!(!stale.exists() && !stale_tmp.exists(), "{:?}", hidden(p));
    assert!(live.exists(), "a live process's staging was removed");
    assert!(other.exists(), "an entry without a pid was removed");
}

// ---------------------------------------------------------------------------------------
// 4. Exit statuses of bad paths

#[test]
fn bad_paths_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    std::os::unix::fs::symlink("loop", p.join("loop")).unwrap();
    bad(&run(p, &["fit", "loop"]), &["loop"]);
    fs::write(
        p.join("meas.csv"),
        "target,class,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,dolp_se\n\
         A,al,30,60,180,45,0.2,0.01\nA,al,40,60,180,50,0.3,0.01\nA,al,50,60,180,55,0.4,0.01\n",
    )
    .unwrap();
    fs::write(p.join("afile"), "x").unwrap();
    for out in [
        "missing/dir/",
        "missing/dir/fits.csv",
        "afile/fits.csv",
        "loop/fits.csv",
        "loop",
    ] {
        let o = run(p, &["fit", "meas.csv", "-o", out]);
        bad(&o, &[]);
    }
    // An output directory under a file, or through a loop.
    let mut v = stokes_inputs(p, 8, 1);
    for out in ["afile/out", "loop/out"] {
        let mut a = v.clone();
        a.extend(["-o".to_string(), out.to_string()]);
        let o = Command::new(bin())
            .args(&a)
            .current_dir(p)
            .output()
            .unwrap();
        bad(&o, &[]);
    }
    v.extend(["-o".to_string(), "fine/new/dir/".to_string()]);
    ok(&Command::new(bin())
        .args(&v)
        .current_dir(p)
        .output()
        .unwrap());
    assert!(p.join("fine/new/dir/s0.tif").exists());
}

// ---------------------------------------------------------------------------------------
// 5. CSV injection

#[test]
fn formula_names_are_neutralised_in_csv_outputs_and_round_trip() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let names = ["=HYPERLINK(\"http://x\")", "+cmd|calc", "@SUM(1)", "-2+3"];
    let mut s = String::from(FITS_HEADER);
    for (i, n) in names.iter().enumerate() {
        let q = n.replace('"', "\"\"");
        s += &format!(
            "\"{q}\",\"{q}\",{},{},0.05,0.05,0,0.001,5,ok\n",
            0.5 + i as f64,
            1.0 + i as f64
        );
        s += &format!(
            "\"{q}2\",\"{q}\",{},{},0.05,0.05,0,0.001,5,ok\n",
            0.52 + i as f64,
            1.02 + i as f64
        );
    }
    fs::write(p.join("fits.csv"), s).unwrap();
    ok(&run(p, &["train", "fits.csv", "-o", "model.json"]));
    let model = fs::read_to_string(p.join("model.json")).unwrap();
    assert!(
        model.contains("\"@SUM(1)\""),
        "JSON keeps names as they are: {model}"
    );
    ok(&run(
        p,
        &[
            "classify",
            "fits.csv",
            "--model",
            "model.json",
            "-o",
            "c.csv",
        ],
    ));
    let out = fs::read_to_string(p.join("c.csv")).unwrap();
    for line in out.lines().skip(1).filter(|l| !l.starts_with('#')) {
        let first = line.trim_start_matches('"');
        assert!(
            !first.starts_with(['=', '+', '-', '@']),
            "a row starts with a formula: {line}"
        );
    }
    assert!(
        out.contains("'=HYPERLINK") && out.contains("'+cmd|calc") && out.contains("'@SUM(1)"),
        "{out}"
    );
    // Read back by polarid: the quote is removed again (train on its own fits output).
    ok(&run(
        p,
        &["evaluate", "fits.csv", "--format", "json", "-o", "e.json"],
    ));
    let e = fs::read_to_string(p.join("e.json")).unwrap();
    assert!(e.contains("\"+cmd|calc\"") && !e.contains("'+cmd"), "{e}");
    // Numbers are not quoted.
    assert!(!out.contains("'-0") && !out.contains("'-1"), "{out}");
    use polarid_io::table::{CsvTable, guard, unguard};
    for n in names
        .iter()
        .chain(&["'=x", "''@y", "plain", "-1.5", "'", "'abc"])
    {
        assert_eq!(unguard(&guard(n)), *n, "{n}");
    }
    assert_eq!(guard("-1.5"), "-1.5");
    assert_eq!(guard("=1+1"), "'=1+1");
    let t = CsvTable::from_reader(Path::new("t.csv"), "a,b\n'=x,'plain\n".as_bytes()).unwrap();
    assert_eq!((t.text(0, 0), t.text(0, 1)), ("=x", "'plain"));
}

// ---------------------------------------------------------------------------------------
// 6. Silent acceptance

#[test]
fn out_of_range_fit_values_are_refused_naming_line_column_and_value() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let cases = [
        ("A,al,1.5,4,-0.1,0.1,0,0,5,ok", "n_se", "-0.1"),
        ("A,al,1.5,4,0.1,-1e-3,0,0,5,ok", "k_se", "-1e-3"),
        ("A,al,1.5,4,0.1,0.1,2,0,5,ok", "nk_corr", "\"2\""),
        ("A,al,1.5,4,0.1,0.1,-1.5,0,5,ok", "nk_corr", "-1.5"),
        ("A,al,1.5,4,inf,0.1,0,0,5,ok", "n_se", "inf"),
        ("A,al,1.5,4,0.1,0.1,0,0,5,", "status", "empty fit status"),
    ];
    for (row, col, word) in cases {
        fs::write(
            p.join("f.csv"),
            format!("{FITS_HEADER}B,cu,0.5,3,0.1,0.1,0,0,5,ok\n{row}\n"),
        )
        .unwrap();
        for cmd in [
            &["train", "f.csv", "-o", "m.json"][..],
            &["evaluate", "f.csv"],
        ] {
            bad(
                &run(p, cmd),
                &["f.csv", "line 3", &format!("`{col}`"), word],
            );
        }
    }
    // An empty cell is "unknown" and accepted; the literal nan in a usable row is not
    // (it silently dropped the covariance), in a failed fit's row it is.
    fs::write(
        p.join("f.csv"),
        format!("{FITS_HEADER}B,cu,0.5,3,,,,0,5,ok\nA,al,1.5,4,0.1,0.1,0.2,0,5,ok\n"),
    )
    .unwrap();
    ok(&run(p, &["train", "f.csv", "-o", "m2.json"]));
    fs::write(
        p.join("f.csv"),
        format!(
            "{FITS_HEADER}B,cu,nan,nan,nan,nan,nan,nan,5,not_converged\n\
             A,al,1.5,4,0.1,0.1,0.2,0,5,ok\nC,cu,0.5,3,0.1,0.1,0,0,5,ok\n"
        ),
    )
    .unwrap();
    ok(&run(
        p,
        &["train", "f.csv", "-o", "m3.json", "--allow-not-ok"],
    ));
}

#[test]
fn look_alike_names_are_one_class_and_invisible_characters_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    // "café" composed (NFC) and decomposed (NFD): one class.
    let nfc = "caf\u{e9}";
    let nfd = "cafe\u{301}";
    fs::write(
        p.join("f.csv"),
        format!(
            "{FITS_HEADER}A,{nfc},1.5,4,0.1,0.1,0,0,5,ok\nB,{nfd},1.52,4.02,0.1,0.1,0,0,5,ok\n\
             C,cu,0.5,3,0.1,0.1,0,0,5,ok\nD,cu,0.52,3.02,0.1,0.1,0,0,5,ok\n"
        ),
    )
    .unwrap();
    ok(&run(
        p,
        &["evaluate", "f.csv", "--format", "json", "-o", "e.json"],
    ));
    let e = fs::read_to_string(p.join("e.json")).unwrap();
    assert!(!e.contains(nfd), "the NFD spelling survived: {e}");
    let v: serde_json::Value = serde_json::from_str(&e).unwrap();
    assert_eq!(v["accuracy"].as_f64(), Some(1.0), "{e}");
    for (bad_name, cp) in [
        ("al\u{200b}", "U+200B"),
        ("\u{202e}la", "U+202E"),
        ("a\u{2066}l", "U+2066"),
        ("a\u{7}l", "U+0007"),
    ] {
        fs::write(
            p.join("g.csv"),
            format!(
                "{FITS_HEADER}A,{bad_name},1.5,4,0.1,0.1,0,0,5,ok\nB,cu,0.5,3,0.1,0.1,0,0,5,ok\n"
            ),
        )
        .unwrap();
        bad(
            &run(p, &["train", "g.csv", "-o", "m.json"]),
            &["g.csv", "line 2", "`class`", cp],
        );
    }
}

fn manifest_with(p: &Path, top: &str, capture_extra: &str, angle2: &str) -> String {
    for n in ["a.png", "b.png", "c.png"] {
        let v: Vec<u16> = vec![1000; 64];
        if !p.join(n).exists() {
            image::write_gray16(&p.join(n), false, 8, 8, &v).unwrap();
        }
    }
    let m = format!(
        "theta_r_deg = 60.0\n{top}\n[[region]]\nname = \"A\"\nrect = [1, 1, 4, 4]\n\n\
         [[capture]]\ntheta_i_deg = 30.0\n{capture_extra}\nframes = [\n  \
         {{ angle_deg = 0.0, file = \"a.png\" }},\n  {{ angle_deg = 60.0, file = \"b.png\" }},\n  \
         {{ angle_deg = {angle2}, file = \"c.png\" }},\n]\n"
    );
    fs::write(p.join("m.toml"), m).unwrap();
    "m.toml".into()
}

#[test]
fn manifest_values_out_of_physical_range_are_refused_naming_the_field() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let m = manifest_with(p, "", "", "1e308");
    bad(
        &run(p, &["measure", &m]),
        &["m.toml", "capture[1].frames", "1e308"],
    );
    let m = manifest_with(p, "", "exposure = 1e-308", "120.0");
    bad(
        &run(p, &["measure", &m]),
        &["m.toml", "capture[1].exposure", "1e-308"],
    );
    // dark_level = 1e308: the manifest's field is blamed (not the image, not "inf").
    let m = manifest_with(p, "dark_level = 1e308", "", "120.0");
    let e = bad(
        &run(p, &["measure", &m]),
        &["m.toml", "dark_level", "1e308"],
    );
    assert!(!e.contains("got inf") && !e.contains("a.png"), "{e}");
    let m = manifest_with(p, "", "dark_level = 1e308", "120.0");
    bad(
        &run(p, &["measure", &m]),
        &["capture[1].dark_level", "1e308"],
    );
    // And the command-line polarizer angles.
    let v = stokes_inputs(p, 8, 2);
    let mut a: Vec<String> = v[..5].to_vec();
    a.extend([
        "--angles".into(),
        "0,60,1e308".into(),
        "-o".into(),
        "o".into(),
    ]);
    let o = Command::new(bin())
        .args(&a)
        .current_dir(p)
        .output()
        .unwrap();
    bad(&o, &["--angles", "polarizer angle", "1e308"]);
    // A good manifest still measures.
    let m = manifest_with(p, "", "exposure = 0.001", "120.0");
    ok(&run(p, &["measure", &m, "-o", "meas.csv"]));
}

#[test]
fn scene_arrays_past_the_position_limit_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let list: Vec<String> = (0..20_000)
        .map(|i| format!("{}", 10.0 + (i % 70) as f64))
        .collect();
    let scene = format!(
        "width = 32\nheight = 32\ntheta_r_deg = 45.0\ntheta_i_deg = [{}]\nwavelength_nm = 650.0\n\n\
         [[plate]]\nname = \"al\"\nclass = \"aluminum\"\nn = 1.2\nk = 6.6\nsigma = 0.3\n\
         rect = [0, 0, 32, 32]\n",
        list.join(", ")
    );
    fs::write(p.join("s.toml"), scene).unwrap();
    let o = run(p, &["simulate", "s.toml", "-o", "sim"]);
    bad(
        &o,
        &[
            "s.toml",
            "theta_i_deg",
            "20000 source positions, more than 10000",
        ],
    );
}

// ---------------------------------------------------------------------------------------
// 7. Messages

#[test]
fn long_values_are_echoed_shortened() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    let big = "9".repeat(309);
    fs::write(
        p.join("f.csv"),
        format!("{FITS_HEADER}A,al,1.5,{big},0.1,0.1,0,0,5,ok\n"),
    )
    .unwrap();
    let e = bad(
        &run(p, &["train", "f.csv", "-o", "m.json"]),
        &["f.csv", "(309 characters)"],
    );
    assert!(e.len() < 400, "{} bytes: {e}", e.len());
    let name = "x".repeat(10 << 20);
    fs::write(
        p.join("g.csv"),
        format!("{FITS_HEADER}A\u{200b}{name},al,1.5,4,0.1,0.1,0,0,5,ok\n"),
    )
    .unwrap();
    let e = bad(
        &run(p, &["train", "g.csv", "-o", "m.json"]),
        &["g.csv", "characters)"],
    );
    assert!(e.len() < 600, "{} bytes echoed", e.len());
}

#[test]
fn byte_order_marks_are_accepted_in_json_csv_and_toml() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    fs::write(
        p.join("f.csv"),
        format!("\u{feff}{FITS_HEADER}A,al,1.5,4,0.1,0.1,0,0,5,ok\nB,cu,0.5,3,0.1,0.1,0,0,5,ok\n"),
    )
    .unwrap();
    ok(&run(p, &["train", "f.csv", "-o", "m.json"]));
    let m = fs::read_to_string(p.join("m.json")).unwrap();
    fs::write(p.join("bom.json"), format!("\u{feff}{m}")).unwrap();
    ok(&run(
        p,
        &["classify", "f.csv", "--model", "bom.json", "-o", "c.csv"],
    ));
    let m = manifest_with(p, "", "", "120.0");
    let t = fs::read_to_string(p.join(&m)).unwrap();
    fs::write(p.join(&m), format!("\u{feff}{t}")).unwrap();
    ok(&run(p, &["measure", &m, "-o", "meas.csv"]));
}

#[test]
fn identical_map_runs_write_identical_files() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path();
    for n in ["a.png", "b.png", "c.png"] {
        let v: Vec<u16> = (0..256).map(|i| 1000 + (i * 13 % 500) as u16).collect();
        image::write_gray16(&p.join(n), false, 16, 16, &v).unwrap();
    }
    let mut m =
        String::from("theta_r_deg = 45.0\n\n[[region]]\nname = \"A\"\nrect = [0, 0, 8, 8]\n");
    for th in [30.0, 45.0, 60.0] {
        m += &format!(
            "\n[[capture]]\ntheta_i_deg = {th}\nframes = [\n  {{ angle_deg = 0.0, file = \"a.png\" }},\n  \
             {{ angle_deg = 60.0, file = \"b.png\" }},\n  {{ angle_deg = 120.0, file = \"c.png\" }},\n]\n"
        );
    }
    fs::write(p.join("m.toml"), m).unwrap();
    fs::write(
        p.join("fits.csv"),
        format!("{FITS_HEADER}A,al,1.5,4,0.1,0.1,0,0,5,ok\nB,cu,0.5,3,0.1,0.1,0,0,5,ok\n"),
    )
    .unwrap();
    ok(&run(p, &["train", "fits.csv", "-o", "model.json"]));
    ok(&run(
        p,
        &["map", "m.toml", "--model", "model.json", "-o", "m1"],
    ));
    ok(&run(
        p,
        &["map", "m.toml", "--model", "model.json", "-o", "m2"],
    ));
    let (a, b) = (contents(&p.join("m1")), contents(&p.join("m2")));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x, y, "{} differs between identical runs", x.0);
    }
    let summary = fs::read_to_string(p.join("m1/map_summary.json")).unwrap();
    assert!(!summary.contains("seconds"), "{summary}");
}
