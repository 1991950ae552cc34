#!/usr/bin/python3
"""Makes a 1 m "lidar-like" DEM square from a real, coarser DEM in a metric CRS, for terrain-cook-bench --scale.

Heights = cubic upsampling of the source (Keys a = -0.5, GDAL's "cubic") plus band-limited roughness: four
octaves of value noise, wavelengths 2.5-20 m, about 1 m peak in total, hashed from the global integer
coordinates and --seed (so the result is deterministic and the same metre of ground gets the same roughness
in every square size). The square is centred on the source; where it reaches past the source's edges the
source is mirrored at them (Kilauea is 25.7 x 23.8 km, the 40 km square needs this).

Streams by blocks of rows and columns: memory is one block plus the (small) source, whatever the size.
Writes a tiled, ZSTD-compressed Float32 GeoTIFF (BIGTIFF=IF_SAFER) through a temporary name, so a file
under the final name is always complete. With --tile-km K the square is instead cut into K x K km GeoTIFF
tiles (as national lidar is delivered) in the folder OUT.tiles, listed by the VRT OUT (written last); the
samples are the same as those of the single file.

Usage: make_lidar_like.py --size-km 8 --out DIR/lidar_like_8km.tif [--source DEM] [--seed 1] [--block 2048]
       make_lidar_like.py --size-km 8 --out DIR/lidar_like_8km_tiles1km.vrt --tile-km 1
Needs python3-gdal and python3-numpy (Debian's /usr/bin/python3).
"""
import argparse
import os
import sys

import numpy as np
from osgeo import gdal

gdal.UseExceptions()

# Roughness octaves: (wavelength m, amplitude m). Sum of amplitudes 1.0 m; the value noise spends most of its
# time well inside [-1, 1], so the typical roughness is a few decimetres, like bare-earth lidar texture.
OCTAVES = [(2.5, 0.10), (5.0, 0.18), (10.0, 0.30), (20.0, 0.42)]
NODATA = -32768.0


def keys_cubic(t):
    """Keys cubic convolution weights (a = -0.5) for offsets t = distance to the sample (any sign)."""
    t = np.abs(t)
    a = -0.5
    w = np.where(t <= 1, (a + 2) * t**3 - (a + 3) * t**2 + 1, a * t**3 - 5 * a * t**2 + 8 * a * t - 4 * a)
    return np.where(t < 2, w, 0.0)


def mirror(idx, n):
    """Reflects indices into [0, n) about the edges (..., 1, 0 | 0, 1, ..., n-1 | n-1, n-2, ...)."""
    period = 2 * n
    m = np.mod(idx, period)
    return np.where(m < n, m, period - 1 - m)


def cubic_matrix(u, n):
    """Dense weights W (len(u) x span) and the first source index: out = W @ src[first:first+span]."""
    base = np.floor(u).astype(np.int64)
    taps = base[:, None] + np.arange(-1, 3)[None, :]
    weights = keys_cubic(u[:, None] - taps)
    idx = mirror(taps, n)
    first, last = int(idx.min()), int(idx.max())
    w = np.zeros((len(u), last - first + 1))
    rows = np.repeat(np.arange(len(u)), 4)
    np.add.at(w, (rows, (idx - first).ravel()), weights.ravel())
    return w, first


def splitmix(x):
    """64-bit mix (splitmix64 finaliser) on uint64 arrays; wraps like C."""
    x = (x + np.uint64(0x9E3779B97F4A7C15)) & np.uint64(0xFFFFFFFFFFFFFFFF)
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def lattice_values(ix, iy, octave, seed):
    """Value in [-1, 1] at integer lattice points (outer product of ix and iy), from the hash."""
    key = np.uint64((seed * 1_000_003 + octave * 7919) & 0xFFFFFFFF)
    h = splitmix((iy.astype(np.uint64)[:, None] << np.uint64(32)) ^ ix.astype(np.uint64)[None, :] ^ (key << np.uint64(17)))
    h = splitmix(h ^ key)
    return (h >> np.uint64(11)).astype(np.float64) * (2.0 / 2.0**53) - 1.0


def fade(coord, wavelength):
    """Lattice cell index and quintic fade weight of each coordinate for one octave."""
    g = coord / wavelength
    base = np.floor(g).astype(np.int64)
    f = g - base
    return base, f * f * f * (f * (f * 6 - 15) + 10)


