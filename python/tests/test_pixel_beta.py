"""A β per pixel: ``polarid.fit_nk`` with angles broadcastable to the DoLP stack, and
``polarid.map_manifest`` on a manifest with calibrated geometry (a camera and a lamp at
a finite distance give every pixel its own angles)."""

import json
import subprocess

import numpy as np
import pytest

import polarid

BETA = np.linspace(30.0, 65.0, 8)


def cost(y, n, k, beta):
    """Σ (P(n, k, β) − y)² over the last axis."""
    return ((polarid.dolp_model(n[..., None], k[..., None], beta) - y) ** 2).sum(-1)


def varying(h=20, w=30, seed=1, sd=0.004):
    """An (h, w) stack whose angles drift by up to ±5° across the image, differently at
    each source position; (n, k) uniform in [0.5, 2.5] × [0, 5]."""
    rng = np.random.default_rng(seed)
    n = rng.uniform(0.5, 2.5, (h, w))
    k = rng.uniform(0.0, 5.0, (h, w))
    u = np.linspace(-1, 1, w)[None, :, None]
    v = np.linspace(-1, 1, h)[:, None, None]
    t = np.arange(BETA.size)
    beta = BETA + 5.0 * (u * np.cos(0.7 * t) + v * np.sin(0.7 * t))
    y = np.clip(polarid.dolp_model(n[..., None], k[..., None], beta) + rng.normal(0, sd, beta.shape), 0, 1)
    return n, k, beta, y


