// Patch cones: per node 8x8 patches of 16x16 quads; per patch the smallest cone enclosing the
// normals of every triangle the renderer can draw there, encoded conservatively in BC3 8x8.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "terrain/format.h"
#include "terrain/surface_contract.h"

namespace terrain::cook {

inline constexpr int kPatchCount = kPatchesPerSide * kPatchesPerSide;
inline constexpr int kMaxStitchLevels = kMaxConeStitchDelta;  // edge collapse d = 1..4 (16-quad patch edge)

// A run of unit normals, structure-of-arrays (so the dot-product scans vectorise).
struct NormalSpan {
  const float* x = nullptr;
  const float* y = nullptr;
  const float* z = nullptr;
  int n = 0;
  bool same = false;  // every normal equals the first (flat ground: the sea); false when unknown
};

// Unit normals of every triangle the renderer can draw, grouped by patch (patch p + 8 q).
struct PatchNormals {
  std::vector<float> x, y, z;                     // capacity; begin[64] normals are valid
  std::array<uint32_t, kPatchCount + 1> begin{};  // normals of patch k: [begin[k], begin[k+1])
  std::array<uint8_t, kPatchCount> same{};        // NormalSpan::same of each patch (0: unknown)
  int count(int k) const { return int(begin[size_t(k) + 1] - begin[size_t(k)]); }
  NormalSpan patch(int k) const {
    const size_t b = begin[size_t(k)];
    return {x.data() + b, y.data() + b, z.data() + b, count(k), same[size_t(k)] != 0};
  }
};

// Whether v holds at least one normal and every normal equals the first (==: signed zeros alike,
// never a NaN): PatchNormals::same.
bool all_normals_equal(NormalSpan v);

// Triangulation and LOD stitching as in terrain/surface_contract.h (format/SPEC.md section 16.5):
// the unstitched triangles of every quad, plus every non-degenerate triangle any edge deltas
// d = 1..4 produce. A triangle is dropped when a vertex is a hole (a stitched one only when it is
// a hole both at its collapsed and at its original vertices).
// heights: the node's R16 grid; holes: kWindowCount window flags (may be null).
void collect_patch_normals(const NodeData& node, int32_t height_offset, int step_log2, double spacing_m,
                           const uint8_t* window_holes, PatchNormals& out);

struct Cone {
  double axis[3] = {0, 0, 1};
  double half_angle_rad = 0;  // 0 for an empty or perfectly flat patch
};
// Smallest cone containing unit vectors v[0..n) (all with z > 0): axis = direction of the point of
// their convex hull nearest the origin (GJK), half-angle = largest angle to any of them.
Cone smallest_enclosing_cone(NormalSpan normals);
// Largest angle between `axis` and the normals (0 if none).
double max_angle_to(const double axis[3], NormalSpan normals);
// Index of the normal with the smallest dot(axis, normal) in double, the first of equals (0 if
// none); argmin_dot_per_candidate is the float-prefiltered form it is checked against.
int argmin_dot(NormalSpan normals, double ax, double ay, double az);
int argmin_dot_per_candidate(NormalSpan normals, double ax, double ay, double az);

// The normals i of v with (ax v.x[i] + ay v.y[i]) + az v.z[i] <= limit in float, in order, written
// from x[m], y[m], z[m] (room for v.n more); returns m plus their count. The encoder's far set:
// the only normals that can be farthest from an axis near a patch's exact one.
size_t append_far_normals(NormalSpan v, float ax, float ay, float az, float limit, float* x, float* y, float* z,
                          size_t m);

struct ConeStats {
  double mean_exact_deg = 0, mean_encoded_deg = 0;  // over patches with triangles
  int patches = 0;                                  // patches with triangles
  int patches_never_cull = 0;
};

// Encodes 64 cones into kConesBytes of BC3 (layout in terrain/surface_contract.h). For every patch the decoded
// cone is checked against every normal with the margins of format/SPEC.md section 16.5; returns false if a
// check fails (a bug, never expected).
bool encode_patch_cones(const PatchNormals& normals, const Cone cones[kPatchCount], uint8_t out[kConesBytes],
                        ConeStats* stats);

// Smallest slack (radians) over all patches and normals: decoded half-angle minus the angle of
// the normal from the decoded axis. >= 0 means every normal is inside its decoded cone.
double decoded_cone_slack(const PatchNormals& normals, const uint8_t cones_bc3[kConesBytes]);

}  // namespace terrain::cook