def roughness(xs, ys, seed):
    """Sum of the octaves at the sample centres xs (eastings) x ys (northings), metres."""
    out = np.zeros((len(ys), len(xs)))
    for k, (wavelength, amplitude) in enumerate(OCTAVES):
        bx, sx = fade(xs, wavelength)
        by, sy = fade(ys, wavelength)
        fx, fy = int(bx.min()), int(by.min())
        v = lattice_values(np.arange(fx, int(bx.max()) + 2), np.arange(fy, int(by.max()) + 2), k, seed)
        # Separable blend with gathers (a dense interpolation matrix would be mostly zeros).
        t = v[by - fy] * (1 - sy)[:, None] + v[by - fy + 1] * sy[:, None]
        out += amplitude * (t[:, bx - fx] * (1 - sx) + t[:, bx - fx + 1] * sx)
    return out


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    default_source = os.path.normpath(os.path.join(here, "..", "..", "..", "shared", "data", "kilauea_utm5n.tif"))
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--source", default=default_source, help="real DEM in a metric CRS (default: %(default)s)")
    p.add_argument("--size-km", type=float, required=True, help="side of the square, km")
    p.add_argument("--out", required=True, help="output GeoTIFF (its folder must exist)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--block", type=int, default=2048, help="samples per block side (multiple of 512)")
    p.add_argument("--tile-km", type=float, default=0,
                   help="write K x K km GeoTIFF tiles listed by the VRT --out (default 0: one GeoTIFF)")
    a = p.parse_args()
    if a.block % 512 or a.block <= 0:
        sys.exit("make_lidar_like.py: --block must be a positive multiple of 512")
    if a.tile_km < 0 or (a.tile_km and not a.out.endswith(".vrt")):
        sys.exit("make_lidar_like.py: --tile-km needs a positive size and an --out ending in .vrt")

    try:
        src = gdal.Open(a.source)
    except RuntimeError as e:
        sys.exit(f"make_lidar_like.py: cannot open {a.source}: {e}")
    srs = src.GetSpatialRef()
    if srs is None or not srs.IsProjected() or abs(srs.GetLinearUnits() - 1.0) > 1e-9:
        sys.exit(f"make_lidar_like.py: {a.source} is not in a projected CRS in metres")
    gx0, dx, rx, gy0, ry, dy = src.GetGeoTransform()
    if rx or ry or dy >= 0:
        sys.exit(f"make_lidar_like.py: {a.source} is rotated or south-up (not supported)")
    band = src.GetRasterBand(1)
    s = band.ReadAsArray().astype(np.float64)  # the source is coarse (30 m): small
    nd = band.GetNoDataValue()
    valid = np.isfinite(s) if nd is None else (s != nd) & np.isfinite(s)
    holes = (~valid).astype(np.float64)
    s = np.where(valid, s, 0.0)
    sh, sw = s.shape

    n = int(round(a.size_km * 1000))
    # Centre of the source, snapped to whole metres: output sample (i, j) sits at (x0 + j + 0.5, y0 - i - 0.5).
    x0 = np.floor(gx0 + 0.5 * sw * dx) - n // 2
    y0 = np.floor(gy0 + 0.5 * sh * dy) + n // 2

    opts = ["TILED=YES", "BLOCKXSIZE=512", "BLOCKYSIZE=512", "COMPRESS=ZSTD", "ZSTD_LEVEL=1", "PREDICTOR=3",
            "BIGTIFF=IF_SAFER"]
    gdal.SetCacheMax(256 << 20)
    any_hole = holes.any()

    def write_geotiff(path, r_first, c_first, rows_n, cols_n):
        """Samples [r_first, r_first + rows_n) x [c_first, c_first + cols_n) of the square into one GeoTIFF."""
        out = gdal.GetDriverByName("GTiff").Create(path, cols_n, rows_n, 1, gdal.GDT_Float32, opts)
        out.SetGeoTransform((x0 + c_first, 1.0, 0.0, y0 - r_first, 0.0, -1.0))
        out.SetSpatialRef(srs)
        ob = out.GetRasterBand(1)
        if any_hole:
            ob.SetNoDataValue(NODATA)
        for r0 in range(0, rows_n, a.block):
            rows = min(a.block, rows_n - r0)
            ys = y0 - (r_first + r0 + np.arange(rows) + 0.5)
            wy, fy = cubic_matrix((ys - gy0) / dy - 0.5, sh)
            for c0 in range(0, cols_n, a.block):
                cols = min(a.block, cols_n - c0)
                xs = x0 + c_first + c0 + np.arange(cols) + 0.5
                wx, fx = cubic_matrix((xs - gx0) / dx - 0.5, sw)
                win = (slice(fy, fy + wy.shape[1]), slice(fx, fx + wx.shape[1]))
                z = wy @ s[win] @ wx.T + roughness(xs, ys, a.seed)
                if any_hole:  # a sample whose cubic support touches a void is a void
                    z[(np.abs(wy) > 0) @ holes[win] @ (np.abs(wx) > 0).T > 0] = NODATA
                ob.WriteArray(z.astype(np.float32), c0, r0)
            if not a.tile_km:
                print(f"\rmake_lidar_like.py: {a.size_km:g} km: rows {r0 + rows}/{n}", end="", file=sys.stderr,
                      flush=True)
        ob.FlushCache()
        ob = None
        out = None  # closes the file

    if not a.tile_km:
        tmp = a.out + ".partial.tif"
        write_geotiff(tmp, 0, 0, n, n)
        print(file=sys.stderr)
        os.replace(tmp, a.out)
        return

    # Tiles of t samples (the last row and column of tiles may be narrower), then the VRT listing them:
    # the VRT exists only once every tile is complete.
    t = int(round(a.tile_km * 1000))
    folder = a.out + ".tiles"
    os.makedirs(folder, exist_ok=True)
    tiles = []
    count = ((n + t - 1) // t) ** 2
    for r_first in range(0, n, t):
        for c_first in range(0, n, t):
            path = os.path.join(folder, f"r{r_first // t:03d}_c{c_first // t:03d}.tif")
            write_geotiff(path + ".partial.tif", r_first, c_first, min(t, n - r_first), min(t, n - c_first))
            os.replace(path + ".partial.tif", path)
            tiles.append(path)
            print(f"\rmake_lidar_like.py: {a.size_km:g} km: tiles {len(tiles)}/{count}", end="", file=sys.stderr,
                  flush=True)
    print(file=sys.stderr)
    tmp = a.out + ".partial.vrt"
    vrt = gdal.BuildVRT(tmp, tiles)
    vrt.FlushCache()
    vrt = None
    os.replace(tmp, a.out)

if __name__ == "__main__":
    main()
