// The patch triangulation and LOD stitching rule of terrain/surface_contract.h, checked against
// properties derived here from the geometry (not from the rule's code): the plain grid, exact
// cover of the patch, edges without T-junctions, watertight seams against a coarser neighbour.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "terrain/surface_contract.h"

namespace terrain {
namespace {

using Point = std::pair<int, int>;
using Edge = std::pair<Point, Point>;

Point pt(const NodeVertex& v) { return {v.i, v.j}; }

// Twice the signed area (counter-clockwise > 0).
long twice_area(const PatchTriangle& t) {
  return long(t.v[1].i - t.v[0].i) * (t.v[2].j - t.v[0].j) - long(t.v[2].i - t.v[0].i) * (t.v[1].j - t.v[0].j);
}

std::vector<PatchMesh> meshes_up_to(int max_delta, int decimation, int px, int py) {
  std::vector<PatchMesh> out;
  for (int s = 0; s <= max_delta; ++s)
    for (int w = 0; w <= max_delta; ++w)
      for (int n = 0; n <= max_delta; ++n)
        for (int e = 0; e <= max_delta; ++e) out.push_back({px, py, decimation, {s, w, n, e}});
  return out;
}

TEST(Stitching, NoDeltaIsThePlainGridOfTwoTrianglesPerQuad) {
  for (int e = 0; e <= 4; ++e) {
    const PatchMesh m{3, 5, e, {}};
    const int step = 1 << e, x0 = 48, y0 = 80;
    std::vector<PatchTriangle> want;
    for (int y = y0; y < y0 + 16; y += step)
      for (int x = x0; x < x0 + 16; x += step) {
        want.push_back({{{x, y}, {x + step, y}, {x + step, y + step}}});
        want.push_back({{{x, y}, {x + step, y + step}, {x, y + step}}});
      }
    const std::vector<PatchTriangle> got = patch_triangles(m);
    ASSERT_EQ(got.size(), size_t(2 * (16 / step) * (16 / step))) << "e " << e;
    for (size_t k = 0; k < want.size(); ++k)
      for (int c = 0; c < 3; ++c) EXPECT_EQ(pt(got[k].v[c]), pt(want[k].v[c])) << "e " << e << " triangle " << k;
    for (int j = 0; j <= 16 / step; ++j)
      for (int i = 0; i <= 16 / step; ++i)
        EXPECT_EQ(pt(stitched_vertex(m, i, j)), Point(x0 + i * step, y0 + j * step));
  }
}

// For d <= 4 the patch keeps its square: every triangle is counter-clockwise, inside the square,
// their areas add up to 16 x 16 quads, and each inner edge is shared by exactly two triangles in
// opposite directions while the rest lie on the square's sides: an exact cover.
TEST(Stitching, EveryDeltaCoversThePatchExactly) {
  size_t meshes = 0;
  for (int e = 0; e <= 4; ++e)
    for (const Point& patch : {Point{0, 0}, Point{3, 6}, Point{7, 7}})
      for (const PatchMesh& m : meshes_up_to(4, e, patch.first, patch.second)) {
        const int x0 = 16 * m.px, y0 = 16 * m.py;
        long area2 = 0;
        std::map<Edge, int> edges;
        for (const PatchTriangle& t : patch_triangles(m)) {
          const long a = twice_area(t);
          ASSERT_GT(a, 0) << "flipped or degenerate triangle";
          area2 += a;
          for (int k = 0; k < 3; ++k) {
            ASSERT_GE(t.v[k].i, x0);
            ASSERT_LE(t.v[k].i, x0 + 16);
            ASSERT_GE(t.v[k].j, y0);
            ASSERT_LE(t.v[k].j, y0 + 16);
            ++edges[{pt(t.v[k]), pt(t.v[(k + 1) % 3])}];
          }
        }
        ASSERT_EQ(area2, 2 * 16 * 16);
        for (const auto& [edge, count] : edges) {
          ASSERT_EQ(count, 1) << "an edge used twice in one direction (overlap)";
          const auto [a, b] = edge;
          const bool side = (a.first == b.first && (a.first == x0 || a.first == x0 + 16)) ||
                            (a.second == b.second && (a.second == y0 || a.second == y0 + 16));
          if (!side) {
            ASSERT_EQ(edges.count({b, a}), 1u) << "an inner edge without its twin (a hole)";
          }
        }
        ++meshes;
      }
  EXPECT_EQ(meshes, size_t(5 * 3 * 625));
}

// The vertices the triangles put on one side of the patch (x along the side).
std::set<int> side_vertices(const std::vector<PatchTriangle>& tris, int side, int x0, int y0) {
  std::set<int> out;
  for (const PatchTriangle& t : tris)
    for (const NodeVertex& v : t.v) {
      if (side == 0 && v.j == y0) out.insert(v.i);
      if (side == 1 && v.i == x0) out.insert(v.j);
      if (side == 2 && v.j == y0 + 16) out.insert(v.i);
      if (side == 3 && v.i == x0 + 16) out.insert(v.j);
    }
  return out;
}

// No T-junctions: the vertices on a side facing a neighbour coarser by d are exactly that
// neighbour's vertices, 2^d apart (2^e when the patch's own decimation e is coarser), corners
// included; with two coarser neighbours at a corner both sides hold at once.
TEST(Stitching, SidesFacingACoarserNeighbourHaveOnlyItsVertices) {
  for (int e = 0; e <= 4; ++e)
    for (const Point& patch : {Point{0, 0}, Point{1, 2}, Point{7, 7}})
      for (const PatchMesh& m : meshes_up_to(4, e, patch.first, patch.second)) {
        const int x0 = 16 * m.px, y0 = 16 * m.py;
        const std::vector<PatchTriangle> tris = patch_triangles(m);
        const int d[4] = {m.deltas.south, m.deltas.west, m.deltas.north, m.deltas.east};
        for (int side = 0; side < 4; ++side) {
          const int along0 = side % 2 == 0 ? x0 : y0;
          const int step = 1 << std::max(d[side], e);
          std::set<int> want;
          for (int k = along0; k <= along0 + 16; k += step) want.insert(k);
          ASSERT_EQ(side_vertices(tris, side, x0, y0), want)
              << "side " << side << " d " << d[side] << " e " << e << " patch " << m.px << "," << m.py;
        }
      }
}

// d = 5..7 (the viewer's deltas onto decimated or coarsened roots) collapse a whole side, corners
// included, onto the coarser grid (reaching into earlier patches). Nothing flips while such a side
// meets no collapsing side at its corners; with one there (e.g. south 6, west 2) triangles of
// the corner quad do flip, so the viewer must not produce that (its own reference tests check
// its meshes for flips).
TEST(Stitching, DeltasBeyondThePatchCollapseTheWholeSide) {
  size_t checked = 0, unflipped_meshes = 0;
  for (int e = 0; e <= 4; ++e)
    for (const Point& patch : {Point{0, 0}, Point{1, 2}, Point{5, 3}, Point{7, 7}})
      for (int s : {0, 5, 6, 7})
        for (int w : {0, 5, 6, 7})
          for (int n : {0, 5, 6, 7})
            for (int ea : {0, 5, 6, 7}) {
              const PatchMesh m{patch.first, patch.second, e, {s, w, n, ea}};
              const int d[4] = {s, w, n, ea};
              bool wide_corner = false;  // a side with d > 4 next to a collapsing side
              for (int k = 0; k < 4; ++k) wide_corner = wide_corner || (d[k] > 4 && (d[(k + 1) % 4] > 0 || d[(k + 3) % 4] > 0));
              if (!wide_corner) {
                for (const PatchTriangle& t : patch_triangles(m)) ASSERT_GT(twice_area(t), 0) << "flipped triangle";
                ++unflipped_meshes;
              }
              const int last = 16 >> e, x0 = 16 * m.px, y0 = 16 * m.py;
              for (int k = 0; k <= last; ++k) {
                // (mesh vertex, coordinate along the side, its start, delta) per side
                const struct {
                  NodeVertex v;
                  int along, start, d;
                } sides[4] = {{stitched_vertex(m, k, 0), 0, x0, s},
                              {stitched_vertex(m, 0, k), 1, y0, w},
                              {stitched_vertex(m, k, last), 0, x0, n},
                              {stitched_vertex(m, last, k), 1, y0, ea}};
                for (const auto& sd : sides) {
                  if (sd.d == 0) continue;
                  const int c = sd.along == 0 ? sd.v.i : sd.v.j;
                  const int before = sd.start + (k << e);  // where the vertex sits unstitched
                  ASSERT_EQ(c % (1 << sd.d), 0) << "d " << sd.d;
                  ASSERT_LE(c, before);
                  ASSERT_GT(c + (1 << sd.d), before) << "collapsed onto its own group's first vertex";
                  ++checked;
                }
              }
            }
  EXPECT_EQ(checked, size_t(3 * 256 * 4 * (17 + 9 + 5 + 3 + 2)));  // 3 collapsing sides on average
  // Per patch and e: none, one side, or two opposite sides collapsing: 1 + 4 * 3 + 2 * 9 = 31.
  EXPECT_EQ(unflipped_meshes, size_t(5 * 4 * 31));
}

// Hand-derived: both neighbours at the south-west corner coarser by 1. The corner quad collapses
// completely, its two neighbours fan from the corner, the next quad is untouched.
TEST(Stitching, CornerWithTwoCoarserNeighbours) {
  const PatchMesh m{2, 1, 0, {1, 1, 0, 0}};
  const int x = 32, y = 16;
  for (int t = 0; t < 2; ++t) EXPECT_TRUE(stitched_quad_triangle(m, 0, 0, t).degenerate());
  const PatchTriangle want[] = {
      {{{x, y}, {x + 2, y}, {x + 2, y + 1}}},          // quad (1, 0)
      {{{x, y}, {x + 2, y + 1}, {x + 1, y + 1}}},
      {{{x, y}, {x + 1, y + 1}, {x + 1, y + 2}}},      // quad (0, 1)
      {{{x, y}, {x + 1, y + 2}, {x, y + 2}}},
      {{{x + 1, y + 1}, {x + 2, y + 1}, {x + 2, y + 2}}},  // quad (1, 1)
      {{{x + 1, y + 1}, {x + 2, y + 2}, {x + 1, y + 2}}}};
  const Point quads[] = {{1, 0}, {1, 0}, {0, 1}, {0, 1}, {1, 1}, {1, 1}};
  for (int k = 0; k < 6; ++k) {
    const PatchTriangle got = stitched_quad_triangle(m, quads[k].first, quads[k].second, k % 2);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(pt(got.v[c]), pt(want[k].v[c])) << "triangle " << k;
  }
  // Different levels at one corner: south coarser by 2, west by 3 (a 4 x 8 fan region).
  const PatchMesh m2{0, 0, 0, {2, 3, 0, 0}};
  EXPECT_EQ(pt(stitched_vertex(m2, 3, 0)), Point(0, 0));
  EXPECT_EQ(pt(stitched_vertex(m2, 5, 0)), Point(4, 0));
  EXPECT_EQ(pt(stitched_vertex(m2, 0, 7)), Point(0, 0));
  EXPECT_EQ(pt(stitched_vertex(m2, 0, 9)), Point(0, 8));
  EXPECT_EQ(pt(stitched_vertex(m2, 1, 1)), Point(1, 1));  // inner vertices never move
}

// The seam between a patch whose neighbour is coarser by d and that neighbour drawn with d levels
// fewer vertices (a patch of the same node decimated by d): together they are watertight.
TEST(Stitching, SeamAgainstACoarserNeighbourIsWatertight) {
  for (int d = 1; d <= 4; ++d)
    for (int side = 0; side < 4; ++side) {
      PatchMesh fine{3, 3, 0, {}};
      PatchMesh coarse{3, 3, d, {}};
      int* delta[4] = {&fine.deltas.south, &fine.deltas.west, &fine.deltas.north, &fine.deltas.east};
      *delta[side] = d;
      if (side == 0) coarse.py = 2;
      if (side == 1) coarse.px = 2;
      if (side == 2) coarse.py = 4;
      if (side == 3) coarse.px = 4;
      std::map<Edge, int> edges;
      for (const PatchMesh& m : {fine, coarse})
        for (const PatchTriangle& t : patch_triangles(m))
          for (int k = 0; k < 3; ++k) ++edges[{pt(t.v[k]), pt(t.v[(k + 1) % 3])}];
      // Every edge on the shared side has its twin.
      size_t seam = 0;
      for (const auto& [edge, count] : edges) {
        const auto [a, b] = edge;
        const bool on_seam = side % 2 == 0 ? (a.second == b.second && a.second == (side == 0 ? 48 : 64))
                                           : (a.first == b.first && a.first == (side == 1 ? 48 : 64));
        if (!on_seam) continue;
        ++seam;
        EXPECT_EQ(edges.count({b, a}), 1u) << "d " << d << " side " << side << ": a crack along the seam";
      }
      EXPECT_EQ(seam, size_t(2 * (16 >> d))) << "d " << d << " side " << side;
    }
}

}  // namespace
}  // namespace terrain
