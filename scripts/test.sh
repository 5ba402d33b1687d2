#!/usr/bin/env bash
# relight's whole test suite: set-up (idempotent), the Rust tests, the Python tool's tests.
# Tests needing ../shared or Mitsuba 3 skip with a printed reason when those are absent.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
venv="${RELIGHT_VENV:-$HOME/.cache/relight/venv}"
if [ -x "$venv/bin/python" ]; then
    export RELIGHT_MITSUBA_PYTHON="${RELIGHT_MITSUBA_PYTHON:-$venv/bin/python}"
    py="$RELIGHT_MITSUBA_PYTHON"
else
    py=python3
fi
echo "== python: tools/test_mitsuba_reference.py"
"$py" tools/test_mitsuba_reference.py
# The binary's optional GPU renderer is on (`relight-cli/gpu`: relight-gpu on Vulkan, lavapipe
# from scripts/setup.sh where there is no GPU) so that its CLI tests (tests/gpu.rs) and the
# bench section compile and run in the same build: wgpu compiles once. relight-gpu's own
# tests run here too. (`cargo test --release -p relight-cli --test gpu` without the feature
# checks that a default build refuses --gpu by name.)
echo "== cargo test --release --workspace --features relight-cli/gpu"
cargo test --release --workspace --features relight-cli/gpu
