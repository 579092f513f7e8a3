#!/usr/bin/env python3
"""DoFP speed, polarid against polanalyser / OpenCV, side by side in one process.

The raw frame is that of `baselines.py stokes`: a 2048 x 2448 uint16 IMX250MZR-style
mosaic (pattern 90, 45, 135, 0) cut from the same synthetic 4-angle stack (seed 0).
Every case runs `--per-round` times back to back in each round, the rounds interleave
the cases (so that a burst of load on a shared machine hits all of them alike, and no
case is only ever timed right after another one's large allocations), and each figure
is the best (and the median) of all its runs. Prints one JSON line.

Cases
  pa_demosaic_stokes_dolp_aolp   polanalyser: demosaicing(raw, COLOR_PolarMono),
                                 calcStokes, cvtStokesToDoLP, cvtStokesToAoLP
  polarid_dofp_dolp_aolp         polarid.dofp_dolp_aolp(raw): fused, new output arrays
  polarid_dofp_dolp_aolp_out     the same into reused arrays (out=(dolp, aolp))
  polarid_demosaic_then_dolp_aolp  polarid.dolp_aolp(polarid.demosaic(raw)) (unfused)
  cv2_demosaic                   OpenCV as polanalyser runs it: cvtColor(raw,
                                 COLOR_BayerBG2BGR) and (COLOR_BayerGR2BGR), new outputs
  cv2_demosaic_dst               the same into reused dst= arrays (OpenCV's best)
  pa_demosaicing                 polanalyser.demosaicing(raw, COLOR_PolarMono) (+ split)
  polarid_demosaic_f32           polarid.demosaic(raw, output="angles"): 4 float32 images
  polarid_demosaic_u16           ... dtype=numpy.uint16: OpenCV's values, new array
  polarid_demosaic_u16_out       ... into a reused uint16 array (out=)

Ratios (polarid / baseline throughput): fused DoLP+AoLP vs polanalyser (new arrays on
both sides, and polarid into reused arrays), demosaicing vs OpenCV (each at its best
settings: the faster of its variants in the run; and both with new outputs).

Needs numpy, polanalyser 3.0.0, OpenCV and polarid in the running interpreter.
"""
import argparse
import json
import os
import platform
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from baselines import ANGLES_DEG, synthetic_stack  # noqa: E402


