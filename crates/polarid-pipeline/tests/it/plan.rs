//! `polarid_pipeline::plan` on a small far-field bench: two plates (aluminum, copper) seen
//! at θr = 50°, the current sources at θi 30–45° (β 40–47.5°), against a few materials of
//! the built-in library. The current plan cannot locate aluminum's fit; the recommended
//! positions reach larger β, locate it and separate every pair better. Bad settings are
//! configuration errors naming the option.

use polarid_pipeline::plan::{PlanConfig, Region, plan};

const SCENE: &str = r#"
name = "plan_far_field"
width = 128
height = 64
theta_r_deg = 50.0
theta_i_deg = [30, 35, 40, 45]
wavelength_nm = 650.0
[[plate]]
name = "al"
class = "aluminum"
n = 1.558
k = 7.712
sigma = 0.2
rect = [0, 0, 64, 64]
[[plate]]
name = "cu"
class = "copper"
n = 0.238
k = 3.626
sigma = 0.2
rect = [64, 0, 64, 64]
"#;

fn cfg() -> PlanConfig {
    PlanConfig {
        positions: 4,
        materials: vec![
            "aluminum".into(),
            "copper".into(),
            "gold".into(),
            "brass_Cu70Zn30".into(),
        ],
        region: Region {
            zenith_deg: (20.0, 85.0),
            step_deg: 5.0,
            ..Region::default()
        },
        ..PlanConfig::default()
    }
}

#[test]
fn the_recommended_positions_locate_aluminum() {
    let scene = polarid_io::scene::parse(std::path::Path::new("s.toml"), SCENE).unwrap();
    let out = plan(&scene, &cfg()).unwrap();
    assert_eq!(out.targets.len(), 2);
    assert_eq!(out.materials.len(), 4);
    let cur = out.current.as_ref().unwrap();
    // Aluminum at β 40–47.5°: the fit does not locate it.
    assert!(!cur.fits[0].locates(), "{:?}", cur.fits[0]);
    assert!(!cur.identifiable(0, 0.95));
    let rec = &out.recommended;
    assert!(rec.fits[0].locates(), "{:?}", rec.fits[0]);
    assert!(rec.worst_margin() > cur.worst_margin());
    // Every pair of each target, hardest first; β of the recommended rows reach 60°.
    assert_eq!(rec.pairs.len(), 2 * 3);
    let max_beta = rec
        .positions
        .iter()
        .map(|p| p.rows[0].beta_deg)
        .fold(0.0, f64::max);
    assert!(max_beta > 60.0, "{max_beta}");
    // The recommended scene replaces the sources.
    let text = out.recommended_scene(SCENE);
    assert!(text.contains("theta_r_deg"));
}

#[test]
fn bad_settings_name_the_option() {
    let scene = polarid_io::scene::parse(std::path::Path::new("s.toml"), SCENE).unwrap();
    for (c, needle) in [
        (
            PlanConfig {
                positions: 1,
                ..cfg()
            },
            "positions",
        ),
        (
            PlanConfig {
                power: 1.0,
                ..cfg()
            },
            "power",
        ),
        (
            PlanConfig {
                materials: vec!["unobtainium".into()],
                ..cfg()
            },
            "unobtainium",
        ),
    ] {
        let e = plan(&scene, &c).unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
    }
}

/// A colour bench (RGGB DoFP, far field): every pair is one test over the rows of the
/// three bands (one layer for all), at least as separating as the bands apart; each
/// pair also has its separation by each band's rows alone.
#[test]
fn a_colour_scene_uses_every_band() {
    const COLOUR: &str = r#"
name = "plan_colour"
width = 128
height = 64
theta_r_deg = 50.0
theta_i_deg = [30, 35, 40, 45]
bands = { R = 650.0, G = 550.0, B = 450.0 }
[capture]
kind = "dofp"
color = "RGGB"
[[plate]]
name = "al"
material = "aluminum"
sigma = 0.2
rect = [0, 0, 64, 64]
[[plate]]
name = "cu"
material = "copper"
sigma = 0.2
rect = [64, 0, 64, 64]
"#;
    let scene = polarid_io::scene::parse(std::path::Path::new("c.toml"), COLOUR).unwrap();
    let out = plan(&scene, &cfg()).unwrap();
    // `builtin` has one band: its three-band version is used, with a warning.
    assert_eq!(out.wavelengths_nm, vec![650.0, 550.0, 450.0]);
    assert_eq!(out.band_letters, vec!['R', 'G', 'B']);
    assert!(out.warnings.iter().any(|w| w.0.contains("builtin-rgb")));
    let cur = out.current.as_ref().unwrap();
    for q in &cur.positions {
        assert_eq!(q.rows[0].bands.len(), 3);
        // RGGB: green has two blocks of each period, so twice the estimates of red.
        let (r, g) = (q.rows[0].bands[0], q.rows[0].bands[1]);
        let per_electron =
            |b: polarid_pipeline::plan::BandNoise| b.dolp_se * b.dolp_se * b.electrons;
        assert!(per_electron(g) < 0.75 * per_electron(r), "{r:?} {g:?}");
    }
    for ev in [cur, &out.recommended] {
        assert_eq!(ev.pairs.len(), 2 * 3);
        for p in &ev.pairs {
            assert_eq!(p.by_band.len(), 3);
            // One test over all bands: its χ² is at least each band's alone, and (one
            // thickness for the three) at least nearly their sum.
            let sum: f64 = p.by_band.iter().map(|b| b.lambda).sum();
            for b in &p.by_band {
                assert!(p.sep.lambda >= b.lambda * 0.98 - 1e-6, "{p:?}");
            }
            assert!(
                p.sep.lambda >= 0.9 * sum - 1e-3,
                "{} vs {sum}",
                p.sep.lambda
            );
        }
    }
    assert!(out.recommended.worst_margin() >= cur.worst_margin());
}

