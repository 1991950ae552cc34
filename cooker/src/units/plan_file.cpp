#include "units/plan_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "frame/crs.h"
#include "inputs/height_units.h"
#include "inputs/source_raster.h"
#include "pyramid/overview_levels.h"
#include "session/cook_options_table.h"
#include "units/file_io.h"
#include "units/work_dir.h"

namespace terrain::cook {
namespace {

using json = nlohmann::ordered_json;

json rect_json(const SampleRect& r) { return json::array({r.c0, r.r0, r.c1, r.r1}); }
SampleRect rect_of(const json& j) { return {j.at(0).get<int>(), j.at(1).get<int>(), j.at(2).get<int>(), j.at(3).get<int>()}; }
bool meets(const SampleRect& a, const SampleRect& b) { return !a.empty() && !b.empty() && !intersect(a, b).empty(); }
// The plan's record of what each input gave (CookReport::input_samples): [path, read, used,
// family, spacing_m] each (plans written before the grid families: the first three, family 0).
json input_samples_json(const std::vector<InputSamples>& v) {
  json a = json::array();
  for (const InputSamples& i : v) a.push_back(json::array({i.path, i.read, i.used, i.family, i.spacing_m}));
  return a;
}
std::vector<InputSamples> input_samples_of(const json& a) {
  std::vector<InputSamples> v;
  for (const json& i : a) {
    InputSamples s{.path = i.at(0).get<std::string>(), .read = i.at(1).get<uint64_t>(), .used = i.at(2).get<uint64_t>()};
    if (i.size() >= 5) {
      s.family = i.at(3).get<uint32_t>();
      s.spacing_m = i.at(4).get<double>();
    }
    v.push_back(std::move(s));
  }
  return v;
}

// A unit's fingerprint: the plan's, its roots, its window and the fingerprints of the files whose
// footprint meets the window (`files`: those, in the plan's order; format/SPEC.md section 18).
template <typename Files>
std::string unit_fingerprint(const std::string& plan_fingerprint, const UnitPlan& u, const Files& files) {
  std::string text = fmt::format("{}|{},{},{},{}|{},{},{},{}", plan_fingerprint, u.roots.x0, u.roots.y0, u.roots.x1,
                                 u.roots.y1, u.window.c0, u.window.r0, u.window.c1, u.window.r1);
  for (const InputFile& f : files) text += "|" + f.fingerprint;
  return hex64(fnv1a(text));
}

// The plan's files a unit reads (plan.unit_files[u]), iterated as InputFile. (A plain iterator:
// clang with libstdc++ 12, the sanitizer and fuzzer builds, rejects std::views here.)
struct UnitFiles {
  struct It {
    const PlanFile* plan;
    const uint32_t* at;
    const InputFile& operator*() const { return plan->files[*at]; }
    It& operator++() {
      ++at;
      return *this;
    }
    bool operator!=(const It& o) const { return at != o.at; }
  };
  const PlanFile& plan;
  uint32_t unit;
  It begin() const { return {&plan, plan.unit_files[unit].data()}; }
  It end() const { return {&plan, plan.unit_files[unit].data() + plan.unit_files[unit].size()}; }
};
UnitFiles unit_files(const PlanFile& plan, uint32_t u) { return {plan, u}; }
// One entry of a list of input files; throws on a malformed one (the caller names the file).
InputFile file_of(const json& fj) {
  InputFile fi;
  fi.path = fj.at("path");
  fi.size = fj.at("size");
  fi.mtime_ns = fj.at("mtime_ns");
  fi.inode = fj.at("inode");
  fi.ctime_ns = fj.at("ctime_ns");
  fi.fingerprint = fj.at("fingerprint");
  fi.footprint = rect_of(fj.at("footprint"));
  return fi;
}

json frame_json(const FrameCrs& f) {
  return {{"kind", int(f.kind)},          {"epsg", f.epsg},
          {"semi_major_m", f.semi_major_m}, {"inverse_flattening", f.inverse_flattening},
          {"lat0_deg", f.lat0_deg},       {"lon0_deg", f.lon0_deg},
          {"scale_k0", f.scale_k0},       {"false_easting_m", f.false_easting_m},
          {"false_northing_m", f.false_northing_m}, {"name", f.name},
          {"definition", f.definition}};
}
FrameCrs frame_of(const json& j) {
  FrameCrs f;
  f.kind = ProjectionKind(j.at("kind").get<int>());
  f.epsg = j.at("epsg");
  f.semi_major_m = j.at("semi_major_m");
  f.inverse_flattening = j.at("inverse_flattening");
  f.lat0_deg = j.at("lat0_deg");
  f.lon0_deg = j.at("lon0_deg");
  f.scale_k0 = j.at("scale_k0");
  f.false_easting_m = j.at("false_easting_m");
  f.false_northing_m = j.at("false_northing_m");
  f.name = j.at("name");
  f.definition = j.at("definition");
  return f;
}

// `path` made absolute against the working directory (not through symbolic links): what `unit`
// and `merge` open, from whatever directory they run in. Paths GDAL reads through a virtual file
// system ("/vsizip/...") are absolute already or left as given.
std::string absolute_path(const std::string& path) {
  if (path.empty() || path.front() == '/') return path;
  std::error_code ec;
  const std::filesystem::path abs = std::filesystem::absolute(path, ec);
  return ec ? path : abs.lexically_normal().string();
}

// The mosaic samples a raster file covers: its corners through the mosaic's georeferencing, one
// sample of margin; the whole mosaic when GDAL cannot say (own formats, another CRS).
SampleRect footprint_of(const FilePlacement& f, const Raster& header, const SampleRect& whole) {
  if (!f.has_geotransform || header.crs.kind == CrsKind::geographic) return whole;
  const double* gt = f.gt;
  const AffineMap m = AffineMap::from(header.geo);
  double cmin = INFINITY, cmax = -INFINITY, rmin = INFINITY, rmax = -INFINITY;
  for (double px : {0.0, double(f.width)})
    for (double py : {0.0, double(f.height)}) {
      double c = 0, r = 0;
      m.to_sample(gt[0] + px * gt[1] + py * gt[2], gt[3] + px * gt[4] + py * gt[5], c, r);
      cmin = std::min(cmin, c);
      cmax = std::max(cmax, c);
      rmin = std::min(rmin, r);
      rmax = std::max(rmax, r);
    }
  if (!std::isfinite(cmin + cmax + rmin + rmax)) return whole;
  const SampleRect r{int(std::max(-1.0, std::floor(cmin) - 1)), int(std::max(-1.0, std::floor(rmin) - 1)),
                     int(std::min(1e9, std::ceil(cmax) + 1)), int(std::min(1e9, std::ceil(rmax) + 1))};
  return intersect(r, whole);
}

Status collect_input_files(const CookSession& s, std::vector<InputFile>& out) {
  const Raster& header = s.source.header();
  const SampleRect whole{0, 0, header.width - 1, header.height - 1};
  std::map<std::string, size_t> seen;
  auto add = [&](const std::string& typed, const SampleRect& footprint) -> Status {
    const std::string path = absolute_path(typed);
    if (auto it = seen.find(path); it != seen.end()) {
      out[it->second].footprint = unite(out[it->second].footprint, footprint);
      return Status::success();
    }
    InputFile f;
    f.path = path;
    if (!stat_file(f))
      return Status::failure(Error::io_open, fmt::format("{}: cannot stat: {}", path, std::strerror(errno)));
    f.footprint = footprint;
    f.fingerprint = file_fingerprint(f);
    seen[path] = out.size();
    out.push_back(std::move(f));
    return Status::success();
  };
  for (const MosaicSource::InputStat& in : s.source.inputs()) {
    // A VRT's tiles follow it: each its own fingerprint and footprint, so a replaced tile touches
    // only its units.
    const std::vector<FilePlacement> files = gdal_file_placements(in.path);
    const bool placed = files[0].opened && same_crs(in.crs, header.crs);
    for (const FilePlacement& f : files)
      TERRAIN_TRY(add(f.path, placed && f.opened ? footprint_of(f, header, whole) : whole));
  }
  for (const std::string* p : {&s.options.materials_path, &s.options.albedo_path, &s.options.holes_path,
                               &s.options.landcover_path, &s.options.landcover_table_path})
    if (!p->empty())
      TERRAIN_TRY(add(*p, whole));
  return Status::success();
}

// The decisions every unit depends on, as text: their hash is the plan's fingerprint.
std::string decisions_text(const CookOptions& o, const FrameCrs& frame, const WorldInfo& w, int width, int height,
                           int finest, const std::array<uint8_t, kLevelCount>& steps) {
  json j;
  j["options"] = plan_options_json(o, /*budget=*/false);  // the memory limit changes blocks, never bytes
  j["source"] = {width, height};
  j["frame"] = frame_json(frame);
  j["grid"] = {w.origin_x_m, w.origin_y_m, w.roots_x, w.roots_y};
  j["finest_level"] = finest;
  j["steps"] = steps;
  if (!w.overview_step_log2.empty()) j["overview_steps"] = w.overview_step_log2;
  return j.dump();
}

// A list of input files as `head` (a JSON object) with a "files" array of them appended, in the
// bytes head.dump(1) + "\n" would give, handed to `put` entry by entry: a list of a national grid
// never stands in memory as one JSON document (62 500 entries took 80 MB as a tree).
template <class Files, class Put>
void put_file_list(const json& head, const Files& files, Put&& put) {
  const std::string h = head.dump(1);  // "{\n ...\n}"
  put(std::string_view(h).substr(0, h.size() - 2));
  put(",\n \"files\": [");
  bool first = true;
  for (const InputFile& f : files) {
    const std::string e = json{{"path", f.path}, {"size", f.size}, {"mtime_ns", f.mtime_ns},
                               {"inode", f.inode}, {"ctime_ns", f.ctime_ns},
                               {"fingerprint", f.fingerprint}, {"footprint", rect_json(f.footprint)}}.dump(1);
    put(first ? "\n  " : ",\n  ");
    first = false;
    size_t from = 0;  // the entry's lines, two levels in
    for (size_t nl = e.find('\n'); nl != std::string::npos; from = nl + 1, nl = e.find('\n', from)) {
      put(std::string_view(e).substr(from, nl + 1 - from));
      put("  ");
    }
    put(std::string_view(e).substr(from));
  }
  put(first ? "]" : "\n ]");
  put("\n}\n");
}


}  // namespace

Status write_unit_inputs(const CookSession& s, const PlanFile& plan, const std::string& work_dir) {
  // Each unit's own list of the files it reads (all of them are in the plan's inputs file).
  for (const UnitPlan& u : plan.units) {
    const std::string path = unit_inputs_file(work_dir, u);
    StagedText f(path);
    put_file_list(json{{"format", "terrain-cook-unit-inputs"}, {"unit", u.index}, {"fingerprint", u.fingerprint}},
                  unit_files(plan, u.index), [&](std::string_view t) { f.put(t); });
    TERRAIN_TRY(f.commit(path, /*durable=*/false));
  }
  const std::vector<MosaicSource::InputStat>& inputs = s.source.inputs();
  std::set<std::string> current;
  std::vector<std::array<int, 4>> windows;
  std::vector<std::string> outputs;
  if (inputs.size() == 1 && inputs[0].windowed && inputs[0].path.ends_with(".vrt"))
    for (const UnitPlan& u : plan.units) {
      if (u.window.empty()) continue;
      // Written again even where one of this name exists: a cut a crash left damaged is replaced.
      const std::string out = unit_vrt_file(work_dir, u);
      current.insert(out);
      windows.push_back({u.window.c0, u.window.r0, u.window.c1, u.window.r1});
      outputs.push_back(out);
    }
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(units_dir(work_dir), ec)) {
    const std::string name = e.path().filename().string();
    if (name.starts_with("unit-") && name.ends_with(".vrt") && !current.count(e.path().string()))
      std::filesystem::remove(e.path(), ec);  // a cut of an earlier plan
  }
  bool written = false;
  if (!outputs.empty())
    TERRAIN_TRY(write_vrt_windows(inputs[0].path, windows, outputs, written));
  // On disk before the plan that names them (write_plan fsyncs plan.json).
  const int fd = ::open(units_dir(work_dir).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  const bool synced = fd >= 0 && ::syncfs(fd) == 0;
  if (fd >= 0) ::close(fd);
  if (!synced)
    return Status::failure(Error::io_write, fmt::format("{}: cannot sync the units' inputs: {}", units_dir(work_dir),
                                                        std::strerror(errno)));
  return Status::success();
}

Status plan_units(CookSession& s, PlanFile& plan) {
  plan = PlanFile{};
  TERRAIN_TRY(collect_input_files(s, plan.files));
  const Raster& header = s.source.header();
  plan.fingerprint = hex64(fnv1a(decisions_text(s.options, s.frame, s.world, header.width, header.height,
                                                s.ctx.finest_level, s.ctx.step_log2)));
  for (uint32_t i = 0; i < s.units.count(); ++i) {
    UnitPlan u;
    u.index = i;
    u.roots = s.units.block(i);
    const SampleRect need = block_cook_rect(s.ctx, u.roots);
    u.window = need.empty() ? SampleRect{} : fill_read_rect(s.voids, need);
    // The files the unit reads, found once: its fingerprint and its list both follow them.
    std::vector<uint32_t>& meeting = plan.unit_files.emplace_back();
    for (uint32_t k = 0; k < plan.files.size(); ++k)
      if (meets(plan.files[k].footprint, u.window)) meeting.push_back(k);
    u.fingerprint = unit_fingerprint(plan.fingerprint, u, unit_files(plan, i));
    plan.units.push_back(u);
  }
  return Status::success();
}

Status write_plan(const CookSession& s, const CookReport& report, const PlanFile& plan, const std::string& path) {
  json j;
  j["format"] = "terrain-cook-plan";
  j["version"] = 3;
  j["fingerprint"] = plan.fingerprint;
  j["options"] = plan_options_json(s.options);  // paths as typed: the cook info keeps them
  j["resolved_paths"] = input_paths_json(resolved_options(s.options));  // what unit and merge open
  // Every input file in a file of its own, named by its contents' fingerprint: only `plan` and the
  // merge read it (a unit reads its own list), so plan.json stays small however many tiles there are.
  const std::string work_dir = std::filesystem::path(path).parent_path().string();
  // Staged before its name (its fingerprint) is known.
  const std::string staged_for = work_dir + "/inputs.json";
  remove_stale_staging(staged_for);
  StagedText list(staged_for);
  uint64_t h = fnv1a({});
  put_file_list(json{{"format", "terrain-cook-inputs"}}, plan.files, [&](std::string_view t) {
    h = fnv1a(t, h);
    list.put(t);
  });
  const std::string inputs_fingerprint = hex64(h);
  const std::string inputs_path = inputs_file(work_dir, inputs_fingerprint);
  TERRAIN_TRY(list.commit(inputs_path, /*durable=*/true));
  j["inputs"] = {{"count", plan.files.size()}, {"fingerprint", inputs_fingerprint}};
  const Raster& header = s.source.header();
  j["source"] = {{"width", header.width}, {"height", header.height}};
  j["frame"] = frame_json(s.frame);
  const WorldInfo& w = s.world;
  j["grid"] = {{"origin_x_m", w.origin_x_m}, {"origin_y_m", w.origin_y_m}, {"roots_x", w.roots_x},
               {"roots_y", w.roots_y}, {"extent", {w.extent_min_x_m, w.extent_min_y_m, w.extent_max_x_m, w.extent_max_y_m}},
               {"unit_roots", s.units.side}};
  j["finest_level"] = s.ctx.finest_level;
  j["tolerance_m"] = s.ctx.tolerance_m;  // in force (options.tolerance_m 0: the source's default)
  j["steps"] = s.ctx.step_log2;
  if (!w.overview_step_log2.empty()) j["overview_steps"] = w.overview_step_log2;
  json fills = json::array();
  for (const SampleRect& r : s.voids.spanning_fills) fills.push_back(rect_json(r));
  const VoidStats& vs = s.voids.stats;
  j["voids"] = {{"tile", s.voids.tile},
                {"valid_samples", s.voids.valid_samples},
                {"valid_bounds", rect_json(s.voids.valid_bounds)},
                {"stats", {vs.filled_samples, vs.filled_regions, vs.hole_samples, vs.hole_regions}},
                {"spanning_fills", fills}};
  json descriptions = json::array();
  for (const auto& [p, d] : s.descriptions) descriptions.push_back({p, d});
  j["report"] = {{"descriptions", descriptions},
                 {"input_descriptions", report.input_descriptions},
                 {"frame_reason", report.frame_reason},
                 {"source_samples", report.source_samples},
                 {"source_spacing_m", report.source_spacing_m},
                 {"source_sample_area_m2", report.source_sample_area_m2},
                 {"implausible_samples", report.implausible_samples},
                 {"warnings", report.warnings},
                 {"input_samples", input_samples_json(report.input_samples)}};
  // Per input: the unit its heights declare and the factor applied (the merge's report and cook info).
  json height_units = json::array();
  for (const HeightUnit& u : report.input_height_units) height_units.push_back(height_unit_json(u));
  j["report"]["input_height_units"] = height_units;
  j["unit_count"] = plan.units.size();
  json units = json::array();
  for (const UnitPlan& u : plan.units)
    units.push_back({{"index", u.index},
                     {"roots", {u.roots.x0, u.roots.y0, u.roots.x1, u.roots.y1}},
                     {"window", rect_json(u.window)},
                     {"fingerprint", u.fingerprint}});
  j["units"] = units;
  // Atomically: a plan is either the old one or the new one.
  remove_stale_staging(path);  // a plan write killed before its rename
  TERRAIN_TRY(write_text_file(path, j.dump(1) + "\n", /*durable=*/true));
  // Only now the inputs of earlier plans go: until the rename they were the plan's.
  std::set<std::string> current{std::filesystem::path(inputs_path).filename().string()};
  for (const UnitPlan& u : plan.units) current.insert(std::filesystem::path(unit_inputs_file(work_dir, u)).filename().string());
  std::error_code ec;
  for (const std::string& dir : {work_dir, units_dir(work_dir)})
    for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
      const std::string name = e.path().filename().string();
      const bool inputs = (name.starts_with("inputs-") || name.starts_with("unit-")) && name.ends_with(".json");
      if (inputs && !current.count(name)) std::filesystem::remove(e.path(), ec);
    }
  return Status::success();
}

