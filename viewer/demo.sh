#!/usr/bin/env bash
# Renders the viewer's demo pictures of real archives (headless, lavapipe-friendly sizes).
# Usage: viewer/demo.sh BUILD_DIR OUT_DIR [ARCHIVE_DIR]
#   ARCHIVE_DIR holds kilauea.terrain, slovenia.terrain, tahoe.terrain (default: BUILD_DIR/test-archives,
#   written by `ctest -R cook_test_archives`). Prints the paths of the pictures it wrote.
set -euo pipefail
build=${1:?usage: viewer/demo.sh BUILD_DIR OUT_DIR [ARCHIVE_DIR]}
out=${2:?usage: viewer/demo.sh BUILD_DIR OUT_DIR [ARCHIVE_DIR]}
archives=${3:-$build/test-archives}
view="$build/bin/terrain-view"
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.x86_64.json}
mkdir -p "$out"
shot() {  # name archive args...
  local name=$1 archive=$2
  shift 2
  if [ ! -f "$archives/$archive.terrain" ]; then
    echo "demo: $archives/$archive.terrain missing, $name skipped" >&2
    return
  fi
  "$view" "$archives/$archive.terrain" --headless --size 1280x720 --out "$out/$name.png" \
    --stats "$out/$name.json" --quiet "$@"
  echo "$out/$name.png"
}
# Kilauea (USGS 30 m DEM, UTM 5N): the whole archive, the caldera, the fault cliffs, the LOD view.
shot kilauea_overview kilauea
shot kilauea_caldera kilauea --camera 260500,2140000,2300 --look-at 260500,2147000,1000
shot kilauea_cliffs kilauea --camera 270000,2133000,1500 --look-at 266000,2140000,900
shot kilauea_lod kilauea --camera 260500,2140000,2300 --look-at 260500,2147000,1000 --debug lod
# Slovenian national lidar (1 m): levels down to 1 m, splat materials near the camera.
shot slovenia_lidar slovenia --camera 564100,146050,420 --look-at 564600,146600,280
shot slovenia_lod slovenia --camera 564100,146050,420 --look-at 564600,146600,280 --debug lod
# Lake Tahoe lidar (0.5 m), level 0 nodes.
shot tahoe_lidar tahoe --camera -60,4350600,2545 --look-at 20,4350760,2505
