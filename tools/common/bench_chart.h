// bench_chart: the benchmarks' SVG charts. A chart is a grid of panels; each panel plots series of
// points (optionally joined by a line) and named points (a peer library measured once: a labelled
// square) against a linear or log10 x and y axis, with optional reference lines (a target). One
// legend per chart: a series name has the same colour in every panel, so a DEM or a view reads
// across panels. Plain SVG 1.1 text that any browser opens; no dependencies beyond fmt and std.
//
// Non-finite values (and values <= 0 on a log axis) are left out of the plot and counted in the
// panel's corner note, never written as numbers: the SVG holds no "nan" or "inf".
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace terrain::chart {

enum class Scale { linear, log10 };

struct Axis {
  std::string label;
  Scale scale = Scale::linear;
  bool include_zero = false;  // linear only: the range reaches 0 (sizes, times from zero)
  // Fixed ends; NaN: from the data (rounded out to "nice" values).
  double min = std::numeric_limits<double>::quiet_NaN(), max = std::numeric_limits<double>::quiet_NaN();
};

struct Point {
  double x = 0, y = 0;
  std::string label;  // drawn next to the point when the series has label_points; always in the tooltip
};

struct Series {
  std::string name;  // legend entry; the colour is chosen by name (same name, same colour)
  std::vector<Point> points;
  bool line = true;          // join the points in the given order
  bool hollow = false;       // rings instead of dots (a second mode over the first stays visible)
  bool dashed = false;       // the line
  bool label_points = false;
  double radius = 4;
};

// A single measurement drawn as a labelled square (peer libraries, a baseline).
struct NamedPoint {
  std::string name;
  double x = 0, y = 0;
};

// A dashed reference line across the panel at y = value (horizontal) or x = value.
struct RefLine {
  std::string label;
  double value = 0;
  bool horizontal = true;
};

struct Panel {
  std::string title;  // above the plot, bold
  Axis x, y;
  std::vector<Series> series;
  std::vector<NamedPoint> named;
  std::vector<RefLine> lines;
};

struct Chart {
  std::string title;
  std::string note;  // under the title, wrapped: what was run, on what machine
  std::vector<Panel> panels;
  int columns = 2;
  double panel_width = 340, panel_height = 230;
};

// The resolved range of an axis and its tick values (what the plot and the tests use).
struct AxisRange {
  double lo = 0, hi = 1;
  bool log = false;
  std::vector<double> ticks;
};
// The axis' range over the finite `values` (and > 0 ones for a log axis) and the axis' fixed ends.
AxisRange axis_range(const Axis& axis, const std::vector<double>& values);
// Pixel of `v` on the axis mapped onto [p0, p1] (p0 at lo). NaN for a value the axis cannot show.
double axis_pixel(const AxisRange& r, double v, double p0, double p1);

// Where panel `index` draws its plot area (SVG user units).
struct Box {
  double x = 0, y = 0, w = 0, h = 0;
};
Box panel_box(const Chart& chart, size_t index);
// The x and y ranges panel `index` is drawn with (its series, named points and lines).
AxisRange panel_x_range(const Panel& panel);
AxisRange panel_y_range(const Panel& panel);

std::string render_svg(const Chart& chart);
// Writes render_svg(chart) to `path`; "" on success, else why not.
std::string write_svg(const Chart& chart, const std::string& path);

std::string xml_escape(const std::string& s);

// "host H, N cores, load average a / b / c when the chart was written": the chart says how busy
// the machine was, since its timings depend on it.
std::string machine_note();

}  // namespace terrain::chart
