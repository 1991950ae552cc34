// Tests of the functions of three stage folders of cooker/src: pyramid/ (quantization, the
// continuous surface of reconstruct.h), voids/ (void fill) and frame/ (CRSs, projection anchors).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "frame/crs.h"
#include "frame/frame.h"
#include "pyramid/quantize.h"
#include "inputs/raster.h"
#include "pyramid/reconstruct.h"
#include "base/sample_window.h"
#include "voids/void_fill.h"

using namespace terrain;
using namespace terrain::cook;

TEST(Quantize, VertexLevelIsTheCoarsestLatticeHoldingTheVertex) {
  EXPECT_EQ(vertex_level(0, 0), 5);
  EXPECT_EQ(vertex_level(1, 0), 0);
  EXPECT_EQ(vertex_level(2, 4), 1);
  EXPECT_EQ(vertex_level(8, 16), 3);
  EXPECT_EQ(vertex_level(32, 64), 5);
  EXPECT_EQ(vertex_level(1 << 20, 0), 5);  // capped at the roots
  EXPECT_EQ(vertex_level(-4, 8), 2);        // window margins west of the origin
}

TEST(Quantize, UnitsAreMultiplesOfTheStepAndWithinHalfAStep) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> h(-500.0, 9000.0);
  for (int s = 0; s <= 10; ++s)
    for (int k = 0; k < 1000; ++k) {
      const double v = h(rng);
      const int64_t u = quantize_units(v, s);
      EXPECT_EQ(u % (int64_t(1) << s), 0);
      EXPECT_LE(std::fabs(double(u) * kHeightUnitM - v), 0.5 * std::ldexp(1.0, s) * kHeightUnitM + 1e-12);
    }
}

// quantize_row (compute_window's rows, 4 lanes at a time) against the per-vertex rule: units bit
// for bit and the holes, for every step 0..14, heights on exact half steps (where rounding
// decides), signed zeros, the archive's limits, vertices without data holding NaN or 1e30 (never
// read), and rows of 1..40 vertices (lanes and tails); false exactly when a vertex with data is
// NaN or beyond +-kMaxHeightUnits, wherever it sits in the row.
TEST(Quantize, RowEqualsThePerVertexRule) {
  std::mt19937 rng(41);
  std::uniform_int_distribution<int> step_of(0, 14), kind_of(0, 15), len(1, 40);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double limit = double(kMaxHeightUnits) * kHeightUnitM;
  long vertices = 0, halves = 0, refused = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int n = len(rng);
    const size_t m = static_cast<size_t>(n);
    std::vector<double> h(m), scale(m), step(m);
    std::vector<int> shift(m);
    std::vector<uint8_t> ok(m, 1), hole(m, 9);
    std::vector<int32_t> units(m, -7);
    for (int i = 0; i < n; ++i) {
      shift[size_t(i)] = step_of(rng);
      scale[size_t(i)] = std::ldexp(1024.0, -shift[size_t(i)]);
      step[size_t(i)] = std::ldexp(1.0, shift[size_t(i)]);
      double v = 0;
      const double units_max = double(kMaxHeightUnits) - step[size_t(i)];  // rounds within the limit
      switch (kind_of(rng)) {
        case 0: case 1: case 2: case 3:  // an exact half step
          v = (std::floor(u(rng) * 0.9 * std::ldexp(1.0, 24 - shift[size_t(i)])) + 0.5) / scale[size_t(i)];
          ++halves;
          break;
        case 4: v = u(rng) < 0 ? -0.0 : 0.0; break;
        case 5: v = (u(rng) < 0 ? -units_max : units_max) * kHeightUnitM; break;
        case 6: ok[size_t(i)] = 0, v = u(rng) < 0 ? NAN : 1e30; break;
        case 7: case 8: case 9: v = u(rng) * 16000.0; break;
        case 15: v = u(rng) < -0.6 ? limit : u(rng) * 300.0; break;  // the limit itself: refused with coarse steps
        default: v = u(rng) * 300.0; break;
      }
      h[size_t(i)] = v;
    }
    // The per-vertex rule refuses a vertex whose rounded units pass the limit (at the limit itself
    // with a coarse step): such rows must be refused too.
    bool accepted = true;
    for (int i = 0; i < n; ++i) {
      if (!ok[size_t(i)]) continue;
      const int64_t q = quantize_units(h[size_t(i)], scale[size_t(i)], shift[size_t(i)]);
      accepted = accepted && q <= kMaxHeightUnits && q >= -kMaxHeightUnits;
    }
    ASSERT_EQ(quantize_row(h.data(), ok.data(), scale.data(), step.data(), n, units.data(), hole.data()), accepted);
    refused += !accepted;
    if (!accepted) continue;
    for (int i = 0; i < n; ++i) {
      ++vertices;
      ASSERT_EQ(hole[size_t(i)], ok[size_t(i)] ? 0 : 1);
      const int64_t want = ok[size_t(i)] ? quantize_units(h[size_t(i)], scale[size_t(i)], shift[size_t(i)]) : 0;
      ASSERT_EQ(int64_t(units[size_t(i)]), want) << "h " << h[size_t(i)] << " step 2^" << shift[size_t(i)];
    }
    // One vertex with data out of range or NaN, anywhere: refused.
    const int at = int(rng() % uint32_t(n));
    for (double bad : {limit * 1.0001, -limit * 1.0001, double(NAN), 1e30}) {
      std::vector<double> hb = h;
      std::vector<uint8_t> okb = ok;
      hb[size_t(at)] = bad;
      okb[size_t(at)] = 1;
      EXPECT_FALSE(quantize_row(hb.data(), okb.data(), scale.data(), step.data(), n, units.data(), hole.data()))
          << "n " << n << " at " << at << " h " << bad;
    }
  }
  EXPECT_GT(vertices, 30000);
  EXPECT_GT(halves, 8000);
  EXPECT_GT(refused, 100);
  std::printf("%ld vertices equal (%ld on half steps), %ld rows refused at the limit\n", vertices, halves, refused);
}

