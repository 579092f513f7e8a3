"""polarid.stokes / demosaic / dolp / aolp: exact values, conventions, errors."""

import numpy as np
import pytest

import polarid

ANGLES = [0.0, 45.0, 90.0, 135.0]


def frames_of(s, angles_deg):
    """Frames I(a) = (S0 + S1 cos 2a + S2 sin 2a) / 2 of Stokes images s (3, H, W)."""
    a = np.radians(np.asarray(angles_deg))[:, None, None]
    return 0.5 * (s[0] + s[1] * np.cos(2 * a) + s[2] * np.sin(2 * a))


@pytest.fixture
def stokes_truth():
    rng = np.random.default_rng(1)
    s0 = rng.uniform(10, 200, (7, 9))
    dolp = rng.uniform(0, 0.9, s0.shape)
    aolp = rng.uniform(0, np.pi, s0.shape)
    return np.stack([s0, s0 * dolp * np.cos(2 * aolp), s0 * dolp * np.sin(2 * aolp)])


def test_stokes_recovers_truth_any_angle_set(stokes_truth):
    for angles in (ANGLES, [0, 60, 120], [10, 50, 95, 130, 170]):
        f = frames_of(stokes_truth, angles).astype(np.float32)
        s = polarid.stokes(f, angles)
        assert s.shape == (3, 7, 9) and s.dtype == np.float32
        np.testing.assert_allclose(s, stokes_truth, rtol=0, atol=2e-4 * stokes_truth[0].max())


def test_stokes_standard_set_is_exact_differences():
    f = np.random.default_rng(2).integers(0, 4096, (4, 5, 6)).astype(np.uint16)
    s, mask = polarid.stokes(f, ANGLES, return_mask=True)
    fi = f.astype(np.float64)
    np.testing.assert_array_equal(s[0], (0.5 * fi.sum(0)).astype(np.float32))
    np.testing.assert_array_equal(s[1], (fi[0] - fi[2]).astype(np.float32))
    np.testing.assert_array_equal(s[2], (fi[1] - fi[3]).astype(np.float32))
    assert mask.dtype == np.uint8 and mask.shape == (5, 6)


def test_stokes_dtypes_agree_and_dark_level():
    f = np.random.default_rng(3).integers(20, 250, (4, 8, 8))
    ref = polarid.stokes(f.astype(np.float32), ANGLES, dark_level=10)
    for dt in (np.uint8, np.uint16, np.float64, np.int32):
        np.testing.assert_array_equal(polarid.stokes(f.astype(dt), ANGLES, dark_level=10), ref)
    np.testing.assert_array_equal(ref[0], 0.5 * (f.sum(0) - 40).astype(np.float32))


def test_stokes_mask_saturation_and_dark():
    f = np.full((4, 2, 3), 100, np.uint8)
    f[2, 0, 0] = 255  # saturated (uint8 default level 255)
    f[:, 1, 2] = 0  # dark (S0 <= 0)
    _, mask = polarid.stokes(f, ANGLES, return_mask=True)
    assert mask[0, 0] == 1 and mask[1, 2] == 2 and mask.sum() == 3
    _, mask = polarid.stokes(f, ANGLES, saturation=100, return_mask=True)
    assert (mask[0] == 1).all()


def test_stokes_errors():
    f = np.zeros((3, 4, 4), np.float32)
    with pytest.raises(ValueError, match=r"angles_deg gives 4 angle\(s\) for 3 frame\(s\)"):
        polarid.stokes(f, ANGLES)
    with pytest.raises(ValueError, match=r"polarizer angles \[0\.0, 90\.0, 180\.0\] \(degrees\) are singular"):
        polarid.stokes(f, [0, 90, 180])
    with pytest.raises(ValueError, match="need at least 3 polarizer angles, got 2"):
        polarid.stokes(f[:2], [0, 90])
    with pytest.raises(ValueError, match="dark_level must be a finite number >= 0 within the float32 range, got -1"):
        polarid.stokes(f, [0, 60, 120], dark_level=-1)
    with pytest.raises(ValueError, match="must hold real numbers"):
        polarid.stokes(np.zeros((3, 2, 2), complex), [0, 60, 120])


