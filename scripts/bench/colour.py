#!/usr/bin/env python3
"""Colour polarization speed (issue 17): raw colour mosaic -> per-band S0, S1, S2, DoLP
and AoLP, polarid against polanalyser on the same frame, in one run.

The frame: 2048 x 2448 uint16, Sony IMX250MYR layout (polarizers 90, 45, 135, 0 under
RGGB blocks of a 4x4 period), a synthetic scene per band (seeded). polanalyser:
demosaicing(raw, COLOR_PolarRGB) (4 angle images of 3 colours), calcStokes on them
(S0, S1, S2 per colour), cvtStokesToDoLP, cvtStokesToAoLP. polarid: the fused kernel
(polarid_core::mosaic::colour_polar, bilinear per lattice, full resolution) into
caller-owned buffers, run by the Rust example `colour_throughput` on the same frame
(written to a temporary file); figures are the best of each side's runs, taken
alternately (polanalyser, polarid, polanalyser, ...) so that load on a shared machine
hits both alike. Prints one JSON line.

Needs numpy, polanalyser 3.0.0 and the built example
(cargo build --release -p polarid-core --example colour_throughput).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np


def colour_mosaic(h, w, seed):
    """An IMX250MYR-style raw frame: per band a smooth scene, partially polarized."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    raw = np.empty((h, w), np.uint16)
    angles = {0: 90.0, 1: 45.0, 2: 135.0, 3: 0.0}  # cell (row*2+col) -> polarizer
    for by, bx, band in ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2)):
        s0 = 1500 + 800 * np.sin(xx / (150 + 40 * band)) * np.cos(yy / 170)
        dolp = 0.1 + 0.1 * band + 0.05 * np.sin((xx + yy) / 300)
        aolp = np.deg2rad(30 + 20 * band + 10 * np.cos(yy / 400))
        for cell, ang in angles.items():
            cy, cx = 2 * by + cell // 2, 2 * bx + cell % 2
            t = np.deg2rad(ang)
            v = 0.5 * s0 * (1 + dolp * np.cos(2 * (t - aolp)))
            sl = (slice(cy, None, 4), slice(cx, None, 4))
            raw[sl] = np.clip(v[sl] + rng.normal(0, 8, v[sl].shape), 0, 4095).astype(np.uint16)
    return raw


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--height", type=int, default=2048)
    ap.add_argument("--width", type=int, default=2448)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--exe", default=os.path.join("target", "release", "examples", "colour_throughput"))
    a = ap.parse_args(argv)
    import polanalyser as pa

    h, w = a.height, a.width
    mpix = h * w / 1e6
    raw = colour_mosaic(h, w, a.seed)
    angles = np.deg2rad([0.0, 45.0, 90.0, 135.0])

    def pa_full():
        imgs = pa.demosaicing(raw, pa.COLOR_PolarRGB)
        stokes = pa.calcStokes(imgs, angles)
        return pa.cvtStokesToDoLP(stokes), pa.cvtStokesToAoLP(stokes)

    with tempfile.TemporaryDirectory() as td:
        path = os.path.join(td, "raw.u16")
        raw.astype("<u2").tofile(path)
        pa_full()  # warm-up
        pa_t, ours = [], []
        for _ in range(a.rounds):
            t0 = time.perf_counter()
            pa_full()
            pa_t.append(time.perf_counter() - t0)
            out = subprocess.run([a.exe, "--raw", path, "--width", str(w), "--height", str(h),
                                  "--repeats", "3"], capture_output=True, text=True, check=True)
            ours.append(json.loads(out.stdout.strip().splitlines()[-1]))
    bil = min(r["colour_bilinear"]["best_s"] for r in ours)
    sp = min(r["colour_superpixel"]["best_s"] for r in ours)
    res = {
        "bench": "colour",
        "width": w,
        "height": h,
        "pa_demosaic_stokes_dolp_aolp": {"best_s": round(min(pa_t), 4), "median_s": round(statistics.median(pa_t), 4),
                                         "mpix_per_s": round(mpix / min(pa_t), 2)},
        "polarid_colour_bilinear": {"best_s": bil, "mpix_per_s": round(mpix / bil, 1)},
        "polarid_colour_superpixel": {"best_s": sp, "mpix_per_s": round(mpix / sp, 1)},
        "ratio_bilinear_vs_polanalyser": round(min(pa_t) / bil, 1),
        "loadavg_1min": os.getloadavg()[0],
    }
    print(json.dumps(res))


if __name__ == "__main__":
    sys.exit(main())
