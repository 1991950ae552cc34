#include "units/work_units.h"

#include "pyramid/overview_levels.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "frame/crs.h"
#include "inputs/height_units.h"
#include "pyramid/node_spool.h"
#include "inputs/source_raster.h"
#include "terrain/archive_writer.h"
#include "terrain/bc_decode.h"
#include "terrain/output_paths.h"
#include "terrain/surface_contract.h"

namespace terrain::cook {
namespace {

using json = nlohmann::ordered_json;

// ---- fingerprints ----
uint64_t fnv1a(std::string_view s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}
std::string hex64(uint64_t v) { return fmt::format("{:016x}", v); }

json rect_json(const SampleRect& r) { return json::array({r.c0, r.r0, r.c1, r.r1}); }
SampleRect rect_of(const json& j) { return {j.at(0).get<int>(), j.at(1).get<int>(), j.at(2).get<int>(), j.at(3).get<int>()}; }
bool meets(const SampleRect& a, const SampleRect& b) { return !a.empty() && !b.empty() && !intersect(a, b).empty(); }
// The plan's record of what each input gave (CookReport::input_samples): [path, read, used] each.
json input_samples_json(const std::vector<InputSamples>& v) {
  json a = json::array();
  for (const InputSamples& i : v) a.push_back(json::array({i.path, i.read, i.used}));
  return a;
}
std::vector<InputSamples> input_samples_of(const json& a) {
  std::vector<InputSamples> v;
  for (const json& i : a) v.push_back(InputSamples{i.at(0).get<std::string>(), i.at(1).get<uint64_t>(), i.at(2).get<uint64_t>()});
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

// ---- options: every field, so a unit on another machine cooks with the plan's ----
json options_json(const CookOptions& o) {
  json j;
  j["inputs"] = o.inputs;
  j["tolerance_m"] = o.tolerance_m;
  j["finest_level"] = o.finest_level;
  j["crs"] = o.crs;
  j["frame"] = o.frame;
  j["origin"] = o.origin ? json(*o.origin) : json(nullptr);
  j["spacing"] = o.spacing ? json(*o.spacing) : json(nullptr);
  j["height_scale"] = o.height_scale;
  j["height_offset"] = o.height_offset;
  if (o.height_scale_set) j["height_scale_set"] = true;  // absent: false (earlier plans kept)
  j["nodata_value"] = o.nodata_value ? json(*o.nodata_value) : json(nullptr);
  j["valid_range_m"] = o.valid_range_m;
  j["memory_limit_bytes"] = o.memory_limit_bytes;
  j["raw_size"] = o.raw_size;
  j["raw_type"] = o.raw_type;
  j["raw_big_endian"] = o.raw_big_endian;
  j["tile_encoding"] = o.tile_encoding;
  j["nodata"] = policy_name(o.nodata);
  j["fill_max_samples"] = o.fill_max_samples;
  j["materials"] = o.materials_path;
  j["surface_quality"] = int(o.surface_quality);
  if (o.bc_rdo > 0) j["bc_rdo"] = o.bc_rdo;
  if (o.error_checks == ErrorChecks::all) j["error_checks"] = "all";  // absent: sample (earlier plans kept)
  j["albedo"] = o.albedo_path;
  j["holes"] = o.holes_path;
  j["landcover"] = o.landcover_path;
  j["landcover_table"] = o.landcover_table_path;
  j["heights_only"] = o.heights_only;
  j["force"] = o.force;
  j["zstd_level"] = o.zstd_level;
  j["surface_zstd_level"] = o.surface_zstd_level;
  j["overview_levels"] = int(o.overview_levels);
  return j;
}

CookOptions options_of(const json& j) {
  CookOptions o;
  o.inputs = j.at("inputs").get<std::vector<std::string>>();
  o.tolerance_m = j.at("tolerance_m");
  o.finest_level = j.at("finest_level");
  o.crs = j.at("crs");
  o.frame = j.at("frame");
  if (!j.at("origin").is_null()) o.origin = j.at("origin").get<std::array<double, 2>>();
  if (!j.at("spacing").is_null()) o.spacing = j.at("spacing").get<std::array<double, 2>>();
  o.height_scale = j.at("height_scale");
  o.height_offset = j.at("height_offset");
  o.height_scale_set = j.value("height_scale_set", false);
  if (!j.at("nodata_value").is_null()) o.nodata_value = j.at("nodata_value").get<double>();
  o.valid_range_m = j.at("valid_range_m").get<std::array<double, 2>>();
  o.memory_limit_bytes = j.at("memory_limit_bytes");
  o.raw_size = j.at("raw_size").get<std::array<int, 2>>();
  o.raw_type = j.at("raw_type");
  o.raw_big_endian = j.at("raw_big_endian");
  o.tile_encoding = j.at("tile_encoding");
  const std::string nodata = j.at("nodata");
  o.nodata = nodata == "hole" ? NodataPolicy::hole : nodata == "fill" ? NodataPolicy::fill : NodataPolicy::automatic;
  o.fill_max_samples = j.at("fill_max_samples");
  o.materials_path = j.at("materials");
  o.surface_quality = SurfaceQuality(j.at("surface_quality").get<int>());
  o.bc_rdo = j.value("bc_rdo", 0.0f);
  o.error_checks = j.value("error_checks", std::string("sample")) == "all" ? ErrorChecks::all : ErrorChecks::sample;
  o.albedo_path = j.at("albedo");
  o.holes_path = j.at("holes");
  o.landcover_path = j.at("landcover");
  o.landcover_table_path = j.at("landcover_table");
  o.heights_only = j.at("heights_only");
  o.force = j.at("force");
  o.zstd_level = j.at("zstd_level");
  o.surface_zstd_level = j.at("surface_zstd_level");
  o.overview_levels = OverviewMode(j.value("overview_levels", 0));
  return o;
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

// ---- input files: fingerprints and footprints ----
// Size, mtime, inode and ctime of `f.path` into `f`.
bool stat_file(InputFile& f) {
  struct stat st {};
  if (::stat(f.path.c_str(), &st) != 0) return false;
  f.size = uint64_t(st.st_size);
  f.mtime_ns = int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
  f.inode = uint64_t(st.st_ino);
  f.ctime_ns = int64_t(st.st_ctim.tv_sec) * 1000000000 + st.st_ctim.tv_nsec;
  return true;
}
std::string file_fingerprint(const InputFile& f) {
  return hex64(fnv1a(fmt::format("{}\n{}\n{}\n{}\n{}", f.path, f.size, f.mtime_ns, f.inode, f.ctime_ns)));
}
// What differs between two stats of one file, for messages: "size 10 -> 12, ctime 5 -> 9".
std::string file_change(const InputFile& was, const InputFile& now) {
  std::string what;
  auto differ = [&](const char* name, auto a, auto b) {
    if (a != b) what += fmt::format("{}{} {} -> {}", what.empty() ? "" : ", ", name, a, b);
  };
  differ("size", was.size, now.size);
  differ("mtime", was.mtime_ns, now.mtime_ns);
  differ("inode", was.inode, now.inode);
  differ("ctime", was.ctime_ns, now.ctime_ns);
  if (was.ctime_ns != now.ctime_ns && was.size == now.size && was.mtime_ns == now.mtime_ns)
    what += ": rewritten or replaced keeping size and mtime (cp -p, rsync -t, tar), or its metadata changed";
  return what.empty() ? "its fingerprint" : what;
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

// The options' file paths as plan.json's "resolved_paths" holds them, and back.
json resolved_paths_json(const CookOptions& o) {
  return {{"inputs", o.inputs}, {"materials", o.materials_path}, {"albedo", o.albedo_path}, {"holes", o.holes_path},
          {"landcover", o.landcover_path}, {"landcover_table", o.landcover_table_path}};
}
CookOptions with_paths_of(CookOptions o, const json& j) {
  o.inputs = j.at("inputs").get<std::vector<std::string>>();
  o.materials_path = j.at("materials");
  o.albedo_path = j.at("albedo");
  o.holes_path = j.at("holes");
  o.landcover_path = j.at("landcover");
  o.landcover_table_path = j.at("landcover_table");
  return o;
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
      if (Status st = add(f.path, placed && f.opened ? footprint_of(f, header, whole) : whole); !st.ok()) return st;
  }
  for (const std::string* p : {&s.options.materials_path, &s.options.albedo_path, &s.options.holes_path,
                               &s.options.landcover_path, &s.options.landcover_table_path})
    if (!p->empty())
      if (Status st = add(*p, whole); !st.ok()) return st;
  return Status::success();
}

// The decisions every unit depends on, as text: their hash is the plan's fingerprint.
std::string decisions_text(const CookOptions& o, const FrameCrs& frame, const WorldInfo& w, int width, int height,
                           int finest, const std::array<uint8_t, kLevelCount>& steps) {
  json j;
  json opt = options_json(o);
  opt.erase("memory_limit_bytes");  // changes blocks, never bytes
  j["options"] = opt;
  j["source"] = {width, height};
  j["frame"] = frame_json(frame);
  j["grid"] = {w.origin_x_m, w.origin_y_m, w.roots_x, w.roots_y};
  j["finest_level"] = finest;
  j["steps"] = steps;
  if (!w.overview_step_log2.empty()) j["overview_steps"] = w.overview_step_log2;
  return j.dump();
}

// ---- unit files (format/SPEC.md "Work units") ----
constexpr char kUnitMagic[8] = {'T', 'C', 'U', 'N', 'I', 'T', '1', '\0'};
constexpr char kUnitEnd[4] = {'T', 'C', 'U', 'E'};
constexpr size_t kUnitHeader = 64, kUnitRecord = 48;

void put_u32(uint8_t* p, uint32_t v) { for (int i = 0; i < 4; ++i) p[i] = uint8_t(v >> (8 * i)); }
void put_u64(uint8_t* p, uint64_t v) { for (int i = 0; i < 8; ++i) p[i] = uint8_t(v >> (8 * i)); }
uint32_t get_u32(const uint8_t* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }
uint64_t get_u64(const uint8_t* p) { return uint64_t(get_u32(p)) | uint64_t(get_u32(p + 4)) << 32; }

// A unit table entry (SPEC 18): the node's record; payload offset and size are the caller's.
NodeRecord unit_record(const uint8_t* p) {
  NodeRecord r;
  r.key = {get_u32(p), get_u32(p + 4), get_u32(p + 8)};
  r.child_mask = p[12];
  r.flags = p[13];
  r.height_offset = int32_t(get_u32(p + 16));
  r.min_height = int32_t(get_u32(p + 20));
  r.max_height = int32_t(get_u32(p + 24));
  const uint32_t err = get_u32(p + 28);
  std::memcpy(&r.geometric_error_m, &err, 4);
  return r;
}

uint32_t crc_update(uint32_t crc, const uint8_t* p, size_t n) {
  uLong c = crc;
  while (n > 0) {
    const uInt k = n > (1u << 30) ? (1u << 30) : uInt(n);
    c = ::crc32(c, p, k);
    p += k;
    n -= k;
  }
  return uint32_t(c);
}

json error_json(const ErrorStats& e) { return {e.max_m, e.sum_sq, e.samples, e.uncovered}; }
ErrorStats error_of(const json& j) {
  ErrorStats e;
  e.max_m = j.at(0);
  e.sum_sq = j.at(1);
  e.samples = j.at(2);
  e.uncovered = j.at(3);
  return e;
}

json stats_json(const UnitStats& u) {
  const CookReport& r = u.part;
  json levels = json::array(), errors = json::array(), level_cpu = json::array();
  for (int l = 0; l < kLevelCount; ++l) {
    const LevelStats& ls = r.levels[size_t(l)];
    levels.push_back({ls.nodes, ls.vertices});
    errors.push_back(error_json(u.totals.level_error[size_t(l)]));
    level_cpu.push_back({{"stages", {ls.cpu_heights, ls.cpu_error, ls.cpu_surface, ls.cpu_encode}},
                         {"parts", ls.cpu_parts}});
  }
  const SurfaceTotals& t = r.surface;
  return {{"levels", levels},
          {"level_error", errors},
          {"leaf", error_json(u.totals.leaf)},
          {"cpu", {r.cpu_heights, r.cpu_error, r.cpu_surface, r.cpu_encode}},
          {"surface",
           {t.cpu_normals, t.cpu_albedo, t.cpu_splat, t.cpu_cones, t.normal_err_max_deg, t.normal_err_sum_deg,
            t.normal_samples, t.albedo_sq_err_sum, t.albedo_samples, t.albedo_hole_texels, t.albedo_alpha_mismatches,
            t.cone_exact_deg_sum, t.cone_encoded_deg_sum, t.cone_patches, t.cone_patches_never_cull}},
          {"cpu_parts", t.cpu_parts},  // absent in units of older tools: read as zeros
          {"level_cpu", level_cpu},    // ditto
          {"surface_nodes", {t.nodes, t.checked_nodes}},  // ditto
          {"void_fill_residual_m", r.void_fill_residual_m},
          {"window_samples", r.block_window_samples_max},
          {"input_bytes_read", r.input_bytes_read}};
}

// Adds one unit's stats to the cook's (the sums cook_block and the window reads make, in unit
// order): the bytes its inputs read to `r`, the rest to `totals`.
void add_stats(const json& j, PyramidTotals& totals, CookReport& r) {
  for (int l = 0; l < kLevelCount; ++l) {
    totals.levels[size_t(l)].nodes += j.at("levels").at(l).at(0).get<uint32_t>();
    totals.levels[size_t(l)].vertices += j.at("levels").at(l).at(1).get<uint64_t>();
    totals.level_error[size_t(l)].add(error_of(j.at("level_error").at(l)));
    if (j.contains("level_cpu")) {
      LevelStats& ls = totals.levels[size_t(l)];
      const json& c = j.at("level_cpu").at(l);
      const auto stages = c.at("stages").get<std::vector<double>>();
      ls.cpu_heights += stages.at(0);
      ls.cpu_error += stages.at(1);
      ls.cpu_surface += stages.at(2);
      ls.cpu_encode += stages.at(3);
      const auto parts = c.at("parts").get<std::vector<double>>();
      for (size_t k = 0; k < std::min(parts.size(), ls.cpu_parts.size()); ++k) ls.cpu_parts[k] += parts[k];
    }
  }
  totals.leaf.add(error_of(j.at("leaf")));
  const json& c = j.at("cpu");
  totals.cpu_heights += c.at(0).get<double>();
  totals.cpu_error += c.at(1).get<double>();
  totals.cpu_surface += c.at(2).get<double>();
  totals.cpu_encode += c.at(3).get<double>();
  const json& s = j.at("surface");
  SurfaceTotals& t = totals.surface;
  t.cpu_normals += s.at(0).get<double>();
  t.cpu_albedo += s.at(1).get<double>();
  t.cpu_splat += s.at(2).get<double>();
  t.cpu_cones += s.at(3).get<double>();
  t.normal_err_max_deg = std::max(t.normal_err_max_deg, s.at(4).get<double>());
  t.normal_err_sum_deg += s.at(5).get<double>();
  t.normal_samples += s.at(6).get<uint64_t>();
  t.albedo_sq_err_sum += s.at(7).get<double>();
  t.albedo_samples += s.at(8).get<uint64_t>();
  t.albedo_hole_texels += s.at(9).get<uint64_t>();
  t.albedo_alpha_mismatches += s.at(10).get<uint64_t>();
  t.cone_exact_deg_sum += s.at(11).get<double>();
  t.cone_encoded_deg_sum += s.at(12).get<double>();
  t.cone_patches += s.at(13).get<uint64_t>();
  t.cone_patches_never_cull += s.at(14).get<uint64_t>();
  if (j.contains("surface_nodes")) {
    t.nodes += j.at("surface_nodes").at(0).get<uint64_t>();
    t.checked_nodes += j.at("surface_nodes").at(1).get<uint64_t>();
  }
  if (j.contains("cpu_parts")) {
    const auto parts = j.at("cpu_parts").get<std::vector<double>>();
    for (size_t k = 0; k < std::min(parts.size(), t.cpu_parts.size()); ++k) t.cpu_parts[k] += parts[k];
  }
  totals.void_fill_residual_m = std::max(totals.void_fill_residual_m, j.at("void_fill_residual_m").get<double>());
  totals.window_samples_max = std::max(totals.window_samples_max, j.at("window_samples").get<uint64_t>());
  const auto bytes = j.at("input_bytes_read").get<std::vector<uint64_t>>();
  if (r.input_bytes_read.size() < bytes.size()) r.input_bytes_read.resize(bytes.size());
  for (size_t i = 0; i < bytes.size(); ++i) r.input_bytes_read[i] += bytes[i];
}

Status write_all(int fd, const uint8_t* p, size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t k = ::write(fd, p, n);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0)
      return Status::failure(Error::io_write, fmt::format("{}: {}", path, k < 0 ? std::strerror(errno) : "short write"));
    p += k;
    n -= size_t(k);
  }
  return Status::success();
}
// A file written piece by piece (through a 64 KB buffer) under a staged name, then renamed into
// place by commit(); with `durable`, fsynced first (else the caller syncs the folder's filesystem
// before anything names the file). Uncommitted, the staged file is removed.
class StagedText {
 public:
  explicit StagedText(const std::string& stage_for) : temp_(staging_path(stage_for)) {
    fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) st_ = Status::failure(Error::io_write, fmt::format("{}: {}", temp_, std::strerror(errno)));
    buf_.reserve(kBuffer);
  }
  ~StagedText() {
    if (fd_ >= 0) ::close(fd_);
    if (!committed_) ::unlink(temp_.c_str());
  }
  StagedText(const StagedText&) = delete;
  StagedText& operator=(const StagedText&) = delete;
  void put(std::string_view text) {
    buf_.append(text);
    if (buf_.size() >= kBuffer) flush();
  }
  Status commit(const std::string& path, bool durable) {
    flush();
    if (st_.ok() && durable && ::fsync(fd_) != 0)
      st_ = Status::failure(Error::io_write, fmt::format("{}: fsync: {}", temp_, std::strerror(errno)));
    if (fd_ >= 0 && ::close(fd_) != 0 && st_.ok())
      st_ = Status::failure(Error::io_write, fmt::format("{}: {}", temp_, std::strerror(errno)));
    fd_ = -1;
    if (st_.ok() && ::rename(temp_.c_str(), path.c_str()) != 0)
      st_ = Status::failure(Error::io_rename, fmt::format("{}: {}", path, std::strerror(errno)));
    committed_ = st_.ok();
    return st_;
  }

