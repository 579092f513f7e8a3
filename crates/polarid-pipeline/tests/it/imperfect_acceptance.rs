//! Issue 16's acceptance statistics, measured on targets from the simulator of
//! real-world imperfections (`polarid_core::simulate::imperfect`), fitted and classified
//! with the defaults (`FitConfig::default()`, the 95% set rule against the built-in
//! library): angle offsets, extinction 300:1 and native oxides; thick films whose AoLP
//! flips; diffusers with known brightness. Fixed seeds; figures in docs/ERRORS.md.

use std::path::Path;

use polarid_core::FitStatus;
use polarid_core::classify::{Classifier, ClassifierConfig, Prototype};
use polarid_core::simulate::imperfect::{
    ImperfectRow, ImperfectTarget, Imperfections, Surface, simulate_target,
};
use polarid_io::library::Library;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;
use polarid_pipeline::classify::estimate_of;
use polarid_pipeline::fit::{FitConfig, fit};
use polarid_testkit::Rng;

fn silent(_: &str, _: u64, _: u64) {}

/// Source zeniths of the captures, degrees, and the camera's: the paper's bench
/// (section 7: θr = 60°, θi = 35–80° in 5° steps, β = 47.5–70°).
const THETA_I: [f64; 10] = [35.0, 40.0, 45.0, 50.0, 55.0, 60.0, 65.0, 70.0, 75.0, 80.0];
const THETA_R: f64 = 60.0;

/// Rows of the measurements CSV from simulated rows; `brightness`: with `s0` and
/// `exposure` (as `measure` writes them), else without.
fn measurements(target: &str, rows: &[ImperfectRow], brightness: bool) -> Vec<Measurement> {
    rows.iter()
        .map(|r| Measurement {
            target: target.into(),
            theta_i_deg: Some(r.theta_i_deg),
            theta_r_deg: Some(r.theta_r_deg),
            phi_deg: 180.0,
            beta_deg: r.beta_deg,
            dolp: r.dolp,
            dolp_se: Some(r.dolp_se),
            s0: brightness.then_some(r.s0),
            exposure: brightness.then_some(r.exposure),
            aolp_poi_deg: Some(r.aolp_poi_deg),
            ..Default::default()
        })
        .collect()
}

fn fit_rows(rows: &[Measurement], cfg: &FitConfig) -> Vec<FitRow> {
    let lines: Vec<(u64, Measurement)> = rows
        .iter()
        .enumerate()
        .map(|(i, m)| (i as u64 + 2, m.clone()))
        .collect();
    fit(Path::new("m.csv"), &lines, cfg, &silent)
        .unwrap()
        .rows()
}

fn library() -> Vec<Prototype> {
    Library::builtin().unwrap().prototypes()
}

fn proto<'a>(lib: &'a [Prototype], class: &str) -> &'a Prototype {
    lib.iter().find(|p| p.class == class).unwrap()
}

/// Native oxides (or a contamination layer): substrate class, film index.
const OXIDES: [(&str, (f64, f64)); 5] = [
    ("silicon", (1.46, 0.0)),  // SiO2
    ("aluminum", (1.65, 0.0)), // amorphous Al2O3
    ("copper", (2.9, 0.1)),    // Cu2O
    ("gold", (1.5, 0.0)),      // adsorbed hydrocarbons
    ("nickel", (2.3, 0.0)),    // NiO
];

fn realistic(max_off_deg: f64) -> Imperfections {
    Imperfections {
        angle_offset_max: max_off_deg.to_radians(),
        extinction_ratio: 300.0,
        dolp_se: 1e-3,
        s0_rel_sd: 0.01,
        ..Imperfections::default()
    }
}

