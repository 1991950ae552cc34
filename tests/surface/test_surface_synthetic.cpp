// cook_surface_layers on synthetic terrain: flat patches, cliffs, ridges whose normals spread past
// 90 degrees, holes, the edge of the data, determinism and seams between neighbouring nodes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <thread>
#include <utility>
#include <vector>

#include "bc_blocks.h"
#include "terrain/surface_contract.h"
#include "cones.h"
#include "normals.h"
#include "surface_encoders.h"
#include "surface_test_support.h"

using namespace terrain;
using namespace terrain::cook;
using namespace terrain::cook::test;

namespace {

double rolling(double x, double y) { return 300 + 20 * std::sin(x / 37.0) * std::cos(y / 23.0) + 0.05 * x; }

// Decoded cone of patch k.
cone::DecodedCone decoded_cone(const NodeData& d, int k) {
  const int p = k % 8, q = k / 8;
  uint8_t dec[64];
  decode_bc3_block(d.cones_bc3.data() + 16 * ((q / 4) * 2 + p / 4), dec);
  const int t = (q % 4) * 4 + p % 4;
  return cone::decode_cone_texel(dec[4 * t], dec[4 * t + 1], dec[4 * t + 3]);
}

}  // namespace

TEST(SurfaceSynthetic, FlatNodeHasZeroAngleConesThatCullFromBelow) {
  const auto node = synthetic_node([](double, double) { return 100.0; }, 0, 2, 3);
  const Cooked c = cook_node(node, default_rules());
  ASSERT_TRUE(c.status.ok()) << c.status.to_string();
  PatchNormals pn;
  collect_patch_normals(node.node, node.height_offset, node.step_log2, node.spacing_m, node.holes.data(), pn);
  for (int k = 0; k < kPatchCount; ++k) {
    const Cone exact = smallest_enclosing_cone(pn.patch(k));
    EXPECT_EQ(exact.half_angle_rad, 0.0) << "patch " << k;
    EXPECT_DOUBLE_EQ(exact.axis[2], 1.0);
    const cone::DecodedCone d = decoded_cone(c.data, k);
    EXPECT_FALSE(d.never_cull);
    EXPECT_NEAR(d.axis[2], 1.0, 1e-12);
    // One alpha step of margin (0.35 degrees) on top of the exact angle 0.
    EXPECT_LE(d.half_angle_rad, 1.01 * kPi / 2 / 255) << "patch " << k;
  }
  // Seen from below every patch is back-facing; from above none is.
  const double below[3] = {500, 600, 50}, above[3] = {500, 600, 150};
  for (int k = 0; k < kPatchCount; ++k) {
    const double bmin[3] = {(k % 8) * 8.0, (k / 8) * 8.0, 100}, bmax[3] = {(k % 8 + 1) * 8.0, (k / 8 + 1) * 8.0, 100};
    EXPECT_TRUE(cone::cone_patch_backfacing(decoded_cone(c.data, k), below, bmin, bmax));
    EXPECT_FALSE(cone::cone_patch_backfacing(decoded_cone(c.data, k), above, bmin, bmax));
  }
  const ConeCheck check = check_cones(node, c.data, 300, 1);
  EXPECT_EQ(check.violations, 0u);
  // The cones do cull: check_cones draws eye heights uniformly in [h - 0.2 size, h + 0.5 size], so
  // a share p = 0.2 / 0.7 = 2/7 of the 300 eyes is below the plane, where all 64 patches are
  // back-facing (the 0.35 degree margin only spares eyes within tan(0.35 deg) * 1.5 size of the
  // plane, a negligible share); above it none is. Floor and ceiling: 64 * (300 p -+ 4 sigma),
  // sigma = sqrt(300 p (1 - p)) = 7.8 eyes, i.e. 64 * (85.7 -+ 31.3).
  const double p = 2.0 / 7.0, mean_eyes = 300 * p, sigma = std::sqrt(300 * p * (1 - p));
  EXPECT_GT(double(check.culled), 64 * (mean_eyes - 4 * sigma));
  EXPECT_LT(double(check.culled), 64 * (mean_eyes + 4 * sigma));
  std::printf("flat node: %llu of %llu patch tests culled (expected ~%.0f)\n", (unsigned long long)check.culled,
              (unsigned long long)check.patch_tests, 64 * mean_eyes);
  // Flat: normals decode exactly up, albedo opaque everywhere.
  const auto n = decode_normals(c.data);
  for (size_t k = 0; k < size_t(kTexels) * kTexels; ++k) {
    double v[3];
    texel_normal(&n[k * 4], v);
    ASSERT_EQ(v[2], 1.0);
  }
  EXPECT_EQ(c.stats.normal_err_max_deg, 0.0);
  for (int i = 0; i < kAlbedoBytes / 8; ++i) ASSERT_EQ(bc1_transparent_mask(c.data.albedo_bc1.data() + 8 * i), 0);
}

