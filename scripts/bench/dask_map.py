#!/usr/bin/env python3
"""Throughput of polarid.dask.material_map against Dask workers and chunk size.

A synthetic capture set held in memory: six plates of known (n, k) (polarid.simulate,
4 polarizer angles, T source positions) tiled to --size x --size pixels, mapped at bin 1
with a model of the six materials. For every chunk size (rows = columns, --chunks) the
map is computed on

  * a dask.distributed LocalCluster of 1 and of 2 worker processes (threads per worker:
    --threads; the frame blocks are made on the workers and kept there before the clock
    starts, as a reader of files on the workers would),
  * the local threaded scheduler (one process, for reference),

and compared with polarid.map-style work in one call (one block = the whole frame,
threaded scheduler). Each figure is the best of --repeats runs, in Mpixel/s of map
(pixels fitted and classified per second, T DoLP values each). The first run of each
configuration warms the workers (imports, plan caches) and is not counted. Prints a
table and one JSON line. Run with the interpreter that has polarid and dask[distributed]
(.venv-test after scripts/test_python.sh):

    .venv-test/bin/python scripts/bench/dask_map.py [--size 1024] [--chunks 128,256,512]
"""
import argparse
import json
import os
import platform
import tempfile
import time

import numpy as np

MATERIALS = {  # (n, k) near 650 nm
    "aluminium": (1.49, 7.82),
    "gold": (0.17, 3.48),
    "copper": (0.24, 3.42),
    "steel": (2.87, 3.35),
    "glass": (1.51, 0.0),
    "plastic": (1.59, 0.0),
}


def capture_set(size, t, seed=1):
    import polarid

    plates = [(n, k, 0.15) for n, k in MATERIALS.values()]
    sim = polarid.simulate(plates, np.linspace(20.0, 75.0, t), theta_r_deg=50.0, tile=48, gap=8,
                           seed=seed)
    f = sim["frames"]  # (T, A, h, w)
    reps = (1, 1, -(-size // f.shape[2]), -(-size // f.shape[3]))
    frames = np.ascontiguousarray(np.tile(f, reps)[:, :, :size, :size])
    return frames, sim["angles_deg"], sim["beta_deg"]


def frames_block(size, t, rows, cols):
    """Rows and columns `rows`, `cols` (slices) of the capture set: made where the task
    runs (a worker), as a reader of files would, so the frames do not travel in the graph."""
    frames, _, _ = capture_set(size, t)
    return np.ascontiguousarray(frames[:, :, rows, cols])


def lazy_frames(size, t, chunk):
    """The capture set as a dask array of blocks made on the workers."""
    import dask
    import dask.array as da

    frames, _, _ = capture_set(min(size, 64), t)  # dtype only
    rows = []
    for r in range(0, size, chunk):
        row = []
        for c in range(0, size, chunk):
            h, w = min(chunk, size - r), min(chunk, size - c)
            d = dask.delayed(frames_block)(size, t, slice(r, r + h), slice(c, c + w))
            row.append(da.from_delayed(d, shape=(t, 4, h, w), dtype=frames.dtype))
        rows.append(row)
    return da.block(rows)


def model_dict():
    protos = [{"class": c, "n": n, "k": k, "covariance": None, "category": None,
               "source": {"file": "bench", "line": i + 1, "target": c}}
              for i, (c, (n, k)) in enumerate(MATERIALS.items())]
    return {"format": "polarid-model", "format_version": 1, "created_by": "bench", "prototypes": protos}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=1024, help="frame rows = columns")
    ap.add_argument("--t", type=int, default=8, help="captures (source positions)")
    ap.add_argument("--chunks", default="128,256,512")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--threads", type=int, default=1, help="threads per worker process")
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)

    import dask
    import dask.array as da
    from distributed import Client, LocalCluster, wait

    import polarid.dask as pdask

    frames, angles, beta = capture_set(a.size, a.t)
    model = model_dict()
    npix = a.size * a.size
    chunks = [int(c) for c in a.chunks.split(",")]
    load0 = os.getloadavg()[0]

    def run(x, scheduler):
        maps = pdask.material_map(x, angles, beta, model)
        arrays = [maps[k] for k in ("n", "k", "n_se", "k_se", "class", "reason")]
        t0 = time.perf_counter()
        out = dask.compute(*arrays, scheduler=scheduler)
        return time.perf_counter() - t0, out

    def best(x, scheduler):
        run(x, scheduler)  # warm-up
        return min(run(x, scheduler)[0] for _ in range(a.repeats))

    results = {}
    # One block: the whole frame in one call (threaded scheduler, all cores).
    whole = da.from_array(frames, chunks=frames.shape)
    dt = best(whole, "threads")
    results["one block, threads"] = round(npix / dt / 1e6, 3)
    _, ref = run(whole, "threads")
    for c in chunks:
        x = da.from_array(frames, chunks=(a.t, 4, c, c))
        dt = best(x, "threads")
        results[f"threads, chunk {c}"] = round(npix / dt / 1e6, 3)
    with tempfile.TemporaryDirectory() as tmp:
        for w in (int(v) for v in a.workers.split(",")):
            with LocalCluster(n_workers=w, threads_per_worker=a.threads, processes=True,
                              dashboard_address=None, local_directory=tmp) as cluster, \
                    Client(cluster) as client:
                for c in chunks:
                    # The frames are made and kept on the workers (as they would be when
                    # read there), before the clock starts.
                    x = lazy_frames(a.size, a.t, c).persist()
                    wait(x)
                    dt = best(x, client)
                    results[f"{w} worker(s), chunk {c}"] = round(npix / dt / 1e6, 3)
                    _, out = run(x, client)
                    for r, o in zip(ref, out):
                        np.testing.assert_array_equal(r, o)  # same map whatever the chunks
                    del x
    width = max(map(len, results))
    print(f"{'configuration':<{width}}  Mpixel/s  ({a.size}x{a.size}, T={a.t}, bin 1)")
    for k, v in results.items():
        print(f"{k:<{width}}  {v:8.3f}")
    print(json.dumps({
        "bench": "polarid.dask.material_map throughput",
        "size": a.size, "T": a.t, "threads_per_worker": a.threads,
        "mpix_per_s": results,
        "env": {"python": platform.python_version(), "cpus": os.cpu_count(),
                "dask": dask.__version__, "loadavg_1min_start": round(load0, 2),
                "loadavg_1min_end": round(os.getloadavg()[0], 2)},
    }))


if __name__ == "__main__":
    main()
