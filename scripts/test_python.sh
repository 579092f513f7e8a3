#!/usr/bin/env bash
# Python tests of polarid: build and install the package from this repository into the
# virtualenv .venv-test (created on first use, reused afterwards), with pytest and the
# pinned baseline environment of scripts/bench/requirements.txt (numpy, scipy,
# polanalyser, OpenCV, matplotlib: the comparison tests use them) and dask with its
# distributed scheduler (python/tests/test_dask.py runs a LocalCluster), then run
# `pytest python/tests -q`. The tests that compare with the command-line program use the
# release build of `polarid` (built here with `cargo build --release --locked -p
# polarid-cli`, or given as $POLARID_CLI).
#
# Needs only Rust (cargo) and Python >= 3.11 with pip. Environment:
#   PYTHON          interpreter that creates the venv (default: python3)
#   POLARID_VENV    the virtualenv (default: .venv-test at the repository root)
#   POLARID_CLI     a prebuilt polarid binary (default: build target/release/polarid)
# Extra arguments are passed to pytest. `--prepare` only creates the venv and installs the
# test requirements (scripts/test.sh runs it in the background while Rust compiles); the
# requirements are installed again only when their list changes (a stamp in the venv).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
venv=${POLARID_VENV:-$root/.venv-test}
python=${PYTHON:-python3}

if [[ ! -x "$venv/bin/python" ]] || ! "$venv/bin/python" -c 'import sys' 2>/dev/null; then
    "$python" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' || {
        echo "error: $python is $("$python" --version 2>&1); polarid needs Python >= 3.11 (set PYTHON=...)" >&2
        exit 1
    }
    echo "== creating virtualenv $venv"
    "$python" -m venv "$venv"
fi
pip=("$venv/bin/python" -m pip --disable-pip-version-check)

# maturin: python/pyproject.toml's build backend, installed here so that the package
# builds without an isolated build environment (--no-build-isolation below).
reqs=(pytest numpy "dask[array,distributed]==2026.8.0" "maturin>=1.16,<2"
      -r scripts/bench/requirements.txt)
stamp="$venv/.polarid-test-requirements"
want="${reqs[*]} $(cat scripts/bench/requirements.txt)"
if [[ ! -f "$stamp" ]] || [[ "$(cat "$stamp")" != "$want" ]]; then
    echo "== installing test requirements"
    "${pip[@]}" install -q "${reqs[@]}"
    printf '%s' "$want" >"$stamp"
fi
if [[ "${1:-}" == "--prepare" ]]; then
    exit 0
fi

echo "== building and installing polarid (maturin, release, --locked)"
# --force-reinstall: the version number does not change between builds.
# The venv's bin first on PATH: without build isolation, maturin's build hook runs the
# `maturin` executable installed in the venv.
# The build shares target/ and the release profile with `cargo test --release` (and the
# features of the shared dependencies, see python/Cargo.toml): after scripts/test.sh's
# test build it compiles only PyO3, numpy and the extension crate itself. Cargo's
# progress lines are shown; a warning says when polarid-core was compiled again.
build_log=$(mktemp)
if ! PATH="$venv/bin:$PATH" "${pip[@]}" install -v --force-reinstall --no-deps --no-build-isolation \
        ./python >"$build_log" 2>&1; then
    cat "$build_log" >&2
    echo "error: building the Python package failed" >&2
    exit 1
fi
grep -E '^ *(Compiling|Finished) ' "$build_log" | sed 's/^ */    /' || true
if [[ -n "${POLARID_CLI:-}" ]] && grep -qE '^ *Compiling polarid-core ' "$build_log"; then
    echo "warning: the extension's build compiled polarid-core again instead of reusing the" \
         "test build's (the features of a shared dependency differ: python/Cargo.toml)" >&2
fi
rm -f "$build_log"

if [[ -z "${POLARID_CLI:-}" ]]; then
    echo "== building the polarid CLI (cargo build --release --locked -p polarid-cli)"
    cargo build --release --locked -q -p polarid-cli
    POLARID_CLI="${CARGO_TARGET_DIR:-$root/target}/release/polarid"
fi

echo "== pytest python/tests"
export POLARID_CLI
exec "$venv/bin/python" -m pytest python/tests -q "$@"
