//! The material library CSV (`classify --library FILE`, `polarid library` output) on
//! arbitrary bytes. An accepted library has materials with usable names, finite `n > 0`
//! and `k >= 0`, positive wavelengths when banded; it survives write → read; and its
//! prototypes build a classifier.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use polarid_core::classify::{Classifier, ClassifierConfig, Estimate};
use polarid_io::library::Library;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(lib) = Library::from_csv_text("fuzz.csv", text) else {
        return;
    };
    assert!(!lib.materials.is_empty());
    for m in &lib.materials {
        assert!(!m.name.is_empty(), "{m:?}");
        assert!(m.n.is_finite() && m.n > 0.0, "{m:?}");
        assert!(m.k.is_finite() && m.k >= 0.0, "{m:?}");
        if let Some(w) = m.wavelength_nm {
            assert!(w.is_finite() && w > 0.0, "{m:?}");
        }
    }
    let mut buf = Vec::new();
    lib.write_csv(&mut buf, Path::new("out.csv"), Some("fuzz\ncomment"))
        .expect("write to memory"); // ok: in memory
    let back = Library::from_csv_text("out.csv", std::str::from_utf8(&buf).expect("UTF-8"))
        .expect("re-read own output");
    assert_eq!(back.materials.len(), lib.materials.len());
    for (a, b) in lib.materials.iter().zip(&back.materials) {
        assert_eq!(
            (&a.name, a.n, a.k, a.wavelength_nm),
            (&b.name, b.n, b.k, b.wavelength_nm)
        );
    }
    for cfg in [ClassifierConfig::set(0.95), ClassifierConfig::default()] {
        if let Ok(clf) = Classifier::multi(lib.multi_prototypes(), cfg) {
            let _ = clf.classify(&Estimate::point(1.5, 0.1));
        }
        if let Ok(clf) = Classifier::new(lib.prototypes(), cfg) {
            let _ = clf.classify(&Estimate::point(1.5, 0.1));
        }
    }
});
