"""polarid.dask.material_map on a dask.distributed LocalCluster of 2 worker processes:
the same maps as `polarid map` with its defaults (set rule at 95 %, ambiguous last,
noise-weighted fits with calibrated geometry: classes and reasons identical, |dn|, |dk|
<= 1e-6, the same noise model) for rotating-polarizer frames, DoFP mosaics and
calibrated geometry (a beta per pixel), at several bins, with chunks whose edges cut
through the frames; its other options (nearest rule, weights) as the CLI's; and the same
map (bit for bit) whatever the chunking."""

import json
import subprocess

import numpy as np
import pytest

import polarid
from conftest import REPO_ROOT

da = pytest.importorskip("dask.array")
distributed = pytest.importorskip("distributed")
import dask  # noqa: E402

import polarid.dask as pdask  # noqa: E402

SCENES = REPO_ROOT / "examples" / "scenes"
FLOATS = ("n", "k", "n_se", "k_se", "rms_residual")


def read_image(path):
    """A single-channel TIFF or PNG as stored (uint16 frames, float32 maps)."""
    import cv2

    a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert a is not None, path
    return a


def run(cli, *args):
    subprocess.run([str(cli), *map(str, args)], check=True, capture_output=True)


@pytest.fixture(scope="module")
def client():
    """One cluster for the module: 2 worker processes of 1 thread."""
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def sets(tmp_path_factory, polarid_cli):
    d = tmp_path_factory.mktemp("dask")
    run(polarid_cli, "simulate", SCENES / "dofp_plates.toml", "-o", d / "dofp")
    run(polarid_cli, "simulate", SCENES / "aluminum_test_60.toml", "-o", d / "frames")
    run(polarid_cli, "simulate", SCENES / "bench_lamp_lens.toml", "-o", d / "bench")
    run(polarid_cli, "measure", d / "dofp" / "manifest.toml", "-o", d / "m.csv")
    run(polarid_cli, "fit", d / "m.csv", "-o", d / "f.csv")
    run(polarid_cli, "train", d / "f.csv", "-o", d / "model.json")
    return d


def load(manifest):
    """Frames (T, A, H, W) or mosaics (T, H, W), angles/pattern, β, levels of a manifest."""
    m = polarid.load_manifest(manifest)
    caps = m["captures"]
    if caps[0]["kind"] == "dofp":
        frames = np.stack([read_image(c["dofp"]["file"]) for c in caps])
        extra = dict(angles_deg=None, pattern=caps[0]["dofp"]["pattern"])
    else:
        frames = np.stack([np.stack([read_image(f["file"]) for f in c["frames"]]) for c in caps])
        extra = dict(angles_deg=[f["angle_deg"] for f in caps[0]["frames"]])
    levels = dict(dark_level=[c["dark_level"] for c in caps], saturation=[c["saturation"] for c in caps])
    return frames, np.array([c["beta_deg"] for c in caps]), extra, levels


def cli_map(cli, sets, name, bin, *options):
    """`polarid map` of a simulated set with its defaults (or `options`), read back."""
    tag = "".join(str(o).strip("-") for o in options)
    out = sets / f"cli_{name}_{bin}{tag}"
    if not out.exists():
        run(cli, "map", sets / name / "manifest.toml", "--model", sets / "model.json", "-o", out,
            "--bin", bin, *options)
    maps = {k: read_image(out / f"{k}.tif") for k in (*FLOATS, "class", "reason")}
    maps["class_names"] = [v for _, v in sorted(json.loads((out / "classes.json").read_text()).items(),
                                                 key=lambda kv: int(kv[0]))]
    summary = json.loads((out / "map_summary.json").read_text())
    maps["reason_names"] = summary["reason_codes"]
    maps["summary"] = summary
    return maps


