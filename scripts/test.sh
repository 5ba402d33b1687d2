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
echo "== cargo test --release --workspace"
cargo test --release --workspace
# The binary's optional GPU renderer (`--features gpu`, relight-gpu on Vulkan: lavapipe from
# scripts/setup.sh where there is no GPU); relight-gpu's own tests ran in the workspace above.
echo "== cargo test --release -p relight-cli --features gpu --test gpu"
cargo test --release -p relight-cli --features gpu --test gpu
