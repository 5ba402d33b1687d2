#!/usr/bin/env bash
# relight's fuzzing campaign: every target (or those named) for SECONDS each, with libFuzzer
# through cargo-fuzz on the stable toolchain (no sanitizer: `--sanitizer none`; debug
# assertions on, so integer overflows are findings too).
#
#   fuzz/run.sh [SECONDS] [TARGET...]        default: 60 s per target, every target
#
# Each run starts from fuzz/seeds/<target> plus the corpus kept in fuzz/corpus/<target>
# (grown by earlier runs; not committed), with a 2 GiB limit on the process and on any one
# allocation (an input may not make relight allocate beyond what its real size justifies)
# and 10 s per input. Prints one markdown row per target (executions, coverage, findings)
# and exits 1 if any target found a crash, an abort, an allocation over the limit or a
# timeout; the inputs are in fuzz/artifacts/<target>/, to become regression tests.
# Needs `cargo install cargo-fuzz` (scripts/setup.sh does not: CI installs it in .ci/run).
set -euo pipefail
cd "$(dirname "$0")"
secs=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(obj ply gltf hdr exr scene bundle)
flags=(--sanitizer none -O --debug-assertions)
python3 make_seeds.py   # the binary seeds (meshes, HDR, EXR) are generated, not committed
cargo fuzz build "${flags[@]}" >/dev/null
echo "| target | seconds | executions | exec/s | coverage (edges) | features | corpus | findings |"
echo "|---|---|---|---|---|---|---|---|"
found=0
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    log="artifacts/$t/last-run.log"
    set +e
    cargo fuzz run "${flags[@]}" "$t" "corpus/$t" "seeds/$t" -- \
        -max_total_time="$secs" -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=10 \
        -print_final_stats=1 -artifact_prefix="artifacts/$t/" >"$log" 2>&1
    status=$?
    set -e
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
    rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
    last=$(grep -E '^#[0-9]+' "$log" | tail -n 1)
    cov=$(echo "$last" | grep -o 'cov: [0-9]*' | grep -o '[0-9]*' || echo "?")
    ft=$(echo "$last" | grep -o 'ft: [0-9]*' | grep -o '[0-9]*' || echo "?")
    corpus=$(find "corpus/$t" -type f | wc -l)
    findings=$(find "artifacts/$t" -type f ! -name last-run.log | wc -l)
    if [ "$status" -ne 0 ] || [ "$findings" -gt 0 ]; then
        found=1
        what="$findings (exit $status; see fuzz/artifacts/$t/)"
    else
        what=0
    fi
    echo "| $t | $secs | $execs | $rate | $cov | $ft | $corpus | $what |"
done
exit $found
