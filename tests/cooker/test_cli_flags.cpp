// The terrain-cook flags that had no test, each run through the command line on inputs the test
// writes, and checked through the archive reader: heights within the quantization step of the
// value the flag implies, holes where nodata is a hole, the first listed input winning a mosaic.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>

#include "cooker_test_util.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

constexpr double kMm = 1e-3;
constexpr int kW = 65, kH = 33;  // raw grid: 65 x 33 samples at 2 m, south-west sample at (100, 200)

// Runs terrain-cook with `args`; returns its exit code.
int cook_cli(const std::string& args) {
  std::string cmd(1, '\'');  // built by appending: GCC 12's -Wrestrict misfires on "'" + string
  cmd += (bin_dir() / "terrain-cook").string();
  cmd += "' " + args + " --quiet --threads 2";
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

// The raw heightmap's value at (col, row), row 0 north: a plane that spans negative values, so a
// signed/unsigned or byte-order misreading changes it by far more than the step.
double plane(int col, int row) { return -300.0 + 10.0 * col + 3.0 * (kH - 1 - row); }

// Writes kW x kH samples of `value` as `type` (u16, i16, f32) in the byte order asked for.
void write_raw(const std::string& path, const std::string& type, bool big_endian,
               const std::function<double(int, int)>& value) {
  std::ofstream f(path, std::ios::binary);
  for (int row = 0; row < kH; ++row)
    for (int col = 0; col < kW; ++col) {
      unsigned char b[4];
      int n = 2;
      const double v = value(col, row);
      if (type == "f32") {
        const float x = float(v);
        uint32_t u;
        std::memcpy(&u, &x, 4);
        for (int i = 0; i < 4; ++i) b[i] = uint8_t(u >> (8 * i));
        n = 4;
      } else {
        const uint16_t u = type == "i16" ? uint16_t(int16_t(std::lround(v))) : uint16_t(std::lround(v));
        b[0] = uint8_t(u & 0xFF);
        b[1] = uint8_t(u >> 8);
      }
      if (big_endian) std::reverse(b, b + n);
      f.write(reinterpret_cast<const char*>(b), n);
    }
}

std::string raw_flags(const std::string& type) {
  return "--raw-size " + std::to_string(kW) + "x" + std::to_string(kH) + " --raw-type " + type +
         " --spacing 2 --origin 100,200 --crs local";
}
double frame_x(int col) { return 100.0 + 2.0 * col; }
double frame_y(int row) { return 200.0 + 2.0 * (kH - 1 - row); }

// Largest |archive height - expected| over the interior samples (edges excluded: the border
// vertices of the outermost nodes are clamped); NaN when a sample has no terrain.
double worst_error(CookedArchive& a, const std::function<double(int, int)>& expected) {
  double worst = 0;
  for (int row = 1; row < kH - 1; ++row)
    for (int col = 1; col < kW - 1; ++col) {
      const auto z = a.height(frame_x(col), frame_y(row));
      if (!z) return std::nan("");
      worst = std::max(worst, std::fabs(*z - expected(col, row)));
    }
  return worst;
}

}  // namespace

