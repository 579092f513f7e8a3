//! Issue 16's acceptance on real held-out measurements, checked on faithful proxies of
//! them (the real files are kept outside the repository and run by someone else with the
//! defaults; nothing here is tuned to them). Five targets, each at 500, 650 and 800 nm,
//! in the measurements CSV a user would write when converting an ellipsometer's Ψ/Δ or a
//! Mueller BRDF into polarid's format, with and without the optional columns:
//!
//! - **silicon**: a wafer with a 1–3 nm native oxide (SiO₂), ellipsometer angles of
//!   incidence 45–75° (β = θi), the goniometer off by up to ±0.1°;
//! - **glass**: a glass substrate (N-BK7, n ≈ 1.52) with 0–2 nm of adsorbed hydrocarbons;
//! - **LSAT**: a crystal of n ≈ 2.02 (a dielectric absent from the library);
//! - **oxide**: 100–300 nm of SiO₂ on silicon (a coating: its polarization is parallel to
//!   the plane of incidence at some angles);
//! - **PTFE**: sintered PTFE seen as a Mueller BRDF (in-plane, θi 30–60°, θr −75…75°): a
//!   white diffuser, not quite Lambertian (a forward-scattering lobe, darkening at grazing
//!   view), DoLP 0.01–0.06, brightness known.
//!
//! Literature indices: the repository's copies of the refractiveindex.info files
//! (`data/materials/refractiveindex`: Si Aspnes, SiO₂ Malitson, N-BK7 Schott). Ellipsometer
//! DoLP: `cos 2Ψ = (Rs − Rp)/(Rs + Rp)` with unpolarized light (the signed DoLP of
//! `polarid_core::film`); Ψ's noise 0.02° → `dolp_se = 2 sin 2Ψ σ_Ψ`.
//!
//! Variants of each file: `full` (geometry, `dolp_se`, `wavelength_nm`, `aolp_poi_deg`,
//! `angle_sd_deg` 0.1 for the ellipsometer; `s0` and `exposure` for the BRDF), `band`
//! (`beta_deg`, `dolp`, `dolp_se`, `wavelength_nm`), `se` (`beta_deg`, `dolp`, `dolp_se`)
//! and `bare` (`beta_deg`, `dolp`).
//!
//! Expectations (issue 16): silicon → silicon, or ambiguous with silicon among the
//! candidates; glass → a dielectric; LSAT → unknown or a dielectric, never a metal or
//! semiconductor; oxide → never a metal, and not classified where its AoLP flips; PTFE →
//! no class. All with `polarid fit` and `polarid classify --library builtin` defaults.

use crate::common;

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use common::{polarid_in, text};
use polarid_core::film::thin_film;
use polarid_io::library::RiiData;
use polarid_testkit::Rng;

const WAVELENGTHS: [f64; 3] = [500.0, 650.0, 800.0];
const AOI: [f64; 7] = [45.0, 50.0, 55.0, 60.0, 65.0, 70.0, 75.0];
const KINDS: [&str; 5] = ["silicon", "glass", "lsat", "oxide", "ptfe"];
const VARIANTS: [&str; 4] = ["full", "band", "se", "bare"];

/// One row of a proxy measurements file.
#[derive(Debug, Clone)]
struct Row {
    theta_i: f64,
    theta_r: f64,
    phi: f64,
    beta: f64,
    /// The signed DoLP as measured (< 0: parallel to the plane of incidence).
    signed: f64,
    dolp_se: f64,
    s0: Option<f64>,
}

/// One proxy target.
struct Proxy {
    name: String,
    kind: &'static str,
    wavelength_nm: f64,
    /// Angle uncertainty the instrument states (`full` variant).
    angle_sd_deg: Option<f64>,
    rows: Vec<Row>,
}

impl Proxy {
    /// Some row's polarization is parallel to the plane of incidence (the AoLP flips).
    fn flips(&self) -> bool {
        self.rows.iter().any(|r| r.signed < 0.0)
    }
}

fn rii(rel: &str) -> RiiData {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/materials/refractiveindex")
        .join(rel);
    RiiData::read(&p).expect("read refractiveindex file")
}

