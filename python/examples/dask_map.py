"""Material maps of a capture set on Dask: read lazily, map block by block, write back.

    python python/examples/dask_map.py CAPTURES MODEL -o maps [--bin 2] [--chunk 512]
        [--scheduler threads|processes|distributed] [--workers 2]

CAPTURES is either

* a directory of captures described by its ``manifest.toml`` (the layout ``polarid
  simulate`` writes and ``polarid map`` reads: TIFF/PNG frames per capture, or DoFP
  mosaics), or the manifest itself; every frame file is read lazily (one
  ``dask.delayed`` read per file, so the frames never all sit in the client's memory);
* or a zarr store (``*.zarr``, needs ``pip install zarr``) holding an array ``frames``
  (T, A, H, W) (or DoFP mosaics (T, H, W)) whose attributes give ``beta_deg`` (T
  values) and ``angles_deg`` (or ``pattern``), and optionally ``dark_level`` and
  ``saturation``.

MODEL is a model JSON of ``polarid train``; the maps are those of ``polarid map`` with
its defaults (answer sets at 95 %; noise-weighted fits with a β per pixel). The maps
``n, k, n_se, k_se, rms_residual, class, reason`` are written to ``-o``: into a zarr
store when it ends in ``.zarr`` (``dask.array.to_zarr``, block by block), else as one
``.npy`` file per map (each assembled from its blocks) with ``names.json``; the code →
name tables (``class_names``, ``reason_names``) and the fit weights (``weights``,
``noise``) go into the zarr store's attributes or names.json.
A progress bar shows the blocks done (``dask.diagnostics.ProgressBar`` for the local
schedulers, ``distributed.progress`` on a cluster).

Try it on a simulated set:

    polarid simulate examples/scenes/dofp_plates.toml -o sim/dofp
    polarid measure sim/dofp/manifest.toml -o sim/m.csv && polarid fit sim/m.csv -o sim/f.csv
    polarid train sim/f.csv -o sim/model.json
    python python/examples/dask_map.py sim/dofp sim/model.json -o sim/maps --chunk 64
"""

import argparse
import json
import os
from pathlib import Path

import dask
import dask.array as da
import numpy as np

import polarid
import polarid.dask


def read_image(path):
    """One frame as stored (uint8/uint16/float32). OpenCV or tifffile, whichever exists."""
    try:
        import cv2

        a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if a is not None:
            return a
    except ImportError:
        pass
    import tifffile

    return tifffile.imread(path)


def lazy_image(path, shape, dtype):
    return da.from_delayed(dask.delayed(read_image)(path), shape=shape, dtype=dtype)


def from_manifest(path, chunk):
    """Lazy frames and the mapping options of a manifest (far-field angles)."""
    path = Path(path)
    m = polarid.load_manifest(path / "manifest.toml" if path.is_dir() else path)
    caps = m["captures"]
    kinds = {c["kind"] for c in caps}
    if kinds - {"frames", "dofp"} or len(kinds) != 1:
        raise SystemExit(f"{m['path']}: captures of kind {sorted(kinds)}; this example maps frames or DoFP sets")
    first_file = caps[0]["dofp"]["file"] if "dofp" in kinds else caps[0]["frames"][0]["file"]
    probe = read_image(first_file)  # the size and dtype of every frame
    img = lambda f: lazy_image(f, probe.shape, probe.dtype)  # noqa: E731
    if "dofp" in kinds:
        frames = da.stack([img(c["dofp"]["file"]) for c in caps])
        geometry = dict(angles_deg=None, pattern=caps[0]["dofp"]["pattern"])
    else:
        frames = da.stack([da.stack([img(f["file"]) for f in c["frames"]]) for c in caps])
        geometry = dict(angles_deg=[f["angle_deg"] for f in caps[0]["frames"]])
    frames = frames.rechunk({frames.ndim - 2: chunk, frames.ndim - 1: chunk})
    options = dict(dark_level=[c["dark_level"] for c in caps],
                   saturation=[c["saturation"] for c in caps])
    return frames, [c["beta_deg"] for c in caps], geometry, options


def from_zarr(path, chunk):
    import zarr

    z = zarr.open(str(path), mode="r")
    arr = z["frames"]
    attrs = dict(arr.attrs)
    frames = da.from_zarr(arr)
    frames = frames.rechunk({frames.ndim - 2: chunk, frames.ndim - 1: chunk})
    geometry = dict(angles_deg=attrs.get("angles_deg"), pattern=attrs.get("pattern"))
    options = {k: attrs[k] for k in ("dark_level", "saturation") if k in attrs}
    return frames, attrs["beta_deg"], geometry, options


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("captures", help="a directory with manifest.toml, a manifest, or a .zarr store")
    ap.add_argument("model", help="model JSON of polarid train")
    ap.add_argument("-o", "--output", required=True, help="output directory, or a .zarr store")
    ap.add_argument("--bin", type=int, default=1)
    ap.add_argument("--chunk", type=int, default=512, help="rows and columns per block of frames")
    ap.add_argument("--scheduler", choices=("threads", "processes", "distributed"), default="threads")
    ap.add_argument("--workers", type=int, default=2, help="worker processes of the local cluster")
    a = ap.parse_args()

    src = Path(a.captures)
    load = from_zarr if src.suffix == ".zarr" else from_manifest
    frames, beta_deg, geometry, options = load(src, a.chunk)
    maps = polarid.dask.material_map(frames, geometry.pop("angles_deg"), beta_deg, a.model,
                                     bin=a.bin, **geometry, **options)
    names = {"class": maps.pop("class_names"), "reason": maps.pop("reason_names")}
    # What the fits used: "noise" with the noise model (estimated here when weighted, as
    # polarid map does), or "none".
    fit_info = {"weights": maps.pop("weights"), "noise": maps.pop("noise")}
    print(f"{frames.shape} frames in {frames.numblocks[-2] * frames.numblocks[-1]} blocks -> "
          f"maps {maps['n'].shape}, classes {names['class'][1:]}")

    out = Path(a.output)
    if out.suffix == ".zarr":
        # One store, one array per map, written block by block as the blocks finish.
        targets = [da.to_zarr(v, str(out), component=k, overwrite=True, compute=False)
                   for k, v in maps.items()]
    else:
        out.mkdir(parents=True, exist_ok=True)
        targets = list(maps.values())

    if a.scheduler == "distributed":
        from distributed import Client, LocalCluster, progress

        with LocalCluster(n_workers=a.workers, threads_per_worker=max(1, (os.cpu_count() or 2) // a.workers),
                          dashboard_address=None) as cluster, Client(cluster) as client:
            futures = client.compute(targets)
            progress(futures)
            results = client.gather(futures)
    else:
        from dask.diagnostics import ProgressBar

        with ProgressBar():
            results = dask.compute(*targets, scheduler=a.scheduler)

    tables = {"class_names": names["class"], "reason_names": names["reason"], **fit_info}
    if out.suffix == ".zarr":
        import zarr

        zarr.open_group(str(out), mode="a").attrs.update(tables)  # code -> name tables
        classes = da.from_zarr(str(out), component="class").compute()
    else:
        for k, v in zip(maps, results):
            np.save(out / f"{k}.npy", v)
        (out / "names.json").write_text(json.dumps(tables, indent=1))
        classes = results[list(maps).index("class")]
    counts = np.bincount(np.asarray(classes).ravel(), minlength=len(names["class"]))
    for code, c in enumerate(counts):
        print(f"  {names['class'][code]:<12} {c:>9} pixels")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
