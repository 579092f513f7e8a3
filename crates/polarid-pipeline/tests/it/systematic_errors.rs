//! The error model of `fit` (docs/ERRORS.md), measured over many seeds: coverage of the
//! 95% confidence region with realistic systematics, the sandwich covariance against a
//! Monte Carlo over systematic draws, and the model checks' false-alarm and detection
//! rates.

use std::path::Path;

use polarid_core::FitStatus;
use polarid_core::dop::dop;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;
use polarid_pipeline::fit::{FitConfig, fit};
use polarid_testkit::Rng;

/// Absorbing materials (gold and copper at 450 nm, copper at 650 nm, an absorbing
/// semiconductor). Aluminium (1.2 + 7.0i) is left out of the coverage claim: with six
/// captures and DoLP noise 1e-3 its `k` is so poorly determined that the linearised
/// covariance fails with the noise alone (40% coverage; `debug_coverage_by_material`).
const MATERIALS: [(f64, f64); 4] = [(1.38, 1.92), (1.01, 2.58), (0.27, 3.4), (3.0, 1.0)];
/// Source zeniths of the captures; the camera at 45°, in the plane of incidence.
const THETA_I: [f64; 6] = [20.0, 30.0, 40.0, 50.0, 60.0, 70.0];
const THETA_R: f64 = 45.0;

fn silent(_: &str, _: u64, _: u64) {}

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

/// `(d/σ)ᵀ C⁻¹ (d/σ)` of the error `(n̂ − n, k̂ − k)` with standard errors and correlation.
fn mahalanobis(dn: f64, dk: f64, n_se: f64, k_se: f64, r: f64) -> f64 {
    let (a, b) = (dn / n_se, dk / k_se);
    (a * a - 2.0 * r * a * b + b * b) / (1.0 - r * r)
}

/// One target's rows with realistic systematics: uniform angle offsets up to `max_off`
/// degrees (camera per target, source per capture), an analyzer of extinction ratio
/// `er`, Gaussian noise `se`. The rows carry only `dolp_se` (no `angle_sd_deg`).
fn realistic(
    rng: &mut Rng,
    name: &str,
    (n, k): (f64, f64),
    max_off: f64,
    er: f64,
    se: f64,
) -> Vec<Measurement> {
    let cam = (2.0 * rng.uniform_co() - 1.0) * max_off;
    let scale = if er.is_finite() {
        (er - 1.0) / (er + 1.0)
    } else {
        1.0
    };
    THETA_I
        .iter()
        .map(|&ti| {
            let src = (2.0 * rng.uniform_co() - 1.0) * max_off;
            let beta_true = (0.5 * (ti + src + THETA_R + cam)).to_radians();
            let dolp = (scale * dop(n, k, beta_true) + se * rng.normal_co()).clamp(0.0, 1.0);
            Measurement {
                target: name.into(),
                theta_i_deg: Some(ti),
                theta_r_deg: Some(THETA_R),
                phi_deg: 180.0,
                beta_deg: 0.5 * (ti + THETA_R),
                dolp,
                dolp_se: Some(se),
                ..Default::default()
            }
        })
        .collect()
}

/// Coverage per material and systematic (run with `--ignored --nocapture`).
#[test]
#[ignore]
fn debug_coverage_by_material() {
    let cfg = FitConfig::default();
    for (off, er) in [
        (0.0, f64::INFINITY),
        (0.3, f64::INFINITY),
        (0.0, 300.0),
        (0.3, 300.0),
    ] {
        for (i, &nk) in MATERIALS.iter().chain(&[(1.2, 7.0)]).enumerate() {
            let mut rng = Rng(7 + i as u64);
            let mut rows = Vec::new();
            for seed in 0..300 {
                rows.extend(realistic(&mut rng, &format!("t{seed}"), nk, off, er, 1e-3));
            }
            let fits = fit_rows(&rows, &cfg);
            let cov = fits
                .iter()
                .filter(|f| mahalanobis(f.n - nk.0, f.k - nk.1, f.n_se, f.k_se, f.nk_corr) <= 5.991)
                .count();
            let mn = fits.iter().map(|f| f.n - nk.0).sum::<f64>() / 300.0;
            let mk = fits.iter().map(|f| f.k - nk.1).sum::<f64>() / 300.0;
            eprintln!(
                "off {off} er {er} {nk:?}: {cov}/300 bias n {mn:.2e} k {mk:.2e} se {:.2e} {:.2e} noise {:.2e} {:.2e} statuses {:?}",
                fits[0].n_se,
                fits[0].k_se,
                fits[0].n_se_noise.unwrap(),
                fits[0].k_se_noise.unwrap(),
                fits.iter().filter(|f| !f.status.is_ok()).count()
            );
        }
    }
}

