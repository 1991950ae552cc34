#include "bench_chart.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <thread>

#include <stdlib.h>
#include <unistd.h>

namespace terrain::chart {
namespace {

// Layout (SVG user units). The left margin holds the y tick labels and the rotated y label; the gaps
// between panels hold the next panel's y labels and the x label plus the next row's titles.
constexpr double kLeft = 80, kRight = 28, kGapX = 100, kGapY = 92, kTitleY = 24, kNoteLine = 14, kLegendRow = 18;
constexpr double kCharW = 6.6;  // mean advance of a 12 px sans-serif character, for wrapping and the legend
const char* const kPalette[] = {"#1f5fbf", "#d0402a", "#2a9d4a", "#8e44ad", "#e08a00",
                                "#17a2b8", "#795548", "#c2185b", "#556b2f", "#607d8b"};

bool finite(double v) { return std::isfinite(v); }

// The 1-2-5 sequence: the largest member <= v (down) or the smallest >= v (up), v > 0.
double nice125(double v, bool up) {
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  const double ms[] = {1, 2, 5, 10};
  if (up) {
    for (double m : ms)
      if (m * p >= v * (1 - 1e-12)) return m * p;
    return 10 * p;
  }
  for (int i = 3; i >= 0; --i)
    if (ms[i] * p <= v * (1 + 1e-12)) return ms[i] * p;
  return p;
}

// A round step near range / 5 (1, 2, 2.5 or 5 times a power of ten).
double nice_step(double range) {
  const double raw = range / 5, p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 2.5, 5.0})
    if (m * p >= raw) return m * p;
  return 10 * p;
}

std::string tick_text(double v) {
  if (v == 0) return "0";
  const double a = std::abs(v);
  if (a >= 1e6 || a < 1e-3) return fmt::format("{:.3g}", v);
  if (std::abs(v - std::round(v)) < 1e-9 * std::max(1.0, a)) return fmt::format("{:.0f}", v);
  return fmt::format("{:.4g}", v);
}

std::string value_text(double v) { return finite(v) ? fmt::format("{:.4g}", v) : "n/a"; }

