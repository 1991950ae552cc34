#!/usr/bin/env bash
# README's test command: set up, build (release) and run every test.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/scripts/setup.sh"
"$root/scripts/build.sh" release
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.x86_64.json}
cd "$root/build/release"
ctest --no-tests=error --output-on-failure -j "$(nproc)" "$@"
