// cook_surface_layers(): normals, albedo, splat and cones of one node.
#include "surface_layers.h"

#include <algorithm>
#include <cstring>
#include <cmath>
#include <vector>
#include <ctime>
#include <string>

#include "bc_blocks.h"
#include "bc_rdo.h"
#include "cones.h"
#include "materials.h"
#include "normals.h"
#include "splat.h"
#include "surface_encoders.h"
#include "terrain/surface_contract.h"

namespace terrain::cook {

const char* cpu_part_name(CpuPart p) {
  static constexpr const char* kNames[kCpuParts] = {
      "splat_fields", "splat_rules", "cones_normals", "cones_fit",   "cones_bc3",   "normals_texels", "normals_bc3", "albedo_bake",
      "albedo_bc1",   "checks",      "zstd_heights",  "zstd_normals", "zstd_albedo", "zstd_splat",     "zstd_cones"};
  return size_t(p) < kCpuParts ? kNames[size_t(p)] : "?";
}

Bc1Method albedo_method(BcQuality q) {
  switch (q) {
    case BcQuality::fast: return Bc1Method::axis_fit;
    case BcQuality::balanced: return Bc1Method::axis_fit_hard;
    case BcQuality::best: return Bc1Method::best_of_axis_fit_and_squish;
  }
  return Bc1Method::axis_fit_hard;
}

Bc3Method normals_method(BcQuality q) {
  switch (q) {
    case BcQuality::fast: return Bc3Method::stb;
    case BcQuality::balanced: return Bc3Method::g_axis_fit;
    case BcQuality::best: return Bc3Method::g_axis_fit_hq;
  }
  return Bc3Method::g_axis_fit;
}

void encode_bc1_image(const uint8_t* rgba, Bc1Method method, uint8_t* out_blocks) {
  encode_image_blocks(rgba, 8, out_blocks,
                      [method](const uint8_t* block, uint8_t* out) { encode_bc1_block(block, method, out); });
}

AlbedoCheck check_albedo(const uint8_t* rgba, const uint8_t* bc1_blocks) {
  // The squared differences are integers: summed in 64-bit integers, the node's total is the
  // double that adding them one by one as doubles gives (every partial sum is below 2^53, exact).
  AlbedoCheck c;
  uint64_t sq = 0, mismatches = 0, holes = 0;
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t dec[64];
      decode_bc1_block(bc1_blocks + size_t(by * kTexelBlocks + bx) * 8, dec);
      for (int r = 0; r < 4; ++r) {
        const uint8_t* src = rgba + size_t((by * 4 + r) * kTexels + bx * 4) * 4;
        const uint8_t* got = dec + r * 16;
        for (int i = 0; i < 4; ++i) {
          const bool hole = src[i * 4 + 3] < 128, transparent = got[i * 4 + 3] == 0;
          mismatches += hole != transparent;
          holes += hole;
          uint32_t e = 0;
          for (int ch = 0; ch < 3; ++ch) {
            const int d = int(src[i * 4 + ch]) - got[i * 4 + ch];
            e += uint32_t(d * d);
          }
          sq += hole ? 0u : e;
        }
      }
    }
  c.alpha_mismatches = mismatches;
  c.holes = holes;
  c.sq_err = double(sq);
  c.samples = (uint64_t(kTexelCount) - holes) * 3;
  return c;
}

AlbedoCheck check_albedo_alpha(const uint8_t* rgba, const uint8_t* bc1_blocks) {
  AlbedoCheck c;
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      const uint8_t* b = bc1_blocks + size_t(by * kTexelBlocks + bx) * 8;
      const bool three_colour = uint32_t(b[0] | (b[1] << 8)) <= uint32_t(b[2] | (b[3] << 8));
      const uint32_t idx = uint32_t(b[4]) | uint32_t(b[5]) << 8 | uint32_t(b[6]) << 16 | uint32_t(b[7]) << 24;
      for (int i = 0; i < 16; ++i) {
        const bool hole = rgba[size_t((by * 4 + i / 4) * kTexels + bx * 4 + i % 4) * 4 + 3] < 128;
        const bool transparent = three_colour && ((idx >> (2 * i)) & 3u) == 3u;
        c.holes += hole;
        c.alpha_mismatches += hole != transparent;
      }
    }
  return c;
}