struct Indices {
    si: RiiData,
    sio2: RiiData,
    bk7: RiiData,
}

impl Indices {
    fn load() -> Self {
        Self {
            si: rii("main/Si/nk/Aspnes.yml"),
            sio2: rii("main/SiO2/nk/Malitson.yml"),
            bk7: rii("specs/schott/optical/N-BK7.yml"),
        }
    }
    fn at(d: &RiiData, wl: f64) -> (f64, f64) {
        d.nk(wl / 1000.0).expect("index in range")
    }
}

/// LSAT: n ≈ 2.02 at 650 nm, a Cauchy dispersion, transparent.
fn lsat_n(wl: f64) -> f64 {
    let l = wl / 1000.0;
    1.99 + 0.012 / (l * l)
}

/// An ellipsometer target: a film stack seen at the angles of incidence `AOI` with a
/// goniometer offset (common to the target) up to ±0.1°, Ψ noise 0.02°.
fn ellipsometer(
    rng: &mut Rng,
    substrate: (f64, f64),
    film: (f64, f64),
    thickness_nm: f64,
    wl: f64,
) -> Vec<Row> {
    let offset = rng.range(-0.1, 0.1);
    let sd_psi = 0.02f64.to_radians();
    AOI.iter()
        .map(|&a| {
            let b = (a + offset + 0.01 * rng.normal_co()).to_radians();
            let p = thin_film(film, thickness_nm, substrate, b, wl)
                .expect("film")
                .signed_dolp();
            // cos 2Ψ = p; Ψ measured with noise σ_Ψ.
            let psi = 0.5 * p.clamp(-1.0, 1.0).acos() + sd_psi * rng.normal_co();
            let se = (2.0 * (2.0 * psi).sin().abs() * sd_psi).max(1e-5);
            Row {
                theta_i: a,
                theta_r: a,
                phi: 180.0,
                beta: a,
                signed: (2.0 * psi).cos(),
                dolp_se: se,
                s0: None,
            }
        })
        .collect()
}

/// β of an in-plane geometry (eq. 5): half the angle between the source and camera
/// directions; `theta_r < 0` is the camera on the source's side (φ = 0).
fn beta_in_plane(ti: f64, tr: f64) -> f64 {
    // Source at azimuth 0 with zenith ti; camera at azimuth 180 (tr >= 0) with zenith |tr|.
    let (ti, tr) = (ti.to_radians(), tr.to_radians());
    let s = [ti.sin(), 0.0, ti.cos()];
    let v = [-tr.sin(), 0.0, tr.cos()];
    let c = (s[0] * v[0] + s[1] * v[1] + s[2] * v[2]).clamp(-1.0, 1.0);
    0.5 * c.acos().to_degrees()
}

/// Sintered PTFE as a Mueller BRDF: brightness `ρ/π (1 + a exp(−g²/2w²)) (1 − c (1 − cos θr))`
/// (g: angle from the specular direction), DoLP `d0 + (d1 − d0) sin²β` (0.01–0.06), the
/// polarization perpendicular or parallel to the plane of incidence, DoLP noise 0.003,
/// BRDF noise 1%.
fn ptfe(rng: &mut Rng) -> Vec<Row> {
    let rho = rng.range(0.95, 0.99);
    let a = rng.range(0.05, 0.4);
    let w = rng.range(20.0, 40.0);
    let c = rng.range(0.0, 0.15);
    let d0 = rng.range(0.005, 0.015);
    let d1 = rng.range(0.05, 0.08);
    let parallel = rng.uniform_co() < 0.5;
    let mut rows = Vec::new();
    for ti in [30.0, 45.0, 60.0] {
        for k in 0..11 {
            let tr = -75.0 + 15.0 * k as f64;
            if (tr + ti).abs() < 10.0 {
                continue; // the detector would block the source
            }
            let beta = beta_in_plane(ti, tr);
            let g = tr - ti;
            let f = rho / std::f64::consts::PI
                * (1.0 + a * (-(g * g) / (2.0 * w * w)).exp())
                * (1.0 - c * (1.0 - tr.to_radians().cos()));
            let s0 = f * ti.to_radians().cos() * (1.0 + 0.01 * rng.normal_co());
            let d = d0 + (d1 - d0) * beta.to_radians().sin().powi(2);
            let se = 0.003;
            let q = d + se * rng.normal_co();
            let u = se * rng.normal_co();
            let mag = (q * q + u * u).sqrt();
            rows.push(Row {
                theta_i: ti,
                theta_r: tr.abs(),
                phi: if tr >= 0.0 { 180.0 } else { 0.0 },
                beta,
                signed: if parallel { -mag } else { mag },
                dolp_se: se,
                s0: Some(s0),
            });
        }
    }
    rows
}

