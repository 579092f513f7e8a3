#!/usr/bin/env bash
# The one command that runs every test of polarid (README, CI).
# Rust: formatting check, the whole workspace's tests (release build: the Monte-Carlo
# acceptance tests run 10^5 fits). Python: builds the package into a venv and runs pytest.
# First of all: the repository must not read anything beside it (scripts/check_self_contained.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
echo "== self-contained (no reads outside the repository)"
./scripts/check_self_contained.sh
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo test (release)"
cargo test --release --locked
echo "== Python package (venv .venv-test, pytest)"
./scripts/test_python.sh
echo "== all tests passed"