// --raw-type i16 and f32, --raw-big-endian, --height-offset: the plane comes back within half a
// quantization step + 1 mm. Control: the big-endian file read as little-endian is far off.
TEST(CookFlags, RawTypesByteOrderAndHeightOffset) {
  const auto dir = scratch_dir("cooker-flags-raw");
  struct Case { std::string type; bool big; double offset; };
  for (const Case& c : {Case{"i16", true, 0.0}, Case{"f32", true, 0.0},
                        Case{"f32", false, 1234.5}, Case{"u16", true, 0.0}}) {
    SCOPED_TRACE(c.type + (c.big ? " big-endian" : " little-endian") + " offset " + std::to_string(c.offset));
    // u16 cannot hold the plane's negative values: shift it up by 1000 in the file, and back down
    // with --height-offset -1000.
    const double file_shift = c.type == "u16" ? 1000.0 : 0.0;
    const double offset = c.type == "u16" ? -1000.0 : c.offset;
    const std::string raw = (dir / ("map-" + c.type + (c.big ? "-be" : "-le") + ".raw")).string();
    write_raw(raw, c.type, c.big, [&](int col, int row) { return plane(col, row) + file_shift; });
    const std::string out = (dir / "map.terrain").string();
    const std::string flags = raw_flags(c.type) + (c.big ? " --raw-big-endian" : "") +
                              " --height-offset " + std::to_string(offset) + " --heights-only";
    ASSERT_EQ(cook_cli("'" + raw + "' -o '" + out + "' " + flags), 0);
    CookedArchive a;
    ASSERT_TRUE(a.open(out).ok());
    const double worst = worst_error(a, [&](int col, int row) { return plane(col, row) + file_shift + offset; });
    EXPECT_LE(worst, a.max_half_step() + kMm);
    // Control: the same bytes without --raw-big-endian are other heights (or heights out of range,
    // which the cook rejects); never the plane.
    if (c.big && cook_cli("'" + raw + "' -o '" + out + "' " + raw_flags(c.type) + " --heights-only") == 0) {
      CookedArchive b;
      ASSERT_TRUE(b.open(out).ok());
      const double wrong = worst_error(b, [&](int col, int row) { return plane(col, row) + file_shift; });
      EXPECT_FALSE(wrong <= 1.0) << wrong;  // NaN (all-nodata misread) or far off
    }
  }
}

// --nodata-value marks a 5 x 5 block of -77 as nodata; --nodata hole leaves it a hole (no height,
// the node flagged has_holes), --nodata fill fills it (a plane: the fill lies between the
// neighbours' extremes). Control: without --nodata-value the block is terrain at -77 m.
TEST(CookFlags, NodataValueHoleAndFill) {
  const auto dir = scratch_dir("cooker-flags-nodata");
  const std::string raw = (dir / "voids.r32").string();
  auto in_void = [](int col, int row) { return col >= 30 && col < 35 && row >= 14 && row < 19; };
  write_raw(raw, "f32", false, [&](int col, int row) { return in_void(col, row) ? -77.0 : plane(col, row); });
  const std::string out = (dir / "voids.terrain").string();
  const double vx = frame_x(32), vy = frame_y(16);  // the void's centre sample

  ASSERT_EQ(cook_cli("'" + raw + "' -o '" + out + "' " + raw_flags("f32") + " --nodata-value -77 --nodata hole"), 0);
  {
    CookedArchive a;
    ASSERT_TRUE(a.open(out).ok());
    const NodeRecord* node = nullptr;
    EXPECT_FALSE(a.height(vx, vy)) << "a nodata sample with --nodata hole has terrain";
    const auto beside = a.height(frame_x(20), frame_y(16), &node);
    ASSERT_TRUE(beside);
    EXPECT_NEAR(*beside, plane(20, 16), a.max_half_step() + kMm);
    ASSERT_NE(node, nullptr);
    EXPECT_TRUE(node->flags & 1) << "node with a hole vertex is not flagged has_holes";
  }
  ASSERT_EQ(cook_cli("'" + raw + "' -o '" + out + "' " + raw_flags("f32") + " --nodata-value -77 --nodata fill"), 0);
  {
    CookedArchive a;
    ASSERT_TRUE(a.open(out).ok());
    const auto z = a.height(vx, vy);
    ASSERT_TRUE(z) << "--nodata fill left a hole";
    // The void's ring spans plane(29..35, 13..19); a fill from the ring stays inside it.
    EXPECT_GE(*z, plane(29, 19) - a.max_half_step() - kMm);
    EXPECT_LE(*z, plane(35, 13) + a.max_half_step() + kMm);
  }
  ASSERT_EQ(cook_cli("'" + raw + "' -o '" + out + "' " + raw_flags("f32")), 0);
  {
    CookedArchive a;
    ASSERT_TRUE(a.open(out).ok());
    const auto z = a.height(vx, vy);
    ASSERT_TRUE(z);
    EXPECT_NEAR(*z, -77.0, a.max_half_step() + kMm);
  }
}