#[test]
fn total_covariance_covers_the_truth_with_realistic_systematics() {
    let cfg = FitConfig::default();
    let (mut total_in, mut noise_in, mut count, mut flagged) = (0, 0, 0, 0);
    let mut rng = Rng(7);
    for seed in 0..150 {
        let mut rows = Vec::new();
        for (i, &nk) in MATERIALS.iter().enumerate() {
            rows.extend(realistic(
                &mut rng,
                &format!("t{seed}_{i}"),
                nk,
                0.3,
                300.0,
                1e-3,
            ));
        }
        for (f, &(n, k)) in fit_rows(&rows, &cfg).iter().zip(&MATERIALS) {
            count += 1;
            if f.status == FitStatus::ModelMismatch {
                flagged += 1;
            }
            let (dn, dk) = (f.n - n, f.k - k);
            if mahalanobis(dn, dk, f.n_se, f.k_se, f.nk_corr) <= 5.991 {
                total_in += 1;
            }
            let (a, b, r) = (
                f.n_se_noise.unwrap(),
                f.k_se_noise.unwrap(),
                f.nk_corr_noise.unwrap(),
            );
            if mahalanobis(dn, dk, a, b, r) <= 5.991 {
                noise_in += 1;
            }
        }
    }
    let total = total_in as f64 / count as f64;
    let noise = noise_in as f64 / count as f64;
    eprintln!(
        "coverage of the 95% region over {count} targets: total {total:.3}, noise only {noise:.3}; model_mismatch {flagged}"
    );
    assert!(total >= 0.95, "total covariance covers {total}");
    assert!(noise < 0.6, "noise-only covariance covers {noise}");
    assert!(
        (flagged as f64) < 0.01 * count as f64,
        "{flagged} false alarms"
    );
}

/// Rows whose systematic errors are drawn from the model itself (Gaussian direction
/// errors of sd `angle_sd`, a Gaussian scale error of sd `u`, a Gaussian floor).
fn model_draw(
    rng: &mut Rng,
    name: &str,
    (n, k): (f64, f64),
    cfg: &FitConfig,
    se: f64,
) -> Vec<Measurement> {
    let sd = cfg.angle_sd_deg;
    let cam = sd * rng.normal_co();
    let eps = cfg.polarimetric().scale_sd() * rng.normal_co();
    THETA_I
        .iter()
        .map(|&ti| {
            let src = sd * rng.normal_co();
            let beta_true = (0.5 * (ti + src + THETA_R + cam)).to_radians();
            let dolp = (1.0 - eps) * dop(n, k, beta_true)
                + cfg.dolp_floor * rng.normal_co()
                + se * rng.normal_co();
            Measurement {
                target: name.into(),
                phi_deg: 180.0,
                beta_deg: 0.5 * (ti + THETA_R),
                dolp: dolp.clamp(0.0, 1.0),
                dolp_se: Some(se),
                ..Default::default()
            }
        })
        .collect()
}