TEST(Quantize, StepsFitSixteenBitsWithTheRootRounding) {
  // 9278 m in a root (Dead Sea to Everest): 9.5 M units need step 2^8 (0.25 m).
  const int root = required_step(9278.0, -1);
  EXPECT_EQ(root, 8);
  EXPECT_LE((9278.0 * 1024 + 1 + std::ldexp(1.0, root)) / std::ldexp(1.0, root), 65535.0);
  // 0.5 m of relief fits 16 bits at 1/1024 m, even with the root step's rounding on top.
  EXPECT_EQ(required_step(0.5, root), 0);
  // 64 m of relief is 65536 units: one unit too many for step 1.
  EXPECT_EQ(required_step(64.0, 0), 1);
  EXPECT_EQ(required_step(63.0, 0), 0);
  // 1 mm of relief: the finest step.
  EXPECT_EQ(required_step(0.001, -1), 0);
  // The bound is never too small: random ranges always fit.
  std::mt19937 rng(5);
  for (int k = 0; k < 1000; ++k) {
    const double range = std::uniform_real_distribution<double>(0, 16000)(rng);
    const int rs = required_step(range, -1);
    EXPECT_LE(range * 1024 + 1 + std::ldexp(1.0, rs), 65535.0 * std::ldexp(1.0, rs));
    if (rs > 0) {
      EXPECT_GT(range * 1024 + 1 + std::ldexp(1.0, rs - 1), 65535.0 * std::ldexp(1.0, rs - 1));
    }
  }
}

// The tolerance's step: the largest power of two of units <= tolerance / 32, clamped to 2^0..2^14.
TEST(Quantize, ToleranceStepIsTheLargestPowerOfTwoWithinAThirtySecondOfTheTolerance) {
  EXPECT_EQ(tolerance_step(0.5), 4);                 // 15.6 mm
  EXPECT_EQ(tolerance_step(0.5 - 1e-9), 3);          // just below: 7.8 mm
  EXPECT_EQ(tolerance_step(1.0), 5);
  EXPECT_EQ(tolerance_step(0.1), 1);                 // 3.1 mm <= 2^1 units (1.95 mm)
  EXPECT_EQ(tolerance_step(32.0 / 1024.0), 0);       // exactly one unit
  EXPECT_EQ(tolerance_step(0.0005), 0);              // finer than a unit: still one unit
  EXPECT_EQ(tolerance_step(1e6), 14);                // the format's cap
  for (double t : {0.01, 0.05, 0.25, 0.5, 2.0, 10.0}) {
    const double step_m = std::ldexp(1.0, tolerance_step(t)) * kHeightUnitM;
    if (tolerance_step(t) > 0) {
      EXPECT_LE(step_m, t / 32.0);
    }
    EXPECT_GT(2.0 * step_m, t / 32.0);
  }
}