def assert_same_noise(got, cli, rtol=1e-12):
    """The Dask map's noise model is the one `polarid map` estimated."""
    want = cli["summary"]["noise"]
    assert cli["summary"]["weights"] == got["weights"]
    if want is None:
        assert got["noise"] is None
        return
    for key in ("pixels", "outliers"):
        assert got["noise"][key] == want[key], key
    def rel(k):
        g, w = got["noise"][k], want[k]
        return "equal" if g == w else f"rel. diff {g / w - 1:.1e}" if w else f"{g} vs {w}"

    print("noise model: " + ", ".join(f"{k} {got['noise'][k]} ({rel(k)})"
                                      for k in ("read_noise_dn", "gain_e_per_dn", "reduced_chi2"))
          + f", pixels {want['pixels']}, outliers {want['outliers']}")
    for key in ("read_noise_dn", "gain_e_per_dn", "reduced_chi2"):
        assert got["noise"][key] == pytest.approx(want[key], rel=rtol), key


def assert_same(got, cli):
    assert got["class_names"] == cli["class_names"]
    assert got["reason_names"] == cli["reason_names"]
    np.testing.assert_array_equal(got["class"], cli["class"])
    np.testing.assert_array_equal(got["reason"], cli["reason"])
    if "summary" in cli and isinstance(got.get("weights"), str):
        assert_same_noise(got, cli)
    for key in FLOATS:
        g, c = got[key], cli[key]
        assert g.dtype == np.float32 and g.shape == c.shape, key
        np.testing.assert_array_equal(np.isnan(g), np.isnan(c), err_msg=key)
        ok = ~np.isnan(c)
        diff = np.abs(g[ok].astype(np.float64) - c[ok])
        # n, k: the acceptance (|dn|, |dk| <= 1e-6); the standard errors of ill-conditioned
        # pixels reach ~100: relative. Differences come only from beta_deg (the manifest's
        # beta in degrees, back to radians: the last bit of beta may differ).
        tol = 1e-6 if key in ("n", "k") else 1e-6 * np.maximum(1.0, np.abs(c[ok]))
        assert (diff <= tol).all(), (key, diff.max())
    assert (cli["reason"] == 0).sum() > 0  # something was classified
    ok = ~np.isnan(cli["n"])
    print(f"dask vs cli: {cli['class'].size} pixels, classes equal {(got['class'] == cli['class']).sum()}, "
          f"classified {(cli['reason'] == 0).sum()}, max |dn| {np.abs(got['n'][ok] - cli['n'][ok]).max():.2e}, "
          f"max |dk| {np.abs(got['k'][ok] - cli['k'][ok]).max():.2e}, weights {cli['summary']['weights']}")


def compute(maps, scheduler):
    keys = [k for k, v in maps.items() if isinstance(v, da.Array)]
    maps = dict(maps)
    vals = dask.compute(*[maps[k] for k in keys], scheduler=scheduler)
    return {**maps, **dict(zip(keys, vals))}


@pytest.mark.parametrize("bin,chunks", [(1, (37, 50)), (4, (40, 33)), (2, (128, 128))])
def test_frames_equal_cli(client, sets, polarid_cli, bin, chunks):
    frames, beta, extra, levels = load(sets / "frames" / "manifest.toml")
    x = da.from_array(frames, chunks=(1, 2, *chunks))
    maps = pdask.material_map(x, extra["angles_deg"], beta, sets / "model.json", bin=bin, **levels)
    assert maps["n"].numblocks == maps["class"].numblocks
    if chunks[0] < frames.shape[2]:
        assert maps["n"].numblocks[0] > 1 and maps["n"].numblocks[1] > 1  # edges inside
    assert_same(compute(maps, client), cli_map(polarid_cli, sets, "frames", bin))


@pytest.mark.parametrize("bin,chunks", [(1, (30, 70)), (2, (64, 50))])
def test_dofp_equal_cli(client, sets, polarid_cli, bin, chunks):
    mosaics, beta, extra, levels = load(sets / "dofp" / "manifest.toml")
    x = da.from_array(mosaics, chunks=(1, *chunks))
    maps = pdask.material_map(x, None, beta, sets / "model.json", pattern=extra["pattern"], bin=bin,
                              **levels)
    assert maps["n"].numblocks[0] > 1 and maps["n"].numblocks[1] > 1
    assert_same(compute(maps, client), cli_map(polarid_cli, sets, "dofp", bin))


