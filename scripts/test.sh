#!/usr/bin/env bash
# The one command that runs every test of polarid (README, CI). It must finish within 8
# minutes on 2 cores from a clean clone, build included:
#   1. the repository reads nothing beside it (scripts/check_self_contained.sh), no
#      crate has a module import cycle (scripts/check_cycles.py), and no function is
#      over 120 lines outside the SIMD kernels (scripts/check_long_functions.py);
#   2. cargo fmt --check, then cargo clippy on every target (examples and the benchmarks
#      of benches/ included) with warnings as errors (the lints: [workspace.lints] of
#      Cargo.toml);
#      in the release profile, so that the build scripts and procedural macros it
#      compiles are the test build's;
#   3. cargo test (release: the Monte-Carlo acceptance tests run 10^5 fits) of the
#      workspace's binaries and integration tests (one test binary per crate,
#      crates/*/tests/it/), the libraries' unit tests (polarid-core's built alone at
#      opt-level 1, see below) and doc tests (examples and benches: checked by clippy,
#      not built);
#   4. Python (scripts/test_python.sh): builds the package into the venv .venv-test and
#      runs pytest; its package downloads run in the background while Rust compiles, the
#      extension's build reuses the crates compiled in step 3 (same profile, target
#      directory and features) and the tests use the `polarid` binary built there.
# Statistical studies run a quick number of seeds; POLARID_FULL=1 runs them at full size
# (.ci/run does, after this script). Tests on the independent renders run when
# POLARID_RENDERS names their directory and say so on the terminal when skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
# The tests need no debug information: without the release profile's line tables the
# test build links faster. Every cargo and maturin call below (and .ci/run's) sees the
# same setting, so that they share one build.
export CARGO_PROFILE_RELEASE_DEBUG="${CARGO_PROFILE_RELEASE_DEBUG:-false}"
root=$(pwd)
start=$SECONDS
step() { echo "== $1 [$((SECONDS - start)) s]"; }

step "self-contained (no reads outside the repository)"
./scripts/check_self_contained.sh
step "no module import cycles"
python3 scripts/check_cycles.py
step "no function over 120 lines"
python3 scripts/check_long_functions.py
step "cargo fmt --check"
cargo fmt --all -- --check

# Python packages (pip: downloads and unpacking, little CPU) while Rust compiles.
prep_log=$(mktemp)
./scripts/test_python.sh --prepare >"$prep_log" 2>&1 &
prep=$!
trap 'kill $prep 2>/dev/null || true; rm -f "$prep_log"' EXIT

step "cargo clippy (all targets, warnings are errors)"
cargo clippy --release --workspace --exclude polarid-python --all-targets --locked -- -D warnings

step "cargo test (release): binaries and integration tests"
cargo test --release --locked --bins --test '*'
# The libraries' unit tests: those of polarid-io and -pipeline (and the test kit's) against the
# libraries built above (polarid-cli, which has no library, is selected so that the
# dependencies keep the features of the step above and are not compiled again);
# polarid-core's alone, at opt-level 1 (its unit-test binary costs
# about 110 CPU-s to build there against about 660 at opt-level 3, and its tests run in a
# few seconds). polarid-core has no dependency on the other crates, even among its test
# dependencies, so that selecting it alone builds only its test binary at opt-level 1
# and leaves the libraries of the other steps as they are.
step "cargo test (release): the libraries' unit tests"
cargo test --release --locked --lib -p polarid-io -p polarid-pipeline -p polarid-testkit -p polarid-cli
step "cargo test (release, polarid-core at opt-level 1): polarid-core's unit tests"
cargo test --release --locked --lib -p polarid-core --config 'profile.release.package.polarid-core.opt-level=1'
step "cargo test (release): doc tests"
cargo test --release --locked --doc

step "Python: waiting for the package downloads"
if ! wait $prep; then
    cat "$prep_log" >&2
    echo "error: preparing the Python environment failed" >&2
    exit 1
fi
step "Python package (venv .venv-test, pytest)"
POLARID_CLI=${POLARID_CLI:-${CARGO_TARGET_DIR:-$root/target}/release/polarid} \
    ./scripts/test_python.sh
step "all tests passed"
