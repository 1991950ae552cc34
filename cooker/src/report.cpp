// The cook report: JSON for --report / --json, and the closing summary lines.
#include <cmath>
#include <fstream>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "frame/crs.h"
#include "inputs/height_units.h"
#include "surface/surface_layers.h"
#include "terrain/cook.h"

namespace terrain::cook {
namespace {

constexpr const char* kSectionNames[5] = {"heights", "normals", "albedo", "splat", "cones"};
static_assert(std::tuple_size_v<decltype(SurfaceTotals::cpu_parts)> == kCpuParts, "cook.h lists every CpuPart");

// CPU milliseconds per cooked node of one stage or part.
double ms_per_node(uint64_t nodes, double seconds) { return nodes ? 1e3 * seconds / double(nodes) : 0.0; }
double ms_per_node(const CookReport& r, double seconds) { return ms_per_node(r.nodes, seconds); }

// Every stage and part in CPU ms per node, over `nodes` nodes (the cook's, or one level's).
nlohmann::ordered_json cpu_per_node_json(uint64_t nodes, double heights, double error, double surface, double encode,
                                         const std::array<double, kCpuParts>& parts) {
  nlohmann::ordered_json j;
  j["heights"] = ms_per_node(nodes, heights);
  j["error"] = ms_per_node(nodes, error);
  j["surface"] = ms_per_node(nodes, surface);
  j["encode"] = ms_per_node(nodes, encode);
  j["total"] = ms_per_node(nodes, heights + error + surface + encode);
  for (size_t k = 0; k < kCpuParts; ++k) j[cpu_part_name(CpuPart(k))] = ms_per_node(nodes, parts[k]);
  return j;
}

}  // namespace

double SurfaceTotals::albedo_psnr_db() const {
  if (!albedo_samples || !(albedo_sq_err_sum > 0)) return 0.0;
  return 10.0 * std::log10(255.0 * 255.0 / (albedo_sq_err_sum / double(albedo_samples)));
}

// A level's stored bytes by section, per km2 of its nodes' area and per valid source sample (the
// archive's size at lidar density is what users compare; issue 17).
nlohmann::ordered_json level_bytes_json(const CookReport& r, int l) {
  const auto& by_section = r.level_section_stored_bytes[size_t(l)];
  uint64_t stored = 0;
  nlohmann::ordered_json sections;
  for (int k = 0; k < 5; ++k) {
    stored += by_section[size_t(k)];
    sections[kSectionNames[k]] = by_section[size_t(k)];
  }
  const double km2 = double(r.level_nodes[size_t(l)]) * node_size_m(l) * node_size_m(l) * 1e-6;
  return {{"stored_bytes", stored},
          {"section_stored_bytes", sections},
          {"bytes_per_km2", km2 > 0 ? double(stored) / km2 : 0.0},
          {"bytes_per_source_sample", r.source_valid_samples ? double(stored) / double(r.source_valid_samples) : 0.0}};
}

bool is_cook_report(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  f.seekg(0, std::ios::end);
  const std::streamoff size = f.tellg();
  if (size <= 0 || size > (std::streamoff(16) << 20)) return false;  // reports are kilobytes
  f.seekg(0);
  if (f.peek() != '{') return false;  // an archive, an image: no parse
  const nlohmann::json j = nlohmann::json::parse(f, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return false;
  for (const char* key : {"inputs", "source", "frame", "levels", "output", "time_s"})
    if (!j.contains(key)) return false;
  return j.at("inputs").is_array() && j.at("levels").is_array() && j.at("output").is_object() &&
         j.at("output").contains("archive_bytes");
}

std::string report_json(const CookReport& r) {
  nlohmann::ordered_json j;
  j["inputs"] = r.input_descriptions;
  j["input_bytes_read"] = r.input_bytes_read;
  // Per input: the unit its heights declare and the factor applied to its values.
  nlohmann::ordered_json units = nlohmann::ordered_json::array();
  for (const HeightUnit& u : r.input_height_units) units.push_back(height_unit_json(u));
  j["input_height_units"] = units;
  // Per input, on the mosaic's grid: samples where it has a height, and those the archive is cooked from.
  nlohmann::ordered_json input_samples = nlohmann::ordered_json::array();
  for (const InputSamples& in : r.input_samples)
    input_samples.push_back({{"path", in.path},
                             {"samples_read", in.read},
                             {"samples_used", in.used},
                             {"family", in.family},
                             {"spacing_m", in.spacing_m},
                             {"area_km2", in.area_km2},
                             {"tolerance_m", in.tolerance_m},
                             {"finest_level", in.finest_level}});
  j["input_samples"] = input_samples;
  j["source"] = {{"samples", r.source_samples},
                 {"valid_samples", r.source_valid_samples},
                 {"spacing_m", r.source_spacing_m},
                 {"voids_filled_samples", r.voids_filled_samples},
                 {"voids_filled_regions", r.voids_filled_regions},
                 {"hole_samples", r.hole_samples},
                 {"hole_regions", r.hole_regions},
                 {"void_fill_residual_m", r.void_fill_residual_m},
                 {"implausible_samples", r.implausible_samples}};
  j["frame"] = {{"description", describe_frame(r.frame)},
                {"reason", r.frame_reason},
                {"epsg", r.frame.epsg},
                {"origin_m", {r.origin_x_m, r.origin_y_m}},
                {"extent_m", {r.extent_min_x_m, r.extent_min_y_m, r.extent_max_x_m, r.extent_max_y_m}},
                {"lon0_deg", r.frame.lon0_deg},
                {"lat0_deg", r.frame.lat0_deg},
                {"k0", r.frame.scale_k0},
                {"false_easting_m", r.frame.false_easting_m},
                {"false_northing_m", r.frame.false_northing_m},
                {"semi_major_m", r.frame.semi_major_m},
                {"inverse_flattening", r.frame.inverse_flattening},
                {"local", r.frame.kind == ProjectionKind::local},
                {"roots", {r.roots_x, r.roots_y}}};
  j["tolerance_m"] = r.tolerance_m;
  j["tolerance_from"] = r.tolerance_from_source ? "source" : "option";
  j["finest_level"] = r.finest_level;
  nlohmann::ordered_json levels = nlohmann::ordered_json::array();
  for (int l = 0; l < kLevelCount; ++l) {
    const LevelStats& s = r.levels[size_t(l)];
    levels.push_back({{"level", l},
                      {"vertex_spacing_m", vertex_spacing_m(l)},
                      {"nodes", s.nodes},
                      {"step_log2", s.step_log2},
                      {"range_bound_m", s.range_bound_m},
                      {"step_m", std::ldexp(1.0, s.step_log2) * kHeightUnitM},
                      {"vertices", s.vertices},
                      {"error_samples", s.error_samples},
                      {"error_max_m", s.error_max_m},
                      {"error_rms_m", s.error_rms_m},
                      {"uncovered_samples", s.uncovered_samples}});
    levels.back().update(level_bytes_json(r, l));
    levels.back()["cpu_ms_per_node"] =
        cpu_per_node_json(s.nodes, s.cpu_heights, s.cpu_error, s.cpu_surface, s.cpu_encode, s.cpu_parts);
  }
  j["levels"] = levels;
  j["full_detail_error"] = {{"samples", r.leaf_error_samples},
                            {"max_m", r.leaf_error_max_m},
                            {"rms_m", r.leaf_error_rms_m},
                            {"uncovered_samples", r.leaf_uncovered_samples}};
  nlohmann::ordered_json sections;
  for (int s = 0; s < 5; ++s)
    sections[kSectionNames[s]] = {{"stored_bytes", r.section_stored_bytes[size_t(s)]},
                                  {"raw_bytes", r.section_raw_bytes[size_t(s)]}};
  j["output"] = {{"nodes", r.nodes}, {"archive_bytes", r.archive_bytes}, {"sections", sections},
                 {"surface_layers", r.surface_layers},
                 {"bytes_per_source_sample",
                  r.source_valid_samples ? double(r.archive_bytes) / double(r.source_valid_samples) : 0.0}};
  j["time_s"] = {{"read", r.seconds_read},       {"prepare", r.seconds_prepare}, {"pyramid", r.seconds_pyramid},
                 {"finish", r.seconds_finish},   {"total", r.seconds_total},     {"cpu_heights", r.cpu_heights},
                 {"cpu_error", r.cpu_error},     {"cpu_surface", r.cpu_surface}, {"cpu_encode", r.cpu_encode},
                 {"cpu_first_pass", r.cpu_first_pass}, {"cpu_steps", r.cpu_steps}, {"cpu_blocks", r.cpu_blocks},
                 {"cpu_total", r.cpu_total}, {"cpu_overview", r.cpu_overview}};
  j["overview_levels"] = {{"levels", r.overview_levels},
                          {"step_log2", r.overview_step_log2},
                          {"range_bound_m", r.overview_range_bound_m},
                          {"nodes", r.overview_nodes},
                          {"error_max_m", r.overview_error_max_m}};
  nlohmann::ordered_json overview_bytes = nlohmann::ordered_json::array();
  for (int l = kLevelCount; l < kLevelCount + r.overview_levels && l < kMaxLevels; ++l) {
    overview_bytes.push_back({{"level", l}, {"nodes", r.level_nodes[size_t(l)]}});
    overview_bytes.back().update(level_bytes_json(r, l));
  }
  j["overview_levels"]["bytes_by_level"] = overview_bytes;
  // The per-layer / per-encoder / per-section split of cpu_surface and cpu_encode, and every stage
  // and part in CPU ms per node (the unit of the cook-throughput budget).
  nlohmann::ordered_json parts;
  for (size_t k = 0; k < kCpuParts; ++k) parts[cpu_part_name(CpuPart(k))] = r.surface.cpu_parts[k];
  j["time_s"]["cpu_parts"] = parts;
  j["time_s"]["cpu_ms_per_node"] =
      cpu_per_node_json(r.nodes, r.cpu_heights, r.cpu_error, r.cpu_surface, r.cpu_encode, r.surface.cpu_parts);
  j["speed"] = {{"threads", r.threads},
                {"source_samples_per_s", r.source_samples_per_second},
                {"output_vertices", r.output_vertices},
                {"height_samples_per_cpu_s", r.height_samples_per_cpu_second}};
  j["peak_rss_bytes"] = r.peak_rss_bytes;
  j["memory_limit_bytes"] = r.memory_limit_bytes;
  j["blocks"] = {{"block_roots", r.block_roots},
                 {"count", r.blocks},
                 {"window_samples_max", r.block_window_samples_max},
                 {"spool_bytes", r.spool_bytes},
                 {"spool_bytes_returned", r.spool_bytes_returned}};
  if (r.surface_layers) {
    const SurfaceTotals& t = r.surface;
    j["surface"] = {{"normal_err_max_deg", t.normal_err_max_deg},
                    {"normal_err_mean_deg", t.normal_err_mean_deg()},
                    {"normal_samples", t.normal_samples},
                    {"albedo_psnr_db", t.albedo_psnr_db()},
                    {"albedo_samples", t.albedo_samples},
                    {"albedo_hole_texels", t.albedo_hole_texels},
                    {"albedo_alpha_mismatches", t.albedo_alpha_mismatches},
                    // Normal and albedo errors are measured on checked_nodes of nodes (--error-checks).
                    {"nodes", t.nodes},
                    {"checked_nodes", t.checked_nodes},
                    {"cones", {{"patches", t.cone_patches},
                               {"patches_never_cull", t.cone_patches_never_cull},
                               {"exact_mean_deg", t.cone_exact_mean_deg()},
                               {"encoded_mean_deg", t.cone_encoded_mean_deg()}}},
                    {"cpu_s", {{"normals", t.cpu_normals},
                               {"albedo", t.cpu_albedo},
                               {"splat", t.cpu_splat},
                               {"cones", t.cpu_cones}}}};
  }
  j["warnings"] = r.warnings;
  return j.dump(2);
}

std::string report_summary(const CookReport& r) {
  std::string s;
  s += fmt::format("frame: {}\n", describe_frame(r.frame));
  s += fmt::format("grid: origin ({:.1f}, {:.1f}) m, {}x{} roots of 2048 m; finest level {} ({} m); tolerance {:.3g} m{}\n",
                   r.origin_x_m, r.origin_y_m, r.roots_x, r.roots_y, r.finest_level, vertex_spacing_m(r.finest_level),
                   r.tolerance_m, r.tolerance_from_source ? " (1/32 of the source spacing, at least 0.5 m)" : "");
  // Heights that were not taken as metres as they are: the unit and the factor applied.
  for (size_t i = 0; i < r.input_height_units.size(); ++i) {
    const HeightUnit& u = r.input_height_units[i];
    if (u.declared.empty() && !u.scale_from_flag) continue;
    const std::string which = r.input_height_units.size() > 1 ? fmt::format(" (input {})", i + 1) : "";
    const std::string unit = u.declared.empty() ? "no unit declared" : fmt::format("'{}' ({})", u.declared, u.declared_by);
    s += fmt::format("heights{}: {}; values x {:.10g} to metres{}\n", which, unit, u.scale,
                     u.scale_from_flag ? " (--height-scale)" : "");
  }
  if (r.voids_filled_samples || r.hole_samples)
    s += fmt::format("nodata: {} samples in {} voids filled, {} samples in {} regions left as holes\n",
                     r.voids_filled_samples, r.voids_filled_regions, r.hole_samples, r.hole_regions);
  if (r.input_samples.size() > 1) {
    s += "inputs: samples used of read (on the mosaic's grid):";
    for (const InputSamples& in : r.input_samples) s += fmt::format(" {} {} of {};", in.path, in.used, in.read);
    s.back() = '\n';
    s += "inputs: area owned, spacing, tolerance, finest level:";
    for (const InputSamples& in : r.input_samples)
      s += fmt::format(" {} {:.3g} km2, {:.3g} m, {:.3g} m, {};", in.path, in.area_km2, in.spacing_m, in.tolerance_m,
                       in.finest_level);
    s.back() = '\n';
  }
  s += "level  spacing  nodes   step(mm)  err max(m)  err rms(m)  samples\n";
  for (int l = kLevelCount - 1; l >= 0; --l) {
    const LevelStats& v = r.levels[size_t(l)];
    if (!v.nodes) continue;
    s += fmt::format("{:>5}  {:>6.1f}  {:>6}  {:>8.3f}  {:>10.3f}  {:>10.3f}  {}\n", l, vertex_spacing_m(l), v.nodes,
                     std::ldexp(1.0, v.step_log2) * kHeightUnitM * 1000.0, v.error_max_m, v.error_rms_m, v.error_samples);
  }
  if (r.overview_levels > 0)
    s += fmt::format("overview: {} levels above the roots (SPEC 19), {} nodes, step {:.3f} mm (range bound {:.1f} m), "
                     "error max {:.3f} m, {:.2f} cpu s\n",
                     r.overview_levels, r.overview_nodes, std::ldexp(1.0, r.overview_step_log2) * kHeightUnitM * 1000.0,
                     r.overview_range_bound_m, r.overview_error_max_m, r.cpu_overview);
  // Counted per node (node_cook.cpp measure_error): a valid sample on an edge shared by two finest
  // nodes is measured in both, so the count can exceed the raster's samples.
  s += fmt::format("full detail: error max {:.3f} m, rms {:.3f} m over {} sample measurements (each valid source "
                   "sample against every finest node touching it)\n", r.leaf_error_max_m,
                   r.leaf_error_rms_m, r.leaf_error_samples);
  if (r.leaf_uncovered_samples)
    s += fmt::format("full detail: {} valid source sample measurements lie under dropped (hole) triangles\n",
                     r.leaf_uncovered_samples);
  if (r.surface_layers) {
    const SurfaceTotals& t = r.surface;
    s += fmt::format("surface: normals err max {:.2f} deg, mean {:.2f} deg; albedo PSNR {:.1f} dB (measured on {} of {} "
                     "nodes); cones over {} patches: mean half-angle {:.1f} deg exact, {:.1f} deg encoded, {} never cull "
                     "(cpu: normals {:.2f}, albedo {:.2f}, splat {:.2f}, cones {:.2f})\n",
                     t.normal_err_max_deg, t.normal_err_mean_deg(), t.albedo_psnr_db(), t.checked_nodes, t.nodes,
                     t.cone_patches,
                     t.cone_exact_mean_deg(), t.cone_encoded_mean_deg(), t.cone_patches_never_cull, t.cpu_normals,
                     t.cpu_albedo, t.cpu_splat, t.cpu_cones);
  }
  s += "bytes:";
  for (int k = 0; k < 5; ++k) s += fmt::format(" {} {}", kSectionNames[k], r.section_stored_bytes[size_t(k)]);
  if (r.source_valid_samples)
    s += fmt::format("; {:.3f} bytes per valid source sample", double(r.archive_bytes) / double(r.source_valid_samples));
  s += "\nbytes per km2 of the level's nodes:";
  for (int l = kMaxLevels - 1; l >= 0; --l) {
    if (!r.level_nodes[size_t(l)]) continue;
    uint64_t stored = 0;
    for (uint64_t b : r.level_section_stored_bytes[size_t(l)]) stored += b;
    s += fmt::format(" L{} {:.0f}", l, double(stored) / (double(r.level_nodes[size_t(l)]) * node_size_m(l) * node_size_m(l) * 1e-6));
  }
  s += "\n";
  s += fmt::format("time: read {:.2f} s, prepare {:.2f} s, pyramid {:.2f} s, finish {:.2f} s (cpu: heights {:.2f}, "
                   "error {:.2f}, surface {:.2f}, encode {:.2f}) on {} threads\n",
                   r.seconds_read, r.seconds_prepare, r.seconds_pyramid, r.seconds_finish, r.cpu_heights, r.cpu_error,
                   r.cpu_surface, r.cpu_encode, r.threads);
  if (r.nodes) {
    s += fmt::format("cpu ms/node: heights {:.3f}, error {:.3f}, surface {:.3f}, encode {:.3f}; parts:", ms_per_node(r, r.cpu_heights),
                     ms_per_node(r, r.cpu_error), ms_per_node(r, r.cpu_surface), ms_per_node(r, r.cpu_encode));
    for (size_t k = 0; k < kCpuParts; ++k)
      s += fmt::format(" {} {:.3f}", cpu_part_name(CpuPart(k)), ms_per_node(r, r.surface.cpu_parts[k]));
    s += "\n";
    // Level by level: the four stages, then the parts that take a tenth of the level's time or more.
    for (int l = kLevelCount - 1; l >= 0; --l) {
      const LevelStats& v = r.levels[size_t(l)];
      if (!v.nodes) continue;
      const double total = v.cpu_heights + v.cpu_error + v.cpu_surface + v.cpu_encode;
      s += fmt::format("  L{} {} nodes: {:.3f} ms/node (heights {:.3f}, error {:.3f}, surface {:.3f}, encode {:.3f})", l,
                       v.nodes, ms_per_node(v.nodes, total), ms_per_node(v.nodes, v.cpu_heights),
                       ms_per_node(v.nodes, v.cpu_error), ms_per_node(v.nodes, v.cpu_surface),
                       ms_per_node(v.nodes, v.cpu_encode));
      for (size_t k = 0; k < kCpuParts; ++k)
        if (v.cpu_parts[k] >= 0.1 * total && total > 0)
          s += fmt::format(" {} {:.3f}", cpu_part_name(CpuPart(k)), ms_per_node(v.nodes, v.cpu_parts[k]));
      s += "\n";
    }
  }
  s += fmt::format("{} nodes, {} source samples -> {} bytes ({:.2f} bytes/sample), {:.2f} s, {:.2f} M source samples/s, "
                   "{:.1f} M height samples per cpu-second, peak memory {} MB\n",
                   r.nodes, r.source_samples, r.archive_bytes,
                   r.source_samples ? double(r.archive_bytes) / double(r.source_samples) : 0.0, r.seconds_total,
                   r.source_samples_per_second / 1e6, r.height_samples_per_cpu_second / 1e6, r.peak_rss_bytes >> 20);
  uint64_t read = 0;
  for (uint64_t b : r.input_bytes_read) read += b;
  if (read) s += fmt::format("read: {} bytes of samples from {} inputs (2 passes: the first pass, the blocks)\n", read,
                             r.input_bytes_read.size());
  s += fmt::format("blocks: {} of {}x{} roots, largest source window {} samples, {} bytes spooled ({} given back "
                   "while copied); memory limit {} MB\n",
                   r.blocks, r.block_roots, r.block_roots, r.block_window_samples_max, r.spool_bytes,
                   r.spool_bytes_returned, r.memory_limit_bytes >> 20);
  return s;
}

}  // namespace terrain::cook
