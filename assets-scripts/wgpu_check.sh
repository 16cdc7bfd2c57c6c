#!/usr/bin/env bash
# Trains the same small run on burn's wgpu backend and on the CPU backend (flex) and compares
# their loss curves epoch by epoch (material-nn/tests/cli/wgpu_backend.rs). Any Vulkan driver
# serves; on a machine without a GPU, Mesa's software driver lavapipe (Debian/Ubuntu:
# mesa-vulkan-drivers and libvulkan1, installed here when missing and run as root).
# The wgpu build adds about 10 minutes on two cores, which is why CI does not run it.
#
# Usage: assets-scripts/wgpu_check.sh
set -euo pipefail
cd "$(dirname "$0")/.."
if ! ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1 || ! ldconfig -p | grep -q libvulkan.so.1; then
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null; then
        apt-get update -qq && apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
    else
        echo "error: no Vulkan driver: install mesa-vulkan-drivers and libvulkan1 (or a GPU's driver)" >&2
        exit 2
    fi
fi
# Mesa's window-system probing asks for XDG_RUNTIME_DIR; a headless run has none to offer.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
cargo test --release -p material-nn --features wgpu --test cli -- wgpu_backend:: --nocapture