namespace {

// The `files` of the list of input files at `path` whose "format" is `format`. Each entry becomes
// an InputFile as soon as it is parsed and its JSON is dropped: memory is the list, not a document
// of it (a national grid lists 10^5 to 10^6 files; at 62 500 the document took 81 MB).
Status parse_file_list(const std::string& path, const char* format, std::vector<InputFile>& files) {
  std::ifstream f(path, std::ios::binary);
  files.clear();
  std::string bad_entry;
  const json::parser_callback_t keep = [&](int depth, json::parse_event_t event, json& parsed) {
    if (depth != 2 || event != json::parse_event_t::object_end) return true;  // an entry of "files" ends at depth 2
    try {
      files.push_back(file_of(parsed));
    } catch (const std::exception& e) {
      if (bad_entry.empty()) bad_entry = e.what();
    }
    return false;
  };
  json j;
  try {
    j = json::parse(f, keep, false);
  } catch (const std::exception& e) {
    return Status::failure(Error::no_data, fmt::format("{}: malformed ({})", path, e.what()));
  }
  if (j.is_discarded() || !j.is_object() || j.value("format", "") != format || !j.contains("files") ||
      !j.at("files").is_array())
    return Status::failure(Error::no_data, fmt::format("{}: not a {} file", path, format));
  if (!bad_entry.empty()) return Status::failure(Error::no_data, fmt::format("{}: malformed ({})", path, bad_entry));
  return Status::success();
}

// The plan's inputs file: every input file, checked against the fingerprint plan.json gives it.
Status read_all_inputs(const std::string& work_dir, const json& ref, std::vector<InputFile>& files) {
  const std::string fingerprint = ref.at("fingerprint");
  if (fingerprint.size() != 16 || fingerprint.find_first_not_of("0123456789abcdef") != std::string::npos)
    return Status::failure(Error::invalid_argument, fmt::format("{}: malformed plan (inputs fingerprint '{}')",
                                                                plan_file(work_dir), fingerprint));
  const std::string path = inputs_file(work_dir, fingerprint);
  uint64_t h = 0;
  if (!file_fnv1a(path, h))
    return Status::failure(Error::io_open, fmt::format("{}: the plan's list of input files is missing ({}); run "
                                                       "`terrain-cook plan` again", path, std::strerror(errno)));
  if (hex64(h) != fingerprint)
    return Status::failure(Error::no_data, fmt::format("{}: damaged (its fingerprint is not the plan's); run "
                                                       "`terrain-cook plan` again", path));
  TERRAIN_TRY(parse_file_list(path, "terrain-cook-inputs", files));
  if (files.size() != ref.at("count").get<size_t>())
    return Status::failure(Error::no_data, fmt::format("{}: {} files, the plan says {}", path, files.size(),
                                                       ref.at("count").get<size_t>()));
  return Status::success();
}

// A unit's own list of the files its window meets, checked against its fingerprint: the plan's
// fingerprint, its roots and window and those files' fingerprints give the unit's (a list of
// another plan, damaged or short, gives another).
Status read_unit_inputs(const std::string& work_dir, const std::string& plan_fingerprint, const UnitPlan& unit,
                        std::vector<InputFile>& files) {
  const std::string path = unit_inputs_file(work_dir, unit);
  if (!std::ifstream(path))
    return Status::failure(Error::io_open, fmt::format("{}: unit {}'s list of input files is missing ({}); run "
                                                       "`terrain-cook plan` again", path, unit.index, std::strerror(errno)));
  TERRAIN_TRY(parse_file_list(path, "terrain-cook-unit-inputs", files));
  bool all_meet = true;
  for (const InputFile& f : files) all_meet = all_meet && meets(f.footprint, unit.window);
  if (!all_meet || unit_fingerprint(plan_fingerprint, unit, files) != unit.fingerprint)
    return Status::failure(Error::no_data, fmt::format("{}: its files do not give unit {}'s fingerprint (damaged or "
                                                       "of another plan); run `terrain-cook plan` again",
                                                       path, unit.index));
  return Status::success();
}

}  // namespace

