//! `measure` → `fit` on calibrated captures (issue 15, deliverables 2 and 5): on the
//! synthetic bench of `polarid_testkit::calibrated_bench` (perspective camera,
//! lamps at 0.5 m and 0.25 m in and out of the plane of incidence, a specular lobe on
//! each plate), the fit of the measured rows recovers `(n, k)` within 3 reported standard
//! errors for ≥ 99 % of the targets over many seeds; fitting the same rows at the
//! rectangle's centre β without the spread model misses by many standard errors. And
//! out-of-plane far-field captures (φ ≠ 180°) through measure and fit.

use polarid_testkit::calibrated_bench as bench;

use std::path::Path;

use bench::{Clean, Plate, clean_with, lamps_at, load};
use polarid_core::dop::dop;
use polarid_core::geometry;
use polarid_io::manifest::Manifest;
use polarid_io::measure::{measure_images, measure_manifest};
use polarid_io::table::CsvTable;
use polarid_io::table::measurements::{self, Measurement};
use polarid_pipeline::fit::{FitConfig, fit};
use polarid_pipeline::progress::no_progress;

/// Gold and copper at 450 nm, side by side. (Glass, `k = 0`, is left out: at the
/// `k = 0` boundary the fit's `k_se` is a one-sided deviation and `(n, k)` fall outside
/// 3 SE for ~6 % of seeds even with ideal far-field data, a property of the core fit,
/// not of the geometry.)
const PLATES: [Plate; 2] = [
    Plate {
        name: "gold",
        rect: [14, 18, 24, 24],
        n: 1.38,
        k: 1.92,
    },
    Plate {
        name: "copper",
        rect: [44, 18, 22, 24],
        n: 1.01,
        k: 2.58,
    },
];

/// A bench: lamp distance (m), lobe RMS slope (rad), noise gain and read noise (DN).
struct Setup {
    distance: f64,
    sigma: f64,
    gain: f64,
    read: f64,
}

const MILD: Setup = Setup {
    distance: 0.5,
    sigma: 0.2,
    gain: 1.0,
    read: bench::READ_NOISE,
};
const CLOSE: Setup = Setup {
    distance: 0.25,
    sigma: 0.1,
    gain: 0.2,
    read: bench::READ_NOISE,
};

fn prepare(dir: &Path, s: &Setup) -> (Manifest, Vec<Clean>) {
    let lamps = lamps_at(s.distance);
    let m = load(dir, &PLATES, &lamps);
    let cleans = lamps
        .iter()
        .map(|l| clean_with(&m, &PLATES, *l, s.sigma))
        .collect();
    (m, cleans)
}

/// The measurement rows of one seed, with line numbers.
fn measure_seed(m: &Manifest, cleans: &[Clean], s: &Setup, seed: u64) -> Vec<(u64, Measurement)> {
    let mut rows = Vec::new();
    for (j, c) in m.captures.iter().enumerate() {
        let img = bench::noisy_with(&cleans[j], s.gain, s.read, 7919 * seed + j as u64);
        rows.extend(measure_images(m, c, &img).unwrap());
    }
    rows.into_iter()
        .enumerate()
        .map(|(i, r)| (i as u64 + 2, r))
        .collect()
}

/// Largest error of `(n, k)` in reported standard errors, per plate: the noise's
/// (`n_se_noise`, `k_se_noise`; the rendered bench has no systematic error, and the
/// total would hide the geometry models' differences, docs/ERRORS.md).
fn errors_in_se(rows: &[(u64, Measurement)]) -> Vec<f64> {
    let out = fit(
        Path::new("m.csv"),
        rows,
        &FitConfig::default(),
        &no_progress,
    )
    .unwrap();
    PLATES
        .iter()
        .map(|p| {
            let r = out.targets.iter().find(|t| t.row.target == p.name).unwrap();
            let r = &r.row;
            let (n_se, k_se) = (r.n_se_noise.unwrap(), r.k_se_noise.unwrap());
            ((r.n - p.n) / n_se).abs().max(((r.k - p.k) / k_se).abs())
        })
        .collect()
}