def test_per_pixel_beta_equals_cli(client, sets, polarid_cli):
    """Calibrated geometry: β per pixel and capture (as polarid map computes it from the
    camera, planes and lamp positions), as a dask array; bin 2 and cut chunks.

    The β maps come from map_manifest as float64 degrees of the float32 radians polarid
    map fits with, so degrees → radians → float32 gives the CLI's β bit for bit."""
    frames, _, extra, levels = load(sets / "bench" / "manifest.toml")
    cli = cli_map(polarid_cli, sets, "bench", 2)
    beta = polarid.map_manifest(sets / "bench" / "manifest.toml", sets / "model.json", bin=2)["beta_deg"]
    assert beta.shape[0] == frames.shape[0] and np.isfinite(beta).any()
    x = da.from_array(frames, chunks=(3, 4, 100, 130))
    b = da.from_array(beta, chunks=(9, 40, 40))
    with open(sets / "model.json") as f:
        model = json.load(f)  # the model as an object
    maps = pdask.material_map(x, extra["angles_deg"], b, model, bin=2, **levels)
    assert "no_geometry" in maps["reason_names"] and min(maps["n"].numblocks) > 1
    got = compute(maps, client)
    assert got["class_names"] == cli["class_names"] and got["reason_names"] == cli["reason_names"]
    # Calibrated geometry: noise-weighted fits by default, the CLI's noise model (the same
    # sample; its numbers equal, checked to 1e-5).
    assert got["weights"] == "noise" and "ambiguous" in got["class_names"]
    assert_same_noise(got, cli, rtol=1e-5)
    firm = (cli["n_se"] < 0.1) & (cli["k_se"] < 0.1)
    assert firm.sum() > 1000 and (cli["reason"][firm] == 0).sum() > 500
    ok = ~np.isnan(cli["n"])
    print(f"per-pixel beta: {cli['class'].size} pixels, classes equal {(got['class'] == cli['class']).sum()}, "
          f"classified {(cli['reason'] == 0).sum()}, max |dn| {np.abs(got['n'][ok] - cli['n'][ok]).max():.2e}, "
          f"max |dk| {np.abs(got['k'][ok] - cli['k'][ok]).max():.2e}")
    # The acceptance, on every pixel: identical classes and reasons, |dn|, |dk| <= 1e-6.
    np.testing.assert_array_equal(got["class"], cli["class"])
    np.testing.assert_array_equal(got["reason"], cli["reason"])
    for key in ("n", "k"):
        assert np.abs(got[key][ok] - cli[key][ok]).max() <= 1e-6, key
    np.testing.assert_array_equal(np.isnan(got["n"]), np.isnan(cli["n"]))
    # One block against the cut chunks: the same classes and reasons, n and k to 1e-6.
    # (Per-pixel-β fits are grouped by their usable captures within a tile, and a group's
    # last bits depend on its members: `polarid map --tile 1000` differs from the default
    # tile in the same way; the far-field fits do not, see test_chunking_is_bit_exact.)
    one = pdask.material_map(frames, extra["angles_deg"], beta, model, bin=2, scheduler="threads", **levels)
    assert one["noise"] == maps["noise"]  # the same global estimate, one block or many
    ref = compute(one, "threads")
    for key in ("class", "reason"):
        np.testing.assert_array_equal(got[key], ref[key], err_msg=key)
    for key in ("n", "k"):
        np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=1e-6, err_msg=key)


@pytest.mark.parametrize("name,bin", [("frames", 2), ("dofp", 2)])
def test_chunking_is_bit_exact(client, sets, name, bin):
    """Far field: the map of cut chunks is the map of one block, bit for bit."""
    frames, beta, extra, levels = load(sets / name / "manifest.toml")
    cut = (2, 2) + (34, 46) if name == "frames" else (2, 34, 46)
    maps = [pdask.material_map(da.from_array(frames, chunks=c), extra["angles_deg"], beta,
                               sets / "model.json", bin=bin, pattern=extra.get("pattern"), **levels)
            for c in (frames.shape, cut)]
    assert maps[1]["n"].numblocks[0] > 2 and maps[1]["n"].numblocks[1] > 2
    one, many = compute(maps[0], "threads"), compute(maps[1], client)
    for key in (*FLOATS, "class", "reason"):
        np.testing.assert_array_equal(many[key], one[key], err_msg=key)


