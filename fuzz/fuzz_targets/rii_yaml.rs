//! The refractiveindex.info YAML reader (`polarid library --yaml`) on arbitrary bytes.
//! An accepted file gives a wavelength range; inside it `nk` either fails with an error
//! or returns finite values with `k >= 0` from tabulated data (formulas may give any
//! real `n`); band means over the range never panic.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use polarid_io::library::{Dispersion, RiiData};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(d) = RiiData::parse(Path::new("fuzz.yml"), text) else {
        return;
    };
    let (lo, hi) = d.range_um();
    for wl in [lo, hi, 0.5 * (lo + hi), 0.65, lo - 1e-3, f64::NAN] {
        if let Ok((n, k)) = d.nk(wl) {
            assert!(wl >= lo && wl <= hi, "{wl} outside {lo}..{hi}");
            assert!(n.is_finite() && k.is_finite(), "n {n} k {k}");
            if matches!(d.k, Some(Dispersion::Table { .. })) {
                // Interpolated tabulated k stays within the data's values.
                let Some(Dispersion::Table { values, .. }) = &d.k else {
                    unreachable!()
                };
                let min = values.iter().copied().fold(f64::INFINITY, f64::min);
                let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                assert!(
                    k >= min - 1e-9 * min.abs().max(1.0) && k <= max + 1e-9 * max.abs().max(1.0)
                );
            }
        }
    }
    // A band of at most ~100 samples inside the range (nm).
    if lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo {
        let (a, b) = (lo * 1e3, hi * 1e3);
        let step = ((b - a) / 100.0).max(1e-3);
        let _ = d.band_mean(a, b, step);
    }
});