TEST(Quantize, PackStoresInheritedValuesExactly) {
  // Values rounded at a coarse step (2^6) and a fine one (2^2), packed at step 2^2.
  std::vector<int32_t> units(kHeightCount);
  std::vector<uint8_t> hole(kHeightCount, 0);
  std::mt19937 rng(3);
  for (size_t k = 0; k < units.size(); ++k)
    units[k] = int32_t(quantize_units(std::uniform_real_distribution<double>(-20, 40)(rng), k % 7 == 0 ? 6 : 2));
  hole[100] = 1;
  units[100] = 123457;  // a hole's value is ignored
  NodeRecord rec;
  std::array<uint16_t, kHeightCount> r16{};
  ASSERT_TRUE(pack_heights(units.data(), hole.data(), kHeightSamples, 2, rec, r16).ok());
  EXPECT_EQ(rec.flags & kNodeFlagHasHoles, kNodeFlagHasHoles);
  for (size_t k = 0; k < units.size(); ++k) {
    if (hole[k]) continue;
    EXPECT_EQ(vertex_units(rec.height_offset, r16[k], 2), units[k]);
  }
  // A value that is not a multiple of the step is refused, not rounded silently.
  units[5] = units[0] + 1;
  EXPECT_EQ(pack_heights(units.data(), hole.data(), kHeightSamples, 2, rec, r16).code, Error::internal);
}

namespace {
Raster plane_raster(int w, int h, double a, double bx, double by) {
  Raster r;
  r.width = w;
  r.height = h;
  r.values.resize(size_t(w) * size_t(h));
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) r.values[size_t(row) * size_t(w) + size_t(col)] = float(a + bx * col + by * row);
  return r;
}
}  // namespace

TEST(Reconstruct, CatmullRomPassesThroughSamplesAndReproducesPlanes) {
  Raster r = plane_raster(20, 20, 100.0, 0.25, -0.5);
  SourceSurface s(r);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 19.0);
  for (int k = 0; k < 2000; ++k) {
    const double c = u(rng), w = u(rng);
    double h = 0;
    ASSERT_TRUE(s.sample(c, w, h));
    EXPECT_NEAR(h, 100.0 + 0.25 * c - 0.5 * w, 2e-5);  // float samples, exact kernel
  }
  // Non-planar data: the surface still interpolates every sample exactly.
  Raster bumpy = plane_raster(16, 16, 0, 0, 0);
  for (size_t i = 0; i < bumpy.values.size(); ++i) bumpy.values[i] = float((i * 7919) % 113);
  SourceSurface sb(bumpy);
  for (int row = 0; row < 16; ++row)
    for (int col = 0; col < 16; ++col) {
      double h = 0;
      ASSERT_TRUE(sb.sample(col, row, h));
      EXPECT_EQ(h, double(bumpy.at(col, row)));
    }
}

TEST(Reconstruct, NodataFallsBackToBilinearOverValidTapsAndHolesFollowTheNearestSample) {
  Raster r = plane_raster(10, 10, 50.0, 1.0, 0.0);
  r.values[size_t(5) * 10 + 5] = NAN;
  SourceSurface s(r);
  double h = 0;
  EXPECT_FALSE(s.sample(5.2, 4.9, h));  // nearest sample is the void
  ASSERT_TRUE(s.sample(5.6, 5.0, h));   // nearest is (6, 5): bilinear from (6,5) only on this row
  EXPECT_NEAR(h, 56.0, 1e-6);
  ASSERT_TRUE(s.sample(3.5, 5.5, h));  // 16 taps include the void: bilinear fallback, still exact on a plane
  EXPECT_NEAR(h, 53.5, 1e-6);
  // Coverage reaches half a sample beyond the raster, pixel edges included on every side.
  EXPECT_TRUE(s.covered(-0.49, 3.0));
  EXPECT_TRUE(s.covered(-0.5, 3.0));
  EXPECT_FALSE(s.covered(-0.51, 3.0));
  EXPECT_TRUE(s.covered(9.5, 3.0));
  EXPECT_FALSE(s.covered(9.51, 3.0));
  EXPECT_TRUE(s.covered(4.5, 5.5));    // corner of the void's pixel: three valid neighbours
  EXPECT_FALSE(s.covered(5.0, 5.49));  // inside the void's pixel
}

