// The synthetic generator's shared parts: the world header and the writer (synthetic_archive.h);
// the shapes are in sparse_tree.cpp and analytic_surface.cpp.
#include <string>

#include "synthetic_shapes.h"
#include "terrain/archive_writer.h"

namespace terrain::synthetic {
namespace {

Status generate(const Spec& spec, const WorldInfo& world, const NodeSink& sink) {
  return spec.shape == Shape::sparse_tree ? generate_sparse_tree(spec, world, sink) : generate_analytic_surface(spec, sink);
}

}  // namespace

Spec analytic_surface() {
  Spec s;
  s.shape = Shape::analytic_surface;
  s.roots_x = s.roots_y = 2;
  s.origin_y_m = 4200000.0;
  return s;
}

WorldInfo world_info(const Spec& spec) {
  WorldInfo w;
  w.crs.kind = ProjectionKind::local;
  w.origin_x_m = spec.origin_x_m;
  w.origin_y_m = spec.origin_y_m;
  w.roots_x = spec.roots_x;
  w.roots_y = spec.roots_y;
  w.extent_min_x_m = spec.origin_x_m;
  w.extent_min_y_m = spec.origin_y_m;
  w.extent_max_x_m = spec.origin_x_m + spec.roots_x * node_size_m(kRootLevel);
  w.extent_max_y_m = spec.origin_y_m + spec.roots_y * node_size_m(kRootLevel);
  if (spec.shape == Shape::sparse_tree) {
    w.crs.name = "synthetic local frame";
    for (int l = 0; l < kLevelCount; ++l) w.step_log2[size_t(l)] = uint8_t(l + 2);
    const int k = spec.overview_levels < 0 ? overview_levels_needed(spec.roots_x, spec.roots_y) : spec.overview_levels;
    w.overview_step_log2.assign(size_t(k), w.step_log2[kRootLevel]);
    Material m;
    m.name = "synthetic";
    w.palette = {m};
    w.cook_info_json = R"({"generator":"terrain::synthetic","seed":)" + std::to_string(spec.seed) + "}";
  } else {
    w.crs.name = "synthetic";
    w.step_log2.fill(uint8_t(kSurfaceStepLog2));
    const char* names[4] = {"sand", "grass", "rock", "snow"};
    const uint8_t colours[4][3] = {{178, 164, 118}, {92, 116, 56}, {116, 104, 92}, {216, 220, 226}};
    for (int i = 0; i < 4; ++i) {
      Material m;
      m.name = names[i];
      m.albedo_srgb = {colours[i][0], colours[i][1], colours[i][2]};
      m.detail_scale_m = 3.0f + float(i);
      m.detail_strength = 0.25f;
      m.height_blend = 0.6f;
      w.palette.push_back(m);
    }
    w.cook_info_json = "{\"synthetic\":true}";
  }
  return w;
}

World make_world(const Spec& spec) {
  World w;
  w.world = world_info(spec);
  // The shapes fail only when their sink does, and this one never does.
  (void)generate(spec, w.world, [&](const NodeRecord& record, const NodeData& data) {
    w.nodes.push_back({record, data});
    return Status::success();
  });
  return w;
}

Status write_archive(const std::string& path, const Spec& spec, Summary* summary) {
  const WorldInfo world = world_info(spec);
  ArchiveWriter writer;
  TERRAIN_TRY(writer.open(path));
  PayloadOptions options;
  options.zstd_level = spec.zstd_level;
  std::vector<uint8_t> payload;
  Summary sum;
  const Status s = generate(spec, world, [&](const NodeRecord& r, const NodeData& data) {
    TERRAIN_TRY(encode_node_payload(data, options, payload));
    TERRAIN_TRY(writer.add_node(r, payload));
    ++sum.nodes;
    sum.roots += r.key.level == uint32_t(kRootLevel);
    sum.payload_bytes += payload.size();
    return Status::success();
  });
  if (!s.ok()) return s;
  TERRAIN_TRY(writer.finish(world));
  if (summary) *summary = sum;
  return Status::success();
}

}  // namespace terrain::synthetic
