"""polarid.dofp_dolp_aolp (fused DoFP raw -> DoLP / AoLP) and demosaic(dtype=, out=):
equality with the unfused path, masking, polanalyser agreement, errors."""

import numpy as np
import pytest

import polarid

PATTERNS = [(90, 45, 135, 0), (0, 45, 90, 135), (45, 135, 0, 90), (135, 0, 45, 90)]


def mosaic(h, w, dtype, seed):
    rng = np.random.default_rng(seed)
    if dtype == np.float32:
        return rng.uniform(0.0, 4000.0, (h, w)).astype(np.float32)
    top = 250 if dtype == np.uint8 else 60000
    return rng.integers(5, top, (h, w)).astype(dtype)


def unfused(raw, pattern, method, **kw):
    """demosaic -> Stokes + mask, then dolp_aolp, NaN where the mask rejects."""
    s, mask = polarid.demosaic(raw, pattern, method, return_mask=True, **kw)
    d, a = polarid.dolp_aolp(s)
    d[mask != 0] = np.nan
    a[mask != 0] = np.nan
    return s, mask, d, a


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("method", ["bilinear", "superpixel"])
@pytest.mark.parametrize("shape", [(4, 4), (6, 10), (10, 6), (34, 1046)])
def test_fused_equals_unfused_bit_for_bit(dtype, method, shape):
    for i, pattern in enumerate(PATTERNS):
        raw = mosaic(*shape, dtype, seed=10 * i + shape[1])
        s, mask, d_ref, a_ref = unfused(raw, pattern, method)
        d, a, s2, m2 = polarid.dofp_dolp_aolp(
            raw, pattern, method, return_stokes=True, return_mask=True
        )
        oh, ow = (shape if method == "bilinear" else (shape[0] // 2, shape[1] // 2))
        assert d.shape == a.shape == (oh, ow) and d.dtype == a.dtype == np.float32
        np.testing.assert_array_equal(d.view(np.uint32), d_ref.view(np.uint32))
        np.testing.assert_array_equal(a.view(np.uint32), a_ref.view(np.uint32))
        np.testing.assert_array_equal(s2.view(np.uint32), s.view(np.uint32))
        np.testing.assert_array_equal(m2, mask)
        # Only DoLP and AoLP asked for: the same numbers.
        d1, a1 = polarid.dofp_dolp_aolp(raw, pattern, method)
        np.testing.assert_array_equal(d1.view(np.uint32), d.view(np.uint32))
        np.testing.assert_array_equal(a1.view(np.uint32), a.view(np.uint32))


def test_rules_and_rounding_are_those_of_demosaic():
    raw = mosaic(40, 44, np.uint16, seed=4) // 3  # 1..19999: S0 about 20000
    rules = dict(saturation=19900.0, min_s0=20000.0)
    for kw in (
        dict(dark_level=30.0, **rules),
        dict(round=False),
        dict(round=False, dark_level=7.5),
    ):
        _, mask, d_ref, a_ref = unfused(raw, PATTERNS[0], "bilinear", **kw)
        d, a, m = polarid.dofp_dolp_aolp(raw, PATTERNS[0], "bilinear", return_mask=True, **kw)
        np.testing.assert_array_equal(m, mask)
        np.testing.assert_array_equal(d.view(np.uint32), d_ref.view(np.uint32))
        np.testing.assert_array_equal(a.view(np.uint32), a_ref.view(np.uint32))
    # the thresholds reject something in this data, and NaN marks exactly the rejections
    d, _, m = polarid.dofp_dolp_aolp(raw, return_mask=True, **rules)
    assert (m == 1).any() and (m == 2).any() and (m == 0).any()
    assert np.array_equal(np.isnan(d), m != 0)


def test_saturated_pixel_rejects_its_neighbourhood():
    raw = np.full((8, 8), 1000, np.uint16)
    raw[3, 4] = 65535
    d, a, m = polarid.dofp_dolp_aolp(raw, return_mask=True)
    expect = np.zeros((8, 8), bool)
    expect[2:5, 3:6] = True
    np.testing.assert_array_equal(m == 1, expect)
    assert np.isnan(d[expect]).all() and np.isnan(a[expect]).all()
    assert np.isfinite(d[~expect]).all()
    d, _, m = polarid.dofp_dolp_aolp(raw, method="superpixel", return_mask=True)
    assert m[1, 2] == 1 and (m == 1).sum() == 1 and np.isnan(d[1, 2])


def test_known_polarization_is_recovered():
    # A uniform field with DoLP 0.3 and AoLP 30 degrees, pattern 90,45,135,0.
    s0, p, t = 2000.0, 0.3, np.radians(30.0)
    inten = {a: 0.5 * s0 * (1 + p * np.cos(2 * t - 2 * np.radians(a))) for a in (0, 45, 90, 135)}
    raw = np.empty((16, 20), np.float32)
    raw[0::2, 0::2], raw[0::2, 1::2] = inten[90], inten[45]
    raw[1::2, 0::2], raw[1::2, 1::2] = inten[135], inten[0]
    for method in ("bilinear", "superpixel"):
        d, a = polarid.dofp_dolp_aolp(raw, method=method)
        np.testing.assert_allclose(d, 0.3, atol=1e-6)
        np.testing.assert_allclose(a, 30.0, atol=1e-4)


def test_agrees_with_polanalyser():
    pa = pytest.importorskip("polanalyser")
    raw = mosaic(32, 48, np.uint16, seed=7)
    imgs = pa.demosaicing(raw, pa.COLOR_PolarMono)
    st = pa.calcStokes(imgs, np.radians([0, 45, 90, 135]))
    d_pa, a_pa = pa.cvtStokesToDoLP(st), pa.cvtStokesToAoLP(st)
    d, a = polarid.dofp_dolp_aolp(raw)
    ok = np.isfinite(d) & (d_pa <= 1)  # polarid clamps DoLP to [0, 1]
    assert ok.mean() > 0.9
    np.testing.assert_allclose(d[ok], d_pa[ok], rtol=0, atol=2e-6)
    sel = ok & (d > 0.01)
    diff = np.angle(np.exp(2j * (np.radians(a[sel]) - a_pa[sel]))) / 2
    assert np.abs(diff).max() < 1e-5


def test_fused_into_caller_arrays():
    raw = mosaic(10, 12, np.uint16, seed=3)
    d_ref, a_ref = polarid.dofp_dolp_aolp(raw)
    out = (np.full((10, 12), 5.0, np.float32), np.full((10, 12), 5.0, np.float32))
    for _ in range(2):  # reused
        d, a = polarid.dofp_dolp_aolp(raw, out=out)
        assert d is out[0] and a is out[1]
        np.testing.assert_array_equal(d, d_ref)
        np.testing.assert_array_equal(a, a_ref)
    small = (out[0][:5, :6].copy(), out[1][:5, :6].copy())
    d, a, m = polarid.dofp_dolp_aolp(raw, method="superpixel", out=small, return_mask=True)
    assert d is small[0] and a is small[1]
    assert d.shape == m.shape == (5, 6)
    with pytest.raises(ValueError, match="out\\[1\\] must be .* shape \\(10, 12\\)"):
        polarid.dofp_dolp_aolp(raw, out=(out[0], np.zeros((12, 10), np.float32)))
    with pytest.raises(ValueError, match="out\\[0\\] must be .* dtype float32"):
        polarid.dofp_dolp_aolp(raw, out=(np.zeros((10, 12)), out[1]))
    with pytest.raises(ValueError, match="two different arrays"):
        polarid.dofp_dolp_aolp(raw, out=(out[0], out[0]))


def test_demosaic_integer_dtype_and_out():
    raw = mosaic(10, 12, np.uint16, seed=8)
    ref = polarid.demosaic(raw, output="angles")
    u16 = polarid.demosaic(raw, output="angles", dtype=np.uint16)
    assert u16.dtype == np.uint16 and u16.shape == (4, 10, 12)
    np.testing.assert_array_equal(u16, ref.astype(np.uint16))
    np.testing.assert_array_equal(ref, u16.astype(np.float32))
    out = np.zeros((4, 10, 12), np.uint16)
    got = polarid.demosaic(raw, output="angles", out=out)  # dtype from out
    assert got is out
    np.testing.assert_array_equal(out, u16)
    sp = polarid.demosaic(raw, method="superpixel", output="angles", dtype="uint16")
    np.testing.assert_array_equal(sp, polarid.demosaic(raw, method="superpixel", output="angles"))
    r8 = mosaic(6, 8, np.uint8, seed=9)
    np.testing.assert_array_equal(
        polarid.demosaic(r8, output="angles", dtype=np.uint8),
        polarid.demosaic(r8, output="angles").astype(np.uint8),
    )
    # float32 angles and Stokes into caller-owned arrays
    outf = np.empty((4, 10, 12), np.float32)
    assert polarid.demosaic(raw, output="angles", dark_level=3.0, out=outf) is outf
    np.testing.assert_array_equal(outf, ref - np.float32(3.0))
    outs = np.empty((3, 10, 12), np.float32)
    s, m = polarid.demosaic(raw, out=outs, return_mask=True)
    assert s is outs
    np.testing.assert_array_equal(outs, polarid.demosaic(raw))


def test_demosaic_integer_output_matches_polanalyser():
    pa = pytest.importorskip("polanalyser")
    raw = mosaic(24, 30, np.uint16, seed=11)
    imgs = pa.demosaicing(raw, pa.COLOR_PolarMono)
    ours = polarid.demosaic(raw, output="angles", dtype=np.uint16)
    for k in range(4):
        np.testing.assert_array_equal(ours[k], imgs[k])


def test_bad_arguments_are_refused():
    raw = mosaic(8, 8, np.uint16, seed=1)
    with pytest.raises(ValueError, match="method must be"):
        polarid.dofp_dolp_aolp(raw, method="vng")
    with pytest.raises(ValueError, match="even width and height"):
        polarid.dofp_dolp_aolp(raw[:, :7])
    with pytest.raises(ValueError, match="2-D mosaic"):
        polarid.dofp_dolp_aolp(raw[0])
    with pytest.raises(ValueError, match="polarizer pattern"):
        polarid.dofp_dolp_aolp(raw, (0, 45, 90, 90))
    with pytest.raises(ValueError, match="dark_level=0"):
        polarid.demosaic(raw, output="angles", dtype=np.uint16, dark_level=2)
    with pytest.raises(ValueError, match="round=True"):
        polarid.demosaic(raw, output="angles", dtype=np.uint16, round=False)
    with pytest.raises(ValueError, match="uint8 raw mosaic"):
        polarid.demosaic(raw, output="angles", dtype=np.uint8)
    with pytest.raises(ValueError, match="needs output=\"angles\""):
        polarid.demosaic(raw, dtype=np.uint16)
    with pytest.raises(ValueError, match="shape \\(4, 8, 8\\)"):
        polarid.demosaic(raw, output="angles", out=np.zeros((4, 8, 6), np.float32))
    with pytest.raises(ValueError, match="dtype float32"):
        polarid.demosaic(raw, output="angles", dtype=np.float32, out=np.zeros((4, 8, 8)))
    with pytest.raises(ValueError, match="C-contiguous"):
        polarid.demosaic(raw, output="angles", out=np.zeros((4, 8, 16), np.float32)[:, :, ::2])
