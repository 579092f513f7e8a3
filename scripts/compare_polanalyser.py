#!/usr/bin/env python3
"""Compare polarid's S0 / DoLP / AoLP with polanalyser 3.0.0 on the real DoFP frames.

For every raw frame in data/real-dofp/ (Sony IMX250MZR, pattern 90,45,135,0)
this runs `polarid stokes --dofp RAW -o TMP` (bilinear demosaicing, OpenCV-exact) and
polanalyser's `demosaicing(raw, COLOR_PolarMono)` + `calcStokes` + `cvtStokesToDoLP` /
`cvtStokesToAoLP`, then prints the maximum and mean absolute differences and checks them
against tolerances. It ends with a line `N passed, N failed` and exits 1 on a failure.

Convention differences (documented, converted before comparing):
  * AoLP: polanalyser returns radians in [0, pi); polarid writes degrees in [0, 180)
    (docs/CONVENTIONS.md). Same sign convention (atan2(S2, S1) / 2), so polarid's value
    is compared with polanalyser's * 180/pi, as an angle modulo 180 degrees.
  * S0: both are (I0 + I45 + I90 + I135) / 2 in raw DN (polanalyser's calcStokes with
    the polarizer Mueller rows (1, cos 2a, sin 2a) / 2), so no rescaling is needed.
  * DoLP / AoLP of rejected pixels: polarid writes NaN where a raw value of the pixel's
    3x3 neighbourhood is saturated (>= 255 for 8-bit frames) or S0 <= 0; polanalyser
    computes them anyway. Those pixels are counted and left out of the DoLP/AoLP
    comparison (S0 is compared everywhere).
  * AoLP where S1 = S2 = 0 exactly (common in dark 8-bit regions) is undefined: polarid
    writes 0, polanalyser an arbitrary angle from the ~1e-14 rounding residues of its
    float64 pseudo-inverse. Those pixels are counted and left out of the AoLP comparison.
  * Precision: polarid computes in float32, polanalyser in float64.

The environment comes from scripts/setup_bench_env.sh (.venv-bench); this script installs
nothing. Run it as `python3 scripts/compare_polanalyser.py` (it re-runs itself with
.venv-bench/bin/python when polanalyser is not importable) after `cargo build --release`.
"""
import argparse
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENV_PY = os.path.join(ROOT, ".venv-bench", "bin", "python")


def _ensure_env():
    try:
        import cv2  # noqa: F401
        import numpy  # noqa: F401
        import polanalyser  # noqa: F401
    except ImportError:
        venv = os.path.dirname(os.path.dirname(VENV_PY))
        if os.path.exists(VENV_PY) and os.path.realpath(sys.prefix) != os.path.realpath(venv):
            os.execv(VENV_PY, [VENV_PY] + sys.argv)
        sys.stderr.write(
            "compare_polanalyser.py: polanalyser/opencv/numpy not found; run scripts/setup_bench_env.sh first\n"
        )
        sys.exit(2)


def read_tif(path):
    import cv2

    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise RuntimeError(f"cannot read {path}")
    return img


