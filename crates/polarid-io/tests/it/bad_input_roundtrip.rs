//! Property tests (issue 9): what polarid writes, polarid reads back unchanged —
//! measurements and fits CSV, 8/16-bit and float images — and generated manifests parse
//! to the values they were written from.

use std::path::Path;

use polarid_io::image::{self, SampleKind};
use polarid_io::manifest::{self, CaptureSource};
use polarid_io::table::fits::{self, FitRow};
use polarid_io::table::measurements::{self, Measurement};
use polarid_io::table::{CsvTable, fmt_f64};
use proptest::prelude::*;

/// Names as a manifest allows them (no comma, quote, control character, or
/// leading/trailing space); may start with `#`, which must not turn a row into a comment.
fn name() -> impl Strategy<Value = String> {
    "[#A-Za-z0-9_]([A-Za-z0-9 _#.;:/-]{0,10}[A-Za-z0-9_#])?"
}

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e6..1e6f64,
        any::<f64>().prop_filter("finite", |x| x.is_finite()),
        Just(0.0),
        Just(1e-300),
    ]
}

fn angle() -> impl Strategy<Value = f64> {
    prop_oneof![0.0..90.0f64, Just(0.0), Just(89.999_999_999)]
}

prop_compose! {
    fn measurement()(
        target in name(),
        class in proptest::option::of(name()),
        ti in proptest::option::of(angle()),
        tr in proptest::option::of(angle()),
        phi in finite(),
        beta in angle(),
        dolp in prop_oneof![0.0..=1.0f64, Just(1.0), Just(0.0)],
        se in proptest::option::of(1e-12..1.0f64),
        s0 in proptest::option::of(finite()),
        pixels in proptest::option::of(any::<u64>()),
        rejected in proptest::option::of(any::<u64>()),
        exposure in proptest::option::of(1e-6..1e6f64),
        saturated in proptest::option::of(any::<u64>()),
        // The optional columns of calibrated captures, each present or not.
        extra in (
            proptest::option::of(prop_oneof![0.0..90.0f64, Just(0.0)]),
            proptest::option::of(0.0..180.0f64),
            proptest::option::of(0.0..180.0f64),
        ),
    ) -> Measurement {
        Measurement {
            target,
            class,
            theta_i_deg: ti,
            theta_r_deg: tr,
            phi_deg: phi,
            beta_deg: beta,
            dolp,
            dolp_se: se,
            s0,
            pixels,
            rejected,
            exposure,
            saturated,
            beta_sd_deg: extra.0,
            aolp_deg: extra.1,
            aolp_poi_deg: extra.2,
            angle_sd_deg: None,
            ..Default::default()
        }
    }
}

fn nan_or(s: impl Strategy<Value = f64>) -> impl Strategy<Value = f64> {
    prop_oneof![3 => s, 1 => Just(f64::NAN)]
}

prop_compose! {
    fn fit_row()(
        target in name(),
        class in proptest::option::of(name()),
        ok in any::<bool>(),
        n in 1e-6..50.0f64,
        k in prop_oneof![0.0..50.0f64, Just(0.0)],
        n_se in nan_or(0.0..10.0f64),
        k_se in nan_or(0.0..10.0f64),
        corr in nan_or(-1.0..=1.0f64),
        rms in nan_or(0.0..1.0f64),
        m in any::<u64>(),
        reason in "[a-z ]{0,12}",
        sigma in proptest::option::of(0.0..1.0f64),
    ) -> FitRow {
        FitRow {
            target,
            class,
            wavelength_nm: None,
            n: if ok { n } else { f64::NAN },
            k: if ok { k } else { f64::NAN },
            n_se,
            k_se,
            nk_corr: corr,
            rms_residual: rms,
            measurements: m,
            status: if ok { polarid_core::FitStatus::Ok } else { polarid_core::FitStatus::NotConverged },
            // The reader trims cells.
            reason: reason.trim().to_string(),
            model: "specular".into(),
            sigma,
            rho_d: None,
            n_se_noise: None,
            k_se_noise: None,
            nk_corr_noise: None,
            gof_p: None,
            aolp_p: None,
            n_se_sample: None,
            k_se_sample: None,
            nk_corr_sample: None,
            theta_r_deg: None,
            film: None,
        }
    }
}

