"""polarid.classify and polarid.pbrdf."""

import json
import subprocess

import numpy as np
import pytest

import polarid
from conftest import read_csv

PROTOS = [("aluminium", 1.2, 7.0, "metal"), ("gold", 0.2, 3.5, "metal"), ("glass", 1.5, 0.0, "dielectric")]


def test_classify_prototypes_scalar_and_array():
    d = polarid.classify(1.25, 6.8, PROTOS)
    assert d["predicted"] == "aluminium" and d["status"] == "ok"
    assert d["distance"] == pytest.approx(np.hypot(0.05, 0.2))
    assert d["runner_up"] == "gold" and d["margin"] == pytest.approx(d["runner_up_distance"] - d["distance"])
    r = polarid.classify(np.array([[1.25], [1.45]]), np.array([6.8, 0.1]), PROTOS, strings=True)
    assert r["predicted"].shape == (2, 2)
    assert r["predicted"][1, 1] == "glass" and r["predicted"][0, 0] == "aluminium"


def test_classify_fit_status_and_reject():
    r = polarid.classify([1.2, 1.2, 1.2], [7.0, 7.0, 7.0], PROTOS,
                         fit_status=["ok", "at_bound", "ok"], strings=True)
    assert list(r["predicted"]) == ["aluminium", "unknown", "aluminium"]
    assert r["status"][1] == "fit_at_bound" and np.isnan(r["distance"][1])
    r = polarid.classify([1.2, 1.2], [7.0, 7.0], PROTOS, fit_status=np.array([0, 2], np.uint8))
    assert "status" not in r and "predicted" not in r  # codes by default
    assert [r["status_names"][c] for c in r["status_code"]] == ["ok", "fit_ill_conditioned"]
    r = polarid.classify([1.2, 3.0], [7.0, 3.0], PROTOS, max_distance=0.5)
    assert [r["class_names"][c] for c in r["predicted_code"]] == ["aluminium", "unknown"]
    assert r["status_names"][r["status_code"][1]] == "rejected"
    assert r["class_names"][0] == "" and r["runner_up_code"][1] != 0
    r = polarid.classify(1.3, 6.9, PROTOS, n_se=0.05, k_se=0.05, nk_corr=0.0, metric="mahalanobis")
    assert r["predicted"] == "aluminium" and r["distance"] == pytest.approx(np.hypot(0.1, 0.1) / 0.05)


def test_classify_builtin_matches_cli(tmp_path, polarid_cli):
    fits = tmp_path / "fits.csv"
    rng = np.random.default_rng(5)
    n, k = rng.uniform(0.1, 3, 30), rng.uniform(0, 8, 30)
    with open(fits, "w") as fh:
        fh.write("target,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n")
        for i in range(30):
            fh.write(f"T{i},{float(n[i])!r},{float(k[i])!r},0.05,0.1,0.3,0.001,5,ok\n")
    for lib in ("builtin", "paper2007"):
        out = tmp_path / f"{lib}.csv"
        subprocess.run([str(polarid_cli), "classify", str(fits), "--library", lib, "--rule", "nearest",
                        "-o", str(out)],
                       check=True, capture_output=True)
        cli = read_csv(out)
        py = polarid.classify(n, k, lib, strings=True)
        assert list(py["predicted"]) == cli["predicted"]
        assert list(py["runner_up"]) == cli["runner_up"]
        np.testing.assert_array_equal(py["distance"], [float(v) for v in cli["distance"]])


def test_classify_files(tmp_path):
    lib = tmp_path / "lib.csv"
    lib.write_text("name,n,k,category\nsteel,2.9,3.1,metal\nwater,1.33,0,dielectric\n")
    assert polarid.classify(1.4, 0.1, lib)["predicted"] == "water"
    assert polarid.classify(1.4, 0.1, str(lib))["predicted"] == "water"
    with pytest.raises(FileNotFoundError, match="missing.csv: No such file"):
        polarid.classify(1.4, 0.1, tmp_path / "missing.csv")
    with pytest.raises(ValueError, match="prototype 2 must be a tuple"):
        polarid.classify(1.0, 1.0, [("a", 1.0, 1.0), "b"])
    with pytest.raises(ValueError, match="metric must be"):
        polarid.classify(1.0, 1.0, PROTOS, metric="cosine")
    with pytest.raises(ValueError, match="classifier option is invalid"):
        polarid.classify(1.0, 1.0, PROTOS, neighbours=0)


