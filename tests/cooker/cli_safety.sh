#!/usr/bin/env bash
# CLI safety cases of issue 11: cli_safety.sh CASE BIN_DIR SCRATCH_PARENT. Each case checks the exit
# code, the message, and that every file present before the command is byte-identical after it.
set -u
here=$(cd "$(dirname "$0")" && pwd)
case_name=$1 bin=$2 work=$3/cli-safety-$1
dem=/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz
[ -f "$dem" ] || { echo "SKIP: $dem absent"; exit 0; }
rm -rf "$work"; mkdir -p "$work"; cd "$work" || exit 1
cp "$dem" in.npz
# old.json: the setup cook's report (a previous report is what --report may replace without --force).
"$bin/terrain-cook" in.npz --crs EPSG:4326 -q -o keep.terrain --report old.json || { echo "FAIL: setup cook"; exit 1; }
mknod null c 1 3 2>/dev/null || { echo "SKIP: mknod needs root"; exit 0; }
mkfifo fifo; mkdir dir
snapshot() { find . -type f -print0 | sort -z | xargs -0 sha256sum; ls -l null fifo | cut -c1; }
before=$(snapshot)
. "$here/cli_expect.sh"
expect() { expect_exit "$before" "$@"; }  # expect RC REGEX command... (against the files at the start)
cook=("$bin/terrain-cook" in.npz --crs EPSG:4326 -q)
case $case_name in
  output_device) expect 2 "character device" "${cook[@]}" -o null ;;
  output_fifo) expect 2 "FIFO" "${cook[@]}" -o fifo ;;
  output_directory) expect 2 "directory" "${cook[@]}" -o dir ;;
  output_is_input) expect 2 "same file as input" "${cook[@]}" -o in.npz ;;
  report_is_archive) expect 2 "same file as -o" "${cook[@]}" -o keep.terrain --report keep.terrain ;;
  report_is_input) expect 2 "same file as input" "${cook[@]}" -o keep.terrain --report in.npz ;;
  report_missing_dir) expect 2 "does not exist" "${cook[@]}" -o keep.terrain --report missing/r.json ;;
  input_fifo) expect 1 "not a regular file \(FIFO\)" "$bin/terrain-cook" fifo -q -o x.terrain ;;
  input_directory) expect 1 "a directory with no raster files in it" "$bin/terrain-cook" dir -q -o x.terrain ;;
  input_device) expect 1 "not a regular file \(character device\)" "$bin/terrain-cook" null -q -o x.terrain ;;
  origin_huge) expect 2 "within \+-1e8" "${cook[@]}" -o x.terrain --origin 1e300,0 --spacing 1 ;;
  origin_nan) expect 2 "--origin" "${cook[@]}" -o x.terrain --origin nan,0 --spacing 1 ;;
  tolerance_short) expect 2 "must be > 0 and <= 10000, got -1" "${cook[@]}" -o x.terrain --tolerance -1 ;;
  threads_range) expect 2 "must be an integer 0..1024" "${cook[@]}" -o x.terrain --threads 100000 ;;
  nodata_nan) expect 2 "NaN samples are always nodata" "${cook[@]}" -o x.terrain --nodata-value nan ;;
  inspect_fifo) expect 1 "not a regular file \(FIFO\)" "$bin/terrain-inspect" fifo ;;
  inspect_export_file) expect 2 "not a directory" "$bin/terrain-inspect" keep.terrain --export 5/0/0 old.json ;;
  inspect_json_one_doc)
    out=$("$bin/terrain-inspect" keep.terrain --json --verify -q --sample 0,0) || { echo "FAIL: rc"; exit 1; }
    echo "$out" | python3 -c 'import json,sys; d=json.load(sys.stdin); assert d["valid"] and len(d["samples"])==1' ||
      { echo "FAIL: not one JSON document: $out"; exit 1; }
    echo "ok: one document" ;;
  report_committed)  # a successful cook replaces archive and report together, nothing staged left
    cp old.json previous.json
    "${cook[@]}" -o keep.terrain --report old.json || { echo "FAIL: cook"; exit 1; }
    ! cmp -s old.json previous.json || { echo "FAIL: the previous report was not replaced"; exit 1; }
    grep -q '"levels"' old.json || { echo "FAIL: report not written"; exit 1; }
    ls | grep -q 'tmp-' && { echo "FAIL: temp left"; exit 1; }
    echo "ok: committed" ;;
  signal)
    for sig in TERM INT; do
      "$bin/terrain-cook" in.npz --crs EPSG:4326 -q --tolerance 0.01 --finest-level 0 -o keep.terrain --report old.json &
      # Signal once the staged archive exists: the cook is under way and its handler installed (a fixed
      # sleep raced a loaded machine, and a background job of a script starts with SIGINT ignored).
      pid=$!
      for _ in $(seq 600); do ls | grep -q 'tmp-' && break; kill -0 $pid 2>/dev/null || break; sleep 0.1; done
      kill -$sig $pid; wait $pid; rc=$?
      [ "$rc" != 0 ] || { echo "FAIL: SIG$sig: cook finished before the signal (rc 0)"; exit 1; }
      ls | grep -q 'tmp-' && { echo "FAIL: SIG$sig left $(ls | grep tmp-)"; exit 1; }
      [ "$(snapshot)" = "$before" ] || { echo "FAIL: SIG$sig changed files"; exit 1; }
      echo "ok: SIG$sig -> $rc, no temp files, files unchanged"
    done
    # SIGKILL cannot be handled: the staged files stay, the targets are untouched, and the next
    # cook of the same targets removes what the killed one left.
    "$bin/terrain-cook" in.npz --crs EPSG:4326 -q --tolerance 0.01 --finest-level 0 -o keep.terrain --report old.json &
    pid=$!
    for _ in $(seq 600); do ls | grep -q 'tmp-' && break; kill -0 $pid 2>/dev/null || break; sleep 0.1; done
    kill -KILL $pid; wait $pid
    left=$(ls | grep 'tmp-')
    [ -n "$left" ] || { echo "FAIL: SIGKILL: no staged file to clear (the cook ended first?)"; exit 1; }
    [ "$(snapshot | grep -v tmp-)" = "$before" ] || { echo "FAIL: SIGKILL changed files"; exit 1; }
    "$bin/terrain-cook" in.npz --crs EPSG:4326 -q -o keep.terrain --report old.json || { echo "FAIL: cook after SIGKILL"; exit 1; }
    ls | grep -q 'tmp-' && { echo "FAIL: the cook after SIGKILL left $(ls | grep tmp-)"; exit 1; }
    echo "ok: SIGKILL left $(echo $left), the next cook removed it" ;;
  view_flags)
    for a in "--error 0" "--budget 0" "--threads 1000"; do
      expect 2 "must be" "$bin/terrain-view" keep.terrain --headless --out x.png $a
    done ;;
  view_fifo) VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json expect 1 "not a regular file \(FIFO\)" "$bin/terrain-view" fifo --headless --out x.png ;;
  view_budget)  # Jacksboro cooks to 16 x 16 roots, always resident: the message names the flag and the value
    VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json \
      expect 2 "--budget 100 is smaller than the archive's 256 roots.*use --budget 256" \
      "$bin/terrain-view" keep.terrain --headless --out x.png --budget 100 ;;
  view_outputs)  # --out / --stats never replace the archive, the camera path or a device
    export VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
    expect 2 "same file as" "$bin/terrain-view" keep.terrain --headless --out keep.terrain
    expect 2 "same file as" "$bin/terrain-view" keep.terrain --headless --stats old.json --out old.json
    expect 2 "character device" "$bin/terrain-view" keep.terrain --headless --stats null ;;
  view_too_many_roots)  # 65 x 65 samples 1500 m apart span 96 km: 47 x 47 = 2209 roots, no overview levels, more than
    # the old traversal list (2048, refused before): default settings raise the budget and draw every root
    head -c 8450 /dev/zero > wide.r16
    "$bin/terrain-cook" wide.r16 --raw-size 65x65 --spacing 1500 --crs local --heights-only --overview-levels off -q -o wide.terrain \
      || { echo "FAIL: wide cook"; exit 1; }
    VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json timeout 360 \
      "$bin/terrain-view" wide.terrain --headless --out wide.png --size 320x180 --stats wide.json -q \
      || { echo "FAIL: terrain-view did not draw the 2209-root archive"; exit 1; }
    [ -s wide.png ] || { echo "FAIL: no image"; exit 1; }
    grep -q '"nodes": 2209,' wide.json || { echo "FAIL: not every root drawn: $(grep '"nodes"' wide.json | tail -1)"; exit 1; }
    grep -q '"traversal_overflow": [1-9]' wide.json && { echo "FAIL: traversal overflow"; exit 1; }
    echo "ok: 2209 roots drawn with default settings" ;;
  summary_counts)  # item 19: the summary says what its error count counts (138 632 samples, more measurements)
    out=$("$bin/terrain-cook" in.npz --crs EPSG:4326 -o summary.terrain --threads 1)
    [[ "$out" =~ over\ ([0-9]+)\ sample\ measurements\ \(each\ valid\ source\ sample\ against\ every\ finest\ node ]] \
      || { echo "FAIL: summary does not say what it counts: $out"; exit 1; }
    [[ "$out" =~ 138632\ source\ samples ]] || { echo "FAIL: source sample count missing: $out"; exit 1; }
    echo "ok: ${BASH_REMATCH[0]}" ;;
  work_bound)  # 64 x 64 samples at 100 km: 9.5 M roots, refused in well under a second
    head -c 8192 /dev/zero > coarse.r16; before=$(snapshot)
    expect 1 "3077 x 3077 root nodes.*--force" "$bin/terrain-cook" coarse.r16 --raw-size 64x64 --spacing 100000 --crs local -q -o x.terrain ;;
  side_bound)  # 17 x 2 samples spanning 65536 roots of 2048 m and 16 m: one root past the 65536 per side
    # of format and streamer, refused with --force too (the plan-size test checks the bound itself)
    head -c 68 /dev/zero > strip.r16; before=$(snapshot)
    expect 1 "65537 x 1 root nodes.*beyond 65536 per side" "$bin/terrain-cook" strip.r16 --raw-size 17x2 \
      --spacing 8388609,1000 --crs local --force -q -o x.terrain ;;
  *) echo "unknown case $case_name"; exit 1 ;;
esac
cd .. && rm -rf "$work"
