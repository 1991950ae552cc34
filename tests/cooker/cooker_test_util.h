// Helpers of the cooker tests: synthetic GeoTIFFs written with libtiff + libgeotiff, cooking
// through the library, and reading heights back the way a renderer sees them.
#pragma once
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/cook.h"
#include "terrain/format.h"
#include "terrain/sample.h"

namespace terrain::cook {
struct Raster;
}

namespace terrain::test {

struct SyntheticDem {
  int width = 0, height = 0;
  std::vector<double> values;  // row-major, row 0 = north; NaN = nodata (written as `nodata` if set)
  bool int16 = false;          // Int16 samples, else Float32
  std::optional<double> nodata;
  // Model coordinates of the CENTRE of sample (0, 0) (the north-west sample) and the spacing.
  double x0 = 0, y0 = 0, dx = 1, dy = 1;
  bool point = false;          // PixelIsPoint (else PixelIsArea)
  int epsg_geographic = 0;     // e.g. 4326
  int epsg_projected = 0;      // e.g. 32632

  double& at(int col, int row) { return values[size_t(row) * size_t(width) + size_t(col)]; }
  // Model coordinates of sample centre (col, row).
  double mx(int col) const { return x0 + col * dx; }
  double my(int row) const { return y0 - row * dy; }
};

// Writes a tiled (deflate) or striped GeoTIFF; returns false with a message on failure.
bool write_geotiff(const std::string& path, const SyntheticDem& dem, bool tiled, std::string& error);

// Writes `dem` as <dir>/<stem>.tif (tiled or striped) and points `options` at it: that file in,
// <dir>/<stem>.terrain out. A fatal test failure when the GeoTIFF cannot be written (callers wrap
// the call in ASSERT_NO_FATAL_FAILURE).
void write_cook_input(const std::filesystem::path& dir, const std::string& stem, const SyntheticDem& dem, bool tiled,
                      cook::CookOptions& options);

// A refused cook: status `code` and a message that contains each of `fragments`.
void expect_refusal(const Status& st, Error code, std::initializer_list<std::string_view> fragments);

// A reader plus sampler over a finished archive.
struct CookedArchive {
  ArchiveReader reader;
  std::unique_ptr<SurfaceSampler> sampler;
  Status open(const std::string& path) {
    Status st = reader.open(path);
    if (st.ok()) sampler = std::make_unique<SurfaceSampler>(reader);
    return st;
  }
  // Height at frame (x, y) and the node's record; nullopt where there is no terrain.
  std::optional<double> height(double x, double y, const NodeRecord** node = nullptr) {
    std::optional<SurfaceSample> s;
    if (!sampler->sample(x, y, s).ok() || !s) return std::nullopt;
    if (node) *node = &reader.nodes()[size_t(reader.find(s->node))];
    return s->height_m;
  }
  // Half the quantization step of `level`, in metres.
  double half_step(int level) const { return 0.5 * std::ldexp(1.0, reader.world().step_log2[size_t(level)]) * kHeightUnitM; }
  double max_half_step() const {
    double m = 0;
    for (int l = 0; l < kLevelCount; ++l) m = std::max(m, half_step(l));
    return m;
  }
  // The tolerance the cook used, as its cook information records it (0 when absent).
  double tolerance() const;
};

// Frame coordinates of longitude/latitude in an archive's Transverse Mercator frame
// (GeographicLib directly, independent of the cooker's own projection code).
void lonlat_to_frame(const FrameCrs& crs, double lon, double lat, double& x, double& y);

// Every same-level edge and parent/child vertex of an archive compared bit for bit (dequantized
// float32 heights and hole flags). Returns the number of mismatches; `compared` counts pairs.
uint64_t count_seam_mismatches(const ArchiveReader& reader, uint64_t& compared, std::string& first_problem);

// Cooks `options`, opens the result into `archive` and checks that it verifies and has no seam
// mismatch; `compared` is the number of vertex pairs the seam walk compared. Fatal test failures
// when the cook, the open or the verify fails.
void cook_and_verify(const cook::CookOptions& options, cook::CookReport& report, CookedArchive& archive,
                     uint64_t& compared);

// Two readers' rasters of one file agree: size, every value and georeferencing bit, nodata,
// description and CRS (GoogleTest expectations).
void expect_same_raster(const cook::Raster& a, const cook::Raster& b);

// Runs `cmd` through the shell; its standard output in `out`. True when it exits 0.
bool run_command(const std::string& cmd, std::string& out);

}  // namespace terrain::test
