"""polarid.fit_nk: recovery, single vs batch, identical numbers to the `polarid fit` CLI."""

import subprocess

import numpy as np
import pytest

import polarid
from conftest import read_csv

BETA = np.linspace(25.0, 70.0, 10)


def noisy_stack(p, seed=0, sd=0.005):
    rng = np.random.default_rng(seed)
    n = rng.uniform(0.3, 3.0, p)
    k = rng.uniform(0.0, 8.0, p)
    y = polarid.dolp_model(n[:, None], k[:, None], BETA[None, :])
    y = np.clip(y + rng.normal(0, sd, y.shape), 0, 1)
    return n, k, y


def test_single_target_recovers_exact_data():
    for n, k in [(1.5, 0.0), (0.96, 6.69), (2.4, 1.3)]:
        f = polarid.fit_nk(polarid.dolp_model(n, k, BETA), BETA)
        assert f["status"] == "ok" and f["reason"] == ""
        assert abs(f["n"] - n) < 1e-6 and abs(f["k"] - k) < 1e-6
        assert f["rms_residual"] < 1e-9
        assert set(f) >= {"n_se", "k_se", "nk_corr", "cost", "iterations", "evaluations", "starts"}


def test_batch_equals_single_and_shapes():
    _, _, y = noisy_stack(50, seed=1)
    se = np.full_like(y, 0.005)
    for kw in ({}, {"dolp_se": se}, {"dolp_se": 0.005}):
        b = polarid.fit_nk(y, BETA, **kw, status_strings=True)
        assert b["n"].shape == (50,) and b["status"].shape == (50,)
        assert b["status_names"] == polarid.FIT_STATUS
        for i in range(0, 50, 7):
            s = polarid.fit_nk(y[i], BETA, **{k: (v[i] if np.ndim(v) else v) for k, v in kw.items()})
            for key in ("n", "k", "n_se", "k_se", "nk_corr", "rms_residual", "cost"):
                assert b[key][i] == s[key] or (np.isnan(b[key][i]) and np.isnan(s[key])), key
            assert b["status"][i] == s["status"]
            assert b["reasons"][b["reason_code"][i]] == s["reason"]
            for key in ("iterations", "evaluations", "starts"):
                assert b[key][i] == s[key], key
            assert polarid.FIT_STATUS[b["status_code"][i]] == s["status"]
    # (H, W, T) stacks keep their leading shape.
    m = polarid.fit_nk(y[:48].reshape(6, 8, 10), BETA)
    assert m["k"].shape == (6, 8)
    np.testing.assert_array_equal(m["k"].ravel(), polarid.fit_nk(y[:48], BETA)["k"])


def test_batch_flags_invalid_pixels_instead_of_failing():
    _, _, y = noisy_stack(4, seed=2)
    y[1, 3] = np.nan
    y[2, 0] = 1.5
    b = polarid.fit_nk(y, BETA, status_strings=True)
    reason = [b["reasons"][c] for c in b["reason_code"]]
    assert b["status"][1] == "invalid_input" and reason[1] == "non-finite DoLP"
    assert b["status"][2] == "invalid_input" and reason[2] == "DoLP outside [0, 1]"
    assert b["reasons"][0] == "" and b["status_code"][1] == polarid.FIT_STATUS.index("invalid_input")
    assert np.isnan(b["n"][1]) and np.isfinite(b["n"][0])


def test_errors():
    y = polarid.dolp_model(1.5, 0.0, BETA)
    with pytest.raises(ValueError, match=r"dolp = 1.5 is out of range \(expected \[0, 1\]\)"):
        polarid.fit_nk(np.where(BETA > 60, 1.5, y), BETA)
    with pytest.raises(ValueError, match="need at least 3 DoLP measurements"):
        polarid.fit_nk(y[:2], BETA[:2])
    with pytest.raises(ValueError, match="last axis must have 10 values"):
        polarid.fit_nk(y[:9], BETA)
    with pytest.raises(ValueError, match=r"n_range: need 0 <= MIN < MAX, got 2,1"):
        polarid.fit_nk(y, BETA, n_range=(2.0, 1.0))
    with pytest.raises(ValueError, match="dolp_se cannot be broadcast"):
        polarid.fit_nk(np.tile(y, (3, 1)), BETA, dolp_se=np.ones(4))


@pytest.mark.parametrize("with_se", [False, True])
def test_1000x10_identical_to_cli(tmp_path, polarid_cli, with_se):
    """fit_nk on a (1000, 10) stack returns exactly the numbers of `polarid fit`."""
    p = 1000
    n, k, y = noisy_stack(p, seed=3)
    se = np.random.default_rng(4).uniform(0.003, 0.008, y.shape)
    csv = tmp_path / "m.csv"
    with open(csv, "w") as fh:
        fh.write("target,beta_deg,dolp" + (",dolp_se" if with_se else "") + "\n")
        for i in range(p):
            for t in range(BETA.size):
                row = f"T{i},{float(BETA[t])!r},{float(y[i, t])!r}"
                fh.write(row + (f",{float(se[i, t])!r}\n" if with_se else "\n"))
    out = tmp_path / "fits.csv"
    # fit_nk is the noise-only fit: compare with the CLI's noise columns (its n_se, k_se,
    # nk_corr add the systematic errors, docs/ERRORS.md) and without the model checks.
    subprocess.run([str(polarid_cli), "fit", str(csv), "-o", str(out), "--mismatch-p", "0"],
                   check=True, capture_output=True)
    cli = read_csv(out)
    assert cli["target"] == [f"T{i}" for i in range(p)]
    py = polarid.fit_nk(y, BETA, dolp_se=se if with_se else None)
    assert "status" not in py  # codes by default (no per-pixel strings)
    py["status"] = np.array(py["status_names"])[py["status_code"]]
    noise = {"n_se": "n_se_noise", "k_se": "k_se_noise", "nk_corr": "nk_corr_noise"}
    for key in ("n", "k", "n_se", "k_se", "nk_corr", "rms_residual"):
        want = np.array([float(v) for v in cli[noise.get(key, key)]])
        np.testing.assert_array_equal(py[key], want, err_msg=key)
    assert list(py["status"]) == cli["status"]
    assert [py["reasons"][c] for c in py["reason_code"]] == cli["reason"]
    # and the fit recovers the truth within its standard errors for most pixels
    good = py["status"] == "ok"
    assert good.mean() > 0.9
    for est, truth, se_key in ((py["n"], n, "n_se"), (py["k"], k, "k_se")):
        within = np.abs(est[good] - truth[good]) < 4 * py[se_key][good]
        assert within.mean() > 0.95, se_key