def test_options_and_errors(client, sets):
    frames, beta, extra, levels = load(sets / "frames" / "manifest.toml")
    model = sets / "model.json"
    x = da.from_array(frames, chunks=(1, 4, 50, 50))
    with pytest.raises(ValueError, match=r"must end at multiples of 4 \(bin=4\)"):
        pdask.material_map(x, extra["angles_deg"], beta, model, bin=4, rechunk=False)
    with pytest.raises(ValueError, match=r"bin must be in 1\.\.=64, got 0"):
        pdask.material_map(x, extra["angles_deg"], beta, model, bin=0)
    with pytest.raises(ValueError, match="metric must be"):
        pdask.material_map(x, extra["angles_deg"], beta, model, metric="cosine")
    with pytest.raises(ValueError, match=r"beta_deg must have shape \(\d+,\)"):
        pdask.material_map(x, extra["angles_deg"], beta[:2], model)
    with pytest.raises(FileNotFoundError, match="nope.json"):
        pdask.material_map(x, extra["angles_deg"], beta, sets / "nope.json")
    with pytest.raises(ValueError, match="angles_deg"):
        pdask.material_map(x, None, beta, model)
    for bad, match in [(dict(rule="vote"), "rule must be"), (dict(weights="some"), "weights must be"),
                       (dict(confidence=1.5), r"confidence must be in \(0, 1\), got 1\.5"),
                       (dict(dolp_floor=-1), "dolp-floor|dolp_floor"),
                       (dict(angle_sd_deg=[0.2, 0.3]), "angle_sd_deg gives 2"),
                       (dict(weights="none", noise=dict(read_var_dn2=1.0, inv_gain=0.1)), "weights=\"none\"")]:
        with pytest.raises(ValueError, match=match):
            pdask.material_map(x, extra["angles_deg"], beta, model, **bad)
    # Options reach the blocks: everything dark, or everything rejected.
    dark = pdask.material_map(x, extra["angles_deg"], beta, model, min_s0=1e9, **levels)
    r = dark["reason"].compute(scheduler=client)
    assert (r == dark["reason_names"].index("dark")).all()
    strict = pdask.material_map(x, extra["angles_deg"], beta, model, rule="nearest", max_distance=1e-6,
                                **levels)
    r = strict["reason"].compute(scheduler=client)
    assert (r == strict["reason_names"].index("rejected")).any() and not (r == 0).any()


def test_aligned_chunks():
    assert pdask.aligned_chunks((37, 37, 37, 17), 4) == (36, 36, 36, 20)
    assert pdask.aligned_chunks((50, 50, 28), 4) == (48, 52, 28)
    assert pdask.aligned_chunks((64, 64, 2), 4, minimum=4) == (64, 66)  # last too small
    assert pdask.aligned_chunks((3,), 4) == (3,)
    assert sum(pdask.aligned_chunks((10,) * 13, 8)) == 130