bool error_check_sampled(const NodeKey& key) {
  uint64_t h = (uint64_t(key.level) << 58) ^ (uint64_t(key.y) << 29) ^ uint64_t(key.x);
  h ^= h >> 33; h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33; h *= 0xc4ceb9fe1a85ec53ull;
  h ^= h >> 33;
  return (h & 7u) == 0;
}

double psnr_db(double sq_err, uint64_t samples) {
  if (samples == 0) return 0;
  if (sq_err <= 0) return 99.0;
  return 10.0 * std::log10(255.0 * 255.0 * double(samples) / sq_err);
}

namespace {

// The overlays resampled to the window, then the plain path: mask holes join the data holes
// (a hole vertex drops its triangles, so the cones ignore them too); orthophoto colours replace
// the splat bake, which stays where the orthophoto has no data.
Status cook_with_overlays(const SurfaceInput& in, const NodeData& node_heights, int32_t height_offset, int step_log2,
                          NormalsDerivation* derived_normals,
                          NodeData& out, SurfaceStats* stats) {
  static thread_local std::vector<uint8_t> rgb, valid, holes, classes;
  const SurfaceOverlays& ov = *in.overlays;
  const bool with_rgb = ov.has_albedo() && in.rules && !in.rules->palette.empty();
  rgb.assign(with_rgb ? size_t(kWindowCount) * 3 : 0, 0);
  valid.assign(with_rgb ? size_t(kWindowCount) : 0, 0);
  holes.assign(ov.has_holes() ? size_t(kWindowCount) : 0, 0);
  classes.assign(ov.has_classes() ? size_t(kWindowCount) : 0, kNoClassMaterial);
  ov.sample(in.x0_m, in.y0_m, in.spacing_m, with_rgb ? rgb.data() : nullptr, with_rgb ? valid.data() : nullptr,
            ov.has_holes() ? holes.data() : nullptr, ov.has_classes() ? classes.data() : nullptr);
  SurfaceInput plain = in;
  plain.overlays = nullptr;
  if (ov.has_classes()) plain.class_materials = classes.data();
  if (ov.has_holes()) {
    if (in.holes)
      for (size_t k = 0; k < size_t(kWindowCount); ++k) holes[k] = uint8_t(holes[k] | in.holes[k]);
    plain.holes = holes.data();
  }
  if (with_rgb) {
    size_t missing = 0;
    for (uint8_t v : valid) missing += v == 0;
    if (missing == size_t(kWindowCount)) return cook_surface_layers(plain, node_heights, height_offset, step_log2, out, stats, derived_normals);
    if (missing > 0) {
      // Vertices without orthophoto data take the splat-baked colour around them: vertex v is
      // the corner of texels v + 1 and v + 2 (centres v -/+ 0.5), so no shift.
      SplatLattice lattice;
      compute_splat_lattice(plain, *in.rules, lattice);
      static thread_local std::array<uint8_t, kTexelCount * 4> baked;
      bake_albedo(plain, *in.rules, lattice, baked.data());
      for (int j = 0; j < kWindowSize; ++j)
        for (int i = 0; i < kWindowSize; ++i) {
          const size_t k = size_t(j * kWindowSize + i);
          if (valid[k]) continue;
          const int t0 = std::clamp(i - kWindowMargin + kApron - 1, 0, kTexels - 1);
          const int t1 = std::clamp(i - kWindowMargin + kApron, 0, kTexels - 1);
          const int u0 = std::clamp(j - kWindowMargin + kApron - 1, 0, kTexels - 1);
          const int u1 = std::clamp(j - kWindowMargin + kApron, 0, kTexels - 1);
          for (int c = 0; c < 3; ++c) {
            const auto at = [&](int t, int u) { return int(baked[size_t(u * kTexels + t) * 4 + size_t(c)]); };
            rgb[k * 3 + size_t(c)] = uint8_t((at(t0, u0) + at(t1, u0) + at(t0, u1) + at(t1, u1) + 2) / 4);
          }
        }
    }
    plain.albedo_rgb = rgb.data();
  }
  return cook_surface_layers(plain, node_heights, height_offset, step_log2, out, stats, derived_normals);
}

}  // namespace

