//! The manifest's `[camera] opencv` reader on files written by OpenCV itself
//! (`cv2.FileStorage`, tests/data/opencv/, OpenCV 5.1.0), and — when a Python with
//! OpenCV is at hand (`POLARID_PYTHON`, or the repository's `.venv-test`) — on files
//! written now with random intrinsics, compared to the last bit.

use std::path::{Path, PathBuf};
use std::process::Command;

use polarid_io::manifest::opencv::{OpenCvKeys, read_opencv_calibration};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/opencv")
        .join(name)
}

#[test]
fn reads_what_opencv_writes() {
    for f in ["calib.yml", "calib.json", "calib.xml"] {
        let c = read_opencv_calibration(&data(f), &OpenCvKeys::default())
            .unwrap_or_else(|e| panic!("{f}: {e}"));
        assert_eq!(c.focal_px, [659.4, 659.4], "{f}");
        assert_eq!(c.principal_point_px, [239.5, 179.5], "{f}");
        assert_eq!(c.distortion, [-0.08, 0.02, 0.0, 0.0, 0.0], "{f}");
        assert_eq!(c.image_size, Some([480, 360]), "{f}");
    }
    let c = read_opencv_calibration(&data("d14.yml"), &OpenCvKeys::default()).unwrap();
    assert_eq!(
        (c.camera_matrix_key.as_str(), c.distortion_key.as_str()),
        ("K", "D")
    );
    assert_eq!(c.distortion, [0.0; 5]);
}

fn python() -> Option<PathBuf> {
    let p = std::env::var_os("POLARID_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv-test/bin/python")
        });
    let ok = Command::new(&p)
        .args(["-c", "import cv2, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(p)
}

#[test]
fn round_trip_through_opencv_when_available() {
    let Some(py) = python() else {
        eprintln!("skipped: no Python with OpenCV (set POLARID_PYTHON)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let script = r#"
import sys, cv2, numpy as np
rng = np.random.default_rng(int(sys.argv[2]))
K = np.array([[rng.uniform(300, 3000), 0, rng.uniform(100, 1200)],
              [0, rng.uniform(300, 3000), rng.uniform(100, 1000)], [0, 0, 1]])
D = rng.normal(0, 0.1, (1, 5))
for ext in ("yml", "json", "xml"):
    fs = cv2.FileStorage(sys.argv[1] + "/c." + ext, cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 2448); fs.write("image_height", 2048)
    fs.writeComment("flags: none")
    fs.write("camera_matrix", K); fs.write("distortion_coefficients", D)
    fs.release()
print(" ".join(repr(float(x)) for x in [K[0,0], K[1,1], K[0,2], K[1,2], *D.ravel()]))
"#;
    for seed in 0..5 {
        let out = Command::new(&py)
            .args([
                "-c",
                script,
                dir.path().to_str().unwrap(),
                &seed.to_string(),
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let want: Vec<f64> = String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        for ext in ["yml", "json", "xml"] {
            let c = read_opencv_calibration(
                &dir.path().join(format!("c.{ext}")),
                &OpenCvKeys::default(),
            )
            .unwrap_or_else(|e| panic!("{ext}: {e}"));
            let got = [
                c.focal_px[0],
                c.focal_px[1],
                c.principal_point_px[0],
                c.principal_point_px[1],
                c.distortion[0],
                c.distortion[1],
                c.distortion[2],
                c.distortion[3],
                c.distortion[4],
            ];
            assert_eq!(got.to_vec(), want, "seed {seed} {ext}");
            assert_eq!(c.image_size, Some([2448, 2048]));
        }
    }
}
