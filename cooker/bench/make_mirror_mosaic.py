#!/usr/bin/python3
"""Makes a large DEM of real relief from one real tile: copies of it, every other copy mirrored, so the
relief is continuous across every seam (a mirrored copy meets its neighbour with the same edge row).

Mirroring keeps the tile's own statistics (roughness, slopes, lidar texture) at any size: the benchmarks
of terrain-cook-bench --scale and --units cook squares of real 1 m lidar made this way, and a 1-degree
SRTM1 tile in 2 x 3 copies makes a world of 10^4 roots (issue 15) without a national dataset.

The copies share their edge rows and columns (SRTM's pixel-is-point tiles do too): copy i starts at
column i * (W - 1). Two ways to size the result:
  --grid NXxNY   NX x NY whole copies: (NX * (W - 1) + 1) x (NY * (H - 1) + 1) samples;
  --size-km KM   a square of KM km (KM * 1000 / spacing samples a side, rounded to whole samples),
                 cut from the same endless mirrored tiling.
Both are georeferenced from the source's origin and spacing, growing east and south; nodata stays nodata.

A geographic source (the Tahoe lidar, EPSG:4326) is first warped with GDAL (cubic) to the UTM zone of its
centre at --tr metres and cropped to the largest rectangle without the warp's empty corners, so that the
mirrored copies have no nodata seams, when --metric, --tr, --size-km or --tile-km asks for metres;
otherwise (--grid alone) it is mirrored in its own CRS. `--grid 1x1 --metric` writes just the metric tile.

Writes a tiled (512), ZSTD-compressed GeoTIFF of the source's data type (floating-point predictor for
floats) through a temporary name, by blocks: memory is one block plus the source tile. With --tile-km K
the result is instead cut into K x K km GeoTIFF tiles (as national lidar is delivered) in the folder
OUT.tiles, listed by the VRT OUT (gdalbuildvrt's library call, written last); the samples are the same.

Usage: make_mirror_mosaic.py --source S46W066.hgt.gz --grid 2x3 --out DIR/s46w066_2x3.tif
       make_mirror_mosaic.py --source slovenia_TM1_564_146.tif --size-km 8 --out DIR/slovenia_mirror_8km.tif
       make_mirror_mosaic.py --source slovenia_TM1_564_146.tif --size-km 8 --tile-km 1 --out DIR/s8.vrt
       make_mirror_mosaic.py --source tahoe_lidar_bareearth.tif --metric --tr 0.5 --grid 1x1 --out DIR/tahoe_utm.tif
Needs python3-gdal and python3-numpy (Debian's /usr/bin/python3).
"""
import argparse
import math
import os
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()
PROG = "make_mirror_mosaic.py"
BLOCK = 2048  # samples per block side when writing (a multiple of the 512 GeoTIFF tiles)


def fail(message):
    sys.exit(f"{PROG}: {message}")


def open_source(path):
    """The source dataset; GDAL opens SRTM's .hgt.zip itself, a .gz through /vsigzip."""
    if path.endswith(".gz") and not path.startswith("/vsi"):
        path = "/vsigzip/" + path
    try:
        return gdal.Open(path)
    except RuntimeError as e:
        fail(f"cannot open {path}: {e}")


def is_metric(ds):
    srs = ds.GetSpatialRef()
    return srs is not None and srs.IsProjected() and abs(srs.GetLinearUnits() - 1.0) < 1e-9


def utm_epsg(ds):
    """EPSG code of the WGS 84 UTM zone holding the centre of a geographic dataset."""
    gx0, dx, _, gy0, _, dy = ds.GetGeoTransform()
    lon = gx0 + 0.5 * ds.RasterXSize * dx
    lat = gy0 + 0.5 * ds.RasterYSize * dy
    zone = int(math.floor((lon + 180.0) / 6.0)) % 60 + 1
    return (32600 if lat >= 0 else 32700) + zone


def default_spacing_m(ds):
    """The geographic dataset's finer sample spacing in metres at its centre, to 2 significant digits."""
    gx0, dx, _, gy0, _, dy = ds.GetGeoTransform()
    lat = math.radians(gy0 + 0.5 * ds.RasterYSize * dy)
    metres = min(abs(dx) * 111320.0 * math.cos(lat), abs(dy) * 110574.0)
    return float(f"{metres:.2g}")