// The shared-axis and cached-row forms of the surface (used for vertex rows and columns) give the
// very bits of the per-point form: a vertex gets one value whichever node computes it.
TEST(Reconstruct, SharedAxesAndCachedRowsGiveIdenticalBits) {
  Raster r = plane_raster(40, 40, 0, 0, 0);
  for (size_t i = 0; i < r.values.size(); ++i) r.values[i] = float(std::sin(double(i) * 0.37) * 100.0);
  r.values[size_t(20) * 40 + 20] = NAN;
  SourceSurface s(r);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-0.6, 39.6);
  int compared = 0;
  for (int k = 0; k < 20000; ++k) {
    const double c = u(rng), w = u(rng);
    double a = 0, b = 0, d = 0;
    const bool ok_a = s.sample(c, w, a);
    const SourceSurface::Axis x = s.column(c), y = s.row(w);
    const bool ok_b = s.sample(x, y, b);
    ASSERT_EQ(ok_a, ok_b);
    if (ok_a) {
      EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0);
    }
    if (s.x_interior(x) && s.y_interior(y)) {
      double rows[4];
      const double* at[4];
      for (int t = 0; t < 4; ++t) {
        rows[t] = s.horizontal(x, y.i - 1 + t);
        at[t] = &rows[t];
      }
      ASSERT_EQ(s.sample_rows(x, y, at, d), ok_a);
      if (ok_a) {
        EXPECT_EQ(std::memcmp(&a, &d, sizeof a), 0);
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 15000);
}

