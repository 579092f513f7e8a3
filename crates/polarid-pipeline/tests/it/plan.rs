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
