#!/usr/bin/env bash
# What each input gives the cook (issue 48 item 8): input_samples_cli.sh CASE BIN_DIR SCRATCH_PARENT DATA_DIR.
# A 200 m cut of the Slovenian 1 m lidar DTM and a 10 m copy of it (gdalwarp -r average) covering
# the same square. By default (--overlap finer) the 1 m input wins in either order and both orders
# give the same archive; with --overlap list the input listed second contributes nothing (or under
# 1 %). Such an input is named in a warning on stderr and in the report; the report's input_samples
# give, per input in the order of precedence, the samples read and used on the mosaic's grid, the
# used ones adding up to source.valid_samples.
set -u
case_name=$1 bin=$2 work=$3/input-samples-cli-$1 data=$4
src=$data/slovenia_TM1_564_146.tif
[ -f "$src" ] || { echo "SKIP: $src absent (set TERRAIN_DATA_DIR)"; exit 0; }
command -v gdalwarp >/dev/null && command -v jq >/dev/null || { echo "SKIP: gdalwarp or jq absent"; exit 0; }
rm -rf "$work"; mkdir -p "$work"; cd "$work" || exit 1
gdal_translate -q -srcwin 300 300 200 200 "$src" fine.tif || { echo "FAIL: gdal_translate"; exit 1; }
gdalwarp -q -tr 10 10 -r average fine.tif coarse.tif || { echo "FAIL: gdalwarp"; exit 1; }
cook() {  # cook REPORT INPUTS...: stderr into err.txt, exit code checked
  local report=$1; shift
  "$bin/terrain-cook" "$@" -o out.terrain --report "$report" --heights-only 2>err.txt
  local rc=$?
  [ $rc = 0 ] || { echo "FAIL: terrain-cook $* exit $rc: $(cat err.txt)"; exit 1; }
}
# field REPORT INDEX NAME
field() { jq -r ".input_samples[$2].$3" "$1"; }
check_sum() {  # the used samples of every input add up to the mosaic's valid samples
  local sum valid
  sum=$(jq '[.input_samples[].samples_used] | add' "$1") valid=$(jq '.source.valid_samples' "$1")
  [ "$sum" = "$valid" ] || { echo "FAIL: used samples add up to $sum, valid samples $valid"; exit 1; }
}
case $case_name in
  fine_first)
    cook fine_first.json fine.tif coarse.tif
    [ "$(field fine_first.json 0 path)" = fine.tif ] || { echo "FAIL: first input path"; exit 1; }
    [ "$(field fine_first.json 0 samples_read)" = 40000 ] || { echo "FAIL: fine read $(field fine_first.json 0 samples_read)"; exit 1; }
    [ "$(field fine_first.json 0 samples_used)" = 40000 ] || { echo "FAIL: fine used $(field fine_first.json 0 samples_used)"; exit 1; }
    read1=$(field fine_first.json 1 samples_read) used1=$(field fine_first.json 1 samples_used)
    [ "$read1" -gt 30000 ] || { echo "FAIL: coarse read $read1 samples on the 1 m grid"; exit 1; }
    [ $((used1 * 100)) -lt "$read1" ] || { echo "FAIL: coarse used $used1 of $read1"; exit 1; }
    check_sum fine_first.json
    grep -Eq "terrain-cook: warning: coarse\.tif: contributes (nothing|only $used1 of its $read1 samples)" err.txt ||
      { echo "FAIL: no warning for coarse.tif: $(cat err.txt)"; exit 1; }
    grep -q "fine\.tif: contributes" err.txt && { echo "FAIL: fine.tif named: $(cat err.txt)"; exit 1; }
    jq -e '.warnings | map(select(startswith("coarse.tif: contributes"))) | length == 1' fine_first.json >/dev/null ||
      { echo "FAIL: the report's warnings"; exit 1; }
    echo "ok: fine first: fine 40000 of 40000, coarse $used1 of $read1" ;;
  finer_wins)
    # Listed second, the 1 m input still wins (issue 51) and sets the grid: the archive of the other order.
    cook fine_first.json fine.tif coarse.tif
    mv out.terrain fine_first.terrain
    cook coarse_listed_first.json coarse.tif fine.tif
    cmp -s out.terrain fine_first.terrain || { echo "FAIL: the two orders give different archives"; exit 1; }
    [ "$(jq -c .input_samples coarse_listed_first.json)" = "$(jq -c .input_samples fine_first.json)" ] ||
      { echo "FAIL: input_samples $(jq -c .input_samples coarse_listed_first.json) vs $(jq -c .input_samples fine_first.json)"; exit 1; }
    [ "$(field coarse_listed_first.json 0 path)" = fine.tif ] && [ "$(field coarse_listed_first.json 0 samples_used)" = 40000 ] ||
      { echo "FAIL: fine.tif does not take precedence: $(jq -c .input_samples coarse_listed_first.json)"; exit 1; }
    grep -q "terrain-cook: warning: coarse\.tif: contributes" err.txt || { echo "FAIL: no warning for coarse.tif: $(cat err.txt)"; exit 1; }
    grep -q "the finer wins" err.txt || { echo "FAIL: the warning does not state the rule: $(cat err.txt)"; exit 1; }
    # Per input: its grid family, spacing, tolerance (1/32 of its spacing, at least 0.5 m), area
    # owned (its used samples of 1 m2) and the finest level it reached.
    jq -e '.input_samples[0] | .family == 0 and .spacing_m == 1 and .tolerance_m == 0.5 and (.area_km2 * 1e6 | round) == 40000' \
      coarse_listed_first.json >/dev/null || { echo "FAIL: fine.tif's entry $(jq -c '.input_samples[0]' coarse_listed_first.json)"; exit 1; }
    jq -e '.input_samples[1] | .family == 1 and .spacing_m == 10 and .tolerance_m == 0.5' coarse_listed_first.json >/dev/null ||
      { echo "FAIL: coarse.tif's entry $(jq -c '.input_samples[1]' coarse_listed_first.json)"; exit 1; }
    jq -e '.input_samples[0].finest_level >= 0 and .input_samples[0].finest_level <= 5' coarse_listed_first.json >/dev/null ||
      { echo "FAIL: fine.tif's finest level $(jq -c '.input_samples[0]' coarse_listed_first.json)"; exit 1; }
    echo "ok: coarse listed first, fine wins: $(jq -c .input_samples coarse_listed_first.json), same archive" ;;
  coarse_first)
    cook coarse_first.json coarse.tif fine.tif --overlap list
    [ "$(field coarse_first.json 0 samples_read)" = 400 ] || { echo "FAIL: coarse read $(field coarse_first.json 0 samples_read)"; exit 1; }
    [ "$(field coarse_first.json 0 samples_used)" = 400 ] || { echo "FAIL: coarse used"; exit 1; }
    read1=$(field coarse_first.json 1 samples_read) used1=$(field coarse_first.json 1 samples_used)
    [ "$read1" -gt 300 ] && [ "$used1" = 0 ] || { echo "FAIL: fine used $used1 of $read1"; exit 1; }
    check_sum coarse_first.json
    grep -q "terrain-cook: warning: fine\.tif: contributes nothing to the archive: inputs that take precedence have a height at each of its $read1 samples on the mosaic's grid (--overlap list" err.txt ||
      { echo "FAIL: no warning for fine.tif: $(cat err.txt)"; exit 1; }
    jq -e '.warnings | map(select(startswith("fine.tif: contributes nothing"))) | length == 1' coarse_first.json >/dev/null ||
      { echo "FAIL: the report's warnings"; exit 1; }
    echo "ok: coarse first: fine $used1 of $read1" ;;
  work_dir)
    # Through a plan and its work units: the plan records what each input gave; the merged report
    # says the same as the one-process cook's, warning included.
    cook one.json coarse.tif fine.tif --overlap list
    cook units.json coarse.tif fine.tif --overlap list --work-dir W
    [ "$(jq -c .input_samples one.json)" = "$(jq -c .input_samples units.json)" ] ||
      { echo "FAIL: one process $(jq -c .input_samples one.json), units $(jq -c .input_samples units.json)"; exit 1; }
    grep -q "warning: fine\.tif: contributes nothing" err.txt || { echo "FAIL: no warning through the units: $(cat err.txt)"; exit 1; }
    jq -e '.warnings | map(select(startswith("fine.tif: contributes nothing"))) | length == 1' units.json >/dev/null ||
      { echo "FAIL: the merged report's warnings"; exit 1; }
    echo "ok: work units: $(jq -c .input_samples units.json)" ;;
  single)
    cook single.json fine.tif
    [ "$(field single.json 0 samples_read)" = 40000 ] && [ "$(field single.json 0 samples_used)" = 40000 ] ||
      { echo "FAIL: single input $(jq -c .input_samples single.json)"; exit 1; }
    check_sum single.json
    grep -q "contributes" err.txt && { echo "FAIL: warned: $(cat err.txt)"; exit 1; }
    echo "ok: one input, no warning" ;;
  *) echo "FAIL: unknown case $case_name"; exit 1 ;;
esac
