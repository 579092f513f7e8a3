#!/usr/bin/env bash
# Side-by-side speed comparison of polarid with the Python baselines of
# scripts/bench/baselines.py, in ONE run on the same machine (issue 7):
#   - Stokes + DoLP + AoLP of a 2048x2448 4-angle uint16 stack: polarid
#     (examples/stokes_throughput.rs) vs polanalyser and numpy     target >= 20x polanalyser
#   - per-pixel (n, k) fits, T = 10, noise sd 0.005: polarid
#     (examples/fit_throughput.rs, when present) vs `fit-vec` (numpy batched LM)
#     and `fit-loop` (scipy per pixel)              targets >= 50x fit-vec, >= 2000x fit-loop,
#                                                   with at least the same global-optimum rate
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
