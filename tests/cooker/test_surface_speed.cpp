// The surface stage's faster forms against their definitions, bit for bit: normal_error (4 lanes)
// against normal_error_per_texel, check_albedo (integer sums) against the per-texel double loop,
// and compute_normal_texels' block AO (4 blocks per lane group) against the per-block loop.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "normals.h"
#include "surface_encoders.h"
#include "surface_layers.h"
#include "terrain/bc_decode.h"
#include "terrain/surface_contract.h"

using namespace terrain;
using namespace terrain::cook;

namespace {

// Unit normals with tilts from flat to steep, some exactly (0, 0, 1).
void random_normals(std::mt19937& rng, float spread, NormalTexels& n) {
  std::normal_distribution<float> gauss(0.0f, spread);
  for (size_t k = 0; k < kTexelCount; ++k) {
    float v[3] = {gauss(rng), gauss(rng), 1.0f};
    if (rng() % 16 == 0) v[0] = v[1] = 0.0f;
    const float len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int c = 0; c < 3; ++c) n.n[k * 3 + size_t(c)] = v[c] / len;
  }
  for (float& a : n.ao) a = 1.0f;
}

void expect_same_angles(const NormalTexels& ref, const std::vector<uint8_t>& blocks, const char* what) {
  const AngleStats got = normal_error(ref, blocks.data());
  const AngleStats want = normal_error_per_texel(ref, blocks.data());
  EXPECT_EQ(got.count, want.count) << what;
  EXPECT_EQ(got.sum_deg, want.sum_deg) << what;  // the same doubles summed in the same order
  EXPECT_EQ(got.max_deg, want.max_deg) << what;
}

}  // namespace

// Encoded normals (small angles, the usual case), random BC3 bytes (decoded normals outside the
// unit disc, whose x and y unpack_normal rescales), decoded normals perpendicular to the reference
// (a zero dot product) and equal to it (a zero cross product).
TEST(SurfaceSpeed, NormalErrorEqualsThePerTexelLoop) {
  std::mt19937 rng(20261207);
  std::vector<uint8_t> blocks(size_t(kTexelBlocks) * kTexelBlocks * 16);
  std::array<uint8_t, kTexelCount * 4> rgba{};
  for (float spread : {0.02f, 0.3f, 2.0f}) {
    NormalTexels ref;
    random_normals(rng, spread, ref);
    pack_normal_texels(ref, rgba);
    encode_bc3_image(rgba.data(), Bc3Method::g_axis_fit, blocks.data());
    expect_same_angles(ref, blocks, "encoded");
    const AngleStats st = normal_error(ref, blocks.data());
    EXPECT_GT(st.sum_deg, 0.0);
    if (spread < 0.1f) {
      EXPECT_LT(st.sum_deg / double(st.count), 2.0);  // near-flat normals survive BC3 closely
    }
  }
  NormalTexels up;
  random_normals(rng, 0.0f, up);  // all (0, 0, 1)
  for (int trial = 0; trial < 5; ++trial) {
    for (uint8_t& b : blocks) b = uint8_t(rng());
    expect_same_angles(up, blocks, "random bytes");
    NormalTexels tilted;
    random_normals(rng, 1.0f, tilted);
    expect_same_angles(tilted, blocks, "random bytes, tilted");
  }
  // Alpha (x) 255 and G (y) 255 everywhere: decoded (1, 1) -> rescaled into the plane z = 0, so
  // against (0, 0, 1) every dot product is 0 and every angle 90 degrees.
  for (size_t b = 0; b < blocks.size(); b += 16) {
    const uint8_t block[16] = {255, 255, 0, 0, 0, 0, 0, 0, 0xE0, 0x07, 0xE0, 0x07, 0, 0, 0, 0};
    std::memcpy(&blocks[b], block, 16);
  }
  expect_same_angles(up, blocks, "perpendicular");
  EXPECT_NEAR(normal_error(up, blocks.data()).max_deg, 90.0, 1e-3);
  // The reference set to the decoded normals: zero angles.
  for (uint8_t& b : blocks) b = uint8_t(rng());
  NormalTexels same;
  std::vector<uint8_t> decoded(kTexelCount * 4);
  decode_bc3_image(blocks.data(), kTexelBlocks, kTexelBlocks, decoded.data());
  for (size_t k = 0; k < kTexelCount; ++k) unpack_normal(&decoded[k * 4], &same.n[k * 3]);
  expect_same_angles(same, blocks, "equal");
  EXPECT_LT(normal_error(same, blocks.data()).max_deg, 1e-3);
}

