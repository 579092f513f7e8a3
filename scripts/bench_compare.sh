#!/usr/bin/env bash
# Side-by-side speed comparison of polarid with the Python baselines of
# scripts/bench/baselines.py, in ONE run on the same machine (issue 7):
#   - Stokes + DoLP + AoLP of a 2048x2448 4-angle uint16 stack: polarid
#     (examples/stokes_throughput.rs) vs polanalyser and numpy     target >= 20x polanalyser
#   - per-pixel (n, k) fits, T = 10, noise sd 0.005, 10^6 pixels: polarid.fit_nk from
#     Python (scripts/bench/fit_nk.py, one process) vs the numpy batched LM at its best
#     chunk size (10^5 or 10^6 pixels per call), and vs `fit-loop` (scipy per pixel);
#     the Rust fit_batch (examples/fit_throughput.rs) for reference
#                                                   targets >= 50x numpy, >= 2000x fit-loop,
#                                                   with at least the same global-optimum rate
#   - DoFP raw -> DoLP + AoLP and bilinear demosaicing through the Python API
#     (scripts/bench/dofp.py) vs polanalyser / OpenCV  targets >= 20x, >= 2x
# The Python figures run in the interpreter of .venv-test (scripts/test_python.sh
# installs polarid there; or --polarid-python / $POLARID_PYTHON).
# Prints every figure and each ratio polarid/baseline against its target.
#
# Usage: scripts/bench_compare.sh [--quick]   (--quick: fewer pixels/repeats)
# Environment: BENCH_VENV (default .venv-bench, created by scripts/setup_bench_env.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${BENCH_VENV:-.venv-bench}"
scripts/setup_bench_env.sh "$venv" >&2
cargo build --release --locked -q -p polarid-core --examples >&2
exec "$venv/bin/python" scripts/bench_compare.py --baselines scripts/bench/baselines.py \
    --target-dir target/release/examples "$@"
