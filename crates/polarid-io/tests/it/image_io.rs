//! Frame readers and writers: round trips for every supported type, and clear errors
//! (naming the file) for colour, multi-page, truncated and mismatched frames.

use std::path::Path;

use polarid_io::IoError;
use polarid_io::image::{self, SampleKind};

fn reason(e: IoError, file: &Path) -> String {
    let msg = e.to_string();
    assert!(msg.contains(&file.display().to_string()), "{msg}");
    match e {
        IoError::Image { reason, .. } => reason,
        other => panic!("expected IoError::Image, got {other:?}"),
    }
}

#[test]
fn round_trips_of_every_supported_type() {
    let d = tempfile::tempdir().unwrap();
    let (w, h) = (5, 3);
    let v8: Vec<u8> = (0..15).map(|i| (i * 17) as u8).collect();
    let v16: Vec<u16> = (0..15).map(|i| (i * 4000 + 7) as u16).collect();
    let vf: Vec<f32> = (0..15).map(|i| i as f32 * 0.25 - 1.0).collect();
    for ext in ["png", "tif"] {
        let p8 = d.path().join(format!("a8.{ext}"));
        image::write_gray8(&p8, false, w, h, &v8).unwrap();
        let f = image::read_frame(&p8).unwrap();
        assert_eq!(
            (f.width, f.height, f.kind, f.type_max()),
            (w, h, SampleKind::U8, 255.0)
        );
        assert_eq!(f.data, v8.iter().map(|&x| x as f32).collect::<Vec<_>>());
        let p16 = d.path().join(format!("a16.{ext}"));
        image::write_gray16(&p16, false, w, h, &v16).unwrap();
        let f = image::read_frame(&p16).unwrap();
        assert_eq!(
            (f.kind, f.bit_depth(), f.type_max()),
            (SampleKind::U16, 16, 65535.0)
        );
        assert_eq!(f.data, v16.iter().map(|&x| x as f32).collect::<Vec<_>>());
    }
    let pf = d.path().join("f.tif");
    image::write_tiff_f32(&pf, false, w, h, &vf).unwrap();
    let f = image::read_frame(&pf).unwrap();
    assert_eq!((f.kind, f.width, f.height), (SampleKind::F32, w, h));
    assert_eq!(f.data, vf);
    // Existing outputs are kept without force.
    assert!(matches!(
        image::write_tiff_f32(&pf, false, w, h, &vf),
        Err(IoError::OutputExists { .. })
    ));
    // Bad buffer sizes are refused and leave nothing.
    let bad = d.path().join("bad.png");
    assert!(image::write_gray8(&bad, false, 4, 4, &v8).is_err());
    assert!(!bad.exists());
}

#[test]
fn colour_images_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("rgb.png");
    image::write_rgb8_png(&p, false, 2, 2, &[10; 12]).unwrap();
    let r = reason(image::read_frame(&p).unwrap_err(), &p);
    assert!(r.contains("colour"), "{r}");
    // RGB TIFF.
    let t = d.path().join("rgb.tif");
    let mut buf = std::io::Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new(&mut buf)
        .unwrap()
        .write_image::<tiff::encoder::colortype::RGB8>(2, 2, &[1u8; 12])
        .unwrap();
    std::fs::write(&t, buf.into_inner()).unwrap();
    let r = reason(image::read_frame(&t).unwrap_err(), &t);
    assert!(r.contains("colour"), "{r}");
}

#[test]
fn multi_page_tiff_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let t = d.path().join("pages.tif");
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut enc = tiff::encoder::TiffEncoder::new(&mut buf).unwrap();
        for _ in 0..3 {
            enc.write_image::<tiff::encoder::colortype::Gray16>(2, 2, &[1u16; 4])
                .unwrap();
        }
    }
    std::fs::write(&t, buf.into_inner()).unwrap();
    let r = reason(image::read_frame(&t).unwrap_err(), &t);
    assert!(r.contains("multi-page") && r.contains("3 pages"), "{r}");
}

#[test]
fn truncated_corrupt_and_foreign_files_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let src = d.path().join("ok.png");
    image::write_gray16(&src, false, 64, 64, &vec![1234u16; 64 * 64]).unwrap();
    let bytes = std::fs::read(&src).unwrap();
    let cut = d.path().join("cut.png");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let r = reason(image::read_frame(&cut).unwrap_err(), &cut);
    assert!(r.contains("truncated or corrupt"), "{r}");
    let srct = d.path().join("ok.tif");
    image::write_tiff_f32(&srct, false, 64, 64, &vec![1.0; 64 * 64]).unwrap();
    let bytes = std::fs::read(&srct).unwrap();
    let cutt = d.path().join("cut.tif");
    std::fs::write(&cutt, &bytes[..bytes.len() / 3]).unwrap();
    let r = reason(image::read_frame(&cutt).unwrap_err(), &cutt);
    assert!(r.contains("truncated or corrupt"), "{r}");
    let txt = d.path().join("notes.png");
    std::fs::write(&txt, "hello").unwrap();
    let r = reason(image::read_frame(&txt).unwrap_err(), &txt);
    assert!(r.contains("not a PNG or TIFF"), "{r}");
    let missing = d.path().join("missing.png");
    let e = image::read_frame(&missing).unwrap_err();
    assert!(e.is_bad_input() && e.to_string().contains("missing.png"));
}

#[test]
fn frames_of_different_sizes_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let a = d.path().join("a.png");
    let b = d.path().join("b.tif");
    image::write_gray8(&a, false, 4, 4, &[0; 16]).unwrap();
    image::write_gray8(&b, false, 4, 2, &[0; 8]).unwrap();
    let r = reason(image::read_frames(&[&a, &b]).unwrap_err(), &b);
    assert!(
        r.contains("4x2") && r.contains("4x4") && r.contains("same size"),
        "{r}"
    );
}
