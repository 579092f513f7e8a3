//! Classification on several bands at once (issue 17): distances over the bands in common,
//! χ² with 2 × bands degrees of freedom, targets with fewer bands than the prototypes,
//! bands whose fit failed, no band in common, and leave-one-out on multi-band targets.

use polarid_core::classify::{
    BandPoint, Classifier, ClassifierConfig, Cov2, Estimate, EstimateBand, Labelled, Metric,
    MultiEstimate, MultiPrototype, Prototype, Reject, Status, chi2_2dof_quantile, chi2_quantile,
    leave_one_out,
};
use polarid_core::status::FitStatus;

const WL: [f64; 3] = [450.0, 550.0, 650.0];

fn band(wl: f64, n: f64, k: f64, cov: Option<Cov2>) -> BandPoint {
    BandPoint {
        wavelength_nm: Some(wl),
        n,
        k,
        cov,
        film: None,
        layer: None,
    }
}

/// Copper- and gold-like prototypes: nearly equal at 650 nm, apart at 450 and 550 nm.
fn protos() -> Vec<MultiPrototype> {
    let mk = |class: &str, nk: [(f64, f64); 3]| MultiPrototype {
        class: class.into(),
        category: Some("metal".into()),
        source: "test".into(),
        bands: WL
            .iter()
            .zip(nk)
            .map(|(&w, (n, k))| band(w, n, k, None))
            .collect(),
        surface: None,
    };
    vec![
        mk("copper", [(1.25, 2.38), (0.97, 2.63), (0.25, 3.61)]),
        mk("gold", [(1.36, 1.90), (0.46, 2.46), (0.16, 3.60)]),
    ]
}

fn est_band(wl: f64, n: f64, k: f64, se: f64) -> EstimateBand {
    EstimateBand {
        wavelength_nm: Some(wl),
        estimate: Estimate {
            n,
            k,
            cov: Cov2::from_se(se, se, 0.0),
            fit_status: FitStatus::Ok,
        },
        film: None,
    }
}

#[test]
fn distance_adds_over_bands_and_reports_them() {
    let clf = Classifier::multi(protos(), ClassifierConfig::default()).unwrap();
    let est = MultiEstimate {
        bands: vec![
            est_band(450.0, 1.30, 2.30, 0.1),
            est_band(550.0, 0.90, 2.60, 0.1),
            est_band(650.0, 0.20, 3.60, 0.1),
        ],
    };
    let d = clf.classify_multi(&est);
    assert_eq!(d.predicted, "copper");
    let expect = ((0.05f64).hypot(0.08).powi(2)
        + (0.07f64).hypot(0.03).powi(2)
        + (0.05f64).hypot(0.01).powi(2))
    .sqrt();
    assert!(
        (d.distance - expect).abs() < 1e-12,
        "{} {expect}",
        d.distance
    );
    assert_eq!(d.bands_used, vec![Some(450.0), Some(550.0), Some(650.0)]);
    assert_eq!(d.bands_used_text(), "450;550;650");
    // At 650 nm alone the same estimate is nearer gold: the bands matter.
    let only650 = MultiEstimate {
        bands: vec![est_band(650.0, 0.20, 3.60, 0.1)],
    };
    let d = clf.classify_multi(&only650);
    assert_eq!(d.bands_used, vec![Some(650.0)]);
    let (dc, dg) = (0.05f64.hypot(0.01), 0.04f64.hypot(0.0));
    assert_eq!(d.predicted, if dc < dg { "copper" } else { "gold" });
}

#[test]
fn one_band_is_the_single_band_classifier_bit_for_bit() {
    let single = vec![
        Prototype {
            class: "a".into(),
            n: 1.2,
            k: 3.4,
            cov: Cov2::from_se(0.05, 0.1, 0.2),
            category: None,
            source: "s".into(),
        },
        Prototype {
            class: "b".into(),
            n: 0.4,
            k: 3.0,
            cov: None,
            category: None,
            source: "s".into(),
        },
    ];
    let est = Estimate {
        n: 1.0,
        k: 3.3,
        cov: Cov2::from_se(0.1, 0.2, -0.3),
        fit_status: FitStatus::Ok,
    };
    for cfg in [
        ClassifierConfig::default(),
        ClassifierConfig::set(0.95),
        ClassifierConfig {
            metric: Metric::Mahalanobis,
            reject: Reject::Chi2 { p: 0.99 },
            ..Default::default()
        },
    ] {
        let a = Classifier::new(single.clone(), cfg).unwrap().classify(&est);
        // The same prototypes and estimate tagged 650 nm, through the multi-band path.
        let multi: Vec<MultiPrototype> = single
            .iter()
            .cloned()
            .map(|p| {
                let mut m = MultiPrototype::from(p);
                m.bands[0].wavelength_nm = Some(650.0);
                m
            })
            .collect();
        let b = Classifier::multi(multi, cfg)
            .unwrap()
            .classify_multi(&MultiEstimate {
                bands: vec![EstimateBand {
                    wavelength_nm: Some(650.0),
                    estimate: est.clone(),
                    film: None,
                }],
            });
        assert_eq!(a.predicted, b.predicted);
        assert_eq!(a.distance.to_bits(), b.distance.to_bits());
        assert_eq!(a.candidates, b.candidates);
        assert_eq!(a.reason, b.reason);
        assert_eq!(b.bands_used, vec![Some(650.0)]);
        assert_eq!(a.bands_used, vec![None]);
    }
}