#[test]
fn sandwich_matches_monte_carlo_and_gof_false_alarms_are_nominal() {
    // The draws have no surface layer: the model's film term is left out.
    let cfg = FitConfig {
        mismatch_p: 0.05,
        film_sd_nm: 0.0,
        ..FitConfig::default()
    };
    let mut rng = Rng(11);
    let reps = 1500;
    for &(n, k) in &MATERIALS[..2] {
        let mut rows = Vec::new();
        for r in 0..reps {
            rows.extend(model_draw(&mut rng, &format!("r{r}"), (n, k), &cfg, 1e-3));
        }
        let fits = fit_rows(&rows, &cfg);
        let m = fits.len() as f64;
        let (mn, mk) = (
            fits.iter().map(|f| f.n).sum::<f64>() / m,
            fits.iter().map(|f| f.k).sum::<f64>() / m,
        );
        let vn = fits.iter().map(|f| (f.n - mn).powi(2)).sum::<f64>() / (m - 1.0);
        let vk = fits.iter().map(|f| (f.k - mk).powi(2)).sum::<f64>() / (m - 1.0);
        let cnk = fits.iter().map(|f| (f.n - mn) * (f.k - mk)).sum::<f64>() / (m - 1.0);
        let med = |g: fn(&FitRow) -> f64| {
            let mut v: Vec<f64> = fits.iter().map(g).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (sn, sk, sr) = (med(|f| f.n_se), med(|f| f.k_se), med(|f| f.nk_corr));
        let rho = cnk / (vn * vk).sqrt();
        let alarms = fits
            .iter()
            .filter(|f| f.status == FitStatus::ModelMismatch)
            .count() as f64
            / m;
        eprintln!(
            "({n}, {k}): MC sd n {:.3e} k {:.3e} corr {rho:.3}; sandwich n {sn:.3e} k {sk:.3e} corr {sr:.3}; gof alarms at p<0.05: {alarms:.3}",
            vn.sqrt(),
            vk.sqrt()
        );
        // 1500 draws: the sd of a sample sd is ~1.8%.
        assert!(
            (vn.sqrt() / sn - 1.0).abs() < 0.08,
            "n: {} vs {sn}",
            vn.sqrt()
        );
        assert!(
            (vk.sqrt() / sk - 1.0).abs() < 0.08,
            "k: {} vs {sk}",
            vk.sqrt()
        );
        assert!((rho - sr).abs() < 0.05, "corr {rho} vs {sr}");
        // Binomial sd of the rate at 5%: 0.56%.
        assert!((0.035..0.068).contains(&alarms), "false alarms {alarms}");
    }
}

/// A minimal complex number (the test has no complex-number dependency).
#[derive(Clone, Copy)]
struct C(f64, f64);

impl C {
    fn new(re: f64, im: f64) -> Self {
        C(re, im)
    }
    fn norm_sqr(self) -> f64 {
        self.0 * self.0 + self.1 * self.1
    }
    fn sqrt(self) -> Self {
        let r = self.norm_sqr().sqrt();
        let re = ((r + self.0) / 2.0).max(0.0).sqrt();
        let im = ((r - self.0) / 2.0).max(0.0).sqrt().copysign(self.1);
        C(re, im)
    }
    fn exp(self) -> Self {
        let e = self.0.exp();
        C(e * self.1.cos(), e * self.1.sin())
    }
}

impl std::ops::Add for C {
    type Output = C;
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
}
impl std::ops::Sub for C {
    type Output = C;
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
}
impl std::ops::Mul for C {
    type Output = C;
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
}
impl std::ops::Div for C {
    type Output = C;
    fn div(self, o: C) -> C {
        let d = o.norm_sqr();
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
}

/// Signed DoLP `(Rs − Rp)/(Rs + Rp)` of a single film (index `nf`, thickness `d` in
/// wavelengths) on a substrate `(n, k)`, at incidence `beta` (radians), from air.
fn film_dolp(nf: f64, d: f64, (n, k): (f64, f64), beta: f64) -> f64 {
    let n0 = C::new(1.0, 0.0);
    let n1 = C::new(nf, 0.0);
    let n2 = C::new(n, k);
    let s0 = C::new(beta.sin(), 0.0);
    let cos = |ni: C| (C::new(1.0, 0.0) - (s0 * n0 / ni) * (s0 * n0 / ni)).sqrt();
    let (c0, c1, c2) = (cos(n0), cos(n1), cos(n2));
    let rs = |a: C, ca: C, b: C, cb: C| (a * ca - b * cb) / (a * ca + b * cb);
    let rp = |a: C, ca: C, b: C, cb: C| (b * ca - a * cb) / (b * ca + a * cb);
    let phase = (C::new(0.0, 2.0) * C::new(std::f64::consts::TAU * d, 0.0) * n1 * c1).exp();
    let total = |r01: C, r12: C| (r01 + r12 * phase) / (C::new(1.0, 0.0) + r01 * r12 * phase);
    let s = total(rs(n0, c0, n1, c1), rs(n1, c1, n2, c2)).norm_sqr();
    let p = total(rp(n0, c0, n1, c1), rp(n1, c1, n2, c2)).norm_sqr();
    (s - p) / (s + p)
}

#[test]
fn films_whose_aolp_flips_are_model_mismatch() {
    let cfg = FitConfig::default();
    let mut rng = Rng(23);
    let (mut flips, mut caught, mut caught_residuals) = (0, 0, 0);
    let (mut good, mut good_flagged) = (0, 0);
    for seed in 0..300 {
        // SiO2 on silicon, 0.3–3 wavelengths thick; or a bare metal for the false alarms.
        let bare = seed % 3 == 0;
        let d = 0.3 + 2.7 * rng.uniform_co();
        let sub = if bare {
            MATERIALS[seed % 4]
        } else {
            (3.87, 0.016)
        };
        let se = 2e-3;
        let rows: Vec<Measurement> = THETA_I
            .iter()
            .map(|&ti| {
                let beta = (0.5 * (ti + THETA_R)).to_radians();
                let p = if bare {
                    dop(sub.0, sub.1, beta)
                } else {
                    film_dolp(1.46, d, sub, beta)
                };
                let dolp = (p.abs() + se * rng.normal_co()).clamp(0.0, 1.0);
                let aolp_sd = (se / (2.0 * p.abs().max(1e-3))).to_degrees();
                let aolp = if p >= 0.0 { 90.0 } else { 0.0 } + aolp_sd * rng.normal_co();
                Measurement {
                    target: "t".into(),
                    phi_deg: 180.0,
                    beta_deg: beta.to_degrees(),
                    dolp,
                    dolp_se: Some(se),
                    aolp_poi_deg: Some(aolp.rem_euclid(180.0)),
                    ..Default::default()
                }
            })
            .collect();
        let f = &fit_rows(&rows, &cfg)[0];
        let flips_here = !bare
            && THETA_I
                .iter()
                .any(|&ti| film_dolp(1.46, d, sub, (0.5 * (ti + THETA_R)).to_radians()) < -0.02);
        if bare {
            good += 1;
            good_flagged += usize::from(f.status == FitStatus::ModelMismatch);
        } else if flips_here {
            flips += 1;
            if f.status == FitStatus::ModelMismatch || f.aolp_p.is_some_and(|p| p < 1e-3) {
                caught += 1;
            }
            if f.gof_p.is_some_and(|p| p < 1e-3) {
                caught_residuals += 1;
            }
        }
    }
    eprintln!(
        "films with a flipped AoLP: {caught}/{flips} flagged ({caught_residuals} by the residuals alone); bare metals flagged {good_flagged}/{good}"
    );
    assert!(flips >= 50, "{flips}");
    assert!(caught as f64 >= 0.9 * flips as f64);
    assert!(good_flagged as f64 <= 0.02 * good as f64);
}

#[test]
fn angle_sd_deg_in_the_manifest_and_bad_options() {
    let dir = tempfile::tempdir().unwrap();
    for f in ["s0.tif", "s1.tif", "s2.tif"] {
        std::fs::write(dir.path().join(f), b"x").unwrap();
    }
    let path = dir.path().join("m.toml");
    let text = |top: &str, cap: &str| {
        format!(
            "theta_r_deg = 45.0\n{top}\n[[region]]\nname = \"A\"\nrect = [0, 0, 2, 2]\n\n\
             [[capture]]\ntheta_i_deg = 30.0\n{cap}\nstokes = {{ s0 = \"s0.tif\", s1 = \"s1.tif\", s2 = \"s2.tif\" }}\n\n\
             [[capture]]\ntheta_i_deg = 40.0\nstokes = {{ s0 = \"s0.tif\", s1 = \"s1.tif\", s2 = \"s2.tif\" }}\n"
        )
    };
    let m = polarid_io::manifest::parse(&path, &text("angle_sd_deg = 0.3", "angle_sd_deg = 0.05"))
        .unwrap();
    assert_eq!(m.angle_sd_deg, Some(0.3));
    assert_eq!(m.captures[0].angle_sd_deg, Some(0.05));
    assert_eq!(m.captures[1].angle_sd_deg, Some(0.3));
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let none = polarid_io::manifest::parse(&path, &text("", "")).unwrap();
    assert_eq!(none.captures[0].angle_sd_deg, None);
    let e = polarid_io::manifest::parse(&path, &text("", "angle_sd_deg = -0.1"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("capture[1].angle_sd_deg") && e.contains("-0.1"),
        "{e}"
    );
    let e = polarid_io::manifest::parse(&path, &text("angle_sd_deg = nan", ""))
        .unwrap_err()
        .to_string();
    assert!(e.contains("angle_sd_deg"), "{e}");

    for (cfg, word) in [
        (
            FitConfig {
                angle_sd_deg: -1.0,
                ..FitConfig::default()
            },
            "angle_sd_deg",
        ),
        (
            FitConfig {
                dolp_floor: f64::NAN,
                ..FitConfig::default()
            },
            "dolp_floor",
        ),
        (
            FitConfig {
                extinction_ratio: 1.0,
                ..FitConfig::default()
            },
            "extinction_ratio",
        ),
        (
            FitConfig {
                retardance_deg: 91.0,
                ..FitConfig::default()
            },
            "retardance_deg",
        ),
        (
            FitConfig {
                mismatch_p: 1.0,
                ..FitConfig::default()
            },
            "mismatch_p",
        ),
    ] {
        let e = cfg.validate().unwrap_err().to_string();
        assert!(e.starts_with(word) && e.contains("got"), "{e}");
    }
}