 private:
  static constexpr size_t kBuffer = size_t(1) << 16;
  void flush() {
    if (st_.ok() && !buf_.empty()) st_ = write_all(fd_, reinterpret_cast<const uint8_t*>(buf_.data()), buf_.size(), temp_);
    buf_.clear();
  }
  std::string temp_, buf_;
  int fd_ = -1;
  Status st_;
  bool committed_ = false;
};

// `text` under `path` through a staged name renamed into place (StagedText).
Status write_text_file(const std::string& path, const std::string& text, bool durable) {
  StagedText f(path);
  f.put(text);
  return f.commit(path, durable);
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

Status read_at(int fd, uint8_t* p, size_t n, uint64_t off, const std::string& path) {
  while (n > 0) {
    const ssize_t k = ::pread(fd, p, n, off_t(off));
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0)
      return Status::failure(Error::truncated, fmt::format("{}: {}", path, k < 0 ? std::strerror(errno) : "ends early"));
    p += k;
    n -= size_t(k);
    off += uint64_t(k);
  }
  return Status::success();
}

// A unit file's parts, checked: header, node table, stats and the payloads' extent.
struct UnitContents {
  std::string plan_fp, unit_fp;
  std::vector<std::pair<NodeRecord, uint64_t>> nodes;  // record (payload_offset relative), file offset
  json stats;
  uint64_t payload_start = 0, size = 0;
  uint32_t head_crc = 0;    // CRC-32 of the bytes before the payloads
  uint32_t stored_crc = 0;  // the trailer's, of every byte before it
};

// How much of a unit file read_unit checks. `full`: every byte against the CRC (a unit deciding
// whether it is done: a damaged file must be redone). `head`: everything but the payloads' CRC,
// which the caller computes from the bytes it reads anyway (the merge, while it copies them) or
// leaves to the unit and the merge (plan, keeping the units of an earlier plan).
enum class UnitCheck { head, full };

// Continues `crc` over bytes [from, to) of `fd`, streamed; false when unreadable.
bool crc_range(int fd, uint64_t from, uint64_t to, uint32_t& crc, const std::string& path) {
  std::vector<uint8_t> buf(size_t(std::min<uint64_t>(to - from, uint64_t(1) << 20)));
  for (uint64_t off = from; off < to;) {
    const size_t n = size_t(std::min<uint64_t>(buf.size(), to - off));
    if (!read_at(fd, buf.data(), n, off, path).ok()) return false;
    crc = crc_update(crc, buf.data(), n);
    off += n;
  }
  return true;
}

// Reads and checks a unit file: header, size, trailer, node table (in canonical order, payloads
// back to back), stats, fingerprint; with UnitCheck::full also the CRC of every byte. Whatever
// the mode, a file failing any check is reported as "checksum mismatch" when its CRC does not
// match (a damaged file is named as such, not by the field the damage hit). `why` on failure.
bool read_unit(const std::string& path, uint32_t index, const std::string& expected_unit_fp, UnitCheck check,
               UnitContents& out, std::string& why) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    why = errno == ENOENT ? "missing" : fmt::format("cannot open: {}", std::strerror(errno));
    return false;
  }
  struct Closer { int fd; ~Closer() { ::close(fd); } } closer{fd};
  struct stat st {};
  ::fstat(fd, &st);
  const uint64_t size = uint64_t(st.st_size);
  if (size < kUnitHeader + 8) {
    why = fmt::format("truncated ({} bytes)", size);
    return false;
  }
  uint8_t h[kUnitHeader];
  if (!read_at(fd, h, kUnitHeader, 0, path).ok() || std::memcmp(h, kUnitMagic, 8) != 0) {
    why = "not a unit file (bad magic)";
    return false;
  }
  if (get_u32(h + 8) != 1) {
    why = fmt::format("unit file version {} (this tool reads 1)", get_u32(h + 8));
    return false;
  }
  if (get_u32(h + 12) != index) {
    why = fmt::format("holds unit {}", get_u32(h + 12));
    return false;
  }
  out.plan_fp.assign(reinterpret_cast<const char*>(h + 16), 16);
  out.unit_fp.assign(reinterpret_cast<const char*>(h + 32), 16);
  const uint32_t count = get_u32(h + 48), stats_bytes = get_u32(h + 52);
  const uint64_t payload_bytes = get_u64(h + 56);
  const uint64_t expect = kUnitHeader + uint64_t(count) * kUnitRecord + stats_bytes + payload_bytes + 8;
  if (expect != size) {
    why = fmt::format("truncated or padded: {} bytes, its header says {}", size, expect);
    return false;
  }
  // Table and stats in one read; the CRC of everything before the payloads.
  const uint64_t payload_start = kUnitHeader + uint64_t(count) * kUnitRecord + stats_bytes;
  std::vector<uint8_t> head(size_t(payload_start - kUnitHeader));
  uint8_t tail[8];
  if (!read_at(fd, head.data(), head.size(), kUnitHeader, path).ok() || !read_at(fd, tail, 8, size - 8, path).ok()) {
    why = "unreadable";
    return false;
  }
  out.head_crc = crc_update(crc_update(0, h, kUnitHeader), head.data(), head.size());
  out.stored_crc = get_u32(tail);
  out.payload_start = payload_start;
  out.size = size;
  // The payloads' CRC, computed at most once, and only when needed.
  int damaged = -1;
  auto is_damaged = [&] {
    if (damaged < 0) {
      uint32_t crc = out.head_crc;
      damaged = !crc_range(fd, payload_start, size - 8, crc, path) || crc != out.stored_crc ? 1 : 0;
    }
    return damaged == 1;
  };
  auto fail = [&](std::string reason) {
    why = std::memcmp(tail + 4, kUnitEnd, 4) != 0 || is_damaged() ? "checksum mismatch (damaged or half-written)"
                                                                   : std::move(reason);
    return false;
  };
  if (std::memcmp(tail + 4, kUnitEnd, 4) != 0) return fail("");
  if (check == UnitCheck::full && is_damaged()) return fail("");
  if (out.unit_fp != expected_unit_fp)
    return fail(fmt::format("from another plan or stale inputs (unit fingerprint {}, the plan's {})", out.unit_fp,
                            expected_unit_fp));
  out.stats = json::parse(head.begin() + ptrdiff_t(count) * ptrdiff_t(kUnitRecord), head.end(), nullptr, false);
  if (out.stats.is_discarded()) return fail("bad stats");
  out.nodes.clear();
  out.nodes.reserve(count);
  uint64_t next = 0;  // payloads back to back, in table order
  for (uint32_t i = 0; i < count; ++i) {
    const uint8_t* p = &head[size_t(i) * kUnitRecord];
    NodeRecord r = unit_record(p);
    r.payload_offset = get_u64(p + 32);
    r.payload_size = get_u32(p + 40);
    if (r.payload_offset + r.payload_size > payload_bytes || r.key.level >= uint32_t(kLevelCount))
      return fail(fmt::format("node {} lies outside the unit's payloads", i));
    // The merge reads each unit's payloads in file order (one pass, its CRC computed as it copies).
    if (r.payload_offset != next || (i > 0 && !payload_order_less(out.nodes.back().first.key, r.key)))
      return fail(fmt::format("node {} is not in canonical order with its payload after the previous one's", i));
    next += r.payload_size;
    out.nodes.emplace_back(r, payload_start + r.payload_offset);
  }
  if (next != payload_bytes) return fail(fmt::format("the node payloads cover {} of {} payload bytes", next, payload_bytes));
  return true;
}

}  // namespace