/// The five proxies at one wavelength for one seed.
fn proxies(idx: &Indices, wl: f64, seed: u64) -> Vec<Proxy> {
    let mut rng = Rng(seed.wrapping_mul(0x1000_0001) ^ wl as u64);
    let si = Indices::at(&idx.si, wl);
    let sio2 = Indices::at(&idx.sio2, wl);
    let bk7 = Indices::at(&idx.bk7, wl);
    let mut out = Vec::new();
    let mut push = |kind: &'static str, sd: Option<f64>, rows: Vec<Row>| {
        out.push(Proxy {
            name: format!("{kind}_{}_s{seed}", wl as u64),
            kind,
            wavelength_nm: wl,
            angle_sd_deg: sd,
            rows,
        })
    };
    let d = rng.range(1.0, 3.0);
    push(
        "silicon",
        Some(0.1),
        ellipsometer(&mut rng, si, sio2, d, wl),
    );
    let d = rng.range(0.0, 2.0);
    push(
        "glass",
        Some(0.1),
        ellipsometer(&mut rng, bk7, (1.5, 0.0), d, wl),
    );
    let d = rng.range(0.0, 2.0);
    push(
        "lsat",
        Some(0.1),
        ellipsometer(&mut rng, (lsat_n(wl), 0.0), (1.5, 0.0), d, wl),
    );
    let d = rng.range(100.0, 300.0);
    push("oxide", Some(0.1), ellipsometer(&mut rng, si, sio2, d, wl));
    push("ptfe", None, ptfe(&mut rng));
    out
}

/// AoLP from the plane of incidence, degrees in [0, 180): 90 perpendicular, 0 parallel,
/// with the noise of a DoLP `p` of standard error `se`.
fn aolp_poi(rng: &mut Rng, signed: f64, se: f64) -> f64 {
    let base = if signed >= 0.0 { 90.0 } else { 0.0 };
    let sd = (se / (2.0 * signed.abs().max(1e-6))).min(1.0).to_degrees();
    (base + sd * rng.normal_co()).rem_euclid(180.0)
}

/// The measurements CSV of `targets` in `variant`.
fn csv(targets: &[Proxy], variant: &str, seed: u64) -> String {
    let mut rng = Rng(seed ^ 0xA01F);
    let mut s = String::new();
    s.push_str(match variant {
        "full" => {
            "target,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,dolp_se,s0,exposure,\
             wavelength_nm,aolp_poi_deg,angle_sd_deg\n"
        }
        "band" => "target,beta_deg,dolp,dolp_se,wavelength_nm\n",
        "se" => "target,beta_deg,dolp,dolp_se\n",
        _ => "target,beta_deg,dolp\n",
    });
    for t in targets {
        for r in &t.rows {
            let dolp = r.signed.abs().min(1.0);
            match variant {
                "full" => {
                    let (s0, exp) = match r.s0 {
                        Some(v) => (format!("{v}"), "1".to_string()),
                        None => (String::new(), String::new()),
                    };
                    let sd = t.angle_sd_deg.map_or(String::new(), |v| format!("{v}"));
                    writeln!(
                        s,
                        "{},{},{},{},{},{dolp},{},{s0},{exp},{},{},{sd}",
                        t.name,
                        r.theta_i,
                        r.theta_r,
                        r.phi,
                        r.beta,
                        r.dolp_se,
                        t.wavelength_nm,
                        aolp_poi(&mut rng, r.signed, r.dolp_se),
                    )
                }
                "band" => writeln!(
                    s,
                    "{},{},{dolp},{},{}",
                    t.name, r.beta, r.dolp_se, t.wavelength_nm
                ),
                "se" => writeln!(s, "{},{},{dolp},{}", t.name, r.beta, r.dolp_se),
                _ => writeln!(s, "{},{},{dolp}", t.name, r.beta),
            }
            .unwrap();
        }
    }
    s
}

