#!/usr/bin/env bash
# Installs a terrain build into a fresh prefix, builds samples/engine against that prefix from a
# separate build directory (find_package(terrain), no add_subdirectory), runs it on an archive, and
# compiles a one-line program with `pkg-config --cflags --libs terrain-streamer`.
# Usage: check_package.sh <terrain build dir> <install prefix> <work dir> [archive]
# Without an archive it cooks the Jacksboro DEM (Debian's python-matplotlib-data) with the installed
# terrain-cook. Prefix and work dir are deleted first. Exit 0 only when every step passed.
set -euo pipefail
[ $# -ge 3 ] || { echo "usage: $0 <build dir> <install prefix> <work dir> [archive]" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
build=$(cd "$1" && pwd)
prefix=$2
work=$3
archive=${4:-}
fail() { echo "check_package: $*" >&2; exit 1; }

rm -rf "$prefix" "$work"
mkdir -p "$prefix" "$work"
prefix=$(cd "$prefix" && pwd)
work=$(cd "$work" && pwd)

echo "check_package: install $build -> $prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log"
for f in include/terrain/streamer.h include/terrain/format.h include/terrain/byte_source.h bin/terrain-cook \
         bin/terrain-inspect; do
  [ -e "$prefix/$f" ] || fail "$prefix/$f not installed"
done
config=$(find "$prefix" -name terrainConfig.cmake -print -quit)
pcfile=$(find "$prefix" -name terrain-streamer.pc -print -quit)
[ -n "$config" ] && [ -n "$pcfile" ] || fail "terrainConfig.cmake or terrain-streamer.pc not installed"
# 0.3 changed the streamer's API (issue 49: the residency index); 0.4 the format library's
# (WorldInfo::derived_normals, format version 2 archives whose normals readers derive); 0.5 the
# layout of StreamerConfig, StreamerStats, HttpOptions, HttpStats and ByteSource's virtuals (issue
# 52: reads apart from decodes, the range cache); 0.6 format version 3 (the paged directory, SPEC
# 20: archives that 0.5 readers refuse) and ArchiveReader's DirectoryLoad, lookup(), record(),
# prefetch(): the version file says so and refuses a request for an older minor version
# (SameMinorVersion).
grep -q 'PACKAGE_VERSION "0.6.0"' "$(dirname "$config")/terrainConfigVersion.cmake" ||
  fail "terrainConfigVersion.cmake does not say 0.6.0"
# The tools' shared helpers (tools/common: CLI11 flag checks, progress bar, charts) stay out of the package.
for f in cli_checks.h terminal_progress.h bench_chart.h bench_paths.h tool_module.h; do
  [ -z "$(find "$prefix" -name "$f" -print -quit)" ] || fail "$f (tools only) was installed"
done
# Public headers: standard library and our own headers only.
if grep -n '#include <' "$prefix"/include/terrain/*.h | grep -v -E '#include <[a-z_]+>$'; then
  fail "an installed header includes a third-party header (above)"
fi

echo "check_package: build samples/engine against $prefix"
launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
generator=()
if command -v ninja >/dev/null; then generator=(-G Ninja); fi
cmake -S "$here" -B "$work/build" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_COMPILE_WARNING_AS_ERROR=ON "${launcher[@]}" >"$work/configure.log"
found=$(sed -n 's/^terrain_DIR:PATH=//p' "$work/build/CMakeCache.txt")
[ "$found" = "$(dirname "$config")" ] || fail "find_package(terrain) found '$found', not the installed $(dirname "$config")"
cmake --build "$work/build" >"$work/build.log" || { cat "$work/build.log"; fail "samples/engine does not build"; }

if [ -z "$archive" ]; then
  dem=/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz
  [ -e "$dem" ] || fail "$dem missing (scripts/setup.sh installs python-matplotlib-data)"
  archive="$work/jacksboro.terrain"
  # --tolerance 0.5: the two levels the flight below needs (the default for its 75 m samples, 2.3 m,
  # keeps the roots alone).
  "$prefix/bin/terrain-cook" "$dem" -o "$archive" --crs EPSG:4326 --tolerance 0.5 --quiet
fi
# The installed terrain-inspect finds its image writer module in lib/terrain (tools/common/tool_module.h).
"$prefix/bin/terrain-inspect" "$archive" --export 5/0/0 "$work/export" -q >/dev/null ||
  fail "the installed terrain-inspect could not export a node"
[ -s "$work/export/heights.exr" ] && [ -s "$work/export/albedo.png" ] || fail "the installed terrain-inspect wrote no images"
echo "check_package: run the sample on $archive"
# Jacksboro has two levels (16 x 16 roots and their children): a low error target and a budget of 296
# nodes in 296 slots make the there-and-back flight split, evict and reuse slots right at their fence.
"$work/build/terrain-engine-sample" "$archive" "$root/samples/paths/jacksboro.txt" --error-px 0.06 --budget 296 \
  --slots 296 >"$work/sample.log" || { tail -n 30 "$work/sample.log"; fail "terrain-engine-sample failed"; }
summary=$(tail -n 1 "$work/sample.log")
echo "$summary"
if echo "$summary" | grep -q ' 0 evictions'; then fail "no evictions along the path: the sample checked too little"; fi

echo "check_package: pkg-config terrain-streamer"
export PKG_CONFIG_PATH="$(dirname "$pcfile")${PKG_CONFIG_PATH:+:$PKG_CONFIG_PATH}"
echo '#include <terrain/streamer.h>
int main(int argc, char** argv) { terrain::Streamer s; return argc > 1 && s.open(argv[1]).ok() ? 0 : 1; }' >"$work/pc_check.cpp"
# shellcheck disable=SC2046  # pkg-config's output is a list of flags
# (the rpath matters only for a BUILD_SHARED_LIBS=ON build)
${CXX:-c++} -std=c++20 "$work/pc_check.cpp" -o "$work/pc_check" $(pkg-config --cflags --libs terrain-streamer) \
  -Wl,-rpath,"$(pkg-config --variable=libdir terrain-streamer)"
"$work/pc_check" "$archive" || fail "the pkg-config program could not open $archive"
echo "check_package: ok"