def mosaic_of(images4, pattern=(90, 45, 135, 0)):
    """A DoFP raw frame from four full-resolution images at 0, 45, 90, 135."""
    h, w = images4.shape[1:]
    raw = np.empty((h, w), images4.dtype)
    for pos, a in enumerate(pattern):
        r, c = divmod(pos, 2)
        raw[r::2, c::2] = images4[int(a) // 45][r::2, c::2]
    return raw


def test_demosaic_superpixel_and_angles():
    rng = np.random.default_rng(4)
    img = rng.integers(0, 4000, (4, 6, 8)).astype(np.uint16)
    for pattern in [(90, 45, 135, 0), (0, 45, 135, 90)]:
        raw = mosaic_of(img, pattern)
        ang = polarid.demosaic(raw, pattern, method="superpixel", output="angles")
        assert ang.shape == (4, 3, 4)
        for k, a in enumerate((0, 45, 90, 135)):
            r, c = divmod(list(pattern).index(a), 2)
            np.testing.assert_array_equal(ang[k], raw[r::2, c::2])
        s = polarid.demosaic(raw, pattern, method="superpixel")
        np.testing.assert_array_equal(s, polarid.stokes(ang, [0, 45, 90, 135]))


def test_demosaic_bilinear_uniform_field_is_exact():
    # A uniform polarized field: every interpolation returns the channel's own value.
    s_true = np.array([100.0, 30.0, -20.0])
    img = frames_of(np.broadcast_to(s_true[:, None, None], (3, 8, 10)), [0, 45, 90, 135])
    raw = mosaic_of(img.astype(np.float32))
    s = polarid.demosaic(raw)
    assert s.shape == (3, 8, 10)
    np.testing.assert_allclose(s.reshape(3, -1), np.repeat(s_true[:, None], 80, 1), atol=1e-4)
    ang = polarid.demosaic(raw, output="angles")
    np.testing.assert_allclose(ang, img, atol=1e-4)


def test_demosaic_errors():
    with pytest.raises(ValueError, match=r"invalid 2x2 polarizer pattern \[0\.0, 45\.0, 90\.0, 90\.0\]"):
        polarid.demosaic(np.zeros((4, 4)), (0, 45, 90, 90))
    with pytest.raises(ValueError, match="even width and height"):
        polarid.demosaic(np.zeros((5, 4), np.uint8))
    with pytest.raises(ValueError, match="method must be"):
        polarid.demosaic(np.zeros((4, 4)), method="nearest")
    with pytest.raises(ValueError, match="2-D mosaic"):
        polarid.demosaic(np.zeros((2, 4, 4)))


def test_dolp_aolp_conventions():
    s = np.array([[2.0, 2.0, 2.0, 1.0, 0.0], [0.0, -1.0, 1.0, 3.0, 1.0], [1.0, -1e-9, -1e-3, 0.0, 0.0]])
    d, a = polarid.dolp_aolp(s)
    assert d.dtype == np.float64
    np.testing.assert_allclose(d[:3], [0.5, 0.5, np.hypot(1, 1e-3) / 2])
    assert d[3] == 1.0  # clamped
    assert np.isnan(d[4]) and np.isnan(a[4])  # S0 <= 0
    np.testing.assert_allclose(a[0], 45.0)
    assert abs(a[1] - 90.0) < 1e-6 and 179.9 < a[2] < 180.0
    np.testing.assert_array_equal(polarid.dolp(s), d)
    np.testing.assert_array_equal(polarid.aolp(s), a)
    # float32: the CLI's kernel, same values to float32 accuracy
    d32, a32 = polarid.dolp_aolp(s.astype(np.float32))
    assert d32.dtype == np.float32
    np.testing.assert_allclose(d32[:4], d[:4], atol=1e-6)
    np.testing.assert_allclose(a32[:4], a[:4], atol=1e-3)
    with pytest.raises(ValueError, match=r"shape \(3, \.\.\.\)"):
        polarid.dolp(np.zeros((2, 5)))


def test_dolp_aolp_of_random_fields(stokes_truth):
    d, a = polarid.dolp_aolp(stokes_truth)
    s0, s1, s2 = stokes_truth
    np.testing.assert_allclose(d, np.hypot(s1, s2) / s0, rtol=1e-14)
    np.testing.assert_allclose(a, np.degrees(np.arctan2(s2, s1) / 2) % 180, atol=1e-10)
