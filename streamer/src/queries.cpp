// Height, normal and ray queries on the resident surface (terrain/queries.h) and on the archive's
// finest data. The per-node evaluation is SurfaceSampler's (format/src/sample.cpp) step for step,
// so both give the same bits where they read the same node.
#include "terrain/queries.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <list>

#include "resident_surface.h"
#include "terrain/bc_decode.h"
#include "terrain/surface_contract.h"

namespace terrain {
namespace detail {

std::shared_ptr<const NodeSurface> make_node_surface(const ArchiveReader& reader, size_t index, const NodeData& data,
                                                     bool have_albedo) {
  auto n = std::make_shared<NodeSurface>();
  const NodeRecord& r = reader.nodes()[index];
  n->key = r.key;
  n->child_mask = r.child_mask;
  const int step = level_step_log2(reader.world(), int(r.key.level));
  n->h.resize(size_t(kHeightCount));
  for (size_t k = 0; k < size_t(kHeightCount); ++k)
    n->h[k] = float(vertex_units(r.height_offset, data.heights[k], step)) * float(kHeightUnitM);  // exact
  if (r.flags & kNodeFlagHasHoles) {
    n->holes.resize(size_t(kHeightCount));
    if (have_albedo) {
      decode_hole_mask(data, n->holes.data());
    } else {
      // The caller's sections lack the albedo that carries the hole flags: read it here (rare).
      auto scratch = std::make_unique<NodeData>();
      if (reader.decode_node(index, *scratch, kSectionAlbedo).ok())
        decode_hole_mask(*scratch, n->holes.data());
      else
        std::fill(n->holes.begin(), n->holes.end(), uint8_t(1));  // unreadable: draw nothing
    }
  }
  // Height ranges over non-hole vertices, per node and per 16x16-quad patch (17x17 vertices).
  const float inf = std::numeric_limits<float>::infinity();
  float lo = inf, hi = -inf;
  for (int pj = 0; pj < kPatchesSide; ++pj)
    for (int pi = 0; pi < kPatchesSide; ++pi) {
      float plo = inf, phi = -inf;
      for (int j = pj * detail::kPatchQuads; j <= (pj + 1) * detail::kPatchQuads; ++j)
        for (int i = pi * detail::kPatchQuads; i <= (pi + 1) * detail::kPatchQuads; ++i) {
          const size_t k = size_t(j * kHeightSamples + i);
          if (!n->holes.empty() && n->holes[k]) continue;
          plo = std::min(plo, n->h[k]);
          phi = std::max(phi, n->h[k]);
        }
      n->patch_min[size_t(pj * kPatchesSide + pi)] = plo;
      n->patch_max[size_t(pj * kPatchesSide + pi)] = phi;
      lo = std::min(lo, plo);
      hi = std::max(hi, phi);
    }
  n->min_m = lo;
  n->max_m = hi;
  return n;
}

int32_t SurfaceSnapshot::find(const NodeKey& key) const {
  auto it = std::lower_bound(nodes.begin(), nodes.end(), key,
                             [](const SnapshotNode& n, const NodeKey& k) { return directory_less(n.s->key, k); });
  return it != nodes.end() && it->s->key == key ? int32_t(it - nodes.begin()) : -1;
}

void SurfacePublisher::add(uint32_t directory_index, std::shared_ptr<const NodeSurface> s) {
  live_[directory_index] = std::move(s);
  changed_ = true;
}

void SurfacePublisher::remove(uint32_t directory_index) { changed_ |= live_.erase(directory_index) > 0; }

void SurfacePublisher::publish(uint64_t frame, const ArchiveReader& reader) {
  if (!changed_) return;
  changed_ = false;
  const WorldInfo& world = reader.world();
  if (!archive_keys_) {
    auto keys = std::make_shared<std::vector<NodeKey>>();
    for (const NodeRecord& r : reader.nodes()) keys->push_back(r.key);
    archive_keys_ = std::move(keys);
  }
  auto snap = std::make_shared<SurfaceSnapshot>();
  snap->archive_keys = archive_keys_;
  snap->frame = frame;
  snap->origin_x = world.origin_x_m;
  snap->origin_y = world.origin_y_m;
  snap->roots_x = world.roots_x;
  snap->roots_y = world.roots_y;
  snap->top_level = top_level(world);
  snap->top_x = uint32_t(level_grid_cells(world.roots_x, snap->top_level));
  snap->top_y = uint32_t(level_grid_cells(world.roots_y, snap->top_level));
  snap->top_grid.assign(size_t(snap->top_x) * snap->top_y, -1);
  snap->owned.reserve(live_.size());
  snap->nodes.reserve(live_.size());
  for (const auto& [index, s] : live_) {  // directory order: finer levels first
    snap->owned.push_back(s);
    SnapshotNode n;
    n.s = s.get();
    n.lo = s->min_m;
    n.hi = s->max_m;
    snap->nodes.push_back(n);
  }
  // Children come before parents: each node's subtree range is complete when its parent reads it.
  for (size_t i = 0; i < snap->nodes.size(); ++i) {
    const SnapshotNode& n = snap->nodes[i];
    const NodeKey& k = n.s->key;
    if (k.level == uint32_t(snap->top_level)) {
      if (k.x < snap->top_x && k.y < snap->top_y) snap->top_grid[size_t(k.y) * snap->top_x + k.x] = int32_t(i);
      continue;
    }
    const int32_t p = snap->find(parent_of(k));
    if (p < 0) continue;  // cannot happen: the resident set is closed under parents
    SnapshotNode& parent = snap->nodes[size_t(p)];
    parent.child[size_t((k.x & 1) | ((k.y & 1) << 1))] = int32_t(i);
    parent.lo = std::min(parent.lo, n.lo);
    parent.hi = std::max(parent.hi, n.hi);
  }
  std::lock_guard lock(mutex_);
  current_ = std::move(snap);
}

std::shared_ptr<const SurfaceSnapshot> SurfacePublisher::latest() const {
  std::lock_guard lock(mutex_);
  return current_;
}

}  // namespace detail

namespace {

using detail::NodeSurface;
using detail::SnapshotNode;
using detail::SurfaceSnapshot;

// Node sizes and vertex spacings are powers of two, so x / size == x * (1 / size) exactly: the
// multiplications below give SurfaceSampler's divisions bit for bit, at a fraction of the cost.
struct LevelScales {
  std::array<double, kMaxLevels> inv_size{}, inv_spacing{};
  constexpr LevelScales() {
    for (int l = 0; l < kMaxLevels; ++l) {
      inv_size[size_t(l)] = 1.0 / node_size_m(l);
      inv_spacing[size_t(l)] = 1.0 / vertex_spacing_m(l);
    }
  }
};
constexpr LevelScales kScales;
static_assert(node_size_m(0) == 64.0 && vertex_spacing_m(0) == 0.5, "sizes must stay powers of two");

// SurfaceSampler's evaluation of one node at (rx, ry) (frame point minus origin); (cx, cy) the
// node's coordinates. False when the node draws no triangle at the point.
bool node_height(const NodeSurface& n, double rx, double ry, double cx, double cy, SurfacePoint& out) {
  const int level = int(n.key.level);
  const double size = node_size_m(level);
  const double inv_s = kScales.inv_spacing[size_t(level)];
  const double u = (rx - cx * size) * inv_s, v = (ry - cy * size) * inv_s;  // 0..128
  const int i0 = std::clamp(int(std::floor(u)), 0, kQuadsPerSide - 1);
  const int j0 = std::clamp(int(std::floor(v)), 0, kQuadsPerSide - 1);
  const float* H = n.h.data();
  const uint8_t* holes = n.holes.empty() ? nullptr : n.holes.data();
  auto at = [](int a, int b) { return size_t(b * kHeightSamples + a); };
  auto hole = [&](size_t a, size_t b, size_t c) { return holes && (holes[a] || holes[b] || holes[c]); };
  auto set = [&](double h, double gx, double gy) {  // gx, gy: height change per quad along x, y
    out.hit = true;
    out.height_m = h;
    const double nx = -gx * inv_s, ny = -gy * inv_s, inv_len = 1.0 / std::sqrt(nx * nx + ny * ny + 1.0);
    out.normal = {nx * inv_len, ny * inv_len, inv_len};
    out.node = n.key;
  };
  for (int q = 0; q < 4; ++q) {
    const int i = i0 - (q & 1), j = j0 - ((q >> 1) & 1);
    if (i < 0 || j < 0 || u < i || u > i + 1 || v < j || v > j + 1) continue;
    const double fu = std::clamp(u - i, 0.0, 1.0), fv = std::clamp(v - j, 0.0, 1.0);
    const size_t A = at(i, j), B = at(i + 1, j), C = at(i, j + 1), D = at(i + 1, j + 1);
    const double hA = H[A], hB = H[B], hC = H[C], hD = H[D];
    if (fu >= fv && !hole(A, B, D)) {  // south-east triangle A, B, D
      set(hA + fu * (hB - hA) + fv * (hD - hB), hB - hA, hD - hB);
      return true;
    }
    if (fu <= fv && !hole(A, D, C)) {  // north-west triangle A, D, C
      set(hA + fv * (hC - hA) + fu * (hD - hC), hD - hC, hC - hA);
      return true;
    }
  }
  return false;
}

// SurfaceSampler's level loop: the finest level with a node (found by `lookup`) covering the
// point answers, with its neighbours across a shared edge as further candidates.
// lookup(key, const NodeSurface*&) -> Status; nullptr = no node.
template <class Lookup>
Status sample_levels(double rx, double ry, uint32_t roots_x, uint32_t roots_y, int top, Lookup&& lookup, SurfacePoint& out) {
  for (int level = 0; level <= top; ++level) {  // overview levels answer where no root is resident
    const double size = node_size_m(level);
    const double fx = rx / size, fy = ry / size;
    const double grid_x = double(level_grid_cells(roots_x, level));
    const double grid_y = double(level_grid_cells(roots_y, level));
    if (fx < 0 || fy < 0 || fx > grid_x || fy > grid_y) return Status::success();
    NodeKey holding[4];
    const int holding_count = nodes_holding_point(level, fx, fy, grid_x, grid_y, holding);
    bool any_node = false;
    for (int k = 0; k < holding_count; ++k) {
      const double cx = holding[k].x, cy = holding[k].y;
      const NodeSurface* n = nullptr;
      TERRAIN_TRY(lookup(holding[k], n));
      if (!n) continue;
      if (!any_node) out.node = n->key;
      any_node = true;
      if (node_height(*n, rx, ry, cx, cy, out)) return Status::success();
    }
    if (any_node) {
      out.hole = true;
      return Status::success();
    }
  }
  return Status::success();
}

// Points on a node edge at some level: the level loop over the snapshot's nodes.
SurfacePoint resident_height_on_edge(const SurfaceSnapshot& S, double rx, double ry) {
  SurfacePoint out;
  auto lookup = [&](const NodeKey& k, const NodeSurface*& n) {
    const int32_t i = S.find(k);
    n = i >= 0 ? S.nodes[size_t(i)].s : nullptr;
    return Status::success();
  };
  (void)sample_levels(rx, ry, S.roots_x, S.roots_y, S.top_level, lookup, out);
  if (!(out.hit || out.hole)) return out;
  // Finer data: an archive node of a finer level whose closed square holds the point (none of
  // them is resident, or the level loop would have answered there).
  const std::vector<NodeKey>& keys = *S.archive_keys;
  for (int level = int(out.node.level) - 1; level >= 0 && !out.finer_not_resident; --level) {
    const double fx = rx / node_size_m(level), fy = ry / node_size_m(level);
    const double nx = std::floor(fx), ny = std::floor(fy);
    for (int cand = 0; cand < 4; ++cand) {
      if (((cand & 1) && fx != nx) || ((cand & 2) && fy != ny)) continue;
      const double cx = nx - (cand & 1), cy = ny - ((cand >> 1) & 1);
      if (cx < 0 || cy < 0) continue;
      const NodeKey k{uint32_t(level), uint32_t(cx), uint32_t(cy)};
      if (std::binary_search(keys.begin(), keys.end(), k, directory_less)) out.finer_not_resident = true;
    }
  }
  return out;
}

// ---- Ray casting ------------------------------------------------------------------------------

struct RayWalk {
  const SurfaceSnapshot& S;
  double ox, oy, oz;  // origin minus frame origin
  double dx, dy, dz;  // unit direction
  double best_t;      // nearest hit so far (starts at the max distance)
  RayHit hit;