/// Per material: (targets, truth in the 95% set, set sizes, statuses not ok).
fn oxide_coverage(
    per_material: usize,
    seed: u64,
    cfg: &FitConfig,
    brightness: bool,
    verbose: bool,
) -> Vec<(String, usize, usize, usize, usize)> {
    let lib = library();
    let clf = Classifier::new(lib.clone(), ClassifierConfig::set(0.95)).unwrap();
    let mut rng = Rng(seed);
    let mut out = Vec::new();
    for (mi, &(class, film)) in OXIDES.iter().enumerate() {
        let p = proto(&lib, class);
        let mut rows = Vec::new();
        let mut thick = Vec::new();
        for t in 0..per_material {
            let d = 1.0 + 4.0 * rng.uniform_co();
            thick.push(d);
            let target = ImperfectTarget {
                surface: Surface::Film {
                    substrate: (p.n, p.k),
                    film,
                    thickness_nm: d,
                },
                sigma: 0.1 + 0.2 * rng.uniform_co(),
                rho_d: 0.0,
            };
            let theta_i: Vec<f64> = THETA_I.iter().map(|d| d.to_radians()).collect();
            let sim = simulate_target(
                &target,
                &theta_i,
                THETA_R.to_radians(),
                &realistic(0.3),
                seed * 1_000_003 + (mi * 100_000 + t) as u64,
            )
            .unwrap();
            rows.extend(measurements(&format!("{class}_{t}"), &sim, brightness));
        }
        let fits = fit_rows(&rows, cfg);
        let (mut covered, mut size, mut bad) = (0, 0, 0);
        for (f, d) in fits.iter().zip(&thick) {
            let dec = clf.classify(&estimate_of(f));
            let inside = f.status.is_ok() && dec.candidates.iter().any(|c| c.class == class);
            covered += usize::from(inside);
            size += dec.candidates.len();
            bad += usize::from(!f.status.is_ok());
            if verbose && !inside {
                eprintln!(
                    "  {class} d {d:.2} nm: {:.3} + {:.3}i (se {:.3} {:.3} r {:.2}) truth {:.3} + {:.3}i status {} {} set {}",
                    f.n,
                    f.k,
                    f.n_se,
                    f.k_se,
                    f.nk_corr,
                    p.n,
                    p.k,
                    f.status.as_str(),
                    f.reason,
                    dec.candidates_text()
                );
            }
        }
        out.push((class.to_string(), fits.len(), covered, size, bad));
    }
    out
}

#[test]
#[ignore]
fn debug_oxide_coverage() {
    let film = std::env::var("POLARID_DBG_FILM").map_or(3.0, |v| v.parse().unwrap());
    let cfg = FitConfig {
        film_sd_nm: film,
        ..FitConfig::default()
    };
    for (class, n, cov, size, bad) in oxide_coverage(100, 1, &cfg, true, true) {
        eprintln!(
            "{class}: {cov}/{n} covered, mean set size {:.2}, not ok {bad}",
            size as f64 / n as f64
        );
    }
}

#[test]
fn oxides_angle_offsets_and_extinction_truth_in_the_95_set() {
    let cfg = FitConfig::default();
    let (mut n, mut covered) = (0, 0);
    for (class, m, cov, size, bad) in oxide_coverage(60, 7, &cfg, true, false) {
        eprintln!(
            "{class}: truth in the 95% set {cov}/{m}, mean set size {:.2}, not ok {bad}",
            size as f64 / m as f64
        );
        n += m;
        covered += cov;
    }
    let rate = covered as f64 / n as f64;
    eprintln!("all: {covered}/{n} = {rate:.3}");
    assert!(rate >= 0.95, "truth in the 95% set for {rate}");
}

/// A classifier of the built-in library with the set rule at 95%.
fn set_classifier() -> Classifier {
    Classifier::new(library(), ClassifierConfig::set(0.95)).unwrap()
}

#[test]
fn thick_films_whose_aolp_flips_are_model_mismatch() {
    let cfg = FitConfig::default();
    let clf = set_classifier();
    let lib = library();
    let mut rng = Rng(31);
    // Oxides of 80–1500 nm on silicon and aluminium, TiO2 on glass.
    let stacks = [
        ("silicon", (1.46, 0.0)),
        ("aluminum", (1.65, 0.0)),
        ("N-BK7", (2.4, 0.0)),
    ];
    let theta_i: Vec<f64> = THETA_I.iter().map(|d| d.to_radians()).collect();
    let (mut flips, mut flagged, mut classified) = (0, 0, 0);
    let mut rows = Vec::new();
    let mut flipped = Vec::new();
    for t in 0..360 {
        let (class, film) = stacks[t % 3];
        let p = proto(&lib, class);
        let target = ImperfectTarget {
            surface: Surface::Film {
                substrate: (p.n, p.k),
                film,
                thickness_nm: 80.0 + 1420.0 * rng.uniform_co(),
            },
            sigma: 0.1 + 0.2 * rng.uniform_co(),
            rho_d: 0.0,
        };
        let sim = simulate_target(
            &target,
            &theta_i,
            THETA_R.to_radians(),
            &realistic(0.3),
            5_000 + t as u64,
        )
        .unwrap();
        flipped.push(sim.iter().any(|r| r.dolp_true_signed < -0.02));
        rows.extend(measurements(&format!("film_{t}"), &sim, true));
    }
    for (f, &flip) in fit_rows(&rows, &cfg).iter().zip(&flipped) {
        if !flip {
            continue;
        }
        flips += 1;
        flagged += usize::from(f.status == FitStatus::ModelMismatch);
        let dec = clf.classify(&estimate_of(f));
        classified += usize::from(dec.predicted != "unknown" && dec.predicted != "ambiguous");
    }
    let rate = flagged as f64 / flips as f64;
    eprintln!(
        "films whose AoLP flips: {flagged}/{flips} model_mismatch ({rate:.3}); classified {classified}"
    );
    assert!(flips >= 100, "{flips}");
    assert!(rate >= 0.9, "{rate}");
    assert_eq!(classified, 0);
}

