// terrain-cook: a thin shell over terrain::cook::cook(). Exit codes: 0 ok, 1 failure, 2 usage error.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <charconv>
#include <cstdio>
#include <fstream>

#include "terrain/cook.h"
#include "terrain/progress.h"

namespace {

// "A,B" or a single "A" (then both) into two numbers.
bool parse_pair(const std::string& text, std::array<double, 2>& out, bool allow_single) {
  const size_t comma = text.find(',');
  auto num = [](std::string_view s, double& v) {
    auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && p == s.data() + s.size();
  };
  if (comma == std::string::npos) {
    if (!allow_single || !num(text, out[0])) return false;
    out[1] = out[0];
    return true;
  }
  return num(std::string_view(text).substr(0, comma), out[0]) && num(std::string_view(text).substr(comma + 1), out[1]);
}

}  // namespace

int main(int argc, char** argv) {
  using terrain::cook::CookOptions;
  CookOptions o;
  std::string origin, spacing, raw_size, valid_range, memory_limit, nodata = "auto", quality = "balanced", report_path;
  std::optional<double> nodata_value;
  bool quiet = false, json = false;

  CLI::App app{"terrain-cook: real DEMs (GeoTIFF, SRTM HGT, PNG16/EXR/raw heightmaps, .npz) to a sparse, crack-free "
               "terrain archive"};
  app.add_option("inputs", o.inputs, "Input DEM(s); several are mosaicked (same CRS and pixel grid, first listed wins)")
      ->required();
  app.add_option("-o,--output", o.output, "Archive to write (atomically)")->required();
  app.add_option("--tolerance", o.tolerance_m, "Refine nodes while their geometric error exceeds this (metres)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--finest-level", o.finest_level,
                 "Finest level to cook, 0 (0.5 m) .. 5 (16 m); default: the finest level with spacing >= 1/32 of the source spacing (refinement stops earlier where the tolerance is met)")
      ->check(CLI::Range(0, 5));
  app.add_option("--threads", o.threads, "Worker threads (default: all cores)")->check(CLI::NonNegativeNumber);
  app.add_option("--crs", o.crs,
                 "CRS of inputs that lack one (or override): EPSG:4326, EPSG:326xx, any Transverse Mercator EPSG code, "
                 "tm:lon0=..,lat0=..,k0=..,x0=..,y0=..,ellps=WGS84|GRS80, or local");
  app.add_option("--frame", o.frame, "Archive frame instead of the automatic choice (same forms; TM or local)");
  app.add_option("--origin", origin, "Images/raw: frame coordinates X,Y of the south-west sample (default 0,0)");
  app.add_option("--spacing", spacing, "Images/raw: sample spacing D or DX,DY in CRS units");
  app.add_option("--height-scale", o.height_scale, "metres = value * scale + offset")->capture_default_str();
  app.add_option("--height-offset", o.height_offset, "metres = value * scale + offset")->capture_default_str();
  app.add_option("--nodata", nodata, "auto: fill small enclosed voids, holes elsewhere; hole; fill")
      ->check(CLI::IsMember({"auto", "hole", "fill"}))
      ->capture_default_str();
  app.add_option("--nodata-value", nodata_value, "Nodata value (overrides the file's)");
  app.add_option("--valid-range", valid_range,
                 "Plausible heights MIN,MAX in metres after scale/offset; others become nodata with a warning "
                 "(default -12000,9000)");
  app.add_option("--memory-limit", memory_limit,
                 "Memory budget, e.g. 256M, 2G: inputs whose cook would need more are refused before reading "
                 "(today the cook holds the source at ~16 B per sample); default: half the RAM, cgroup limit or "
                 "ulimit -v, whichever is least (" +
                     fmt::format("{:.1f}G here)", double(terrain::cook::default_memory_limit_bytes()) / (1 << 30)));
  app.add_option("--fill-max", o.fill_max_samples, "auto: largest enclosed void to fill, in samples")
      ->capture_default_str();
  app.add_option("--raw-size", raw_size, "Raw heightmaps: WIDTHxHEIGHT");
  app.add_option("--raw-type", o.raw_type, "Raw heightmaps: u16 (default for .r16/.raw), i16, f32 (.r32/.f32)")
      ->check(CLI::IsMember({"u16", "i16", "f32"}));
  app.add_flag("--raw-big-endian", o.raw_big_endian, "Raw heightmaps are big-endian");
  app.add_option("--materials", o.materials_path, "Material rules JSON for the splat map (default: built-in)");
  app.add_option("--albedo", o.albedo_path,
                 "Orthophoto for the albedo: GeoTIFF RGB(A) in any supported CRS, resampled to the frame "
                 "(default: baked from the splat materials)");
  app.add_option("--holes", o.holes_path,
                 "Hole mask: GeoTIFF in any supported CRS; nonzero = hole (those vertices drop their triangles)");
  app.add_option("--landcover", o.landcover_path,
                 "Class raster (e.g. land cover GeoTIFF, integer classes, any supported CRS) for the splat map; "
                 "needs --landcover-table");
  app.add_option("--landcover-table", o.landcover_table_path,
                 "JSON class -> material table: {\"classes\": {\"10\": \"forest_floor\", \"80\": \"water\"}} "
                 "(palette names or indices; classes not listed keep the rules' choice)");
  app.add_option("--bc-quality", quality, "Block compression quality of normals and albedo")
      ->check(CLI::IsMember({"fast", "balanced", "best"}))
      ->capture_default_str();
  app.add_flag("--heights-only", o.heights_only, "Skip normals, albedo, splat and cones (they stay zero)");
  app.add_option("--report", report_path, "Write the cook report (JSON) to this file");
  app.add_flag("--json", json, "Print the report as JSON on stdout instead of the summary");
  app.add_flag("-q,--quiet", quiet, "No progress bar and no summary");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }

  auto usage = [&](const std::string& msg) {
    std::fprintf(stderr, "terrain-cook: %s\n", msg.c_str());
    return 2;
  };
  if (!origin.empty()) {
    std::array<double, 2> v{};
    if (!parse_pair(origin, v, false)) return usage("--origin expects X,Y");
    o.origin = v;
  }
  if (!spacing.empty()) {
    std::array<double, 2> v{};
    if (!parse_pair(spacing, v, true)) return usage("--spacing expects D or DX,DY");
    o.spacing = v;
  }
  if (!raw_size.empty()) {
    int w = 0, h = 0;
    if (std::sscanf(raw_size.c_str(), "%dx%d", &w, &h) != 2 || w <= 0 || h <= 0)
      return usage("--raw-size expects WIDTHxHEIGHT, e.g. 1025x1025");
    o.raw_size = {w, h};
  }
  if (!valid_range.empty()) {
    std::array<double, 2> v{};
    if (!parse_pair(valid_range, v, false)) return usage("--valid-range expects MIN,MAX in metres, e.g. -500,5000");
    o.valid_range_m = v;
  }
  if (!memory_limit.empty() && !terrain::cook::parse_byte_size(memory_limit, o.memory_limit_bytes))
    return usage("--memory-limit " + memory_limit + ": expects a size of at least 1M, e.g. 512M, 2G, 1.5G");
  o.nodata_value = nodata_value;
  o.nodata = nodata == "hole" ? terrain::cook::NodataPolicy::hole
             : nodata == "fill" ? terrain::cook::NodataPolicy::fill
                                : terrain::cook::NodataPolicy::automatic;
  o.surface_quality = quality == "fast" ? terrain::cook::SurfaceQuality::fast
                      : quality == "best" ? terrain::cook::SurfaceQuality::best
                                          : terrain::cook::SurfaceQuality::balanced;

  terrain::TerminalProgress bar(!quiet && !json);
  terrain::cook::CookReport report;
  terrain::Status st;
  try {
    st = terrain::cook::cook(o, bar.active() ? bar.callback() : terrain::ProgressFn{}, report);
  } catch (const std::bad_alloc&) {  // past the budget's checks: the system refused (ulimit, overcommit)
    st = terrain::Status::failure(terrain::Error::internal,
                                  "out of memory: the system refused an allocation; give a lower --memory-limit "
                                  "than the memory this process may use, or a smaller input");
  } catch (const std::exception& e) {
    st = terrain::Status::failure(terrain::Error::internal, std::string("unexpected error: ") + e.what());
  }
  bar.done();
  if (!quiet)
    for (const std::string& w : report.warnings) std::fprintf(stderr, "terrain-cook: warning: %s\n", w.c_str());
  if (!st.ok()) {
    std::fprintf(stderr, "terrain-cook: %s\n", st.to_string().c_str());
    return st.code == terrain::Error::invalid_argument ? 2 : 1;
  }
  if (!report_path.empty()) {
    std::ofstream out(report_path);
    out << terrain::cook::report_json(report) << "\n";
    if (!out) {
      std::fprintf(stderr, "terrain-cook: cannot write the report %s\n", report_path.c_str());
      return 1;
    }
  }
  if (json) std::printf("%s\n", terrain::cook::report_json(report).c_str());
  else if (!quiet) std::printf("%s", terrain::cook::report_summary(report).c_str());
  return 0;
}