  // Can the segment t in [t0, t1] reach heights [lo, hi]?
  bool z_overlaps(double t0, double t1, double lo, double hi) const {
    const double z0 = oz + t0 * dz, z1 = oz + t1 * dz;
    const double slack = 1e-6 * (1.0 + std::fabs(z0) + std::fabs(z1));
    return std::max(z0, z1) >= lo - slack && std::min(z0, z1) <= hi + slack;
  }

  // Visits the cells of an nx x ny grid (origin gx, gy, cell size cs) the segment [t0, t1]
  // crosses, front to back, while their entry lies before the best hit. visit(ix, iy, te, tx).
  template <class Visit>
  void walk_grid(double gx, double gy, double cs, int nx, int ny, double t0, double t1, Visit&& visit) {
    const double px = ox + t0 * dx, py = oy + t0 * dy;
    int ix = std::clamp(int(std::floor((px - gx) / cs)), 0, nx - 1);
    int iy = std::clamp(int(std::floor((py - gy) / cs)), 0, ny - 1);
    const double inf = std::numeric_limits<double>::infinity();
    const int sx = dx > 0 ? 1 : -1, sy = dy > 0 ? 1 : -1;
    auto next_x = [&](int i) { return dx != 0 ? (gx + (i + (dx > 0 ? 1 : 0)) * cs - ox) / dx : inf; };
    auto next_y = [&](int j) { return dy != 0 ? (gy + (j + (dy > 0 ? 1 : 0)) * cs - oy) / dy : inf; };
    double tx = next_x(ix), ty = next_y(iy), t = t0;
    for (;;) {
      if (t > best_t) return;
      const double te = std::max(t, std::min({tx, ty, t1}));
      visit(ix, iy, t, te);
      if (te >= t1) return;
      if (tx <= ty) {
        ix += sx;
        if (ix < 0 || ix >= nx) return;
        t = te;
        tx = next_x(ix);
      } else {
        iy += sy;
        if (iy < 0 || iy >= ny) return;
        t = te;
        ty = next_y(iy);
      }
    }
  }