// check_albedo against the per-texel double loop it replaced, on images with holes, colours far
// from and near to their blocks, and random BC1 bytes (3-colour blocks with transparent texels).
TEST(SurfaceSpeed, AlbedoCheckEqualsThePerTexelLoop) {
  std::mt19937 rng(20261207);
  std::vector<uint8_t> rgba(kTexelCount * 4), blocks(size_t(kTexelBlocks) * kTexelBlocks * 8);
  for (int trial = 0; trial < 6; ++trial) {
    for (size_t k = 0; k < kTexelCount; ++k) {
      for (int c = 0; c < 3; ++c) rgba[k * 4 + size_t(c)] = uint8_t(trial < 3 ? 100 + rng() % 40 : rng());
      rgba[k * 4 + 3] = rng() % 5 == 0 ? uint8_t(rng() % 128) : uint8_t(128 + rng() % 128);
    }
    if (trial % 2 == 0)
      encode_bc1_image(rgba.data(), Bc1Method::axis_fit_hard, blocks.data());
    else
      for (uint8_t& b : blocks) b = uint8_t(rng());
    AlbedoCheck want;
    std::vector<uint8_t> decoded(kTexelCount * 4);
    decode_bc1_image(blocks.data(), kTexelBlocks, kTexelBlocks, decoded.data());
    for (int by = 0; by < kTexelBlocks; ++by)  // block order, as the per-texel visitor walked
      for (int bx = 0; bx < kTexelBlocks; ++bx)
        for (int i = 0; i < 16; ++i) {
          const size_t k = size_t((by * 4 + i / 4) * kTexels + bx * 4 + i % 4);
          const bool hole = rgba[k * 4 + 3] < 128, transparent = decoded[k * 4 + 3] == 0;
          if (hole != transparent) ++want.alpha_mismatches;
          if (hole) {
            ++want.holes;
            continue;
          }
          for (int ch = 0; ch < 3; ++ch) {
            const double d = double(rgba[k * 4 + size_t(ch)]) - decoded[k * 4 + size_t(ch)];
            want.sq_err += d * d;
          }
          want.samples += 3;
        }
    const AlbedoCheck got = check_albedo(rgba.data(), blocks.data());
    EXPECT_EQ(got.sq_err, want.sq_err) << trial;
    EXPECT_EQ(got.samples, want.samples) << trial;
    EXPECT_EQ(got.holes, want.holes) << trial;
    EXPECT_EQ(got.alpha_mismatches, want.alpha_mismatches) << trial;
    EXPECT_GT(want.holes, 2000u);
    EXPECT_GT(want.sq_err, 0.0);
    if (trial % 2 == 1) {
      EXPECT_GT(want.alpha_mismatches, 0u);
    }
  }
}

// The block AO of compute_normal_texels against the per-block loop over the 9 x 9 neighbourhood:
// rough terrain with pits, NaN runs (missing data) in places that drop some, most or all of a
// block's ring or centre, on a window whose values span many binades. (A lane reading another
// block's heights fails it; the order of the double sums seldom shows in the float AO.)
TEST(SurfaceSpeed, BlockAoEqualsThePerBlockLoop) {
  std::mt19937 rng(20261207);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  std::vector<float> h(static_cast<size_t>(kWindowCount));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int trial = 0; trial < 4; ++trial) {
    for (size_t k = 0; k < h.size(); ++k) {
      const float scale = trial == 3 ? std::ldexp(1.0f, int(rng() % 40) - 20) : 50.0f;
      h[k] = scale * uni(rng) + (trial == 2 ? 3000.0f : 0.0f);
    }
    if (trial >= 1)
      for (int run = 0; run < 300; ++run) {  // NaN rectangles of 1..12 samples a side
        const int w = 1 + int(rng() % 12), ht = 1 + int(rng() % 12);
        const int x0 = int(rng() % uint32_t(kWindowSize - w)), y0 = int(rng() % uint32_t(kWindowSize - ht));
        for (int y = y0; y < y0 + ht; ++y)
          for (int x = x0; x < x0 + w; ++x) h[size_t(y * kWindowSize + x)] = nan;
      }
    SurfaceInput in;
    in.heights_m = h.data();
    in.spacing_m = trial == 3 ? 0.5 : 2.0;
    NormalTexels got;
    compute_normal_texels(in, got);
    int below_one = 0, ones_without_data = 0;
    for (int by = 0; by < kTexelBlocks; ++by)
      for (int bx = 0; bx < kTexelBlocks; ++bx) {
        const int i0 = bx * 4 - kApron, j0 = by * 4 - kApron;
        double inner = 0, ring = 0;
        int ni = 0, nr = 0;
        for (int b = -2; b <= 6; ++b)
          for (int a = -2; a <= 6; ++a) {
            const bool border = a == -2 || a == 6 || b == -2 || b == 6;
            const bool centre = a >= 0 && a <= 4 && b >= 0 && b <= 4;
            if (!border && !centre) continue;
            const float v = h[size_t((j0 + b + kWindowMargin) * kWindowSize + (i0 + a + kWindowMargin))];
            if (std::isnan(v)) continue;
            if (border) { ring += v; ++nr; } else { inner += v; ++ni; }
          }
        float want = 1.0f;
        if (ni && nr) {
          const double depth = std::max(0.0, ring / nr - inner / ni);
          const double r = depth / (4.0 * in.spacing_m);
          want = float(1.0 / (1.0 + r * r));
        } else {
          ++ones_without_data;
        }
        below_one += want < 1.0f;
        ASSERT_EQ(got.ao[size_t(by * kTexelBlocks + bx)], want) << "trial " << trial << " block " << bx << "," << by;
      }
    EXPECT_GT(below_one, 100) << trial;
    if (trial >= 1) {
      EXPECT_GT(ones_without_data, 0) << trial;
    }
  }
}
