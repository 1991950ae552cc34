#!/usr/bin/env bash
# README's demo command: set up, build (release), cook a real DEM, check the archive and look at it.
# Default input: jacksboro_fault_dem.npz, a USGS DEM shipped by Debian's python-matplotlib-data.
# When ../shared/data is present, the Kilauea 30 m DEM and the Tahoe lidar are cooked too.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/scripts/setup.sh"
"$root/scripts/build.sh" release
bin="$root/build/release/bin"
out="$root/out/demo"
mkdir -p "$out"
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.x86_64.json}
data=${TERRAIN_DATA_DIR:-$root/../shared/data}

step() { printf '\n== %s\n' "$*"; }

inputs=("jacksboro|/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz|--crs EPSG:4326")
if [ -d "$data" ]; then
  inputs+=("kilauea|$data/kilauea_utm5n.tif|" "slovenia|$data/slovenia_TM1_564_146.tif|"
           "tahoe|$data/tahoe_lidar_bareearth.tif|")
else
  echo "demo: $data not found; cooking only the Debian-packaged DEM"
fi

for entry in "${inputs[@]}"; do
  IFS='|' read -r name src flags <<<"$entry"
  step "cook $name: $src"
  # shellcheck disable=SC2086
  "$bin/terrain-cook" "$src" -o "$out/$name.terrain" $flags --report "$out/$name.report.json"
  step "inspect $name"
  "$bin/terrain-inspect" "$out/$name.terrain"
  "$bin/terrain-inspect" --verify "$out/$name.terrain"
done

step "render (headless, Mesa lavapipe unless a GPU is present)"
"$bin/terrain-view" "$out/jacksboro.terrain" --headless --size 1280x720 --out "$out/jacksboro.png" --quiet
echo "$out/jacksboro.png"
if [ -d "$data" ]; then
  "$root/viewer/demo.sh" "$root/build/release" "$out" "$out"
fi
step "done: archives, reports (*.report.json) and pictures (*.png) are in $out"
