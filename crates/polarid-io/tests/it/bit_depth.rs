//! The bit depth a frame's file records (PNG sBIT, TIFF MaxSampleValue) sets the default
//! saturation level; what the data say against a level is reported.

use std::path::PathBuf;

use polarid_io::image::{self, SampleKind};
use polarid_io::manifest::Capture;
use polarid_io::measure::{rules_for, saturation_notes};

#[test]
fn recorded_bit_depth_round_trips_and_sets_the_saturation() {
    let d = tempfile::tempdir().unwrap();
    let data: Vec<u16> = (0..64).map(|i| i * 60).collect();
    for name in ["f.png", "f.tif"] {
        let p = d.path().join(name);
        image::write_gray16_bits(&p, false, 8, 8, &data, 12).unwrap();
        let f = image::read_frame(&p).unwrap();
        assert_eq!(f.kind, SampleKind::U16);
        assert_eq!(f.recorded_max, Some(4095.0), "{name}");
        assert_eq!(rules_for(&f, 0.0, None).saturation, 4095.0);
        // The manifest's value wins.
        assert_eq!(rules_for(&f, 0.0, Some(4000.0)).saturation, 4000.0);
        // Without a record: the type's maximum.
        let q = d.path().join(format!("plain_{name}"));
        image::write_gray16(&q, false, 8, 8, &data).unwrap();
        let g = image::read_frame(&q).unwrap();
        assert_eq!(g.recorded_max, None);
        assert_eq!(rules_for(&g, 0.0, None).saturation, 65535.0);
    }
    // 16 significant bits record nothing below the type's maximum.
    let p = d.path().join("full.png");
    image::write_gray16_bits(&p, false, 8, 8, &data, 16).unwrap();
    assert_eq!(image::read_frame(&p).unwrap().recorded_max, None);
    // A sample that does not fit the bits is refused.
    let e = image::write_gray16_bits(&d.path().join("x.png"), false, 8, 8, &[5000; 64], 12)
        .unwrap_err();
    assert!(e.to_string().contains("does not fit in 12 bits"), "{e}");
}

fn capture(saturation: Option<f64>) -> Capture {
    Capture {
        index: 2,
        line: 9,
        name: None,
        theta_i_deg: 40.0,
        theta_r_deg: 60.0,
        phi_deg: 180.0,
        illumination: None,
        exposure: 1.0,
        dark_level: 0.0,
        saturation,
        angle_sd_deg: None,
        dark_signal_dn: None,
        source: polarid_io::manifest::CaptureSource::Dofp {
            file: PathBuf::from("raw.png"),
            pattern: Default::default(),
        },
        brackets: Vec::new(),
        wavelength_nm: None,
    }
}

fn frame(max: f32, recorded_max: Option<f32>) -> image::Frame {
    image::Frame {
        path: PathBuf::from("raw.png"),
        width: 2,
        height: 2,
        kind: SampleKind::U16,
        data: vec![100.0, 200.0, 300.0, max],
        recorded_max,
    }
}

#[test]
fn data_that_contradict_the_saturation_level_are_reported() {
    // 12-bit data (clipped at 4095) in a file that records no depth: the ceiling.
    let f = frame(4095.0, None);
    let w = saturation_notes(&capture(None), [&f], 65535.0);
    assert_eq!(w.len(), 1);
    assert!(
        w[0].starts_with("capture 2 (line 9): the values of raw.png stop at exactly 4095")
            && w[0].contains("set `saturation = 4095`"),
        "{w:?}"
    );
    // Dim unrecorded 16-bit data: they may be 12-bit.
    let f = frame(3000.0, None);
    let w = saturation_notes(&capture(None), [&f], 65535.0);
    assert!(
        w.len() == 1 && w[0].contains("records no bit depth") && w[0].contains("4095 for 12"),
        "{w:?}"
    );
    // ... unless the manifest gives the level.
    assert!(saturation_notes(&capture(Some(65535.0)), [&f], 65535.0).is_empty());
    // Values above a bit depth's ceiling.
    let f = frame(9000.0, Some(4095.0));
    let w = saturation_notes(&capture(None), [&f], 4095.0);
    assert!(
        w.len() == 1 && w[0].contains("values up to 9000, above the saturation level 4095"),
        "{w:?}"
    );
    // Bright 16-bit data and float frames: nothing to say.
    assert!(saturation_notes(&capture(None), [&frame(40000.0, None)], 65535.0).is_empty());
    let mut fl = frame(1.5, None);
    fl.kind = SampleKind::F32;
    assert!(saturation_notes(&capture(None), [&fl], f32::INFINITY).is_empty());
}

/// `polarid init` (`frames_dir`) and `measure` (`Frame::recorded_max`) read one saturation
/// level from a recorded bit depth: 12 significant bits in 16-bit samples are 4095, also
/// when every value happens to be a multiple of 16 (which once read as 12 bits shifted to
/// the top, 65520).
#[test]
fn init_and_measure_agree_on_a_recorded_bit_depth() {
    use polarid_io::frames_dir::{SensorDepth, frame_stats};
    let d = tempfile::tempdir().unwrap();
    // Multiples of 16 below 4096: the low four bits are zero in every pixel.
    let data: Vec<u16> = (0..64).map(|i| i * 64).collect();
    for name in ["f.png", "f.tif"] {
        let p = d.path().join(name);
        image::write_gray16_bits(&p, false, 8, 8, &data, 12).unwrap();
        let frame = image::read_frame(&p).unwrap();
        let stats = frame_stats(&p).unwrap();
        assert_eq!(stats.zero_low_bits, 6, "{name}");
        assert_eq!(stats.recorded_max, frame.recorded_max, "{name}");
        let depth = SensorDepth::infer(&[stats]);
        let measured = rules_for(&frame, 0.0, None).saturation;
        assert_eq!(measured, 4095.0, "{name}");
        assert_eq!(
            depth.saturation,
            Some(f64::from(measured)),
            "{name}: {depth:?}"
        );
        assert_eq!((depth.bits, depth.shift), (Some(12), 0), "{name}");
        assert!(
            depth.evidence.contains("12 significant bits"),
            "{}",
            depth.evidence
        );
    }
    // The one rule, for each sample type.
    assert_eq!(
        image::recorded_max_of_bits(SampleKind::U16, 12),
        Some(4095.0)
    );
    assert_eq!(image::recorded_max_of_bits(SampleKind::U16, 16), None);
    assert_eq!(image::recorded_max_of_bits(SampleKind::U8, 8), None);
    assert_eq!(image::recorded_max_of_bits(SampleKind::U8, 6), Some(63.0));
    assert_eq!(image::recorded_max_of_bits(SampleKind::U16, 0), None);
}
