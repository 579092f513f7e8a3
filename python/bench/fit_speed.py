"""Speed of polarid.fit_nk against the Rust batch fit on the same data (not a test).

Usage (from the repository root, with polarid installed):

    cargo build --release -p polarid-python --example fit_speed
    python python/bench/fit_speed.py [--reps 15]

For each stack size P x 10 (P = 1000, 10 000, 100 000) it writes the DoLP values to a
temporary file, times ``polarid_core::fit::fit_batch`` over them in Rust (plan built once,
not timed) and ``polarid.fit_nk(dolp, beta_deg)`` from Python (median of the repetitions,
the plan cache warm), and prints the time per pixel of each and their ratio
(Python / Rust, of the medians and of the fastest runs, which are the least disturbed
by other load on the machine; the acceptance bound of issue 8 is 1.10). The checksum column checks that
both fitted the same values.
"""

import argparse
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import polarid

ROOT = Path(__file__).resolve().parents[2]
BETA = np.linspace(25.0, 70.0, 10)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10_000, 100_000])
    args = ap.parse_args()
    exe = ROOT / "target" / "release" / "examples" / "fit_speed"
    rng = np.random.default_rng(0)
    print("time per pixel, ns: median and fastest of the repetitions")
    print(f"{'pixels':>8} {'rust med':>8} {'rust min':>8} {'py med':>8} {'py min':>8} "
          f"{'ratio med':>10} {'ratio min':>9}  checksum match")
    for p in args.sizes:
        n = rng.uniform(0.3, 3.0, p)
        k = rng.uniform(0.0, 8.0, p)
        y = polarid.dolp_model(n[:, None], k[:, None], BETA[None, :])
        y = np.ascontiguousarray(np.clip(y + rng.normal(0, 0.005, y.shape), 0, 1))
        rust_med, rust_min, py_times = [], [], []
        with tempfile.TemporaryDirectory() as d:
            data = Path(d) / "y.f64"
            y.astype("<f8").tofile(data)
            BETA.astype("<f8").tofile(f"{data}.beta")
            polarid.fit_nk(y, BETA)  # warm the plan cache and the thread pool
            # Rounds alternate the two sides so that other load on the machine hits both.
            for _ in range(args.rounds):
                out = subprocess.run([str(exe), str(data), "10", str(args.reps)], check=True,
                                     capture_output=True, text=True).stdout.split()
                rust_med.append(float(out[0]))
                rust_min.append(float(out[1]))
                rust_sum = float(out[2])
                for _ in range(args.reps):
                    t0 = time.perf_counter()
                    r = polarid.fit_nk(y, BETA)
                    py_times.append(time.perf_counter() - t0)
        rust_med = statistics.median(rust_med)
        rust_min = min(rust_min)
        py_med = statistics.median(py_times) * 1e9 / p
        py_min = min(py_times) * 1e9 / p
        v = r["n"] + r["k"]
        py_sum = float(np.sum(v[np.isfinite(v)]))
        same = abs(py_sum - rust_sum) <= 1e-9 * abs(rust_sum)
        print(f"{p:>8} {rust_med:>8.0f} {rust_min:>8.0f} {py_med:>8.0f} {py_min:>8.0f} "
              f"{py_med / rust_med:>10.3f} {py_min / rust_min:>9.3f}  {same}")


if __name__ == "__main__":
    main()
