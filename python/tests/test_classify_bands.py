"""polarid.classify and polarid.classify_table on multi-band models and libraries (colour
cameras, docs/BANDS.md): the same answers as ``polarid classify`` on the same inputs."""

import subprocess
import warnings

import numpy as np
import pytest

import polarid
from conftest import DATA_DIR, REPO_ROOT, read_csv

REPO_SCENES = REPO_ROOT / "examples" / "scenes"

#: A colour polarization camera (RGGB blocks of 90/45/135/0 polarizers) looking at three
#: metals whose (n, k) per band are builtin-rgb's, 8 source positions (docs/SCENE.md).
SCENE = """
name = "colour_plates"
width = 96
height = 32
theta_r_deg = 50.0
theta_i_deg = [30, 36, 42, 48, 54, 60, 66, 72]
background = 0.01
seed = {seed}
format = "tiff"

[sensor]
dark_level_dn = 32.0
full_well_e = 30000.0

[exposure]
mode = "auto"
fraction = 0.8

[capture]
kind = "dofp"
pattern = [90, 45, 135, 0]
color = "RGGB"

[[plate]]
name = "cu"
material = "copper"
sigma = 0.2
rect = [0, 0, 32, 32]

[[plate]]
name = "au"
material = "gold"
sigma = 0.2
rect = [32, 0, 32, 32]

[[plate]]
name = "al"
material = "aluminum"
sigma = 0.2
rect = [64, 0, 32, 32]
"""


def run(cli, *args, cwd=None):
    return subprocess.run([str(cli), *map(str, args)], check=True, capture_output=True, text=True, cwd=cwd)


def fits_of(cli, d, seed):
    """Colour captures of SCENE (seed), their per-band measurements and fits."""
    (d / f"scene{seed}.toml").write_text(SCENE.format(seed=seed))
    run(cli, "simulate", d / f"scene{seed}.toml", "-o", d / f"sim{seed}")
    run(cli, "measure", d / f"sim{seed}" / "manifest.toml", "-o", d / f"m{seed}.csv")
    run(cli, "fit", d / f"m{seed}.csv", "-o", d / f"fits{seed}.csv")
    return d / f"fits{seed}.csv"


@pytest.fixture(scope="module")
def colour(tmp_path_factory, polarid_cli):
    """Three-band fits (one row per target and band), a three-band model trained on
    another seed, a three-band library made by ``polarid library``, and a single-band
    fits file without wavelengths."""
    d = tmp_path_factory.mktemp("bands")
    fits = fits_of(polarid_cli, d, 3)
    run(polarid_cli, "train", fits_of(polarid_cli, d, 4), "-o", d / "model.json")
    run(polarid_cli, "library", DATA_DIR / "materials" / "refractiveindex", "--band", "450", "--band", "550",
        "--band", "650", "--names", DATA_DIR / "materials" / "builtin_names.csv", "--skip-missing", "-q",
        "-o", d / "lib3.csv")
    cols = read_csv(fits)
    mono = d / "mono.csv"
    keep = [h for h in cols if h != "wavelength_nm"]
    rows = [i for i, w in enumerate(cols["wavelength_nm"]) if float(w) == 550.0]
    mono.write_text(",".join(keep) + "\n" + "".join(
        ",".join(cols[h][i] for h in keep) + "\n" for i in rows))
    return dict(dir=d, fits=fits, model=d / "model.json", lib3=d / "lib3.csv", mono=mono)


def opt_float(v):
    return None if v == "" else float(v)


def assert_same_as_cli(py, cli):
    """classify_table's columns == the CLI's classification CSV (without Wolff's baseline,
    whose columns are empty here)."""
    for key in ("wolff_class", "wolff_fr_max", "wolff_beta_deg"):
        assert set(cli.pop(key)) == {""}, key
    assert list(py) == list(cli), "columns"
    for key, col in cli.items():
        if key in ("distance", "runner_up_distance", "margin", "confidence", "gate"):
            assert py[key] == [opt_float(v) for v in col], key
        elif key == "candidates":
            assert [";".join(c) for c in py[key]] == col, key
        elif key == "votes":
            assert py[key] == [None if v == "" else int(v) for v in col], key
        elif key in ("class", "runner_up", "nearest", "category"):
            assert py[key] == [v or None for v in col], key
        else:
            assert py[key] == col, key


SOURCES = ["builtin-rgb", "builtin", "lib3", "model"]


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("rule", ["set", "nearest"])
def test_classify_table_equals_cli(colour, polarid_cli, source, rule):
    spec = colour.get(source, source)
    opt = "--model" if source == "model" else "--library"
    out = colour["dir"] / f"cls_{source}_{rule}.csv"
    run(polarid_cli, "classify", colour["fits"], opt, spec, "--rule", rule, "-o", out)
    cli = read_csv(out)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        py = polarid.classify_table(colour["fits"], spec, rule=rule)
    assert_same_as_cli(py, cli)
    assert py["target"] == ["cu", "au", "al"]


