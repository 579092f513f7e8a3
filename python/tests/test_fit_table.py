"""polarid.fit_table: the table-level fit, identical to `polarid fit` (same Rust function,
polarid_pipeline::fit): same columns, statuses and numbers."""

import math
import subprocess

import pytest

import polarid
from conftest import REPO_ROOT, read_csv

SCENES = REPO_ROOT / "examples" / "scenes"
FLOATS = ["n", "k", "n_se", "k_se", "nk_corr", "rms_residual"]
OPTIONAL = ["sigma", "rho_d", "theta_r_deg"]


@pytest.fixture(scope="module")
def measurements(tmp_path_factory, polarid_cli):
    """Measurements CSVs of two example scenes, by `polarid simulate` + `polarid measure`."""
    d = tmp_path_factory.mktemp("fit_table")
    out = {}
    for scene in ["paper_training_60", "aluminum_test_60"]:
        sim = d / scene
        subprocess.run([str(polarid_cli), "simulate", str(SCENES / f"{scene}.toml"), "-o", str(sim), "-q"],
                       check=True, capture_output=True)
        csv = d / f"{scene}.csv"
        subprocess.run([str(polarid_cli), "measure", str(sim / "manifest.toml"), "-o", str(csv), "-q"],
                       check=True, capture_output=True)
        out[scene] = csv
    return out


def cli_fit(polarid_cli, path, out, args):
    subprocess.run([str(polarid_cli), "fit", str(path), "-o", str(out), "-q", *args], check=True,
                   capture_output=True)
    return read_csv(out)


def same_float(a: float, b: str) -> bool:
    x = float(b)
    return (math.isnan(a) and math.isnan(x)) or a == x


CASES = [
    ("paper_training_60", [], {}),
    ("paper_training_60", ["--depolarized-dolp", "0.3"], {"depolarized_dolp": 0.3}),
    ("paper_training_60", ["--n-range", "0.5,4", "--k-range", "0,8"],
     {"n_range": (0.5, 4.0), "k_range": (0.0, 8.0)}),
    ("paper_training_60", ["--reflectance", "mixed"], {"reflectance": "mixed"}),
    ("aluminum_test_60", ["--reflectance", "mixed", "--estimate-theta-r", "--shadowing", "smith"],
     {"reflectance": "mixed", "estimate_theta_r": True, "shadowing": "smith"}),
]


@pytest.mark.parametrize("scene,args,kwargs", CASES)
def test_fit_table_equals_cli(tmp_path, polarid_cli, measurements, scene, args, kwargs):
    path = measurements[scene]
    cli = cli_fit(polarid_cli, path, tmp_path / "fits.csv", args)
    py = polarid.fit_table(path, **kwargs)
    assert list(py) == list(cli), "same columns in the same order"
    assert py["target"] == cli["target"]
    assert py["status"] == cli["status"]
    assert all(s in polarid.FIT_STATUS for s in py["status"])
    assert py["reason"] == cli["reason"]
    assert py["model"] == cli["model"]
    assert [c or "" for c in py["class"]] == cli["class"]
    assert [str(m) for m in py["measurements"]] == cli["measurements"]
    for col in FLOATS:
        for a, b in zip(py[col], cli[col], strict=True):
            assert same_float(a, b), f"{col}: {a!r} != {b}"
    for col in OPTIONAL:
        for a, b in zip(py[col], cli[col], strict=True):
            assert (a is None and b == "") or same_float(a, b), f"{col}: {a!r} != {b!r}"


def test_fit_table_statuses(measurements):
    # Every target of the paper's training set is below DoLP 0.99: all `depolarized`.
    py = polarid.fit_table(measurements["paper_training_60"], depolarized_dolp=0.99)
    assert set(py["status"]) == {"depolarized"}
    assert all("DoLP below 0.99" in r for r in py["reason"])
    ok = polarid.fit_table(measurements["paper_training_60"])
    assert "ok" in ok["status"]


