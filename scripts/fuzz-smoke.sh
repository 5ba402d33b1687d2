#!/usr/bin/env bash
# A short smoke run of every fuzz target (10 s each; fuzz/run.sh has the campaign), run by
# .ci/run after the tests. Installs cargo-fuzz from crates.io if it is missing (it builds on
# the stable toolchain; the targets run without a sanitizer, see fuzz/README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "fuzz-smoke: installing cargo-fuzz (cargo install)"
    cargo install cargo-fuzz --locked --quiet
fi
bash fuzz/run.sh "${RELIGHT_FUZZ_SECONDS:-10}"