// Mosaic precedence: two overlapping GeoTIFFs on one pixel grid, 100 m and 200 m; where they
// overlap the first listed input wins, in either order.
TEST(CookFlags, MosaicOverlapFirstListedWins) {
  const auto dir = scratch_dir("cooker-flags-mosaic");
  auto dem = [](double value, double east) {
    SyntheticDem d;
    d.width = d.height = 64;
    d.values.assign(64 * 64, value);
    d.dx = d.dy = 4.0;
    d.x0 = east;
    d.y0 = 5018110.0;
    d.epsg_projected = 32632;
    return d;
  };
  // A covers x 510002..510254, B 32 samples further east: overlap x 510130..510254.
  const std::string a_path = (dir / "a.tif").string(), b_path = (dir / "b.tif").string();
  std::string error;
  ASSERT_TRUE(write_geotiff(a_path, dem(100.0, 510002.0), true, error)) << error;
  ASSERT_TRUE(write_geotiff(b_path, dem(200.0, 510002.0 + 32 * 4.0), true, error)) << error;
  const std::string out = (dir / "m.terrain").string();
  const double y = 5018110.0 - 30 * 4.0;
  for (bool a_first : {true, false}) {
    SCOPED_TRACE(a_first ? "a.tif first" : "b.tif first");
    const std::string inputs = a_first ? "'" + a_path + "' '" + b_path + "'" : "'" + b_path + "' '" + a_path + "'";
    ASSERT_EQ(cook_cli(inputs + " -o '" + out + "' --heights-only"), 0);
    CookedArchive m;
    ASSERT_TRUE(m.open(out).ok());
    // A UTM input keeps its zone as the archive frame, so frame coordinates are the GeoTIFF's.
    auto at = [&](double east) { return m.height(east, y); };
    const auto only_a = at(510002.0 + 10 * 4.0), only_b = at(510002.0 + 80 * 4.0), both = at(510002.0 + 48 * 4.0);
    ASSERT_TRUE(only_a && only_b && both);
    const double tol = m.max_half_step() + kMm;
    EXPECT_NEAR(*only_a, 100.0, tol);
    EXPECT_NEAR(*only_b, 200.0, tol);
    EXPECT_NEAR(*both, a_first ? 100.0 : 200.0, tol);
  }
}

