// bench_chart (tools/common/bench_chart.h): the benchmarks' SVG charts. Points land where a linear
// and a log10 axis put them, the automatic axis ends are round, the file parses as XML, and
// NaN / inf / empty series neither crash nor write "nan" or "inf".
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "bench_chart.h"
#include "test_data.h"

namespace ch = terrain::chart;
namespace {

struct Mark {
  double x = 0, y = 0;
};

// Centres of the data markers (<circle class="pt">) and of the named points (<rect class="named">,
// 9 x 9 squares) in document order.
std::vector<Mark> circles(const std::string& svg) {
  std::vector<Mark> out;
  const std::regex re("<circle class=\"pt\" cx=\"([-0-9.]+)\" cy=\"([-0-9.]+)\"");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back({std::stod((*it)[1]), std::stod((*it)[2])});
  return out;
}
std::vector<Mark> squares(const std::string& svg) {
  std::vector<Mark> out;
  const std::regex re("<rect class=\"named\" x=\"([-0-9.]+)\" y=\"([-0-9.]+)\"");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back({std::stod((*it)[1]) + 4.5, std::stod((*it)[2]) + 4.5});
  return out;
}

// Python's XML parser over the file; the root must be an SVG element.
bool parses_as_svg(const std::string& path) {
  const std::string cmd = "/usr/bin/python3 -c \"import sys, xml.etree.ElementTree as E; "
                          "sys.exit(0 if E.parse(sys.argv[1]).getroot().tag == '{http://www.w3.org/2000/svg}svg' "
                          "else 3)\" '" + path + "' 2>&1";
  return std::system(cmd.c_str()) == 0;
}

std::string scratch(const std::string& name) {
  const std::filesystem::path dir = terrain::test::scratch_root() / "bench_chart";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

std::string read(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// A number spelt "nan" or "inf" anywhere (attribute or text).
bool has_non_finite(const std::string& svg) {
  return std::regex_search(svg, std::regex("(^|[^a-zA-Z])-?(nan|inf)([^a-zA-Z]|$)", std::regex::icase));
}

}  // namespace

TEST(BenchChart, PointsLandOnLinearAndLogAxes) {
  ch::Chart c;
  c.title = "known points";
  ch::Panel p;
  p.x = {"x", ch::Scale::linear, false, 0, 10};
  p.y = {"y", ch::Scale::log10, false, 1, 1000};
  ch::Series s{"series", {{0, 1, ""}, {2.5, 100, ""}, {5, 10, ""}, {10, 1000, ""}}};
  p.series.push_back(s);
  p.named.push_back({"peer", 7.5, std::sqrt(1000.0)});
  c.panels.push_back(p);
  ch::Panel q = p;  // the second panel swaps the scales: log x over 0.1..100, linear y over -5..5
  q.x = {"x", ch::Scale::log10, false, 0.1, 100};
  q.y = {"y", ch::Scale::linear, false, -5, 5};
  q.series = {ch::Series{"series", {{0.1, -5, ""}, {1, 0, ""}, {100, 5, ""}}}};
  q.named = {{"peer", 10, 2.5}};
  c.panels.push_back(q);
  const std::string svg = ch::render_svg(c);
  const std::vector<Mark> pts = circles(svg), named = squares(svg);
  ASSERT_EQ(pts.size(), 7u);
  ASSERT_EQ(named.size(), 2u);

  const ch::Box a = ch::panel_box(c, 0), b = ch::panel_box(c, 1);
  EXPECT_GT(b.x, a.x + a.w);  // side by side
  EXPECT_DOUBLE_EQ(b.y, a.y);
  // Panel 0: x linear 0..10 over the box width, y log 1..1000 (3 decades) from the bottom up.
  const double expect0[][2] = {{0, 0}, {0.25, 2.0 / 3}, {0.5, 1.0 / 3}, {1, 1}};
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(pts[size_t(i)].x, a.x + expect0[i][0] * a.w, 0.051) << i;
    EXPECT_NEAR(pts[size_t(i)].y, a.y + a.h - expect0[i][1] * a.h, 0.051) << i;
  }
  EXPECT_NEAR(named[0].x, a.x + 0.75 * a.w, 0.051);
  EXPECT_NEAR(named[0].y, a.y + a.h * 0.5, 0.051);  // sqrt(1000): half of the three decades
  // Panel 1: x log 0.1..100 (3 decades), y linear -5..5.
  const double expect1[][2] = {{0, 0}, {1.0 / 3, 0.5}, {1, 1}};
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(pts[size_t(4 + i)].x, b.x + expect1[i][0] * b.w, 0.051) << i;
    EXPECT_NEAR(pts[size_t(4 + i)].y, b.y + b.h - expect1[i][1] * b.h, 0.051) << i;
  }
  EXPECT_NEAR(named[1].x, b.x + 2.0 / 3 * b.w, 0.051);
  EXPECT_NEAR(named[1].y, b.y + 0.25 * b.h, 0.051);