TEST(SurfaceSynthetic, NearVerticalCliffNormalsAndCones) {
  // A 400 m cliff between two vertices (x = 100 and 100.5 m, 89.9 degrees) across a gentle slope,
  // inside node (1, 1) of level 0 (x 64..128 m).
  auto f = [](double x, double y) { return 1000 + 0.2 * y + (x > 100.2 ? 400.0 : 0.0) + 0.05 * (x > 100.2 ? x - 100 : 0); };
  const auto node = synthetic_node(f, 0, 1, 1);
  const Cooked c = cook_node(node, default_rules());
  ASSERT_TRUE(c.status.ok());
  // The float normal of the cliff cell is ~89.9 degrees from up; the decoded one keeps that tilt.
  NormalTexels ref;
  compute_normal_texels(node.input(&default_rules(), BcQuality::balanced), ref);
  const auto dec = decode_normals(c.data);
  double worst_cliff = 0, worst_tilt = 90;
  int cliff_texels = 0;
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const size_t k = size_t(u * kTexels + t);
      if (ref.n[k * 3 + 2] > 0.1f) continue;  // only the near-vertical texels
      ++cliff_texels;
      double v[3];
      texel_normal(&dec[k * 4], v);
      const double dotp = v[0] * ref.n[k * 3] + v[1] * ref.n[k * 3 + 1] + v[2] * ref.n[k * 3 + 2];
      worst_cliff = std::max(worst_cliff, std::acos(std::min(1.0, dotp)) * 180 / kPi);
      worst_tilt = std::min(worst_tilt, std::acos(v[2]) * 180 / kPi);
    }
  ASSERT_EQ(cliff_texels, kTexels);  // one cell column holds the step
  std::printf("cliff texels %d: worst decoded error %.2f deg, least tilt %.2f deg\n", cliff_texels, worst_cliff, worst_tilt);
  EXPECT_LT(worst_cliff, 3.0);
  EXPECT_GT(worst_tilt, 85.0);
  // Cones of the cliff patches are wide, still conservative.
  const ConeCheck check = check_cones(node, c.data, 400, 2);
  EXPECT_EQ(check.violations, 0u);
  EXPECT_GT(check.culled, 100u);
}

TEST(SurfaceSynthetic, RidgeWithNormalsSpreadingPast90Degrees) {
  // A sharp ridge: faces at +-60 degrees, so normals spread 120 degrees inside one patch.
  const double k60 = std::tan(60 * kPi / 180);
  auto f = [&](double x, double y) { return 500 - k60 * std::fabs(x - 36.0) + 0.01 * y; };
  const auto node = synthetic_node(f, 0, 0, 1);
  const Cooked c = cook_node(node, default_rules());
  ASSERT_TRUE(c.status.ok());
  PatchNormals pn;
  collect_patch_normals(node.node, node.height_offset, node.step_log2, node.spacing_m, node.holes.data(), pn);
  // Ridge at x = 36 m: patch column 4 (32..40 m) holds both faces (normals 120 degrees apart), so
  // its cone is at least 60 degrees; the LOD-stitched edge triangles (a collapsed edge vertex joined
  // to row-1 vertices across the ridge) are steeper still and widen it toward 90 degrees.
  const int k = 1 * 8 + 4;
  const Cone exact = smallest_enclosing_cone(pn.patch(k));
  std::printf("ridge patch cone: exact %.2f deg, axis z %.4f, decoded %.2f deg\n", exact.half_angle_rad * 180 / kPi,
              exact.axis[2], decoded_cone(c.data, k).half_angle_rad * 180 / kPi);
  EXPECT_GE(exact.half_angle_rad * 180 / kPi, 59.9);
  EXPECT_LT(exact.half_angle_rad * 180 / kPi, 90.0);
  const cone::DecodedCone d = decoded_cone(c.data, k);
  EXPECT_GE(d.half_angle_rad, exact.half_angle_rad);
  EXPECT_GE(decoded_cone_slack(pn, c.data.cones_bc3.data()), 0.0);
  const ConeCheck check = check_cones(node, c.data, 400, 3);
  EXPECT_EQ(check.violations, 0u);
  EXPECT_GT(check.culled, 0u);
}

