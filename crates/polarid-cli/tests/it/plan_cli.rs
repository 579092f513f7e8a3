//! `polarid plan` on the bench of examples/scenes/dofp_lamp_plates.toml (aluminum, copper
//! and gold plates, a DoFP camera behind a lens 0.8 m away, a lamp at six positions
//! around the mirror direction): the six positions cannot identify aluminum (nor gold,
//! which magnesium under its oxide mimics there); a simulation at the recommended
//! positions is then classified aluminum, copper and gold by `classify MEASUREMENTS.csv
//! --library builtin` (docs/PLAN.md). Also: bad input names the option and exits 2.

use crate::common;

use std::path::{Path, PathBuf};

use common::{csv_rows, polarid, text};

fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes/dofp_lamp_plates.toml")
}

fn ok(args: &[&str]) -> (String, String) {
    let o = polarid(args);
    assert!(
        o.status.success(),
        "polarid {args:?} failed: {}",
        text(&o.stderr)
    );
    (text(&o.stdout), text(&o.stderr))
}

#[test]
fn plan_then_simulate_identifies_the_three_metals() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    let s = scene();
    // A region cut to the useful zeniths keeps the test to seconds (the default region
    // gives the same six positions, docs/PLAN.md).
    let (stdout, _) = ok(&[
        "plan",
        s.to_str().unwrap(),
        "--zenith-deg",
        "30:85",
        "--azimuth-deg=-20:20",
        "-o",
        out.to_str().unwrap(),
    ]);
    let (current, recommended) = stdout
        .split_once("Recommended")
        .expect("a recommended section");
    assert!(
        current.contains("aluminum: aluminum NOT identifiable"),
        "{stdout}"
    );
    assert!(current.contains("gold: gold NOT identifiable"), "{stdout}");
    assert!(current.contains("copper: copper identifiable"), "{stdout}");
    // The recommended plan locates aluminum's fit, and separates gold from its hardest
    // alternative better than the current one.
    assert!(!recommended.contains("cannot locate"), "{recommended}");
    let pairs = csv_rows(&out.join("pairs.csv"));
    let worst = |design: &str, plate: &str| {
        pairs
            .iter()
            .filter(|r| r["design"] == design && r["plate"] == plate)
            .map(|r| r["margin"].parse::<f64>().unwrap())
            .fold(f64::INFINITY, f64::min)
    };
    assert!(
        worst("recommended", "gold") > 5.0 * worst("current", "gold"),
        "{stdout}"
    );
    assert!(recommended.contains("6 positions"), "{recommended}");
    for f in ["positions.csv", "plan.png", "plan.svg", "scene.toml"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let positions = csv_rows(&out.join("positions.csv"));
    let rec_beta: Vec<f64> = positions
        .iter()
        .filter(|r| r["design"] == "recommended" && r["plate"] == "aluminum")
        .map(|r| r["beta_deg"].parse().unwrap())
        .collect();
    assert_eq!(rec_beta.len(), 6);
    assert!(
        rec_beta.iter().copied().fold(0.0, f64::max) > 60.0,
        "{rec_beta:?}"
    );
    // The recommended scene, simulated, measured and classified against the library.
    let sim = tmp.path().join("sim");
    let m = tmp.path().join("m.csv");
    ok(&[
        "simulate",
        out.join("scene.toml").to_str().unwrap(),
        "-o",
        sim.to_str().unwrap(),
        "-q",
    ]);
    ok(&[
        "measure",
        sim.join("manifest.toml").to_str().unwrap(),
        "-o",
        m.to_str().unwrap(),
        "-q",
    ]);
    let c = tmp.path().join("c.csv");
    ok(&[
        "classify",
        m.to_str().unwrap(),
        "--library",
        "builtin",
        "-o",
        c.to_str().unwrap(),
        "-q",
    ]);
    let rows = csv_rows(&c);
    for plate in ["aluminum", "copper", "gold"] {
        let r = rows.iter().find(|r| r["target"] == plate).unwrap();
        assert_eq!(r["status"], "ok", "{plate}: {r:?}");
        assert_eq!(r["predicted"], plate, "{plate}: {r:?}");
    }
}

#[test]
fn plan_refuses_bad_input_naming_it() {
    let s = scene();
    let s = s.to_str().unwrap();
    for (args, needle) in [
        (vec!["plan", s, "--positions", "1"], "positions"),
        (vec!["plan", s, "--materials", "alumin"], "alumin"),
        (vec!["plan", s, "--zenith-deg", "50:95"], "zenith-deg"),
        (vec!["plan", s, "--power", "1.5"], "power"),
        (vec!["plan", "no/such/scene.toml"], "no/such/scene.toml"),
    ] {
        let o = polarid(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o.stderr));
        assert!(
            text(&o.stderr).contains(needle),
            "{args:?}: {}",
            text(&o.stderr)
        );
        assert!(o.stdout.is_empty(), "{args:?}: no partial output");
    }
}

/// The sun over a morning (`[plan.sun]` of examples/scenes/sun_plates.toml): capture
/// times, the times figure, and a bad key refused naming the file, the key and the
/// value, with exit status 2 and nothing written.
#[test]
fn plan_picks_the_sun_s_capture_times() {
    let tmp = tempfile::tempdir().unwrap();
    let s = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes/sun_plates.toml");
    let out = tmp.path().join("plan");
    let (stdout, _) = ok(&[
        "plan",
        s.to_str().unwrap(),
        "-n",
        "4",
        "--materials",
        "aluminum,copper,gold,silver",
        "-o",
        out.to_str().unwrap(),
    ]);
    let (_, recommended) = stdout.split_once("Recommended").expect("recommended");
    assert_eq!(recommended.matches("2026-06-21T").count(), 4, "{stdout}");
    for f in ["times.png", "times.svg", "plan.png", "scene.toml"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let scene = std::fs::read_to_string(out.join("scene.toml")).unwrap();
    assert_eq!(scene.matches("sun = \"2026-06-21T").count(), 4, "{scene}");
    let bad = tmp.path().join("bad.toml");
    let bad_text = std::fs::read_to_string(&s).unwrap().replacen(
        "step_minutes = 15 ",
        "step_minutes = -5 ",
        1,
    );
    std::fs::write(&bad, bad_text).unwrap();
    let o = polarid(&[
        "plan",
        bad.to_str().unwrap(),
        "-o",
        tmp.path().join("x").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    let e = text(&o.stderr);
    assert!(
        e.contains("bad.toml, line ") && e.contains("plan.sun.step_minutes") && e.contains("-5"),
        "{e}"
    );
    assert!(o.stdout.is_empty());
    assert!(!tmp.path().join("x").exists());
}
