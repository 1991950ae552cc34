// Gameplay queries on the terrain: where the ground is under a point, what a ray hits, whether a
// point is in a hole, answered from the data the streamer holds resident (what the player sees
// and what physics should agree with), or from the finest data in the archive.
//
// Use:
//   terrain::Streamer streamer;  ...  streamer.update(views);             // render thread
//   // any thread, any time while the streamer is open:
//   terrain::ResidentSurface ground = streamer.resident_surface();      // cheap: one shared_ptr copy
//   terrain::SurfacePoint p = ground.height_at(x, y);
//   if (p.hit) character.z = p.height_m;
//   terrain::RayHit h = ground.raycast({{ex, ey, ez}, {dx, dy, dz}, 100.0});
//
// Surface (format/SPEC.md "Surface", the definition terrain::SurfaceSampler and the renderer use):
// the finest node covering a frame point answers; its vertices are dequantized (units * 2^-10 m),
// each quad is split along its south-west to north-east diagonal, and triangles touching a hole
// vertex are dropped. The *resident* surface replaces "finest node in the archive" by "finest
// resident node": it is view independent (no stitching, coarsening or decimation) and, wherever
// the archive's finest node at a point is resident, height_at() equals SurfaceSampler::sample()
// bit for bit. Where a resident node borders a finer resident neighbour the two surfaces meet with
// the usual T-junction gaps; rays may pass through those gaps as they pass through holes.
//
// Units: frame metres (x east, y north, z up, the archive's vertical datum), double throughout.
//
// Threading: a ResidentSurface is an immutable snapshot of the resident nodes' surfaces at the end
// of one Streamer::update(). All its methods are const and may run concurrently from any number of
// threads, also while the streamer's thread runs update(), close() or destroys the streamer: the
// snapshot owns (by reference counting) its own copies of the vertex heights and hole masks, so a
// node evicted after the snapshot was taken stays readable until the last copy of the snapshot is
// gone. Streamer::resident_surface() itself may be called from any thread while the streamer is
// open, concurrently with update(); not concurrently with open(), close() or the destructor.
// A snapshot does not change: take a new one (e.g. once per game tick) to see newer nodes.
// ArchiveSurface is not thread-safe (it caches decoded nodes); use one per thread.
//
// Costs: height_at() descends the resident quadtree from the root holding the point (at most
// kLevelCount steps) and evaluates one triangle. raycast() walks the root grid with a 2D DDA,
// descends only into nodes whose box (footprint x [min, max] height) the ray segment enters,
// front to back, and inside a node walks 16x16-quad patches (skipped by their own height range)
// and then quads, stopping at the first hit: its cost follows the nodes and quads crossed, not the
// number of resident nodes. update() pays for the snapshot: each delivered node's heights are
// copied (16 641 floats, ~66 KB, hole mask decoded when the node has holes) and each update that
// delivers or evicts publishes a new table of the resident nodes.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain {

namespace detail {
struct SurfaceSnapshot;
struct NodeSurface;
}  // namespace detail

// The answer of a height query.
struct SurfacePoint {
  bool hit = false;   // a triangle covers the point: height_m, normal and node are set
  bool hole = false;  // the finest node covering the point draws no triangle there (a hole);
                      // hit == false and hole == false: no node covers the point (outside the data)
  // Resident queries: the archive has a finer node covering the point that is not resident (the
  // answer comes from a coarser level than the archive holds). Always false for ArchiveSurface.
  bool finer_not_resident = false;
  double height_m = 0;
  std::array<double, 3> normal{0, 0, 1};  // unit face normal of the triangle, z > 0
  NodeKey node;  // the node that answered (also set for a hole)
};

struct Ray {
  std::array<double, 3> origin{};     // frame metres
  std::array<double, 3> direction{};  // any length > 0 (normalized internally)
  double max_distance_m = 0;          // along the direction, metres (finite)
};

struct RayHit {
  bool hit = false;
  double distance_m = 0;                  // from the origin, metres, <= max_distance_m
  std::array<double, 3> point{};          // origin + distance_m * unit direction
  std::array<double, 3> normal{0, 0, 1};  // unit face normal of the triangle hit, z > 0
  NodeKey node;                           // resident node whose triangle was hit
};

// Immutable snapshot of the resident surface (see Threading above). Copy freely; a
// default-constructed one is empty and every query on it misses.
class ResidentSurface {
 public:
  ResidentSurface() = default;
  explicit ResidentSurface(std::shared_ptr<const detail::SurfaceSnapshot> snapshot);

  bool empty() const;
  uint64_t frame() const;  // the update() that published this snapshot (0 if empty)
  // Resident nodes in this snapshot, directory order (directory_less: level, tiles of 32 x 32 nodes, y, x).
  std::vector<NodeKey> nodes() const;

  // Height, normal and flags at frame point (x, y). Non-finite input: a miss.
  SurfacePoint height_at(double x, double y) const;
  // First hit of the segment origin + t * unit(direction), t in [0, max_distance_m], with the
  // resident surface's triangles (either side: a ray from below hits too). Misses through holes.
  // A zero or non-finite direction, or a negative or non-finite max distance: a miss.
  RayHit raycast(const Ray& ray) const;

  // Batched: out[i] = height_at(points[i]) / raycast(rays[i]); out must be at least as long.
  void heights_at(std::span<const std::array<double, 2>> points, std::span<SurfacePoint> out) const;
  void raycast(std::span<const Ray> rays, std::span<RayHit> out) const;

 private:
  std::shared_ptr<const detail::SurfaceSnapshot> s_;
};

// The same height queries on the finest data in the archive, decoding nodes through the reader
// (with a small cache of decoded nodes, like SurfaceSampler). The reader must outlive this
// object. Not thread-safe: one per thread (the reader itself may be shared).
class ArchiveSurface {
 public:
  explicit ArchiveSurface(const ArchiveReader& reader);
  ~ArchiveSurface();
  ArchiveSurface(const ArchiveSurface&) = delete;
  ArchiveSurface& operator=(const ArchiveSurface&) = delete;

  // Errors: a closed reader, a non-finite point (invalid_argument), a payload that fails to decode.
  Status height_at(double x, double y, SurfacePoint& out);
  Status heights_at(std::span<const std::array<double, 2>> points, std::span<SurfacePoint> out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terrain
