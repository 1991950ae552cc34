#!/usr/bin/env bash
# Issue 48: an archive cut to half its size while terrain-stream-bench and terrain-query-bench read
# it, 20 times each, at delays spread over the run. Every run must end by itself, without a signal
# (the mapped reader died of SIGBUS, exit 135, no message), with exit 1 and a message naming the
# truncation. Runs cut while loading must count their failed loads in the output; at least a
# quarter of each benchmark's runs must be such runs, or the test checked too little.
# Usage: truncate_while_reading.sh STREAM_BENCH QUERY_BENCH ARCHIVE WORK_DIR
set -uo pipefail
[ $# -eq 4 ] || { echo "usage: $0 STREAM_BENCH QUERY_BENCH ARCHIVE WORK_DIR" >&2; exit 2; }
stream_bench=$1 query_bench=$2 archive=$3 work=$4
rm -rf "$work"
mkdir -p "$work"
size=$(stat -c %s "$archive")
half=$((size / 2))
fail() { echo "truncate_while_reading: $*" >&2; exit 1; }

# run NAME DELAY_S CMD...: copies the archive, starts CMD on the copy, cuts the copy to half after
# DELAY_S and waits. Sets rc, out (stdout + stderr), and cut_while_running (1 when the process was
# still running at the cut).
run() {
  local name=$1 delay=$2
  shift 2
  cp "$archive" "$work/copy.terrain"
  "$@" >"$work/$name.out" 2>&1 &
  local pid=$!
  sleep "$delay"
  cut_while_running=0
  if kill -0 "$pid" 2>/dev/null; then cut_while_running=1; fi
  truncate -s "$half" "$work/copy.terrain"
  wait "$pid"
  rc=$?
  out=$(cat "$work/$name.out")
}

check_bench() {
  local name=$1 counted_regex=$2
  shift 2
  local counted=0 runs=0 late=0
  for i in $(seq 1 20); do
    # Delays 0.05 .. 2.0 s: from inside open() and the first loads to the last queries.
    local delay
    delay=$(awk -v i="$i" 'BEGIN { printf "%.2f", 0.1 * i - 0.05 }')
    run "$name-$i" "$delay" "$@"
    [ "$rc" -lt 128 ] || fail "$name run $i (cut after ${delay}s): killed by signal $((rc - 128)), output: $(tail -n 3 <<<"$out")"
    if [ "$cut_while_running" = 0 ]; then
      late=$((late + 1))  # it had finished on an intact file: nothing to check
      continue
    fi
    runs=$((runs + 1))
    [ "$rc" -eq 1 ] || fail "$name run $i (cut after ${delay}s): exit $rc, expected 1; output: $(tail -n 5 <<<"$out")"
    grep -Eq 'truncated|short read' <<<"$out" ||
      fail "$name run $i (cut after ${delay}s): exit 1 without a message naming the truncation: $(tail -n 5 <<<"$out")"
    if grep -Eq "$counted_regex" <<<"$out"; then counted=$((counted + 1)); fi
  done
  echo "$name: $runs runs cut while running ($late finished first), $counted of them counted failed loads"
  [ "$counted" -ge 5 ] || fail "$name: only $counted of 20 runs were cut while loading and counted failed loads (need 5)"
}

check_bench stream '[1-9][0-9]* node loads failed' \
  "$stream_bench" "$work/copy.terrain" --seconds 1 --teleports 4 --quiet
check_bench query '[1-9][0-9]* streamer node loads and [0-9]+ archive reads failed|[0-9]+ streamer node loads and [1-9][0-9]* archive reads failed' \
  "$query_bench" "$work/copy.terrain" --runs 1
echo "truncate_while_reading: ok"