// sample_points (rows mapped point by point: geographic sources through the anchors) computes the
// axes of a run in vector lanes; every point must keep sample()'s bits and hole decision: inside,
// at the raster's edges and beyond them, next to nodata, on integer coordinates and half-sample
// ties, for NaN and far-off coordinates, and for runs of any length (lanes and the 64-point runs
// partly filled).
TEST(Reconstruct, SamplePointsGivesEveryPointTheBitsOfSample) {
  Raster r = plane_raster(37, 29, 0, 0, 0);
  for (size_t i = 0; i < r.values.size(); ++i) r.values[i] = float(std::sin(double(i) * 0.37) * 100.0 - 40.0);
  for (const auto& [c, w] : std::vector<std::pair<int, int>>{{20, 14}, {0, 7}, {36, 28}, {5, 0}, {21, 14}})
    r.values[size_t(w) * 37 + size_t(c)] = NAN;
  SourceSurface s(r);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-3.0, 40.0);
  std::uniform_int_distribution<int> pick(0, 9), len(1, 200);
  int points = 0, holes = 0, general = 0;
  for (int run = 0; run < 400; ++run) {
    const int n = len(rng);
    std::vector<double> cols(static_cast<size_t>(n)), rows(static_cast<size_t>(n)), h(static_cast<size_t>(n), -1.0);
    std::vector<uint8_t> ok(size_t(n), 7);
    for (int k = 0; k < n; ++k) {
      double c = u(rng), w = u(rng) * 29.0 / 37.0;
      switch (pick(rng)) {  // special coordinates
        case 0: c = std::round(c); break;
        case 1: w = std::floor(w) + 0.5; break;
        case 2: c = std::numeric_limits<double>::quiet_NaN(); break;
        case 3: w = (k % 2 ? 1e12 : -1e12); break;
        case 4: c = std::floor(c) + 0.5, w = std::round(w); break;
        default: break;
      }
      cols[size_t(k)] = c;
      rows[size_t(k)] = w;
    }
    s.sample_points(cols.data(), rows.data(), n, h.data(), ok.data());
    for (int k = 0; k < n; ++k) {
      double want = 0;
      const bool want_ok = s.sample(cols[size_t(k)], rows[size_t(k)], want);
      ASSERT_EQ(ok[size_t(k)], want_ok ? 1 : 0) << "point " << k << " (" << cols[size_t(k)] << ", " << rows[size_t(k)] << ")";
      ++points;
      if (!want_ok) {
        ++holes;
        continue;
      }
      EXPECT_EQ(std::memcmp(&want, &h[size_t(k)], sizeof want), 0) << cols[size_t(k)] << ", " << rows[size_t(k)];
      const SourceSurface::Axis x = s.column(cols[size_t(k)]), y = s.row(rows[size_t(k)]);
      general += !(s.x_interior(x) && s.y_interior(y));
    }
  }
  // The mix the loop is meant to reach: holes (outside, NaN, voids) and edge points of the general path.
  EXPECT_GT(points, 30000);
  EXPECT_GT(holes, 3000);
  EXPECT_GT(general, 2000);
  // Vertices denser than the source (lines of points 0.02-0.4 samples apart, in any direction):
  // consecutive points share a source cell, whose widened taps sample_points reuses.
  std::uniform_real_distribution<double> step(0.02, 0.4), angle(0.0, 6.2832);
  int shared = 0;
  for (int run = 0; run < 300; ++run) {
    const int n = len(rng);
    const double a = angle(rng), d = step(rng);
    double c = u(rng), w = u(rng) * 29.0 / 37.0;
    std::vector<double> cols, rows;
    for (int k = 0; k < n; ++k, c += d * std::cos(a), w += d * std::sin(a)) {
      cols.push_back(c);
      rows.push_back(w);
    }
    std::vector<double> h(cols.size(), -1.0);
    std::vector<uint8_t> ok(cols.size(), 7);
    s.sample_points(cols.data(), rows.data(), n, h.data(), ok.data());
    for (int k = 0; k < n; ++k) {
      double want = 0;
      const bool want_ok = s.sample(cols[size_t(k)], rows[size_t(k)], want);
      ASSERT_EQ(ok[size_t(k)], want_ok ? 1 : 0) << "point " << k;
      if (want_ok) {
        ASSERT_EQ(std::memcmp(&want, &h[size_t(k)], sizeof want), 0) << cols[size_t(k)] << ", " << rows[size_t(k)];
      }
      shared += k > 0 && std::floor(cols[size_t(k)]) == std::floor(cols[size_t(k) - 1]) &&
                std::floor(rows[size_t(k)]) == std::floor(rows[size_t(k) - 1]);
    }
  }
  EXPECT_GT(shared, 5000);
}