Status read_plan(const std::string& work_dir, PlanData& out, std::optional<uint32_t> unit) {
  const std::string path = plan_file(work_dir);
  std::ifstream f(path);
  if (!f) return Status::failure(Error::io_open, fmt::format("{}: no plan (run `terrain-cook plan ... --work-dir {}` first)", path, work_dir));
  const json j = json::parse(f, nullptr, false);
  if (j.is_discarded() || !j.is_object() || j.value("format", "") != "terrain-cook-plan")
    return Status::failure(Error::invalid_argument, fmt::format("{}: not a terrain-cook plan", path));
  if (j.value("version", 0) != 3)
    return Status::failure(Error::unsupported_version, fmt::format("{}: plan version {} (this tool reads 3); run "
                                                                   "`terrain-cook plan` again", path, j.value("version", 0)));
  try {
    out = PlanData{};
    out.options = options_of_plan_json(j.at("options"));
    out.resolved = with_input_paths_of(out.options, j.at("resolved_paths"));
    out.plan.fingerprint = j.at("fingerprint");
    out.source_width = j.at("source").at("width");
    out.source_height = j.at("source").at("height");
    out.frame = frame_of(j.at("frame"));
    const json& g = j.at("grid");
    out.world.crs = out.frame;
    out.world.origin_x_m = g.at("origin_x_m");
    out.world.origin_y_m = g.at("origin_y_m");
    out.world.roots_x = g.at("roots_x");
    out.world.roots_y = g.at("roots_y");
    out.world.extent_min_x_m = g.at("extent").at(0);
    out.world.extent_min_y_m = g.at("extent").at(1);
    out.world.extent_max_x_m = g.at("extent").at(2);
    out.world.extent_max_y_m = g.at("extent").at(3);
    out.unit_roots = g.at("unit_roots");
    out.steps = j.at("steps").get<std::array<uint8_t, kLevelCount>>();
    if (j.contains("overview_steps")) out.world.overview_step_log2 = j.at("overview_steps").get<std::vector<uint8_t>>();
    const json& v = j.at("voids");
    out.voids.width = out.source_width;
    out.voids.height = out.source_height;
    out.voids.tile = v.at("tile");
    out.voids.policy = out.options.nodata;
    out.voids.max_fill_samples = out.options.fill_max_samples;
    out.voids.valid_samples = v.at("valid_samples");
    out.voids.valid_bounds = rect_of(v.at("valid_bounds"));
    out.voids.stats.filled_samples = v.at("stats").at(0);
    out.voids.stats.filled_regions = v.at("stats").at(1);
    out.voids.stats.hole_samples = v.at("stats").at(2);
    out.voids.stats.hole_regions = v.at("stats").at(3);
    for (const json& r : v.at("spanning_fills")) out.voids.spanning_fills.push_back(rect_of(r));
    const json& r = j.at("report");
    for (const json& d : r.at("descriptions")) out.descriptions.emplace_back(d.at(0), d.at(1));
    CookReport& rep = out.report;
    rep.input_descriptions = r.at("input_descriptions").get<std::vector<std::string>>();
    rep.frame_reason = r.at("frame_reason");
    rep.source_samples = r.at("source_samples");
    rep.source_spacing_m = r.at("source_spacing_m");
    rep.source_sample_area_m2 = r.value("source_sample_area_m2", 0.0);  // absent in older plans
    rep.implausible_samples = r.at("implausible_samples");
    rep.warnings = r.at("warnings").get<std::vector<std::string>>();
    if (r.contains("input_height_units"))  // absent in plans written before it
      for (const json& u : r.at("input_height_units")) rep.input_height_units.push_back(height_unit_of_json(u));
    if (r.contains("input_samples")) rep.input_samples = input_samples_of(r.at("input_samples"));
    rep.frame = out.frame;
    rep.source_valid_samples = out.voids.valid_samples;
    rep.voids_filled_samples = out.voids.stats.filled_samples;
    rep.voids_filled_regions = out.voids.stats.filled_regions;
    rep.hole_samples = out.voids.stats.hole_samples;
    rep.hole_regions = out.voids.stats.hole_regions;
    rep.origin_x_m = out.world.origin_x_m;
    rep.origin_y_m = out.world.origin_y_m;
    rep.roots_x = out.world.roots_x;
    rep.roots_y = out.world.roots_y;
    rep.extent_min_x_m = out.world.extent_min_x_m;
    rep.extent_min_y_m = out.world.extent_min_y_m;
    rep.extent_max_x_m = out.world.extent_max_x_m;
    rep.extent_max_y_m = out.world.extent_max_y_m;
    rep.finest_level = j.at("finest_level");
    rep.overview_levels = int(out.world.overview_step_log2.size());
    rep.overview_step_log2 = out.world.overview_step_log2.empty() ? 0 : out.world.overview_step_log2[0];
    rep.tolerance_m = j.value("tolerance_m", out.options.tolerance_m);  // absent in plans written before it
    rep.tolerance_from_source = !(out.options.tolerance_m > 0);
    rep.block_roots = out.unit_roots;
    rep.blocks = j.at("unit_count");
    for (const json& u : j.at("units")) {
      UnitPlan up;
      up.index = u.at("index");
      up.roots = {u.at("roots").at(0), u.at("roots").at(1), u.at("roots").at(2), u.at("roots").at(3)};
      up.window = rect_of(u.at("window"));
      up.fingerprint = u.at("fingerprint");
      if (up.index != out.plan.units.size())
        return Status::failure(Error::invalid_argument, fmt::format("{}: units out of order at {}", path, up.index));
      out.plan.units.push_back(up);
    }
    if (unit && *unit >= out.plan.units.size())
      return Status::failure(Error::invalid_argument,
                             fmt::format("unit {}: the plan in {} has {} units (0..{})", *unit, work_dir,
                                         out.plan.units.size(), out.plan.units.size() - 1));
    // The input files: a unit's own (what it checks and reads), else all of them.
    const Status st = unit ? read_unit_inputs(work_dir, out.plan.fingerprint, out.plan.units[*unit], out.plan.files)
                           : read_all_inputs(work_dir, j.at("inputs"), out.plan.files);
    if (!st.ok()) return st;
  } catch (const std::exception& e) {
    return Status::failure(Error::invalid_argument, fmt::format("{}: malformed plan ({})", path, e.what()));
  }
  return Status::success();
}