def test_classify_table_three_bands_right(colour):
    """Three bands against builtin-rgb (set rule): copper and gold told apart, aluminum
    among the candidates of its answer, all on their three bands."""
    py = polarid.classify_table(colour["fits"], "builtin-rgb")
    assert py["predicted"][:2] == ["copper", "gold"]
    assert py["predicted"][2] in ("aluminum", "ambiguous") and "aluminum" in py["candidates"][2]
    assert py["bands_used"] == ["450;550;650"] * 3


@pytest.mark.parametrize("source", ["builtin-rgb", "builtin", "lib3"])
def test_classify_table_wavelength_option(colour, polarid_cli, source):
    """Rows without wavelength_nm, given one by wavelength_nm= (--wavelength-nm)."""
    spec = colour.get(source, source)
    out = colour["dir"] / f"mono_{source}.csv"
    run(polarid_cli, "classify", colour["mono"], "--library", spec, "--wavelength-nm", "550", "-o", out)
    py = polarid.classify_table(colour["mono"], spec, wavelength_nm=550.0)
    assert_same_as_cli(py, read_csv(out))
    assert py["bands_used"] == ["550"] * 3


def test_classify_table_warns_as_cli(colour, polarid_cli):
    r = run(polarid_cli, "classify", colour["mono"], "--library", "builtin")
    with pytest.warns(UserWarning, match="carry no wavelength_nm") as w:
        polarid.classify_table(colour["mono"], "builtin")
    assert str(w[0].message) in r.stderr