namespace {

// What a codec-4 normals section stores (the packed texels' apron and block AO), and (with
// `blocks`) in out.normals_bc3 what every reader derives from it, the node's heights and its albedo's holes.
void derive_reader_normals(const uint8_t* packed_rgba, const NodeData& node_heights, int step_log2, double spacing_m,
                           bool blocks, NodeData& out, NormalsDerivation& d) {
  d.rise_per_unit = float(std::ldexp(kHeightUnitM, step_log2) / spacing_m);
  size_t at = 0;
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      if (t >= kApron && t < kTexels - kApron && u >= kApron && u < kTexels - kApron) continue;
      const uint8_t* px = packed_rgba + 4 * size_t(u * kTexels + t);
      d.apron[at++] = px[3];
      d.apron[at++] = px[1];
    }
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx)
      d.ao[size_t(by * kTexelBlocks + bx)] = uint8_t(packed_rgba[4 * size_t(by * 4 * kTexels + bx * 4)] >> 3);
  if (!blocks) return;
  static thread_local std::array<uint8_t, kHeightCount> holes;
  decode_hole_mask(out, holes.data());
  static thread_local std::array<uint8_t, kTexelCount * 4> derived;
  derive_normal_texels(node_heights.heights.data(), holes.data(), d, derived.data());
  encode_derived_normals_bc3(derived.data(), out.normals_bc3.data());
}

double next_lap_time(double& t) {
  const double now = thread_cpu_seconds();
  const double lap = now - t;
  t = now;
  return lap;
}

}  // namespace

