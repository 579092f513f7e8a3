//! The fits CSV (`fit` → `train`, `classify`, `evaluate`) and the classification CSV
//! (`classify` output) on arbitrary bytes, through the same table reader as the CLI.
//!
//! Fits: a usable (`ok`) row has finite `n > 0`, `k >= 0`; standard errors are unknown
//! (NaN, from an empty cell) or finite and `>= 0`; correlations unknown or in `[-1, 1]`;
//! rows survive write → read exactly; a classifier trained on the usable rows classifies
//! every row without panicking. Classification rows survive write → read.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use polarid_core::classify::{Classifier, ClassifierConfig, Cov2, Estimate, Prototype};
use polarid_io::table::{CsvTable, classification, fits};

fn same(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

fn same_opt(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => same(a, b),
        (None, None) => true,
        _ => false,
    }
}

fn estimate(f: &fits::FitRow) -> Estimate {
    let corr = if f.nk_corr.is_nan() { 0.0 } else { f.nk_corr };
    Estimate {
        n: f.n,
        k: f.k,
        cov: Cov2::from_se(f.n_se, f.k_se, corr),
        fit_status: f.status,
    }
}

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.csv");
    let Ok(t) = CsvTable::from_reader(path, data) else {
        return;
    };
    if let Ok(rows) = fits::from_table(&t) {
        for f in &rows {
            assert!(!f.target.is_empty());
            if f.status.is_ok() {
                assert!(f.n.is_finite() && f.n > 0.0, "{f:?}");
                assert!(f.k.is_finite() && f.k >= 0.0, "{f:?}");
            }
            for se in [f.n_se, f.k_se] {
                assert!(se.is_nan() || (se.is_finite() && se >= 0.0), "{f:?}");
            }
            assert!(
                f.nk_corr.is_nan() || (-1.0..=1.0).contains(&f.nk_corr),
                "{f:?}"
            );
        }
        let mut buf = Vec::new();
        fits::write(&mut buf, path, &rows).expect("write to memory"); // ok: in memory
        let t2 = CsvTable::from_reader(path, buf.as_slice()).expect("re-read own output");
        let back = fits::from_table(&t2).expect("re-parse own output");
        assert_eq!(back.len(), rows.len());
        for (a, b) in rows.iter().zip(&back) {
            assert_eq!(
                (&a.target, &a.class, a.status),
                (&b.target, &b.class, b.status)
            );
            assert!(same(a.n, b.n) && same(a.k, b.k), "{a:?} vs {b:?}");
            assert!(
                same(a.n_se, b.n_se) && same(a.k_se, b.k_se),
                "{a:?} vs {b:?}"
            );
            assert!(same(a.nk_corr, b.nk_corr), "{a:?} vs {b:?}");
            assert!(same_opt(a.wavelength_nm, b.wavelength_nm), "{a:?} vs {b:?}");
        }
        let protos: Vec<Prototype> = rows
            .iter()
            .filter(|f| f.status.is_ok())
            .filter_map(|f| {
                Some(Prototype {
                    class: f.class.clone()?,
                    n: f.n,
                    k: f.k,
                    cov: estimate(f).cov,
                    category: None,
                    source: f.target.clone(),
                })
            })
            .collect();
        for cfg in [ClassifierConfig::set(0.95), ClassifierConfig::default()] {
            if let Ok(clf) = Classifier::new(protos.clone(), cfg) {
                for f in rows.iter().take(64) {
                    let _ = clf.classify(&estimate(f));
                }
            }
        }
    }
    if let Ok(rows) = classification::from_table(&t) {
        let mut buf = Vec::new();
        classification::write(&mut buf, path, &rows).expect("write to memory"); // ok: in memory
        let t2 = CsvTable::from_reader(path, buf.as_slice()).expect("re-read own output");
        let back = classification::from_table(&t2).expect("re-parse own output");
        assert_eq!(back.len(), rows.len());
        for (a, b) in rows.iter().zip(&back) {
            assert_eq!(
                (&a.target, &a.predicted, &a.status),
                (&b.target, &b.predicted, &b.status)
            );
        }
    }
});
