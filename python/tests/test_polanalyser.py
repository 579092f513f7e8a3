"""Agreement of polarid's Stokes, DoLP and AoLP with polanalyser 3.0.0 on the same frames.

Convention differences (documented in the docstrings of polarid.stokes/dolp/aolp):

* layout: polanalyser returns Stokes vectors on the last axis, (H, W, 3), and its
  demosaiced images as a list [I0, I45, I90, I135]; polarid puts S0, S1, S2 (and the
  angles) on the first axis, (3, H, W).
* AoLP: polanalyser's ``cvtStokesToAoLP`` is in radians in [0, pi); polarid's ``aolp``
  is in degrees in [0, 180). Compared modulo pi after conversion.
* DoLP: polarid clamps to [0, 1] (noisy pixels can give sqrt(S1²+S2²) > S0) and returns
  NaN where S0 <= 0; polanalyser does neither.
* numbers: polarid's Stokes images are float32 (exact for integer frames: sums and
  differences of integers), polanalyser's float64; polarid's float32 DoLP/AoLP kernel
  is the one of ``polarid stokes``.
"""

import math

import numpy as np
import pytest

import polarid

cv2 = pytest.importorskip("cv2")
pa = pytest.importorskip("polanalyser")

ANGLES = np.array([0.0, 45.0, 90.0, 135.0])


def compare(s_pid, s_pa, label):
    """Assert and return agreement figures of Stokes (3, ...) vs polanalyser (..., 3)."""
    s_pa_first = np.moveaxis(s_pa, -1, 0)
    ds = np.abs(s_pid.astype(np.float64) - s_pa_first).max() / np.abs(s_pa_first).max()
    d, a = polarid.dolp_aolp(s_pid)
    d_pa = pa.cvtStokesToDoLP(s_pa)
    a_pa = pa.cvtStokesToAoLP(s_pa)
    ok = (s_pa[..., 0] > 0) & (d_pa <= 1)
    dd = np.abs(d[ok] - d_pa[ok]).max()
    # AoLP is only meaningful where the light is polarized at all.
    pol = ok & (d_pa > 1e-3)
    diff = np.radians(a[pol].astype(np.float64)) - a_pa[pol]
    diff = (diff + math.pi / 2) % math.pi - math.pi / 2
    da = np.abs(diff).max()
    # Clamping: where polanalyser's DoLP exceeds 1, polarid's is exactly 1.
    over = (s_pa[..., 0] > 0) & (d_pa > 1)
    assert (d[over] == 1).all()
    print(f"{label}: max |dS|/max|S| = {ds:.2e}, max |dDoLP| = {dd:.2e}, "
          f"max |dAoLP| = {da:.2e} rad over {pol.sum()} pixels ({over.sum()} clamped)")
    return ds, dd, da


@pytest.mark.parametrize("name", ["fruits", "camera"])
def test_real_dofp_frames(data_dir, name):
    path = data_dir / "real-dofp" / f"{name}_IMX250MZR.png"
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert raw is not None and raw.dtype == np.uint8 and raw.shape == (2048, 2448)
    imgs = pa.demosaicing(raw, pa.COLOR_PolarMono)
    # Same demosaicing (polarid rounds like OpenCV for integer input by default).
    ours = polarid.demosaic(raw, (90, 45, 135, 0), output="angles")
    for k in range(4):
        np.testing.assert_array_equal(ours[k], imgs[k])
    s_pa = pa.calcStokes(imgs, np.radians(ANGLES))
    s = polarid.demosaic(raw, (90, 45, 135, 0))
    ds, dd, da = compare(s, s_pa, name)
    assert ds <= 1e-6  # float32 of exact half-integers: identical
    assert dd <= 2e-6
    assert da <= 2e-6
    # Stokes from the demosaiced images with polarid.stokes (general least squares:
    # pseudo-inverse rounding, ~1e-14): the same.
    np.testing.assert_allclose(polarid.stokes(ours, ANGLES), s, rtol=0, atol=1e-4)


@pytest.mark.parametrize("angles", [[0, 45, 90, 135], [0, 60, 120], [15, 50, 100, 140, 170]])
def test_synthetic_frames(angles):
    rng = np.random.default_rng(7)
    h, w = 64, 80
    s0 = rng.uniform(100, 3000, (h, w))
    dol = rng.uniform(0, 1, (h, w))
    ao = rng.uniform(0, np.pi, (h, w))
    a = np.radians(np.asarray(angles, float))[:, None, None]
    frames = 0.5 * s0 * (1 + dol * np.cos(2 * a - 2 * ao))
    frames = np.clip(np.round(frames + rng.normal(0, 5, frames.shape)), 0, 4095).astype(np.uint16)
    s_pa = pa.calcStokes(frames.astype(np.float64), np.radians(angles))
    s = polarid.stokes(frames, angles)
    ds, dd, da = compare(s, s_pa, f"synthetic {angles}")
    assert ds <= 1e-6 and dd <= 1e-5 and da <= 2e-5
    # float64 path of dolp/aolp on polanalyser's own Stokes: agreement to rounding.
    d64, a64 = polarid.dolp_aolp(np.moveaxis(s_pa, -1, 0))
    d_pa = pa.cvtStokesToDoLP(s_pa)
    ok = d_pa <= 1
    np.testing.assert_allclose(d64[ok], d_pa[ok], rtol=1e-12, atol=1e-15)
    diff = (np.radians(a64) - pa.cvtStokesToAoLP(s_pa) + np.pi / 2) % np.pi - np.pi / 2
    assert np.abs(diff).max() < 1e-12
