#include "inspect.h"
#include "image_write.h"
#include "inspect_lonlat.h"

#include <GeographicLib/TransverseMercator.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "terrain/archive_layout.h"
#include "terrain/bc_decode.h"
#include "cli_checks.h"
#include "terrain/sample.h"

namespace terrain::inspect {
namespace {

const char* kind_name(ProjectionKind k) {
  switch (k) {
    case ProjectionKind::local: return "local";
    case ProjectionKind::transverse_mercator: return "transverse_mercator";
    case ProjectionKind::proj: return "proj";
  }
  return "unknown";
}

std::string key_text(const NodeKey& k) { return fmt::format("{}/{}/{}", k.level, k.x, k.y); }

uint64_t level_stored_bytes(const SectionBytes& b, int l) {
  uint64_t sum = 0;
  for (size_t s = 0; s < layout::kSectionCount; ++s) sum += b.stored_by_level[l][s];
  return sum;
}

// Stored bytes per km2 of the area the level's nodes cover (levels are sparse: not per km2 of the world).
double level_bytes_per_km2(const SectionBytes& b, int l) {
  const double km2 = double(b.nodes_by_level[l]) * node_size_m(l) * node_size_m(l) * 1e-6;
  return km2 > 0 ? double(level_stored_bytes(b, l)) / km2 : 0.0;
}

// The valid source samples the cooker recorded in the cook info (0 when absent: other writers,
// earlier cooks), the denominator of the cook report's bytes per source sample.
uint64_t source_valid_samples(const WorldInfo& w) {
  if (w.cook_info_json.empty()) return 0;
  const nlohmann::json j = nlohmann::json::parse(w.cook_info_json, nullptr, false);
  if (!j.is_object()) return 0;
  const auto it = j.find("source_valid_samples");
  return it != j.end() && it->is_number_unsigned() ? it->get<uint64_t>() : 0;
}

// Per input the cooker recorded: its path and the unit of its heights with the factor applied to
// its values (cook info inputs[].heights: unit, declared_by, unit_m, scale, scale_from); empty when
// absent (other writers, earlier cooks).
std::vector<std::pair<std::string, nlohmann::json>> input_height_units(const WorldInfo& w) {
  std::vector<std::pair<std::string, nlohmann::json>> out;
  if (w.cook_info_json.empty()) return out;
  const nlohmann::json j = nlohmann::json::parse(w.cook_info_json, nullptr, false);
  if (!j.is_object() || !j.contains("inputs") || !j["inputs"].is_array()) return out;
  for (const nlohmann::json& in : j["inputs"])
    if (in.is_object() && in.contains("heights") && in["heights"].is_object() && in["heights"].value("scale", 0.0) != 0.0)
      out.emplace_back(in.value("path", ""), in["heights"]);
  return out;
}

struct Facts {
  SectionBytes sections;
  std::vector<uint32_t> per_level;  // levels 0 .. top (overview levels included, SPEC 19)
  std::array<float, kMaxLevels> max_error{};
  int32_t min_units = 0, max_units = 0;
  bool any = false;
};

Status gather(const ArchiveReader& reader, Facts& f) {
  TERRAIN_TRY(reader.section_bytes(f.sections));
  f.per_level = reader.nodes_per_level();
  for (const NodeRecord& r : reader.nodes()) {
    f.max_error[r.key.level] = std::max(f.max_error[r.key.level], r.geometric_error_m);
    if (!f.any || r.min_height < f.min_units) f.min_units = r.min_height;
    if (!f.any || r.max_height > f.max_units) f.max_units = r.max_height;
    f.any = true;
  }
  return Status::success();
}

}  // namespace

Status summary_text(const ArchiveReader& reader, const std::string& path, std::string& out) {
  Facts f;
  TERRAIN_TRY(gather(reader, f));
  const WorldInfo& w = reader.world();
  std::ostringstream o;
  o << fmt::format("{}: terrain archive v{}, {} bytes, {} nodes", path, reader.format_version(), reader.file_size(),
                   reader.nodes().size());
  if (reader.directory_pages()) o << fmt::format(" in {} directory pages", reader.directory_pages());
  o << "\n";
  const FrameCrs& c = w.crs;
  o << fmt::format("frame      {} \"{}\"", kind_name(c.kind), c.name);
  if (c.epsg) o << fmt::format(" EPSG:{}", c.epsg);
  o << "\n";
  if (c.kind == ProjectionKind::transverse_mercator)
    o << fmt::format("           ellipsoid a={} m 1/f={}; lat0={} lon0={} k0={} FE={} m FN={} m\n", c.semi_major_m,
                     c.inverse_flattening, c.lat0_deg, c.lon0_deg, c.scale_k0, c.false_easting_m, c.false_northing_m);
  o << fmt::format("origin     ({:.3f}, {:.3f}) m, {} x {} roots of {} m\n", w.origin_x_m, w.origin_y_m, w.roots_x, w.roots_y,
                   node_size_m(kRootLevel));
  o << fmt::format("extent     x {:.3f} .. {:.3f}, y {:.3f} .. {:.3f} ({:.3f} x {:.3f} km)\n", w.extent_min_x_m, w.extent_max_x_m,
                   w.extent_min_y_m, w.extent_max_y_m, (w.extent_max_x_m - w.extent_min_x_m) / 1000,
                   (w.extent_max_y_m - w.extent_min_y_m) / 1000);
  const uint64_t samples = source_valid_samples(w);
  const auto per_sample = [&](uint64_t bytes) {
    return samples ? fmt::format("{:>16.4f}", double(bytes) / double(samples)) : fmt::format("{:>16}", "-");
  };
  o << "levels     level  node_m  spacing_m  step_mm   nodes  max_error_m  stored_bytes  bytes_per_km2  bytes_per_sample\n";
  for (int l = level_count(w) - 1; l >= 0; --l)
    o << fmt::format("           {:>5}  {:>6.0f}  {:>9.4f}  {:>7.3f}  {:>6}  {:>11.4f}  {:>12}  {:>13.0f}{}{}\n", l, node_size_m(l),
                     vertex_spacing_m(l), 1000.0 * double(1 << level_step_log2(w, l)) * kHeightUnitM, f.per_level[size_t(l)],
                     f.max_error[size_t(l)], level_stored_bytes(f.sections, l), level_bytes_per_km2(f.sections, l),
                     per_sample(level_stored_bytes(f.sections, l)), l > kRootLevel ? "  overview" : "");
  o << fmt::format("           bytes_per_sample: stored bytes per valid source sample ({})\n",
                   samples ? fmt::format("{} samples", samples) : std::string("not recorded by the writer"));
  if (level_count(w) > kLevelCount)
    o << fmt::format("overview   {} levels above the roots (6..{}), top level {} holds {} nodes\n", level_count(w) - kLevelCount,
                     top_level(w), top_level(w), f.per_level[size_t(top_level(w))]);
  if (f.any)
    o << fmt::format("heights    {:.3f} .. {:.3f} m\n", units_to_metres(f.min_units), units_to_metres(f.max_units));
  for (const auto& [input, h] : input_height_units(w)) {
    const std::string unit = h.value("unit", "");
    o << fmt::format("           input {}: values x {:.10g} to metres ({}{})\n", input, h.value("scale", 0.0),
                     unit.empty() ? "no unit declared" : fmt::format("'{}', {}", unit, h.value("declared_by", "")),
                     h.value("scale_from", "") == "--height-scale" ? "; --height-scale" : "");
  }
  o << "sections   section     stored_bytes      raw_bytes  ratio\n";
  uint64_t st = 0, rw = 0;
  for (size_t s = 0; s < layout::kSectionCount; ++s) {
    st += f.sections.stored[s];
    rw += f.sections.raw[s];
    o << fmt::format("           {:<8} {:>15} {:>14} {:>6.2f}\n", layout::kSectionName[s], f.sections.stored[s], f.sections.raw[s],
                     f.sections.stored[s] ? double(f.sections.raw[s]) / double(f.sections.stored[s]) : 0.0);
  }
  o << fmt::format("           {:<8} {:>15} {:>14} {:>6.2f}\n", "all", st, rw, st ? double(rw) / double(st) : 0.0);
  o << fmt::format("palette    {} materials", w.palette.size());
  for (size_t i = 0; i < w.palette.size(); ++i) o << (i ? ", " : ": ") << i << "=" << w.palette[i].name;
  o << "\n";
  if (!w.cook_info_json.empty()) o << "cook info  " << w.cook_info_json << "\n";
  out = o.str();
  return Status::success();
}

Status summary_json(const ArchiveReader& reader, const std::string& path, std::string& out) {
  Facts f;
  TERRAIN_TRY(gather(reader, f));
  const WorldInfo& w = reader.world();
  using nlohmann::json;
  json j;
  j["file"] = path;
  j["format_version"] = reader.format_version();
  j["file_bytes"] = reader.file_size();
  j["nodes"] = reader.nodes().size();
  j["directory_pages"] = reader.directory_pages();  // SPEC 20; 0 in versions 1 and 2
  const FrameCrs& c = w.crs;
  j["frame"] = {{"kind", kind_name(c.kind)}, {"epsg", c.epsg}, {"name", c.name}, {"semi_major_m", c.semi_major_m},
                {"inverse_flattening", c.inverse_flattening}, {"lat0_deg", c.lat0_deg}, {"lon0_deg", c.lon0_deg},
                {"scale_k0", c.scale_k0}, {"false_easting_m", c.false_easting_m}, {"false_northing_m", c.false_northing_m}};
  if (c.kind == ProjectionKind::proj) j["frame"]["definition_wkt2"] = c.definition;
  j["origin_m"] = {w.origin_x_m, w.origin_y_m};
  j["roots"] = {w.roots_x, w.roots_y};
  j["extent_m"] = {{"min_x", w.extent_min_x_m}, {"min_y", w.extent_min_y_m}, {"max_x", w.extent_max_x_m}, {"max_y", w.extent_max_y_m}};
  const uint64_t samples = source_valid_samples(w);
  for (int l = 0; l < level_count(w); ++l) {
    j["levels"].push_back({{"level", l}, {"node_size_m", node_size_m(l)}, {"vertex_spacing_m", vertex_spacing_m(l)},
                           {"step_log2", level_step_log2(w, l)}, {"nodes", f.per_level[size_t(l)]},
                           {"max_geometric_error_m", f.max_error[size_t(l)]}, {"overview", l > kRootLevel},
                           {"stored_bytes", level_stored_bytes(f.sections, l)},
                           {"bytes_per_km2", level_bytes_per_km2(f.sections, l)}});
    if (samples) j["levels"].back()["bytes_per_source_sample"] = double(level_stored_bytes(f.sections, l)) / double(samples);
  }
  if (samples) {
    j["source_valid_samples"] = samples;
    j["bytes_per_source_sample"] = double(reader.file_size()) / double(samples);
  }
  j["overview_levels"] = level_count(w) - kLevelCount;
  j["top_level"] = top_level(w);
  if (f.any) j["height_range_m"] = {units_to_metres(f.min_units), units_to_metres(f.max_units)};
  for (const auto& [input, h] : input_height_units(w)) {
    json e = h;
    e["path"] = input;
    j["input_height_units"].push_back(e);
  }
  uint64_t st = 0, rw = 0;
  for (size_t s = 0; s < layout::kSectionCount; ++s) {
    st += f.sections.stored[s];
    rw += f.sections.raw[s];
    j["sections"][layout::kSectionName[s]] = {
        {"stored_bytes", f.sections.stored[s]}, {"raw_bytes", f.sections.raw[s]},
        {"ratio", f.sections.stored[s] ? double(f.sections.raw[s]) / double(f.sections.stored[s]) : 0.0}};
  }
  j["sections"]["all"] = {{"stored_bytes", st}, {"raw_bytes", rw}, {"ratio", st ? double(rw) / double(st) : 0.0}};
  for (const Material& m : w.palette)
    j["palette"].push_back({{"name", m.name}, {"albedo_srgb", m.albedo_srgb}, {"roughness", m.roughness},
                            {"detail_scale_m", m.detail_scale_m}, {"detail_strength", m.detail_strength},
                            {"height_blend", m.height_blend}});
  if (!w.palette.size()) j["palette"] = json::array();
  if (!w.cook_info_json.empty()) {
    j["cook_info"] = json::parse(w.cook_info_json, nullptr, false);  // validated at open
  }
  out = j.dump(2) + "\n";
  return Status::success();
}

Status lonlat_to_frame(const FrameCrs& crs, double lon_deg, double lat_deg, double& x, double& y) {
  if (crs.kind != ProjectionKind::transverse_mercator)
    return Status::failure(Error::invalid_argument,
                           "this archive's frame is 'local' (no geodetic meaning): give frame metres with --sample/--sample-file "
                           "instead of longitude/latitude");
  if (!(std::fabs(lat_deg) <= 90) || !std::isfinite(lon_deg))
    return Status::failure(Error::invalid_argument, fmt::format("latitude {} / longitude {} out of range", lat_deg, lon_deg));
  const double f = crs.inverse_flattening > 0 ? 1.0 / crs.inverse_flattening : 0.0;
  const GeographicLib::TransverseMercator tm(crs.semi_major_m, f, crs.scale_k0);
  double x0 = 0, y0 = 0, e = 0, n = 0;
  tm.Forward(crs.lon0_deg, crs.lat0_deg, crs.lon0_deg, x0, y0);
  tm.Forward(crs.lon0_deg, lat_deg, lon_deg, e, n);
  x = crs.false_easting_m + e;
  y = crs.false_northing_m + n - y0;
  return Status::success();
}

bool parse_pair(const std::string& text, double& a, double& b) {
  std::string t = text;
  std::replace(t.begin(), t.end(), ',', ' ');
  std::istringstream in(t);
  std::string extra;
  if (!(in >> a >> b) || (in >> extra)) return false;
  return std::isfinite(a) && std::isfinite(b);
}

bool parse_key(const std::string& text, NodeKey& out) {
  unsigned l = 0, x = 0, y = 0;
  char c1 = 0, c2 = 0;
  std::istringstream in(text);
  std::string extra;
  if (!(in >> l >> c1 >> x >> c2 >> y) || c1 != '/' || c2 != '/' || (in >> extra) || l >= unsigned(kLevelCount)) return false;
  out = {l, x, y};
  return true;
}

Status read_point_file(const std::string& path, bool lonlat, std::vector<SamplePoint>& out) {
  std::ifstream in(path);
  if (!in) return Status::failure(Error::io_open, path + ": cannot open");
  std::string line;
  int number = 0;
  while (cli::next_line(in, line, number)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    SamplePoint p;
    p.lonlat = lonlat;
    if (!parse_pair(line, p.x, p.y))
      return Status::failure(Error::invalid_argument, fmt::format("{}:{}: expected two numbers ({}), got '{}'", path, number,
                                                                  lonlat ? "lon lat" : "x y", line));
    out.push_back(p);
  }
  return Status::success();
}

Status sample(const ArchiveReader& reader, const std::vector<SamplePoint>& points, std::vector<SampleAnswer>& out,
              const std::string& lonlat_crs) {
  SurfaceSampler sampler(reader);
  out.clear();
  LonLatToFrame to_frame;  // prepared at the first lon/lat point
  bool to_frame_ready = false;
  for (const SamplePoint& p : points) {
    SampleAnswer a;
    a.frame_x = p.x;
    a.frame_y = p.y;
    if (p.lonlat && !to_frame_ready) {
      TERRAIN_TRY(to_frame.init(reader.world().crs, lonlat_crs));
      to_frame_ready = true;
    }
    if (p.lonlat)
      TERRAIN_TRY(to_frame.convert(p.x, p.y, a.frame_x, a.frame_y));
    std::optional<SurfaceSample> got;
    TERRAIN_TRY(sampler.sample(a.frame_x, a.frame_y, got));
    if (got) {
      a.height_m = got->height_m;
      a.node = got->node;
    }
    out.push_back(a);
  }
  return Status::success();
}

namespace {

// Writes an image north up (grid row 0 is south, image row 0 is north): from the last row backwards.
Status write_image(const std::string& path, int w, int h, int channels, TerrainPixelType type, const void* south_up_rows,
                   size_t pixel_bytes) {
  ImageWriteFn write = nullptr;
  TERRAIN_TRY(image_writer(write));
  const auto* base = static_cast<const uint8_t*>(south_up_rows);
  const size_t row_bytes = size_t(w) * pixel_bytes;
  char error[512] = {};
  if (!write(path.c_str(), w, h, channels, type, base + size_t(h - 1) * row_bytes, -ptrdiff_t(row_bytes), error,
             sizeof error))
    return Status::failure(Error::io_write, path + ": " + error);
  return Status::success();
}

}  // namespace

Status export_node(const ArchiveReader& reader, const NodeKey& key, const std::string& dir, std::vector<std::string>& written) {
  int64_t index = -1;
  TERRAIN_TRY(reader.lookup(key, index));
  if (index < 0) return Status::failure(Error::node_not_found, "no node " + key_text(key) + " in the archive");
  auto d = std::make_unique<NodeData>();
  TERRAIN_TRY(reader.decode_node(size_t(index), *d));
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Status::failure(Error::io_write, dir + ": cannot create: " + ec.message());
  NodeRecord r;
  TERRAIN_TRY(reader.record(size_t(index), r));
  const WorldInfo& w = reader.world();
  const int step = level_step_log2(w, int(key.level));
  std::vector<uint8_t> holes(static_cast<size_t>(kHeightCount));
  decode_hole_mask(*d, holes.data());
  auto file = [&](const char* name) {
    written.push_back((std::filesystem::path(dir) / name).string());
    return written.back();
  };
  std::vector<float> metres(static_cast<size_t>(kHeightCount));
  for (size_t k = 0; k < metres.size(); ++k)
    metres[k] = holes[k] ? NAN : units_to_metres_f32(vertex_units(r.height_offset, d->heights[k], step));
  TERRAIN_TRY(write_image(file("heights.exr"), kHeightSamples, kHeightSamples, 1, terrain_pixel_f32, metres.data(), 4));
  TERRAIN_TRY(write_image(file("heights.png"), kHeightSamples, kHeightSamples, 1, terrain_pixel_u16, d->heights.data(), 2));
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4);
  decode_bc3_image(d->normals_bc3.data(), kTexelBlocks, kTexelBlocks, rgba.data());
  TERRAIN_TRY(write_image(file("normals.png"), kTexels, kTexels, 4, terrain_pixel_u8, rgba.data(), 4));
  decode_bc1_image(d->albedo_bc1.data(), kTexelBlocks, kTexelBlocks, rgba.data());
  TERRAIN_TRY(write_image(file("albedo.png"), kTexels, kTexels, 4, terrain_pixel_u8, rgba.data(), 4));
  std::vector<uint8_t> cones(8 * 8 * 4);
  decode_bc3_image(d->cones_bc3.data(), 2, 2, cones.data());
  TERRAIN_TRY(write_image(file("cones.png"), 8, 8, 4, terrain_pixel_u8, cones.data(), 4));
  {  // raw ids as binary PGM, north up
    std::ofstream pgm(file("splat.pgm"), std::ios::binary);
    pgm << "P5\n" << kSplatSamples << " " << kSplatSamples << "\n255\n";
    for (int j = kSplatSamples - 1; j >= 0; --j)
      pgm.write(reinterpret_cast<const char*>(d->splat.data() + size_t(j) * kSplatSamples), kSplatSamples);
    if (!pgm) return Status::failure(Error::io_write, written.back() + ": write failed");
  }
  std::vector<uint8_t> colours(size_t(kSplatCount) * 3);
  for (size_t k = 0; k < size_t(kSplatCount); ++k) {
    const uint8_t id = d->splat[k];
    std::array<uint8_t, 3> c{};
    if (id < w.palette.size()) {
      c = w.palette[id].albedo_srgb;
    } else {  // no palette entry: a stable false colour
      c = {uint8_t(id * 97), uint8_t(id * 57 + 80), uint8_t(id * 23 + 160)};
    }
    std::copy(c.begin(), c.end(), colours.begin() + std::ptrdiff_t(k * 3));
  }
  TERRAIN_TRY(write_image(file("splat.png"), kSplatSamples, kSplatSamples, 3, terrain_pixel_u8, colours.data(), 3));
  nlohmann::json j;
  const double size = node_size_m(int(key.level)), s = vertex_spacing_m(int(key.level));
  const double x0 = w.origin_x_m + key.x * size, y0 = w.origin_y_m + key.y * size;
  j["node"] = key_text(key);
  j["south_west_corner_m"] = {x0, y0};
  j["vertex_spacing_m"] = s;
  j["height_offset_units"] = r.height_offset;
  j["step_log2"] = step;
  j["metres_from_png16"] = fmt::format("({} + (value << {})) / 1024", r.height_offset, step);
  j["min_height_m"] = units_to_metres(r.min_height);
  j["max_height_m"] = units_to_metres(r.max_height);
  j["geometric_error_m"] = r.geometric_error_m;
  j["child_mask"] = r.child_mask;
  j["has_holes"] = bool(r.flags & kNodeFlagHasHoles);
  j["hole_vertices"] = std::count(holes.begin(), holes.end(), uint8_t(1));
  j["images"] = "north up; heights 129x129 vertices; normals/albedo 132x132 cell-centred texels with a 2-texel apron; "
                "splat 65x65 at every second vertex; cones 8x8 patches";
  std::ofstream js(file("node.json"));
  js << j.dump(2) << "\n";
  if (!js) return Status::failure(Error::io_write, written.back() + ": write failed");
  return Status::success();
}

Status verify(const ArchiveReader& reader, const ProgressFn& progress) {
  struct Ctx {
    const ProgressFn* fn;
  } ctx{&progress};
  return reader.verify(
      [](double fraction, void* user) {
        const auto* c = static_cast<const Ctx*>(user);
        if (*c->fn) (*c->fn)(fraction, "verify");
      },
      &ctx);
}

}  // namespace terrain::inspect
