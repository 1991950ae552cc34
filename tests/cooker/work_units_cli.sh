#!/usr/bin/env bash
# Work units of issue 14: work_units_cli.sh CASE BIN_DIR SCRATCH_PARENT [DATA_DIR]. Every case compares
# whole archives byte for byte with the one-process cook of the same inputs and flags.
set -u
case_name=$1 bin=$2 work=$3/work-units-$1 data=${4:-}
cook="$bin/terrain-cook"
fail() { echo "FAIL ($case_name): $*"; exit 1; }
dem=/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz
[ -f "$dem" ] || { echo "SKIP: $dem absent (python3-matplotlib-data)"; exit 0; }
rm -rf "$work"; mkdir -p "$work"; cd "$work" || exit 1
flags=(--crs EPSG:4326 --heights-only -q)
# No staged or spooled file may survive a finished command.
no_leftovers() {
  local left
  left=$(find . \( -name '*.tmp-*' -o -name '*.spool-*' -o -name '*.payloads' \) -print)
  [ -z "$left" ] || fail "left behind: $left"
}
# Runs every unit of work dir $1 in an order shuffled by seed $2.
units_shuffled() {
  local n i
  n=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['unit_count'])" "$1/plan.json")
  # Two at a time, as two machines sharing the work dir would.
  python3 -c "import random,sys; l=list(range(int(sys.argv[1]))); random.Random(int(sys.argv[2])).shuffle(l); print(*l, sep='\n')" "$n" "$2" |
    xargs -P 2 -I{} "$cook" unit "$1" {} -q --threads 1 || fail "a unit of $1 failed"
}

# Every file under . but err.txt with its hash: "byte-identical after" checks.
snapshot() { find . -type f ! -name err.txt -print0 | sort -z | xargs -0 sha256sum; }
# expect_refused RC REGEX CMD...: CMD exits RC, its stderr matches REGEX, and every file is as it was.
expect_refused() {
  local want=$1 re=$2 before rc
  shift 2
  before=$(snapshot)
  "$@" > /dev/null 2> err.txt
  rc=$?
  echo "exit $rc: $(cat err.txt)"
  [ $rc = "$want" ] || fail "'$*': exit $rc, expected $want"
  grep -Eq -- "$re" err.txt || fail "'$*': message does not match '$re'"
  [ "$(snapshot)" = "$before" ] || fail "'$*': files changed: $(diff <(echo "$before") <(snapshot))"
}
# npz_plus SRC DST METRES: DST holds SRC's heights + METRES, every member stored uncompressed, so two
# files made from one SRC have the same size whatever their heights.
npz_plus() {
  python3 - "$@" <<'PY'
import array, sys, zipfile
src, dst, add = sys.argv[1], sys.argv[2], int(sys.argv[3])
zin = zipfile.ZipFile(src)
with zipfile.ZipFile(dst, "w", zipfile.ZIP_STORED) as zout:
    for info in zin.infolist():
        b = zin.read(info.filename)
        if info.filename == "elevation.npy":
            start = int.from_bytes(b[8:10], "little") + 10
            a = array.array("h", b[start:])
            for i in range(len(a)):
                a[i] += add
            b = b[:start] + a.tobytes()
        zout.writestr(zipfile.ZipInfo(info.filename, date_time=(2020, 1, 1, 0, 0, 0)), b)
PY
}
unit_count() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['unit_count'])" "$1/plan.json"; }

case $case_name in
  any_split_any_order)
    # Units of 1, 2 and 7 roots per side (256, 64 and 9 units of the 16 x 16 roots), run in shuffled
    # orders two at a time, merge to the one-process bytes.
    "$cook" "$dem" "${flags[@]}" -o ref.terrain --report ref.json || fail "reference cook"
    for roots in 1 2 7; do
      n=$("$cook" plan "$dem" "${flags[@]}" --work-dir "w$roots" --unit-roots $roots) || fail "plan $roots"
      echo "unit roots $roots: $n units"
      units_shuffled "w$roots" $roots
      "$cook" merge "w$roots" -o "m$roots.terrain" -q || fail "merge $roots"
      cmp ref.terrain "m$roots.terrain" || fail "units of $roots roots: not the one-process bytes"
    done
    # The units carry the per-stage CPU of their nodes: every stage the one-process cook timed is
    # timed in the merged report too (CPU seconds differ run to run; zero would mean not carried).
    "$cook" merge w2 -o m2b.terrain -q --report m2.json || fail "merge 2 with a report"
    python3 - ref.json m2.json <<'PY' || fail "cpu_parts of the units are not in the merged report"
