"""polarid.map_manifest: the maps of `polarid map` as numpy arrays (same pipeline function,
so the arrays equal the CLI's TIFFs)."""

import json
import subprocess

import numpy as np
import pytest

import polarid
from conftest import REPO_ROOT

SCENES = REPO_ROOT / "examples" / "scenes"


def read_tiff(path):
    """A single-channel TIFF written by the CLI, with whichever reader the venv has."""
    try:
        import tifffile

        return tifffile.imread(path)
    except ImportError:
        pass
    try:
        import cv2

        a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if a is not None:
            return a
    except ImportError:
        pass
    from PIL import Image

    return np.array(Image.open(path))


def run(cli, *args):
    subprocess.run([str(cli), *map(str, args)], check=True, capture_output=True)


@pytest.fixture(scope="module")
def sets(tmp_path_factory, polarid_cli):
    """A DoFP set (trains the model) and a rotating-polarizer set, made by `polarid simulate`,
    and a model from `polarid train`."""
    d = tmp_path_factory.mktemp("map")
    run(polarid_cli, "simulate", SCENES / "dofp_plates.toml", "-o", d / "dofp")
    run(polarid_cli, "simulate", SCENES / "aluminum_test_60.toml", "-o", d / "frames")
    run(polarid_cli, "measure", d / "dofp" / "manifest.toml", "-o", d / "m.csv")
    run(polarid_cli, "fit", d / "m.csv", "-o", d / "f.csv")
    run(polarid_cli, "train", d / "f.csv", "-o", d / "model.json")
    return d


@pytest.mark.parametrize("name,bin", [("dofp", 1), ("dofp", 2), ("frames", 1), ("frames", 4)])
def test_map_manifest_equals_cli(sets, polarid_cli, name, bin):
    manifest, model = sets / name / "manifest.toml", sets / "model.json"
    out = sets / f"out_{name}_{bin}"
    run(polarid_cli, "map", manifest, "--model", model, "-o", out, "--bin", bin)
    py = polarid.map_manifest(manifest, model, bin=bin)

    for key in ("n", "k", "n_se", "k_se", "rms_residual"):
        cli = read_tiff(out / f"{key}.tif")
        assert py[key].dtype == np.float32 and py[key].shape == cli.shape, key
        np.testing.assert_array_equal(py[key], cli, err_msg=key)
    for key in ("class", "reason"):
        cli = read_tiff(out / f"{key}.tif")
        assert py[key].dtype == np.uint8, key
        np.testing.assert_array_equal(py[key], cli, err_msg=key)

    classes = json.loads((out / "classes.json").read_text())
    assert py["class_names"] == [classes[str(i)] for i in range(len(classes))]
    summary = json.loads((out / "map_summary.json").read_text())
    assert py["reason_names"] == summary["reason_codes"]
    for k in ("manifest", "model"):
        summary.pop(k)
    assert "seconds" not in summary  # timings go to standard error (issue 19)
    assert py["summary"] == summary
    np.testing.assert_array_equal(py["class_counts"], [c["pixels"] for c in summary["classes"]])
    np.testing.assert_array_equal(py["reason_counts"], [summary["reasons"][r] for r in py["reason_names"]])
    assert py["reason_counts"].sum() == py["n"].size
    assert py["class"].max() < len(py["class_names"])
    assert [r["name"] for r in py["summary"]["regions"]] == (
        ["gold", "glass"] if name == "dofp" else [r["name"] for r in summary["regions"]])


def test_map_manifest_options(sets):
    manifest, model = sets / "dofp" / "manifest.toml", sets / "model.json"
    strict = polarid.map_manifest(manifest, model, rule="nearest", max_distance=1e-6)
    assert strict["reason_counts"][strict["reason_names"].index("rejected")] > 0
    assert "ambiguous" not in strict["class_names"]
    maha = polarid.map_manifest(manifest, model, rule="nearest", metric="mahalanobis", bin=2)
    assert maha["summary"]["metric"] == "mahalanobis" and maha["n"].shape == (64, 128)
    dark = polarid.map_manifest(manifest, model, min_s0=1e9)
    assert (dark["class"] == 0).all()


def test_map_manifest_sets_and_noise_weights(sets):
    """The set rule (default): `ambiguous` is the last class name, the answers add up; with
    a huge DoLP floor every fitted pixel is ambiguous or unknown; noise weights give a
    noise model in the summary."""
    manifest, model = sets / "dofp" / "manifest.toml", sets / "model.json"
    r = polarid.map_manifest(manifest, model, bin=2)
    assert r["class_names"][0] == "unknown" and r["class_names"][-1] == "ambiguous"
    s = r["summary"]
    assert s["rule"] == "set" and s["confidence"] == 0.95 and s["weights"] == "none"
    a = s["answers"]
    assert a["material"] + a["ambiguous"] + a["unknown"] == r["n"].size
    assert "not_classified" not in a
    amb = len(r["class_names"]) - 1
    assert (r["class"] == amb).sum() == a["ambiguous"] == r["reason_counts"][r["reason_names"].index("ambiguous")]
    # A shared error such as the DoLP floor cancels on one bench; with both sides' totals
    # (another bench) a huge floor leaves no pixel named alone.
    vague = polarid.map_manifest(manifest, model, bin=2, dolp_floor=0.5, bench="other")
    assert vague["summary"]["answers"]["material"] == 0
    w = polarid.map_manifest(manifest, model, bin=2, weights="noise")
    assert w["summary"]["weights"] == "noise" and w["summary"]["noise"]["pixels"] > 100


def test_map_manifest_errors(sets):
    manifest, model = sets / "dofp" / "manifest.toml", sets / "model.json"
    with pytest.raises(ValueError, match=r"bin must be in 1\.\.=64, got 0"):
        polarid.map_manifest(manifest, model, bin=0)
    with pytest.raises(ValueError, match="min_s0 must be a finite number, got inf"):
        polarid.map_manifest(manifest, model, min_s0=float("inf"))
    with pytest.raises(ValueError, match="max_distance must be finite and > 0, got -1"):
        polarid.map_manifest(manifest, model, max_distance=-1.0)
    with pytest.raises(ValueError, match="metric must be"):
        polarid.map_manifest(manifest, model, metric="cosine")
    with pytest.raises(ValueError, match="rule must be"):
        polarid.map_manifest(manifest, model, rule="best")
    with pytest.raises(ValueError, match="confidence must be in"):
        polarid.map_manifest(manifest, model, confidence=1.5)
    with pytest.raises(ValueError, match="weights must be"):
        polarid.map_manifest(manifest, model, weights="some")
    with pytest.raises(ValueError, match="dolp_floor must be in"):
        polarid.map_manifest(manifest, model, dolp_floor=-1.0)
    with pytest.raises(FileNotFoundError, match="nope.json"):
        polarid.map_manifest(manifest, sets / "nope.json")
    with pytest.raises(FileNotFoundError, match="nope.toml"):
        polarid.map_manifest(sets / "nope.toml", model)
