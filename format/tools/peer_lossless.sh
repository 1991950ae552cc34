#!/usr/bin/env bash
# JPEG-XL lossless (cjxl, Debian libjxl-tools) on the tiles that `terrain-format-bench --dump-pgm DIR`
# wrote: encodes every DIR/<dataset>/NNNNN.pgm, decodes it back with djxl and compares it byte for byte
# with the input (a tile that does not round-trip fails the run), sums the .jxl bytes per dataset and
# prints them next to the bench's own byte counts (DIR/<dataset>/bench_bytes.tsv: zstd -19, predictor,
# JPEG-LS). Bytes only: JPEG-XL decode speed is not measured here.
#
# Usage: peer_lossless.sh [-j JOBS] DIR [cjxl options...]   (default options: -d 0 -e 9)
# Exit codes: 0 ok, 1 failure (tool missing, encode/decode error, mismatch), 2 usage error.
set -euo pipefail

usage() {
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
}
jobs=2
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    -j) [ $# -ge 2 ] || { echo "peer_lossless.sh: -j needs a number" >&2; exit 2; }; jobs="$2"; shift 2 ;;
    *) break ;;
  esac
done
[ $# -ge 1 ] || { usage >&2; exit 2; }
dir="$1"
shift
[ -d "$dir" ] || { echo "peer_lossless.sh: $dir is not a folder (write it with terrain-format-bench --dump-pgm)" >&2; exit 2; }
[[ "$jobs" =~ ^[1-9][0-9]*$ ]] || { echo "peer_lossless.sh: -j wants a positive number, got '$jobs'" >&2; exit 2; }
opts=("$@")
[ ${#opts[@]} -gt 0 ] || opts=(-d 0 -e 9)
for tool in cjxl djxl; do
  command -v "$tool" >/dev/null || { echo "peer_lossless.sh: $tool not found (apt-get install libjxl-tools)" >&2; exit 1; }
done

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# One tile: encode, decode, compare; prints "<bytes>" on success.
encode_one() {
  local pgm="$1" out="$2"
  shift 2
  cjxl "$@" --num_threads=1 --quiet "$pgm" "$out.jxl" >/dev/null 2>"$out.err" || { echo "cjxl failed on $pgm: $(cat "$out.err")" >&2; return 1; }
  djxl --num_threads=1 --quiet "$out.jxl" "$out.pgm" >/dev/null 2>"$out.err" || { echo "djxl failed on $out.jxl" >&2; return 1; }
  cmp -s "$out.pgm" "$pgm" || { echo "JPEG-XL round trip differs from $pgm" >&2; return 1; }
  stat -c %s "$out.jxl"
  rm -f "$out.jxl" "$out.pgm" "$out.err"
}
export -f encode_one

echo "# JPEG-XL lossless: $(cjxl --version 2>&1 | head -n1), options: ${opts[*]}; every tile decoded with djxl and compared"
printf 'dataset\ttiles\tzstd19_B\tpredictor_zstd19_B\tjpegls_B\tjxl_B\tjxl_vs_zstd19\tjxl_vs_predictor\n'
found=0
for sub in "$dir"/*/; do
  sub=${sub%/}
  name=$(basename "$sub")
  shopt -s nullglob
  tiles=("$sub"/*.pgm)
  shopt -u nullglob
  [ ${#tiles[@]} -gt 0 ] || continue
  found=1
  mkdir -p "$work/$name"
  # xargs appends the tile's path after the cjxl options; the single quotes are for the child bash.
  # shellcheck disable=SC2016
  sizes=$(printf '%s\0' "${tiles[@]}" |
    PEER_OUT="$work/$name" xargs -0 -n 1 -P "$jobs" bash -c \
      'f="${!#}"; set -- "${@:1:$#-1}"; encode_one "$f" "$PEER_OUT/$(basename "$f" .pgm)" "$@"' _ "${opts[@]}") ||
    { echo "peer_lossless.sh: $name: JPEG-XL failed" >&2; exit 1; }
  count=$(printf '%s\n' "$sizes" | grep -c .)
  [ "$count" -eq ${#tiles[@]} ] || { echo "peer_lossless.sh: $name: $count of ${#tiles[@]} tiles coded" >&2; exit 1; }
  jxl=$(printf '%s\n' "$sizes" | awk '{s += $1} END {print s}')
  get() { awk -F'\t' -v k="$1" '$1 == k {print $2}' "$sub/bench_bytes.tsv" 2>/dev/null; }
  z19=$(get zstd19)
  pred=$(get predictor_zstd19)
  jls=$(get jpegls_charls)
  awk -v n="$name" -v t="${#tiles[@]}" -v z="${z19:-}" -v p="${pred:-}" -v l="${jls:-}" -v x="$jxl" 'BEGIN {
    printf "%s\t%d\t%s\t%s\t%s\t%d\t%s\t%s\n", n, t, (z == "" ? "-" : z), (p == "" ? "-" : p), (l == "" ? "-" : l), x,
      (z == "" ? "-" : sprintf("%.3f", x / z)), (p == "" ? "-" : sprintf("%.3f", x / p)) }'
done
[ "$found" -eq 1 ] || { echo "peer_lossless.sh: no DIR/<dataset>/*.pgm under $dir" >&2; exit 1; }