/// 150 seeds per bench with `POLARID_FULL=1` (600 fits: at least 99% within 3 SE; 599
/// measured), 50 in the quick suite (200 fits: no more misses than a 99% rate makes with
/// probability 10⁻³, `polarid_testkit::max_misses`: 8).
#[test]
fn measure_then_fit_recovers_nk_within_3_se() {
    let seeds = polarid_testkit::seeds(50, 150);
    let (mut inside, mut total) = (0, 0);
    let mut worst: Vec<f64> = Vec::new();
    for s in [MILD, CLOSE] {
        let d = tempfile::tempdir().unwrap();
        let (m, cleans) = prepare(d.path(), &s);
        for seed in 0..seeds {
            for e in errors_in_se(&measure_seed(&m, &cleans, &s, seed)) {
                inside += usize::from(e < 3.0);
                total += 1;
                worst.push(e);
            }
        }
    }
    worst.sort_by(f64::total_cmp);
    let rate = inside as f64 / total as f64;
    println!(
        "within 3 SE: {inside} of {total} ({rate}); median error {:.2} SE, largest {:.2} SE",
        worst[worst.len() / 2],
        worst[worst.len() - 1]
    );
    if polarid_testkit::full() {
        assert!(rate >= 0.99, "{inside} of {total} within 3 SE");
    } else {
        let misses = (total - inside) as u64;
        let most = polarid_testkit::max_misses(total as u64, 0.01, 1e-3);
        assert!(
            misses <= most,
            "{inside} of {total} within 3 SE (at most {most} misses)"
        );
    }
}