def compare(raw_path, polarid, tol):
    import cv2
    import numpy as np
    import polanalyser as pa

    raw = cv2.imread(raw_path, cv2.IMREAD_UNCHANGED)
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "out")
        subprocess.run([polarid, "--quiet", "stokes", "--dofp", raw_path, "-o", out], check=True)
        s0 = read_tif(os.path.join(out, "s0.tif")).astype(np.float64)
        s1 = read_tif(os.path.join(out, "s1.tif")).astype(np.float64)
        s2 = read_tif(os.path.join(out, "s2.tif")).astype(np.float64)
        dolp = read_tif(os.path.join(out, "dolp.tif")).astype(np.float64)
        aolp = read_tif(os.path.join(out, "aolp.tif")).astype(np.float64)

    imgs = pa.demosaicing(raw, pa.COLOR_PolarMono)
    stokes = pa.calcStokes(np.array(imgs), np.deg2rad([0, 45, 90, 135]))
    p_s0 = pa.cvtStokesToIntensity(stokes)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_dolp = pa.cvtStokesToDoLP(stokes)
    p_aolp = np.rad2deg(pa.cvtStokesToAoLP(stokes))

    ok = np.isfinite(dolp) & np.isfinite(p_dolp)
    masked = int((~np.isfinite(dolp)).sum())
    d_s0 = np.abs(s0 - p_s0)
    rel_s0 = d_s0 / np.maximum(np.abs(p_s0), 1.0)
    d_s1 = np.abs(s1 - stokes[..., 1])
    d_s2 = np.abs(s2 - stokes[..., 2])
    d_dolp = np.abs(dolp - np.clip(p_dolp, 0, 1))[ok]
    # AoLP is undefined where S1 = S2 = 0 exactly (polarid writes 0; polanalyser's value
    # there comes from ~1e-14 rounding residues of its float64 pseudo-inverse).
    undefined = ok & (s1 == 0) & (s2 == 0)
    defined = ok & ~undefined
    da = np.abs(aolp - p_aolp)[defined]
    d_aolp = np.minimum(da, 180.0 - da)
    pol = ok & (p_dolp > 0.01)
    da_pol = np.abs(aolp - p_aolp)[pol]
    d_aolp_pol = np.minimum(da_pol, 180.0 - da_pol)
    name = os.path.basename(raw_path)
    h, w = raw.shape
    print(f"== {name}: {w}x{h}, {raw.dtype}, pixels compared for DoLP/AoLP {int(ok.sum())}, "
          f"rejected by polarid (saturated neighbourhood or S0<=0) {masked}")
    print(f"   S0    max |diff| {d_s0.max():.3e} DN   mean {d_s0.mean():.3e} DN   max rel {rel_s0.max():.3e}")
    print(f"   S1,S2 max |diff| {max(d_s1.max(), d_s2.max()):.3e} DN")
    print(f"   DoLP  max |diff| {d_dolp.max():.3e}      mean {d_dolp.mean():.3e}")
    print(f"   AoLP  max |diff| {d_aolp.max():.3e} deg  mean {d_aolp.mean():.3e} deg (all pixels with S1, S2 not both 0; {int(undefined.sum())} with S1 = S2 = 0 left out)")
    print(f"   AoLP  max |diff| {d_aolp_pol.max():.3e} deg  mean {d_aolp_pol.mean():.3e} deg (DoLP > 0.01)")
    checks = [
        (f"{name} S0 max rel diff <= {tol['s0']}", rel_s0.max() <= tol["s0"]),
        (f"{name} DoLP max abs diff <= {tol['dolp']}", d_dolp.max() <= tol["dolp"]),
        (f"{name} AoLP max abs diff <= {tol['aolp']} deg", d_aolp.max() <= tol["aolp"]),
        (f"{name} S1, S2 max abs diff <= 1e-6 DN", max(d_s1.max(), d_s2.max()) <= 1e-6),
    ]
    return checks


def main(argv=None):
    _ensure_env()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--polarid", default=os.path.join(ROOT, "target", "release", "polarid"),
                    help="polarid binary (default target/release/polarid; build it with cargo build --release)")
    ap.add_argument("--data", default=os.path.join(ROOT, "data", "real-dofp"))
    args = ap.parse_args(argv)
    if not os.path.exists(args.polarid):
        sys.stderr.write(f"compare_polanalyser.py: {args.polarid} not found; run cargo build --release\n")
        return 2
    frames = sorted(f for f in os.listdir(args.data) if f.endswith(".png"))
    if not frames:
        sys.stderr.write(f"compare_polanalyser.py: no PNG frames in {args.data}\n")
        return 2
    # float32 vs float64: S0 relative 1e-6; DoLP 1e-5; AoLP 1e-3 degree (polarid's atan2
    # polynomial is accurate to 4e-8 rad; float32 rounding of S1/S2 is exact for 8-bit data).
    tol = {"s0": 1e-6, "dolp": 1e-5, "aolp": 1e-3}
    passed = failed = 0
    for f in frames:
        for label, good in compare(os.path.join(args.data, f), args.polarid, tol):
            print(("   ok   " if good else "   FAIL ") + label)
            passed += bool(good)
            failed += not good
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