CookOptions resolved_options(CookOptions o) {
  for (std::string& p : o.inputs) p = absolute_path(p);
  for (std::string* p : {&o.materials_path, &o.albedo_path, &o.holes_path, &o.landcover_path, &o.landcover_table_path})
    *p = absolute_path(*p);
  return o;
}

bool same_plan_options(const CookOptions& planned, const CookOptions& given) {
  return plan_options_json(planned, /*budget=*/false) == plan_options_json(given, /*budget=*/false);
}

Status check_merge_outputs(const std::string& work_dir, const PlanFile& plan, const std::vector<NamedPath>& outputs) {
  for (const NamedPath& out : outputs)
    if (work_dir_owns(work_dir, out.path))
      return Status::failure(Error::invalid_argument,
                             fmt::format("{} {}: is a file of the work dir {} (its plan, input lists and units); "
                                         "refusing to overwrite it", out.flag, out.path, work_dir));
  std::vector<NamedPath> inputs;
  inputs.reserve(plan.files.size());
  for (const InputFile& f : plan.files) inputs.push_back({"input of the plan", f.path});
  return check_output_paths(inputs, outputs);
}

Status check_plan_inputs(const PlanFile& plan, std::optional<uint32_t> unit) {
  for (const InputFile& f : plan.files) {
    if (unit && !meets(f.footprint, plan.units[*unit].window)) continue;  // not in the unit's fingerprint
    InputFile now = f;
    if (!stat_file(now))
      return Status::failure(Error::io_open, fmt::format("{}: input of the plan is gone ({}); run `terrain-cook plan` again",
                                                         f.path, std::strerror(errno)));
    if (file_fingerprint(now) != f.fingerprint)
      return Status::failure(Error::unsupported_input,
                             fmt::format("{}: changed since the plan ({}); run `terrain-cook plan` again (it keeps "
                                         "the units the change does not touch)",
                                         f.path, file_change(f, now)));
  }
  return Status::success();
}