  // The two triangles of quad (i, j) of node n (south-west corner (x0, y0) local, spacing s).
  void test_quad(const NodeSurface& n, double x0, double y0, double s, int i, int j) {
    auto at = [](int a, int b) { return size_t(b * kHeightSamples + a); };
    const size_t A = at(i, j), B = at(i + 1, j), C = at(i, j + 1), D = at(i + 1, j + 1);
    const float* H = n.h.data();
    const double hA = H[A], hB = H[B], hC = H[C], hD = H[D];
    const double inv_s = kScales.inv_spacing[n.key.level];
    const double u0 = (ox - (x0 + i * s)) * inv_s, v0 = (oy - (y0 + j * s)) * inv_s, du = dx * inv_s, dv = dy * inv_s;
    constexpr double kEps = 1e-9;  // quad units: rays along a shared edge hit one side
    // Plane z = hA + u * a + v * b; returns whether it took the hit.
    auto plane = [&](double a, double b, bool south_east) {
      const double f0 = oz - hA - u0 * a - v0 * b, f1 = dz - du * a - dv * b;
      if (f1 == 0) return;  // parallel
      const double t = -f0 / f1;
      if (!(t >= 0 && t < best_t)) return;
      const double u = u0 + t * du, v = v0 + t * dv;
      const bool inside = south_east ? (v >= -kEps && u >= v - kEps && u <= 1 + kEps)
                                     : (u >= -kEps && v >= u - kEps && v <= 1 + kEps);
      if (!inside) return;
      best_t = t;
      hit.hit = true;
      hit.node = n.key;
      const double gx = -(south_east ? a : hD - hC) * inv_s, gy = -(south_east ? b : hC - hA) * inv_s;
      const double inv_len = 1.0 / std::sqrt(gx * gx + gy * gy + 1.0);
      hit.normal = {gx * inv_len, gy * inv_len, inv_len};
    };
    const uint8_t* holes = n.holes.empty() ? nullptr : n.holes.data();
    if (!holes || !(holes[A] || holes[B] || holes[D])) plane(hB - hA, hD - hB, true);
    if (!holes || !(holes[A] || holes[D] || holes[C])) plane(hD - hC, hC - hA, false);
  }

