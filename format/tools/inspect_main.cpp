// terrain-inspect: a thin shell over terrain::inspect (inspect.h).
// Exit codes: 0 ok, 1 failure (bad archive, verification failed, I/O), 2 usage error.
#include <CLI/CLI.hpp>
#include <sys/stat.h>
#include <cstdio>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "cli_checks.h"
#include "inspect.h"
#include "terminal_progress.h"
#include "terrain/output_paths.h"
#include "terrain/remote_source.h"

namespace {

int fail(const terrain::Status& s) {
  std::fprintf(stderr, "terrain-inspect: %s\n", s.to_string().c_str());
  return s.code == terrain::Error::invalid_argument ? 2 : 1;
}

// --export DIR: DIR is a directory or absent; none of the files it receives is the archive or a
// non-regular file (output_paths.h).
terrain::Status check_export_dir(const std::string& archive, const std::string& dir) {
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) return terrain::Status::success();  // created by export_node
  if (!S_ISDIR(st.st_mode))
    return terrain::Status::failure(terrain::Error::invalid_argument,
                                    "--export " + dir + ": is a " + terrain::file_kind_name(st.st_mode) + ", not a directory");
  std::vector<terrain::NamedPath> outputs;
  for (const char* name : terrain::inspect::kExportFiles) outputs.push_back({"--export", dir + "/" + name});
  return terrain::check_output_paths({{"archive", archive}}, outputs);
}