  const std::string path = scratch("known_points.svg");
  ASSERT_EQ(ch::write_svg(c, path), "");
  EXPECT_EQ(read(path), svg);
  EXPECT_TRUE(parses_as_svg(path));
}

TEST(BenchChart, AutomaticAxesAreRound) {
  // Linear from the data (3..47): 0..50 in steps of 10; with include_zero from 20..47: still 0..50.
  ch::AxisRange r = ch::axis_range({"", ch::Scale::linear}, {3, 47, 20});
  EXPECT_DOUBLE_EQ(r.lo, 0);
  EXPECT_DOUBLE_EQ(r.hi, 50);
  EXPECT_EQ(r.ticks, (std::vector<double>{0, 10, 20, 30, 40, 50}));
  r = ch::axis_range({"", ch::Scale::linear, true}, {20, 47});
  EXPECT_DOUBLE_EQ(r.lo, 0);
  EXPECT_DOUBLE_EQ(r.hi, 50);
  r = ch::axis_range({"", ch::Scale::linear}, {31.2, 44.9});  // PSNR-like: not from zero
  EXPECT_DOUBLE_EQ(r.lo, 30);
  EXPECT_DOUBLE_EQ(r.hi, 45);
  // Log: the 1-2-5 values around the data; non-positive and non-finite values ignored.
  r = ch::axis_range({"", ch::Scale::log10}, {0.3, 70, 0, -4, NAN, INFINITY});
  EXPECT_TRUE(r.log);
  EXPECT_DOUBLE_EQ(r.lo, 0.2);
  EXPECT_DOUBLE_EQ(r.hi, 100);
  r = ch::axis_range({"", ch::Scale::log10}, {1.3, 4.1});
  EXPECT_DOUBLE_EQ(r.lo, 1);
  EXPECT_DOUBLE_EQ(r.hi, 5);
  EXPECT_EQ(r.ticks, (std::vector<double>{1, 2, 3, 4, 5}));  // under a decade: 1..9 steps
  // One value: widened, never an empty range.
  r = ch::axis_range({"", ch::Scale::log10}, {2});
  EXPECT_LT(r.lo, 2);
  EXPECT_GT(r.hi, 2);
  r = ch::axis_range({"", ch::Scale::linear}, {7});
  EXPECT_LT(r.lo, 7);
  EXPECT_GT(r.hi, 7);
  EXPECT_TRUE(std::isnan(ch::axis_pixel(r, NAN, 0, 100)));
}

TEST(BenchChart, NonFiniteAndEmptySeriesWriteNoNan) {
  ch::Chart c;
  c.title = "odd data <&> \"quoted\"";
  c.note = std::string(400, 'x') + " a long note that wraps";
  ch::Panel p;
  p.x = {"x", ch::Scale::log10};
  p.y = {"y", ch::Scale::linear};
  p.series.push_back({"with holes & <tags>", {{1, 1, "a"}, {NAN, 2, "b"}, {INFINITY, 3, ""}, {0, 4, ""}, {-1, 5, ""},
                                              {10, -INFINITY, ""}, {100, 7, "g"}}});
  p.series.back().label_points = true;
  p.series.push_back({"empty", {}});
  p.named.push_back({"peer without x", NAN, 1});
  p.lines.push_back({"line without value", NAN, true});
  ch::Panel only_nan;
  only_nan.series.push_back({"all unplaceable", {{NAN, NAN, ""}, {INFINITY, -INFINITY, ""}}});
  ch::Panel nothing;
  c.panels = {p, only_nan, nothing};
  const std::string svg = ch::render_svg(c);
  EXPECT_FALSE(has_non_finite(svg)) << svg;
  EXPECT_EQ(circles(svg).size(), 2u);  // (1, 1) and (100, 7)
  EXPECT_NE(svg.find("6 points not shown"), std::string::npos);
  EXPECT_NE(svg.find("no data"), std::string::npos);
  // No two placeable points are neighbours in the series, so no line may bridge the gaps.
  EXPECT_EQ(svg.find("<polyline"), std::string::npos);

  const std::string path = scratch("non_finite.svg");
  ASSERT_EQ(ch::write_svg(c, path), "");
  EXPECT_TRUE(parses_as_svg(path));
  // A chart without panels is still a valid SVG.
  const std::string empty_path = scratch("empty.svg");
  ASSERT_EQ(ch::write_svg(ch::Chart{}, empty_path), "");
  EXPECT_TRUE(parses_as_svg(empty_path));
  EXPECT_FALSE(has_non_finite(read(empty_path)));
  // An unwritable path is an error value, not a crash.
  EXPECT_NE(ch::write_svg(c, "/nonexistent-dir/chart.svg"), "");
}