TEST(SurfaceSynthetic, SpikySurfaceConesStayConservative) {
  // Pseudo-random spikes up to 8 m on 0.5 m spacing (tree-top like), plus stitched edges.
  auto f = [](double x, double y) {
    const uint32_t h = uint32_t(x * 2) * 73856093u ^ uint32_t(y * 2) * 19349663u;
    return 2500 + ((h >> 7) % 1000) * 0.008;
  };
  const auto node = synthetic_node(f, 0, 1, 1);
  const Cooked c = cook_node(node, default_rules());
  ASSERT_TRUE(c.status.ok());
  const ConeCheck check = check_cones(node, c.data, 600, 4);
  EXPECT_EQ(check.violations, 0u) << "worst cos " << check.worst_cos;
  std::printf("spiky: %llu of %llu patch tests culled, worst triangle cos %.4f\n",
              (unsigned long long)check.culled, (unsigned long long)check.patch_tests, check.worst_cos);
}

TEST(SurfaceSynthetic, HolesSurviveAtVertexGranularity) {
  // A 1-vertex hole, a 3x2 hole and a hole touching the node's west edge.
  auto hole = [](double x, double y) {
    const int i = int(std::lround(x / 0.5)) - 128, j = int(std::lround(y / 0.5)) - 128;  // node (1,1) vertex
    return (i == 40 && j == 40) || (i >= 70 && i <= 72 && j >= 10 && j <= 11) || (i >= -3 && i <= 1 && j == 90);
  };
  const auto node = synthetic_node(rolling, 0, 1, 1, 2, hole);
  for (BcQuality q : {BcQuality::fast, BcQuality::balanced, BcQuality::best}) {
    const Cooked c = cook_node(node, default_rules(), q);
    ASSERT_TRUE(c.status.ok());
    const auto alb = decode_albedo(c.data);
    int holes = 0;
    for (int u = 0; u < kTexels; ++u)
      for (int t = 0; t < kTexels; ++t) {
        const bool want = texel_is_hole(node, t, u);
        holes += want;
        ASSERT_EQ(alb[size_t(u * kTexels + t) * 4 + 3] == 0, want) << "texel " << t << "," << u;
      }
    EXPECT_EQ(holes, 1 + 6 + 4);  // vertices -2..1 of the west hole are texels 0..3
    const ConeCheck check = check_cones(node, c.data, 100, 5);
    EXPECT_EQ(check.violations, 0u);
  }
}

TEST(SurfaceSynthetic, NodeAtTheEdgeOfTheDataCooksWithHolesAndFiniteNormals) {
  // Data only for x < 40 m: node (0, 1) at level 0 is cut by the edge of the data; the window's
  // west margin (x < 0) has no data either.
  auto f = [](double x, double y) { return x < 40.0 ? rolling(x, y) : NAN; };
  const auto node = synthetic_node(f, 0, 0, 1);
  ASSERT_GT(node.hole_vertices, 0);
  const Cooked c = cook_node(node, default_rules());
  ASSERT_TRUE(c.status.ok());
  const auto alb = decode_albedo(c.data);
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t)
      ASSERT_EQ(alb[size_t(u * kTexels + t) * 4 + 3] == 0, texel_is_hole(node, t, u));
  const auto n = decode_normals(c.data);
  for (size_t k = 0; k < size_t(kTexelCount); ++k) {
    double v[3];
    texel_normal(&n[k * 4], v);
    ASSERT_TRUE(std::isfinite(v[0]) && std::isfinite(v[2]) && v[2] > 0.5) << k;
  }
  // Patches entirely in the hole have no triangles and may be culled freely; the others hold.
  EXPECT_EQ(check_cones(node, c.data, 200, 6).violations, 0u);
}