// Zero ground (the sea of SRTM tiles): compute_window writes +0 for mapped rows whose points all
// lie inside SourceSurface::zero_bounds. Bound checked: every such point gets exactly sample()'s +0 (and
// sample_points'), including points on the bounds' lower edges and just below their upper edges;
// the zero block is ringed by nonzero samples, so bounds one sample too wide read one of them
// (the points just outside do, below). Extents reaching a nonzero sample, a NaN or the window's
// edge give no bounds.
TEST(Reconstruct, ZeroBoundsHoldOnlyPointsWhoseTapsAreAllZero) {
  constexpr int kW = 64, kH = 48;
  Raster r = plane_raster(kW, kH, 0, 0, 0);
  for (size_t i = 0; i < r.values.size(); ++i) r.values[i] = float(50.0 + 20.0 * std::sin(double(i) * 0.37));
  for (int row = 8; row <= 30; ++row)  // the zero block: columns 10..40, rows 8..30, signed zeros mixed
    for (int col = 10; col <= 40; ++col) r.values[size_t(row) * kW + size_t(col)] = (col + row) % 3 ? 0.0f : -0.0f;
  const SourceSurface s(r);
  const auto bounded = [](const SourceSurface::ZeroBounds& b) { return b.c_lo < b.c_hi && b.r_lo < b.r_hi; };
  // Extent 11..38.9 x 9..28.9 without spare reads columns 10..40, rows 8..30: the block exactly.
  const SourceSurface::ZeroBounds b = s.zero_bounds(11.0, 38.9, 9.0, 28.9, 0);
  ASSERT_TRUE(bounded(b));
  EXPECT_EQ(b.c_lo, 11.0);
  EXPECT_EQ(b.c_hi, 39.0);
  EXPECT_EQ(b.r_lo, 9.0);
  EXPECT_EQ(b.r_hi, 29.0);
  EXPECT_TRUE(bounded(s.zero_bounds(13.0, 36.9, 11.0, 26.9, 2)));
  EXPECT_FALSE(bounded(s.zero_bounds(10.9, 38.9, 9.0, 28.9, 0)));  // reaches column 9
  EXPECT_FALSE(bounded(s.zero_bounds(11.0, 39.0, 9.0, 28.9, 0)));  // reaches column 41
  EXPECT_FALSE(bounded(s.zero_bounds(11.0, 38.9, 8.9, 28.9, 0)));  // reaches row 7
  EXPECT_FALSE(bounded(s.zero_bounds(11.0, 38.9, 9.0, 29.0, 0)));  // reaches row 31
  EXPECT_FALSE(bounded(s.zero_bounds(11.0, 38.9, 9.0, 28.9, 1)));
  EXPECT_FALSE(bounded(s.zero_bounds(std::nan(""), 38.9, 9.0, 28.9, 0)));
  EXPECT_FALSE(bounded(s.zero_bounds(11.0, INFINITY, 9.0, 28.9, 0)));
  Raster voided = r;
  voided.values[size_t(20) * kW + 25] = NAN;
  EXPECT_FALSE(bounded(SourceSurface(voided).zero_bounds(11.0, 38.9, 9.0, 28.9, 0)));
  // A window of the source that ends at column 11: the same zeros, but not all inside it.
  SampleWindow win;
  win.rect = {11, 0, kW - 1, kH - 1};
  win.source_width = kW;
  win.source_height = kH;
  win.values.resize(win.rect.samples());
  for (int row = 0; row < kH; ++row)
    for (int col = 11; col < kW; ++col) win.values[win.index(col, row)] = r.values[size_t(row) * kW + size_t(col)];
  EXPECT_FALSE(bounded(SourceSurface(win).zero_bounds(11.0, 38.9, 9.0, 28.9, 0)));
  EXPECT_TRUE(bounded(SourceSurface(win).zero_bounds(12.0, 38.9, 9.0, 28.9, 0)));

  std::mt19937 rng(23);
  std::uniform_real_distribution<double> uc(b.c_lo, b.c_hi), ur(b.r_lo, b.r_hi);
  std::vector<double> cols, rows;
  for (int k = 0; k < 3000; ++k) {
    double c = uc(rng), w = ur(rng);
    if (k % 7 == 0) c = std::floor(c);  // integer coordinates, the lower edge among them
    if (k % 11 == 0) w = b.r_lo;
    if (k % 13 == 0) c = std::nextafter(b.c_hi, 0.0);  // just below the upper edge
    if (k % 17 == 0) w = std::nextafter(b.r_hi, 0.0);
    ASSERT_TRUE(b.holds(c, w));
    cols.push_back(c);
    rows.push_back(w);
  }
  std::vector<double> h(cols.size(), -1.0);
  std::vector<uint8_t> ok(cols.size(), 0);
  s.sample_points(cols.data(), rows.data(), int(cols.size()), h.data(), ok.data());
  const double plus_zero = 0.0;
  for (size_t k = 0; k < cols.size(); ++k) {
    double one = -1.0;
    ASSERT_TRUE(s.sample(cols[k], rows[k], one));
    ASSERT_EQ(std::memcmp(&one, &plus_zero, sizeof one), 0) << cols[k] << ", " << rows[k] << ": " << one;
    ASSERT_EQ(ok[k], 1);
    ASSERT_EQ(std::memcmp(&h[k], &plus_zero, sizeof plus_zero), 0) << cols[k] << ", " << rows[k];
  }
  // Half a sample outside, a tap reads the ring (on the edges themselves it carries no weight).
  for (const auto& [c, w] : std::vector<std::pair<double, double>>{
           {b.c_hi + 0.5, 20.0}, {b.c_lo - 0.5, 20.0}, {20.0, b.r_hi + 0.5}, {20.0, b.r_lo - 0.5}}) {
    EXPECT_FALSE(b.holds(c, w));
    double one = 0.0;
    ASSERT_TRUE(s.sample(c, w, one));
    EXPECT_NE(one, 0.0) << c << ", " << w;
  }
}

