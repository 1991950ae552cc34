// Heights as the renderer draws them (SPEC "Surface"): finest node covering the point, quads split
// along the south-west to north-east diagonal, triangles touching a hole vertex dropped.
#include "terrain/sample.h"

#include <algorithm>
#include <cmath>
#include <list>
#include <vector>

#include "terrain/bc_decode.h"
#include "terrain/surface_contract.h"

namespace terrain {

struct SurfaceSampler::Impl {
  const ArchiveReader& reader;
  struct Cached {
    size_t index;
    std::vector<int32_t> units;
    std::vector<uint8_t> holes;
  };
  std::list<Cached> cache;  // most recent first
  static constexpr size_t kCacheNodes = 16;
  std::unique_ptr<NodeData> scratch = std::make_unique<NodeData>();

  explicit Impl(const ArchiveReader& r) : reader(r) {}

  Status get(size_t index, const Cached*& out) {
    for (auto it = cache.begin(); it != cache.end(); ++it)
      if (it->index == index) {
        cache.splice(cache.begin(), cache, it);
        out = &cache.front();
        return Status::success();
      }
    TERRAIN_TRY(reader.decode_node(index, *scratch, kSectionHeights | kSectionAlbedo));
    Cached c{index, std::vector<int32_t>(size_t(kHeightCount)), std::vector<uint8_t>(size_t(kHeightCount))};
    NodeRecord r;
    TERRAIN_TRY(reader.record(index, r));
    const int step = reader.world().step_log2[r.key.level];
    for (size_t k = 0; k < size_t(kHeightCount); ++k) c.units[k] = vertex_units(r.height_offset, scratch->heights[k], step);
    decode_hole_mask(*scratch, c.holes.data());
    cache.push_front(std::move(c));
    if (cache.size() > kCacheNodes) cache.pop_back();
    out = &cache.front();
    return Status::success();
  }
};

SurfaceSampler::SurfaceSampler(const ArchiveReader& reader) : impl_(std::make_unique<Impl>(reader)) {}
SurfaceSampler::~SurfaceSampler() = default;

Status SurfaceSampler::sample(double frame_x, double frame_y, std::optional<SurfaceSample>& out) {
  out.reset();
  if (!impl_->reader.is_open()) return Status::failure(Error::invalid_argument, "archive is not open");
  if (!std::isfinite(frame_x) || !std::isfinite(frame_y))
    return Status::failure(Error::invalid_argument, "sample point is not finite");
  const WorldInfo& w = impl_->reader.world();
  const double rx = frame_x - w.origin_x_m, ry = frame_y - w.origin_y_m;
  for (int level = 0; level < kLevelCount; ++level) {
    const double size = node_size_m(level);
    const double fx = rx / size, fy = ry / size;
    const double grid_x = double(uint64_t(w.roots_x) << (kRootLevel - level));
    const double grid_y = double(uint64_t(w.roots_y) << (kRootLevel - level));
    if (fx < 0 || fy < 0 || fx > grid_x || fy > grid_y) return Status::success();  // outside the frame's grid
    // The node containing the point; a point on a west/south node edge also lies on the
    // neighbour's east/north edge. A point on an edge or vertex shared by several triangles (of
    // one node or of neighbours) lies on each of them and is answered by the first one drawn
    // (heights agree along shared edges); "no data" only when none is drawn.
    NodeKey holding[4];
    const int holding_count = nodes_holding_point(level, fx, fy, grid_x, grid_y, holding);
    bool any_node = false;
    for (int k = 0; k < holding_count; ++k) {
      const NodeKey key = holding[k];
      const double cx = key.x, cy = key.y;
      int64_t index = -1;
      TERRAIN_TRY(impl_->reader.lookup(key, index));  // a directory page that fails its checks is an error
      if (index < 0) continue;
      any_node = true;
      const Impl::Cached* node = nullptr;
      TERRAIN_TRY(impl_->get(size_t(index), node));
      const double s = vertex_spacing_m(level);
      const double u = (rx - cx * size) / s, v = (ry - cy * size) / s;  // 0..128
      const int i0 = std::clamp(int(std::floor(u)), 0, kQuadsPerSide - 1);
      const int j0 = std::clamp(int(std::floor(v)), 0, kQuadsPerSide - 1);
      const auto& H = node->units;
      const auto& holes = node->holes;
      auto at = [&](int a, int b) { return size_t(b * kHeightSamples + a); };
      // Quads whose closed square holds the point: (i0, j0) first, then the ones to the west or
      // south when the point is on their shared edge.
      for (int q = 0; q < 4; ++q) {
        const int i = i0 - (q & 1), j = j0 - ((q >> 1) & 1);
        if (i < 0 || j < 0 || u < i || u > i + 1 || v < j || v > j + 1) continue;
        const double fu = std::clamp(u - i, 0.0, 1.0), fv = std::clamp(v - j, 0.0, 1.0);
        const size_t A = at(i, j), B = at(i + 1, j), C = at(i, j + 1), D = at(i + 1, j + 1);
        if (fu >= fv && !(holes[A] || holes[B] || holes[D])) {  // south-east triangle A, B, D
          const double h = units_to_metres(H[A]) + fu * (units_to_metres(H[B]) - units_to_metres(H[A])) +
                           fv * (units_to_metres(H[D]) - units_to_metres(H[B]));
          out = SurfaceSample{h, key};
          return Status::success();
        }
        if (fu <= fv && !(holes[A] || holes[D] || holes[C])) {  // north-west triangle A, D, C
          const double h = units_to_metres(H[A]) + fv * (units_to_metres(H[C]) - units_to_metres(H[A])) +
                           fu * (units_to_metres(H[D]) - units_to_metres(H[C]));
          out = SurfaceSample{h, key};
          return Status::success();
        }
      }
    }
    if (any_node) return Status::success();  // the finest node here draws no triangle at the point
  }
  return Status::success();
}

}  // namespace terrain