std::string plan_file(const std::string& work_dir) { return work_dir + "/plan.json"; }
std::string units_dir(const std::string& work_dir) { return work_dir + "/units"; }
std::string inputs_file(const std::string& work_dir, const std::string& fingerprint) {
  return fmt::format("{}/inputs-{}.json", work_dir, fingerprint);
}
std::string unit_file(const std::string& work_dir, uint32_t index) {
  return fmt::format("{}/unit-{}.tcu", units_dir(work_dir), index);
}
std::string unit_vrt_file(const std::string& work_dir, const UnitPlan& unit) {
  return fmt::format("{}/unit-{}-{}.vrt", units_dir(work_dir), unit.index, unit.fingerprint);
}

std::string unit_inputs_file(const std::string& work_dir, const UnitPlan& unit) {
  return fmt::format("{}/unit-{}-{}.inputs.json", units_dir(work_dir), unit.index, unit.fingerprint);
}

Status write_unit_inputs(const CookSession& s, const PlanFile& plan, const std::string& work_dir) {
  // Each unit's own list of the files it reads (all of them are in the plan's inputs file).
  for (const UnitPlan& u : plan.units) {
    const std::string path = unit_inputs_file(work_dir, u);
    StagedText f(path);
    put_file_list(json{{"format", "terrain-cook-unit-inputs"}, {"unit", u.index}, {"fingerprint", u.fingerprint}},
                  unit_files(plan, u.index), [&](std::string_view t) { f.put(t); });
    if (Status st = f.commit(path, /*durable=*/false); !st.ok()) return st;
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
    if (Status st = write_vrt_windows(inputs[0].path, windows, outputs, written); !st.ok()) return st;
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
  if (Status st = collect_input_files(s, plan.files); !st.ok()) return st;
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
  j["options"] = options_json(s.options);  // paths as typed: the cook info keeps them
  j["resolved_paths"] = resolved_paths_json(resolved_options(s.options));  // what unit and merge open
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
  if (Status st = list.commit(inputs_path, /*durable=*/true); !st.ok()) return st;
  j["inputs"] = {{"count", plan.files.size()}, {"fingerprint", inputs_fingerprint}};
  const Raster& header = s.source.header();
  j["source"] = {{"width", header.width}, {"height", header.height}};
  j["frame"] = frame_json(s.frame);
  const WorldInfo& w = s.world;
  j["grid"] = {{"origin_x_m", w.origin_x_m}, {"origin_y_m", w.origin_y_m}, {"roots_x", w.roots_x},
               {"roots_y", w.roots_y}, {"extent", {w.extent_min_x_m, w.extent_min_y_m, w.extent_max_x_m, w.extent_max_y_m}},
               {"unit_roots", s.units.side}};
  j["finest_level"] = s.ctx.finest_level;
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
  if (Status st = write_text_file(path, j.dump(1) + "\n", /*durable=*/true); !st.ok()) return st;
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

// FNV-1a of a file's bytes, read in chunks; false when it cannot be read.
bool file_fnv1a(const std::string& path, uint64_t& h) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  h = fnv1a({});
  std::vector<char> chunk(1 << 16);
  while (f) {
    f.read(chunk.data(), std::streamsize(chunk.size()));
    h = fnv1a(std::string_view(chunk.data(), size_t(f.gcount())), h);
  }
  return !f.bad();
}

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
  if (Status st = parse_file_list(path, "terrain-cook-inputs", files); !st.ok()) return st;
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
  if (Status st = parse_file_list(path, "terrain-cook-unit-inputs", files); !st.ok()) return st;
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
    out.options = options_of(j.at("options"));
    out.resolved = with_paths_of(out.options, j.at("resolved_paths"));
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
    rep.tolerance_m = out.options.tolerance_m;
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
  json a = options_json(planned), b = options_json(given);
  a.erase("memory_limit_bytes");
  b.erase("memory_limit_bytes");
  return a == b;
}

