// The statistics of a cook that the stages count and the report (terrain/cook.h CookReport)
// states: per level, and of the surface layers. A light header: stage headers include it without
// the whole of terrain/cook.h.
#pragma once
#include <array>
#include <cstdint>

namespace terrain::cook {

struct LevelStats {
  uint32_t nodes = 0;
  uint8_t step_log2 = 0;             // quantization step of the level: 2^step_log2 units of 2^-10 m
  double range_bound_m = 0;          // the step rule's bound: the largest range bound of a node of the level
  uint64_t vertices = 0;             // non-hole vertices of the level's nodes (129x129 per node)
  uint64_t error_samples = 0;        // source samples measured against the level's nodes
  double error_max_m = 0;            // max |node surface - source| over those samples
  double error_rms_m = 0;
  uint64_t uncovered_samples = 0;    // valid source samples under a dropped (hole) triangle
  // CPU seconds of the level's nodes, summed over threads: the four stages and the parts of
  // SurfaceTotals::cpu_parts (where a node's time goes, level by level; report "cpu_ms_per_node").
  double cpu_heights = 0, cpu_error = 0, cpu_surface = 0, cpu_encode = 0;
  std::array<double, 15> cpu_parts{};
};

// The surface layers' statistics over every node (cooker/src/surface measures them per node; the
// pyramid sums them in key order, so they do not depend on the thread count).
struct SurfaceTotals {
  // CPU seconds per layer, compression included, summed over threads (parts of cpu_surface).
  double cpu_normals = 0, cpu_albedo = 0, cpu_splat = 0, cpu_cones = 0;
  // Finer split (report "cpu_parts"): splat fields, splat rules, cone normals, cone fit, cone BC3,
  // normal texels, normal BC3, albedo bake, albedo BC1, error checks (the rest of cpu_surface), then
  // zstd of the heights, normals, albedo, splat and cones sections (cpu_encode). Names: report.cpp.
  std::array<double, 15> cpu_parts{};
  // Decoded BC3 normals against the float normals, per texel.
  double normal_err_max_deg = 0, normal_err_sum_deg = 0;
  uint64_t normal_samples = 0;
  // Decoded BC1 albedo against the uncompressed bake, per colour channel of the opaque texels.
  double albedo_sq_err_sum = 0;
  uint64_t albedo_samples = 0;
  // Albedo texels that are holes, and texels whose decoded alpha disagrees with the hole flag (the
  // encoders guarantee 0: hole alpha is exact).
  uint64_t albedo_hole_texels = 0, albedo_alpha_mismatches = 0;
  // Patch cones (8 x 8 per node) over the patches holding triangles: half-angles of the exact
  // cones and of the encoded ones (with the margins the viewer culls with), and the patches whose
  // encoded cone can never cull (90 degrees or more).
  double cone_exact_deg_sum = 0, cone_encoded_deg_sum = 0;
  uint64_t cone_patches = 0, cone_patches_never_cull = 0;
  // Nodes with surface layers, and those of them whose normal and albedo errors were measured.
  uint64_t nodes = 0, checked_nodes = 0;

  double normal_err_mean_deg() const { return normal_samples ? normal_err_sum_deg / double(normal_samples) : 0.0; }
  double albedo_psnr_db() const;  // 0 when nothing was measured or the albedo is exact
  double cone_exact_mean_deg() const { return cone_patches ? cone_exact_deg_sum / double(cone_patches) : 0.0; }
  double cone_encoded_mean_deg() const { return cone_patches ? cone_encoded_deg_sum / double(cone_patches) : 0.0; }
};

}  // namespace terrain::cook