int run(int argc, char** argv) {
  CLI::App app{"terrain-inspect: summary, verification, sampling and export of a terrain archive (format/SPEC.md)"};
  std::string path, export_key, export_dir, sample_file, lonlat_crs;
  std::vector<std::string> samples, samples_lonlat, export_args;
  bool json = false, do_verify = false, lonlat = false, quiet = false;
  app.add_option("archive", path, "archive file, or an http:// or https:// URL (read with range requests)")->required();
  app.add_flag("--json", json, "machine-readable output (summary, verification, samples)");
  app.add_flag("--verify", do_verify, "check everything; exit 0 only when the archive is fully valid");
  app.add_option("--sample", samples, "height at frame point X,Y (metres); repeatable")->type_name("X,Y");
  app.add_option("--sample-lonlat", samples_lonlat,
                 "height at LON,LAT (degrees on WGS 84, EPSG:4326, as GPS and web maps give; see --lonlat-crs); repeatable")
      ->type_name("LON,LAT");
  app.add_option("--lonlat-crs", lonlat_crs,
                 "geographic CRS of --sample-lonlat / --lonlat points (default EPSG:4326 WGS 84; e.g. EPSG:4267 NAD27, "
                 "EPSG:4258 ETRS89); PROJ converts to the archive's datum (without datum grids where none are installed)")
      ->type_name("CRS");
  app.add_option("--sample-file", sample_file, "heights at the points of FILE, one 'x y' (or 'lon lat' with --lonlat) per line")
      ->check(CLI::ExistingFile);
  app.add_flag("--lonlat", lonlat, "--sample-file holds longitude latitude pairs (on --lonlat-crs, default WGS 84)");
  app.add_option("--export", export_args, "write node LEVEL/X/Y as images into DIR")->expected(2)->type_name("LEVEL/X/Y DIR");
  app.add_flag("-q,--quiet", quiet, "no progress bar");
  app.footer(std::string("Heights print one per line in metres, or 'nodata'. With --json, one JSON document: the summary, "
                         "or {file, valid, nodes, error} for --verify plus samples: [...] for --sample.\n"
                         "Byte layout: format/SPEC.md.\n") +
             terrain::cli::kExitCodes);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }

  std::vector<terrain::inspect::SamplePoint> points;
  for (const std::string& s : samples) {
    terrain::inspect::SamplePoint p;
    if (!terrain::inspect::parse_pair(s, p.x, p.y)) {
      std::fprintf(stderr, "terrain-inspect: --sample expects X,Y (two numbers), got '%s'\n", s.c_str());
      return 2;
    }
    points.push_back(p);
  }
  for (const std::string& s : samples_lonlat) {
    terrain::inspect::SamplePoint p;
    p.lonlat = true;
    if (!terrain::inspect::parse_pair(s, p.x, p.y)) {
      std::fprintf(stderr, "terrain-inspect: --sample-lonlat expects LON,LAT (two numbers), got '%s'\n", s.c_str());
      return 2;
    }
    points.push_back(p);
  }
  if (lonlat && sample_file.empty()) {
    std::fprintf(stderr, "terrain-inspect: --lonlat only applies to --sample-file\n");
    return 2;
  }
  if (!sample_file.empty())
    if (terrain::Status s = terrain::inspect::read_point_file(sample_file, lonlat, points); !s.ok()) return fail(s);
  terrain::NodeKey export_node{};
  if (!export_args.empty() && !terrain::inspect::parse_key(export_args[0], export_node)) {
    std::fprintf(stderr, "terrain-inspect: --export expects LEVEL/X/Y (level 0..5), got '%s'\n", export_args[0].c_str());
    return 2;
  }

  if (!export_args.empty())
    if (terrain::Status s = check_export_dir(path, export_args[1]); !s.ok()) return fail(s);

  // Samples and an export need a few nodes: their directory pages are read as needed (SPEC 20), so
  // a URL of a national archive costs a few requests, not its whole directory.
  const bool summary = points.empty() && export_args.empty() && !do_verify;
  const auto load = summary || do_verify ? terrain::DirectoryLoad::whole : terrain::DirectoryLoad::by_page;
  terrain::ArchiveReader reader;
  if (terrain::Status s = terrain::open_archive(reader, path, {}, load); !s.ok()) {
    // --json --verify promises its document for every file, an unreadable or foreign one too.
    if (json && do_verify) {
      const nlohmann::json doc = {{"file", path}, {"valid", false}, {"nodes", 0},
                                  {"error", {{"code", int(s.code)}, {"name", terrain::error_name(s.code)}, {"message", s.message}}}};
      std::printf("%s\n", doc.dump(2).c_str());
    }
    return fail(s);
  }

  if (summary) {
    std::string text;
    const terrain::Status s = json ? terrain::inspect::summary_json(reader, path, text) : terrain::inspect::summary_text(reader, path, text);
    if (!s.ok()) return fail(s);
    std::fputs(text.c_str(), stdout);
    return 0;
  }
  // --json: one document for --verify and --sample together (printed once, at the end).
  nlohmann::json doc = {{"file", path}};
  if (do_verify) {
    terrain::TerminalProgress bar(!quiet);
    const terrain::Status s = terrain::inspect::verify(reader, bar.callback());
    bar.done();
    if (json) {
      doc["valid"] = s.ok();
      doc["nodes"] = reader.nodes().size();
      if (!s.ok()) doc["error"] = {{"code", int(s.code)}, {"name", terrain::error_name(s.code)}, {"message", s.message}};
      if (!s.ok()) std::printf("%s\n", doc.dump(2).c_str());
    } else if (s.ok()) {
      std::printf("%s: valid (%zu nodes, %llu bytes)\n", path.c_str(), reader.nodes().size(),
                  static_cast<unsigned long long>(reader.file_size()));
    }
    if (!s.ok()) {
      std::fprintf(stderr, "terrain-inspect: %s: INVALID: %s\n", path.c_str(), s.to_string().c_str());
      return 1;
    }
  }
  if (!points.empty()) {
    std::vector<terrain::inspect::SampleAnswer> answers;
    if (terrain::Status s = terrain::inspect::sample(reader, points, answers, lonlat_crs); !s.ok()) return fail(s);
    if (json) {
      nlohmann::json j = nlohmann::json::array();
      for (size_t i = 0; i < answers.size(); ++i) {
        const auto& a = answers[i];
        nlohmann::json o = {{"input", {points[i].x, points[i].y}}, {"frame_m", {a.frame_x, a.frame_y}}};
        o["height_m"] = a.height_m ? nlohmann::json(*a.height_m) : nlohmann::json(nullptr);
        if (a.height_m) o["node"] = fmt::format("{}/{}/{}", a.node.level, a.node.x, a.node.y);
        j.push_back(o);
      }
      doc["samples"] = j;
    } else {
      for (const auto& a : answers) {
        if (a.height_m)
          std::printf("%.4f\n", *a.height_m);
        else
          std::printf("nodata\n");
      }
    }
  }
  if (json && (do_verify || !points.empty())) std::printf("%s\n", doc.dump(2).c_str());
  if (!export_args.empty()) {
    std::vector<std::string> written;
    if (terrain::Status s = terrain::inspect::export_node(reader, export_node, export_args[1], written); !s.ok()) return fail(s);
    if (!quiet && !json)
      for (const std::string& f : written) std::fprintf(stderr, "wrote %s\n", f.c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return terrain::cli::guarded_main("terrain-inspect", [&] { return run(argc, argv); });
}
