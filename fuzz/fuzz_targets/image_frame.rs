//! The PNG/TIFF frame reader (`polarid_io::image::decode_frame_limited`) on arbitrary
//! bytes. A frame it accepts must be consistent (size, sample range).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use polarid_io::image::{SampleKind, decode_frame_limited};

/// Keep single runs fast: at most 1 Mpixel (the real limit is `MAX_PIXELS`).
const MAX_PIXELS: u64 = 1 << 20;

fuzz_target!(|data: &[u8]| {
    if let Ok(f) = decode_frame_limited(Path::new("fuzz.img"), data, MAX_PIXELS) {
        assert!(f.width > 0 && f.height > 0);
        assert_eq!(f.data.len(), f.width * f.height);
        assert!((f.width * f.height) as u64 <= MAX_PIXELS);
        if f.kind != SampleKind::F32 {
            assert!(f.data.iter().all(|&v| v >= 0.0 && v <= f.kind.type_max()));
        }
    }
});