/// The same rows fitted as if each region had one β — its rectangle's centre's, or the
/// weighted mean without the spread term — miss by many standard errors on the close
/// bench (β spread 0.8–2.7°, the lobe moving the weighted mean up to 0.5° from the
/// centre), while the spread model stays within 3.
#[test]
fn one_beta_per_region_misses_by_many_se() {
    // Low noise (many photons, or many frames averaged): DoLP SE ~1e-4.
    let s = Setup {
        gain: 0.01,
        read: 0.5,
        ..CLOSE
    };
    let d = tempfile::tempdir().unwrap();
    let (m, cleans) = prepare(d.path(), &s);
    let mut full = Vec::new();
    let mut no_spread = Vec::new();
    let mut centre = Vec::new();
    for seed in 0..20 {
        let rows = measure_seed(&m, &cleans, &s, seed);
        full.extend(errors_in_se(&rows));
        let flat: Vec<_> = rows
            .iter()
            .map(|(l, r)| {
                let r = Measurement {
                    beta_sd_deg: None,
                    ..r.clone()
                };
                (*l, r)
            })
            .collect();
        no_spread.extend(errors_in_se(&flat));
        let at_centre: Vec<_> = rows
            .iter()
            .enumerate()
            .map(|(i, (l, r))| {
                let t = cleans[i / PLATES.len()].truth[i % PLATES.len()];
                let r = Measurement {
                    beta_deg: t.centre_beta.to_degrees(),
                    beta_sd_deg: None,
                    ..r.clone()
                };
                (*l, r)
            })
            .collect();
        centre.extend(errors_in_se(&at_centre));
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (a, b, c) = (
        median(&mut full),
        median(&mut no_spread),
        median(&mut centre),
    );
    println!(
        "median error in SE: spread model {a:.2}, mean beta without spread {b:.2}, centre beta {c:.2}"
    );
    assert!(
        full.iter().filter(|&&e| e < 3.0).count() >= full.len() - 1,
        "{full:?}"
    );
    assert!(c > 10.0, "centre beta: median {c} SE");
    assert!(centre.iter().all(|&e| e > 3.0), "{centre:?}");
    assert!(b > 3.0, "no spread term: median {b} SE");
}

/// Far-field captures out of the plane of incidence (φ = 120°, 240°): `measure` reports
/// β of eq. (5) with φ, and `fit` recovers `(n, k)` from those rows and from rows that
/// give only `theta_i_deg`, `theta_r_deg`, `phi_deg`.
#[test]
fn out_of_plane_far_field_through_measure_and_fit() {
    let (n, k) = (0.27, 2.8);
    let d = tempfile::tempdir().unwrap();
    let (w, h) = (8, 6);
    let caps: [(f64, f64); 5] = [
        (20.0, 180.0),
        (35.0, 120.0),
        (50.0, 240.0),
        (65.0, 150.0),
        (75.0, 200.0),
    ];
    let mut text =
        String::from("theta_r_deg = 50.0\n[[region]]\nname = \"cu\"\nrect = [1, 1, 6, 4]\n");
    for (j, (ti, phi)) in caps.iter().enumerate() {
        let b = geometry::beta(ti.to_radians(), 50f64.to_radians(), phi.to_radians());
        let p = dop(n, k, b);
        for (c, v) in [1000.0f32, -1000.0 * p as f32, 0.0].iter().enumerate() {
            polarid_io::image::write_tiff_f32(
                &d.path().join(format!("c{j}_{c}.tif")),
                false,
                w,
                h,
                &vec![*v; w * h],
            )
            .unwrap();
        }
        text += &format!(
            "\n[[capture]]\ntheta_i_deg = {ti}\nphi_deg = {phi}\n\
             stokes = {{ s0 = \"c{j}_0.tif\", s1 = \"c{j}_1.tif\", s2 = \"c{j}_2.tif\" }}\n"
        );
    }
    let path = d.path().join("m.toml");
    std::fs::write(&path, &text).unwrap();
    let m = polarid_io::manifest::load(&path).unwrap();
    let rows = measure_manifest(&m, &mut |_| {}).unwrap();
    for (r, (ti, phi)) in rows.iter().zip(&caps) {
        let b = geometry::beta(ti.to_radians(), 50f64.to_radians(), phi.to_radians());
        assert!((r.beta_deg - b.to_degrees()).abs() < 1e-12, "{r:?}");
        assert_eq!(r.phi_deg, *phi);
        // Far-field rows have none of the calibrated columns.
        assert_eq!(
            (r.beta_sd_deg, r.aolp_deg, r.aolp_poi_deg),
            (None, None, None)
        );
    }
    // Out of plane β is below (θi + θr)/2.
    assert!(rows[1].beta_deg < (35.0 + 50.0) / 2.0 - 1.0);
    let lined: Vec<_> = rows.iter().cloned().map(|r| (2, r)).collect();
    let f = fit(
        Path::new("m.csv"),
        &lined,
        &FitConfig::default(),
        &no_progress,
    )
    .unwrap();
    let r = &f.targets[0].row;
    assert!((r.n - n).abs() < 1e-4 && (r.k - k).abs() < 1e-4, "{r:?}");
    // Rows with only the angles: β from eq. (5) with φ.
    let mut csv = String::from("target,theta_i_deg,theta_r_deg,phi_deg,dolp\n");
    for r in &rows {
        csv += &format!(
            "cu,{},50,{},{}\n",
            r.theta_i_deg.unwrap(),
            r.phi_deg,
            r.dolp
        );
    }
    let t = CsvTable::from_reader(Path::new("a.csv"), csv.as_bytes()).unwrap();
    let back = measurements::from_table(&t).unwrap();
    for (a, b) in back.iter().zip(&rows) {
        assert!((a.beta_deg - b.beta_deg).abs() < 1e-12);
    }
    let lined: Vec<_> = back.into_iter().map(|r| (2, r)).collect();
    let g = fit(
        Path::new("a.csv"),
        &lined,
        &FitConfig::default(),
        &no_progress,
    )
    .unwrap();
    assert!((g.targets[0].row.n - r.n).abs() < 1e-9);
    // With both, `beta_deg` is used (calibrated rows' angles are weighted means, whose
    // eq. 5 is not the weighted mean β).
    let csv = "target,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp\ncu,30,50,180,33.5,0.2\n";
    let t = CsvTable::from_reader(Path::new("b.csv"), csv.as_bytes()).unwrap();
    assert_eq!(measurements::from_table(&t).unwrap()[0].beta_deg, 33.5);
}