import json, sys
ref, merged = (json.load(open(p))["time_s"]["cpu_parts"] for p in sys.argv[1:3])
timed = [k for k, v in ref.items() if v > 0]
missing = [k for k in timed if merged.get(k, 0) <= 0]
print(f"cpu_parts timed by the one-process cook: {len(timed)}; zero after the merge: {missing}")
# Level by level too: every level with nodes carries its CPU per node through the unit files.
levels = [l for l in json.load(open(sys.argv[2]))["levels"] if l["nodes"] > 0]
untimed = [l["level"] for l in levels if l["cpu_ms_per_node"]["total"] <= 0]
print(f"levels with nodes after the merge: {len(levels)}; without CPU per node: {untimed}")
sys.exit(1 if not timed or missing or not levels or untimed else 0)
PY
    # A unit larger than the memory blocks its machine can hold is cooked block by block: units of 7
    # roots as blocks of 2 (16 per unit) give the same bytes.
    rm -f w7/units/unit-*.tcu
    n=$(python3 -c "import json; print(json.load(open('w7/plan.json'))['unit_count'])")
    for ((i = 0; i < n; ++i)); do "$cook" unit w7 $i -q --threads 1 --block-roots 2 || fail "unit $i of w7 in blocks of 2"; done
    "$cook" merge w7 -o m7b.terrain -q || fail "merge 7 in blocks of 2"
    cmp ref.terrain m7b.terrain || fail "units of 7 roots cooked as blocks of 2: not the one-process bytes"
    n1=$(python3 -c "import json; print(json.load(open('w1/plan.json'))['unit_count'])")
    n7=$(python3 -c "import json; print(json.load(open('w7/plan.json'))['unit_count'])")
    [ "$n1" -ge 8 ] && [ "$n7" -lt "$n1" ] || fail "expected >= 8 units of 1 root and fewer of 7 (got $n1, $n7)"
    # A second run of a unit redoes nothing.
    out=$("$cook" unit w1 0) || fail "unit 0 again"
    [ "$out" = "unit 0: already complete" ] || fail "unit 0 again: '$out'"
    # terrain-cook's merge maps neither GDAL nor PROJ and runs without the full cooker beside it
    # (terrain-cook and terrain-cook-merge copied alone into a folder); every other command needs it.
    mkdir -p front && cp "$cook" "$bin/terrain-cook-merge" front/ || fail "copy terrain-cook and terrain-cook-merge"
    libs=$(ldd front/terrain-cook-merge) || fail "ldd terrain-cook-merge"
    case $libs in *libgdal*|*libproj*) fail "terrain-cook-merge maps GDAL or PROJ: $libs" ;; esac
    front/terrain-cook merge w1 -o m1f.terrain -q || fail "merge without the full cooker"
    cmp ref.terrain m1f.terrain || fail "merge without the full cooker: not the one-process bytes"
    err=$(front/terrain-cook unit w1 0 2>&1) && fail "a unit ran without the full cooker"
    case $err in *"cannot start terrain-cook-full"*) ;; *) fail "unit without the full cooker: '$err'" ;; esac
    no_leftovers ;;

  kill_resume)
    # SIGKILL at 12 points spread over a cook with --work-dir (planning, units, merge), each time
    # resumed by the same command; the last run completes. The old archive stays until then.
    full=(--crs EPSG:4326 -q --threads 2 --tolerance 1)
    "$cook" "$dem" "${full[@]}" -o ref.terrain || fail "reference cook"
    echo old > out.terrain
    cp out.terrain old.txt
    start=$(date +%s%N)
    "$cook" "$dem" "${full[@]}" -o timing.terrain --work-dir wt --unit-roots 2 || fail "timing cook"
    total_ms=$(( ($(date +%s%N) - start) / 1000000 ))
    echo "uninterrupted cook with --work-dir: $total_ms ms"
    for k in $(seq 1 12); do
      delay_ms=$(( total_ms * k / 13 ))
      "$cook" "$dem" "${full[@]}" -o out.terrain --work-dir w --unit-roots 2 &
      pid=$!
      sleep "$(printf '%d.%03d' $((delay_ms / 1000)) $((delay_ms % 1000)))"
      kill -9 $pid 2>/dev/null
      wait $pid 2>/dev/null
      units=$(ls w/units 2>/dev/null | grep -c '\.tcu$')
      echo "kill $k after $delay_ms ms: $units unit files"
      cmp -s out.terrain old.txt || cmp -s out.terrain ref.terrain || fail "out.terrain is neither the old file nor the result after kill $k"
    done
    # Three more kills inside `terrain-cook merge` itself (the units are complete by now).
    "$cook" plan "$dem" "${full[@]}" --work-dir w --unit-roots 2 > /dev/null || fail "plan before the merge kills"
    for ms in 20 60 120; do
      "$cook" merge w -o out.terrain -q &
      pid=$!
      sleep "0.$(printf '%03d' $ms)"
      kill -9 $pid 2>/dev/null
      wait $pid 2>/dev/null
      cmp -s out.terrain old.txt || cmp -s out.terrain ref.terrain || fail "out.terrain damaged by a merge killed after $ms ms"
      echo "merge killed after $ms ms"
    done
    "$cook" "$dem" "${full[@]}" -o out.terrain --work-dir w --unit-roots 2 || fail "resume"
    cmp ref.terrain out.terrain || fail "resumed archive differs from the one-process cook"
    cmp ref.terrain timing.terrain || fail "uninterrupted --work-dir archive differs"
    # A kill can land in any staged write (the plan's, a unit's, the archive's or its spool); the
    # resume that succeeded removed what the killed runs left of them.
    no_leftovers
    "$cook" "$dem" "${full[@]}" -o out2.terrain --work-dir w --unit-roots 2 || fail "second resume"
    cmp ref.terrain out2.terrain || fail "a finished work dir merges again to other bytes"
    no_leftovers ;;

  recook_one_tile)
    # A 16-tile VRT cut from Kilauea; one tile replaced by a changed copy: plan keeps every unit the
    # tile's footprint does not meet, and the result equals a from-scratch cook of the new inputs.
    kil="$data/kilauea_utm5n.tif"
    [ -n "$data" ] && [ -f "$kil" ] || { echo "SKIP: $kil absent (set TERRAIN_DATA_DIR)"; exit 0; }
    command -v gdalbuildvrt > /dev/null || { echo "SKIP: gdalbuildvrt absent (gdal-bin)"; exit 0; }
    mkdir tiles
    for ty in 0 1 2 3; do for tx in 0 1 2 3; do
      gdal_translate -q -srcwin $((tx * 215)) $((ty * 199)) 215 199 "$kil" "tiles/t${ty}${tx}.tif" || fail "tile"
    done; done
    gdalbuildvrt -q mosaic.vrt tiles/*.tif || fail "gdalbuildvrt"
    kf=(-q --heights-only)
    "$cook" plan mosaic.vrt "${kf[@]}" --work-dir w --unit-roots 2 > /dev/null || fail "plan"
    # The plan cuts the mosaic's VRT to each unit's window (the units parse only their tiles).
    cuts() {
      /usr/bin/python3 - w/plan.json <<'PY'
import glob, json, sys, xml.etree.ElementTree as ET
p = json.load(open(sys.argv[1]))
want = {f"w/units/unit-{u['index']}-{u['fingerprint']}.vrt" for u in p["units"] if u["window"][0] <= u["window"][2]}
have = set(glob.glob("w/units/unit-*.vrt"))
assert have == want, f"cuts {sorted(have ^ want)} missing or stale"
sizes = [sum(len(ET.parse(f).getroot().findall(f"./VRTRasterBand/{k}")) for k in ("ComplexSource", "SimpleSource"))
         for f in sorted(have)]
assert max(sizes) < 16 and min(sizes) > 0, f"sources per cut {sizes}, of 16 tiles"
print(f"{len(have)} cuts of the 16-tile VRT, {min(sizes)}-{max(sizes)} sources each")
PY
    }
    cuts || fail "the units' VRT cuts"
    units_shuffled w 1
    "$cook" merge w -o before.terrain -q || fail "merge before"
    n=$(python3 -c "import json; print(json.load(open('w/plan.json'))['unit_count'])")
    # tile t12 (row 1, column 2): +5 m over a 40 x 40 patch in its middle
    /usr/bin/python3 - tiles/t12.tif <<'PY' || fail "changing the tile"
import sys
from osgeo import gdal
ds = gdal.Open(sys.argv[1], gdal.GA_Update)
b = ds.GetRasterBand(1)
a = b.ReadAsArray()
a[80:120, 90:130] += 5
b.WriteArray(a)
ds = None
PY
    # Behind the old plan, a unit checks only the tiles its window meets (one stat per tile it may
    # read, not per tile of the mosaic): one that does not meet t12 cooks, one that does refuses by
    # name, and so does the merge, which checks every file.
    read -r away near < <(python3 - w/plan.json <<'PY'
import json, sys
p = json.load(open(sys.argv[1]))
files = json.load(open(f"w/inputs-{p['inputs']['fingerprint']}.json"))["files"]
tile = [f for f in files if f["path"].endswith("t12.tif")][0]["footprint"]
meets = lambda a, b: a[0] <= b[2] and b[0] <= a[2] and a[1] <= b[3] and b[1] <= a[3] and a[0] <= a[2] and b[0] <= b[2]
print([u["index"] for u in p["units"] if not meets(u["window"], tile)][0],
      [u["index"] for u in p["units"] if meets(u["window"], tile)][0])
PY
)
    rm -f "w/units/unit-$away.tcu" "w/units/unit-$near.tcu"
    [ "$("$cook" unit w "$away")" = "unit $away: cooked" ] || fail "unit $away (window away from t12) refused a change it does not read"
    "$cook" unit w "$near" 2> near.err && fail "unit $near (window meets t12) cooked behind a changed tile"
    grep -q "t12.tif: changed since the plan" near.err || fail "unit $near does not name the changed tile: $(cat near.err)"
    "$cook" merge w -o stale.terrain -q 2> merge.err && fail "merged units behind a changed tile"
    grep -q "t12.tif: changed since the plan" merge.err || fail "the merge does not name the changed tile: $(cat merge.err)"
    echo "behind the old plan: unit $away cooked, unit $near and the merge refused: $(cat near.err)"
    out=$("$cook" plan mosaic.vrt --heights-only --work-dir w --unit-roots 2) || fail "re-plan"
    echo "$out"
    cuts || fail "the units' VRT cuts after the re-plan"
    echo "$out" | grep -q "tiles/t12.tif: changed" || fail "the re-plan does not name the changed tile"
    expected=$(python3 - w/plan.json <<'PY'
import json, sys
p = json.load(open(sys.argv[1]))
files = json.load(open(f"w/inputs-{p['inputs']['fingerprint']}.json"))["files"]
tile = [f for f in files if f["path"].endswith("t12.tif")][0]["footprint"]
meets = lambda a, b: a[0] <= b[2] and b[0] <= a[2] and a[1] <= b[3] and b[1] <= a[3] and a[0] <= a[2] and b[0] <= b[2]
print(sum(1 for u in p["units"] if meets(u["window"], tile)))
PY
)
    cooked=0
    for i in $(seq 0 $((n - 1))); do
      r=$("$cook" unit w "$i") || fail "unit $i"
      [ "$r" = "unit $i: cooked" ] && cooked=$((cooked + 1))
    done
    echo "units: $n, cooked again: $cooked, whose window meets the tile: $expected"
    [ "$cooked" -gt 0 ] && [ "$cooked" -lt "$n" ] && [ "$cooked" = "$expected" ] || fail "re-cooked $cooked of $n units, expected $expected"
    "$cook" merge w -o after.terrain -q || fail "merge after"
    "$cook" mosaic.vrt "${kf[@]}" -o scratch.terrain || fail "from-scratch cook"
    cmp after.terrain scratch.terrain || fail "the re-cooked archive differs from a from-scratch cook"
    ! cmp -s before.terrain after.terrain || fail "the change did not reach the archive"
    no_leftovers ;;

  bad_states)
    # A unit of another plan, a truncated unit, a missing unit, a changed input behind the plan: each
    # a named error, exit 1, and nothing merged (the old archive stays).
    cp "$dem" in.npz
    "$cook" plan in.npz "${flags[@]}" --work-dir w --unit-roots 4 > /dev/null || fail "plan"
    units_shuffled w 3
    "$cook" plan in.npz "${flags[@]}" --work-dir other --unit-roots 4 --tolerance 2 > /dev/null || fail "other plan"
    units_shuffled other 4
    echo old > out.terrain
    expect_merge() {  # REGEX
      "$cook" merge w -o out.terrain -q 2> err.txt
      rc=$?
      echo "exit $rc: $(cat err.txt)"
      [ $rc = 1 ] || fail "merge exit $rc, expected 1"
      grep -Eq -- "$1" err.txt || fail "message does not match '$1'"
      [ "$(cat out.terrain)" = old ] || fail "out.terrain was replaced"
    }
    flip_byte() {  # FILE OFFSET: invert every bit of one byte (writing a fixed byte may write what is there)
      local b
      b=$(od -An -tu1 -j "$2" -N1 "$1" | tr -d ' ')
      printf "\\$(printf '%03o' $((255 - b)))" | dd of="$1" bs=1 seek="$2" conv=notrunc status=none
    }
    cp w/units/unit-0.tcu keep0
    cp other/units/unit-0.tcu w/units/unit-0.tcu
    expect_merge "unit 0 .*from another plan"
    cp keep0 w/units/unit-0.tcu
    head -c 1000 w/units/unit-1.tcu > t && mv t w/units/unit-1.tcu
    expect_merge "unit 1 .*truncated"
    "$cook" unit w 1 -q || fail "redo unit 1"
    flip_byte w/units/unit-1.tcu 200
    expect_merge "unit 1 .*checksum"
    "$cook" unit w 1 -q || fail "redo unit 1"
    # Damage inside the payloads: the merge finds it while it copies (one read of each unit), fails,
    # and leaves neither an archive nor its temporary file; `unit` (a full check) redoes the unit.
    cp w/units/unit-1.tcu keep1
    size=$(stat -c %s w/units/unit-1.tcu)
    flip_byte w/units/unit-1.tcu $((size - 20))
    cmp -s keep1 w/units/unit-1.tcu && fail "the damage changed nothing"
    expect_merge "unit 1 .*checksum"
    no_leftovers
    cp w/units/unit-1.tcu damaged1
    "$cook" unit w 1 -q || fail "redo unit 1"
    ! cmp -s damaged1 w/units/unit-1.tcu || fail "unit 1 was not redone after damage inside its payloads"
    "$cook" merge w -o mid.terrain -q || fail "merge after redoing unit 1"
    cp w/units/unit-1.tcu keep1
    # A foreign writer's unit with a valid CRC but its table out of canonical order: named, refused.
    python3 - w/units/unit-1.tcu <<'PY' || fail "swap"
import struct, sys, zlib
p = sys.argv[1]
b = bytearray(open(p, 'rb').read())
n = struct.unpack_from('<I', b, 48)[0]
assert n >= 2
e0, e1 = bytes(b[64:112]), bytes(b[112:160])
b[64:112], b[112:160] = e1, e0
struct.pack_into('<I', b, len(b) - 8, zlib.crc32(bytes(b[:-8])) & 0xffffffff)
open(p, 'wb').write(b)
PY
    expect_merge "unit 1 .*canonical order"
    cp keep1 w/units/unit-1.tcu
    rm w/units/unit-2.tcu
    expect_merge "unit 2 .*missing"
    "$cook" unit w 2 -q || fail "redo unit 2"
    # A unit reads its own list of input files, not the plan's list of all of them: it cooks without
    # that; the merge, which checks every input, refuses without it or with it damaged.
    all=$(ls w/inputs-*.json) && [ "$(echo "$all" | wc -l)" = 1 ] || fail "expected one inputs file: $all"
    mv "$all" all.json
    rm w/units/unit-2.tcu
    "$cook" unit w 2 -q || fail "unit 2 without the plan's list of all inputs"
    expect_merge "inputs-.*json: the plan's list of input files is missing"
    head -c 100 all.json > "$all"
    expect_merge "inputs-.*json: damaged"
    mv all.json "$all"
    # A unit's list missing, or of another unit (its files then do not give the unit's fingerprint):
    # named, exit 1.
    list0=$(ls w/units/unit-0-*.inputs.json) && list1=$(ls w/units/unit-1-*.inputs.json) || fail "no unit lists"
    mv "$list0" keep_list0
    "$cook" unit w 0 2> err.txt && fail "unit 0 ran without its list of inputs"
    grep -q "unit 0's list of input files is missing" err.txt || fail "unit 0 without its list: $(cat err.txt)"
    echo "unit without its list: $(cat err.txt)"
    python3 - "$list1" "$list0" <<'PY' || fail "a list of another unit"
import json, sys
j = json.load(open(sys.argv[1]))
j["files"][0]["footprint"] = [0, 0, 0, 0]  # meets unit 1's window, not unit 0's
open(sys.argv[2], "w").write(json.dumps(j))
PY
    "$cook" unit w 0 2> err.txt && fail "unit 0 ran with a list of another unit"
    grep -q "do not give unit 0's fingerprint" err.txt || fail "unit 0 with another unit's list: $(cat err.txt)"
    echo "unit with another unit's list: $(cat err.txt)"
    python3 - keep_list0 "$list0" <<'PY' || fail "a malformed list"
import json, sys
j = json.load(open(sys.argv[1]))
j["files"][0]["size"] = "large"
open(sys.argv[2], "w").write(json.dumps(j))
PY
    "$cook" unit w 0 2> err.txt && fail "unit 0 ran with a malformed list"
    grep -q "inputs.json: malformed" err.txt || fail "unit 0 with a malformed list: $(cat err.txt)"
    echo "unit with a malformed list: $(cat err.txt)"
    mv keep_list0 "$list0"
    touch in.npz
    expect_merge "in.npz: changed since the plan"
    "$cook" unit w 2 -q 2> err.txt && fail "unit of a changed input ran"
    grep -q "in.npz: changed since the plan" err.txt || fail "unit: $(cat err.txt)"
    "$cook" plan in.npz "${flags[@]}" --work-dir w --unit-roots 4 || fail "re-plan"
    units_shuffled w 5
    "$cook" merge w -o out.terrain -q || fail "merge after re-plan"
    "$cook" in.npz "${flags[@]}" -o ref.terrain || fail "reference"
    cmp ref.terrain out.terrain || fail "merged archive differs from the one-process cook"
    no_leftovers ;;
  merge_outputs)
    # Issue 48 item 3: merge's outputs against the plan: its input (also through a hard link), a
    # file of the work dir, a VRT's tile; the one-process cook with --work-dir and plan the same
    # way. Each refused with exit 2 and a message naming both, every file byte-identical.
    cp "$dem" in.npz
    ln in.npz link.npz  # before the plan: a new hard link changes the file's ctime
    "$cook" plan in.npz "${flags[@]}" --work-dir w --unit-roots 8 > /dev/null || fail "plan"
    units_shuffled w 1
    expect_refused 2 "^terrain-cook merge: .*-o in.npz: is the same file as input of the plan .*in.npz; refusing to overwrite an input" \
      "$cook" merge w -o in.npz -q
    expect_refused 2 "-o link.npz: is the same file as input of the plan .*/in.npz" "$cook" merge w -o link.npz -q
    expect_refused 2 "--report in.npz: exists and is not a cook report" "$cook" merge w -o out.terrain --report in.npz -q
    expect_refused 2 "--report in.npz: is the same file as input of the plan" \
      "$cook" merge w -o out.terrain --report in.npz --force -q
    expect_refused 2 "-o w/units/unit-0.tcu: is a file of the work dir w" "$cook" merge w -o w/units/unit-0.tcu -q
    expect_refused 2 "-o w/plan.json: is a file of the work dir w" "$cook" merge w -o w/plan.json -q
    expect_refused 2 "-o w/units/../plan.json: is a file of the work dir w" "$cook" merge w -o w/units/../plan.json -q
    expect_refused 2 "-o w/units/unit-1.tcu: is a file of the work dir w" \
      "$cook" in.npz "${flags[@]}" --work-dir w -o w/units/unit-1.tcu
    # unit: its unit file's name taken by a directory is refused before the unit is cooked.
    rm w/units/unit-3.tcu && mkdir w/units/unit-3.tcu
    expect_refused 2 "^terrain-cook unit 3: invalid_argument: unit file w/units/unit-3.tcu: is a directory, not a regular file" \
      "$cook" unit w 3 -q
    rmdir w/units/unit-3.tcu && "$cook" unit w 3 -q || fail "unit 3"
    # plan: an input among the work dir's own files (which plan and unit rewrite or remove).
    cp in.npz w/units/dem.npz
    expect_refused 2 "w/units/dem.npz: an input lies among the files of the work dir w" \
      "$cook" plan w/units/dem.npz "${flags[@]}" --work-dir w
    rm w/units/dem.npz
    "$cook" merge w -o out.terrain -q || fail "the merge after the refusals"
    "$cook" in.npz "${flags[@]}" -o ref.terrain || fail "reference"
    cmp ref.terrain out.terrain || fail "merged archive differs from the one-process cook"
    # A VRT's tiles are inputs of the plan too (GDAL's tools and the shared Kilauea DEM; skipped
    # without them).
    kil="$data/kilauea_utm5n.tif"
    if [ -n "$data" ] && [ -f "$kil" ] && command -v gdalbuildvrt > /dev/null; then
      mkdir tiles
      for t in 0 1; do gdal_translate -q -srcwin $((300 + t * 100)) 300 100 150 "$kil" "tiles/t$t.tif" || fail "tile"; done
      gdalbuildvrt -q mosaic.vrt tiles/t0.tif tiles/t1.tif || fail "gdalbuildvrt"
      "$cook" plan mosaic.vrt -q --heights-only --work-dir wv --unit-roots 1 > /dev/null || fail "plan of the VRT"
      for ((i = 0; i < $(unit_count wv); ++i)); do "$cook" unit wv $i -q --threads 1 || fail "unit $i of the VRT"; done
      expect_refused 2 "-o tiles/t1.tif: is the same file as input of the plan .*tiles/t1.tif" "$cook" merge wv -o tiles/t1.tif -q
      expect_refused 2 "--report tiles/t0.tif: is the same file as input of the plan .*tiles/t0.tif" \
        "$cook" merge wv -o v.terrain --report tiles/t0.tif --force -q
    else
      echo "VRT tiles: skipped (needs gdalbuildvrt and kilauea_utm5n.tif)"
    fi
    no_leftovers ;;

  report_flags)
    # Issue 48 item 10: --report naming a file that is not a cook report (another archive) is
    # refused without --force, by the cook and by the merge; a previous report is replaced; `plan`
    # refuses -o and --report (it writes neither).
    cp "$dem" in.npz
    "$cook" in.npz "${flags[@]}" -o a.terrain --report r.json || fail "first cook"
    expect_refused 2 "^terrain-cook: --report a.terrain: exists and is not a cook report; refusing to replace it \(give --force" \
      "$cook" in.npz "${flags[@]}" -o b.terrain --report a.terrain
    echo "some notes" > notes.txt
    expect_refused 2 "--report notes.txt: exists and is not a cook report" "$cook" in.npz "${flags[@]}" -o b.terrain --report notes.txt
    "$cook" plan in.npz "${flags[@]}" --work-dir w --unit-roots 8 > /dev/null || fail "plan"
    units_shuffled w 1
    expect_refused 2 "^terrain-cook merge: --report a.terrain: exists and is not a cook report" \
      "$cook" merge w -o m.terrain --report a.terrain -q
    expect_refused 2 "^terrain-cook: plan: -o x.terrain: plan writes no archive.*terrain-cook merge w2 -o ARCHIVE" \
      "$cook" plan in.npz "${flags[@]}" --work-dir w2 -o x.terrain
    expect_refused 2 "^terrain-cook: plan: --report x.json: plan writes no cook report" \
      "$cook" plan in.npz "${flags[@]}" --work-dir w2 --report x.json
    [ ! -e w2 ] || fail "a refused plan made its work dir"
    # A previous report is replaced (the merge's too); --force replaces any regular file.
    "$cook" in.npz "${flags[@]}" -o b.terrain --report r.json || fail "a cook replacing its previous report"
    "$cook" merge w -o m.terrain --report r.json -q || fail "a merge replacing a previous report"
    cmp a.terrain b.terrain && cmp a.terrain m.terrain || fail "archives differ"
    python3 -c "import json,sys; json.load(open(sys.argv[1]))['levels']" r.json || fail "r.json is not a report"
    cp notes.txt keep.txt
    "$cook" merge w -o m2.terrain --report notes.txt --force -q || fail "merge --force"
    ! cmp -s notes.txt keep.txt || fail "--force did not replace notes.txt"
    "$cook" in.npz "${flags[@]}" -o b2.terrain --report a.terrain --force || fail "cook --force"
    python3 -c "import json,sys; json.load(open(sys.argv[1]))['levels']" a.terrain || fail "a.terrain is not the report"
    no_leftovers ;;

  stale_same_size_mtime)
    # Issue 48 item 4: an input replaced by one of the same size and mtime and other heights (cp -p
    # of a file given the old mtime with touch -r): the unit re-run and the merge refuse, naming the
    # file, and every file stays as it was; a new plan then merges to the new inputs' bytes.
    cp "$dem" orig.npz
    npz_plus orig.npz in.npz 0
    npz_plus orig.npz new.npz 7
    [ "$(stat -c %s in.npz)" = "$(stat -c %s new.npz)" ] || fail "the two inputs differ in size"
    cmp -s in.npz new.npz && fail "the two inputs are the same"
    "$cook" plan in.npz "${flags[@]}" --work-dir w --unit-roots 4 > /dev/null || fail "plan"
    units_shuffled w 1
    "$cook" merge w -o old.terrain -q || fail "merge"
    touch -r in.npz new.npz
    cp -p new.npz in.npz
    [ "$(stat -c %s:%Y in.npz)" = "$(stat -c %s:%Y new.npz)" ] && cmp -s in.npz new.npz || fail "cp -p"
    rm w/units/unit-1.tcu
    expect_refused 1 "^terrain-cook unit 1: .*/in.npz: changed since the plan \(ctime .*rewritten or replaced keeping size and mtime" \
      "$cook" unit w 1 -q
    expect_refused 1 "^terrain-cook merge: .*/in.npz: changed since the plan \(ctime" "$cook" merge w -o stale.terrain -q
    # The same input rewritten in place with its old mtime and size (no new inode).
    touch -r in.npz t.ref
    npz_plus orig.npz in2.npz 3 && cat in2.npz > in.npz && touch -r t.ref in.npz
    expect_refused 1 "/in.npz: changed since the plan \(ctime" "$cook" merge w -o stale.terrain -q
    cp -p new.npz in.npz
    "$cook" plan in.npz --crs EPSG:4326 --heights-only --work-dir w --unit-roots 4 > plan.txt || fail "re-plan"
    grep -q "in.npz: changed" plan.txt || fail "the re-plan does not name the changed input: $(cat plan.txt)"
    units_shuffled w 2
    "$cook" merge w -o new.terrain -q || fail "merge after the re-plan"
    "$cook" in.npz "${flags[@]}" -o ref.terrain || fail "reference"
    cmp ref.terrain new.terrain || fail "merged archive differs from the one-process cook of the new input"
    ! cmp -s old.terrain new.terrain || fail "the new heights did not reach the archive"
    no_leftovers ;;

  edge_disagreement)
    # Issue 48 item 4: units whose fingerprints match but whose heights along a shared edge differ
    # (a unit of the same plan cooked from other heights, its fingerprint set to the plan's as a
    # change no fingerprint shows would leave it) are refused by the merge, naming the nodes, and
    # nothing is written.
    mkdir a b
    npz_plus "$dem" a/in.npz 0
    npz_plus "$dem" b/in.npz 4
    (cd a && "$cook" plan in.npz "${flags[@]}" --work-dir ../w --unit-roots 4 > /dev/null) || fail "plan a"
    (cd b && "$cook" plan in.npz "${flags[@]}" --work-dir ../wb --unit-roots 4 > /dev/null) || fail "plan b"
    units_shuffled w 1
    units_shuffled wb 1
    "$cook" merge w -o good.terrain -q || fail "merge of a"
    python3 - w wb <<'PY' || fail "forging"