def test_fit_table_errors_match_cli(tmp_path, polarid_cli, measurements):
    lines = measurements["aluminum_test_60"].read_text().splitlines()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:3]) + "\n")
    r = subprocess.run([str(polarid_cli), "fit", str(short), "-q"], capture_output=True, text=True)
    assert r.returncode == 2
    msg = r.stderr.strip().removeprefix("polarid: error: ")
    with pytest.raises(ValueError) as e:
        polarid.fit_table(short)
    assert str(e.value) == msg
    assert "at least 3" in msg
    with pytest.raises(FileNotFoundError):
        polarid.fit_table(tmp_path / "missing.csv")
    with pytest.raises(ValueError, match="n_range: need 0 <= MIN < MAX, got 2,1"):
        polarid.fit_table(short, n_range=(2.0, 1.0))
    with pytest.raises(ValueError, match="reflectance"):
        polarid.fit_table(short, reflectance="diffuse")
    with pytest.raises(ValueError, match="estimate_theta_r"):
        polarid.fit_table(short, estimate_theta_r=True)
    with pytest.raises(ValueError, match="s0_rel_sd"):
        polarid.fit_table(short, reflectance="mixed", s0_rel_sd=0.0)


NOISE = ["n_se_noise", "k_se_noise", "nk_corr_noise", "gof_p", "aolp_p"]

ERROR_MODEL_CASES = [
    (["--angle-sd-deg", "0", "--dolp-floor", "0", "--extinction-ratio", "inf"],
     {"angle_sd_deg": 0.0, "dolp_floor": 0.0, "extinction_ratio": math.inf}),
    (["--angle-sd-deg", "0.5", "--dolp-floor", "0.005", "--extinction-ratio", "300",
      "--retardance-deg", "5"],
     {"angle_sd_deg": 0.5, "dolp_floor": 0.005, "extinction_ratio": 300.0, "retardance_deg": 5.0}),
    (["--mismatch-p", "0"], {"mismatch_p": 0.0}),
    (["--mismatch-p", "0.9", "--dolp-floor", "0"], {"mismatch_p": 0.9, "dolp_floor": 0.0}),
]


@pytest.mark.parametrize("scene", ["paper_training_60", "aluminum_test_60"])
@pytest.mark.parametrize("args,kwargs", ERROR_MODEL_CASES)
def test_fit_table_error_model_equals_cli(tmp_path, polarid_cli, measurements, scene, args, kwargs):
    """The error-model keywords give the rows `polarid fit` gives with the same options."""
    path = measurements[scene]
    cli = cli_fit(polarid_cli, path, tmp_path / "fits.csv", args)
    py = polarid.fit_table(path, **kwargs)
    assert list(py) == list(cli)
    assert py["target"] == cli["target"]
    assert py["status"] == cli["status"]
    assert py["reason"] == cli["reason"]
    for col in FLOATS + NOISE:
        for a, b in zip(py[col], cli[col], strict=True):
            assert (a is None and b == "") or same_float(a, b), f"{col}: {a!r} != {b!r}"


def test_fit_table_error_model_keywords_take_effect(measurements):
    path = measurements["paper_training_60"]
    default = polarid.fit_table(path)
    noise_only = polarid.fit_table(path, angle_sd_deg=0.0, dolp_floor=0.0, extinction_ratio=math.inf,
                                   film_sd_nm=0.0)
    wider = polarid.fit_table(path, angle_sd_deg=1.0, extinction_ratio=10.0, retardance_deg=20.0)
    for i, s in enumerate(default["status"]):
        if s != "ok":
            continue
        # Without systematic errors the total is the noise alone; more error, larger se.
        assert noise_only["n_se"][i] == pytest.approx(noise_only["n_se_noise"][i], rel=1e-9)
        assert noise_only["n_se"][i] < default["n_se"][i] < wider["n_se"][i]
        assert default["n"][i] == noise_only["n"][i] == wider["n"][i], "the estimate is unchanged"
    # A level above every target's p-values marks every specular fit a mismatch.
    strict = polarid.fit_table(path, mismatch_p=0.999999, dolp_floor=0.0)
    assert "model_mismatch" in strict["status"]
    for bad, word in [({"angle_sd_deg": 90.0}, "angle_sd_deg"), ({"dolp_floor": -0.1}, "dolp_floor"),
                      ({"extinction_ratio": 1.0}, "extinction_ratio"),
                      ({"retardance_deg": 91.0}, "retardance_deg"), ({"mismatch_p": 1.0}, "mismatch_p")]:
        with pytest.raises(ValueError, match=word):
            polarid.fit_table(path, **bad)