bool work_dir_owns(const std::string& work_dir, const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path dir = fs::weakly_canonical(fs::absolute(work_dir, ec), ec);
  if (ec) return false;
  const fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) return false;
  const std::string name = p.filename().string();
  if (p.parent_path() == dir / "units") return true;
  return p.parent_path() == dir &&
         (name.starts_with("plan.json") || (name.starts_with("inputs") && name.find(".json") != std::string::npos));
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
  if (Status st = open_inputs(o, s, /*files_checked=*/true); !st.ok()) return st;
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
  if (Status st = frame_and_grid(s, &data.frame); !st.ok()) return st;
  if (s.world.origin_x_m != data.world.origin_x_m || s.world.origin_y_m != data.world.origin_y_m ||
      s.world.roots_x != data.world.roots_x || s.world.roots_y != data.world.roots_y)
    return Status::failure(Error::internal, "the plan's root grid does not follow from its inputs");
  s.ctx.step_log2 = data.steps;
  restore_overview_steps(data.world.overview_step_log2, s);
  return surface_setup(s);
}

Status write_unit(CookSession& s, const PlanFile& plan, uint32_t index, const std::string& work_dir) {
  const std::string path = unit_file(work_dir, index);
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path(), ec);
  // Host and pid in the staged name: the same unit re-run on another machine of a shared work dir
  // (a requeued array task) never writes into this one's file. What a killed run of a unit left is
  // removed by the next plan or merge (one listing of the units for all of them, not one per unit).
  const std::string temp = staging_path(path);
  NodeSpool spool;  // the unit's payloads as they come; the file gets them in canonical order
  if (Status st = spool.open(temp + ".payloads"); !st.ok()) return st;
  UnitStats stats;
  std::vector<uint64_t> read_before;
  for (const MosaicSource::InputStat& in : s.source.inputs()) read_before.push_back(in.bytes_read);
  const NodeSink sink = [&](NodeResult& r) { return spool.add(r.record, r.payload); };
  if (Status st = cook_unit_of_session(s, index, sink, stats.totals); !st.ok()) return st;
  report_blocks(s, stats.totals, stats.part);
  for (size_t i = 0; i < s.source.inputs().size(); ++i)
    stats.part.input_bytes_read.push_back(s.source.inputs()[i].bytes_read - (i < read_before.size() ? read_before[i] : 0));
  // The spool's entries in canonical order, their payloads copied behind the table.
  std::vector<NodeSpool::Entry> entries = spool.sorted_entries();
  const std::string stats_text = stats_json(stats).dump();
  uint64_t payload_bytes = 0;
  for (const auto& e : entries) payload_bytes += e.size;
  std::vector<uint8_t> head(kUnitHeader + entries.size() * kUnitRecord, 0);
  std::memcpy(head.data(), kUnitMagic, 8);
  put_u32(&head[8], 1);
  put_u32(&head[12], index);
  std::memcpy(&head[16], plan.fingerprint.data(), 16);
  std::memcpy(&head[32], plan.units[index].fingerprint.data(), 16);
  put_u32(&head[48], uint32_t(entries.size()));
  put_u32(&head[52], uint32_t(stats_text.size()));
  put_u64(&head[56], payload_bytes);
  uint64_t off = 0;
  for (size_t i = 0; i < entries.size(); ++i) {
    uint8_t* p = &head[kUnitHeader + i * kUnitRecord];
    const NodeRecord& r = entries[i].record;
    put_u32(p, r.key.level);
    put_u32(p + 4, r.key.x);
    put_u32(p + 8, r.key.y);
    p[12] = r.child_mask;
    p[13] = r.flags;
    put_u32(p + 16, uint32_t(r.height_offset));
    put_u32(p + 20, uint32_t(r.min_height));
    put_u32(p + 24, uint32_t(r.max_height));
    uint32_t err = 0;
    std::memcpy(&err, &r.geometric_error_m, 4);
    put_u32(p + 28, err);
    put_u64(p + 32, off);
    put_u32(p + 40, entries[i].size);
    off += entries[i].size;
  }
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status::failure(Error::io_write, fmt::format("{}: {}", temp, std::strerror(errno)));
  uint32_t crc = crc_update(0, head.data(), head.size());
  crc = crc_update(crc, reinterpret_cast<const uint8_t*>(stats_text.data()), stats_text.size());
  Status st = write_all(fd, head.data(), head.size(), temp);
  if (st.ok()) st = write_all(fd, reinterpret_cast<const uint8_t*>(stats_text.data()), stats_text.size(), temp);
  std::vector<uint8_t> buf;
  for (size_t i = 0; st.ok() && i < entries.size(); ++i) {
    st = spool.read(entries[i], buf);
    if (st.ok()) {
      crc = crc_update(crc, buf.data(), buf.size());
      st = write_all(fd, buf.data(), buf.size(), temp);
    }
  }
  uint8_t tail[8];
  put_u32(tail, crc);
  std::memcpy(tail + 4, kUnitEnd, 4);
  if (st.ok()) st = write_all(fd, tail, 8, temp);
  if (st.ok() && ::fsync(fd) != 0) st = Status::failure(Error::io_write, fmt::format("{}: fsync: {}", temp, std::strerror(errno)));
  ::close(fd);
  if (st.ok() && ::rename(temp.c_str(), path.c_str()) != 0)
    st = Status::failure(Error::io_rename, fmt::format("{}: {}", path, std::strerror(errno)));
  if (!st.ok()) ::unlink(temp.c_str());
  return st;
}

