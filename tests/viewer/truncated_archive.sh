#!/usr/bin/env bash
# Issue 48: terrain-view --headless on an archive cut to half its size while it streams. The mapped
# reader died of SIGBUS (exit 135, no message); now the lost nodes fail by name ("truncated ...
# short read"), their parents are drawn, and the run exits 1 saying how many nodes failed. A cut
# before the archive opened is the same error at open (exit 1, "truncated"). Delays grow until a
# run is cut while streaming (a 0.06 px error target and 4 deliveries per frame keep the Jacksboro
# children streaming along the path); every run must end without a signal.
# Usage: truncated_archive.sh TERRAIN_VIEW ARCHIVE CAMERA_PATH WORK_DIR
set -uo pipefail
[ $# -eq 4 ] || { echo "usage: $0 TERRAIN_VIEW ARCHIVE CAMERA_PATH WORK_DIR" >&2; exit 2; }
view=$1 archive=$2 path=$3 work=$4
fail() { echo "truncated_archive: $*" >&2; exit 1; }
rm -rf "$work"
mkdir -p "$work"
half=$(($(stat -c %s "$archive") / 2))
streamed=0
for delay in 0.2 0.5 1 1.5 2 3 4 6; do
  cp "$archive" "$work/copy.terrain"
  "$view" "$work/copy.terrain" --headless --size 320x180 --frames 40 --error 0.06 --deliveries 4 --path "$path" \
    --stats "$work/stats.json" >"$work/out" 2>&1 &
  pid=$!
  sleep "$delay"
  alive=0
  if kill -0 "$pid" 2>/dev/null; then alive=1; fi
  truncate -s "$half" "$work/copy.terrain"
  wait "$pid"
  rc=$?
  out=$(cat "$work/out")
  if grep -q "no Vulkan device" <<<"$out"; then echo "no Vulkan device: skipped"; exit 0; fi
  echo "cut after ${delay}s: exit $rc$([ $alive = 1 ] || echo ', finished before the cut')"
  [ "$rc" -lt 128 ] || fail "killed by signal $((rc - 128)): $(tail -n 3 <<<"$out")"
  [ "$alive" = 1 ] || continue
  [ "$rc" -eq 1 ] || fail "exit $rc, expected 1: $(tail -n 5 <<<"$out")"
  grep -Eq 'truncated' <<<"$out" || fail "no message naming the truncation: $(tail -n 5 <<<"$out")"
  if grep -Eq 'failed to load: .*short read' <<<"$out"; then
    grep -Eq 'terrain-view: [1-9][0-9]* nodes failed to load' <<<"$out" || fail "no count of the failed nodes"
    streamed=1
    break
  fi
done
[ "$streamed" = 1 ] || fail "no run was cut while streaming (all were cut at open or finished first)"
echo "truncated_archive: ok"
