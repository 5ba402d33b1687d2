#!/usr/bin/env bash
# One-time, idempotent set-up of what relight needs beyond the Rust toolchain, on Debian 12:
#   - libembree-dev : Embree 3, relight's default ray-casting back-end and benchmark baseline
#   - libllvm19     : lets Mitsuba 3 use its fast `llvm_ad_rgb` variant (else `scalar_rgb`)
#   - slurm-wlm, munge : the one-node Slurm cluster of the sharded-bake test (the test starts
#                     and stops it itself with deploy/slurm/local-cluster.sh; no service is
#                     enabled)
#   - mesa-vulkan-drivers, libvulkan1 : the Vulkan loader and Mesa's drivers, among them
#                     lavapipe (a CPU Vulkan driver), for relight-gpu's tests and
#                     `relight render --gpu` (feature `gpu`) on machines without a GPU
#   - xvfb          : a virtual X display for the interactive viewer's tests (tests/view.rs)
#   - a Python venv with Mitsuba 3 + numpy at ${RELIGHT_VENV:-$HOME/.cache/relight/venv},
#     used only for ground truth (tools/mitsuba_reference.py and the tests that compare with it)
#   - nodejs, npm    : only if `npm` is missing (Debian's packages), to install:
#   - npm tools at ${RELIGHT_NPM:-$HOME/.cache/relight/npm}, pinned by
#     tools/gltf-assets/package.json + package-lock.json (`npm ci --prefix`): obj2gltf,
#     @gltf-transform/cli, @gltf-transform/core, @gltf-transform/extensions and the Khronos
#     gltf-validator, used only to build the textured glTF test assets
#     (tools/gltf-assets/make_assets.mjs, driven by relight-testdata)
# Each step is skipped when already done. Set RELIGHT_SKIP_MITSUBA=1 to skip the venv.
set -euo pipefail
cd "$(dirname "$0")/.."

pkgs=(libembree-dev libllvm19 slurm-wlm munge mesa-vulkan-drivers libvulkan1 xvfb)
missing=()
for p in "${pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    echo "setup: installing ${missing[*]} with apt-get"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

if [ "${RELIGHT_SKIP_MITSUBA:-0}" != 1 ]; then
    venv="${RELIGHT_VENV:-$HOME/.cache/relight/venv}"
    if ! "$venv/bin/python" -c "import mitsuba, numpy" 2>/dev/null; then
        echo "setup: creating $venv with mitsuba and numpy (pip)"
        python3 -m venv "$venv"
        "$venv/bin/pip" install -q --upgrade pip
        "$venv/bin/pip" install -q "mitsuba>=3.5,<4" numpy
    fi
fi

# The glTF asset tools: reinstalled whenever the committed lock file differs from the one
# installed (npm ci removes node_modules first, so a half-finished install is redone).
if ! command -v npm >/dev/null 2>&1; then
    sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    echo "setup: installing nodejs npm with apt-get"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq nodejs npm >/dev/null
fi
npm_dir="${RELIGHT_NPM:-$HOME/.cache/relight/npm}"
lock=tools/gltf-assets/package-lock.json
if ! cmp -s "$lock" "$npm_dir/package-lock.json" \
    || ! cmp -s "$lock" "$npm_dir/installed-lock.json"; then
    echo "setup: installing the glTF asset tools into $npm_dir (npm ci)"
    mkdir -p "$npm_dir"
    rm -f "$npm_dir/installed-lock.json"
    cp tools/gltf-assets/package.json "$lock" "$npm_dir/"
    npm ci --prefix "$npm_dir" --no-audit --no-fund --loglevel=error
    cp "$lock" "$npm_dir/installed-lock.json"
fi
echo "setup: node $(node --version), glTF asset tools in $npm_dir:"
npm ls --prefix "$npm_dir" --depth=0 | tail -n +2 | grep -v '^[[:space:]]*$' | sed 's/^/setup:   /'
echo "setup: ok"
