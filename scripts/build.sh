#!/usr/bin/env bash
# Configures and builds one flavour into build/<flavour>: release (default), asan, tsan.
# Usage: scripts/build.sh [release|asan|tsan] [extra cmake args...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
flavour=${1:-release}
shift || true
args=(-G Ninja -DCMAKE_BUILD_TYPE=Release)
case "$flavour" in
  release) ;;
  asan) args=(-G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DTERRAIN_SANITIZE=address,undefined"
              -DTERRAIN_BUILD_BENCHMARKS=OFF) ;;
  tsan) args=(-G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTERRAIN_SANITIZE=thread -DTERRAIN_BUILD_VIEWER=OFF
              -DTERRAIN_BUILD_BENCHMARKS=OFF) ;;
  *) echo "build.sh: unknown flavour '$flavour' (release, asan, tsan)" >&2; exit 2 ;;
esac
# ccache (installed by setup.sh) makes rebuilds and the clean-clone CI stage cheap; paths under the
# checkout's parent are hashed relative, so other clones of the project share the cache.
if command -v ccache >/dev/null; then
  args+=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$(dirname "$root")} CCACHE_NOHASHDIR=1
fi
dir="$root/build/$flavour"
cmake -S "$root" -B "$dir" "${args[@]}" "$@" >/dev/null
cmake --build "$dir" -j "$(nproc)"
echo "build.sh: $flavour build in $dir (binaries in $dir/bin)"
