// SurfaceSampler: the renderer's surface (SW-NE diagonal, holes drop triangles, finest node).
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "archive_fixture.h"
#include "scratch_archive_test.h"
#include "terrain/sample.h"
#include "test_data.h"

namespace terrain {
namespace {

class Sampler : public test::ScratchArchiveTest {
 protected:
  // Writes an archive of the one root `rec` with `node`'s sections and opens it in reader_.
  void open_one_root(const WorldInfo& w, const NodeRecord& rec, const NodeData& node) {
    ArchiveWriter writer;
    ASSERT_TRUE(writer.open(path_).ok());
    std::vector<uint8_t> payload;
    ASSERT_TRUE(encode_node_payload(node, {}, payload).ok());
    ASSERT_TRUE(writer.add_node(rec, payload).ok());
    ASSERT_TRUE(writer.finish(w).ok());
    ASSERT_TRUE(reader_.open(path_).ok());
  }
};

// The seed chain is the plane h = (2x + 4y) / 32 m (x, y from the origin) with a round hole of
// radius 20 m at (300, 200); its finest node is 0/4/3.
TEST_F(Sampler, PlaneIsReproducedExactlyFromTheFinestNode) {
  ASSERT_NO_FATAL_FAILURE(open_seed_chain());
  const WorldInfo& w = reader_.world();
  SurfaceSampler sampler(reader_);
  std::mt19937 rng(3);
  int checked = 0, holes = 0;
  for (int t = 0; t < 2000; ++t) {
    const double x = std::uniform_real_distribution<double>(0, 2048)(rng), y = std::uniform_real_distribution<double>(0, 2048)(rng);
    std::optional<SurfaceSample> got;
    ASSERT_TRUE(sampler.sample(w.origin_x_m + x, w.origin_y_m + y, got).ok());
    const bool in_leaf = x >= 256 && x < 320 && y >= 192 && y < 256;
    const double r = std::hypot(x - 300, y - 200);
    if (r < 19.0) {  // every triangle near the centre touches a hole vertex (spacing <= 16 m)
      EXPECT_FALSE(got.has_value()) << x << "," << y;
      ++holes;
      continue;
    }
    if (r < 45.0) continue;  // near the rim the answer depends on the level's vertices
    ASSERT_TRUE(got.has_value()) << x << "," << y;
    EXPECT_NEAR(got->height_m, (2 * x + 4 * y) / 32.0, 1e-9) << x << "," << y;
    if (in_leaf) {
      EXPECT_EQ(got->node.level, 0u);
    }
    ++checked;
  }
  EXPECT_GT(checked, 1500);
  EXPECT_GT(holes, 0);
}

TEST_F(Sampler, OutsideTheFrameIsNodata) {
  ASSERT_NO_FATAL_FAILURE(open_seed_chain());
  const WorldInfo& w = reader_.world();
  SurfaceSampler sampler(reader_);
  std::optional<SurfaceSample> got;
  for (auto [dx, dy] : {std::pair{-1.0, 10.0}, {10.0, -0.001}, {2048.5, 10.0}, {10.0, 3000.0}}) {
    ASSERT_TRUE(sampler.sample(w.origin_x_m + dx, w.origin_y_m + dy, got).ok());
    EXPECT_FALSE(got.has_value()) << dx << "," << dy;
  }
  // The far north-east corner is answered by the root (closed edge of the frame).
  ASSERT_TRUE(sampler.sample(w.origin_x_m + 2048, w.origin_y_m + 2048, got).ok());
  ASSERT_TRUE(got.has_value());
  EXPECT_DOUBLE_EQ(got->height_m, (2 * 2048.0 + 4 * 2048.0) / 32.0);
}

// One raised vertex tells the diagonals apart: with the SW-NE split, quad (10, 20)'s NE vertex
// D only affects points of triangle ABD as fv * D and of ADC as fu * D; with the other diagonal a
// point near B would not see D at all.
TEST_F(Sampler, QuadsSplitAlongTheSouthWestToNorthEastDiagonal) {
  WorldInfo w = test::make_world(1, 1);
  w.step_log2 = {0, 0, 0, 0, 0, 0};
  auto node = std::make_unique<NodeData>();
  std::fill(node->albedo_bc1.begin(), node->albedo_bc1.end(), 0);
  for (size_t b = 0; b < node->albedo_bc1.size(); b += 8) node->albedo_bc1[b] = 1;  // c0 = 1 > c1 = 0: opaque
  node->heights[size_t(21 * kHeightSamples + 11)] = 1024;  // vertex (11, 21) = 1 m
  NodeRecord rec;
  rec.key = {5, 0, 0};
  rec.max_height = 1024;
  ASSERT_NO_FATAL_FAILURE(open_one_root(w, rec, *node));
  SurfaceSampler sampler(reader_);
  const double s = vertex_spacing_m(5);
  auto at = [&](double fu, double fv) {
    std::optional<SurfaceSample> got;
    EXPECT_TRUE(sampler.sample(w.origin_x_m + (10 + fu) * s, w.origin_y_m + (20 + fv) * s, got).ok());
    return got ? got->height_m : -1.0;
  };
  EXPECT_NEAR(at(0.75, 0.25), 0.25, 1e-9);  // triangle A B D: fv * D
  EXPECT_NEAR(at(0.25, 0.75), 0.25, 1e-9);  // triangle A D C: fu * D
  EXPECT_NEAR(at(0.9, 0.1), 0.1, 1e-9);     // near B: the other diagonal would give 0
  EXPECT_NEAR(at(0.5, 0.5), 0.5, 1e-9);     // on the diagonal
}

TEST_F(Sampler, TrianglesTouchingAHoleAreDropped) {
  const WorldInfo w = test::make_world(1, 1);
  auto node = std::make_unique<NodeData>();
  // Opaque everywhere except vertex (40, 50): texel (42, 52) -> block (10, 13), pixel (2, 0).
  for (size_t b = 0; b < node->albedo_bc1.size(); b += 8) node->albedo_bc1[b] = 1;
  uint8_t* blk = node->albedo_bc1.data() + size_t(13 * kTexelBlocks + 10) * 8;
  blk[0] = 0;
  blk[2] = 1;              // c0 <= c1: punch-through mode
  blk[4] = uint8_t(3 << 4);  // pixel (2, 0) = index 3 = transparent
  NodeRecord rec;
  rec.key = {5, 0, 0};
  rec.flags = kNodeFlagHasHoles;
  ASSERT_NO_FATAL_FAILURE(open_one_root(w, rec, *node));
  ASSERT_TRUE(reader_.verify().ok());
  SurfaceSampler sampler(reader_);
  const double s = vertex_spacing_m(5);
  auto has = [&](double u, double v) {
    std::optional<SurfaceSample> got;
    EXPECT_TRUE(sampler.sample(w.origin_x_m + u * s, w.origin_y_m + v * s, got).ok());
    return got.has_value();
  };
  // The hole vertex (40, 50) is A of quad (40, 50), D of quad (39, 49), B of (39, 50), C of (40, 49).
  EXPECT_FALSE(has(40.5, 50.2));   // quad (40,50) ABD
  EXPECT_FALSE(has(40.2, 50.5));   // quad (40,50) ADC
  EXPECT_FALSE(has(39.5, 49.2));   // quad (39,49) ABD (D is the hole)
  EXPECT_FALSE(has(39.8, 50.1));   // quad (39,50) ABD (B is the hole)
  EXPECT_TRUE(has(39.2, 50.8));    // quad (39,50) ADC: A (39,50), D (40,51), C (39,51): no hole
  EXPECT_FALSE(has(40.1, 49.8));   // quad (40,49) ADC: C = (40,50) is the hole
  EXPECT_TRUE(has(40.8, 49.1));    // quad (40,49) ABD: A (40,49), B (41,49), D (41,50): no hole
  // SPEC section 10, shared edges: (39, 49.5) lies on quad (39,49)'s ADC (D = (40,50) is the hole)
  // and on quad (38,49)'s ABD (no hole), so it is drawn; (40, 49.5) lies only on triangles
  // touching the hole vertex.
  EXPECT_TRUE(has(39.0, 49.5));
  EXPECT_FALSE(has(40.0, 49.5));
}

}  // namespace
}  // namespace terrain
