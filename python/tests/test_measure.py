"""polarid.simulate, load_manifest and measure (identical to `polarid measure`)."""

import math
import subprocess

import numpy as np
import pytest

import polarid
from conftest import read_csv

cv2 = pytest.importorskip("cv2")

PLATES = [(1.5, 0.0, 0.15), (0.96, 6.69, 0.15), (2.4, 1.3, 0.15)]
THETA_I = [30.0, 40.0, 50.0, 60.0]


def test_simulate_shapes_and_physics():
    sim = polarid.simulate(PLATES, THETA_I, 45.0, seed=3)
    assert sim["frames"].shape == (4, 4, 24, 64) and sim["frames"].dtype == np.uint16
    assert sim["rects"] == [(4, 4, 16, 16), (24, 4, 16, 16), (44, 4, 16, 16)]
    np.testing.assert_allclose(sim["beta_deg"], (np.array(THETA_I) + 45) / 2)
    # Without diffuse light the expected DoLP is eq. (9) at beta.
    want = polarid.dolp_model(np.array([p[0] for p in PLATES]), np.array([p[1] for p in PLATES]),
                              sim["beta_deg"][:, None])
    np.testing.assert_allclose(sim["dolp"], want, rtol=1e-12)
    # Deterministic per seed; noise differs between seeds.
    again = polarid.simulate(PLATES, THETA_I, 45.0, seed=3)
    np.testing.assert_array_equal(again["frames"], sim["frames"])
    assert (polarid.simulate(PLATES, THETA_I, 45.0, seed=4)["frames"] != sim["frames"]).any()
    # The measured DoLP of each plate matches the expected value.
    for c in range(4):
        s = polarid.stokes(sim["frames"][c], sim["angles_deg"]).astype(np.float64)
        for p, (x, y, w, h) in enumerate(sim["rects"]):
            m = s[:, y:y + h, x:x + w].reshape(3, -1).mean(1)
            assert abs(math.hypot(m[1], m[2]) / m[0] - sim["dolp"][c, p]) < 0.01
    raw = polarid.simulate(PLATES, THETA_I, 45.0, dofp=True)["raw"]
    assert raw.shape == (4, 24, 64)


def test_simulate_errors():
    with pytest.raises(ValueError, match=r"k = -1 is out of range"):
        polarid.simulate([(1.5, -1.0, 0.1)], [30])
    with pytest.raises(ValueError, match=r"theta_i_deg = 95 is out of range"):
        polarid.simulate(PLATES, [30, 95])
    with pytest.raises(ValueError, match="theta_r_deg has 2 values"):
        polarid.simulate(PLATES, [30, 40, 50], [10, 20])


def write_scene(tmp_path, dofp):
    """Frames (or DoFP mosaics) of the simulated plates as 16-bit PNGs, and a manifest."""
    sim = polarid.simulate(PLATES, THETA_I, 45.0, dofp=dofp, seed=11, dark_level_dn=20)
    lines = ["theta_r_deg = 45.0", "dark_level = 20", ""]
    for p, (x, y, w, h) in enumerate(sim["rects"]):
        lines += ["[[region]]", f'name = "P{p}"', f"rect = [{x + 1}, {y + 1}, {w - 2}, {h - 2}]",
                  f'class = "c{p}"', ""]
    for c, ti in enumerate(THETA_I):
        lines += ["[[capture]]", f"theta_i_deg = {ti}", f"exposure = {1.0 + c}"]
        if dofp:
            name = f"raw{c}.png"
            cv2.imwrite(str(tmp_path / name), sim["raw"][c])
            lines.append(f'dofp = {{ file = "{name}" }}')
        else:
            refs = []
            for a, ang in enumerate(sim["angles_deg"]):
                name = f"c{c}_{int(ang)}.png"
                cv2.imwrite(str(tmp_path / name), sim["frames"][c, a])
                refs.append(f'{{ angle_deg = {ang}, file = "{name}" }}')
            lines.append(f"frames = [{', '.join(refs)}]")
        lines.append("")
    path = tmp_path / "manifest.toml"
    path.write_text("\n".join(lines))
    return path, sim


def test_load_manifest(tmp_path):
    path, sim = write_scene(tmp_path, dofp=False)
    m = polarid.load_manifest(path)
    assert m["theta_r_deg"] == 45.0 and m["phi_deg"] == 180.0 and m["dark_level"] == 20
    assert [r["name"] for r in m["regions"]] == ["P0", "P1", "P2"]
    assert m["regions"][1]["rect"] == (25, 5, 14, 14) and m["regions"][1]["class"] == "c1"
    c = m["captures"][2]
    assert c["kind"] == "frames" and c["theta_i_deg"] == 50.0 and c["exposure"] == 3.0
    assert c["beta_deg"] == pytest.approx(47.5)
    assert [f["angle_deg"] for f in c["frames"]] == [0, 45, 90, 135]
    assert c["frames"][0]["file"].endswith("c2_0.png")
    assert m["warnings"] == []