  // Quadrant c of node n where no child is resident: its 4x4 patches, then their quads.
  void walk_own_quadrant(const NodeSurface& n, double x0, double y0, int qx, int qy, double t0, double t1) {
    const double s = vertex_spacing_m(int(n.key.level));
    const double ps = s * detail::kPatchQuads;
    constexpr int kSide = detail::kPatchesSide / 2;  // patches per quadrant side
    const double qx0 = x0 + qx * kSide * ps, qy0 = y0 + qy * kSide * ps;
    walk_grid(qx0, qy0, ps, kSide, kSide, t0, t1, [&](int pi, int pj, double pe, double px) {
      const int P = (qy * kSide + pj) * detail::kPatchesSide + qx * kSide + pi;
      if (!z_overlaps(pe, px, n.patch_min[size_t(P)], n.patch_max[size_t(P)])) return;
      const double gx = qx0 + pi * ps, gy = qy0 + pj * ps;
      const int i0 = (qx * kSide + pi) * detail::kPatchQuads, j0 = (qy * kSide + pj) * detail::kPatchQuads;
      walk_grid(gx, gy, s, detail::kPatchQuads, detail::kPatchQuads, pe, px,
                [&](int i, int j, double, double) { test_quad(n, x0, y0, s, i0 + i, j0 + j); });
    });
  }