bool unit_file_valid(const std::string& work_dir, const PlanFile& plan, uint32_t index, std::string& why) {
  UnitContents c;
  return read_unit(unit_file(work_dir, index), index, plan.units[index].fingerprint, UnitCheck::full, c, why);
}

bool unit_file_usable(const std::string& work_dir, const PlanFile& plan, uint32_t index, std::string& why) {
  UnitContents c;
  return read_unit(unit_file(work_dir, index), index, plan.units[index].fingerprint, UnitCheck::head, c, why);
}

namespace {

// A unit's place in the merge, from its checked head: what the copy needs, not its node table.
struct MergeUnit {
  uint32_t crc = 0, stored_crc = 0;  // running CRC-32 of the bytes copied so far, the trailer's
  uint64_t nodes = 0, left = 0;      // nodes in the file, nodes not copied yet
  std::array<uint64_t, kLevelCount> level_begin{};    // table index of each level's first node
  std::array<uint64_t, kLevelCount> level_nodes{};    // and its node count
  std::array<uint64_t, kLevelCount> level_payload{};  // file offset of each level's first payload
  std::array<uint64_t, kLevelCount> level_bytes{};    // and its payload bytes
};

// A read buffer kept across the bands and levels of a merge (fresh megabytes per cursor cost page
// faults: more system time than the copy itself).
struct ReadBuffer {
  std::unique_ptr<uint8_t[]> data;  // uninitialised: zeroing it per refill would cost as much
  size_t capacity = 0;
};

// Reads one unit's nodes of one level in table order, table and payloads in large sequential reads.
class LevelCursor {
 public:
  LevelCursor(int fd, const std::string& path, const MergeUnit& u, int level, size_t chunk, ReadBuffer& buf)
      : fd_(fd), path_(path), buf_(buf), next_(u.level_begin[size_t(level)]),
        end_(u.level_begin[size_t(level)] + u.level_nodes[size_t(level)]),
        payload_at_(u.level_payload[size_t(level)]),
        payload_end_(u.level_payload[size_t(level)] + u.level_bytes[size_t(level)]), chunk_(chunk) {}
  bool done() const { return next_ == end_; }
  // The next node's record (its payload_offset: the file offset of its payload).
  Status peek(NodeRecord& r) {
    if (table_i_ == table_n_) {
      const uint64_t n = std::min<uint64_t>(end_ - next_, kTableChunk);
      table_.resize(size_t(n) * kUnitRecord);
      if (Status st = read_at(fd_, table_.data(), table_.size(), kUnitHeader + next_ * kUnitRecord, path_); !st.ok()) return st;
      table_i_ = 0;
      table_n_ = n;
    }
    const uint8_t* p = &table_[size_t(table_i_) * kUnitRecord];
    r = unit_record(p);
    r.payload_size = get_u32(p + 40);
    r.payload_offset = payload_at_;
    return Status::success();
  }
  // The payload of the node peek() returned; then moves to the next node.
  Status take(uint32_t size, std::span<const uint8_t>& payload) {
    if (payload_at_ < buf_at_ || payload_at_ + size > buf_at_ + buf_size_) {
      // Refill from this payload on: `chunk_` bytes, never past the level's payloads.
      const size_t want = size_t(std::max<uint64_t>(size, std::min<uint64_t>(chunk_, payload_end_ - payload_at_)));
      if (want > buf_.capacity) {
        buf_.data.reset(new uint8_t[want]);
        buf_.capacity = want;
      }
      buf_at_ = payload_at_;
      buf_size_ = 0;
      while (buf_size_ < size) {  // at least this payload; what follows is a bonus
        const ssize_t k = ::pread(fd_, buf_.data.get() + buf_size_, want - buf_size_, off_t(buf_at_ + buf_size_));
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return Status::failure(Error::truncated, fmt::format("{}: {}", path_, k < 0 ? std::strerror(errno) : "ends early"));
        buf_size_ += size_t(k);
      }
    }
    payload = {buf_.data.get() + size_t(payload_at_ - buf_at_), size};
    payload_at_ += size;
    ++next_;
    ++table_i_;
    return Status::success();
  }