TEST(SurfaceSynthetic, NeighboursAgreeOnTheirOverlap) {
  const auto a = synthetic_node(rolling, 0, 1, 1), b = synthetic_node(rolling, 0, 2, 1);  // b east of a
  NormalTexels na, nb;
  compute_normal_texels(a.input(&default_rules(), BcQuality::balanced), na);
  compute_normal_texels(b.input(&default_rules(), BcQuality::balanced), nb);
  // a's texel t (>= 128) covers the same cell as b's texel t - 128: identical float normals.
  for (int u = 0; u < kTexels; ++u)
    for (int t = 128; t < kTexels; ++t)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(na.n[size_t(u * kTexels + t) * 3 + size_t(c)], nb.n[size_t(u * kTexels + t - 128) * 3 + size_t(c)]);
  const Cooked ca = cook_node(a, default_rules()), cb = cook_node(b, default_rules());
  // Splat: a's east column is b's west column.
  for (int j = 0; j < kSplatSamples; ++j)
    ASSERT_EQ(ca.data.splat[size_t(j * kSplatSamples + 64)], cb.data.splat[size_t(j * kSplatSamples)]) << j;
  // Albedo before compression is identical on the overlap (same lattice, same colours).
  // After compression: decoded normals agree within the compression error of each node.
  const auto da = decode_normals(ca.data), db = decode_normals(cb.data);
  double worst = 0, sum = 0;
  int count = 0;
  for (int u = 0; u < kTexels; ++u)
    for (int t = 128; t < kTexels; ++t) {
      double va[3], vb[3];
      texel_normal(&da[size_t(u * kTexels + t) * 4], va);
      texel_normal(&db[size_t(u * kTexels + t - 128) * 4], vb);
      const double deg = std::acos(std::min(1.0, va[0] * vb[0] + va[1] * vb[1] + va[2] * vb[2])) * 180 / kPi;
      worst = std::max(worst, deg);
      sum += deg;
      ++count;
    }
  // Bound 0, not the encoder's reported error: the float normals are identical (asserted above)
  // and 128 is a multiple of the 4-texel block, so both nodes encode the same blocks from the same
  // texels with a deterministic encoder and decode them identically (SPEC 16.2).
  std::printf("overlap: mean %.3f deg, max %.3f deg over %d texels\n", sum / count, worst, count);
  // (acos of the dot product of two equal unit vectors rounds to ~1e-6 degrees, hence 1e-5.)
  EXPECT_LE(worst, 1e-5);
}

TEST(SurfaceSynthetic, CookingIsDeterministicAcrossThreads) {
  const auto node = synthetic_node(rolling, 1, 3, 2);
  const Cooked ref = cook_node(node, default_rules());
  ASSERT_TRUE(ref.status.ok());
  Cooked other[2];
  std::thread t0([&] { other[0] = cook_node(node, default_rules()); });
  std::thread t1([&] { other[1] = cook_node(node, default_rules()); });
  t0.join();
  t1.join();
  for (const Cooked& o : other) {
    EXPECT_EQ(o.data.normals_bc3, ref.data.normals_bc3);
    EXPECT_EQ(o.data.albedo_bc1, ref.data.albedo_bc1);
    EXPECT_EQ(o.data.splat, ref.data.splat);
    EXPECT_EQ(o.data.cones_bc3, ref.data.cones_bc3);
  }
}

TEST(SurfaceSynthetic, RejectsMissingInputs) {
  SurfaceInput in;
  NodeData d;
  const Status st = cook_surface_layers(in, d, 0, 0, d, nullptr);
  EXPECT_EQ(st.code, Error::invalid_argument);
}

namespace {
// Overlays as the cooker provides them, from functions of frame position: a mask and a photo
// with a solid colour east of x_photo (no data west of it).
struct FnOverlays final : SurfaceOverlays {
  std::function<bool(double, double)> hole;
  double x_photo = 0;
  uint8_t colour[3] = {200, 40, 90};
  bool photo = true;
  bool has_albedo() const override { return photo; }
  bool has_holes() const override { return true; }
  void sample(double x0, double y0, double s, uint8_t* rgb, uint8_t* valid, uint8_t* holes, uint8_t*) const override {
    for (int j = 0; j < kWindowSize; ++j)
      for (int i = 0; i < kWindowSize; ++i) {
        const size_t k = size_t(j * kWindowSize + i);
        const double x = x0 + (i - kWindowMargin) * s, y = y0 + (j - kWindowMargin) * s;
        if (holes) holes[k] = hole(x, y);
        if (rgb) {
          valid[k] = x >= x_photo;
          for (int c = 0; c < 3; ++c) rgb[k * 3 + size_t(c)] = valid[k] ? colour[c] : 0;
        }
      }
  }
};
}  // namespace