def test_example_script(sets, polarid_cli, tmp_path):
    """python/examples/dask_map.py: a directory of captures to maps on disk (threads)."""
    import sys

    out = tmp_path / "maps"
    r = subprocess.run([sys.executable, str(REPO_ROOT / "python" / "examples" / "dask_map.py"),
                        str(sets / "dofp"), str(sets / "model.json"), "-o", str(out), "--bin", "2",
                        "--chunk", "48"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "100% Completed" in r.stdout + r.stderr  # the progress bar
    cli = cli_map(polarid_cli, sets, "dofp", 2)
    np.testing.assert_array_equal(np.load(out / "class.npy"), cli["class"])
    names = json.loads((out / "names.json").read_text())
    assert names["class_names"] == cli["class_names"]


def test_nearest_unweighted_equals_cli(client, sets, polarid_cli):
    """The options reach the blocks as the CLI's: --rule nearest --weights none."""
    frames, beta, extra, levels = load(sets / "frames" / "manifest.toml")
    x = da.from_array(frames, chunks=(1, 2, 41, 57))
    maps = pdask.material_map(x, extra["angles_deg"], beta, sets / "model.json", bin=2, rule="nearest",
                              weights="none", **levels)
    assert "ambiguous" not in maps["class_names"] and maps["noise"] is None
    assert_same(compute(maps, client),
                cli_map(polarid_cli, sets, "frames", 2, "--rule", "nearest", "--weights", "none"))


@pytest.mark.parametrize("name,bin,chunks", [("frames", 2, (2, 2, 46, 34)), ("dofp", 1, (2, 40, 54))])
def test_noise_weighted_equals_cli(client, sets, polarid_cli, name, bin, chunks):
    """--weights noise in the far field: the global noise model estimated over the
    blocks (two passes) is the CLI's (the same sample, pixels and outliers; its numbers
    to 1e-12), and the weighted maps equal the CLI's."""
    frames, beta, extra, levels = load(sets / name / "manifest.toml")
    x = da.from_array(frames, chunks=chunks)
    maps = pdask.material_map(x, extra["angles_deg"], beta, sets / "model.json", bin=bin, weights="noise",
                              pattern=extra.get("pattern"), **levels)
    assert maps["n"].numblocks[0] > 1 and maps["n"].numblocks[1] > 1
    assert maps["weights"] == "noise" and maps["noise"]["pixels"] > 1000
    cli = cli_map(polarid_cli, sets, name, bin, "--weights", "noise")
    assert_same(compute(maps, client), cli)
    # The model given back (noise=) skips the passes and gives the same bits.
    again = pdask.material_map(x, extra["angles_deg"], beta, sets / "model.json", bin=bin,
                               noise=maps["noise"], pattern=extra.get("pattern"), **levels)
    a, b = compute(maps, client), compute(again, client)
    for key in (*FLOATS, "class", "reason"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    # ... and so does map_summary.json's noise (read noise and gain, rounded through the
    # square root and the inverse: n and k to 1e-6).
    from_cli = compute(pdask.material_map(x, extra["angles_deg"], beta, sets / "model.json", bin=bin,
                                          noise=cli["summary"]["noise"], pattern=extra.get("pattern"),
                                          **levels), client)
    np.testing.assert_array_equal(from_cli["class"], cli["class"])
    for key in ("n", "k"):
        np.testing.assert_allclose(from_cli[key], cli[key], rtol=0, atol=1e-6)


# --- colour polarization mosaics (per band, docs/BANDS.md) ----------------------------------

@pytest.fixture(scope="module")
def colour_set(tmp_path_factory, polarid_cli):
    """Colour captures of copper, gold and aluminum (RGGB blocks; the scene of
    test_classify_bands), a three-band model trained on another seed of them."""
    from test_classify_bands import SCENE

    d = tmp_path_factory.mktemp("dask_colour")
    for seed in (3, 4):
        (d / f"scene{seed}.toml").write_text(SCENE.format(seed=seed))
        run(polarid_cli, "simulate", d / f"scene{seed}.toml", "-o", d / f"sim{seed}")
    run(polarid_cli, "measure", d / "sim4" / "manifest.toml", "-o", d / "m4.csv")
    run(polarid_cli, "fit", d / "m4.csv", "-o", d / "f4.csv")
    run(polarid_cli, "train", d / "f4.csv", "-o", d / "model.json")
    return d


@pytest.mark.parametrize("bin,chunks,source", [
    (1, (12, 40), "builtin-rgb"), (2, (16, 36), "model"), (4, (32, 96), "builtin-rgb")])
def test_colour_equal_cli(client, colour_set, polarid_cli, bin, chunks, source):
    """Colour mosaics with color="RGGB": every band's n, k, standard errors, RMS residual
    and the multi-band classes and reasons equal `polarid map`'s on the same captures."""
    manifest = colour_set / "sim3" / "manifest.toml"
    m = polarid.load_manifest(manifest)
    caps = m["captures"]
    assert caps[0]["kind"] == "colour_dofp"
    raw = np.stack([read_image(c["dofp"]["file"]) for c in caps])
    beta = np.array([c["beta_deg"] for c in caps])
    levels = dict(dark_level=[c["dark_level"] for c in caps], saturation=[c["saturation"] for c in caps])
    out = colour_set / f"cli_{bin}_{source}"
    spec = colour_set / "model.json" if source == "model" else source
    run(polarid_cli, "map", manifest, "--model" if source == "model" else "--library", spec, "-o", out,
        "--bin", bin)
    x = da.from_array(raw, chunks=(2, *chunks))
    src = dict(model=spec) if source == "model" else dict(library=source)
    maps = pdask.material_map(x, None, beta, color=caps[0]["dofp"]["color"],
                              pattern=caps[0]["dofp"]["pattern"], bin=bin, **src, **levels)
    if chunks != (32, 96):
        assert maps["class"].numblocks[0] > 1 and maps["class"].numblocks[1] > 1  # edges inside
    assert list(maps["bands"]) == [450.0, 550.0, 650.0]
    arrays = {"class": maps["class"], "reason": maps["reason"]}
    for wl, b in maps["bands"].items():
        for key, a in b.items():
            arrays[(wl, key)] = a
    got = dict(zip(arrays, dask.compute(*arrays.values(), scheduler=client)))
    classes = json.loads((out / "classes.json").read_text())
    assert maps["class_names"] == [classes[str(i)] for i in range(len(classes))]
    np.testing.assert_array_equal(got["class"], read_image(out / "class.tif"))
    np.testing.assert_array_equal(got["reason"], read_image(out / "reason.tif"))
    summary = json.loads((out / "map_summary.json").read_text())
    # A library's hypothesis tests weigh the fits (one noise model per band, estimated as
    # polarid map does; map_summary.json reports the first band's).
    assert summary["weights"] == maps["weights"] == ("none" if source == "model" else "noise")
    assert_same_noise(maps, {"summary": summary})
    worst = 0.0
    for wl, sb in zip(maps["bands"], summary["bands"]):
        for key in FLOATS:
            g, c = got[(wl, key)], read_image(out / f"{key}_{wl:.0f}.tif")
            assert g.dtype == np.float32 and g.shape == c.shape, key
            np.testing.assert_array_equal(np.isnan(g), np.isnan(c), err_msg=f"{key} {wl}")
            ok = ~np.isnan(c)
            diff = np.abs(g[ok].astype(np.float64) - c[ok])
            tol = 1e-6 if key in ("n", "k") else 1e-6 * np.maximum(1.0, np.abs(c[ok]))
            assert (diff <= tol).all(), (key, wl, diff.max())
            if key in ("n", "k"):
                worst = max(worst, float(diff.max()))
        assert int((got[(wl, "reason")] == 0).sum()) == sb["fitted"] > 0
    assert (got["reason"] == 0).sum() > 0
    print(f"dask colour vs cli (bin {bin}, {source}): {got['class'].size} pixels, classes equal "
          f"{(got['class'] == read_image(out / 'class.tif')).sum()}, max |dn|, |dk| {worst:.2e}")


def test_colour_options(colour_set):
    raw = np.zeros((3, 16, 16), np.uint16)
    with pytest.raises(ValueError, match="not both or neither"):
        pdask.material_map(raw, None, [50, 55, 60], color="RGGB")
    with pytest.raises(ValueError, match="one angle per capture"):
        pdask.material_map(raw, None, np.zeros((3, 8, 8)), library="builtin-rgb", color="RGGB")
    with pytest.raises(ValueError, match="colour mosaics only"):
        pdask.material_map(raw, None, [50, 55, 60], library="builtin-rgb", pattern=[90, 45, 135, 0])


# --- calibrated colour captures (a beta per pixel and band-independent geometry) -------------

# A calibrated colour scene (docs/SCENE.md, "Calibrated colour scenes"): copper, gold and
# aluminum plates seen by a lens camera at 0.45 m, a lamp at ten positions.
CALIBRATED_COLOUR_SCENE = (SCENES / "colour_calibrated_bench.toml").read_text()


@pytest.fixture(scope="module")
def calibrated_colour_set(tmp_path_factory, polarid_cli):
    """The calibrated colour scene at seed 3, a three-band model trained on seed 4."""
    d = tmp_path_factory.mktemp("dask_colour_calibrated")
    for seed in (3, 4):
        (d / f"scene{seed}.toml").write_text(CALIBRATED_COLOUR_SCENE.replace("seed = 3", f"seed = {seed}"))
        run(polarid_cli, "simulate", d / f"scene{seed}.toml", "-o", d / f"sim{seed}")
    run(polarid_cli, "measure", d / "sim4" / "manifest.toml", "-o", d / "m4.csv")
    run(polarid_cli, "fit", d / "m4.csv", "-o", d / "f4.csv")
    run(polarid_cli, "train", d / "f4.csv", "-o", d / "model.json")
    return d


def test_colour_calibrated_equal_cli(client, calibrated_colour_set, polarid_cli):
    """Calibrated colour mosaics: a beta per pixel and capture (map_manifest's, as polarid
    map computes it), noise-weighted per band by default; the Dask map's classes, reasons
    and every band's n, k equal `polarid map`'s (bin 2, chunks cutting the frames)."""
    d = calibrated_colour_set
    manifest = d / "sim3" / "manifest.toml"
    caps = polarid.load_manifest(manifest)["captures"]
    raw = np.stack([read_image(c["dofp"]["file"]) for c in caps])
    levels = dict(dark_level=[c["dark_level"] for c in caps], saturation=[c["saturation"] for c in caps])
    out = d / "cli_2"
    run(polarid_cli, "map", manifest, "--model", d / "model.json", "-o", out, "--bin", "2")
    beta = polarid.map_manifest(manifest, d / "model.json", bin=2)["beta_deg"]
    assert beta.shape == (raw.shape[0], raw.shape[1] // 2, raw.shape[2] // 2)
    x = da.from_array(raw, chunks=(3, 96, 128))
    b = da.from_array(beta, chunks=(4, 24, 32))
    maps = pdask.material_map(x, None, b, d / "model.json", color=caps[0]["dofp"]["color"],
                              pattern=caps[0]["dofp"]["pattern"], bin=2, **levels)
    assert min(maps["class"].numblocks) > 1
    summary = json.loads((out / "map_summary.json").read_text())
    assert summary["weights"] == maps["weights"] == "noise"
    arrays = {"class": maps["class"], "reason": maps["reason"]}
    for wl, band in maps["bands"].items():
        for key in ("n", "k"):
            arrays[(wl, key)] = band[key]
    got = dict(zip(arrays, dask.compute(*arrays.values(), scheduler=client)))
    classes = json.loads((out / "classes.json").read_text())
    assert maps["class_names"] == [classes[str(i)] for i in range(len(classes))]
    cli_class = read_image(out / "class.tif")
    np.testing.assert_array_equal(got["reason"], read_image(out / "reason.tif"))
    np.testing.assert_array_equal(got["class"], cli_class)
    assert (got["reason"] == 0).sum() > 500  # plates named
    worst = 0.0
    for wl in maps["bands"]:
        for key in ("n", "k"):
            g, c = got[(wl, key)], read_image(out / f"{key}_{wl:.0f}.tif")
            np.testing.assert_array_equal(np.isnan(g), np.isnan(c), err_msg=f"{key} {wl}")
            ok = ~np.isnan(c)
            diff = np.abs(g[ok].astype(np.float64) - c[ok])
            assert (diff <= 1e-6).all(), (key, wl, diff.max())
            worst = max(worst, float(diff.max()))
    print(f"dask calibrated colour vs cli: {cli_class.size} pixels, classified "
          f"{(got['reason'] == 0).sum()}, max |dn|, |dk| {worst:.2e}")
