#!/usr/bin/env bash
# relight's whole test suite: set-up (idempotent), the Rust tests, the Python tool's tests.
# Tests needing ../shared or Mitsuba 3 skip with a printed reason when those are absent.
set -euo pipefail
cd "$(dirname "$0")/.."
# The skip policy in force (crates/relight-testdata): with RELIGHT_REQUIRE_REFERENCE=1 every
# skip fails, except a platform precondition named in RELIGHT_ALLOW_SKIP (comma-separated).
echo "RELIGHT_REQUIRE_REFERENCE=${RELIGHT_REQUIRE_REFERENCE:-} RELIGHT_ALLOW_SKIP=${RELIGHT_ALLOW_SKIP:-}"
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
# The binary's optional GPU renderer and viewer are on (`relight-cli/view`, which implies
# `relight-cli/gpu`: relight-gpu on Vulkan, lavapipe from scripts/setup.sh where there is no
# GPU; the viewer's tests start their own Xvfb) so that the CLI tests (tests/gpu.rs,
# tests/view.rs) and the bench section compile and run in the same build: wgpu compiles once.
# relight-gpu's and relight-view's own tests run here too. (`cargo test --release -p
# relight-cli --test gpu --test view` without the features checks that a default build
# refuses --gpu and `view` by name: .ci/run runs it, with RELIGHT_ALLOW_SKIP=feature-gpu,
# feature-view.)
echo "== cargo test --release --workspace --features relight-cli/view"
cargo test --release --workspace --features relight-cli/view
# The API documentation builds without warnings: a broken intra-doc link fails here. With the
# features of the tests, so that the optional crates (relight-gpu, relight-view) are checked too.
echo "== cargo doc --release --workspace --no-deps --features relight-cli/view (RUSTDOCFLAGS=-D warnings)"
RUSTDOCFLAGS="-D warnings" cargo doc --release --workspace --no-deps --features relight-cli/view
