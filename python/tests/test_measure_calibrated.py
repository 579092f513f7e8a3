"""polarid.measure on a calibrated manifest ([camera], lamp sources): the same rows as
`polarid measure`, with the per-pixel geometry columns beta_sd_deg, aolp_deg,
aolp_poi_deg (docs/GEOMETRY.md)."""

import math
import subprocess

import numpy as np
import pytest

import polarid
from conftest import read_csv

cv2 = pytest.importorskip("cv2")

W, H = 64, 48

MANIFEST = """[camera]
focal_px = [60.0, 60.0]
principal_point_px = [31.5, 23.5]
position = [0.5, 0.0, 0.6]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]

[[region]]
name = "A"
rect = [20, 14, 24, 20]

[[capture]]
source = { position = [-0.4, 0.0, 0.6] }
stokes = { s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }

[[capture]]
source = { position = [-0.3, 0.3, 0.5] }
stokes = { s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }
"""


def test_measure_calibrated_identical_to_cli(tmp_path, polarid_cli):
    rng = np.random.default_rng(5)
    for name, val in (("s0", 1000.0), ("s1", -300.0), ("s2", 40.0)):
        img = (val + 5.0 * rng.standard_normal((H, W))).astype(np.float32)
        assert cv2.imwrite(str(tmp_path / f"{name}.tif"), img)
    path = tmp_path / "m.toml"
    path.write_text(MANIFEST)
    out = tmp_path / "m.csv"
    subprocess.run([str(polarid_cli), "measure", str(path), "-o", str(out)], check=True,
                   capture_output=True)
    cli = read_csv(out)
    py = polarid.measure(path)
    assert list(py["target"]) == cli["target"] == ["A", "A"]
    for col in ("theta_i_deg", "theta_r_deg", "phi_deg", "beta_deg", "dolp", "dolp_se", "s0",
                "beta_sd_deg", "aolp_deg", "aolp_poi_deg"):
        want = np.array([float(v) if v else np.nan for v in cli[col]])
        np.testing.assert_array_equal(py[col], want, err_msg=col)
    assert (py["beta_sd_deg"] > 0).all()
    # The second lamp is out of the plane of incidence.
    assert abs(py["phi_deg"][1] - 180.0) > 10.0
    # The image-frame AoLP of the mean (S1 < 0, small S2): about 90 degrees.
    assert abs(py["aolp_deg"][0] - 0.5 * math.degrees(math.atan2(40.0, -300.0))) < 0.5


def test_far_field_rows_have_nan_in_the_calibrated_columns(tmp_path):
    for name, val in (("s0", 1000.0), ("s1", 300.0), ("s2", 0.0)):
        cv2.imwrite(str(tmp_path / f"{name}.tif"), np.full((H, W), val, np.float32))
    path = tmp_path / "m.toml"
    path.write_text('theta_r_deg = 50\n[[region]]\nname = "A"\nrect = [0, 0, 8, 8]\n'
                    '[[capture]]\ntheta_i_deg = 40\n'
                    'stokes = { s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }\n')
    py = polarid.measure(path)
    for col in ("beta_sd_deg", "aolp_deg", "aolp_poi_deg"):
        assert np.isnan(py[col]).all()


def test_load_manifest_and_beta_map_of_calibrated_captures(tmp_path):
    """A calibrated capture has no single β: load_manifest says so (beta_deg None) and
    beta_map gives β per pixel, whose mean over the region is the measured beta_deg."""
    rng = np.random.default_rng(6)
    for name, val in (("s0", 1000.0), ("s1", -300.0), ("s2", 40.0)):
        img = (val + 0.01 * rng.standard_normal((H, W))).astype(np.float32)
        assert cv2.imwrite(str(tmp_path / f"{name}.tif"), img)
    path = tmp_path / "m.toml"
    path.write_text(MANIFEST)
    m = polarid.load_manifest(path)
    assert m["calibrated"] is True
    assert all(c["calibrated"] and c["beta_deg"] is None for c in m["captures"])
    rows = polarid.measure(path)
    for i in range(2):
        b = polarid.beta_map(path, i)
        assert b.shape == (H, W) and b.dtype == np.float32
        x, y, w, h = m["regions"][0]["rect"]
        region = b[y:y + h, x:x + w]
        assert np.isfinite(region).all()
        # β varies across the region, and its mean is the row's (S0 nearly uniform).
        assert region.max() - region.min() > 1.0
        assert abs(region.mean() - rows["beta_deg"][i]) < 0.05, (region.mean(), rows["beta_deg"][i])
    assert not np.array_equal(polarid.beta_map(path, 0), polarid.beta_map(path, 1))
    with pytest.raises(ValueError, match="out of range"):
        polarid.beta_map(path, 2)


def test_beta_map_refuses_far_field_captures(tmp_path):
    for name in ("s0", "s1", "s2"):
        assert cv2.imwrite(str(tmp_path / f"{name}.tif"), np.full((H, W), 100.0, np.float32))
    path = tmp_path / "far.toml"
    path.write_text('theta_r_deg = 45.0\n[[region]]\nname = "A"\nrect = [0, 0, 8, 8]\n'
                    '[[capture]]\ntheta_i_deg = 40.0\n'
                    'stokes = { s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }\n')
    m = polarid.load_manifest(path)
    assert m["calibrated"] is False and m["captures"][0]["beta_deg"] > 0
    with pytest.raises(ValueError, match="far-field"):
        polarid.beta_map(path, 0)
