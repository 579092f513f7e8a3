//! Model JSON (`polarid train` → `classify --model`, `map --model`) on arbitrary bytes.
//! An accepted model has prototypes with finite `(n, k)`, `k >= 0`, usable covariances
//! and class names a classifier takes; it survives write → parse; and a classifier built
//! from it (set and nearest rules, single- and multi-band prototypes) classifies points
//! without panicking.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use polarid_core::FitStatus;
use polarid_core::classify::{Classifier, ClassifierConfig, Cov2, Estimate};
use polarid_io::model::Model;

fn close(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz.json");
    let Ok(m) = Model::parse(path, text) else {
        return;
    };
    assert!(!m.prototypes.is_empty());
    for p in &m.prototypes {
        assert!(p.n.is_finite() && p.k.is_finite() && p.k >= 0.0, "{p:?}");
        if let Some(c) = p.covariance {
            assert!(Cov2::from_matrix(c).is_some(), "{c:?}");
        }
    }
    // Round trip through the writer.
    let mut buf = Vec::new();
    m.write(&mut buf, path).expect("write to memory"); // ok: in memory
    let back = Model::parse(
        path,
        std::str::from_utf8(&buf).expect("own output is UTF-8"),
    )
    .expect("re-parse own output");
    assert_eq!(back.prototypes.len(), m.prototypes.len());
    for (a, b) in m.prototypes.iter().zip(&back.prototypes) {
        assert_eq!(a.class, b.class);
        assert!(close(a.n, b.n) && close(a.k, b.k), "{a:?} vs {b:?}");
        assert_eq!(a.covariance.is_some(), b.covariance.is_some());
    }
    // Classifiers built from the model.
    let points = [
        Estimate::point(1.5, 0.0),
        Estimate::point(1.2, 6.6),
        Estimate {
            n: 0.5,
            k: 3.0,
            cov: Cov2::from_se(0.05, 0.1, 0.3),
            fit_status: FitStatus::Ok,
        },
    ];
    for cfg in [ClassifierConfig::set(0.95), ClassifierConfig::default()] {
        if let Ok(clf) = Classifier::multi(m.multi_prototypes(), cfg) {
            for e in &points {
                let _ = clf.classify(e);
            }
        }
        if let Ok(clf) = Classifier::new(m.prototypes(), cfg) {
            for e in &points {
                let d = clf.classify(e);
                let _ = d.candidates_text();
            }
        }
    }
});
