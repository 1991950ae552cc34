// Internal: the per-node surface copies behind terrain::ResidentSurface and ArchiveSurface, and
// the publisher the Streamer feeds from update() (deliveries in, evictions out, one snapshot out).
#pragma once
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/format.h"

namespace terrain::detail {

inline constexpr int kPatchQuads = kQuadsPerPatch;                 // 16 quads per patch side
inline constexpr int kPatchesSide = kQuadsPerSide / kPatchQuads;   // 8 patches per node side

// One node's surface: dequantized vertex heights (float holds units * 2^-10 exactly for
// |units| < 2^24, so widening to double gives units_to_metres() bit for bit) and hole flags.
struct NodeSurface {
  NodeKey key;
  uint8_t child_mask = 0;
  double min_m = 0, max_m = 0;  // over non-hole vertices (what triangles can reach)
  std::vector<float> h;         // kHeightCount, row-major, row 0 south
  std::vector<uint8_t> holes;   // kHeightCount, or empty when the node has no hole
  std::array<float, kPatchesSide * kPatchesSide> patch_min{}, patch_max{};  // per 16x16-quad patch
};

// `data` holds the node's heights; its albedo when `have_albedo` (else the hole mask is decoded
// through the reader, only for nodes flagged with holes).
std::shared_ptr<const NodeSurface> make_node_surface(const ArchiveReader& reader, size_t index, const NodeData& data,
                                                     bool have_albedo);

struct SnapshotNode {
  const NodeSurface* s = nullptr;
  std::array<int32_t, 4> child{-1, -1, -1, -1};  // snapshot index of a resident child, or -1
  double lo = 0, hi = 0;  // height range of the node and its resident descendants (ray pruning)
};

struct SurfaceSnapshot {
  uint64_t frame = 0;
  double origin_x = 0, origin_y = 0;
  uint32_t roots_x = 0, roots_y = 0;
  int top_level = kRootLevel;        // the archive's top level (roots, or the top overview level)
  uint32_t top_x = 0, top_y = 0;     // its node grid
  std::vector<std::shared_ptr<const NodeSurface>> owned;  // keeps every node's data alive
  std::vector<SnapshotNode> nodes;                        // directory order (sorted by directory_less)
  std::vector<int32_t> top_grid;                          // top_y * top_x, snapshot index or -1
  std::shared_ptr<const std::vector<NodeKey>> archive_keys;  // every node of the archive, directory order
  int32_t find(const NodeKey& key) const;                 // snapshot index or -1
};

// Owner's thread: add()/remove()/publish(). Any thread: latest().
class SurfacePublisher {
 public:
  void add(uint32_t directory_index, std::shared_ptr<const NodeSurface> s);
  void remove(uint32_t directory_index);
  // Publishes a new snapshot when nodes were added or removed since the last one.
  void publish(uint64_t frame, const ArchiveReader& reader);
  std::shared_ptr<const SurfaceSnapshot> latest() const;

 private:
  std::map<uint32_t, std::shared_ptr<const NodeSurface>> live_;  // directory order
  bool changed_ = true;
  mutable std::mutex mutex_;
  std::shared_ptr<const SurfaceSnapshot> current_;
  std::shared_ptr<const std::vector<NodeKey>> archive_keys_;  // made once, shared by every snapshot
};

}  // namespace terrain::detail
