//! The capture-set manifest parser (`polarid_io::manifest::parse`) on arbitrary text.
//!
//! The manifest sits in a directory holding a few empty files (`a` … `e`, `s/f.tif`)
//! so that inputs naming them get past the file checks into the frame, DoFP and Stokes
//! validation (`fuzz/dict/manifest.dict` names them).
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

fn manifest_path() -> &'static PathBuf {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &DIR.get_or_init(|| {
        let d = tempfile::tempdir().expect("temp dir"); // ok: harness setup, not user data
        for f in ["a", "b", "c", "d", "e", "s/f.tif"] {
            let p = d.path().join(f);
            if let Some(parent) = p.parent() {
                std::fs::create_dir_all(parent).expect("mkdir"); // ok: harness setup
            }
            std::fs::write(&p, b"").expect("write"); // ok: harness setup
        }
        let m = d.path().join("m.toml");
        (d, m)
    })
    .1
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(m) = polarid_io::manifest::parse(manifest_path(), text) {
        // Invariants of a validated manifest.
        assert!(!m.regions.is_empty() && !m.captures.is_empty());
        for r in &m.regions {
            assert!(r.rect.width > 0 && r.rect.height > 0);
        }
        for c in &m.captures {
            assert!((0.0..90.0).contains(&c.theta_i_deg));
            assert!((0.0..90.0).contains(&c.theta_r_deg));
            assert!(c.exposure > 0.0 && c.exposure.is_finite());
            assert!(!c.source.files().is_empty());
        }
    }
});