@pytest.mark.parametrize("source", SOURCES)
def test_classify_arrays_band_axis_equals_cli(colour, polarid_cli, source):
    """The fits' columns as arrays (targets, bands) with band_axis=1: classify == the CLI.

    The arrays carry the fits' total standard errors, so a model is compared as the CLI
    compares a model from another bench (`--bench other`)."""
    spec = colour.get(source, source)
    opt = ["--model", spec, "--bench", "other"] if source == "model" else ["--library", spec]
    out = colour["dir"] / f"arr_{source}.csv"
    run(polarid_cli, "classify", colour["fits"], *opt, "-o", out)
    cli = read_csv(out)
    f = read_csv(colour["fits"])
    t = len(cli["target"])
    col = lambda key: np.array([float(v) if v else np.nan for v in f[key]]).reshape(t, 3)
    status = np.array(f["status"]).reshape(t, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        py = polarid.classify(col("n"), col("k"), spec, n_se=col("n_se"), k_se=col("k_se"),
                              nk_corr=col("nk_corr"), fit_status=status, wavelength_nm=col("wavelength_nm"),
                              film_shifts=np.stack([col(f"film{j}_{q}") for j in (1, 2, 3) for q in ("dn", "dk")], axis=-1),
                              band_axis=-1, strings=True)
    assert py["predicted"].shape == (t,)
    assert list(py["predicted"]) == cli["predicted"]
    assert list(py["status"]) == cli["status"]
    assert list(py["candidates"]) == cli["candidates"]
    assert list(py["bands_used"]) == cli["bands_used"]
    np.testing.assert_array_equal(py["distance"], [opt_float(v) or np.nan for v in cli["distance"]])
    # One estimate at a time (scalar result).
    one = polarid.classify(col("n")[1], col("k")[1], spec, n_se=col("n_se")[1], k_se=col("k_se")[1],
                           nk_corr=col("nk_corr")[1], wavelength_nm=col("wavelength_nm")[1], band_axis=0,
                           film_shifts=np.stack([col(f"film{j}_{q}")[1] for j in (1, 2, 3) for q in ("dn", "dk")], axis=-1))
    assert one["predicted"] == cli["predicted"][1] and one["bands_used"] == cli["bands_used"][1]


def test_classify_arrays_wavelength(colour):
    """Per-element wavelengths: a 550 nm estimate is compared with builtin-rgb's 550 nm
    band (bands_used), builtin evaluated at 550 nm (with a warning saying so); without
    any wavelength against a multi-band library: no_common_band."""
    gold = polarid.classify_table(colour["fits"], "builtin-rgb", rule="nearest")
    f = read_csv(colour["fits"])
    i = [j for j, (t, w) in enumerate(zip(f["target"], f["wavelength_nm"])) if t == "au" and float(w) == 550.0][0]
    n, k = float(f["n"][i]), float(f["k"][i])
    r = polarid.classify(n, k, "builtin-rgb", wavelength_nm=550.0)
    assert r["bands_used"] == "550" and r["status"] == "ok"
    assert gold["predicted"][1] == "gold"
    with pytest.warns(UserWarning, match="evaluated at 550 nm"):
        polarid.classify(n, k, "builtin", wavelength_nm=550.0)
    r = polarid.classify([n, n], [k, k], "builtin-rgb", strings=True)
    assert list(r["status"]) == ["no_common_band"] * 2 and list(r["predicted"]) == ["unknown"] * 2
    r = polarid.classify([n, n], [k, k], "builtin-rgb", wavelength_nm=[550.0, 650.0], strings=True)
    assert list(r["status"]) == ["ok", "ok"] and list(r["bands_used"]) == ["550", "650"]


def test_classify_multi_band_errors(colour):
    with pytest.raises(ValueError, match="band_axis needs wavelength_nm"):
        polarid.classify([1.0, 1.1], [2.0, 2.1], "builtin-rgb", band_axis=0)
    with pytest.raises(ValueError, match="band_axis 2 is out of range"):
        polarid.classify([1.0, 1.1], [2.0, 2.1], "builtin-rgb", wavelength_nm=[450, 550], band_axis=2)
    with pytest.raises(ValueError, match="wavelength_nm"):
        polarid.classify(1.0, 2.0, "builtin-rgb", wavelength_nm=5.0)
    with pytest.raises(ValueError, match="rule must be"):
        polarid.classify_table(colour["fits"], "builtin-rgb", rule="best")
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        polarid.classify_table(colour["dir"] / "nope.csv", "builtin-rgb")


# --- maps of colour manifests (polarid.map_manifest == polarid map) -----------------------

@pytest.mark.parametrize("source,bin,rule", [("builtin-rgb", 1, "set"), ("model", 2, "set"), ("lib3", 1, "nearest")])
def test_map_manifest_bands_equals_cli(colour, polarid_cli, source, bin, rule):
    """Per-band images == the CLI's n_450.tif ... (bit for bit), the multi-band class and
    reason images and the summary == the CLI's."""
    from test_map_manifest import read_tiff
    import json

    manifest = colour["dir"] / "sim3" / "manifest.toml"
    spec = colour.get(source, source)
    out = colour["dir"] / f"map_{source}_{bin}_{rule}"
    opt = "--model" if source == "model" else "--library"
    run(polarid_cli, "map", manifest, opt, spec, "-o", out, "--bin", bin, "--rule", rule)
    if source == "model":
        py = polarid.map_manifest(manifest, spec, bin=bin, rule=rule)
    else:
        py = polarid.map_manifest(manifest, library=str(spec), bin=bin, rule=rule)

    assert "n" not in py and list(py["bands"]) == [450.0, 550.0, 650.0]
    summary = json.loads((out / "map_summary.json").read_text())
    for key in ("manifest", "model"):
        summary.pop(key)
    assert py["summary"] == summary
    for (wl, b), sb in zip(py["bands"].items(), summary["bands"]):
        assert b["wavelength_nm"] == wl == sb["wavelength_nm"] and b["captures"] == sb["captures"]
        for key in ("n", "k", "n_se", "k_se", "rms_residual"):
            cli = read_tiff(out / f"{key}_{wl:.0f}.tif")
            assert b[key].dtype == np.float32 and b[key].shape == cli.shape == py["class"].shape, key
            np.testing.assert_array_equal(b[key], cli, err_msg=f"{key} {wl}")
        assert b["reason"].shape == py["class"].shape
        counts = {r: int(c) for r, c in zip(py["reason_names"], b["reason_counts"]) if c > 0}
        assert counts == sb["reasons"]
        assert int((b["reason"] == 0).sum()) == sb["fitted"] > 0
    for key in ("class", "reason"):
        np.testing.assert_array_equal(py[key], read_tiff(out / f"{key}.tif"), err_msg=key)
    classes = json.loads((out / "classes.json").read_text())
    assert py["class_names"] == [classes[str(i)] for i in range(len(classes))]
    if source != "builtin-rgb":
        return
    # Copper and gold told apart per pixel: most of each plate's pixels are its material
    # and none is the other metal.
    x = lambda c: slice(c + 8, c + 24)
    cu, au = py["class_names"].index("copper"), py["class_names"].index("gold")
    for col, code, other in ((0, cu, au), (32, au, cu)):
        block = py["class"][x(0), x(col)]
        assert (block == code).mean() > 0.5 and not (block == other).any(), py["class_names"][code]


def test_map_manifest_bands_options(colour, polarid_cli):
    manifest = colour["dir"] / "sim3" / "manifest.toml"
    with pytest.raises(ValueError, match="give model .* or library"):
        polarid.map_manifest(manifest)
    with pytest.raises(ValueError, match="not both or neither"):
        polarid.map_manifest(manifest, colour["model"], library="builtin-rgb")
    with pytest.raises(FileNotFoundError, match="builtin-tv: No such file, and not a built-in library"):
        polarid.map_manifest(manifest, library="builtin-tv")
    run(polarid_cli, "simulate", REPO_SCENES / "aluminum_test_60.toml", "-o", colour["dir"] / "mono_sim")
    # A library maps single-band manifests too (each material tested against every
    # block's rows at the captures' wavelength).
    mono = polarid.map_manifest(
        colour["dir"] / "mono_sim" / "manifest.toml", library="builtin-rgb", bin=16
    )
    assert mono["class_names"][0] == "unknown" and mono["class_names"][-1] == "ambiguous"