#[test]
fn diffusers_with_known_brightness_are_never_classified() {
    let cfg = FitConfig::default();
    let clf = set_classifier();
    let mut rng = Rng(47);
    let theta_i: Vec<f64> = THETA_I.iter().map(|d| d.to_radians()).collect();
    let mut rows = Vec::new();
    let count = 200;
    for t in 0..count {
        let d0 = 0.01 + 0.02 * rng.uniform_co();
        let target = ImperfectTarget {
            surface: Surface::Diffuser {
                albedo: 0.3 + 0.69 * rng.uniform_co(),
                dolp_0: d0,
                dolp_90: d0 + (0.06 - d0) * rng.uniform_co(),
                parallel: t % 2 == 0,
            },
            sigma: 0.0,
            rho_d: 0.0,
        };
        let sim = simulate_target(
            &target,
            &theta_i,
            THETA_R.to_radians(),
            &realistic(0.3),
            9_000 + t as u64,
        )
        .unwrap();
        rows.extend(measurements(&format!("diffuser_{t}"), &sim, true));
    }
    let fits = fit_rows(&rows, &cfg);
    let mut by_status = std::collections::BTreeMap::new();
    let mut classified = 0;
    for f in &fits {
        *by_status.entry(f.status.as_str()).or_insert(0) += 1;
        let dec = clf.classify(&estimate_of(f));
        if dec.predicted != "unknown" || !dec.candidates.is_empty() && f.status.is_ok() {
            classified += 1;
            eprintln!(
                "classified: {} {} {} {:?}",
                f.target,
                f.status.as_str(),
                f.reason,
                dec.candidates_text()
            );
        }
    }
    eprintln!("diffusers: {count}, statuses {by_status:?}, classified {classified}");
    assert_eq!(fits.len(), count);
    assert_eq!(classified, 0);
    assert!(fits.iter().all(|f| !f.status.is_ok()));
    // Without the brightness the same data would be fitted as specular surfaces.
    let no_check = FitConfig {
        brightness_check: false,
        ..cfg
    };
    let spec_ok = fit_rows(&rows, &no_check)
        .iter()
        .filter(|f| f.status.is_ok())
        .count();
    eprintln!("without the brightness check: {spec_ok} of {count} fitted ok");
}

#[test]
fn rows_without_brightness_are_fitted_exactly_as_before() {
    let lib = library();
    let theta_i: Vec<f64> = THETA_I.iter().map(|d| d.to_radians()).collect();
    let mut with = Vec::new();
    for (i, class) in ["gold", "silicon", "copper"].iter().enumerate() {
        let p = proto(&lib, class);
        let target = ImperfectTarget {
            surface: Surface::Bare { n: p.n, k: p.k },
            sigma: 0.2,
            rho_d: 0.3,
        };
        let sim = simulate_target(
            &target,
            &theta_i,
            THETA_R.to_radians(),
            &realistic(0.3),
            i as u64,
        )
        .unwrap();
        with.extend(measurements(class, &sim, true));
    }
    let without: Vec<Measurement> = with
        .iter()
        .map(|m| Measurement {
            s0: None,
            exposure: None,
            ..m.clone()
        })
        .collect();
    let off = FitConfig {
        brightness_check: false,
        ..FitConfig::default()
    };
    let a = fit_rows(&without, &FitConfig::default());
    let b = fit_rows(&without, &off);
    assert_eq!(a, b);
    // With the brightness the diffuse part is seen: the mixed model is selected.
    let c = fit_rows(&with, &FitConfig::default());
    for f in &c {
        assert_eq!(f.model, "mixed", "{f:?}");
        assert!(f.n_se >= f.n_se_noise.unwrap() && f.k_se >= f.k_se_noise.unwrap());
    }
    assert_eq!(fit_rows(&with, &off), b);
}
