//! `polarid measure` on a calibrated manifest (`[camera]`, lamps in and out of the plane
//! of incidence, and a sun source) writes the region's weighted geometry with
//! `beta_sd_deg`, `aolp_deg` and `aolp_poi_deg`; `polarid fit` reads the file and
//! recovers the plates' `(n, k)`.

use crate::common;

use polarid_testkit::calibrated_bench as bench;

use common::{csv_rows, polarid_in, text};

#[test]
fn measure_writes_the_calibrated_columns_and_fit_reads_them() {
    let d = tempfile::tempdir().unwrap();
    let lamps = bench::lamps();
    let m = bench::load(d.path(), &bench::PLATES, &lamps);
    for (j, l) in lamps.iter().enumerate() {
        let clean = bench::clean(&m, &bench::PLATES, *l);
        bench::write_stokes(d.path(), j, &bench::noisy(&clean, 0.05, j as u64));
    }
    let o = polarid_in(
        d.path(),
        &["measure", "manifest.toml", "-o", "measurements.csv"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let csv = std::fs::read_to_string(d.path().join("measurements.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert_eq!(
        header,
        "target,class,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,dolp_se,s0,pixels,\
         rejected,exposure,saturated,beta_sd_deg,aolp_deg,aolp_poi_deg"
    );
    let rows = csv_rows(&d.path().join("measurements.csv"));
    assert_eq!(rows.len(), lamps.len() * bench::PLATES.len());
    let num = |r: &std::collections::HashMap<String, String>, c: &str| -> f64 {
        r[c].parse().unwrap_or_else(|_| panic!("{c}: {:?}", r[c]))
    };
    for r in &rows {
        assert!(num(r, "beta_sd_deg") > 0.1, "{r:?}");
        assert!((num(r, "aolp_poi_deg") - 90.0).abs() < 1.0, "{r:?}");
        let a = num(r, "aolp_deg");
        assert!((0.0..180.0).contains(&a), "{r:?}");
        assert!(num(r, "dolp_se") > 0.0);
    }
    // An out-of-plane lamp: φ well away from 180°.
    let out = &rows[2 * 5];
    assert!((num(out, "phi_deg") - 180.0).abs() > 20.0, "{out:?}");
    let o = polarid_in(d.path(), &["fit", "measurements.csv", "-o", "fits.csv"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let fits = csv_rows(&d.path().join("fits.csv"));
    // Gold (k > 0) within 3 SE; glass (k = 0, on the search box's edge) close.
    let g = &fits[0];
    assert_eq!(g["target"], "gold");
    let (n, k) = (num(g, "n"), num(g, "k"));
    assert!(
        (n - 1.38).abs() < 3.0 * num(g, "n_se") && (k - 1.92).abs() < 3.0 * num(g, "k_se"),
        "{g:?}"
    );
    let gl = &fits[1];
    assert!(
        (num(gl, "n") - 1.52).abs() < 0.02 && num(gl, "k") < 0.05,
        "{gl:?}"
    );
}

#[test]
fn measure_with_a_sun_source() {
    let d = tempfile::tempdir().unwrap();
    let lamps = bench::lamps();
    let m = bench::load(d.path(), &bench::PLATES, &lamps[..1]);
    let clean = bench::clean(&m, &bench::PLATES, lamps[0]);
    bench::write_stokes(d.path(), 0, &bench::noisy(&clean, 0.05, 1));
    // The SPA report's site and time: the sun at azimuth 194°, elevation 40°; turn the
    // scene frame's x to the east and put it behind the plates' normal... simply reuse
    // the bench (x east, y north, z up): the plates face up, the sun is above them.
    let text0 = std::fs::read_to_string(d.path().join("manifest.toml")).unwrap();
    let start = text0.find("source = {").unwrap();
    let end = start + text0[start..].find('\n').unwrap();
    let manifest = format!(
        "{}source = {{ sun = \"2003-10-17T12:30:30-07:00\" }}{}\n[site]\n\
         latitude_deg = 39.742476\nlongitude_deg = -105.1786\nelevation_m = 1830.14\n\
         pressure_mbar = 820.0\ntemperature_c = 11.0\n",
        &text0[..start],
        &text0[end..]
    );
    std::fs::write(d.path().join("sun.toml"), manifest).unwrap();
    let o = polarid_in(d.path(), &["measure", "sun.toml", "-o", "sun.csv"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let rows = csv_rows(&d.path().join("sun.csv"));
    // A distant source: θi is the sun's zenith (50.1°) at every pixel.
    for r in &rows {
        let ti: f64 = r["theta_i_deg"].parse().unwrap();
        assert!((ti - 50.11).abs() < 0.01, "{r:?}");
        assert!(r["beta_sd_deg"].parse::<f64>().unwrap() > 0.0);
    }
}