/// One target's answer.
#[derive(Debug, Clone)]
struct Answer {
    fit_status: String,
    predicted: String,
    status: String,
    candidates: Vec<String>,
    category: String,
}

fn read_csv(path: &Path) -> Vec<HashMap<String, String>> {
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(path)
        .expect("open CSV");
    let header: Vec<String> = rdr.headers().unwrap().iter().map(str::to_string).collect();
    rdr.records()
        .map(|r| {
            let r = r.unwrap();
            header
                .iter()
                .cloned()
                .zip(r.iter().map(str::to_string))
                .collect()
        })
        .collect()
}

/// `polarid fit` and `polarid classify --library builtin` with the defaults.
fn run(dir: &Path, measurements: &str) -> HashMap<String, Answer> {
    std::fs::write(dir.join("m.csv"), measurements).unwrap();
    let _ = std::fs::remove_file(dir.join("fits.csv"));
    let _ = std::fs::remove_file(dir.join("cls.csv"));
    let o = polarid_in(dir, &["fit", "m.csv", "-o", "fits.csv"]);
    assert!(o.status.success(), "fit failed: {}", text(&o.stderr));
    let o = polarid_in(
        dir,
        &[
            "classify",
            "fits.csv",
            "--library",
            "builtin",
            "-o",
            "cls.csv",
        ],
    );
    assert!(o.status.success(), "classify failed: {}", text(&o.stderr));
    let fits: HashMap<String, String> = read_csv(&dir.join("fits.csv"))
        .into_iter()
        .map(|r| (r["target"].clone(), r["status"].clone()))
        .collect();
    read_csv(&dir.join("cls.csv"))
        .into_iter()
        .map(|r| {
            let t = r["target"].clone();
            let a = Answer {
                fit_status: fits.get(&t).cloned().unwrap_or_default(),
                predicted: r["predicted"].clone(),
                status: r["status"].clone(),
                candidates: r["candidates"]
                    .split(';')
                    .filter(|c| !c.is_empty())
                    .map(str::to_string)
                    .collect(),
                category: r.get("category").cloned().unwrap_or_default(),
            };
            (t, a)
        })
        .collect()
}

/// The built-in library's categories.
fn categories() -> HashMap<String, String> {
    polarid_io::library::Library::builtin()
        .unwrap()
        .materials
        .into_iter()
        .map(|m| (m.name, m.category.unwrap_or_default()))
        .collect()
}

/// Why `a` fails the expectation for `p` in `variant`, if it does.
///
/// With a wavelength (`full`, `band`) the five expectations hold as stated. Without one
/// (`se`, `bare`) the fits are compared with the built-in library's 650 nm values
/// (docs/CLASSIFY.md "Wavelength"; `classify` warns), so two answers are weaker, never
/// wrong: silicon at 500 or 800 nm may be `unknown` (its index there is not the 650 nm
/// one), and glass's set may add acetylene soot (1.57 + 0.44i, `other`) to the dielectrics
/// (the surface-layer allowance at 550 nm widens `k`), but never a metal or semiconductor,
/// and a dielectric nearest.
fn problem(p: &Proxy, a: &Answer, cats: &HashMap<String, String>, variant: &str) -> Option<String> {
    let with_wavelength = matches!(variant, "full" | "band");
    let cat = |m: &str| cats.get(m).map(String::as_str).unwrap_or("");
    let named = cats.contains_key(&a.predicted);
    let ambiguous = a.predicted == "ambiguous";
    let classified = named || ambiguous;
    let cands_in = |c: &[&str]| a.candidates.iter().all(|m| c.contains(&cat(m)));
    let ok = match p.kind {
        "silicon" => {
            a.predicted == "silicon"
                || (ambiguous && a.candidates.iter().any(|c| c == "silicon"))
                || (!with_wavelength
                    && p.wavelength_nm != 650.0
                    && a.fit_status == "ok"
                    && a.predicted == "unknown")
        }
        "glass" => {
            (named && cat(&a.predicted) == "dielectric")
                || (ambiguous && a.category == "dielectric")
                || (!with_wavelength
                    && ambiguous
                    && cat(&a.candidates[0]) == "dielectric"
                    && cands_in(&["dielectric", "other"]))
        }
        "lsat" => !classified || cands_in(&["dielectric"]),
        "oxide" => {
            // Never classified where the AoLP flips; never a metal.
            !classified || (!p.flips() && !a.candidates.iter().any(|m| cat(m) == "metal"))
        }
        "ptfe" => !classified,
        _ => unreachable!(),
    };
    (!ok).then(|| format!("{a:?}"))
}

