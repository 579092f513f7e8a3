"""fit_mixed: the depolarization-aware inversion (issue 10) from Python."""

import math

import numpy as np
import pytest

import polarid


def _mixed_captures(n=1.39, k=0.34, sigma=0.2, rho_d=0.56, theta_r=60.0):
    """Noise-free region DoLP and S0 (per unit irradiance) of a plate with a Lambertian
    diffuse term of albedo `rho_d`: S0 = cos(theta_i) (f00 + rho_d/pi)."""
    ti = np.arange(35.0, 80.1, 5.0)
    tr = np.full_like(ti, theta_r)
    f = polarid.pbrdf(n, k, sigma, ti, tr, 180.0)
    f00 = f["global"][..., 0, 0]
    cos_i = np.cos(np.radians(ti))
    rho_over_pi = rho_d / math.pi
    s0 = cos_i * (f00 + rho_over_pi)
    dolp = polarid.dolp_model(n, k, f["beta"]) * f00 / (f00 + rho_over_pi)
    return ti, tr, dolp, s0, rho_over_pi * math.pi


def test_mixed_model_recovers_index_where_the_paper_model_is_biased():
    ti, tr, dolp, s0, rho_d = _mixed_captures()
    r = polarid.fit_mixed(list(ti), list(tr), list(dolp), list(s0))
    assert r["selected"] == "mixed"
    m = r["mixed"]
    assert m["status"] == "ok", m["reason"]
    assert abs(m["n"] - 1.39) < 0.02 and abs(m["k"] - 0.34) < 0.02
    assert abs(m["rho_d"] - rho_d) < 0.05 * rho_d
    spec = polarid.fit_nk(dolp, (ti + tr) / 2.0)
    assert math.hypot(spec["n"] - 1.39, spec["k"] - 0.34) > 0.2


def test_pure_specular_data_give_no_diffuse_part():
    ti, tr, dolp, s0, _ = _mixed_captures(rho_d=0.0)
    r = polarid.fit_mixed(ti.tolist(), tr.tolist(), dolp.tolist(), s0.tolist())
    m = r["mixed"]
    assert m["rho_d"] < 1e-3
    assert abs(m["n"] - 1.39) < 1e-3 and abs(m["k"] - 0.34) < 1e-3


def test_bad_input_raises_value_error():
    with pytest.raises(ValueError, match="same length"):
        polarid.fit_mixed([35, 40, 45], [60, 60], [0.5, 0.5, 0.5], [1, 1, 1])
    with pytest.raises(ValueError, match="shadowing"):
        polarid.fit_mixed([35, 40, 45], [60] * 3, [0.5] * 3, [1.0] * 3, shadowing="x")