 private:
  static constexpr uint64_t kTableChunk = 1024;
  int fd_;
  const std::string& path_;
  ReadBuffer& buf_;
  uint64_t next_, end_, payload_at_, payload_end_;
  size_t chunk_;
  std::vector<uint8_t> table_;
  uint64_t table_i_ = 0, table_n_ = 0;
  size_t buf_size_ = 0;
  uint64_t buf_at_ = 0;
};

// The heights units share along their edges (format.h: a shared vertex has one canonical value),
// checked as the merge copies the nodes: what terrain-inspect --verify checks between west and
// south neighbours, for the pairs of nodes that lie in different units (a unit's own nodes were
// cooked in one session). Only nodes on a unit's edge are decoded (their heights, and their albedo
// when they have holes). Held: the east column of the current row's edge nodes and the north row of
// a band's top row of nodes, one level at a time (129 values per node: a row of nodes across the
// world at most).
class EdgeCheck {
 public:
  EdgeCheck(const PlanFile& plan, const std::array<uint8_t, kLevelCount>& steps) : steps_(steps) {
    for (const UnitPlan& u : plan.units) {
      grid_x1_ = std::max(grid_x1_, u.roots.x1);
      grid_y1_ = std::max(grid_y1_, u.roots.y1);
    }
  }
  void start_level() {
    east_.clear();
    north_.clear();
  }
  // Node `r` of unit `u` (the nodes of a level in the merge's order: bands south to north, rows
  // south to north, units west to east). `problem` gets a message when an edge disagrees;
  // a failure status when the payload cannot be decoded.
  Status node(const NodeRecord& r, std::span<const uint8_t> payload, const UnitPlan& u, std::string& problem) {
    const int level = int(r.key.level);
    const int up = kRootLevel - level;
    const uint32_t x0 = u.roots.x0 << up, x1 = u.roots.x1 << up, y0 = u.roots.y0 << up, y1 = u.roots.y1 << up;
    if (r.key.y != row_) {  // a new row: the east columns of the last one met their neighbours
      east_.clear();
      row_ = r.key.y;
    }
    const bool west = r.key.x == x0 && u.roots.x0 > 0, south = r.key.y == y0 && u.roots.y0 > 0;
    const bool east = r.key.x + 1 == x1 && u.roots.x1 < grid_x1_, north = r.key.y + 1 == y1 && u.roots.y1 < grid_y1_;
    if (!west && !south && !east && !north) return Status::success();
    const auto west_of = west ? east_.find(r.key.x - 1) : east_.end();
    auto south_of = south ? north_.find(r.key.x) : north_.end();
    if (south_of != north_.end() && south_of->second.y + 1 != r.key.y) south_of = north_.end();  // not adjacent
    if (west_of == east_.end() && south_of == north_.end() && !east && !north) return Status::success();
    const bool holes = (r.flags & kNodeFlagHasHoles) != 0;
    if (Status st = decode_node_payload(payload, kSectionHeights | (holes ? kSectionAlbedo : 0u), data_); !st.ok())
      return st;
    if (holes) decode_hole_mask(data_, mask_.data());
    const int step = steps_[size_t(level)];
    auto at = [&](int i, int j) {  // vertex (i, j): its units, or kHole
      const size_t k = size_t(j * kHeightSamples + i);
      return holes && mask_[k] ? kHole : vertex_units(r.height_offset, data_.heights[k], step);
    };
    auto compare = [&](const Edge& other, bool column, const char* side, uint32_t ox, uint32_t oy) {
      for (int k = 0; k < kHeightSamples && problem.empty(); ++k) {
        const int32_t mine = column ? at(0, k) : at(k, 0);
        if (mine == kHole || other[size_t(k)] == kHole || mine == other[size_t(k)]) continue;
        problem = fmt::format("node {} vertex ({}, {}) = {} units but its {} neighbour {} (another unit) stores {} at "
                              "the same point", node_name(r.key), column ? 0 : k, column ? k : 0, mine, side,
                              node_name({r.key.level, ox, oy}), other[size_t(k)]);
      }
    };
    if (west_of != east_.end()) compare(west_of->second, true, "west", r.key.x - 1, r.key.y);
    if (south_of != north_.end()) compare(south_of->second.edge, false, "south", r.key.x, r.key.y - 1);
    if (south_of != north_.end()) north_.erase(south_of);
    if (east) {
      Edge& e = east_[r.key.x];
      for (int k = 0; k < kHeightSamples; ++k) e[size_t(k)] = at(kQuadsPerSide, k);
    }
    if (north) {
      RowEdge& e = north_[r.key.x];
      e.y = r.key.y;
      for (int k = 0; k < kHeightSamples; ++k) e.edge[size_t(k)] = at(k, kQuadsPerSide);
    }
    return Status::success();
  }