fn short(a: &Answer) -> String {
    if a.fit_status != "ok" {
        return format!("fit {}", a.fit_status);
    }
    match a.predicted.as_str() {
        "ambiguous" => format!("amb[{}]", a.candidates.join(";")),
        "unknown" => format!("unknown({})", a.status),
        p => p.to_string(),
    }
}

/// Run every variant over `seeds`; returns the failures and a table of answers.
fn evaluate(seeds: std::ops::Range<u64>) -> (Vec<String>, String) {
    let idx = Indices::load();
    let cats = categories();
    let tmp = tempfile::tempdir().unwrap();
    let mut targets = Vec::new();
    for seed in seeds {
        for wl in WAVELENGTHS {
            targets.extend(proxies(&idx, wl, seed));
        }
    }
    let mut failures = Vec::new();
    let mut table = String::new();
    for variant in VARIANTS {
        let dir: PathBuf = tmp.path().join(variant);
        std::fs::create_dir_all(&dir).unwrap();
        let answers = run(&dir, &csv(&targets, variant, 1));
        for kind in KINDS {
            for wl in WAVELENGTHS {
                let mut cell = Vec::new();
                for p in targets
                    .iter()
                    .filter(|p| p.kind == kind && p.wavelength_nm == wl)
                {
                    let a = &answers[&p.name];
                    cell.push(short(a));
                    if let Some(why) = problem(p, a, &cats, variant) {
                        failures.push(format!("{variant} {} (flips {}): {why}", p.name, p.flips()));
                    }
                }
                writeln!(table, "{variant:5} {kind:8} {wl:4}: {}", cell.join(" | ")).unwrap();
            }
        }
    }
    (failures, table)
}

