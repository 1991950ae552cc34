#!/usr/bin/env bash
# Issue 48: terrain-stream-bench and terrain-query-bench on an archive whose non-root payloads fail
# their CRC-32 (one byte flipped in the middle of each) printed their normal tables and exited 0.
# Now each counts the failed loads in its output, names the first on stderr and exits 1; the
# archive is byte-identical afterwards.
# Usage: bench_failed_loads.sh STREAM_BENCH QUERY_BENCH ARCHIVE WORK_DIR
set -uo pipefail
[ $# -eq 4 ] || { echo "usage: $0 STREAM_BENCH QUERY_BENCH ARCHIVE WORK_DIR" >&2; exit 2; }
stream_bench=$1 query_bench=$2 archive=$3 work=$4
fail() { echo "bench_failed_loads: $*" >&2; exit 1; }
rm -rf "$work"
mkdir -p "$work"
bad="$work/crc.terrain"
# The directory (header fields at 48 and 20; 48-byte entries: level at 0, payload offset u64 at 32,
# size u32 at 40, format/SPEC.md section 8): flip a byte in every payload below the top level.
flipped=$(python3 - "$archive" "$bad" <<'PY'
import struct, sys
d = bytearray(open(sys.argv[1], 'rb').read())
count, = struct.unpack_from('<I', d, 20)
directory, = struct.unpack_from('<Q', d, 48)
entries = [(d[directory + 48 * i], *struct.unpack_from('<QI', d, directory + 48 * i + 32)) for i in range(count)]
top = max(e[0] for e in entries)
n = 0
for level, offset, size in entries:
    if level < top:
        d[offset + size // 2] ^= 0x5A
        n += 1
open(sys.argv[2], 'wb').write(d)
print(n)
PY
) || fail "could not write $bad"
[ "$flipped" -gt 0 ] || fail "the archive has no node below its top level"
before=$(sha256sum "$archive" "$bad")

"$stream_bench" "$bad" --seconds 1 --teleports 4 --quiet >"$work/stream.out" 2>"$work/stream.err"
rc=$?
cat "$work/stream.out" "$work/stream.err"
[ "$rc" -eq 1 ] || fail "terrain-stream-bench: exit $rc, expected 1"
grep -Eq "node loads failed \(first: payload_checksum: node [0-9]+/[0-9]+/[0-9]+" "$work/stream.err" ||
  fail "terrain-stream-bench: no message naming the failed loads"
# The table's last column counts each loader's failures: the teleports failed some in both.
for loader in streamer naive; do
  grep -Eq "^teleport +$loader .* [1-9][0-9]*$" "$work/stream.out" ||
    fail "terrain-stream-bench: the $loader teleport row counts no failed loads"
done

"$query_bench" "$bad" --runs 1 >"$work/query.out" 2>"$work/query.err"
rc=$?
cat "$work/query.out" "$work/query.err"
[ "$rc" -eq 1 ] || fail "terrain-query-bench: exit $rc, expected 1"
grep -Eq "^failed loads: [1-9][0-9]* streamer node loads" "$work/query.out" ||
  fail "terrain-query-bench: the output counts no failed streamer loads"
grep -Eq "payload_checksum: node [0-9]+/[0-9]+/[0-9]+" "$work/query.err" ||
  fail "terrain-query-bench: no message naming a failed load"

[ "$(sha256sum "$archive" "$bad")" = "$before" ] || fail "an archive changed"
echo "bench_failed_loads: ok ($flipped payloads damaged)"