/// Equal, with NaN equal to NaN.
fn same(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn measurements_round_trip(rows in proptest::collection::vec(measurement(), 0..8)) {
        let path = Path::new("m.csv");
        let mut buf = Vec::new();
        measurements::write(&mut buf, path, &rows).unwrap();
        let t = CsvTable::from_reader(path, buf.as_slice()).unwrap();
        let back = measurements::from_table(&t).unwrap();
        prop_assert_eq!(back, rows);
    }

    #[test]
    fn fits_round_trip(rows in proptest::collection::vec(fit_row(), 0..8)) {
        let path = Path::new("f.csv");
        let mut buf = Vec::new();
        fits::write(&mut buf, path, &rows).unwrap();
        let t = CsvTable::from_reader(path, buf.as_slice()).unwrap();
        let back = fits::from_table(&t).unwrap();
        prop_assert_eq!(back.len(), rows.len());
        for (b, r) in back.iter().zip(&rows) {
            prop_assert_eq!(&b.target, &r.target);
            prop_assert_eq!(&b.class, &r.class);
            prop_assert_eq!(&b.status, &r.status);
            prop_assert_eq!(&b.reason, &r.reason);
            prop_assert_eq!(b.measurements, r.measurements);
            prop_assert_eq!(b.sigma, r.sigma);
            for (x, y) in [
                (b.n, r.n),
                (b.k, r.k),
                (b.n_se, r.n_se),
                (b.k_se, r.k_se),
                (b.nk_corr, r.nk_corr),
                (b.rms_residual, r.rms_residual),
            ] {
                prop_assert!(same(x, y), "{} != {}", x, y);
            }
        }
    }

    #[test]
    fn numbers_format_exactly(x in any::<f64>().prop_filter("finite", |x| x.is_finite())) {
        prop_assert_eq!(fmt_f64(x).parse::<f64>().unwrap(), x);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn gray8_images_round_trip(
        w in 1usize..20, h in 1usize..20, seed in any::<u64>(), tif in any::<bool>()
    ) {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join(if tif { "a.tif" } else { "a.png" });
        let v: Vec<u8> = (0..w * h).map(|i| (seed.rotate_left(i as u32 % 64) >> 7) as u8).collect();
        image::write_gray8(&p, false, w, h, &v).unwrap();
        let f = image::read_frame(&p).unwrap();
        prop_assert_eq!((f.width, f.height, f.kind), (w, h, SampleKind::U8));
        let want: Vec<f32> = v.iter().map(|&x| f32::from(x)).collect();
        prop_assert_eq!(f.data, want);
    }

    #[test]
    fn gray16_images_round_trip(
        w in 1usize..20, h in 1usize..20, v0 in any::<u16>(), tif in any::<bool>()
    ) {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join(if tif { "a.tiff" } else { "a.png" });
        let v: Vec<u16> = (0..w * h).map(|i| v0.wrapping_mul(i as u16 | 1)).collect();
        image::write_gray16(&p, false, w, h, &v).unwrap();
        let f = image::read_frame(&p).unwrap();
        prop_assert_eq!((f.width, f.height, f.kind), (w, h, SampleKind::U16));
        let want: Vec<f32> = v.iter().map(|&x| f32::from(x)).collect();
        prop_assert_eq!(f.data, want);
    }

    #[test]
    fn f32_images_round_trip(
        w in 1usize..16,
        h in 1usize..16,
        vals in proptest::collection::vec(any::<f32>(), 256),
    ) {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("s.tif");
        let v: Vec<f32> = vals.into_iter().take(w * h).collect();
        image::write_tiff_f32(&p, false, w, h, &v).unwrap();
        let f = image::read_frame(&p).unwrap();
        prop_assert_eq!((f.width, f.height, f.kind), (w, h, SampleKind::F32));
        let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        prop_assert_eq!(bits(&f.data), bits(&v));
    }

    #[test]
    fn generated_manifests_parse_to_their_values(
        theta_r in angle(),
        regions in proptest::collection::vec(
            (name(), (0usize..1000, 0usize..1000, 1usize..500, 1usize..500),
             proptest::option::of(name())), 1..4),
        captures in proptest::collection::vec(
            (angle(), 0u8..3, -720.0..720.0f64, 1e-3..1e3f64), 1..4),
    ) {
        let d = tempfile::tempdir().unwrap();
        for f in ["a.tif", "b.tif", "c.tif", "d.tif"] {
            std::fs::write(d.path().join(f), b"").unwrap();
        }
        let mut text = format!("theta_r_deg = {theta_r:?}\n");
        let mut seen = std::collections::HashSet::new();
        let regions: Vec<_> = regions.into_iter().filter(|r| seen.insert(r.0.clone())).collect();
        for (n, (x, y, w, h), class) in &regions {
            text.push_str(&format!("\n[[region]]\nname = {n:?}\nrect = [{x}, {y}, {w}, {h}]\n"));
            if let Some(c) = class {
                text.push_str(&format!("class = {c:?}\n"));
            }
        }
        for (ti, kind, a0, exposure) in &captures {
            text.push_str(&format!("\n[[capture]]\ntheta_i_deg = {ti:?}\nexposure = {exposure:?}\n"));
            match kind {
                0 => text.push_str(&format!(
                    "frames = [{{ angle_deg = {:?}, file = \"a.tif\" }}, {{ angle_deg = {:?}, file = \"b.tif\" }}, {{ angle_deg = {:?}, file = \"c.tif\" }}]\n",
                    a0, a0 + 60.0, a0 + 120.0
                )),
                1 => text.push_str("dofp = { file = \"d.tif\", pattern = [0, 45, 90, 135] }\n"),
                _ => text.push_str("stokes = { s0 = \"a.tif\", s1 = \"b.tif\", s2 = \"c.tif\" }\n"),
            }
        }
        let m = manifest::parse(&d.path().join("m.toml"), &text)
            .map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        prop_assert_eq!(m.theta_r_deg, Some(theta_r));
        prop_assert_eq!(m.regions.len(), regions.len());
        for (r, (n, (x, y, w, h), class)) in m.regions.iter().zip(&regions) {
            prop_assert_eq!(&r.name, n);
            prop_assert_eq!((r.rect.x, r.rect.y, r.rect.width, r.rect.height), (*x, *y, *w, *h));
            prop_assert_eq!(r.class.as_deref(), class.as_deref().filter(|c| !c.trim().is_empty()));
        }
        prop_assert_eq!(m.captures.len(), captures.len());
        for (c, (ti, kind, a0, exposure)) in m.captures.iter().zip(&captures) {
            prop_assert_eq!(c.theta_i_deg, *ti);
            prop_assert_eq!(c.exposure, *exposure);
            prop_assert_eq!(c.theta_r_deg, theta_r);
            match (&c.source, kind) {
                (CaptureSource::Frames(f), 0) => {
                    prop_assert_eq!(f.len(), 3);
                    prop_assert_eq!(f[0].angle_deg, *a0);
                    prop_assert!(f[2].file.ends_with("c.tif"));
                }
                (CaptureSource::Dofp { file, .. }, 1) => prop_assert!(file.ends_with("d.tif")),
                (CaptureSource::Stokes { s1, .. }, 2) => prop_assert!(s1.ends_with("b.tif")),
                (s, k) => prop_assert!(false, "capture kind {} parsed as {:?}", k, s),
            }
        }
    }
}

/// Regression: a target named `#1` was written unquoted and read back as a comment line,
/// silently dropping its measurements.
#[test]
fn hash_target_is_not_a_comment() {
    let rows = vec![Measurement {
        target: "#1".into(),
        phi_deg: 180.0,
        beta_deg: 45.0,
        dolp: 0.5,
        ..Default::default()
    }];
    let mut buf = Vec::new();
    measurements::write(&mut buf, Path::new("m.csv"), &rows).unwrap();
    let text = String::from_utf8(buf.clone()).unwrap();
    assert!(text.contains("\"#1\""), "{text}");
    let t = CsvTable::from_reader(Path::new("m.csv"), buf.as_slice()).unwrap();
    assert_eq!(measurements::from_table(&t).unwrap(), rows);
}
