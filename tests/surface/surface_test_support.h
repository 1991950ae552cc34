// Helpers for the surface tests: synthetic and real nodes, cooking, decoding, and an independent
// check of patch cones against the exact triangles the renderer draws.
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "dem_nodes.h"
#include "materials.h"
#include "surface_layers.h"

namespace terrain::cook::test {

constexpr double kPi = 3.14159265358979323846;

// The built-in material rules (default_material_rules()), built once.
const MaterialRules& default_rules();

using HeightFn = std::function<double(double x_m, double y_m)>;
using HoleFn = std::function<bool(double x_m, double y_m)>;

// Node (level, nx, ny) of a frame whose heights are f(x, y) at every lattice vertex (x >= 0,
// y >= 0; NaN or hole(x, y) = true marks no data). Quantized like the pyramid does.
bench::DemNode synthetic_node(const HeightFn& f, uint32_t level, uint32_t nx, uint32_t ny, int step_log2 = 2,
                              const HoleFn& hole = {});

struct Cooked {
  NodeData data;
  SurfaceStats stats;
  Status status;
};
Cooked cook_node(const bench::DemNode& node, const MaterialRules& rules, BcQuality q = BcQuality::balanced);

// 132x132 RGBA8 decodes of the BC images (our reference decoder).
std::vector<uint8_t> decode_albedo(const NodeData& d);
std::vector<uint8_t> decode_normals(const NodeData& d);
// Unit normal of a decoded normal texel as the shader rebuilds it.
void texel_normal(const uint8_t* rgba, double n[3]);

// Exact hole flags of the texels: texel (t, u) <-> window vertex (t - 2, u - 2).
bool texel_is_hole(const bench::DemNode& node, int t, int u);

struct ConeCheck {
  uint64_t eyes = 0, patch_tests = 0, culled = 0;
  uint64_t violations = 0;       // culled patches with a front-facing triangle (must be 0)
  uint64_t triangles_checked = 0;
  double worst_cos = -1;         // largest dot(unit(eye - P), unit n) over culled triangles (< 0 is back-facing)
};
// Draws `eyes` random eye points around and above the node, applies the runtime cone test of
// terrain/surface_contract.h to every patch (box = patch footprint x [node min, node max] height) and checks each
// culled patch against every triangle the renderer can draw there, stitched variants included
// (enumerated here independently of the cooker).
ConeCheck check_cones(const bench::DemNode& node, const NodeData& data, int eyes, uint64_t seed);

// The rules read the way they were before rule scales: every parameter per sample, no despeckle,
// no band-limited noise (the baseline the splat coherence tests compare against).
MaterialRules per_sample(MaterialRules r);

}  // namespace terrain::cook::test