// --materials through a cook: a rules file the test writes with two materials, "low" by default
// and "high" from 150 m (fade 1 m). Over a ramp from -300 m to 340 m every splat sample more than
// 2 m + the quantization step below 150 m is "low" (index 0) and every one above is "high"
// (index 1), and the archive's palette is the file's.
TEST(CookFlags, MaterialsRulesFileDrivesTheSplatMap) {
  const auto dir = scratch_dir("cooker-flags-materials");
  const std::string rules = (dir / "rules.json").string();
  {
    std::ofstream f(rules);
    f << R"({"format": "terrain-material-rules", "version": 1,
  "materials": [
    {"name": "low",  "albedo_srgb": [10, 20, 30], "roughness": 0.5, "detail_scale_m": 2, "detail_strength": 0, "height_blend": 0},
    {"name": "high", "albedo_srgb": [200, 210, 220], "roughness": 0.5, "detail_scale_m": 2, "detail_strength": 0, "height_blend": 0}],
  "default_material": "low",
  "rules": [{"material": "high", "height_m": {"min": 150, "fade": 1}}]})";
  }
  const std::string raw = (dir / "ramp.r32").string();
  write_raw(raw, "f32", false, plane);
  const std::string out = (dir / "ramp.terrain").string();
  ASSERT_EQ(cook_cli("'" + raw + "' -o '" + out + "' " + raw_flags("f32") + " --materials '" + rules + "'"), 0);
  CookedArchive a;
  ASSERT_TRUE(a.open(out).ok());
  const WorldInfo& w = a.reader.world();
  ASSERT_EQ(w.palette.size(), 2u);
  EXPECT_EQ(w.palette[0].name, "low");
  EXPECT_EQ(w.palette[1].name, "high");
  size_t low = 0, high = 0;
  for (size_t n = 0; n < a.reader.nodes().size(); ++n) {
    const NodeRecord& rec = a.reader.nodes()[n];
    auto data = std::make_unique<NodeData>();
    ASSERT_TRUE(a.reader.decode_node(n, *data, kSectionSplat).ok());
    const int level = int(rec.key.level);
    const double x0 = w.origin_x_m + rec.key.x * node_size_m(level), y0 = w.origin_y_m + rec.key.y * node_size_m(level);
    const double margin = 2.0 + a.max_half_step();
    for (int j = 0; j < kSplatSamples; ++j)
      for (int i = 0; i < kSplatSamples; ++i) {
        const double x = x0 + 2 * i * vertex_spacing_m(level), y = y0 + 2 * j * vertex_spacing_m(level);
        if (x < 102 || x > 100 + 2 * (kW - 2) || y < 202 || y > 200 + 2 * (kH - 2)) continue;  // inside the data
        const auto h = a.height(x, y);
        if (!h) continue;
        const uint8_t m = data->splat[size_t(j * kSplatSamples + i)];
        if (*h < 150 - margin) {
          EXPECT_EQ(m, 0) << "at " << x << "," << y << " height " << *h;
          ++low;
        } else if (*h > 150 + margin) {
          EXPECT_EQ(m, 1) << "at " << x << "," << y << " height " << *h;
          ++high;
        }
      }
  }
  EXPECT_GT(low, 100u);
  EXPECT_GT(high, 100u);
}

// --bc-quality: fast and best encode the same normals and albedo differently (the encoder effort
// reaches the bytes) while the heights are identical; each decodes to an archive that verifies.
TEST(CookFlags, BcQualityChangesOnlyTheBlockCompressedLayers) {
  const auto dir = scratch_dir("cooker-flags-bc");
  const std::string raw = (dir / "hills.r32").string();
  write_raw(raw, "f32", false,
            [](int col, int row) { return 50.0 + 20.0 * std::sin(col * 0.37) * std::cos(row * 0.53) + 0.1 * (col * row % 7); });
  std::unique_ptr<NodeData> nodes[2][64];
  size_t count[2] = {0, 0};
  const char* quality[2] = {"fast", "best"};
  for (int q = 0; q < 2; ++q) {
    const std::string out = (dir / (std::string(quality[q]) + ".terrain")).string();
    ASSERT_EQ(cook_cli("'" + raw + "' -o '" + out + "' " + raw_flags("f32") + " --bc-quality " + quality[q]), 0);
    ArchiveReader r;
    ASSERT_TRUE(r.open(out).ok());
    count[q] = r.nodes().size();
    ASSERT_LE(count[q], 64u);
    for (size_t n = 0; n < count[q]; ++n) {
      nodes[q][n] = std::make_unique<NodeData>();
      ASSERT_TRUE(r.decode_node(n, *nodes[q][n]).ok());
    }
  }
  ASSERT_EQ(count[0], count[1]);
  size_t normals_differ = 0, albedo_differ = 0;
  for (size_t n = 0; n < count[0]; ++n) {
    EXPECT_EQ(nodes[0][n]->heights, nodes[1][n]->heights) << "node " << n;
    normals_differ += nodes[0][n]->normals_bc3 != nodes[1][n]->normals_bc3;
    albedo_differ += nodes[0][n]->albedo_bc1 != nodes[1][n]->albedo_bc1;
  }
  EXPECT_GT(normals_differ + albedo_differ, 0u) << "--bc-quality fast and best wrote the same blocks";
}