Status open_session_from_plan(const PlanData& data, int threads, CookSession& s) {
  CookOptions o = data.resolved;  // the files the plan saw, from whatever directory this runs in
  o.threads = threads;
  o.unit_roots = data.unit_roots;
  // The callers checked the plan's files (check_plan_inputs) before anything is read from them.
  TERRAIN_TRY(open_inputs(o, s, /*files_checked=*/true));
  // GDAL's cache as the one-process cook's for a source it cannot hold: 128 MB keeps the tiles
  // that neighbouring blocks of the unit share (a unit is several blocks) instead of decoding them
  // again. 32 MB, once right for units of one block, decoded 15 % more tiles in units of 4 blocks
  // of 1 m lidar (perf samples in libtiff over the 9 units of the 16 km square, 4503 -> 3917;
  // all samples 24 779 -> 23 395).
  set_gdal_cache_bytes(std::min<uint64_t>(s.shares.gdal_cache, uint64_t(128) << 20));
  set_tiff_block_cache(s, std::min<uint64_t>(s.shares.gdal_cache, uint64_t(128) << 20));
  const Raster& header = s.source.header();
  if (header.width != data.source_width || header.height != data.source_height)
    return Status::failure(Error::unsupported_input,
                           fmt::format("the inputs are {}x{} samples, the plan's {}x{}; run `terrain-cook plan` again",
                                       header.width, header.height, data.source_width, data.source_height));
  s.voids = data.voids;
  s.voids.source_name = header.path;
  TERRAIN_TRY(frame_and_grid(s, &data.frame));
  if (s.world.origin_x_m != data.world.origin_x_m || s.world.origin_y_m != data.world.origin_y_m ||
      s.world.roots_x != data.world.roots_x || s.world.roots_y != data.world.roots_y)
    return Status::failure(Error::internal, "the plan's root grid does not follow from its inputs");
  s.ctx.step_log2 = data.steps;
  restore_overview_steps(data.world.overview_step_log2, s);
  return surface_setup(s);
}


}  // namespace terrain::cook
