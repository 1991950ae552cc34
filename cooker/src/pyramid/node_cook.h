// The work of one node: canonical heights of its window, R16 packing, geometric error against the
// source, which children to cook, surface layers and the encoded payload. Pure function of the
// node key and the shared read-only context, so any thread order gives the same bytes.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "frame/frame.h"
#include "inputs/raster.h"
#include "pyramid/reconstruct.h"
#include "base/sample_window.h"
#include "surface/surface_layers.h"
#include "terrain/archive_writer.h"
#include "terrain/format.h"

namespace terrain::cook {

// When to refine a node: while its error exceeds tolerance_m, or hole triangles drop source samples
// and its vertices are further apart than half of source_spacing_m; never below finest_level.
struct RefineRules {
  double tolerance_m = 0;
  double source_spacing_m = 0;
  int finest_level = 0;
};

struct CookContext {
  // The source samples of the block being cooked (sample_window.h): every node of the block reads
  // only inside it; `surface` evaluates them. Set per block by set_window().
  const SampleWindow* window = nullptr;
  int source_width = 0, source_height = 0;  // the whole source (mosaic), in samples
  const SourceMapping* mapping = nullptr;
  SourceSurface surface;
  double origin_x = 0, origin_y = 0;
  std::array<uint8_t, kLevelCount> step_log2{};
  // Overview levels (SPEC 19): their step when it is coarser than the roots' (every vertex on the
  // level-6 lattice, the roots' even vertices, is then rounded to it), else -1 (nothing changes).
  int overview_step_log2 = -1;
  int finest_level = 0;
  double tolerance_m = 0;
  double source_spacing_m = 0;  // finest source sample spacing in frame metres
  // A mosaic of several grid families (SampleWindow::family): the rules of each, from its own
  // spacing (family 0's are the three fields above). A node follows the finest family with a sample
  // in it (node_refine_rules). Empty: one family, the fields above everywhere.
  std::vector<RefineRules> family_rules;
  bool heights_only = false;
  const MaterialRules* rules = nullptr;
  BcQuality bc_quality = BcQuality::balanced;
  float bc_rdo = 0;  // CookOptions::bc_rdo
  bool derive_normals = false;  // CookOptions::normals == derived: normals codec 4 (SPEC 16.7)
  bool check_all_errors = false;  // CookOptions::error_checks == all (else error_check_sampled nodes)
  const SurfaceOverlays* overlays = nullptr;  // --albedo / --holes / --landcover rasters (overlays.cpp), or null
  PayloadOptions payload;

  void set_window(const SampleWindow& w) {
    window = &w;
    surface.set_samples(w);
  }
  // Vertices beyond the node's edge that compute_window evaluates (and a block's window must
  // hold): the surface layers' filters need kWindowMargin; a heights-only node needs only the
  // hole albedo's kApron, so its blocks read fewer samples (cooker/README.md, "Figures behind the code").
  int window_margin() const { return heights_only ? kApron : kWindowMargin; }
  // Frame position of level-0 lattice index (gx, gy): exact in double.
  double lattice_x(int64_t gx) const { return origin_x + double(gx) * 0.5; }
  double lattice_y(int64_t gy) const { return origin_y + double(gy) * 0.5; }
};

// Canonical heights of a node's kWindowSize x kWindowSize window (its 129x129 vertices plus
// kWindowMargin neighbour vertices on each side, surface_layers.h), row-major from the south-west;
// window (i + kWindowMargin, j + kWindowMargin) is vertex (i, j). compute_window evaluates the
// ctx.window_margin() vertices around the node; the rest of the window is holes.
struct NodeWindow {
  std::array<int32_t, kWindowCount> units;
  std::array<uint8_t, kWindowCount> hole;
};
// The albedo of a node without surface layers: flat grey BC1 carrying the hole mask of a
// kWindowSize x kWindowSize window of hole flags (heights-only nodes, overview nodes).
void encode_hole_albedo(const uint8_t* hole_window, std::array<uint8_t, kAlbedoBytes>& out);
// Fails (invalid_argument) when a height is outside the archive's +-16384 m.
Status compute_window(const CookContext& ctx, const NodeKey& key, NodeWindow& w);
// The node square in source sample coordinates: the bounding box of its corners and edge
// midpoints (a projected square bends by far less than a sample over one node).
void node_sample_bounds(const CookContext& ctx, const NodeKey& key, double& cmin, double& rmin, double& cmax,
                        double& rmax);
// The rules that decide whether the node is refined: ctx's, or with family_rules the smallest
// tolerance, spacing and finest level among the families with a sample in the node's sample bounds
// (one sample around; ctx's when it has none: nodata and filled voids only).
// `families`, when not null: bit f set for the first family f < 64 with a sample there, the one
// that takes precedence in the node (0 without family_rules or with no family there).
RefineRules node_refine_rules(const CookContext& ctx, const NodeKey& key, uint64_t* families = nullptr);
// Whether any of the node's 129x129 vertices has terrain (cheap: coverage test only).
bool node_has_terrain(const CookContext& ctx, const NodeKey& key);

// Error of the node's rendered surface against the source samples it covers.
struct ErrorStats {
  double max_m = 0, sum_sq = 0;
  uint64_t samples = 0, uncovered = 0;
  void add(const ErrorStats& o) {
    max_m = std::max(max_m, o.max_m);
    sum_sq += o.sum_sq;
    samples += o.samples;
    uncovered += o.uncovered;
  }
  double rms_m() const { return samples ? std::sqrt(sum_sq / double(samples)) : 0.0; }
};
struct NodeError {
  ErrorStats total;
  std::array<ErrorStats, 4> quadrant;  // by child index (bit 0 east, bit 1 north)
};
void measure_error(const CookContext& ctx, const NodeKey& key, const NodeWindow& w, NodeError& out);
// Tests: whether measure_error takes its 4-lane path for sources denser than the node on the
// frame's axes (on by default; off: the per-sample loop, the definition), returning the previous
// setting; and how many source rows that path has measured in this process.
bool measure_error_dense_rows(bool enabled);
uint64_t dense_error_rows_measured();

struct NodeResult {
  Status status;
  NodeRecord record;
  std::vector<uint8_t> payload;
  NodeError error;
  uint64_t vertices = 0;  // non-hole vertices
  uint64_t families = 0;  // node_refine_rules' families (bit f: grid family f takes precedence in the node)
  double cpu_heights = 0, cpu_error = 0, cpu_surface = 0, cpu_encode = 0;
  SurfaceStats surface;
};
// Cooks one node completely (record.child_mask says which children to cook next).
void cook_node(const CookContext& ctx, const NodeKey& key, NodeResult& out);

}  // namespace terrain::cook