def warp_to_metric(ds, tr):
    """The dataset warped (cubic) to the UTM zone of its centre at tr metres, in memory."""
    band = ds.GetRasterBand(1)
    nd = band.GetNoDataValue()
    return gdal.Warp("", ds, format="MEM", dstSRS=f"EPSG:{utm_epsg(ds)}", xRes=tr, yRes=tr,
                     targetAlignedPixels=True, resampleAlg="cubic", dstNodata=-32768.0 if nd is None else nd)


def crop_to_data(s, nodata):
    """Row and column slices of the largest rectangle, trimmed edge by edge, whose border holds no nodata
    (the warp's empty corners are convex: then the inside has none either)."""
    hole = ~np.isfinite(s) if nodata is None else (s == nodata) | ~np.isfinite(s)
    r0, r1, c0, c1 = 0, s.shape[0], 0, s.shape[1]
    while r0 < r1 and c0 < c1:
        edges = {"top": hole[r0, c0:c1].sum(), "bottom": hole[r1 - 1, c0:c1].sum(),
                 "left": hole[r0:r1, c0].sum(), "right": hole[r0:r1, c1 - 1].sum()}
        worst = max(edges, key=edges.get)
        if edges[worst] == 0:
            return slice(r0, r1), slice(c0, c1)
        if worst == "top":
            r0 += 1
        elif worst == "bottom":
            r1 -= 1
        elif worst == "left":
            c0 += 1
        else:
            c1 -= 1
    fail("the warped source has no rectangle without nodata")


class Tile:
    """The source tile in a metric (or, with --grid, any) CRS: samples, georeferencing, type, nodata."""

    def __init__(self, ds, crop):
        band = ds.GetRasterBand(1)
        gx0, dx, rx, gy0, ry, dy = ds.GetGeoTransform()
        if rx or ry or dy >= 0:
            fail("the source is rotated or south-up (not supported)")
        self.nodata = band.GetNoDataValue()
        self.dtype = band.DataType
        s = band.ReadAsArray()
        rows, cols = crop_to_data(s, self.nodata) if crop else (slice(0, s.shape[0]), slice(0, s.shape[1]))
        self.s = s[rows, cols]
        self.h, self.w = self.s.shape
        if self.h < 2 or self.w < 2:
            fail("the source needs at least 2 x 2 samples")
        self.geo = (gx0 + cols.start * dx, dx, 0.0, gy0 + rows.start * dy, 0.0, dy)
        self.srs = ds.GetSpatialRef()

    def window(self, r0, c0, rows, cols):
        """Samples [r0, r0 + rows) x [c0, c0 + cols) of the endless mirrored tiling."""
        return self.s[np.ix_(mirror_index(r0 + np.arange(rows), self.h), mirror_index(c0 + np.arange(cols), self.w))]


def mirror_index(i, n):
    """Source index of mosaic index i: copies of n samples sharing edge samples, every other one mirrored."""
    period = 2 * (n - 1)
    k = np.mod(i, period)
    return np.where(k < n, k, period - k)


def creation_options(dtype):
    float_type = dtype in (gdal.GDT_Float32, gdal.GDT_Float64)
    return ["TILED=YES", "BLOCKXSIZE=512", "BLOCKYSIZE=512", "COMPRESS=ZSTD", "ZSTD_LEVEL=1",
            f"PREDICTOR={3 if float_type else 2}", "BIGTIFF=IF_SAFER"]


def write_geotiff(path, tile, r_first, c_first, rows_n, cols_n, progress):
    """Samples [r_first, r_first + rows_n) x [c_first, c_first + cols_n) of the mosaic into the GeoTIFF
    `path`, written under a temporary name and renamed when complete."""
    tmp = path + ".partial.tif"
    out = gdal.GetDriverByName("GTiff").Create(tmp, cols_n, rows_n, 1, tile.dtype, creation_options(tile.dtype))
    gx0, dx, _, gy0, _, dy = tile.geo
    out.SetGeoTransform((gx0 + c_first * dx, dx, 0.0, gy0 + r_first * dy, 0.0, dy))
    out.SetSpatialRef(tile.srs)
    ob = out.GetRasterBand(1)
    if tile.nodata is not None:
        ob.SetNoDataValue(tile.nodata)
    for r0 in range(0, rows_n, BLOCK):
        rows = min(BLOCK, rows_n - r0)
        for c0 in range(0, cols_n, BLOCK):
            ob.WriteArray(tile.window(r_first + r0, c_first + c0, rows, min(BLOCK, cols_n - c0)), c0, r0)
        if progress:
            progress(r0 + rows, rows_n)
    ob.FlushCache()
    ob = None
    out = None  # closes the file
    os.replace(tmp, path)