Status cook_surface_layers(const SurfaceInput& in, const NodeData& node_heights, int32_t height_offset, int step_log2,
                           NodeData& out, SurfaceStats* stats, NormalsDerivation* derived_normals) {
  if (!in.heights_m || !in.rules || !(in.spacing_m > 0) || in.rules->palette.empty())
    return Status::failure(Error::invalid_argument,
                           "node " + node_name(in.key) + ": surface input needs heights, material rules and a positive spacing");
  if (in.overlays) return cook_with_overlays(in, node_heights, height_offset, step_log2, derived_normals, out, stats);
  const MaterialRules& rules = *in.rules;

  // Each layer's steps are laps of one clock (CpuPart order); the four layer times are their sums.
  std::array<double, kCpuParts> lap{};
  double t = thread_cpu_seconds();
  auto next_lap = [&](CpuPart part) {
    const double now = thread_cpu_seconds();
    lap[size_t(part)] = now - t;
    t = now;
  };

  // Splat (first: the albedo is baked from it).
  SplatLattice lattice;
  compute_splat_lattice(in, rules, lattice, &lap[size_t(CpuPart::splat_fields)]);
  copy_node_splat(lattice, out.splat);
  next_lap(CpuPart::splat_rules);
  lap[size_t(CpuPart::splat_rules)] -= lap[size_t(CpuPart::splat_fields)];

  // Cones (from the node's quantized heights, before `out` may overwrite them: out may alias).
  static thread_local PatchNormals patch_normals;
  collect_patch_normals(node_heights, height_offset, step_log2, in.spacing_m, in.holes, patch_normals);
  next_lap(CpuPart::cones_normals);
  Cone cones[kPatchCount];
  for (int k = 0; k < kPatchCount; ++k) cones[k] = smallest_enclosing_cone(patch_normals.patch(k));
  next_lap(CpuPart::cones_fit);
  ConeStats cone_stats;
  if (!encode_patch_cones(patch_normals, cones, out.cones_bc3.data(), &cone_stats))
    return Status::failure(Error::internal, "node " + node_name(in.key) + ": a decoded patch cone does not contain its normals");
  next_lap(CpuPart::cones_bc3);

  // Normals.
  static thread_local NormalTexels normals;
  static thread_local std::array<uint8_t, kTexelCount * 4> normal_rgba;
  compute_normal_texels(in, normals);
  pack_normal_texels(normals, normal_rgba);
  next_lap(CpuPart::normals_texels);
  if (!derived_normals) {
    encode_bc3_image(normal_rgba.data(), normals_method(in.bc_quality), out.normals_bc3.data());
    rdo_normal_blocks(normal_rgba.data(), in.bc_rdo, out.normals_bc3.data());
  }
  next_lap(CpuPart::normals_bc3);

  // Albedo.
  static thread_local std::array<uint8_t, kTexelCount * 4> albedo_rgba;
  bake_albedo(in, rules, lattice, albedo_rgba.data());
  next_lap(CpuPart::albedo_bake);
  encode_bc1_image(albedo_rgba.data(), albedo_method(in.bc_quality), out.albedo_bc1.data());
  rdo_albedo_blocks(albedo_rgba.data(), in.bc_rdo, out.albedo_bc1.data());
  next_lap(CpuPart::albedo_bc1);
  if (derived_normals) {
    // After the albedo: the texels come from the hole mask a reader decodes from it.
    // The blocks only serve the error statistics: nothing after the cook reads them.
    derive_reader_normals(normal_rgba.data(), node_heights, step_log2, in.spacing_m, in.measure_errors, out,
                          *derived_normals);
    lap[size_t(CpuPart::normals_bc3)] += next_lap_time(t);
  }
  const auto sum = [&](CpuPart a, CpuPart b) { return lap[size_t(a)] + lap[size_t(b)]; };
  const double t_splat = sum(CpuPart::splat_fields, CpuPart::splat_rules);
  const double t_cones = sum(CpuPart::cones_normals, CpuPart::cones_fit) + lap[size_t(CpuPart::cones_bc3)];
  const double t_normals = sum(CpuPart::normals_texels, CpuPart::normals_bc3);
  const double t_albedo = sum(CpuPart::albedo_bake, CpuPart::albedo_bc1);

  if (stats) {
    stats->seconds_splat += t_splat;
    stats->seconds_cones += t_cones;
    stats->seconds_normals += t_normals;
    stats->seconds_albedo += t_albedo;
    stats->nodes += 1;
    AlbedoCheck ac;
    if (in.measure_errors) {
      stats->checked_nodes += 1;
      const AngleStats ne = normal_error(normals, out.normals_bc3.data());
      stats->normal_err_sum_deg += ne.sum_deg;
      stats->normal_err_max_deg = std::max(stats->normal_err_max_deg, ne.max_deg);
      stats->normal_samples += ne.count;
      ac = check_albedo(albedo_rgba.data(), out.albedo_bc1.data());
    } else {
      ac = check_albedo_alpha(albedo_rgba.data(), out.albedo_bc1.data());
    }
    stats->albedo_sq_err_sum += ac.sq_err;
    stats->albedo_samples += ac.samples;
    stats->albedo_hole_texels += ac.holes;
    stats->albedo_alpha_mismatches += ac.alpha_mismatches;
    stats->cone_exact_deg_sum += cone_stats.mean_exact_deg * cone_stats.patches;
    stats->cone_encoded_deg_sum += cone_stats.mean_encoded_deg * cone_stats.patches;
    stats->cone_patches += uint64_t(cone_stats.patches);
    stats->cone_patches_never_cull += uint64_t(cone_stats.patches_never_cull);
    next_lap(CpuPart::checks);
    for (size_t k = 0; k < kCpuParts; ++k) stats->seconds_parts[k] += lap[k];
  }
  return Status::success();
}

}  // namespace terrain::cook
