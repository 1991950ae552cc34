#!/usr/bin/env bash
# Inputs through GDAL from the command line (issue 13): gdal_inputs_cli.sh CASE BIN_DIR SCRATCH_PARENT.
# Broken inputs exit 1 with a message naming the problem and leave every file as it was (no archive
# written, the previous one untouched); a directory of tiles cooks.
set -u
here=$(cd "$(dirname "$0")" && pwd)
case_name=$1 bin=$2 work=$3/gdal-inputs-cli-$1
command -v gdal_create >/dev/null || { echo "SKIP: gdal_create (gdal-bin) absent"; exit 0; }
rm -rf "$work"; mkdir -p "$work/tiles"; cd "$work" || exit 1
# Two 64 x 64 Float32 tiles side by side in UTM 33N, heights 100 and 300 m.
gdal_create -q -of GTiff -outsize 64 64 -bands 1 -ot Float32 -burn 100 -a_srs EPSG:32633 \
  -a_ullr 500000 5000640 500640 5000000 tiles/a.tif || { echo "FAIL: gdal_create"; exit 1; }
gdal_create -q -of GTiff -outsize 64 64 -bands 1 -ot Float32 -burn 300 -a_srs EPSG:32633 \
  -a_ullr 500640 5000640 501280 5000000 tiles/b.tif || { echo "FAIL: gdal_create"; exit 1; }
gdalbuildvrt -q mosaic.vrt tiles/a.tif tiles/b.tif || { echo "FAIL: gdalbuildvrt"; exit 1; }
"$bin/terrain-cook" tiles/a.tif -q -o keep.terrain --heights-only || { echo "FAIL: setup cook"; exit 1; }
snapshot() { find . -type f -print0 | sort -z | xargs -0 sha256sum; }
. "$here/cli_expect.sh"
expect_refused() { expect_exit "$(snapshot)" "$@"; }  # expect_refused RC REGEX command... (files as they are now)
case $case_name in
  vrt_missing_tile)
    rm tiles/b.tif
    expect_refused 1 "mosaic.vrt: cannot read its tile tiles/b.tif: No such file or directory" \
      "$bin/terrain-cook" mosaic.vrt -q -o keep.terrain --heights-only ;;
  vrt_unreadable_tile)
    head -c 5000 /dev/urandom > tiles/b.tif
    expect_refused 1 "mosaic.vrt: cannot read rows" "$bin/terrain-cook" mosaic.vrt -q -o keep.terrain --heights-only ;;
  unreadable_file)
    printf 'II*\0garbage' > broken.tif
    expect_refused 1 "broken.tif: (GDAL cannot open it|unknown input format)" \
      "$bin/terrain-cook" broken.tif -q -o keep.terrain --heights-only ;;
  tile_without_encoding)
    mkdir -p t/12/654 && gdal_create -q -of PNG -outsize 256 256 -bands 3 -ot Byte -burn 128 t/12/654/1583.png
    expect_refused 2 "--tile-encoding" "$bin/terrain-cook" t/12/654/1583.png -q -o keep.terrain --heights-only ;;
  terrarium_png)
    # A terrarium PNG not under a z/x/y path: 131*256 + 74 + 128/256 - 32768 = 842.5 m everywhere (not
    # the red channel's 131 "m" a grey heightmap reader gives), placed by --spacing / --crs.
    gdal_create -q -of PNG -outsize 64 64 -bands 3 -ot Byte -burn 131 -burn 74 -burn 128 flat.png
    "$bin/terrain-cook" flat.png -q -o flat.terrain --heights-only --tile-encoding terrarium --spacing 30,30 --crs local ||
      { echo "FAIL: terrarium cook"; exit 1; }
    h=$("$bin/terrain-inspect" flat.terrain --sample 900,900)
    echo "$h" | grep -Eq '^842\.5' || { echo "FAIL: height $h, expected 842.5"; exit 1; }
    echo "ok: terrarium PNG cooked at $h" ;;
  tile_encoding_on_grey_png)
    # --tile-encoding says the PNG holds RGB-encoded heights; a grey one is refused, not cooked as metres.
    gdal_create -q -of PNG -outsize 64 64 -bands 1 -ot Byte -burn 128 grey.png
    expect_refused 1 "grey\.png: 1 band\(s\); --tile-encoding terrarium reads heights encoded in red, green and blue" \
      "$bin/terrain-cook" grey.png -q -o keep.terrain --heights-only --tile-encoding terrarium --spacing 30 --crs local ;;
  tile_encoding_unused)
    # A flag that applies to none of the inputs changes nothing: refused.
    expect_refused 2 "--tile-encoding terrarium: names what a PNG or WebP input holds.*none of the inputs is one" \
      "$bin/terrain-cook" tiles/a.tif -q -o keep.terrain --heights-only --tile-encoding terrarium ;;
  directory)
    out=$("$bin/terrain-cook" tiles -q -o dir.terrain --heights-only --json) || { echo "FAIL: directory cook"; exit 1; }
    # Both tiles are read, in path order; the mosaic is 128 samples wide.
    echo "$out" | grep -q '"tiles/a.tif: ' || { echo "FAIL: a.tif not read: $out"; exit 1; }
    echo "$out" | grep -q '"tiles/b.tif: ' || { echo "FAIL: b.tif not read"; exit 1; }
    "$bin/terrain-cook" mosaic.vrt -q -o vrt.terrain --heights-only || { echo "FAIL: vrt cook"; exit 1; }
    h1=$("$bin/terrain-inspect" dir.terrain --sample 500100,5000300 --sample 501000,5000300)
    h2=$("$bin/terrain-inspect" vrt.terrain --sample 500100,5000300 --sample 501000,5000300)
    [ "$h1" = "$h2" ] || { echo "FAIL: directory $h1 vs VRT $h2"; exit 1; }
    echo "$h1" | head -1 | grep -Eq '^(99\.9|100\.0)' || { echo "FAIL: west height $h1"; exit 1; }
    echo "$h1" | tail -1 | grep -Eq '^(299\.9|300\.0)' || { echo "FAIL: east height $h1"; exit 1; }
    echo "ok: directory and VRT agree: $h1" ;;
  *) echo "FAIL: unknown case $case_name"; exit 1 ;;
esac