// Mask holes join the data holes exactly (every hole texel transparent, no other), the photo's
// colour replaces the splat bake where it has data (BC1 of a constant colour: within 4 levels),
// and the splat bake stays where it has none; cones ignore the masked vertices' triangles.
TEST(SurfaceSynthetic, OverlayHolesAndPhotoReachTheAlbedoExactly) {
  auto data_hole = [](double x, double y) {
    const int i = int(std::lround(x / 0.5)) - 128, j = int(std::lround(y / 0.5)) - 128;
    return i >= 20 && i <= 22 && j >= 20 && j <= 22;
  };
  const auto node = synthetic_node(rolling, 0, 1, 1, 2, data_hole);
  FnOverlays ov;
  ov.hole = [](double x, double y) {  // a single vertex, a diagonal stripe and a block on the south edge
    const int i = int(std::lround(x / 0.5)) - 128, j = int(std::lround(y / 0.5)) - 128;
    return (i == 100 && j == 100) || (i == j + 50 && i >= 60 && i < 90) || (i >= 30 && i <= 40 && j >= -2 && j <= 3);
  };
  ov.x_photo = 64.0 + 70 * 0.5;  // vertex column 70 of node (1, 1)
  FnOverlays mask_only = ov;
  mask_only.photo = false;
  SurfaceInput in = node.input(&default_rules(), BcQuality::balanced), plain_in = in;
  in.overlays = &ov;
  plain_in.overlays = &mask_only;
  NodeData with, without;
  with.heights = without.heights = node.node.heights;
  ASSERT_TRUE(cook_surface_layers(in, node.node, node.height_offset, node.step_log2, with, nullptr).ok());
  ASSERT_TRUE(cook_surface_layers(plain_in, node.node, node.height_offset, node.step_log2, without, nullptr).ok());
  const auto a = decode_albedo(with), b = decode_albedo(without);
  int mask_holes = 0, smooth_checked = 0;
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const double x = node.x0_m + (t - kApron) * node.spacing_m, y = node.y0_m + (u - kApron) * node.spacing_m;
      const bool want = texel_is_hole(node, t, u) || ov.hole(x, y);
      mask_holes += ov.hole(x, y) && !texel_is_hole(node, t, u);
      const uint8_t* p = &a[size_t(u * kTexels + t) * 4];
      ASSERT_EQ(p[3] == 0, want) << "texel " << t << "," << u;
      if (want) continue;
      // Texel (t, u) averages vertices t - 2 and t - 1: photo data when both are east of x_photo.
      const double west = node.x0_m + (t - kApron) * node.spacing_m;
      if (west >= ov.x_photo) {
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(p[c], ov.colour[c], 4) << "texel " << t << "," << u;
      } else if (west + 3 * node.spacing_m < ov.x_photo && t > 4 && u > 4 && u < kTexels - 4) {
        // Well west of the photo: the splat bake, as with the mask alone. Each vertex takes the
        // mean of its four texels and each texel the mean of its four vertices (a [1 2 1] blur),
        // so compare where the bake is locally smooth (range <= 4 levels around the block).
        const uint8_t* q = &b[size_t(u * kTexels + t) * 4];
        int range = 0;
        for (int c = 0; c < 3; ++c) {
          int lo = 255, hi = 0;
          // Over the texel's BC1 block and a ring around it (block-wise compression).
          for (int uu = u / 4 * 4 - 1; uu <= u / 4 * 4 + 4; ++uu)
            for (int tt = t / 4 * 4 - 1; tt <= t / 4 * 4 + 4; ++tt) {
              const int v = b[size_t(std::clamp(uu, 0, kTexels - 1) * kTexels + std::clamp(tt, 0, kTexels - 1)) * 4 + size_t(c)];
              lo = std::min(lo, v);
              hi = std::max(hi, v);
            }
          range = std::max(range, hi - lo);
        }
        if (range > 4) continue;
        ++smooth_checked;
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(p[c], q[c], 6) << "texel " << t << "," << u;
      }
    }
  EXPECT_GT(mask_holes, 60);
  EXPECT_GT(smooth_checked, 2000);
  EXPECT_EQ(check_cones(node, with, 200, 7).violations, 0u);
}

