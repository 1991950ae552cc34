// terrain-export: a thin shell over terrain::engine_export (format/export/include/terrain/engine_export.h).
// Exit codes: 0 ok, 1 failure (bad archive, I/O), 2 usage error (bad flag, refused output path).
#include <CLI/CLI.hpp>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "cli_checks.h"
#include "inspect_lonlat.h"
#include "terminal_progress.h"
#include "terrain/engine_export.h"
#include "terrain/output_paths.h"

namespace {

namespace ex = terrain::engine_export;

int fail(const terrain::Status& s) {
  std::fprintf(stderr, "terrain-export: %s\n", s.to_string().c_str());
  return s.code == terrain::Error::invalid_argument ? 2 : 1;
}
int usage(const std::string& msg) {
  std::fprintf(stderr, "terrain-export: %s\n", msg.c_str());
  return 2;
}

// "A,B,C,D": four finite numbers.
bool parse_four(const std::string& text, double v[4]) {
  size_t start = 0;
  for (int i = 0; i < 4; ++i) {
    const size_t comma = i < 3 ? text.find(',', start) : text.size();
    if (comma == std::string::npos) return false;
    if (!terrain::cli::parse_number(text.substr(start, comma - start), v[i]) || !std::isfinite(v[i])) return false;
    start = comma + 1;
  }
  return start == text.size() + 1;
}

int run(int argc, char** argv) {
  CLI::App app{"terrain-export: heightmaps, material weight maps and hole masks of a terrain archive for Unreal Landscape "
               "or Godot (Terrain3D) / other engines, read through the archive's surface (terrain-inspect --sample)"};
  std::string path, out_dir, target = "unreal", rect_text, rect_lonlat_text, lonlat_crs;
  ex::Options o;
  bool json = false, quiet = false;
  app.add_option("archive", path, "archive file")->required();
  app.add_option("-o,--output", out_dir, "directory to write into (created; files in it are replaced)")->required();
  app.add_option("--target", target,
                 "unreal: 16-bit PNG heightmap at an Unreal size (127 .. 8129, tiled _x0_y0 beyond), 8-bit weight map per "
                 "material, visibility (hole) layer; godot: EXR float heights and RGBA control maps per region, collision "
                 "float32 heightfield + uint8 hole mask")
      ->check(CLI::IsMember({"unreal", "godot"}))
      ->capture_default_str();
  app.add_option("--level", o.level, "sample spacing of this level, 0 (0.5 m) .. 5 (16 m); default: the archive's finest")
      ->check(terrain::cli::int_range(0, 5));
  app.add_option("--rect", rect_text, "frame rectangle MIN_X,MIN_Y,MAX_X,MAX_Y in metres (default: the data extent)")
      ->type_name("X0,Y0,X1,Y1");
  app.add_option("--rect-lonlat", rect_lonlat_text,
                 "rectangle WEST,SOUTH,EAST,NORTH in degrees (WGS 84 unless --lonlat-crs); the frame box around it")
      ->type_name("W,S,E,N");
  app.add_option("--lonlat-crs", lonlat_crs, "geographic CRS of --rect-lonlat (default EPSG:4326)")->type_name("CRS");
  app.add_option("--name", o.name, "file name prefix (letters, digits, '-', '_')")->capture_default_str();
  app.add_option("--tile-size", o.tile_size,
                 "unreal: largest heightmap side before tiling (127, 253, 505, 1009, 2017, 4033 or 8129; default 8129); "
                 "godot: region side in samples (16..8192, default 1024)")
      ->check(terrain::cli::int_range(1, 8192));
  app.add_flag("--json", json, "print the export's JSON document (also written as NAME.json) instead of the instructions");
  app.add_flag("-q,--quiet", quiet, "no progress bar and no instructions");
  app.footer(std::string("The instructions (Unreal: the Scale and Location Z to type into the import dialog) are printed and "
                         "written to DIR/NAME.json with the flags that cook an export back (terrain-cook --crs local).\n"
                         "Outputs must not name the archive, a device, a FIFO or a directory.\n") +
             terrain::cli::kExitCodes);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  o.target = target == "godot" ? ex::Target::godot : ex::Target::unreal;
  o.out_dir = out_dir;
  if (!rect_text.empty() && !rect_lonlat_text.empty()) return usage("--rect and --rect-lonlat exclude each other");
  if (!lonlat_crs.empty() && rect_lonlat_text.empty()) return usage("--lonlat-crs only applies to --rect-lonlat");
  double v[4] = {};
  if (!rect_text.empty()) {
    if (!parse_four(rect_text, v)) return usage("--rect expects MIN_X,MIN_Y,MAX_X,MAX_Y (four numbers), got '" + rect_text + "'");
    o.rect = ex::Rect{v[0], v[1], v[2], v[3]};
  }
  if (!rect_lonlat_text.empty() && !parse_four(rect_lonlat_text, v))
    return usage("--rect-lonlat expects WEST,SOUTH,EAST,NORTH (four numbers), got '" + rect_lonlat_text + "'");

  if (terrain::Status s = terrain::check_input_file("", path); !s.ok()) return fail(s);
  struct stat st {};
  if (::stat(out_dir.c_str(), &st) == 0 && !S_ISDIR(st.st_mode))
    return usage("-o " + out_dir + ": is a " + terrain::file_kind_name(st.st_mode) + ", not a directory");

  terrain::ArchiveReader reader;
  if (terrain::Status s = reader.open(path); !s.ok()) return fail(s);
  if (!rect_lonlat_text.empty()) {  // the frame box around the rectangle's edges (TM bends them slightly)
    terrain::inspect::LonLatToFrame to_frame;
    if (terrain::Status s = to_frame.init(reader.world().crs, lonlat_crs); !s.ok()) return fail(s);
    ex::Rect r{1e300, 1e300, -1e300, -1e300};
    for (int k = 0; k <= 16; ++k) {
      const double t = k / 16.0;
      const double pts[4][2] = {{v[0] + t * (v[2] - v[0]), v[1]}, {v[0] + t * (v[2] - v[0]), v[3]},
                                {v[0], v[1] + t * (v[3] - v[1])}, {v[2], v[1] + t * (v[3] - v[1])}};
      for (const auto& p : pts) {
        double x = 0, y = 0;
        if (terrain::Status s = to_frame.convert(p[0], p[1], x, y); !s.ok()) return fail(s);
        r = {std::min(r.min_x, x), std::min(r.min_y, y), std::max(r.max_x, x), std::max(r.max_y, y)};
      }
    }
    o.rect = r;
  }
  ex::Plan plan;
  if (terrain::Status s = ex::plan_export(reader, o, plan); !s.ok()) return fail(s);
  // A new directory cannot hold the archive; it is made now so the files' checks can resolve it,
  // and removed again (empty) when they refuse.
  std::error_code ec;
  const bool made_dir = std::filesystem::create_directories(out_dir, ec);
  if (ec) return fail(terrain::Status::failure(terrain::Error::io_write, "-o " + out_dir + ": cannot create: " + ec.message()));
  std::vector<terrain::NamedPath> outputs;
  for (const std::string& f : plan.files) outputs.push_back({"-o", f});
  if (terrain::Status s = terrain::check_output_paths({{"archive", path}}, outputs); !s.ok()) {
    if (made_dir) std::filesystem::remove(out_dir, ec);
    return fail(s);
  }

  terrain::TerminalProgress bar(!quiet && !json);
  ex::Result result;
  const terrain::Status s = ex::run_export(reader, plan, bar.callback(), result);
  bar.done();
  if (!s.ok()) return fail(s);
  if (json)
    std::fputs(result.json.c_str(), stdout);
  else if (!quiet)
    std::fputs(ex::import_instructions(plan, result).c_str(), stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return terrain::cli::guarded_main("terrain-export", [&] { return run(argc, argv); });
}