 private:
  static constexpr int32_t kHole = INT32_MIN;
  using Edge = std::array<int32_t, kHeightSamples>;
  const std::array<uint8_t, kLevelCount>& steps_;
  uint32_t grid_x1_ = 0, grid_y1_ = 0;
  uint32_t row_ = UINT32_MAX;
  struct RowEdge {
    uint32_t y = 0;
    Edge edge{};
  };
  std::map<uint32_t, Edge> east_;       // by node x: the east columns of the current row's nodes
  std::map<uint32_t, RowEdge> north_;  // by node x: the north rows of the bands' top rows (the last per x)
  std::unique_ptr<NodeData> holder_ = std::make_unique<NodeData>();
  NodeData& data_ = *holder_;
  std::array<uint8_t, kHeightCount> mask_{};
};

}  // namespace

Status merge_unit_files(const std::string& work_dir, const PlanFile& plan, const std::array<uint8_t, kLevelCount>& steps,
                        const std::string& output, ArchiveWriter& writer, PyramidTotals& totals, CookReport& report,
                        const ProgressFn& progress, const std::function<Status(ArchiveShape&)>& extend_shape) {
  // Two passes, memory independent of the archive's size. First every unit's head (header,
  // table, stats) is checked, one unit at a time: what the archive will hold per level, and per
  // unit where each level starts. Then the payloads are copied in the archive's order: a level at
  // a time, the units of one band of roots (the plan's units in a row) side by side, row by row
  // of nodes; each unit is read front to back once, its CRC checked as it is copied (the payload
  // CRC the writer computes anyway, combined into the unit's). The writer is ordered: it writes
  // each directory entry in place. A unit failing a check fails the merge, and the archive is only
  // renamed into place by finish(), so nothing is merged.
  auto bad_unit = [&](uint32_t unit, const std::string& why) {
    return Status::failure(Error::no_data, fmt::format("unit {} ({}): {}; nothing merged (run `terrain-cook unit {} {}`)",
                                                       unit, unit_file(work_dir, unit), why, work_dir, unit));
  };
  const std::string damaged = "checksum mismatch (damaged or half-written)";
  remove_stale_staging_in(units_dir(work_dir));  // staged files of unit runs killed on this host
  std::vector<MergeUnit> units(plan.units.size());
  ArchiveShape shape;
  for (const UnitPlan& u : plan.units) {
    UnitContents c;
    std::string why;
    if (!read_unit(unit_file(work_dir, u.index), u.index, u.fingerprint, UnitCheck::head, c, why))
      return bad_unit(u.index, why);
    MergeUnit& m = units[u.index];
    m.crc = c.head_crc;
    m.stored_crc = c.stored_crc;
    m.nodes = m.left = c.nodes.size();
    if (c.nodes.empty() && c.head_crc != c.stored_crc) return bad_unit(u.index, damaged);
    // Levels in the table: 5 first (canonical order); each node inside the unit's roots, so the
    // band of the unit is where the merge looks for it.
    std::array<uint64_t, kLevelCount> count{};
    for (const auto& [r, off] : c.nodes) {
      const int up = kRootLevel - int(r.key.level);
      const uint32_t rx = r.key.x >> up, ry = r.key.y >> up;
      if (rx < u.roots.x0 || rx >= u.roots.x1 || ry < u.roots.y0 || ry >= u.roots.y1) {
        uint32_t crc = c.head_crc;
        const int fd = ::open(unit_file(work_dir, u.index).c_str(), O_RDONLY | O_CLOEXEC);
        const bool whole = fd >= 0 && crc_range(fd, c.payload_start, c.size - 8, crc, unit_file(work_dir, u.index));
        if (fd >= 0) ::close(fd);
        return bad_unit(u.index, !whole || crc != c.stored_crc ? damaged : fmt::format("node {} lies outside its roots", node_name(r.key)));
      }
      ++count[r.key.level];
    }
    uint64_t index = 0, at = c.payload_start;
    for (int l = kRootLevel; l >= 0; --l) {
      m.level_begin[size_t(l)] = index;
      m.level_payload[size_t(l)] = at;
      for (uint64_t k = 0; k < count[size_t(l)]; ++k) at += c.nodes[size_t(index + k)].first.payload_size;
      m.level_bytes[size_t(l)] = at - m.level_payload[size_t(l)];
      index += count[size_t(l)];
      shape.level_nodes[size_t(l)] += count[size_t(l)];
    }
    m.level_nodes = count;
    shape.payload_bytes += at - c.payload_start;
    try {
      add_stats(c.stats, totals, report);
    } catch (const std::exception& e) {
      return Status::failure(Error::invalid_argument, fmt::format("unit {}: bad stats ({})", u.index, e.what()));
    }
    if (progress && !progress(0.05 * double(u.index + 1) / double(plan.units.size()), "checking units"))
      return Status::failure(Error::cancelled, "cancelled");
  }
  // Bands: the units of one row of the plan's blocks, west to east.
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> bands;
  for (const UnitPlan& u : plan.units) bands[{u.roots.y0, u.roots.y1}].push_back(u.index);
  uint32_t band_end = 0;
  for (auto& [rows, list] : bands) {
    if (rows.first < band_end) return Status::failure(Error::internal, "the plan's units overlap");
    band_end = rows.second;
    std::sort(list.begin(), list.end(), [&](uint32_t a, uint32_t b) { return plan.units[a].roots.x0 < plan.units[b].roots.x0; });
  }
  uint64_t total = 0, copied = 0;
  for (uint64_t n : shape.level_nodes) total += n;
  if (extend_shape)
    if (Status st = extend_shape(shape); !st.ok()) return st;
  if (Status st = writer.open_ordered(output, shape); !st.ok()) return st;
  size_t widest = 0;
  for (const auto& [rows, list] : bands) widest = std::max(widest, list.size());
  std::vector<ReadBuffer> buffers(widest);
  EdgeCheck edges(plan, steps);
  for (int level = kRootLevel; level >= 0; --level) {
    const int up = kRootLevel - level;
    edges.start_level();
    for (const auto& [rows, list] : bands) {
      // The band's files, each with a share of a 4 MB read budget (64-256 KB each: larger reads
      // gained nothing measurable, their fresh pages cost page faults).
      const size_t chunk = std::clamp<size_t>((size_t(4) << 20) / list.size(), size_t(64) << 10, size_t(256) << 10);
      std::vector<std::string> paths;
      std::vector<int> fds;
      std::vector<LevelCursor> cursors;
      paths.reserve(list.size());
      cursors.reserve(list.size());
      struct Closer {
        std::vector<int>& fds;
        ~Closer() { for (int fd : fds) ::close(fd); }
      } closer{fds};
      for (uint32_t unit : list) {
        paths.push_back(unit_file(work_dir, unit));
        const int fd = ::open(paths.back().c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) return bad_unit(unit, fmt::format("cannot open: {}", std::strerror(errno)));
        fds.push_back(fd);
        cursors.emplace_back(fd, paths.back(), units[unit], level, chunk, buffers[cursors.size()]);
      }
      const uint32_t row_end = rows.second << up;
      for (uint32_t row = rows.first << up; row < row_end; ++row)
        for (size_t k = 0; k < list.size(); ++k) {
          const uint32_t unit = list[k];
          LevelCursor& cur = cursors[k];
          MergeUnit& u = units[unit];
          NodeRecord r;
          while (!cur.done()) {
            if (Status st = cur.peek(r); !st.ok()) return bad_unit(unit, st.message);
            if (r.key.y != row) break;
            const uint64_t at = r.payload_offset;
            std::span<const uint8_t> payload;
            if (Status st = cur.take(r.payload_size, payload); !st.ok()) return bad_unit(unit, st.message);
            // A payload refused (by the writer, or undecodable on a unit's edge): name the unit, as
            // damaged when its CRC says so.
            auto is_damaged = [&] {
              uint32_t whole_crc = uint32_t(::crc32(u.crc, payload.data(), uInt(payload.size())));
              struct stat fs {};
              const bool whole = ::fstat(fds[k], &fs) == 0 &&
                                 crc_range(fds[k], at + r.payload_size, uint64_t(fs.st_size) - 8, whole_crc, paths[k]);
              return !whole || whole_crc != u.stored_crc;
            };
            auto refused = [&](const std::string& why) {
              writer.abort();
              return bad_unit(unit, is_damaged() ? damaged : why);
            };
            uint32_t crc = 0;
            if (Status st = writer.add_node(r, payload, &crc); !st.ok()) return refused(st.message);
            std::string disagree;
            if (Status st = edges.node(r, payload, plan.units[unit], disagree); !st.ok()) return refused(st.message);
            if (!disagree.empty()) {
              writer.abort();
              if (is_damaged()) return bad_unit(unit, damaged);
              return Status::failure(
                  Error::no_data,
                  fmt::format("unit {} ({}): {}: the units disagree along their shared edge (cooked from inputs that "
                              "differ, which their fingerprints did not show); nothing merged (run `terrain-cook plan` "
                              "again, remove the unit files of both units and cook them again)",
                              unit, unit_file(work_dir, unit), disagree));
            }
            u.crc = uint32_t(::crc32_combine(u.crc, crc, z_off_t(r.payload_size)));
            if (--u.left == 0 && u.crc != u.stored_crc) return bad_unit(unit, damaged);
            if (progress && ++copied % 4096 == 0 &&
                !progress(0.05 + 0.95 * double(copied) / double(std::max<uint64_t>(total, 1)), "merging"))
              return Status::failure(Error::cancelled, "cancelled");
          }
        }
      for (size_t k = 0; k < list.size(); ++k)
        if (!cursors[k].done()) return bad_unit(list[k], "its table is not in canonical order");
    }
  }
  return Status::success();
}

