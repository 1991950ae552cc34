// cook_surface_layers(): normals, albedo, splat and cones of one node.
#include "surface_layers.h"

#include <cmath>
#include <ctime>
#include <string>

#include "bc_blocks.h"
#include "cones.h"
#include "materials.h"
#include "normals.h"
#include "splat.h"
#include "surface_encoders.h"

namespace terrain::cook {
namespace {

// Stage times are CPU time of the calling thread (the cooker runs nodes on several threads; a
// per-core budget is what matters, and wall time would include other threads' work).
double thread_seconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

std::string node_name(const NodeKey& k) {
  return "node " + std::to_string(k.level) + "/" + std::to_string(k.x) + "/" + std::to_string(k.y);
}

}  // namespace

Bc1Method albedo_method(BcQuality q) {
  switch (q) {
    case BcQuality::fast: return Bc1Method::own_fast;
    case BcQuality::balanced: return Bc1Method::own;
    case BcQuality::best: return Bc1Method::own_best;
  }
  return Bc1Method::own;
}

Bc3Method normals_method(BcQuality q) {
  switch (q) {
    case BcQuality::fast: return Bc3Method::stb;
    case BcQuality::balanced: return Bc3Method::own;
    case BcQuality::best: return Bc3Method::own_hq;
  }
  return Bc3Method::own;
}

void encode_bc1_image(const uint8_t* rgba, Bc1Method method, uint8_t* out_blocks) {
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t block[64];
      for (int r = 0; r < 4; ++r)
        for (int b = 0; b < 16; ++b) block[r * 16 + b] = rgba[size_t((by * 4 + r) * kTexels + bx * 4) * 4 + size_t(b)];
      encode_bc1_block(block, method, out_blocks + size_t(by * kTexelBlocks + bx) * 8);
    }
}

AlbedoCheck check_albedo(const uint8_t* rgba, const uint8_t* bc1_blocks) {
  AlbedoCheck c;
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t dec[64];
      decode_bc1_block(bc1_blocks + size_t(by * kTexelBlocks + bx) * 8, dec);
      for (int i = 0; i < 16; ++i) {
        const size_t k = size_t((by * 4 + i / 4) * kTexels + bx * 4 + i % 4);
        const bool hole = rgba[k * 4 + 3] < 128, transparent = dec[i * 4 + 3] == 0;
        if (hole != transparent) ++c.alpha_mismatches;
        if (hole) {
          ++c.holes;
          continue;
        }
        for (int ch = 0; ch < 3; ++ch) {
          const double d = double(rgba[k * 4 + size_t(ch)]) - dec[i * 4 + ch];
          c.sq_err += d * d;
        }
        c.samples += 3;
      }
    }
  return c;
}

double psnr_db(double sq_err, uint64_t samples) {
  if (samples == 0) return 0;
  if (sq_err <= 0) return 99.0;
  return 10.0 * std::log10(255.0 * 255.0 * double(samples) / sq_err);
}

Status cook_surface_layers(const SurfaceInput& in, const NodeData& node_heights, int32_t height_offset, int step_log2,
                           NodeData& out, SurfaceStats* stats) {
  if (!in.heights_m || !in.rules || !(in.spacing_m > 0) || in.rules->palette.empty())
    return Status::failure(Error::invalid_argument,
                           node_name(in.key) + ": surface input needs heights, material rules and a positive spacing");
  const MaterialRules& rules = *in.rules;

  // Splat (first: the albedo is baked from it).
  double t0 = thread_seconds();
  SplatLattice lattice;
  compute_splat_lattice(in, rules, lattice);
  copy_node_splat(lattice, out.splat);
  const double t_splat = thread_seconds() - t0;

  // Cones (from the node's quantized heights, before `out` may overwrite them: out may alias).
  t0 = thread_seconds();
  static thread_local PatchNormals patch_normals;
  collect_patch_normals(node_heights, height_offset, step_log2, in.spacing_m, in.holes, patch_normals);
  Cone cones[kPatchCount];
  for (int k = 0; k < kPatchCount; ++k) cones[k] = smallest_enclosing_cone(patch_normals.patch(k));
  ConeStats cone_stats;
  if (!encode_patch_cones(patch_normals, cones, out.cones_bc3.data(), &cone_stats))
    return Status::failure(Error::internal, node_name(in.key) + ": a decoded patch cone does not contain its normals");
  const double t_cones = thread_seconds() - t0;

  // Normals.
  t0 = thread_seconds();
  static thread_local NormalTexels normals;
  static thread_local std::array<uint8_t, kTexelCount * 4> normal_rgba;
  compute_normal_texels(in, normals);
  pack_normal_texels(normals, normal_rgba);
  encode_bc3_image(normal_rgba.data(), normals_method(in.bc_quality), out.normals_bc3.data());
  const double t_normals = thread_seconds() - t0;

  // Albedo.
  t0 = thread_seconds();
  static thread_local std::array<uint8_t, kTexelCount * 4> albedo_rgba;
  bake_albedo(in, rules, lattice, albedo_rgba.data());
  encode_bc1_image(albedo_rgba.data(), albedo_method(in.bc_quality), out.albedo_bc1.data());
  const double t_albedo = thread_seconds() - t0;

  if (stats) {
    stats->seconds_splat += t_splat;
    stats->seconds_cones += t_cones;
    stats->seconds_normals += t_normals;
    stats->seconds_albedo += t_albedo;
    const AngleStats ne = normal_error(normals, out.normals_bc3.data());
    stats->normal_err_sum_deg += ne.sum_deg;
    stats->normal_err_max_deg = std::max(stats->normal_err_max_deg, ne.max_deg);
    stats->normal_samples += ne.count;
    const AlbedoCheck ac = check_albedo(albedo_rgba.data(), out.albedo_bc1.data());
    stats->albedo_sq_err_sum += ac.sq_err;
    stats->albedo_samples += ac.samples;
    stats->cone_exact_deg_sum += cone_stats.mean_exact_deg * cone_stats.patches;
    stats->cone_encoded_deg_sum += cone_stats.mean_encoded_deg * cone_stats.patches;
    stats->cone_patches += uint64_t(cone_stats.patches);
    stats->cone_patches_never_cull += uint64_t(cone_stats.patches_never_cull);
  }
  return Status::success();
}

}  // namespace terrain::cook