def raw_mosaic(h, w, seed):
    """The DoFP raw frame of `baselines.py stokes` (pattern 90, 45, 135, 0)."""
    stack = synthetic_stack(h, w, np.random.default_rng(seed))
    raw = np.empty((h, w), dtype=np.uint16)
    raw[0::2, 0::2] = stack[2, 0::2, 0::2]  # 90
    raw[0::2, 1::2] = stack[1, 0::2, 1::2]  # 45
    raw[1::2, 0::2] = stack[3, 1::2, 0::2]  # 135
    raw[1::2, 1::2] = stack[0, 1::2, 1::2]  # 0
    return raw


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--height", type=int, default=2048)
    ap.add_argument("--width", type=int, default=2448)
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds")
    ap.add_argument("--per-round", type=int, default=2, help="back-to-back runs of each case per round")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)

    import cv2
    import polanalyser as pa

    import polarid

    h, w = a.height, a.width
    mpix = h * w / 1e6
    raw = raw_mosaic(h, w, a.seed)
    angles = np.deg2rad(ANGLES_DEG)

    def pa_full():
        imgs = pa.demosaicing(raw, pa.COLOR_PolarMono)
        stokes = pa.calcStokes(imgs, angles)
        return pa.cvtStokesToDoLP(stokes), pa.cvtStokesToAoLP(stokes)

    pol_out = (np.empty((h, w), np.float32), np.empty((h, w), np.float32))
    bg = np.empty((h, w, 3), np.uint16)
    gr = np.empty((h, w, 3), np.uint16)
    u16_out = np.empty((4, h, w), np.uint16)

    def cv2_dst():
        cv2.cvtColor(raw, cv2.COLOR_BayerBG2BGR, dst=bg)
        cv2.cvtColor(raw, cv2.COLOR_BayerGR2BGR, dst=gr)

    cases = {
        "pa_demosaic_stokes_dolp_aolp": pa_full,
        "polarid_dofp_dolp_aolp": lambda: polarid.dofp_dolp_aolp(raw),
        "polarid_dofp_dolp_aolp_out": lambda: polarid.dofp_dolp_aolp(raw, out=pol_out),
        "polarid_demosaic_then_dolp_aolp": lambda: polarid.dolp_aolp(polarid.demosaic(raw)),
        "cv2_demosaic": lambda: (cv2.cvtColor(raw, cv2.COLOR_BayerBG2BGR), cv2.cvtColor(raw, cv2.COLOR_BayerGR2BGR)),
        "cv2_demosaic_dst": cv2_dst,
        "pa_demosaicing": lambda: pa.demosaicing(raw, pa.COLOR_PolarMono),
        "polarid_demosaic_f32": lambda: polarid.demosaic(raw, output="angles"),
        "polarid_demosaic_u16": lambda: polarid.demosaic(raw, output="angles", dtype=np.uint16),
        "polarid_demosaic_u16_out": lambda: polarid.demosaic(raw, output="angles", out=u16_out),
    }
    for fn in cases.values():  # warm-up (imports, thread pools, plan caches)
        fn()
    times = {k: [] for k in cases}
    for _ in range(a.rounds):
        for k, fn in cases.items():
            for _ in range(a.per_round):
                t0 = time.perf_counter()
                fn()
                times[k].append(time.perf_counter() - t0)
    res = {
        k: {
            "best_s": round(min(v), 5),
            "median_s": round(statistics.median(v), 5),
            "mpix_per_s": round(mpix / min(v), 1),
        }
        for k, v in times.items()
    }

    def ratio(ours, base):
        return round(min(times[base]) / min(times[ours]), 2)

    # Each side at its best settings: the faster of its variants in this run.
    opencv_best = min(min(times["cv2_demosaic"]), min(times["cv2_demosaic_dst"]))
    polarid_best = min(min(times[k]) for k in ("polarid_demosaic_u16_out", "polarid_demosaic_u16", "polarid_demosaic_f32"))

    ratios = {
        "dofp_dolp_aolp_vs_polanalyser": ratio("polarid_dofp_dolp_aolp", "pa_demosaic_stokes_dolp_aolp"),
        "dofp_dolp_aolp_out_vs_polanalyser": ratio("polarid_dofp_dolp_aolp_out", "pa_demosaic_stokes_dolp_aolp"),
        "unfused_vs_polanalyser": ratio("polarid_demosaic_then_dolp_aolp", "pa_demosaic_stokes_dolp_aolp"),
        "demosaic_best_vs_opencv_best": round(opencv_best / polarid_best, 2),
        "demosaic_u16_vs_opencv_new_arrays": ratio("polarid_demosaic_u16", "cv2_demosaic"),
        "demosaic_f32_vs_opencv_new_arrays": ratio("polarid_demosaic_f32", "cv2_demosaic"),
        "demosaic_f32_vs_polanalyser_demosaicing": ratio("polarid_demosaic_f32", "pa_demosaicing"),
    }

    # Cross-checks: the same numbers as polanalyser.
    imgs = pa.demosaicing(raw, pa.COLOR_PolarMono)
    ours = polarid.demosaic(raw, output="angles", dtype=np.uint16)
    same_demosaic = all(np.array_equal(ours[k], imgs[k]) for k in range(4))
    d_pa, a_pa = pa_full()
    d, aolp = polarid.dofp_dolp_aolp(raw)
    ok = np.isfinite(d) & (d_pa <= 1.0)
    sel = ok & (d > 0.01)
    dang = np.abs(np.angle(np.exp(2j * (np.radians(aolp[sel]) - a_pa[sel])))) / 2
    out = {
        "bench": "dofp",
        "height": h,
        "width": w,
        "pattern_deg": [90, 45, 135, 0],
        "rounds": a.rounds,
        "per_round": a.per_round,
        "results": res,
        "ratios": ratios,
        "check_demosaic_u16_equals_polanalyser": bool(same_demosaic),
        "check_max_abs_dolp_diff": float(np.max(np.abs(d[ok] - d_pa[ok]))),
        "check_max_abs_aolp_diff_rad_where_dolp_gt_0.01": float(np.max(dang)),
        "env": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "opencv": cv2.__version__,
            "opencv_threads": cv2.getNumThreads(),
            "polarid": getattr(polarid, "__version__", "?"),
            "polarid_path": os.path.dirname(polarid.__file__),
            "cpus": os.cpu_count(),
            "machine": platform.machine(),
            "loadavg_1min": os.getloadavg()[0],
        },
    }
    print(json.dumps(out))


if __name__ == "__main__":
    sys.exit(main())