#[test]
fn set_rule_and_gate_use_two_degrees_of_freedom_per_band() {
    // Identical covariances in every band; the estimate 2.8 σ from copper in total
    // (d² = 7.84): inside χ²₆(0.95) = 12.59, outside χ²₂(0.95) = 5.99.
    let cov = Cov2::from_se(0.1, 0.1, 0.0).unwrap();
    let mut p = protos();
    for m in &mut p {
        for b in &mut m.bands {
            b.cov = None;
        }
    }
    let off = 0.28 / 3f64.sqrt();
    let est = MultiEstimate {
        bands: WL
            .iter()
            .zip([(1.25, 2.38), (0.97, 2.63), (0.25, 3.61)])
            .map(|(&w, (n, k))| EstimateBand {
                wavelength_nm: Some(w),
                estimate: Estimate {
                    n: n + off,
                    k,
                    cov: Some(cov),
                    fit_status: FitStatus::Ok,
                },
                film: None,
            })
            .collect(),
    };
    let clf = Classifier::multi(p.clone(), ClassifierConfig::set(0.95)).unwrap();
    let d = clf.classify_multi(&est);
    assert!((d.distance - 2.8).abs() < 1e-9, "{}", d.distance);
    assert!(d.distance.powi(2) > chi2_2dof_quantile(0.95));
    assert!(d.distance.powi(2) < chi2_quantile(0.95, 6));
    assert_eq!(d.predicted, "copper", "{d:?}");
    assert_eq!(d.status, Status::Ok);
    // The χ² gate of the nearest rule: 6 dof.
    let gate = ClassifierConfig {
        reject: Reject::Chi2 { p: 0.95 },
        ..Default::default()
    };
    let d = Classifier::multi(p.clone(), gate)
        .unwrap()
        .classify_multi(&est);
    assert_eq!(d.predicted, "copper", "{}", d.reason);
    // One band with the same total distance (2.8 σ): rejected under both.
    let one = MultiEstimate {
        bands: vec![EstimateBand {
            wavelength_nm: Some(650.0),
            estimate: Estimate {
                n: 0.25 + 0.28,
                k: 3.61,
                cov: Some(cov),
                fit_status: FitStatus::Ok,
            },
            film: None,
        }],
    };
    let d = clf.classify_multi(&one);
    assert_eq!(d.status, Status::Rejected, "{d:?}");
    let d = Classifier::multi(p, gate).unwrap().classify_multi(&one);
    assert_eq!(d.status, Status::Rejected);
    assert!(d.reason.contains("2 dof"), "{}", d.reason);
}

#[test]
fn failed_bands_are_left_out_and_no_common_band_is_not_classified() {
    let clf = Classifier::multi(protos(), ClassifierConfig::default()).unwrap();
    let mut bad = est_band(450.0, 9.0, 9.0, 0.1);
    bad.estimate.fit_status = FitStatus::NotConverged;
    let est = MultiEstimate {
        bands: vec![bad.clone(), est_band(550.0, 0.46, 2.46, 0.1)],
    };
    let d = clf.classify_multi(&est);
    assert_eq!(d.predicted, "gold");
    assert_eq!(d.bands_used, vec![Some(550.0)]);
    // Every band failed: the first band's status.
    let d = clf.classify_multi(&MultiEstimate { bands: vec![bad] });
    assert_eq!(d.status, Status::FitNotOk(FitStatus::NotConverged));
    // A band no prototype has.
    let d = clf.classify_multi(&MultiEstimate {
        bands: vec![est_band(800.0, 0.2, 5.0, 0.1)],
    });
    assert_eq!(d.status, Status::NoCommonBand);
    assert_eq!(d.status.label(), "no_common_band");
    assert!(d.reason.contains("800 nm"), "{}", d.reason);
    // A single band without a wavelength is not compared with three-band prototypes.
    let d = clf.classify(&Estimate::point(0.25, 3.61));
    assert_eq!(d.status, Status::NoCommonBand);
}

#[test]
fn repeated_bands_are_refused() {
    let mut p = protos();
    p[0].bands[1].wavelength_nm = Some(450.2);
    let e = Classifier::multi(p, ClassifierConfig::default()).unwrap_err();
    assert!(e.to_string().contains("copper"), "{e}");
}

#[test]
fn leave_one_out_on_three_band_targets() {
    let truth = protos();
    let mut items = Vec::new();
    for (c, p) in truth.iter().enumerate() {
        for j in 0..3 {
            let s = 0.01 * (j as f64 - 1.0);
            items.push(Labelled {
                target: format!("{}{j}", p.class),
                class: p.class.clone(),
                estimate: MultiEstimate {
                    bands: p
                        .bands
                        .iter()
                        .map(|b| est_band(b.wavelength_nm.unwrap(), b.n + s, b.k - s, 0.03))
                        .collect(),
                },
                source: format!("t{c}{j}"),
            });
        }
    }
    let ev = leave_one_out(&items, ClassifierConfig::set(0.95)).unwrap();
    assert_eq!(ev.items.len(), 6);
    assert!((ev.accuracy - 1.0).abs() < 1e-12, "{:?}", ev.confusion);
    for it in &ev.items {
        assert_eq!(it.decision.bands_used.len(), 3);
    }
}