#[test]
fn heldout_proxies_meet_the_expectations_with_the_defaults() {
    let (failures, table) = evaluate(0..4);
    eprintln!("{table}");
    assert!(
        failures.is_empty(),
        "{} failure(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Dump the proxies' measurement files (`POLARID_PROXY_DIR`) for inspection.
#[test]
#[ignore]
fn dump_proxies() {
    let dir = PathBuf::from(std::env::var("POLARID_PROXY_DIR").unwrap_or("/tmp/proxies".into()));
    std::fs::create_dir_all(&dir).unwrap();
    let idx = Indices::load();
    let mut targets = Vec::new();
    for seed in 0..4 {
        for wl in WAVELENGTHS {
            targets.extend(proxies(&idx, wl, seed));
        }
    }
    for v in VARIANTS {
        std::fs::write(dir.join(format!("{v}.csv")), csv(&targets, v, 1)).unwrap();
    }
}

/// The built-in library at other wavelengths: its own band kept, other wavelengths from
/// the embedded refractiveindex.info files, uncovered materials named.
#[test]
fn builtin_library_is_evaluated_at_the_fits_wavelengths() {
    use polarid_io::library::Library;
    let lib = Library::builtin().unwrap();
    let (at, uncovered) = lib.at_wavelengths(&[650.2, 800.0, 500.0]).unwrap();
    let row = |name: &str, wl: f64| {
        at.materials
            .iter()
            .find(|m| m.name == name && m.wavelength_nm == Some(wl))
            .unwrap_or_else(|| panic!("{name} at {wl}"))
            .clone()
    };
    let si650 = lib.materials.iter().find(|m| m.name == "silicon").unwrap();
    assert_eq!(row("silicon", 650.0).n, si650.n);
    assert_eq!(row("silicon", 650.0).k, si650.k);
    let idx = Indices::load();
    for wl in [500.0, 800.0] {
        let (n, k) = Indices::at(&idx.si, wl);
        let r = row("silicon", wl);
        assert_eq!((r.n, r.k), (n, k));
        assert_eq!(r.category.as_deref(), Some("semiconductor"));
    }
    assert!((row("silicon", 800.0).n - 3.68).abs() < 0.02);
    assert!((row("silicon", 500.0).n - 4.29).abs() < 0.02);
    // PDMS's data end at 700 nm: left out at 800 nm, and named.
    assert!(
        uncovered
            .iter()
            .any(|u| u.wavelength_nm == 800.0 && u.names == ["PDMS_silicone_Sylgard184"]),
        "{uncovered:?}"
    );
    assert_eq!(uncovered.len(), 1, "{uncovered:?}");
    // Other libraries are left as they are.
    let p = Library::paper_2007().unwrap();
    assert_eq!(p.at_wavelengths(&[800.0]).unwrap().0, p);
}

/// The surface-layer allowance uses each row's own wavelength: rows at 800 nm give the
/// errors of rows without one fitted with `--wavelength-nm 800`, and smaller ones than at
/// the 550 nm default.
#[test]
fn film_allowance_uses_each_rows_wavelength() {
    use polarid_io::table::measurements::Measurement;
    use polarid_pipeline::fit::{FitConfig, fit};
    let idx = Indices::load();
    let si = Indices::at(&idx.si, 800.0);
    let rows = |wl: Option<f64>| -> Vec<(u64, Measurement)> {
        AOI.iter()
            .enumerate()
            .map(|(i, &a)| {
                let p = polarid_core::dop::dop(si.0, si.1, a.to_radians());
                (
                    i as u64 + 2,
                    Measurement {
                        target: "si".into(),
                        beta_deg: a,
                        dolp: p,
                        dolp_se: Some(2e-4),
                        wavelength_nm: wl,
                        ..Default::default()
                    },
                )
            })
            .collect()
    };
    let silent = |_: &str, _: u64, _: u64| {};
    let path = Path::new("m.csv");
    let own = fit(path, &rows(Some(800.0)), &FitConfig::default(), &silent)
        .unwrap()
        .rows();
    let cfg800 = FitConfig {
        wavelength_nm: 800.0,
        ..FitConfig::default()
    };
    let opt = fit(path, &rows(None), &cfg800, &silent).unwrap().rows();
    let dflt = fit(path, &rows(None), &FitConfig::default(), &silent)
        .unwrap()
        .rows();
    assert_eq!((own[0].n_se, own[0].k_se), (opt[0].n_se, opt[0].k_se));
    assert!(
        own[0].n_se < dflt[0].n_se,
        "{} {}",
        own[0].n_se,
        dflt[0].n_se
    );
}

/// `classify --wavelength-nm` gives fits without a wavelength theirs; without it they are
/// compared at 650 nm with a warning.
#[test]
fn classify_wavelength_option_and_warning() {
    let idx = Indices::load();
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let targets: Vec<Proxy> = (0..3)
        .flat_map(|s| proxies(&idx, 800.0, 100 + s))
        .filter(|p| p.kind == "silicon")
        .collect();
    std::fs::write(d.join("m.csv"), csv(&targets, "se", 1)).unwrap();
    let o = polarid_in(d, &["fit", "m.csv", "-o", "fits.csv"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = polarid_in(
        d,
        &[
            "classify",
            "fits.csv",
            "--library",
            "builtin",
            "-o",
            "a.csv",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(err.contains("carry no wavelength_nm"), "{err}");
    for r in read_csv(&d.join("a.csv")) {
        assert_eq!(r["predicted"], "unknown", "{r:?}");
    }
    let o = polarid_in(
        d,
        &[
            "classify",
            "fits.csv",
            "--library",
            "builtin",
            "--wavelength-nm",
            "800",
            "-o",
            "b.csv",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(err.contains("evaluated at 800 nm"), "{err}");
    assert!(err.contains("PDMS_silicone_Sylgard184"), "{err}");
    for r in read_csv(&d.join("b.csv")) {
        assert!(r["candidates"].split(';').any(|c| c == "silicon"), "{r:?}");
    }
}