  void walk_node(int32_t index, double t0, double t1) {
    const SnapshotNode& N = S.nodes[size_t(index)];
    if (!z_overlaps(t0, t1, N.lo, N.hi)) return;
    const NodeSurface& n = *N.s;
    const double size = node_size_m(int(n.key.level));
    const double x0 = n.key.x * size, y0 = n.key.y * size;
    walk_grid(x0, y0, size / 2, 2, 2, t0, t1, [&](int qx, int qy, double te, double tx) {
      const int32_t child = N.child[size_t(qx | (qy << 1))];
      if (child >= 0)
        walk_node(child, te, tx);
      else
        walk_own_quadrant(n, x0, y0, qx, qy, te, tx);
    });
  }
};

RayHit resident_raycast(const SurfaceSnapshot& S, const Ray& ray) {
  const double len = std::sqrt(ray.direction[0] * ray.direction[0] + ray.direction[1] * ray.direction[1] +
                               ray.direction[2] * ray.direction[2]);
  const bool finite = std::isfinite(ray.origin[0]) && std::isfinite(ray.origin[1]) && std::isfinite(ray.origin[2]) &&
                      std::isfinite(len) && std::isfinite(ray.max_distance_m);
  if (!finite || !(len > 0) || !(ray.max_distance_m >= 0) || S.nodes.empty()) return {};
  RayWalk w{S,
            ray.origin[0] - S.origin_x,
            ray.origin[1] - S.origin_y,
            ray.origin[2],
            ray.direction[0] / len,
            ray.direction[1] / len,
            ray.direction[2] / len,
            ray.max_distance_m,
            {}};
  // Clip the segment to the root grid's footprint (slabs in x and y), walk the top level's grid.
  const double R = node_size_m(kRootLevel), T = node_size_m(S.top_level);
  double t0 = 0, t1 = ray.max_distance_m;
  const double o[2] = {w.ox, w.oy}, d[2] = {w.dx, w.dy}, hi[2] = {S.roots_x * R, S.roots_y * R};
  for (int a = 0; a < 2; ++a) {
    if (d[a] == 0) {
      if (o[a] < 0 || o[a] > hi[a]) return {};
      continue;
    }
    double ta = (0 - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 > t1) return {};
  w.walk_grid(0, 0, T, int(S.top_x), int(S.top_y), t0, t1, [&](int ix, int iy, double te, double tx) {
    const int32_t top = S.top_grid[size_t(iy) * S.top_x + size_t(ix)];
    if (top >= 0) w.walk_node(top, te, tx);
  });
  if (!w.hit.hit) return {};
  RayHit h = w.hit;
  h.distance_m = w.best_t;
  h.point = {ray.origin[0] + w.best_t * w.dx, ray.origin[1] + w.best_t * w.dy, ray.origin[2] + w.best_t * w.dz};
  return h;
}

}  // namespace

// ---- ResidentSurface ----------------------------------------------------------------------------

ResidentSurface::ResidentSurface(std::shared_ptr<const detail::SurfaceSnapshot> snapshot) : s_(std::move(snapshot)) {}

bool ResidentSurface::empty() const { return !s_ || s_->nodes.empty(); }
uint64_t ResidentSurface::frame() const { return s_ ? s_->frame : 0; }

std::vector<NodeKey> ResidentSurface::nodes() const {
  std::vector<NodeKey> keys;
  if (s_)
    for (const SnapshotNode& n : s_->nodes) keys.push_back(n.s->key);
  return keys;
}

SurfacePoint ResidentSurface::height_at(double x, double y) const {
  SurfacePoint out;
  if (!s_ || !std::isfinite(x) || !std::isfinite(y)) return out;
  const SurfaceSnapshot& S = *s_;
  const double rx = x - S.origin_x, ry = y - S.origin_y;
  // Fast path: descend from the top node holding the point (a root without overview levels)
  // through resident children. A point on a node edge at any level is shared by several nodes:
  // the level loop decides as SurfaceSampler.
  const double rfx = rx * kScales.inv_size[kRootLevel], rfy = ry * kScales.inv_size[kRootLevel];
  if (!(rfx >= 0 && rfy >= 0 && rfx <= S.roots_x && rfy <= S.roots_y)) return out;
  const double fx = rx * kScales.inv_size[size_t(S.top_level)], fy = ry * kScales.inv_size[size_t(S.top_level)];
  double nx = std::floor(fx), ny = std::floor(fy);
  if (nx == fx || ny == fy) return resident_height_on_edge(S, rx, ry);
  if (nx >= S.top_x || ny >= S.top_y) return out;
  int32_t index = S.top_grid[size_t(ny) * S.top_x + size_t(nx)];
  if (index < 0) return out;
  for (int level = S.top_level; level > 0; --level) {
    const SnapshotNode& N = S.nodes[size_t(index)];
    const double inv = kScales.inv_size[size_t(level - 1)];
    const double gx = rx * inv, gy = ry * inv;
    const double kx = std::floor(gx), ky = std::floor(gy);
    if (kx == gx || ky == gy) return resident_height_on_edge(S, rx, ry);
    const double bx = kx - 2.0 * N.s->key.x, by = ky - 2.0 * N.s->key.y;
    if (!(bx == 0 || bx == 1) || !(by == 0 || by == 1)) return resident_height_on_edge(S, rx, ry);  // rounding
    const int c = int(bx) | (int(by) << 1);
    if (N.child[size_t(c)] < 0) {
      out.finer_not_resident = (N.s->child_mask >> c) & 1;
      break;
    }
    index = N.child[size_t(c)];
    nx = kx;
    ny = ky;
  }
  const NodeSurface& n = *S.nodes[size_t(index)].s;
  if (!node_height(n, rx, ry, nx, ny, out)) {
    out.hole = true;
    out.node = n.key;
  }
  return out;
}

RayHit ResidentSurface::raycast(const Ray& ray) const { return s_ ? resident_raycast(*s_, ray) : RayHit{}; }

void ResidentSurface::heights_at(std::span<const std::array<double, 2>> points, std::span<SurfacePoint> out) const {
  const size_t n = std::min(points.size(), out.size());
  for (size_t i = 0; i < n; ++i) out[i] = height_at(points[i][0], points[i][1]);
}

void ResidentSurface::raycast(std::span<const Ray> rays, std::span<RayHit> out) const {
  const size_t n = std::min(rays.size(), out.size());
  for (size_t i = 0; i < n; ++i) out[i] = raycast(rays[i]);
}

// ---- ArchiveSurface -----------------------------------------------------------------------------

struct ArchiveSurface::Impl {
  const ArchiveReader& reader;
  struct Cached {
    size_t index;
    std::shared_ptr<const NodeSurface> surface;
  };
  std::list<Cached> cache;  // most recent first
  static constexpr size_t kCacheNodes = 16;
  std::unique_ptr<NodeData> scratch = std::make_unique<NodeData>();

