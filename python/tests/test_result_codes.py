"""Large results without per-pixel strings: fit_nk and classify return integer codes with
name tables by default (status_strings= / strings= add the str arrays), and fit_nk
reads float32 DoLP stacks without a float64 copy (same numbers)."""

import numpy as np

import polarid

BETA = np.linspace(35.0, 80.0, 10) / 2 + 30.0
PROTOS = [("aluminium", 1.2, 7.0), ("gold", 0.2, 3.5), ("glass", 1.5, 0.0)]


def stack(p, seed=0):
    rng = np.random.default_rng(seed)
    n, k = rng.uniform(0.3, 3.0, (p, 1)), rng.uniform(0.0, 8.0, (p, 1))
    y = np.clip(polarid.dolp_model(n, k, BETA) + rng.normal(0, 0.005, (p, BETA.size)), 0, 1)
    y[::97, 3] = np.nan  # some invalid pixels
    return y


def test_fit_nk_codes_and_opt_in_strings():
    y = stack(3000)
    f = polarid.fit_nk(y, BETA)
    assert "status" not in f
    assert f["status_names"] == polarid.FIT_STATUS and f["status_code"].dtype == np.uint8
    s = polarid.fit_nk(y, BETA, status_strings=True)
    np.testing.assert_array_equal(s["status"], np.array(f["status_names"])[f["status_code"]])
    assert (s["status"][::97] == "invalid_input").all()
    assert f["reasons"][f["reason_code"][0]] == "non-finite DoLP"


def test_fit_nk_float32_equals_float64_of_the_same_values():
    y32 = stack(5000, seed=1).astype(np.float32)
    a = polarid.fit_nk(y32, BETA)
    b = polarid.fit_nk(y32.astype(np.float64), BETA)
    for key in ("n", "k", "n_se", "k_se", "nk_corr", "cost", "status_code", "evaluations"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    # reason tables are built in the order the parallel workers meet the reasons
    assert [a["reasons"][c] for c in a["reason_code"]] == [b["reasons"][c] for c in b["reason_code"]]
    one = polarid.fit_nk(y32[1], BETA)  # one target from float32
    assert one["n"] == b["n"][1] and one["status"] == b["status_names"][b["status_code"][1]]
    c = polarid.fit_nk(y32.reshape(50, 100, 10)[:, ::2], BETA)  # non-contiguous float32
    np.testing.assert_array_equal(c["n"], b["n"].reshape(50, 100)[:, ::2])


def test_classify_codes_match_strings():
    rng = np.random.default_rng(2)
    n, k = rng.uniform(0, 3, (40, 50)), rng.uniform(0, 8, (40, 50))
    c = polarid.classify(n, k, PROTOS, n_se=0.05, k_se=0.1, max_distance=1.0, rule="nearest")
    s = polarid.classify(n, k, PROTOS, n_se=0.05, k_se=0.1, max_distance=1.0, rule="nearest",
                         strings=True)
    assert "predicted" not in c and c["predicted_code"].shape == (40, 50)
    for key, table in (("predicted", "class_names"), ("runner_up", "class_names"),
                       ("status", "status_names"), ("candidates", "candidates_names"),
                       ("category", "category_names")):
        np.testing.assert_array_equal(s[key], np.array(c[table])[c[f"{key}_code"]], err_msg=key)
    assert set(s["predicted"].ravel()) <= {"aluminium", "gold", "glass", "unknown"}
    assert "unknown" in set(s["predicted"].ravel())