// ---- overview levels (overview_levels.h): the roots of the unit files ----
Status unit_roots(const std::string& work_dir, const PlanFile& plan, RootSource& out) {
  struct Where {
    uint32_t unit;
    uint64_t offset;
    uint32_t size;
  };
  auto where = std::make_shared<std::vector<Where>>();
  out = RootSource{};
  for (const UnitPlan& u : plan.units) {
    UnitContents c;
    std::string why;
    if (!read_unit(unit_file(work_dir, u.index), u.index, u.fingerprint, UnitCheck::head, c, why))
      return Status::failure(Error::no_data, fmt::format("unit {}: {}", u.index, why));
    for (const auto& [r, off] : c.nodes)
      if (r.key.level == uint32_t(kRootLevel)) {
        out.roots.push_back(r);
        where->push_back({u.index, off, r.payload_size});
      }
  }
  out.read = [work_dir, where](size_t i, std::vector<uint8_t>& bytes) {
    const Where& w = (*where)[i];
    const std::string path = unit_file(work_dir, w.unit);
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return Status::failure(Error::io_open, fmt::format("{}: {}", path, std::strerror(errno)));
    bytes.resize(w.size);
    Status st = read_at(fd, bytes.data(), bytes.size(), w.offset, path);
    ::close(fd);
    return st;
  };
  return Status::success();
}

}  // namespace terrain::cook