TEST(VoidFill, SmallEnclosedVoidsAreFilledHarmonicallyAndBorderVoidsStayHoles) {
  Raster r = plane_raster(40, 30, 10.0, 0.5, 0.25);
  // A 3x3 enclosed void, and a strip along the west border.
  for (int row = 10; row < 13; ++row)
    for (int col = 20; col < 23; ++col) r.values[size_t(row) * 40 + size_t(col)] = NAN;
  for (int row = 0; row < 30; ++row) r.values[size_t(row) * 40] = NAN;
  std::vector<uint8_t> filled;
  VoidStats st;
  ASSERT_TRUE(fill_voids(r, NodataPolicy::automatic, 4096, filled, st).ok());
  EXPECT_EQ(st.filled_regions, 1u);
  EXPECT_EQ(st.filled_samples, 9u);
  EXPECT_EQ(st.hole_regions, 1u);
  EXPECT_EQ(st.hole_samples, 30u);
  // A harmonic fill of planar surroundings is the plane itself (within the solver's tolerance).
  for (int row = 10; row < 13; ++row)
    for (int col = 20; col < 23; ++col) {
      EXPECT_NEAR(r.at(col, row), 10.0 + 0.5 * col + 0.25 * row, 2e-3);
      EXPECT_EQ(filled[size_t(row) * 40 + size_t(col)], 1);
    }
  EXPECT_TRUE(std::isnan(r.at(0, 5)));
}

TEST(VoidFill, PolicyAndSizeLimitDecide) {
  Raster base = plane_raster(30, 30, 0.0, 1.0, 0.0);
  for (int row = 5; row < 15; ++row)
    for (int col = 5; col < 15; ++col) base.values[size_t(row) * 30 + size_t(col)] = NAN;  // 100 samples
  std::vector<uint8_t> filled;
  VoidStats st;
  Raster a = base;
  ASSERT_TRUE(fill_voids(a, NodataPolicy::automatic, 99, filled, st).ok());  // too large to fill
  EXPECT_EQ(st.hole_samples, 100u);
  Raster b = base;
  ASSERT_TRUE(fill_voids(b, NodataPolicy::hole, 4096, filled, st).ok());
  EXPECT_EQ(st.hole_samples, 100u);
  Raster c = base;
  ASSERT_TRUE(fill_voids(c, NodataPolicy::fill, 0, filled, st).ok());
  EXPECT_EQ(st.filled_samples, 100u);
  for (float v : c.values) EXPECT_FALSE(std::isnan(v));
}

TEST(Crs, EpsgCodesResolveThroughProj) {
  SourceCrs c;
  ASSERT_TRUE(parse_crs_spec("EPSG:4326", c).ok());
  EXPECT_EQ(c.kind, CrsKind::geographic);
  EXPECT_NEAR(c.tm.inverse_flattening, 298.257223563, 1e-8);
  ASSERT_TRUE(parse_crs_spec("epsg:32733", c).ok());
  EXPECT_EQ(c.kind, CrsKind::transverse_mercator);
  EXPECT_EQ(c.tm.lon0_deg, 15.0);
  EXPECT_EQ(c.tm.scale_k0, 0.9996);
  EXPECT_EQ(c.tm.false_northing_m, 10000000.0);
  EXPECT_EQ(utm_zone_name(c.tm), "UTM zone 33S");
  ASSERT_TRUE(parse_crs_spec("EPSG:3794", c).ok());  // Slovene National Grid, TM on GRS80
  EXPECT_EQ(c.kind, CrsKind::transverse_mercator);
  EXPECT_NEAR(c.tm.lon0_deg, 15.0, 1e-12);  // PROJ's degree conversion may leave the last bit
  EXPECT_EQ(c.tm.scale_k0, 0.9999);
  EXPECT_EQ(c.tm.false_easting_m, 500000.0);
  EXPECT_EQ(c.tm.false_northing_m, -5000000.0);
  EXPECT_NEAR(c.tm.inverse_flattening, 298.257222101, 1e-8);
}

