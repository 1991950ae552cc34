#!/usr/bin/python3
"""Independent oracle for the cooker's accuracy test: reads a DEM with GDAL (or NumPy for .npz),
picks random source samples that hold data and prints one line per sample:

    X Y VALUE EDGE

X Y are the sample centre's longitude/latitude (geographic sources), its projected coordinates
(projected sources, whose CRS is the archive's frame) or frame metres computed from --spacing for
heightmap images (row 0 north, south-west sample at 0,0); VALUE is the source value * --scale;
EDGE is 1 when the sample is on the raster's outer ring or next to nodata (8-neighbourhood).
Runs with Debian's /usr/bin/python3 (python3-gdal, python3-numpy)."""
import argparse
import sys

import numpy as np


def main():
    p = argparse.ArgumentParser()
    p.add_argument("dem")
    p.add_argument("--count", type=int, default=10000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--spacing", type=float, default=0.0, help="heightmap image: sample spacing (frame metres)")
    p.add_argument("--shift", type=float, default=0.0, help="move every point east by this many samples (negative control)")
    a = p.parse_args()

    if a.dem.endswith(".npz"):
        d = np.load(a.dem)
        z = d["elevation"].astype(np.float64)
        rows, cols = z.shape
        west = min(float(d["xmin"]), float(d["xmax"]))
        north = max(float(d["ymin"]), float(d["ymax"]))
        dx = (max(float(d["xmin"]), float(d["xmax"])) - west) / cols
        dy = (north - min(float(d["ymin"]), float(d["ymax"]))) / rows
        gt = (west, dx, 0.0, north, 0.0, -dy)  # rows north to south, extent = outer edges
        valid = np.isfinite(z)
    else:
        from osgeo import gdal
        gdal.UseExceptions()
        ds = gdal.Open(a.dem)
        band = ds.GetRasterBand(1)
        z = band.ReadAsArray().astype(np.float64)
        rows, cols = z.shape
        gt = ds.GetGeoTransform()
        nodata = band.GetNoDataValue()
        valid = np.isfinite(z)
        if nodata is not None:
            valid &= z != nodata

    # Samples on the outer ring or beside nodata (where a hole vertex may drop their triangle).
    inner = np.zeros_like(valid)
    inner[1:-1, 1:-1] = True
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            inner[1:-1, 1:-1] &= valid[1 + dr:rows - 1 + dr, 1 + dc:cols - 1 + dc]
    idx = np.flatnonzero(valid.ravel())
    if idx.size == 0:
        sys.exit("no valid samples")
    rng = np.random.default_rng(a.seed)
    pick = rng.choice(idx, size=min(a.count, idx.size), replace=False)
    r = pick // cols
    c = pick % cols
    cc = c + 0.5 + a.shift  # pixel centre in GDAL's raster space (corner at 0)
    rr = r + 0.5
    if a.spacing > 0:  # heightmap image without georeferencing
        x = (cc - 0.5) * a.spacing
        y = (rows - 1 - (rr - 0.5)) * a.spacing
    else:
        x = gt[0] + cc * gt[1] + rr * gt[2]
        y = gt[3] + cc * gt[4] + rr * gt[5]
    v = z[r, c] * a.scale
    out = sys.stdout
    edge = ~inner[r, c]
    for i in range(pick.size):
        out.write("%.12f %.12f %.9f %d\n" % (x[i], y[i], v[i], 1 if edge[i] else 0))


if __name__ == "__main__":
    main()
