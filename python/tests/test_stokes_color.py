"""polarid.stokes_color: per-band Stokes, DoLP and AoLP of colour polarization mosaics,
bit for bit those of `polarid stokes --dofp RAW --color ...`, and the per-band physics
on mosaics of known Stokes vectors."""

import subprocess

import numpy as np
import pytest

import polarid

IMX = (90, 45, 135, 0)
QUANTITIES = ("s0", "s1", "s2", "dolp", "aolp")


def read_image(path):
    import cv2

    a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert a is not None, path
    return a


def mosaic(stokes_per_block, pattern=IMX, color="RGGB", shape=(4, 4)):
    """A colour mosaic of whole 4x4 periods: under block b of the period, the polarizer
    at angle a reads (S0 + S1 cos 2a + S2 sin 2a)/2 of the Stokes vector of b's colour."""
    ph, pw = shape
    raw = np.zeros((4 * ph, 4 * pw), dtype=np.float32)
    for y in range(4):
        for x in range(4):
            block = (y // 2) * 2 + x // 2
            s0, s1, s2 = stokes_per_block[color[block]]
            a = np.deg2rad(pattern[(y % 2) * 2 + x % 2])
            raw[y::4, x::4] = 0.5 * (s0 + s1 * np.cos(2 * a) + s2 * np.sin(2 * a))
    return raw


def test_known_stokes_per_band():
    """Uniform bands: every method gives each band's own Stokes vector, DoLP and AoLP."""
    truth = {"R": (1000.0, 300.0, -100.0), "G": (2000.0, -200.0, 400.0), "B": (500.0, 0.0, 50.0)}
    raw = mosaic(truth, shape=(5, 6))
    for method, shape in (("superpixel", (5, 6)), ("bilinear", (20, 24))):
        out = polarid.stokes_color(raw, "RGGB", IMX, method)
        assert list(out) == ["R", "G", "B"]
        assert [out[b]["wavelength_nm"] for b in out] == [650.0, 550.0, 450.0]
        for band, (s0, s1, s2) in truth.items():
            e = out[band]
            assert e["s0"].shape == shape and e["s0"].dtype == np.float32
            np.testing.assert_allclose(e["s0"], s0, rtol=1e-6)
            np.testing.assert_allclose(e["s1"], s1, atol=1e-3)
            np.testing.assert_allclose(e["s2"], s2, atol=1e-3)
            np.testing.assert_allclose(e["dolp"], np.hypot(s1, s2) / s0, rtol=1e-5)
            want = np.rad2deg(0.5 * np.arctan2(s2, s1)) % 180
            np.testing.assert_allclose(e["aolp"], want, atol=1e-4)
            assert e["counts"]["valid"] == shape[0] * shape[1]


def test_options():
    truth = {"R": (1000.0, 300.0, 0.0), "G": (1000.0, 0.0, 0.0), "B": (10.0, 0.0, 0.0)}
    raw = mosaic(truth).astype(np.uint16)
    out = polarid.stokes_color(raw, "rggb", method="superpixel", bands={"r": 700, "G": 532, "B": 450},
                               quantities=("dolp",), return_mask=True, min_s0=20)
    assert [out[b]["wavelength_nm"] for b in "RGB"] == [700.0, 532.0, 450.0]
    assert set(out["R"]) == {"wavelength_nm", "dolp", "mask", "counts"}
    assert (out["B"]["mask"] == 2).all() and np.isnan(out["B"]["dolp"]).all()  # dark
    assert out["B"]["counts"]["dark"] == 16 and out["R"]["counts"]["valid"] == 16
    # Saturation and the dark level as `polarid stokes`.
    sat = polarid.stokes_color(raw, saturation=600, method="superpixel", return_mask=True)
    assert (sat["R"]["mask"] == 1).all() and (sat["G"]["mask"] == 0).all()
    dark = polarid.stokes_color(raw, dark_level=5, method="superpixel")
    np.testing.assert_allclose(dark["G"]["s0"], 1000 - 2 * 5)
    # A band table replaces the default one (as the manifest's `bands` and --bands).
    with pytest.raises(ValueError, match="colour B has no wavelength"):
        polarid.stokes_color(raw, "RGGB", bands={"R": 700, "G": 532})
    # Four bands: a letter without a default wavelength needs one.
    with pytest.raises(ValueError, match="colour N has no wavelength"):
        polarid.stokes_color(raw, "RGBN")
    four = polarid.stokes_color(raw, "RGBN", bands={"R": 650, "G": 550, "B": 450, "N": 850})
    assert list(four) == ["R", "G", "B", "N"] and four["N"]["wavelength_nm"] == 850.0
    for bad, match in [(dict(color="RGB"), "colour pattern"), (dict(method="nearest"), "method must be"),
                       (dict(quantities=("s3",)), "quantities"), (dict(bands={"RG": 1.0}), "single colour letters"),
                       (dict(bands={"R": -1.0}), "must be > 0 nm"), (dict(pattern=(0, 0, 90, 135)), "distinct")]:
        with pytest.raises(ValueError, match=match):
            polarid.stokes_color(raw, **bad)
    with pytest.raises(ValueError):
        polarid.stokes_color(raw[:6, :8])  # not whole 4x4 periods


@pytest.mark.parametrize("method", ["bilinear", "superpixel"])
def test_equals_cli(polarid_cli, tmp_path, method):
    """The same raw through `polarid stokes --dofp RAW --color RGGB`: identical float32
    images per band (NaN at the same pixels)."""
    import cv2

    rng = np.random.default_rng(17)
    h, w = 48, 64
    yy, xx = np.mgrid[0:h, 0:w]
    base = 800 + 20 * xx + 10 * yy + 300 * ((xx // 9 + yy // 7) % 2)  # ramps and edges
    raw = (base + rng.normal(0, 30, (h, w))).clip(0, 65535).astype(np.uint16)
    raw[5, 7] = 4000  # saturated below
    raw[30:34, 40:44] = 3  # dark
    path = tmp_path / "raw.tif"
    assert cv2.imwrite(str(path), raw)
    out = tmp_path / "cli"
    subprocess.run([str(polarid_cli), "stokes", "--dofp", str(path), "--color", "RGGB", "--demosaic", method,
                    "--dark-level", "2", "--saturation", "3500", "-o", str(out)],
                   check=True, capture_output=True)
    got = polarid.stokes_color(raw, "RGGB", method=method, dark_level=2, saturation=3500)
    for band in got.values():
        nm = f"{band['wavelength_nm']:.0f}"
        for q in QUANTITIES:
            cli = read_image(out / f"{q}_{nm}.tif")
            np.testing.assert_array_equal(band[q], cli, err_msg=f"{q} {nm}")
    assert sum(b["counts"]["saturated"] for b in got.values()) > 0
