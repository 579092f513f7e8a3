//! The CSV readers on arbitrary bytes: the generic table, measurements, fits, model
//! rows, classification rows and the material library. Accepted rows must satisfy the
//! documented contracts, and measurements and fits must survive a write → read round trip.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use polarid_io::library::Library;
use polarid_io::table::{CsvTable, classification, fits, measurements, model_rows};

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.csv");
    let Ok(t) = CsvTable::from_reader(path, data) else {
        return;
    };
    if let Ok(rows) = measurements::from_table(&t) {
        for m in &rows {
            assert!((0.0..=1.0).contains(&m.dolp), "dolp {}", m.dolp);
            assert!(m.beta_deg.is_finite(), "beta {}", m.beta_deg);
            assert!(!m.target.is_empty());
        }
        let mut buf = Vec::new();
        measurements::write(&mut buf, path, &rows).expect("write to memory"); // ok: in memory
        let t2 = CsvTable::from_reader(path, buf.as_slice()).expect("re-read own output");
        let back = measurements::from_table(&t2).expect("re-parse own output");
        assert_eq!(back.len(), rows.len());
    }
    if let Ok(rows) = fits::from_table(&t) {
        let mut buf = Vec::new();
        fits::write(&mut buf, path, &rows).expect("write to memory"); // ok: in memory
        let t2 = CsvTable::from_reader(path, buf.as_slice()).expect("re-read own output");
        let back = fits::from_table(&t2).expect("re-parse own output");
        assert_eq!(back.len(), rows.len());
    }
    let _ = model_rows::from_table(&t);
    let _ = classification::from_table(&t);
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Library::from_csv_text("fuzz.csv", text);
    }
});