def samples_per(km, spacing, what):
    """Samples in km at this spacing, rounded (the mosaic is cut on the source's own grid)."""
    n = int(round(km * 1000.0 / spacing))
    if n < 1:
        fail(f"{what} {km:g} km is less than one {spacing:g} m sample")
    return n


def write_tiles(out, tile, n_rows, n_cols, tile_km):
    """The mosaic as tile_km x tile_km km GeoTIFFs in the folder OUT.tiles (the last row and column may
    be narrower), then the VRT `out` listing them: the VRT exists only once every tile is complete."""
    t = samples_per(tile_km, abs(tile.geo[1]), "--tile-km")
    folder = out + ".tiles"
    os.makedirs(folder, exist_ok=True)
    count = ((n_rows + t - 1) // t) * ((n_cols + t - 1) // t)
    paths = []
    for r_first in range(0, n_rows, t):
        for c_first in range(0, n_cols, t):
            path = os.path.join(folder, f"r{r_first // t:03d}_c{c_first // t:03d}.tif")
            write_geotiff(path, tile, r_first, c_first, min(t, n_rows - r_first), min(t, n_cols - c_first), None)
            paths.append(path)
            print(f"\r{PROG}: tiles {len(paths)}/{count}", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    tmp = out + ".partial.vrt"
    vrt = gdal.BuildVRT(tmp, paths)
    vrt.FlushCache()
    vrt = None
    os.replace(tmp, out)


def parse_grid(text):
    try:
        nx, ny = (int(v) for v in text.lower().split("x"))
    except ValueError:
        fail(f"--grid {text}: expected NXxNY, e.g. 2x3")
    if not (1 <= nx <= 64 and 1 <= ny <= 64):
        fail(f"--grid {text}: 1..64 copies per side")
    return nx, ny


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", required=True, help="DEM GDAL can read (SRTM .hgt, .hgt.zip, .hgt.gz, GeoTIFF, ...)")
    size = ap.add_mutually_exclusive_group(required=True)
    size.add_argument("--grid", help="whole copies east x south, e.g. 2x3")
    size.add_argument("--size-km", type=float, help="a square of this side, km (metric sources)")
    ap.add_argument("--tile-km", type=float, default=0,
                    help="write K x K km GeoTIFF tiles listed by the VRT --out (default 0: one GeoTIFF)")
    ap.add_argument("--metric", action="store_true", help="warp a geographic source to UTM first (see above)")
    ap.add_argument("--tr", type=float, default=0,
                    help="spacing, m, a geographic source is warped to (implies --metric; default: its finer "
                         "spacing at its centre)")
    ap.add_argument("--out", required=True, help="GeoTIFF (or, with --tile-km, VRT) to write; its folder must exist")
    a = ap.parse_args()
    if a.tile_km < 0 or (a.tile_km and not a.out.endswith(".vrt")):
        fail("--tile-km needs a positive size and an --out ending in .vrt")
    if a.size_km is not None and a.size_km <= 0:
        fail(f"--size-km {a.size_km:g}: must be positive")
    if a.tr < 0:
        fail(f"--tr {a.tr:g}: must be positive")

    ds = open_source(a.source)
    warped = False
    if not is_metric(ds) and (a.metric or a.tr or a.size_km is not None or a.tile_km):
        srs = ds.GetSpatialRef()
        if srs is None or not srs.IsGeographic():
            fail(f"{a.source} is in no metric or geographic CRS: --metric, --tr, --size-km and --tile-km need metres")
        ds = warp_to_metric(ds, a.tr or default_spacing_m(ds))
        warped = True
    tile = Tile(ds, crop=warped)
    if a.grid:
        nx, ny = parse_grid(a.grid)
        n_cols, n_rows = nx * (tile.w - 1) + 1, ny * (tile.h - 1) + 1
    else:
        dx, dy = tile.geo[1], -tile.geo[5]
        if abs(dx - dy) > 1e-9 * dx:
            fail(f"--size-km needs square samples; {a.source} has {dx:g} x {dy:g}")
        n_rows = n_cols = samples_per(a.size_km, dx, "--size-km")
    if a.tile_km:
        write_tiles(a.out, tile, n_rows, n_cols, a.tile_km)
        return

    def progress(done, total):
        print(f"\r{PROG}: rows {done}/{total}", end="", file=sys.stderr, flush=True)

    write_geotiff(a.out, tile, 0, 0, n_rows, n_cols, progress)
    print(file=sys.stderr)


if __name__ == "__main__":
    main()