def test_load_manifest_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.toml"):
        polarid.load_manifest(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text('[[region]]\nname = "A"\nrect = [0, 0, 0, 4]\n')
    with pytest.raises(ValueError, match=r"bad.toml.*line 3"):
        polarid.load_manifest(bad)
    warn = tmp_path / "warn.toml"
    path, _ = write_scene(tmp_path, dofp=False)
    warn.write_text(path.read_text().replace("dark_level = 20", "dark_level = 20\ndark_levle = 3"))
    with pytest.warns(UserWarning, match="dark_levle"):
        assert polarid.load_manifest(warn)["warnings"]


@pytest.mark.parametrize("dofp", [False, True])
def test_measure_identical_to_cli(tmp_path, polarid_cli, dofp):
    path, sim = write_scene(tmp_path, dofp)
    out = tmp_path / "m.csv"
    subprocess.run([str(polarid_cli), "measure", str(path), "-o", str(out)], check=True,
                   capture_output=True)
    cli = read_csv(out)
    py = polarid.measure(path)
    assert list(py["target"]) == cli["target"] and list(py["class"]) == cli["class"]
    assert len(cli["target"]) == 12
    for col in ("theta_i_deg", "theta_r_deg", "phi_deg", "beta_deg", "dolp", "dolp_se", "s0",
                "exposure"):
        want = np.array([float(v) if v else np.nan for v in cli[col]])
        np.testing.assert_array_equal(py[col], want, err_msg=col)
    for col in ("pixels", "rejected", "saturated"):
        np.testing.assert_array_equal(py[col], [int(v) for v in cli[col]], err_msg=col)
    # The measured DoLP is close to the simulated truth.
    np.testing.assert_allclose(py["dolp"].reshape(4, 3), sim["dolp"], atol=0.02)


def test_measure_errors(tmp_path):
    path, _ = write_scene(tmp_path, dofp=False)
    text = path.read_text()
    path.write_text(text.replace("rect = [5, 5, 14, 14]", "rect = [60, 5, 14, 14]"))
    with pytest.raises(ValueError, match=r"region\[1\]\.rect.*in capture 1 .*64x24 pixels"):
        polarid.measure(path)
    path.write_text(text)
    (tmp_path / "c1_45.png").unlink()
    # The manifest checks that its files exist (the CLI's message).
    with pytest.raises(ValueError, match=r"capture\[2\]\.frames\[2\]\.file`: file .*c1_45.png not found"):
        polarid.measure(path)


@pytest.mark.parametrize("dofp", [False, True])
def test_simulate_equals_the_cli(tmp_path, polarid_cli, dofp):
    """polarid.simulate renders the frames `polarid simulate` renders from the same scene
    (the same exposure and noise seeds), and the truth it writes."""
    sim = polarid.simulate(PLATES, THETA_I, 45.0, dofp=dofp, seed=7, fill=0.7, tile=8, gap=2,
                           read_noise_e=5.0, dark_level_dn=10)
    height, width = (sim["raw"] if dofp else sim["frames"]).shape[-2:]
    lines = [f"width = {width}", f"height = {height}", "theta_r_deg = 45.0",
             f"theta_i_deg = {THETA_I}", "seed = 7",
             "[sensor]", "read_noise_e = 5.0", "dark_level_dn = 10",
             "[exposure]", 'mode = "auto"', "fraction = 0.7"]
    if dofp:
        lines += ["[capture]", 'kind = "dofp"']
    for p, ((n, k, s), rect) in enumerate(zip(PLATES, sim["rects"])):
        lines += ["[[plate]]", f'name = "P{p}"', f"n = {n}", f"k = {k}", f"sigma = {s}",
                  f"rect = {list(rect)}"]
    (tmp_path / "scene.toml").write_text("\n".join(lines) + "\n")
    subprocess.run([str(polarid_cli), "simulate", "-o", str(tmp_path / "out"),
                    str(tmp_path / "scene.toml")], check=True, capture_output=True)
    for c, ti in enumerate(THETA_I):
        cap = tmp_path / "out" / f"i{int(ti)}"
        if dofp:
            got = [cv2.imread(str(cap / "raw.png"), cv2.IMREAD_UNCHANGED)]
            want = [sim["raw"][c]]
        else:
            got = [cv2.imread(str(cap / f"pol{int(a):03}.png"), cv2.IMREAD_UNCHANGED)
                   for a in sim["angles_deg"]]
            want = list(sim["frames"][c])
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
    truth = read_csv(tmp_path / "out" / "truth.csv")
    np.testing.assert_allclose(np.array(truth["dolp"], dtype=float), sim["dolp"].ravel(), rtol=1e-9)
    np.testing.assert_allclose(np.array(truth["beta_deg"], dtype=float)[::len(PLATES)],
                               sim["beta_deg"], rtol=1e-12)
