#!/usr/bin/python3
"""Makes the "lidar tile inside a coarser DEM" world of terrain-cook-bench --worlds from one real lidar
tile: the coarse DEM is made from the lidar itself, as a national DEM around a lidar survey.

The lidar tile is mirrored N x N times (every other copy flipped, so the relief is continuous across
each seam, as make_mirror_mosaic.py does) with the original copy in the middle, at its own place; the
result is averaged over blocks of --coarse-m metres (area mean, as DEM products are made) and shifted
by --offset-m metres in height, because national DEMs and lidar disagree by that much. The lidar tile
then lies inside the coarse DEM with --copies // 2 tile widths of coarse data on every side.

Writes OUT_DIR/coarse.tif (Float32, the lidar's CRS, tiled and ZSTD-compressed) and prints its size.
The lidar tile itself is cooked in place (never copied).

Usage: make_lidar_in_coarse.py --lidar ../shared/data/slovenia_TM1_564_146.tif --out-dir DIR
       [--copies 5] [--coarse-m 30] [--offset-m 3]
Needs python3-gdal and python3-numpy (Debian's /usr/bin/python3).
"""
import argparse
import os
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()
PROG = "make_lidar_in_coarse.py"


def fail(message):
    sys.exit(f"{PROG}: {message}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lidar", required=True, help="real lidar tile in a projected CRS, north-up")
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--copies", type=int, default=5, help="copies per side, odd (default 5)")
    ap.add_argument("--coarse-m", type=float, default=30.0, help="coarse DEM spacing, metres (default 30)")
    ap.add_argument("--offset-m", type=float, default=3.0, help="height offset of the coarse DEM (default 3)")
    a = ap.parse_args()
    if a.copies < 1 or a.copies % 2 == 0:
        fail("--copies must be odd (the original tile in the middle)")
    try:
        src = gdal.Open(a.lidar)
    except RuntimeError as e:
        fail(f"cannot open {a.lidar}: {e}")
    gt = src.GetGeoTransform()
    if gt[2] != 0 or gt[4] != 0 or gt[5] >= 0:
        fail(f"{a.lidar}: not a north-up raster")
    if not src.GetSpatialRef() or not src.GetSpatialRef().IsProjected():
        fail(f"{a.lidar}: needs a projected CRS")
    band = src.GetRasterBand(1)
    tile = band.ReadAsArray().astype(np.float32)
    nodata = band.GetNoDataValue()
    if nodata is not None:
        tile[tile == np.float32(nodata)] = np.nan
    h, w = tile.shape
    # Copy i starts at column i * (w - 1): neighbours share their edge column, odd copies flipped.
    n = a.copies
    W, H = n * (w - 1) + 1, n * (h - 1) + 1
    world = np.empty((H, W), np.float32)
    for j in range(n):
        rows = tile[::-1] if j % 2 else tile
        for i in range(n):
            part = rows[:, ::-1] if i % 2 else rows
            world[j * (h - 1):j * (h - 1) + h, i * (w - 1):i * (w - 1) + w] = part
    # Copy (n // 2, n // 2) is the original tile (an even number of flips each way) at its own place.
    c = n // 2
    x0 = gt[0] - c * (w - 1) * gt[1]
    y0 = gt[3] - c * (h - 1) * gt[5]
    k = int(round(a.coarse_m / gt[1]))
    if k < 2 or abs(k * gt[1] - a.coarse_m) > 1e-6 * a.coarse_m or abs(gt[1] + gt[5]) > 1e-9 * gt[1]:
        fail(f"--coarse-m {a.coarse_m} must be a whole number (>= 2) of the lidar's square samples ({gt[1]} m)")
    cw, ch = W // k, H // k
    blocks = world[:ch * k, :cw * k].reshape(ch, k, cw, k)
    coarse = np.nanmean(blocks, axis=(1, 3)).astype(np.float32) + np.float32(a.offset_m)
    os.makedirs(a.out_dir, exist_ok=True)
    out = os.path.join(a.out_dir, "coarse.tif")
    tmp = out + ".part"
    drv = gdal.GetDriverByName("GTiff")
    ds = drv.Create(tmp, cw, ch, 1, gdal.GDT_Float32,
                    ["TILED=YES", "BLOCKXSIZE=256", "BLOCKYSIZE=256", "COMPRESS=ZSTD", "PREDICTOR=3"])
    # The blocks' outer edges: the mosaic's pixel-area corner.
    ds.SetGeoTransform((x0, k * gt[1], 0.0, y0, 0.0, k * gt[5]))
    ds.SetSpatialRef(src.GetSpatialRef())
    ob = ds.GetRasterBand(1)
    ob.SetNoDataValue(-32768.0)
    ob.WriteArray(np.where(np.isnan(coarse), np.float32(-32768.0), coarse))
    ds = None
    os.replace(tmp, out)
    print(f"{out}: {cw} x {ch} samples of {k * gt[1]:g} m ({cw * k * gt[1] / 1000:.2f} x {ch * k * gt[1] / 1000:.2f} km), "
          f"heights +{a.offset_m:g} m, around {a.lidar} ({w} x {h} of {gt[1]:g} m)")


if __name__ == "__main__":
    main()