def test_shared_angles_per_pixel_give_the_shared_fit():
    """Angles given per pixel but equal everywhere: exactly the fit with one angle per
    measurement."""
    rng = np.random.default_rng(0)
    y = np.clip(polarid.dolp_model(rng.uniform(0.5, 3, (50, 1)), rng.uniform(0, 6, (50, 1)), BETA)
                + rng.normal(0, 0.005, (50, BETA.size)), 0, 1)
    a = polarid.fit_nk(y, BETA)
    b = polarid.fit_nk(y, np.broadcast_to(BETA, y.shape))
    c = polarid.fit_nk(y.reshape(5, 10, -1), BETA[None, None, :])  # 3-D β, broadcast
    for key in ("n", "k", "n_se", "k_se", "cost", "evaluations"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        np.testing.assert_array_equal(a[key], c[key].ravel(), err_msg=key)
    np.testing.assert_array_equal(b["status_code"], a["status_code"])


def test_per_pixel_angles_recover_nk():
    """Noisy pixels at their own angles: the global minimum at those angles for every
    pixel, close to the truth; the same data fitted at one set of angles miss."""
    n, k, beta, y = varying()
    f = polarid.fit_nk(y, beta)
    assert f["n"].shape == n.shape
    ok = f["status_code"] == f["status_names"].index("ok")
    assert ok.mean() > 0.95
    c_fit, c_true = cost(y, f["n"], f["k"], beta), cost(y, n, k, beta)
    assert (c_fit <= c_true * (1 + 1e-9) + 1e-14).all()
    within = (np.abs(f["n"] - n) <= 3 * f["n_se"]) & (np.abs(f["k"] - k) <= 3 * f["k_se"])
    assert within[ok].mean() > 0.9
    err = np.hypot(f["n"] - n, f["k"] - k)
    assert np.median(err) < 0.1
    # One set of angles (the image centre's) for every pixel: far worse.
    shared = polarid.fit_nk(y, BETA)
    assert np.median(np.hypot(shared["n"] - n, shared["k"] - k)) > 4 * np.median(err)
    # Angles that vary along the columns only, as a (1, w, T) array.
    row = polarid.fit_nk(y[:3], beta[:1])
    np.testing.assert_array_equal(row["n"][0], f["n"][0])


def test_per_pixel_statuses_and_errors():
    n, k, beta, y = varying(4, 5)
    beta = beta.copy()
    beta[0, 0, 3] = np.nan
    beta[0, 1, :] = 40.0
    beta[0, 2, :] = 40.0 + np.linspace(0, 2, BETA.size)
    f = polarid.fit_nk(y, beta, status_strings=True)
    assert f["status"][0, 0] == "invalid_input" and np.isnan(f["n"][0, 0])
    assert f["status"][0, 1] == "ill_conditioned"
    assert f["reasons"][f["reason_code"][0, 1]] == "fewer than 3 distinct source positions (beta)"
    assert f["status"][0, 2] == "ill_conditioned"
    assert f["reasons"][f["reason_code"][0, 2]] == "beta range narrower than 3 degrees"
    with pytest.raises(ValueError, match="cannot be broadcast"):
        polarid.fit_nk(y, beta[:, :2])
    with pytest.raises(ValueError, match="at least 3 angles"):
        polarid.fit_nk(y[..., :2], beta[..., :2])


# --- map_manifest with calibrated geometry ----------------------------------------------

W, H = 96, 80
FOCAL, CX, CY = 120.0, 47.5, 39.5
CAMERA = np.array([0.6, 0.0, 0.5])
LAMPS = [(-0.7 * np.sin(np.radians(z)), y, 0.7 * np.cos(np.radians(z)))
         for z, y in [(20, 0.0), (30, 0.06), (40, 0.0), (50, -0.06), (60, 0.0), (70, 0.05)]]
PLATES = [("copper", 1.01, 2.58, (8, 10, 36, 28)), ("gold", 1.38, 1.92, (52, 10, 36, 28)),
          ("titanium", 1.90, 2.60, (8, 44, 36, 28)), ("paint", 1.50, 0.30, (52, 44, 36, 28))]


def vec(v):
    """A TOML array of floats."""
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def pixel_beta(lamp, u=None, v=None):
    """β (degrees) at image points (u, v) (default: every pixel centre) of the bench
    plane z = 0 lit from `lamp`: the camera looks at the origin with +z up; β is half the
    angle between the directions to the lamp and to the camera (eq. 5)."""
    z = -CAMERA / np.linalg.norm(CAMERA)
    up = np.array([0.0, 0.0, 1.0])
    yax = z * (up @ z) - up
    yax /= np.linalg.norm(yax)
    xax = np.cross(yax, z)
    if u is None:
        v, u = np.mgrid[0:H, 0:W].astype(float)
    d = (np.stack([(u - CX) / FOCAL, (v - CY) / FOCAL, np.ones_like(u)], -1)
         @ np.stack([xax, yax, z]))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    x = CAMERA - d * (CAMERA[2] / d[..., 2:3])
    ui = np.asarray(lamp) - x
    ui /= np.linalg.norm(ui, axis=-1, keepdims=True)
    return 0.5 * np.degrees(np.arccos(np.clip((ui * -d).sum(-1), -1, 1)))


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """Frames (16-bit PNG, 4 polarizer angles) of four plates under six lamp positions,
    the calibrated manifest and the far-field one (angles of the image centre), and a
    model of the four true (n, k)."""
    cv2 = pytest.importorskip("cv2")
    d = tmp_path_factory.mktemp("bench")
    rng = np.random.default_rng(15)
    s0 = 30000.0
    head = (f"[camera]\nfocal_px = {FOCAL}\nprincipal_point_px = [{CX}, {CY}]\n"
            f"position = {vec(CAMERA)}\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, 1.0]\n")
    regions = "".join(f'\n[[region]]\nname = "{name}"\nrect = [{x + 2}, {y + 2}, {w - 4}, {h - 4}]\n'
                      f'class = "{name}"\n' for name, _, _, (x, y, w, h) in PLATES)
    cal, far = head + regions, regions
    betas = []
    for i, lamp in enumerate(LAMPS):
        beta = pixel_beta(lamp)
        betas.append(beta)
        dolp = np.zeros((H, W))
        s0img = np.zeros((H, W))
        for _, n, k, (x, y, w, h) in PLATES:
            dolp[y:y + h, x:x + w] = polarid.dolp_model(n, k, beta[y:y + h, x:x + w])
            s0img[y:y + h, x:x + w] = s0
        files = []
        for a in (0, 45, 90, 135):
            # AoLP 90°: S1 = −S0·P, S2 = 0.
            i_a = 0.5 * s0img * (1 - dolp * np.cos(np.radians(2 * a))) + rng.normal(0, 20, (H, W))
            name = f"c{i}_{a}.png"
            cv2.imwrite(str(d / name), np.clip(np.rint(i_a) + 100, 0, 65535).astype(np.uint16))
            files.append(f'  {{ angle_deg = {a}.0, file = "{name}" }},\n')
        frames = "frames = [\n" + "".join(files) + "]\n"
        cal += f"\n[[capture]]\nsource = {{ position = {vec(lamp)} }}\n{frames}"
        # Far field: the angles at the image centre, in the plane of incidence.
        b0 = float(pixel_beta(lamp)[H // 2, W // 2])
        far += f"\n[[capture]]\ntheta_i_deg = {b0}\ntheta_r_deg = {b0}\nphi_deg = 180.0\n{frames}"
    common = "dark_level = 100.0\nsaturation = 65535.0\n"
    (d / "calibrated.toml").write_text(common + cal)
    (d / "far_field.toml").write_text(common + far)
    protos = [{"class": name, "n": n, "k": k, "covariance": None, "category": None,
               "source": {"file": "truth", "line": 1, "target": name}} for name, n, k, _ in PLATES]
    (d / "model.json").write_text(json.dumps(
        {"format": "polarid-model", "format_version": 1, "created_by": "test", "prototypes": protos}))
    return d, np.stack(betas)


def interior(a, rect, m=3):
    x, y, w, h = rect
    return a[y + m:y + h - m, x + m:x + w - m]


def test_map_manifest_calibrated(bench):
    d, betas = bench
    # Both sides' totals (the thresholds below were set for that test).
    r = polarid.map_manifest(d / "calibrated.toml", d / "model.json", bench="other")
    assert r["summary"]["geometry"] == "calibrated"
    assert "no_geometry" in r["reason_names"] and len(r["reason_counts"]) == len(r["reason_names"])
    # Every pixel's β: the geometry of the pixel centres (float32, degrees).
    assert r["beta_deg"].shape == (len(LAMPS), H, W) and r["beta_deg"].dtype == np.float64
    np.testing.assert_allclose(r["beta_deg"], betas, atol=1e-4)
    for (lo, hi), b in zip(r["summary"]["beta_range_deg"], betas):
        assert abs(lo - b.min()) < 1e-4 and abs(hi - b.max()) < 1e-4
    miss = {}
    for name, n, k, rect in PLATES:
        cls = interior(r["class"], rect)
        assert (np.asarray(r["class_names"])[cls] == name).mean() >= 0.99, name
        miss[name] = (abs(np.median(interior(r["n"], rect)) - n), abs(np.median(interior(r["k"], rect)) - k))
        assert miss[name][0] < 0.01 and miss[name][1] < 0.02, (name, miss[name])
    # The same frames with one β per capture (the image centre's): far off.
    f = polarid.map_manifest(d / "far_field.toml", d / "model.json")
    assert "geometry" not in f["summary"] and "beta_deg" not in f
    # Every map lists every reason code; a far-field map has no pixel without geometry.
    assert f["reason_counts"][f["reason_names"].index("no_geometry")] == 0
    for name, n, k, rect in PLATES:
        dn = abs(np.median(interior(f["n"], rect)) - n)
        dk = abs(np.median(interior(f["k"], rect)) - k)
        # Every plate: far worse than with its own angles.
        assert dn + dk > 5 * sum(miss[name]) + 0.02, (name, dn, dk, miss[name])
        if name != "paint":
            # Off by more than 0.5 in n + k. (The paint touches the image centre, where
            # the far-field angles are right: its k is off by ~1 standard error.)
            assert dn + dk > 0.5, (name, dn, dk)
    # With 2 × 2 blocks: the geometry at the blocks' centres (block (x, y) at pixel
    # (2x + 0.5, 2y + 0.5) of the files).
    r2 = polarid.map_manifest(d / "calibrated.toml", d / "model.json", bin=2)
    v, u = np.mgrid[0:H // 2, 0:W // 2] * 2.0 + 0.5
    np.testing.assert_allclose(r2["beta_deg"], np.stack([pixel_beta(lamp, u, v) for lamp in LAMPS]),
                               atol=1e-4)


def test_map_manifest_calibrated_equals_cli(bench, polarid_cli):
    d, _ = bench
    out = d / "cli"
    subprocess.run([str(polarid_cli), "map", str(d / "calibrated.toml"), "--model", str(d / "model.json"),
                    "-o", str(out)], check=True, capture_output=True)
    py = polarid.map_manifest(d / "calibrated.toml", d / "model.json")
    summary = json.loads((out / "map_summary.json").read_text())
    for k in ("manifest", "model"):
        summary.pop(k)
    assert "seconds" not in summary  # timings go to standard error (issue 19)
    assert py["summary"] == summary
    assert py["reason_names"] == summary["reason_codes"]
    np.testing.assert_array_equal(py["reason_counts"], [summary["reasons"][r] for r in py["reason_names"]])