// Splits `text` into lines of at most `chars` characters at spaces.
std::vector<std::string> wrap(const std::string& text, size_t chars) {
  std::vector<std::string> lines;
  std::string line, word;
  auto flush_word = [&] {
    if (word.empty()) return;
    if (!line.empty() && line.size() + 1 + word.size() > chars) {
      lines.push_back(line);
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
    word.clear();
  };
  for (char c : text) {
    if (c == ' ' || c == '\n') {
      flush_word();
      if (c == '\n' && !line.empty()) {
        lines.push_back(line);
        line.clear();
      }
    } else {
      word += c;
    }
  }
  flush_word();
  if (!line.empty()) lines.push_back(line);
  return lines;
}

struct LegendEntry {
  std::string name;
  bool hollow = false, line = false, dashed = false;
  double radius = 4;
};

struct Layout {
  double width = 0, height = 0, panels_top = 0;
  std::vector<std::string> note_lines;
  std::vector<LegendEntry> legend;
  std::vector<std::pair<double, double>> legend_at;  // x, y of each entry
  std::map<std::string, std::string> colour;         // series name -> colour
};

Layout layout(const Chart& c) {
  Layout l;
  const int cols = std::max(1, std::min<int>(c.columns, std::max<int>(1, int(c.panels.size()))));
  const int rows = std::max<int>(1, (int(c.panels.size()) + cols - 1) / cols);
  l.width = kLeft + cols * c.panel_width + (cols - 1) * kGapX + kRight;
  l.note_lines = wrap(c.note, size_t(std::max(20.0, (l.width - kLeft) / (0.92 * kCharW))));
  for (const Panel& p : c.panels)
    for (const Series& s : p.series) {
      if (l.colour.count(s.name)) continue;
      l.colour[s.name] = kPalette[l.legend.size() % std::size(kPalette)];
      l.legend.push_back({s.name, s.hollow, s.line, s.dashed, s.radius});
    }
  double y = kTitleY + 8 + kNoteLine * double(l.note_lines.size()) + 12, x = kLeft;
  for (const LegendEntry& e : l.legend) {
    const double w = 34 + kCharW * double(e.name.size()) + 18;
    if (x > kLeft && x + w > l.width - kRight) {
      x = kLeft;
      y += kLegendRow;
    }
    l.legend_at.push_back({x, y});
    x += w;
  }
  l.panels_top = y + (l.legend.empty() ? 0 : kLegendRow) + 30;
  l.height = l.panels_top + rows * c.panel_height + (rows - 1) * kGapY + 50;
  return l;
}

std::string marker(double x, double y, double r, bool hollow, const std::string& colour, const std::string& cls) {
  return hollow ? fmt::format("<circle class=\"{}\" cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"{:g}\" fill=\"none\" stroke=\"{}\" "
                              "stroke-width=\"2\"",
                              cls, x, y, r + 2, colour)
                : fmt::format("<circle class=\"{}\" cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"{:g}\" fill=\"{}\"", cls, x, y, r,
                              colour);
}

std::vector<double> xs_of(const Panel& p) {
  std::vector<double> v;
  for (const Series& s : p.series)
    for (const Point& q : s.points)
      if (finite(q.y)) v.push_back(q.x);  // a point the y axis cannot place does not stretch x
  for (const NamedPoint& n : p.named)
    if (finite(n.y)) v.push_back(n.x);
  for (const RefLine& r : p.lines)
    if (!r.horizontal) v.push_back(r.value);
  return v;
}

std::vector<double> ys_of(const Panel& p) {
  std::vector<double> v;
  for (const Series& s : p.series)
    for (const Point& q : s.points)
      if (finite(q.x)) v.push_back(q.y);
  for (const NamedPoint& n : p.named)
    if (finite(n.x)) v.push_back(n.y);
  for (const RefLine& r : p.lines)
    if (r.horizontal) v.push_back(r.value);
  return v;
}

std::string render_panel(const Chart& c, size_t index, const Layout& l) {
  const Panel& p = c.panels[index];
  const Box b = panel_box(c, index);
  const AxisRange xr = panel_x_range(p), yr = panel_y_range(p);
  const auto px = [&](double v) { return axis_pixel(xr, v, b.x, b.x + b.w); };
  const auto py = [&](double v) { return axis_pixel(yr, v, b.y + b.h, b.y); };
  std::string s = fmt::format("<g class=\"panel\">\n<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" "
                              "fill=\"none\" stroke=\"#888\"/>\n",
                              b.x, b.y, b.w, b.h);
  for (double t : xr.ticks) {
    const double x = px(t);
    if (!finite(x)) continue;
    s += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" stroke=\"#eee\"/>"
                     "<text x=\"{0:.1f}\" y=\"{3:.1f}\" text-anchor=\"middle\">{4}</text>\n",
                     x, b.y, b.y + b.h, b.y + b.h + 16, tick_text(t));
  }
  for (double t : yr.ticks) {
    const double y = py(t);
    if (!finite(y)) continue;
    s += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{2:.1f}\" y2=\"{1:.1f}\" stroke=\"#eee\"/>"
                     "<text x=\"{3:.1f}\" y=\"{4:.1f}\" text-anchor=\"end\">{5}</text>\n",
                     b.x, y, b.x + b.w, b.x - 6, y + 4, tick_text(t));
  }
  s += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">{}{}</text>\n", b.x + b.w / 2,
                   b.y + b.h + 34, xml_escape(p.x.label), xr.log ? " (log)" : "");
  s += fmt::format("<text transform=\"translate({:.1f},{:.1f}) rotate(-90)\" text-anchor=\"middle\">{}{}</text>\n",
                   b.x - 58, b.y + b.h / 2, xml_escape(p.y.label), yr.log ? " (log)" : "");
  s += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" font-weight=\"bold\">{}</text>\n",
                   b.x + b.w / 2, b.y - 8, xml_escape(p.title));
  // Data, clipped to the plot (plus a marker's width) so points outside fixed axis ends stay out.
  s += fmt::format("<clipPath id=\"clip{0}\"><rect x=\"{1:.1f}\" y=\"{2:.1f}\" width=\"{3:.1f}\" height=\"{4:.1f}\"/>"
                   "</clipPath>\n<g clip-path=\"url(#clip{0})\">\n",
                   index, b.x - 8, b.y - 8, b.w + 16, b.h + 16);
  for (const RefLine& r : p.lines) {
    const double v = r.horizontal ? py(r.value) : px(r.value);
    if (!finite(v)) continue;
    if (r.horizontal)
      s += fmt::format("<line class=\"ref\" x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{2:.1f}\" y2=\"{1:.1f}\" stroke=\"#555\" "
                       "stroke-dasharray=\"5,4\"/><text x=\"{3:.1f}\" y=\"{4:.1f}\" fill=\"#555\">{5}</text>\n",
                       b.x, v, b.x + b.w, b.x + 4, v - 4, xml_escape(r.label));
    else
      s += fmt::format("<line class=\"ref\" x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" stroke=\"#555\" "
                       "stroke-dasharray=\"5,4\"/><text x=\"{3:.1f}\" y=\"{4:.1f}\" fill=\"#555\">{5}</text>\n",
                       v, b.y, b.y + b.h, v + 4, b.y + 14, xml_escape(r.label));
  }
  size_t hidden = 0, shown = 0;
  for (const Series& ser : p.series) {
    const std::string& colour = l.colour.at(ser.name);
    // The line, broken where a point cannot be placed.
    std::vector<std::string> runs(1);
    std::string marks;
    for (const Point& q : ser.points) {
      const double x = px(q.x), y = py(q.y);
      if (!finite(x) || !finite(y)) {
        ++hidden;
        if (!runs.back().empty()) runs.emplace_back();
        continue;
      }
      ++shown;
      runs.back() += fmt::format("{:.1f},{:.1f} ", x, y);
      marks += marker(x, y, ser.radius, ser.hollow, colour, "pt") +
               fmt::format("><title>{}{}{}: x {}, y {}</title></circle>\n", xml_escape(ser.name),
                           q.label.empty() ? "" : " ", xml_escape(q.label), value_text(q.x), value_text(q.y));
      if (ser.label_points && !q.label.empty())
        marks += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"10\" fill=\"{}\">{}</text>\n", x + 6,
                             y - 6 < b.y + 10 ? y + 14 : y - 6, colour, xml_escape(q.label));  // below at the top
    }
    if (ser.line)
      for (const std::string& run : runs)
        if (std::count(run.begin(), run.end(), ' ') > 1)
          s += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"{}/>\n", run, colour,
                           ser.dashed ? " stroke-dasharray=\"6,4\"" : "");
    s += marks;
  }
  // Named points: dark squares with the name beside: right of the point, else left, else a line
  // lower or higher, whichever first overlaps no label placed before (estimated text boxes).
  struct Rect {
    double x0, y0, x1, y1;
  };
  std::vector<Rect> placed;
  for (const NamedPoint& n : p.named) {
    const double x = px(n.x), y = py(n.y);
    if (!finite(x) || !finite(y)) {
      ++hidden;
      continue;
    }
    ++shown;
    const double tw = 0.92 * kCharW * double(n.name.size());
    const auto box_at = [&](bool left, double dy) {
      const double x0 = left ? x - 8 - tw : x + 8;
      return Rect{x0, y + dy - 6, x0 + tw, y + dy + 6};
    };
    const auto free = [&](const Rect& r) {
      for (const Rect& q : placed)
        if (r.x0 < q.x1 && q.x0 < r.x1 && r.y0 < q.y1 && q.y0 < r.y1) return false;
      return true;
    };
    const bool prefer_left = x > b.x + 0.7 * b.w;
    bool left = prefer_left;
    double dy = 0;
    for (const auto& [side, d] : {std::pair{prefer_left, 0.0}, std::pair{!prefer_left, 0.0}, std::pair{prefer_left, 12.0},
                               std::pair{prefer_left, -12.0}, std::pair{!prefer_left, 12.0}, std::pair{!prefer_left, -12.0}})
      if (free(box_at(side, d))) {
        left = side;
        dy = d;
        break;
      }
    const Rect r = box_at(left, dy);
    placed.push_back(r);
    s += fmt::format("<rect class=\"named\" x=\"{:.1f}\" y=\"{:.1f}\" width=\"9\" height=\"9\" fill=\"#222\">"
                     "<title>{}: x {}, y {}</title></rect>\n<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"11\" "
                     "fill=\"#222\"{}>{}</text>\n",
                     x - 4.5, y - 4.5, xml_escape(n.name), value_text(n.x), value_text(n.y), left ? x - 8 : x + 8,
                     y + dy + 4, left ? " text-anchor=\"end\"" : "", xml_escape(n.name));
  }
  s += "</g>\n";
  if (shown == 0)
    s += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" fill=\"#888\">no data</text>\n",
                     b.x + b.w / 2, b.y + b.h / 2);
  if (hidden > 0)
    s += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"end\" font-size=\"10\" fill=\"#888\">{} point{} "
                     "not shown (not finite{})</text>\n",
                     b.x + b.w - 4, b.y + b.h - 6, hidden, hidden == 1 ? "" : "s",
                     xr.log || yr.log ? " or &lt;= 0 on a log axis" : "");
  return s + "</g>\n";
}

}  // namespace