/// The DoFP plates bench outdoors: the sun over a morning (`[plan.sun]`) gives the
/// candidate times; the recommended ones are among them, distinct, and separate the
/// plates at least as well as the scene's two.
const SUN_SCENE: &str = include_str!("../../../../examples/scenes/sun_plates.toml");

fn sun_cfg() -> PlanConfig {
    PlanConfig {
        positions: 4,
        materials: vec!["aluminum".into(), "copper".into(), "gold".into()],
        ..PlanConfig::default()
    }
}

#[test]
fn the_sun_over_a_window_gives_the_capture_times() {
    let scene =
        polarid_io::scene::parse(std::path::Path::new("sun_plates.toml"), SUN_SCENE).unwrap();
    let w = polarid_pipeline::plan::sun_window(&scene).unwrap().unwrap();
    assert_eq!(w.step_minutes, 15.0);
    assert_eq!(w.offset_minutes, -360);
    let out = plan(&scene, &sun_cfg()).unwrap();
    // 06:00 to 12:00 every 15 min: 25 times, the first ones while the sun is low may
    // leave a plate dark.
    assert!(
        out.candidates >= 15 && out.candidates <= 25,
        "{}",
        out.candidates
    );
    assert_eq!(out.sun_positions.len(), out.candidates);
    let mut times = Vec::new();
    for q in &out.recommended.positions {
        let polarid_io::manifest::SourceSpec::Sun {
            time, unix_seconds, ..
        } = &q.spec
        else {
            panic!("{q:?}");
        };
        assert!(
            time.starts_with("2026-06-21T") && time.ends_with("-06:00"),
            "{time}"
        );
        assert!(unix_seconds >= &w.start_unix_s && unix_seconds <= &w.end_unix_s);
        assert_eq!((unix_seconds - w.start_unix_s) % 900.0, 0.0, "{time}");
        times.push(time.clone());
    }
    times.sort();
    times.dedup();
    assert_eq!(times.len(), 4);
    let cur = out.current.as_ref().unwrap();
    assert!(out.recommended.worst_margin() >= cur.worst_margin());
    // The recommended scene has the times as sun sources, and loads.
    let text = out.recommended_scene(SUN_SCENE);
    assert_eq!(text.matches("sun = \"2026-06-21T").count(), 4);
    polarid_io::scene::parse(std::path::Path::new("rec.toml"), &text).unwrap();
}

#[test]
fn bad_sun_windows_name_the_file_the_key_and_the_value() {
    for (from, to, needles) in [
        (
            "start = \"2026-06-21T06:00:00-06:00\"",
            "start = \"2026-06-21 6am\"",
            &["sun_plates.toml, line ", "plan.sun.start", "2026-06-21 6am"][..],
        ),
        (
            "end = \"2026-06-21T12:00:00-06:00\"",
            "end = \"2026-06-21T05:00:00-06:00\"",
            &["plan.sun.end", "after plan.sun.start"][..],
        ),
        (
            "step_minutes = 15 ",
            "step_minutes = 0 ",
            &["plan.sun.step_minutes", "1 to 1440", "got 0"][..],
        ),
        (
            "step_minutes = 15 ",
            "step_minute = 15 ",
            &["[plan]", "step_minute"][..],
        ),
        (
            "step_minutes = 15 ",
            "step_minutes = 15\nintensity = -2 ",
            &["plan.sun.intensity", "> 0", "-2"][..],
        ),
    ] {
        let text = SUN_SCENE.replacen(from, to, 1);
        assert_ne!(text, SUN_SCENE, "{from}");
        let scene =
            polarid_io::scene::parse(std::path::Path::new("sun_plates.toml"), &text).unwrap();
        let e = plan(&scene, &sun_cfg()).unwrap_err().to_string();
        for n in needles {
            assert!(e.contains(n), "{n:?} not in {e}");
        }
    }
    // A far-field scene has no site to see the sun from.
    let far = format!(
        "{SCENE}\n[plan.sun]\nstart = \"2026-06-21T06:00:00-06:00\"\nend = \"2026-06-21T12:00:00-06:00\"\n"
    );
    let scene = polarid_io::scene::parse(std::path::Path::new("s.toml"), &far).unwrap();
    let e = plan(&scene, &cfg()).unwrap_err().to_string();
    assert!(e.contains("s.toml, line ") && e.contains("[site]"), "{e}");
    // A window without the sun: no candidate times.
    let night = SUN_SCENE
        .replacen("T06:00:00-06:00\"   #", "T21:00:00-06:00\"   #", 1)
        .replacen(
            "end = \"2026-06-21T12:00:00-06:00\"",
            "end = \"2026-06-21T23:00:00-06:00\"",
            1,
        );
    let scene = polarid_io::scene::parse(std::path::Path::new("sun_plates.toml"), &night).unwrap();
    let e = plan(&scene, &sun_cfg()).unwrap_err().to_string();
    assert!(
        e.contains("[plan.sun]") && e.contains("gives only 0 times"),
        "{e}"
    );
}