  explicit Impl(const ArchiveReader& r) : reader(r) {}

  Status get(const NodeKey& key, const NodeSurface*& out) {
    out = nullptr;
    const int64_t index = reader.find(key);
    if (index < 0) return Status::success();
    for (auto it = cache.begin(); it != cache.end(); ++it)
      if (it->index == size_t(index)) {
        cache.splice(cache.begin(), cache, it);
        out = cache.front().surface.get();
        return Status::success();
      }
    TERRAIN_TRY(reader.decode_node(size_t(index), *scratch, kSectionHeights | kSectionAlbedo));
    cache.push_front({size_t(index), detail::make_node_surface(reader, size_t(index), *scratch, true)});
    if (cache.size() > kCacheNodes) cache.pop_back();
    out = cache.front().surface.get();
    return Status::success();
  }
};

ArchiveSurface::ArchiveSurface(const ArchiveReader& reader) : impl_(std::make_unique<Impl>(reader)) {}
ArchiveSurface::~ArchiveSurface() = default;

Status ArchiveSurface::height_at(double x, double y, SurfacePoint& out) {
  out = SurfacePoint{};
  if (!impl_->reader.is_open()) return Status::failure(Error::invalid_argument, "archive is not open");
  if (!std::isfinite(x) || !std::isfinite(y)) return Status::failure(Error::invalid_argument, "query point is not finite");
  const WorldInfo& w = impl_->reader.world();
  auto lookup = [&](const NodeKey& k, const NodeSurface*& n) { return impl_->get(k, n); };
  return sample_levels(x - w.origin_x_m, y - w.origin_y_m, w.roots_x, w.roots_y, top_level(w), lookup, out);
}

Status ArchiveSurface::heights_at(std::span<const std::array<double, 2>> points, std::span<SurfacePoint> out) {
  const size_t n = std::min(points.size(), out.size());
  for (size_t i = 0; i < n; ++i)
    TERRAIN_TRY(height_at(points[i][0], points[i][1], out[i]));
  return Status::success();
}

}  // namespace terrain