import json, sys, zlib
a, b = (json.load(open(f"{d}/plan.json")) for d in sys.argv[1:3])
assert a["fingerprint"] == b["fingerprint"], "the plans differ in their global decisions"
fp = a["units"][5]["fingerprint"]
assert fp != b["units"][5]["fingerprint"]
data = bytearray(open("wb/units/unit-5.tcu", "rb").read())
data[32:48] = fp.encode()
data[-8:-4] = (zlib.crc32(bytes(data[:-8])) & 0xffffffff).to_bytes(4, "little")
open("w/units/unit-5.tcu", "wb").write(data)
print(f"unit 5 of wb (heights + 4 m) put in w with w's unit fingerprint {fp}")
PY
    expect_refused 1 "^terrain-cook merge: no_data: unit [0-9]+ .*node [0-9]+/[0-9]+/[0-9]+ vertex .* units but its (west|south) neighbour .* \(another unit\) stores .*the units disagree along their shared edge" \
      "$cook" merge w -o out.terrain -q
    no_leftovers ;;

  relative_paths)
    # Issue 48 item 5: a plan of relative input paths, its units and merge run from another working
    # directory (as a scheduler's jobs are): the inputs are opened by the absolute paths the plan
    # resolved, the cook info keeps the paths as typed, and the archive is the one-process cook's.
    mkdir d1 d2
    cp "$dem" d1/in.npz
    (cd d1 && "$cook" in.npz "${flags[@]}" -o ../ref.terrain) || fail "reference"
    (cd d1 && "$cook" plan in.npz "${flags[@]}" --work-dir ../w --unit-roots 4 > /dev/null) || fail "plan"
    n=$(unit_count w)
    for ((i = 0; i < n; ++i)); do (cd d2 && "$cook" unit ../w $i -q --threads 1) || fail "unit $i from d2"; done
    (cd d2 && "$cook" merge ../w -o ../m.terrain -q) || fail "merge from d2"
    cmp ref.terrain m.terrain || fail "merged from another directory: not the one-process bytes"
    python3 - "$(pwd -P)" <<'PY' || fail "paths in the plan"
import json, sys
p = json.load(open("w/plan.json"))
assert p["options"]["inputs"] == ["in.npz"], p["options"]["inputs"]
assert p["resolved_paths"]["inputs"] == [sys.argv[1] + "/d1/in.npz"], p["resolved_paths"]
files = json.load(open(f"w/inputs-{p['inputs']['fingerprint']}.json"))["files"]
assert [f["path"] for f in files] == [sys.argv[1] + "/d1/in.npz"], files
print("plan: typed", p["options"]["inputs"], "opened", p["resolved_paths"]["inputs"])
PY
    # The one-process cook with --work-dir from another directory does not resume a plan whose
    # relative paths named other files: it plans again.
    mkdir d3 && npz_plus "$dem" d3/in.npz 5
    (cd d3 && "$cook" in.npz "${flags[@]}" --work-dir ../w --unit-roots 4 -o ../m3.terrain) || fail "cook from d3"
    (cd d3 && "$cook" in.npz "${flags[@]}" -o ../ref3.terrain) || fail "reference d3"
    cmp ref3.terrain m3.terrain || fail "--work-dir from d3 resumed the plan of d1's file"
    no_leftovers ;;
  *) fail "unknown case" ;;
esac
echo "ok ($case_name)"
