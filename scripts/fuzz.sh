#!/usr/bin/env bash
# Fuzz each cargo-fuzz target of fuzz/ for a bounded time.
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]     (default: 60 s each, every target)
#
# Works with the stable toolchain: cargo-fuzz needs nightly
# only for sanitizers (`-Zsanitizer`), so the targets are built with `--sanitizer none`;
# libFuzzer's coverage instrumentation (`-Cpasses=sancov-module`, `-Cllvm-args=...`) is
# stable. polarid's readers are safe Rust, so bounds and overflow checks
# (`--debug-assertions`) stand in for AddressSanitizer. Install cargo-fuzz with
# `cargo install cargo-fuzz`. See fuzz/README.md.
#
# Targets run one after the other in one process each (the machine has 2 cores); set
# FUZZ_PARALLEL=2 to run two at a time. Each run starts from fuzz/seeds/TARGET and keeps
# its corpus in fuzz/corpus/TARGET (not committed); a crash is saved in
# fuzz/artifacts/TARGET and the script exits 1. A summary line per target gives runs,
# coverage (cov, ft) and corpus size.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
secs=${1:-60}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(manifest csv_tables image_frame dofp scene model_json library_csv rii_yaml fits_classification)
fi
command -v cargo-fuzz >/dev/null || { echo "fuzz.sh: cargo-fuzz not installed (cargo install cargo-fuzz)" >&2; exit 1; }
flags=(--sanitizer none -O --debug-assertions)
cargo fuzz build "${flags[@]}"
mkdir -p logs
dict_for() {
    case $1 in
        manifest) echo "-dict=dict/manifest.dict" ;;
        csv_tables) echo "-dict=dict/csv.dict" ;;
        scene) echo "-dict=dict/scene.dict" ;;
        model_json) echo "-dict=dict/model.dict" ;;
        library_csv) echo "-dict=dict/library.dict" ;;
        rii_yaml) echo "-dict=dict/yaml.dict" ;;
        fits_classification) echo "-dict=dict/fits.dict" ;;
        *) echo "" ;;
    esac
}
run_one() {
    local t=$1
    mkdir -p "corpus/$t" "artifacts/$t" "seeds/$t"
    # -rss_limit_mb and -timeout turn out-of-memory and hangs into findings.
    # shellcheck disable=SC2046
    cargo fuzz run "${flags[@]}" "$t" "corpus/$t" "seeds/$t" -- \
        -max_total_time="$secs" -rss_limit_mb=2048 -timeout=10 \
        -max_len=65536 -print_final_stats=1 $(dict_for "$t") \
        >"logs/$t.log" 2>&1
}
status=0
parallel=${FUZZ_PARALLEL:-1}
pids=()
names=()
for t in "${targets[@]}"; do
    run_one "$t" &
    pids+=($!)
    names+=("$t")
    if [ ${#pids[@]} -ge "$parallel" ]; then
        wait "${pids[0]}" || { echo "fuzz.sh: ${names[0]} FAILED (see fuzz/logs/${names[0]}.log)"; status=1; }
        pids=("${pids[@]:1}")
        names=("${names[@]:1}")
    fi
done
for i in "${!pids[@]}"; do
    wait "${pids[$i]}" || { echo "fuzz.sh: ${names[$i]} FAILED (see fuzz/logs/${names[$i]}.log)"; status=1; }
done
for t in "${targets[@]}"; do
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "logs/$t.log" | grep -o '[0-9]*$' || echo '?')
    last=$(grep -E '^#[0-9]+' "logs/$t.log" | tail -1 || true)
    cov=$(echo "$last" | grep -o 'cov: [0-9]*' || true)
    ft=$(echo "$last" | grep -o 'ft: [0-9]*' || true)
    corp=$(echo "$last" | grep -o 'corp: [0-9]*/[0-9a-zA-Z]*' || true)
    crash=$(ls "artifacts/$t" 2>/dev/null | wc -l)
    echo "$t: ${secs}s, runs ${runs}, ${cov}, ${ft}, ${corp}, artifacts ${crash}"
done
exit $status
