#!/usr/bin/env bash
# Create the Python environment used by the side-by-side comparisons and benchmarks
# (scripts/bench/baselines.py, scripts/compare_polanalyser.py): a virtualenv
# `.venv-bench` at the repository root with the pinned packages of
# scripts/bench/requirements.txt (numpy, scipy, polanalyser 3.0.0, opencv, matplotlib).
#
# Usage: scripts/setup_bench_env.sh [VENV_DIR]     (default: .venv-bench)
# Re-running it is cheap: pip skips what is already installed.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${1:-.venv-bench}"
req="scripts/bench/requirements.txt"
if [ ! -f "$req" ]; then
    echo "setup_bench_env.sh: $req not found (an incomplete checkout?)" >&2
    exit 2
fi
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --upgrade pip
"$venv/bin/python" -m pip install --quiet -r "$req"
"$venv/bin/python" -c 'import polanalyser, cv2, numpy; print("bench env ok: polanalyser", getattr(polanalyser, "__version__", "?"), "opencv", cv2.__version__, "numpy", numpy.__version__)'