AxisRange axis_range(const Axis& axis, const std::vector<double>& values) {
  AxisRange r;
  r.log = axis.scale == Scale::log10;
  double lo = INFINITY, hi = -INFINITY;
  for (double v : values)
    if (finite(v) && (!r.log || v > 0)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  if (r.log) {
    if (finite(axis.min) && axis.min > 0) lo = axis.min;
    if (finite(axis.max) && axis.max > 0) hi = axis.max;
    if (!(lo <= hi)) {  // no data
      lo = 1;
      hi = 10;
    }
    r.lo = finite(axis.min) && axis.min > 0 ? axis.min : nice125(lo, false);
    r.hi = finite(axis.max) && axis.max > 0 ? axis.max : nice125(hi, true);
    if (r.hi <= r.lo) {  // one value on a 1-2-5 step: widen to the neighbours
      r.lo = nice125(r.lo * 0.99, false);
      r.hi = nice125(r.hi * 1.01, true);
    }
    std::vector<double> t125, decades;
    for (int e = int(std::floor(std::log10(r.lo))); e <= int(std::ceil(std::log10(r.hi))); ++e)
      for (double m : {1.0, 2.0, 5.0}) {
        const double v = m * std::pow(10.0, e);
        if (v < r.lo * (1 - 1e-9) || v > r.hi * (1 + 1e-9)) continue;
        t125.push_back(v);
        if (m == 1) decades.push_back(v);
      }
    if (t125.size() < 4) {  // less than a decade: every 1..9 times a power of ten
      for (int e = int(std::floor(std::log10(r.lo))); e <= int(std::ceil(std::log10(r.hi))); ++e)
        for (int m = 1; m <= 9; ++m) {
          const double v = m * std::pow(10.0, e);
          if (v >= r.lo * (1 - 1e-9) && v <= r.hi * (1 + 1e-9)) r.ticks.push_back(v);
        }
    } else if (t125.size() <= 8) {
      r.ticks = t125;
    } else {  // many decades: every k-th decade, at most 8 labels
      const size_t k = (decades.size() + 7) / 8;
      for (size_t i = 0; i < decades.size(); i += k) r.ticks.push_back(decades[i]);
    }
    return r;
  }
  if (axis.include_zero && lo <= hi) {
    lo = std::min(lo, 0.0);
    hi = std::max(hi, 0.0);
  }
  if (finite(axis.min)) lo = axis.min;
  if (finite(axis.max)) hi = axis.max;
  if (!(lo <= hi)) {  // no data
    lo = 0;
    hi = 1;
  }
  if (lo == hi) {
    const double pad = lo == 0 ? 1 : 0.1 * std::abs(lo);
    lo -= pad;
    hi += pad;
  }
  const double step = nice_step(hi - lo);
  r.lo = finite(axis.min) ? axis.min : std::floor(lo / step + 1e-9) * step;
  r.hi = finite(axis.max) ? axis.max : std::ceil(hi / step - 1e-9) * step;
  for (double k = std::ceil(r.lo / step - 1e-9); k * step <= r.hi * (1 + 1e-12) + 1e-12 * step; k += 1)
    r.ticks.push_back(std::abs(k) < 0.5 ? 0.0 : k * step);
  return r;
}

double axis_pixel(const AxisRange& r, double v, double p0, double p1) {
  if (!finite(v) || (r.log && v <= 0)) return NAN;
  const double a = r.log ? std::log10(r.lo) : r.lo, b = r.log ? std::log10(r.hi) : r.hi;
  const double t = ((r.log ? std::log10(v) : v) - a) / (b - a);
  const double p = p0 + t * (p1 - p0);
  return finite(p) ? p : NAN;
}

Box panel_box(const Chart& chart, size_t index) {
  const Layout l = layout(chart);
  const int cols = std::max(1, std::min<int>(chart.columns, std::max<int>(1, int(chart.panels.size()))));
  const int row = int(index) / cols, col = int(index) % cols;
  return {kLeft + col * (chart.panel_width + kGapX), l.panels_top + row * (chart.panel_height + kGapY),
          chart.panel_width, chart.panel_height};
}

AxisRange panel_x_range(const Panel& panel) { return axis_range(panel.x, xs_of(panel)); }
AxisRange panel_y_range(const Panel& panel) { return axis_range(panel.y, ys_of(panel)); }

std::string render_svg(const Chart& chart) {
  const Layout l = layout(chart);
  std::string s = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0:.0f}\" height=\"{1:.0f}\" viewBox=\"0 0 {0:.0f} {1:.0f}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      "<text x=\"{2:.0f}\" y=\"{3:.0f}\" font-size=\"15\">{4}</text>\n",
      l.width, l.height, kLeft, kTitleY, xml_escape(chart.title));
  for (size_t i = 0; i < l.note_lines.size(); ++i)
    s += fmt::format("<text x=\"{:.0f}\" y=\"{:.0f}\" font-size=\"11\" fill=\"#555\">{}</text>\n", kLeft,
                     kTitleY + 4 + kNoteLine * double(i + 1), xml_escape(l.note_lines[i]));
  for (size_t i = 0; i < l.legend.size(); ++i) {
    const LegendEntry& e = l.legend[i];
    const auto [x, y] = l.legend_at[i];
    const std::string& colour = l.colour.at(e.name);
    if (e.line)
      s += fmt::format("<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" stroke-width=\"1.5\"{}/>",
                       x, y, x + 28, y, colour, e.dashed ? " stroke-dasharray=\"6,4\"" : "");
    s += marker(x + 14, y, e.radius, e.hollow, colour, "legend") +
         fmt::format("/><text x=\"{:.1f}\" y=\"{:.1f}\">{}</text>\n", x + 34, y + 4, xml_escape(e.name));
  }
  for (size_t i = 0; i < chart.panels.size(); ++i) s += render_panel(chart, i, l);
  return s + "</svg>\n";
}

std::string write_svg(const Chart& chart, const std::string& path) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) return fmt::format("cannot open {} for writing", path);
  const std::string svg = render_svg(chart);
  f.write(svg.data(), std::streamsize(svg.size()));
  if (!f.flush()) return fmt::format("cannot write {}", path);
  return "";
}

std::string xml_escape(const std::string& s) {
  std::string o;
  for (char ch : s) {
    switch (ch) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += ch;
    }
  }
  return o;
}

std::string machine_note() {
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  double load[3] = {NAN, NAN, NAN};
  const bool have_load = getloadavg(load, 3) == 3;
  return fmt::format("Host {}, {} cores{}.", host, std::max(1u, std::thread::hardware_concurrency()),
                     have_load ? fmt::format(", load average {:.1f} / {:.1f} / {:.1f} (1 / 5 / 15 min) when the chart was "
                                             "written",
                                             load[0], load[1], load[2])
                               : "");
}

}  // namespace terrain::chart
