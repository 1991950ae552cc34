#!/usr/bin/python3
"""Makes a large world of real relief from one DEM: NX x NY copies of it, every other copy mirrored, so
the relief is continuous across every seam (a mirrored copy meets its neighbour with the same edge row).

For worlds of 10^4 roots and more (issue 15: streaming and drawing them) without a national dataset: a
1-degree SRTM1 tile (3601 x 3601 samples, about 2000 roots) in 2 x 3 copies is about 12 500 root cells.
The copies share their edge rows and columns (SRTM's pixel-is-point tiles do too), so the output is
(NX * (W - 1) + 1) x (NY * (H - 1) + 1) samples, georeferenced from the source's origin and spacing,
growing east and south. Nodata stays nodata. Writes a tiled, ZSTD-compressed GeoTIFF of the source's data
type through a temporary name, one row of copies at a time.

Usage: make_mirror_mosaic.py --source S46W066.hgt.gz --grid 2x3 --out DIR/s46w066_2x3.tif
Needs python3-gdal and python3-numpy (Debian's /usr/bin/python3).
"""
import argparse
import os
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", required=True, help="DEM GDAL can read (SRTM .hgt, .hgt.zip, .hgt.gz, GeoTIFF, ...)")
    ap.add_argument("--grid", default="2x3", help="copies east x south, e.g. 2x3")
    ap.add_argument("--out", required=True, help="GeoTIFF to write")
    a = ap.parse_args()
    try:
        nx, ny = (int(v) for v in a.grid.lower().split("x"))
    except ValueError:
        sys.exit(f"make_mirror_mosaic.py: --grid {a.grid}: expected NXxNY, e.g. 2x3")
    if not (1 <= nx <= 64 and 1 <= ny <= 64):
        sys.exit(f"make_mirror_mosaic.py: --grid {a.grid}: 1..64 copies per side")
    # GDAL opens SRTM's .hgt.zip itself; a .gz through /vsigzip.
    path = "/vsigzip/" + a.source if a.source.endswith(".gz") and not a.source.startswith("/vsi") else a.source
    try:
        src = gdal.Open(path)
    except RuntimeError as e:
        sys.exit(f"make_mirror_mosaic.py: cannot open {a.source}: {e}")
    gx0, dx, rx, gy0, ry, dy = src.GetGeoTransform()
    if rx or ry or dy >= 0:
        sys.exit(f"make_mirror_mosaic.py: {a.source} is rotated or south-up (not supported)")
    band = src.GetRasterBand(1)
    s = band.ReadAsArray()
    h, w = s.shape
    out_w, out_h = nx * (w - 1) + 1, ny * (h - 1) + 1
    opts = ["TILED=YES", "BLOCKXSIZE=512", "BLOCKYSIZE=512", "COMPRESS=ZSTD", "ZSTD_LEVEL=1", "BIGTIFF=IF_SAFER"]
    tmp = a.out + ".partial.tif"
    out = gdal.GetDriverByName("GTiff").Create(tmp, out_w, out_h, 1, band.DataType, opts)
    out.SetGeoTransform((gx0, dx, 0.0, gy0, 0.0, dy))
    out.SetSpatialRef(src.GetSpatialRef())
    ob = out.GetRasterBand(1)
    nd = band.GetNoDataValue()
    if nd is not None:
        ob.SetNoDataValue(nd)
    for j in range(ny):
        row = s[::-1, :] if j % 2 else s
        # One row of copies: copy i starts at column i * (w - 1); its first column repeats the last one
        # of copy i - 1 (equal by the mirroring), so writing it again changes nothing.
        strip = np.empty((h, out_w), dtype=s.dtype)
        for i in range(nx):
            strip[:, i * (w - 1):i * (w - 1) + w] = row[:, ::-1] if i % 2 else row
        ob.WriteArray(strip, 0, j * (h - 1))
        print(f"\rmake_mirror_mosaic.py: rows of copies {j + 1}/{ny}", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    ob.FlushCache()
    ob = None
    out = None
    os.replace(tmp, a.out)


if __name__ == "__main__":
    main()
