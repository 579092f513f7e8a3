//! The fit's choices a user can rely on: `--reflectance auto` (the default) applies the
//! brightness check, an explicit `specular` is obeyed; an estimate whose standard error
//! is wider than its search box is `ill_conditioned`, and `train` can refuse labelled
//! fits that are not `ok`.

use std::path::Path;

use polarid_core::FitStatus;
use polarid_core::dop::dop;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;
use polarid_pipeline::fit::{self, FitConfig, MAX_SE_BOX_FRACTION, Reflectance};
use polarid_pipeline::progress::no_progress;
use polarid_pipeline::train;

const THETA_R: f64 = 60.0;
const THETA_I: [f64; 6] = [30.0, 40.0, 50.0, 60.0, 70.0, 80.0];

/// In-plane rows (φ = 180°, β = (θi + θr)/2) of a target of index (n, k), with the
/// brightness `s0` of a Lambertian surface (∝ cos θi) and exposure 1, each with the
/// standard error `se`.
fn lambertian_target(n: f64, k: f64, se: f64) -> Vec<(u64, Measurement)> {
    THETA_I
        .iter()
        .enumerate()
        .map(|(i, &ti)| {
            let beta = 0.5 * (ti + THETA_R);
            (
                i as u64 + 2,
                Measurement {
                    target: "plate".into(),
                    class: Some("aluminum".into()),
                    theta_i_deg: Some(ti),
                    theta_r_deg: Some(THETA_R),
                    phi_deg: 180.0,
                    beta_deg: beta,
                    dolp: dop(n, k, beta.to_radians()),
                    dolp_se: Some(se),
                    s0: Some(1000.0 * ti.to_radians().cos()),
                    exposure: Some(1.0),
                    ..Default::default()
                },
            )
        })
        .collect()
}

fn fit_with(rows: &[(u64, Measurement)], reflectance: Reflectance) -> FitRow {
    let cfg = FitConfig {
        reflectance,
        ..FitConfig::default()
    };
    let out = fit::fit(Path::new("m.csv"), rows, &cfg, &no_progress).unwrap();
    out.rows().remove(0)
}

#[test]
fn auto_is_the_default_and_an_explicit_specular_is_obeyed() {
    assert_eq!(FitConfig::default().reflectance, Reflectance::Auto);
    assert_eq!(Reflectance::parse("auto"), Some(Reflectance::Auto));
    let rows = lambertian_target(1.24, 6.6, 0.002);
    // auto: s0 follows Lambert's cosine law exactly, so the brightness check says the
    // target shows no specular lobe.
    let auto = fit_with(&rows, Reflectance::Auto);
    assert_eq!(auto.status, FitStatus::Depolarized, "{}", auto.reason);
    assert!(auto.reason.starts_with("brightness"), "{}", auto.reason);
    // specular, asked for: the DoLP-only fit and nothing else.
    let spec = fit_with(&rows, Reflectance::Specular);
    assert_eq!(spec.model, "specular");
    assert!(!spec.reason.contains("brightness"), "{}", spec.reason);
    assert_ne!(spec.status, FitStatus::Depolarized, "{}", spec.reason);
    assert!(
        (spec.n - 1.24).abs() < 1e-3 && (spec.k - 6.6).abs() < 1e-2,
        "{spec:?}"
    );
    // Without brightness auto is the specular fit.
    let mut dark = rows.clone();
    for (_, m) in &mut dark {
        m.s0 = None;
    }
    let a = fit_with(&dark, Reflectance::Auto);
    let s = fit_with(&dark, Reflectance::Specular);
    assert_eq!((a.n, a.k, a.status), (s.n, s.k, s.status));
}

#[test]
fn an_estimate_wider_than_its_box_is_ill_conditioned() {
    let cfg = FitConfig {
        reflectance: Reflectance::Specular,
        ..FitConfig::default()
    };
    let bound_n = MAX_SE_BOX_FRACTION * (cfg.n_range.1 - cfg.n_range.0);
    let bound_k = MAX_SE_BOX_FRACTION * (cfg.k_range.1 - cfg.k_range.0);
    // Precise data: ok, errors well inside the bound.
    let good = fit_with(&lambertian_target(1.24, 6.6, 0.002), Reflectance::Specular);
    assert_eq!(good.status, FitStatus::Ok, "{}", good.reason);
    assert!(good.n_se < bound_n && good.k_se < bound_k, "{good:?}");
    // The same plate with DoLP errors of 0.3: the fit lands on the data, but its
    // standard errors are several search boxes wide.
    let vague = fit_with(&lambertian_target(1.24, 6.6, 0.3), Reflectance::Specular);
    assert!(
        vague.n_se > bound_n || vague.k_se > bound_k,
        "n_se {} k_se {}",
        vague.n_se,
        vague.k_se
    );
    assert_eq!(vague.status, FitStatus::IllConditioned, "{}", vague.reason);
    assert!(
        vague.reason.contains("times the width of the search box"),
        "{}",
        vague.reason
    );
}

#[test]
fn train_can_refuse_labelled_fits_that_are_not_ok() {
    let ok = FitRow {
        target: "al1".into(),
        class: Some("aluminum".into()),
        n: 1.2,
        k: 7.0,
        n_se: 0.1,
        k_se: 0.2,
        nk_corr: 0.5,
        status: FitStatus::Ok,
        ..FitRow::default()
    };
    let bad = FitRow {
        target: "al2".into(),
        n: 5.56,
        k: 13.9,
        n_se: 44.0,
        k_se: 25.0,
        status: FitStatus::IllConditioned,
        ..ok.clone()
    };
    let unlabelled = FitRow {
        target: "x".into(),
        class: None,
        status: FitStatus::AtBound,
        ..ok.clone()
    };
    let fits = vec![(2, ok.clone()), (3, bad), (4, unlabelled)];
    let e = train::refuse_not_ok(&fits, Path::new("fits.csv"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("fits.csv: 1 labelled fit(s) are not `ok`")
            && e.contains("al2 (ill_conditioned, line 3)")
            && e.contains("--allow-not-ok")
            && !e.contains("x (at_bound"),
        "{e}"
    );
    assert!(train::refuse_not_ok(&fits[..1], Path::new("fits.csv")).is_ok());
    // Allowed: the others train, the bad one is skipped with a warning.
    let t = train::train(&fits, Path::new("fits.csv"), "fits.csv").unwrap();
    assert_eq!(t.model.prototypes.len(), 1);
    assert_eq!(t.warnings.len(), 1);
}