def test_classify_sets():
    # Between aluminium and a second metal: both consistent -> ambiguous, common category.
    protos = PROTOS + [("tin", 1.3, 6.9, "metal")]
    d = polarid.classify(1.25, 6.95, protos, n_se=0.1, k_se=0.1, nk_corr=0.0)
    assert d["predicted"] == "ambiguous" and d["status"] == "ambiguous"
    assert d["candidates"] == ["aluminium", "tin"] or d["candidates"] == ["tin", "aluminium"]
    assert d["n_candidates"] == 2 and d["category"] == "metal"
    # Tight: one; far: none.
    d = polarid.classify(1.2, 7.0, protos, n_se=0.01, k_se=0.01)
    assert d["predicted"] == "aluminium" and d["candidates"] == ["aluminium"]
    r = polarid.classify([1.2, 3.0], [7.0, 3.0], protos, n_se=0.01, k_se=0.01, strings=True)
    c = polarid.classify([1.2, 3.0], [7.0, 3.0], protos, n_se=0.01, k_se=0.01)
    for key in ("predicted", "runner_up", "status", "candidates", "category"):
        table = c["class_names" if key in ("predicted", "runner_up") else f"{key}_names"]
        assert list(r[key]) == [table[i] for i in c[f"{key}_code"]], key
    assert list(r["predicted"]) == ["aluminium", "unknown"] and r["status"][1] == "rejected"
    assert list(r["candidates"]) == ["aluminium", ""] and list(r["n_candidates"]) == [1, 0]
    # Nearest rule keeps the paper's answer and still reports the set.
    d = polarid.classify(1.25, 6.95, protos, n_se=0.1, k_se=0.1, rule="nearest")
    assert d["predicted"] in ("aluminium", "tin") and d["n_candidates"] == 2
    # Higher confidence never shrinks the set.
    a = polarid.classify(1.25, 6.8, protos, n_se=0.05, k_se=0.1, confidence=0.5)
    b = polarid.classify(1.25, 6.8, protos, n_se=0.05, k_se=0.1, confidence=0.999)
    assert set(a["candidates"]) <= set(b["candidates"])
    with pytest.raises(ValueError, match="confidence must be in"):
        polarid.classify(1.0, 1.0, PROTOS, n_se=0.1, k_se=0.1, confidence=1.5)
    with pytest.raises(ValueError, match="rule must be"):
        polarid.classify(1.0, 1.0, PROTOS, rule="vote")
    with pytest.raises(ValueError, match="option of --rule nearest"):
        polarid.classify(1.0, 1.0, PROTOS, rule="set", metric="euclidean")


def load_pbrdf_oracle(data_dir):
    path = data_dir / "oracles" / "pbrdf_reference.csv"
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    header = lines[0].split(",")
    rows = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    return {h: rows[:, i] for i, h in enumerate(header)}


def test_pbrdf_oracle(data_dir):
    d = load_pbrdf_oracle(data_dir)
    r = polarid.pbrdf(d["n"], d["k"], d["sigma"], d["theta_i_deg"], d["theta_r_deg"], d["phi_deg"])
    m00 = d["m00"]
    assert r["local"].shape == (300, 3, 3)
    for i in range(3):
        for j in range(3):
            np.testing.assert_allclose(r["local"][:, i, j], d[f"m{i}{j}"], rtol=0, atol=1e-9 * m00.max())
            np.testing.assert_array_less(np.abs(r["local"][:, i, j] - d[f"m{i}{j}"]), 1e-9 * m00 + 1e-300)
            if (i, j) != (0, 0):
                np.testing.assert_array_less(
                    np.abs(r["global"][:, i, j] - d[f"m{i}{j}_psps"]), 1e-9 * m00 + 1e-300)
    np.testing.assert_allclose(r["beta"], d["beta_deg"], atol=1e-9)
    np.testing.assert_allclose(r["facet_tilt"], d["facet_tilt_deg"], atol=1e-7)
    np.testing.assert_allclose(r["dolp"], d["dolp"], atol=1e-10)


def test_pbrdf_scalar_broadcast_errors():
    r = polarid.pbrdf(1.5, 0.0, 0.2, 30, 40, 180)
    assert r["local"].shape == (3, 3) and type(r["beta"]) is float
    assert r["beta"] == pytest.approx(35.0) and r["dolp"] == pytest.approx(polarid.dolp_model(1.5, 0, 35))
    b = polarid.pbrdf([1.5, 2.0], 0.0, 0.2, [[30.0], [20.0], [10.0]], 40, 180)
    assert b["global"].shape == (3, 2, 3, 3) and b["beta"].shape == (3, 2)
    np.testing.assert_array_equal(b["local"][0, 0], r["local"])
    with pytest.raises(ValueError, match=r"theta_i_deg = 90 is out of range"):
        polarid.pbrdf(1.5, 0, 0.2, 90, 10, 180)
    with pytest.raises(ValueError, match=r"sigma = 0 is out of range \(expected sigma > 0\)"):
        polarid.pbrdf(1.5, 0, 0.0, 30, 10, 180)
    with pytest.raises(ValueError, match="cannot be broadcast"):
        polarid.pbrdf([1, 2], 0, 0.2, [10, 20, 30], 10, 180)
