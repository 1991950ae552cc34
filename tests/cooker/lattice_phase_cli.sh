#!/usr/bin/env bash
# The vertex lattice follows the source's samples (cooker/README.md, "What gets cooked", lattice
# phase): the shared Slovenian 1 m lidar tile (sample centres on whole metres) and the same tile
# moved by half a metre (centres on half metres, as products whose tile corners lie on whole metres
# have them) both cook with every sample on a level-1 vertex, so neither needs level 0 and both
# reproduce every sample up to the height rounding.
# Usage: lattice_phase_cli.sh TERRAIN_COOK SCRATCH_DIR DATA_DIR
set -uo pipefail
cook=$1 dir=$2 data=$3
tile=$data/slovenia_TM1_564_146.tif
[ -f "$tile" ] || { echo "SKIPPED: $tile not found (set TERRAIN_DATA_DIR)"; exit 0; }
rm -rf "$dir" && mkdir -p "$dir" && cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
# The same samples, the corner moved from (563999.5, 147000.5) to (564000, 147000).
gdal_translate -q -a_ullr 564000 147000 565000 146000 "$tile" shifted.tif || fail "gdal_translate"
for name in tile shifted; do
  src=$tile; [ $name = shifted ] && src=shifted.tif
  "$cook" "$src" -o $name.terrain --heights-only --threads 2 --json > $name.json 2> $name.err ||
    fail "cook of $name: $(head -c 600 $name.err)"
done
python3 - tile.json shifted.json <<'PY' || fail "reports"
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:3])
for name, r in (("tile", a), ("shifted", b)):
    levels = r["levels"]
    print(name, "origin", r["frame"]["origin_m"], "nodes per level", [l["nodes"] for l in levels],
          "full detail", r["full_detail_error"])
    # The origin is a multiple of 2048 m plus the samples' offset from whole metres.
    phase = 0.0 if name == "tile" else 0.5
    for v in r["frame"]["origin_m"]:
        assert v % 2048 == phase, (name, v)
    # 1 m samples on level-1 vertices: the error-driven refinement stops at level 1 and no data edge
    # needs level 0 (every edge sample is a vertex of a drawn triangle).
    assert levels[0]["nodes"] == 0, (name, levels[0])
    assert levels[1]["nodes"] > 0, (name, levels[1])
    # Sample-exact: the full-detail error is the rounding of each height to its level's step
    # (SPEC 7: a vertex is rounded to the nearest multiple), at most half of it.
    fd = r["full_detail_error"]
    step = levels[1]["step_m"]
    # (samples on a node edge are measured by both nodes)
    assert fd["samples"] >= 1000 * 1000 and fd["uncovered_samples"] == 0, (name, fd)
    assert fd["max_m"] <= step / 2, (name, fd["max_m"], step)
# The same samples relative to the lattice: the same tree and the same height bytes.
assert [l["nodes"] for l in a["levels"]] == [l["nodes"] for l in b["levels"]]
assert a["output"]["sections"]["heights"]["stored_bytes"] == b["output"]["sections"]["heights"]["stored_bytes"]
PY
echo "PASS"