// The cheap hole check (block bits) that unchecked nodes get must count what the decoding check
// counts: random BC1 blocks (both colour modes, every index) against random hole flags, then a
// cooked node with holes whose blocks are then broken (endpoints swapped: 3-colour <-> 4-colour).
TEST(SurfaceSynthetic, HoleAlphaFromBlockBitsEqualsTheDecodedCheck) {
  std::vector<uint8_t> rgba(size_t(kTexelCount) * 4), blocks(size_t(kTexelBlocks * kTexelBlocks) * 8);
  uint64_t s = 0x9E3779B97F4A7C15ull;
  auto next = [&] { s ^= s << 13; s ^= s >> 7; s ^= s << 17; return s; };
  for (int round = 0; round < 20; ++round) {
    for (uint8_t& b : blocks) b = uint8_t(next());
    for (size_t k = 0; k < rgba.size(); ++k) rgba[k] = uint8_t(next());
    if (round % 4 == 0)  // equal endpoints: 3-colour mode on every block
      for (size_t b = 0; b < blocks.size(); b += 8) blocks[b + 2] = blocks[b], blocks[b + 3] = blocks[b + 1];
    const AlbedoCheck full = check_albedo(rgba.data(), blocks.data());
    const AlbedoCheck fast = check_albedo_alpha(rgba.data(), blocks.data());
    EXPECT_EQ(fast.holes, full.holes);
    EXPECT_EQ(fast.alpha_mismatches, full.alpha_mismatches);
    EXPECT_GT(full.alpha_mismatches, 0u);  // random flags against random blocks: the test can fail
  }
  auto hole = [](double x, double y) {
    const int i = int(std::lround(x / 0.5)) - 128, j = int(std::lround(y / 0.5)) - 128;
    return i >= 20 && i <= 60 && j >= 30 && j <= 41;
  };
  const auto node = synthetic_node(rolling, 0, 1, 1, 2, hole);
  const Cooked c = cook_node(node, default_rules(), BcQuality::balanced);
  ASSERT_TRUE(c.status.ok());
  std::vector<uint8_t> want(size_t(kTexelCount) * 4, 255);
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) want[size_t(u * kTexels + t) * 4 + 3] = texel_is_hole(node, t, u) ? 0 : 255;
  std::vector<uint8_t> bc1(c.data.albedo_bc1.begin(), c.data.albedo_bc1.end());
  EXPECT_EQ(check_albedo_alpha(want.data(), bc1.data()).alpha_mismatches, 0u);
  EXPECT_EQ(check_albedo_alpha(want.data(), bc1.data()).holes, check_albedo(want.data(), bc1.data()).holes);
  EXPECT_GT(check_albedo(want.data(), bc1.data()).holes, 400u);
  for (size_t b = 0; b < bc1.size(); b += 8) {
    std::swap(bc1[b], bc1[b + 2]);
    std::swap(bc1[b + 1], bc1[b + 3]);
  }
  const AlbedoCheck broken = check_albedo(want.data(), bc1.data());
  EXPECT_GT(broken.alpha_mismatches, 0u);
  EXPECT_EQ(check_albedo_alpha(want.data(), bc1.data()).alpha_mismatches, broken.alpha_mismatches);
}

// Sampled error checks measure about one node in 8 at every level, the same nodes every time.
TEST(SurfaceSynthetic, ErrorCheckSampleIsOneNodeInEightAtEveryLevel) {
  for (uint32_t level = 0; level <= 7; ++level) {
    int picked = 0, total = 0;
    for (uint32_t y = 0; y < 200; ++y)
      for (uint32_t x = 0; x < 200; ++x) {
        const NodeKey k{level, x + 1000 * level, y};
        picked += error_check_sampled(k);
        ++total;
        ASSERT_EQ(error_check_sampled(k), error_check_sampled(NodeKey{level, x + 1000 * level, y}));
      }
    const double share = double(picked) / total;
    EXPECT_NEAR(share, 0.125, 0.01) << "level " << level;
  }
}
