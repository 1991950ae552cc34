// Contract between the height pyramid (cooker/src/pyramid) and the surface layers (cooker/src/surface):
// everything of a node's payload except its heights, cooked from the canonical quantized heights.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "terrain/cpu_clock.h"
#include "terrain/derived_normals.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

// Heights of one level's vertex lattice around a node, as every renderer dequantizes them.
// Vertex (i, j) of the node (0..128) is window element (i + kWindowMargin, j + kWindowMargin);
// the margin holds the neighbours' vertices (same canonical values they store), so aprons and
// normals are computed from real neighbour data and agree across node edges.
inline constexpr int kWindowMargin = 18;  // 4 for normals and AO; the splat filters need the rest
inline constexpr int kWindowSize = kHeightSamples + 2 * kWindowMargin;  // 165
inline constexpr int kWindowCount = kWindowSize * kWindowSize;

enum class BcQuality : uint8_t { fast, balanced, best };

struct SurfaceOptions {
  std::string materials_path;   // JSON rules file; empty = built-in default rules and palette
  BcQuality bc_quality = BcQuality::balanced;
  // Orthophoto, hole-mask and class rasters (--albedo, --holes, --landcover) are mapped to the frame
  // by the cooker (cooker/src/overlays/overlays.cpp) and sampled per node through SurfaceInput::overlays.
};

// Material rules and palette, loaded once per cook (owned by the surface side).
struct MaterialRules;  // defined in cooker/src/surface/materials.h
Status load_material_rules(const SurfaceOptions& options, std::shared_ptr<const MaterialRules>& out);
const std::vector<Material>& palette_of(const MaterialRules& rules);

// Optional rasters of a cook (--albedo orthophoto, --holes mask) resampled to a node's window
// vertices. The cooker implements it (overlays/overlays.cpp: it owns the CRS mapping to the frame); the
// surface side only samples. Must be thread-safe and a pure function of the window position.
class SurfaceOverlays {
 public:
  virtual ~SurfaceOverlays() = default;
  virtual bool has_albedo() const = 0;
  virtual bool has_holes() const = 0;
  virtual bool has_classes() const { return false; }
  // Window vertex (i, j) (0..kWindowSize-1, element j * kWindowSize + i) sits at frame
  // (x0 + (i - kWindowMargin) * spacing, y0 + (j - kWindowMargin) * spacing). Fills kWindowCount
  // entries of each non-null output: rgb (3 bytes, sRGB) with rgb_valid 0 where the orthophoto
  // has no data; holes 1 where the mask marks a hole (0 outside the mask); class_materials the
  // palette index the class raster's table gives the vertex, kNoClassMaterial where none.
  virtual void sample(double x0, double y0, double spacing, uint8_t* rgb, uint8_t* rgb_valid, uint8_t* holes,
                      uint8_t* class_materials) const = 0;
};
inline constexpr uint8_t kNoClassMaterial = 255;

struct SurfaceInput {
  NodeKey key;
  // Frame coords of vertex (0, 0) (south-west corner). The splat noise is evaluated at
  // x0 + i*s, so neighbours must get values whose sums agree (true when the frame origin is a
  // multiple of the spacing, e.g. integer metres).
  double x0_m = 0, y0_m = 0;
  double spacing_m = 0;         // vertex_spacing_m(key.level)
  // kWindowCount, metres, row-major south to north: element (i + kWindowMargin, j + kWindowMargin)
  // is vertex (i, j).
  // NaN where there is no data (a hole vertex may also carry its height: both work).
  const float* heights_m = nullptr;
  const uint8_t* holes = nullptr;    // kWindowCount, 1 = hole vertex (also outside the data); may be null
  // Optional RGB orthophoto colour per window vertex (kWindowCount * 3, sRGB), or null.
  const uint8_t* albedo_rgb = nullptr;
  // Optional palette index per window vertex from a class raster (--landcover), or null;
  // kNoClassMaterial where the raster gives none. A splat sample with one uses it instead of the rules.
  const uint8_t* class_materials = nullptr;
  const MaterialRules* rules = nullptr;
  BcQuality bc_quality = BcQuality::balanced;
  float bc_rdo = 0;  // lambda of rdo_normal_blocks() and rdo_albedo_blocks() (bc_rdo.h); 0 = off
  // Decode the normal and albedo blocks and measure their errors into SurfaceStats (the report's
  // degrees and PSNR). Off: only the hole alpha is checked, from the block bits.
  bool measure_errors = true;
  // Orthophoto and hole mask of the cook (may be null). Its holes add to `holes`; its colours
  // replace the splat-baked albedo where the orthophoto has data.
  const SurfaceOverlays* overlays = nullptr;
};