TEST(Crs, OtherProjectionsAndGarbageAreNamed) {
  SourceCrs c;
  ASSERT_TRUE(parse_crs_spec("EPSG:3857", c).ok());
  EXPECT_EQ(c.kind, CrsKind::projected);  // any projected CRS PROJ knows (issue 13); choose_frame decides
  EXPECT_EQ(c.tm.kind, ProjectionKind::proj);
  EXPECT_NE(c.tm.definition.find("Popular Visualisation Pseudo Mercator"), std::string::npos) << c.tm.definition;
  EXPECT_NE(describe_crs(c).find("Pseudo-Mercator"), std::string::npos) << describe_crs(c);
  EXPECT_NE(conversion_hint(c, "in.tif").find("gdalwarp -t_srs EPSG:326"), std::string::npos);
  EXPECT_FALSE(parse_crs_spec("EPSG:99999", c).ok());
  EXPECT_FALSE(parse_crs_spec("EPSG:123456", c).ok());
  EXPECT_FALSE(parse_crs_spec("mercator", c).ok());
  EXPECT_FALSE(parse_crs_spec("tm:k0=1", c).ok());  // lon0 missing
  ASSERT_TRUE(parse_crs_spec("tm:lon0=-153,k0=0.9996,x0=500000,ellps=GRS80", c).ok());
  EXPECT_EQ(c.tm.lon0_deg, -153.0);
  EXPECT_NEAR(c.tm.inverse_flattening, 298.257222101, 1e-9);
  ASSERT_TRUE(parse_crs_spec("local", c).ok());
  EXPECT_EQ(c.kind, CrsKind::local);
}

// Geographic source at 70-71 deg N: the interpolated frame -> sample mapping against the exact
// GeographicLib chain, in metres on the ground.
TEST(Frame, AnchorInterpolationStaysBelowATenthOfAMillimetre) {
  Raster r;
  r.width = 3601;
  r.height = 3601;
  r.values.assign(size_t(r.width) * size_t(r.height), 1.0f);
  r.geo.c[0] = 24.0;
  r.geo.c[1] = 1.0 / 3600;
  r.geo.c[3] = 71.0;
  r.geo.c[5] = -1.0 / 3600;
  r.geo.valid = true;
  r.crs = wgs84_geographic();
  FrameCrs frame;
  std::string reason;
  ASSERT_TRUE(choose_frame(r, "", frame, reason).ok());
  EXPECT_NEAR(frame.lon0_deg, 24.5, 1e-9);
  SourceMapping m;
  ASSERT_TRUE(m.init(r, frame, 2).ok());
  double x0, y0, x1, y1;
  m.frame_bounds(0, 0, r.width - 1, r.height - 1, 0.5, x0, y0, x1, y1);
  m.cover_frame_area(x0 - 3000, y0 - 3000, x1 + 3000, y1 + 3000, 2);
  double sx, sy;
  m.spacing_m(sx, sy);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1);
  double worst_m = 0, worst_back_m = 0;
  for (int k = 0; k < 20000; ++k) {
    const double x = ux(rng), y = uy(rng);
    double c1, r1, c2, r2;
    m.frame_to_sample(x, y, c1, r1);
    m.exact_frame_to_sample(x, y, c2, r2);
    worst_m = std::max(worst_m, std::hypot((c1 - c2) * sx, (r1 - r2) * sy));
    // Source samples -> frame (measuring the error against the source), over the raster.
    const double sc = std::uniform_real_distribution<double>(0, r.width - 1)(rng);
    const double sr = std::uniform_real_distribution<double>(0, r.height - 1)(rng);
    double bx, by, ex, ey;
    m.sample_to_frame(sc, sr, bx, by);
    m.exact_sample_to_frame(sc, sr, ex, ey);
    worst_back_m = std::max(worst_back_m, std::hypot(bx - ex, by - ey));
  }
  EXPECT_LT(worst_m, 1e-4);
  EXPECT_LT(worst_back_m, 1e-4);
  // The batch form gives a point the same bits whatever batch it comes in.
  const double xs[3] = {x0 + 1000.25, x0 + 5000.5, x0 + 1000.25};
  double cs[3], rs[3], c_alone, r_alone;
  m.map_frame_row(y0 + 777.0, xs, 3, cs, rs);
  m.map_frame_row(y0 + 777.0, &xs[2], 1, &c_alone, &r_alone);
  EXPECT_EQ(cs[0], c_alone);
  EXPECT_EQ(rs[0], r_alone);
  EXPECT_EQ(cs[2], c_alone);
}