// Finer split of a node's CPU time for the cook report: the parts of the four layer times (per step
// and per block encoder), the error checks below, and zstd per payload section (the parts of the
// cooker's encode time, filled by node_cook.cpp). Contiguous laps of one thread CPU clock.
enum class CpuPart : uint8_t {
  splat_fields,    // Gaussian-filtered height fields of the rule scales
  splat_rules,     // per-sample attributes, rules, despeckle
  cones_normals,   // triangle normals incl. stitching variants
  cones_fit,       // smallest enclosing cones
  cones_bc3,       // conservative BC3 encoding and its checks
  normals_texels,  // texel normals, AO, channel packing
  normals_bc3,     // BC3 encoder
  albedo_bake,     // splat-baked (or orthophoto) colours
  albedo_bc1,      // BC1 encoder
  checks,          // error statistics (decode and compare) for the report
  zstd_heights, zstd_normals, zstd_albedo, zstd_splat, zstd_cones,
  count
};
inline constexpr size_t kCpuParts = size_t(CpuPart::count);
const char* cpu_part_name(CpuPart p);

struct SurfaceStats {  // summed over nodes by the caller
  // CPU time of the calling thread per stage (compression included; the error statistics below are
  // measured outside these times).
  double seconds_normals = 0, seconds_albedo = 0, seconds_splat = 0, seconds_cones = 0;
  std::array<double, kCpuParts> seconds_parts{};  // by CpuPart (checks and zstd outside the four above)
  double normal_err_max_deg = 0, normal_err_sum_deg = 0;  // decoded BC3 vs float normals
  uint64_t normal_samples = 0;
  double albedo_sq_err_sum = 0;  // decoded BC1 vs uncompressed, over opaque texels (for PSNR)
  uint64_t albedo_samples = 0;   // colour channels summed (3 per opaque texel)
  uint64_t albedo_hole_texels = 0;       // texels flagged as holes (transparent by the format's rule)
  uint64_t albedo_alpha_mismatches = 0;  // texels whose decoded alpha differs from the hole flag (0 by design)
  double cone_exact_deg_sum = 0;    // half-angles of the exact cones, over patches with triangles
  double cone_encoded_deg_sum = 0;  // decoded half-angles incl. margins (what the viewer culls with)
  uint64_t cone_patches = 0;        // patches with triangles
  uint64_t cone_patches_never_cull = 0;  // decoded angle 255 (>= 90 degrees)
  uint64_t nodes = 0, checked_nodes = 0;  // nodes cooked, and those with measure_errors
};

// The nodes whose errors a sampled cook measures (ErrorChecks::sample): one in 8 at every level, by
// a hash of the key, so the same nodes at any thread count, block or unit split (always checking
// the roots would bias the figures toward the coarsest level). What checking every node costs is
// in cooker/README.md ("Figures behind the code").
bool error_check_sampled(const NodeKey& key);

// Fills out.normals_bc3, out.albedo_bc1, out.splat and out.cones_bc3 (heights untouched).
// `node_heights` is the node's own R16 grid with its offset and level step (cones use the exact
// triangles the renderer draws); it may be the same object as `out`. Thread-safe; deterministic.
// derived_normals (optional): the normals are coded with codec 4 (SPEC 16.7): it receives what the
// payload stores; with in.measure_errors out.normals_bc3 holds what every reader derives from it
// (so the error statistics measure what a renderer samples), else it is left as it was. The
// cooker's BC3 encoder and --bc-rdo do not run.
Status cook_surface_layers(const SurfaceInput& in, const NodeData& node_heights, int32_t height_offset,
                           int step_log2, NodeData& out, SurfaceStats* stats,
                           NormalsDerivation* derived_normals = nullptr);

}  // namespace terrain::cook
