// terrain-view-bench: frame cost of the FC5 pipeline against the error it leaves.
//
// For each view and screen-space error target: GPU time split into traversal, culling (LOD map +
// patch list) and drawing (timestamp queries, median of --frames after a warm-up), the wall time
// of the frame, patches drawn and culled by frustum and by cone, triangles; the CPU reference
// traversal + culling of the same frame; and the error the target really leaves: for every pixel
// of a full-detail render (every node resident and split, no coarsening), the vertical distance
// between that surface and the surface the target draws, projected to pixels at the pixel's
// distance (the quantity the LOD test bounds). Every node is decoded up front (same residency for
// all rows), so an archive must fit --max-nodes. --chart FILE.svg draws frame and work time against
// the measured error, one series per view (bench_chart.h).
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <unordered_map>

#include "bench_chart.h"
#include "reference.h"
#include "session.h"
#include "terrain/bc_decode.h"

namespace terrain::view {
namespace {

// CPU time of this process (every thread), ms.
double process_cpu_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return (double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) * 1e3) + double(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-3;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(p * double(v.size())))];
}

// Decimation of each drawn root patch: key slot * 64 + patch.
using DecimationMap = std::unordered_map<uint32_t, uint32_t>;
DecimationMap decimations(const std::vector<GpuPatch>& patches) {
  DecimationMap m;
  for (const GpuPatch& p : patches)
    if (patch_decimation(p) > 0)
      m[patch_slot(p) * TV_PATCH_ERRORS_PER_NODE + patch_error_index(patch_coarsening(p), patch_px(p), patch_py(p))] =
          patch_decimation(p);
  return m;
}

// Height (m) of the surface the frame draws at local point (lx, ly) (metres from the world
// origin): the node drawing the sector (LOD map), its triangle (SW->NE split) at the node's
// geometric level and, for a decimated root patch (coarsened or not), every 2^e-th vertex. Stitching
// (only the outermost quad strip of a node or decimated patch) is ignored. NaN if none, or where
// that triangle has a hole corner (holes drawn: the frame drops it there).
using HoleMasks = std::unordered_map<uint32_t, std::vector<uint8_t>>;
double drawn_height(const Session& s, const std::vector<uint32_t>& lod_map, const DecimationMap& dec, HoleMasks& holes,
                    double lx, double ly) {
  const TerrainState& st = s.state;
  if (lx < 0 || ly < 0) return NAN;
  const int64_t k = lod_index(s.renderer.uniforms(), int64_t(lx / 64.0), int64_t(ly / 64.0));
  if (k < 0) return NAN;
  const uint32_t v = lod_map[size_t(k)];
  if (v == 0) return NAN;
  const uint32_t geo = v - 1;
  // Levels 6+ of an archive with overview levels may be an overview node or a coarsened root:
  // the LOD map does not say which, so such points are not sampled.
  if (geo > uint32_t(terrain::kRootLevel) && st.top_level() > terrain::kRootLevel) return NAN;
  uint32_t c = geo > uint32_t(terrain::kRootLevel) ? geo - uint32_t(terrain::kRootLevel) : 0u;
  const int level = int(std::min<uint32_t>(geo, uint32_t(terrain::kRootLevel)));
  const double size = node_size_m(level);
  const uint32_t nx = uint32_t(lx / size), ny = uint32_t(ly / size);
  const uint16_t slot = st.slot_of(NodeKey{uint32_t(level), nx, ny});
  if (slot >= TV_SLOT_INVALID) return NAN;
  if (level == terrain::kRootLevel) {  // a root patch, coarsened or not, may be decimated
    const uint32_t pps = TV_PATCHES_PER_SIDE >> c;
    const double patch = size / pps;
    const uint32_t px = std::min(uint32_t((lx - nx * size) / patch), pps - 1);
    const uint32_t py = std::min(uint32_t((ly - ny * size) / patch), pps - 1);
    if (auto it = dec.find(slot * TV_PATCH_ERRORS_PER_NODE + patch_error_index(c, px, py)); it != dec.end()) c += it->second;
  }
  const double step = vertex_spacing_m(level) * double(1 << c);
  const NodeData* data = s.source->slot_data(slot);
  if (!data) return NAN;
  const SlotDescriptor& d = st.descriptor(slot);
  const double u = (lx - nx * size) / step, w = (ly - ny * size) / step;
  const int cells = kQuadsPerSide >> c;
  const int ci = std::clamp(int(u), 0, cells - 1), cj = std::clamp(int(w), 0, cells - 1);
  const double a = u - ci, b = w - cj;
  auto h = [&](int i, int j) {
    const int ti = i << c, tj = j << c;
    return units_to_metres(vertex_units(d.height_offset, data->heights[size_t(tj) * kHeightSamples + ti], d.step_log2));
  };
  if (s.options.settings.holes && (d.flags & kNodeFlagHasHoles)) {
    auto [it, fresh] = holes.try_emplace(slot);
    if (fresh) {
      it->second.resize(kHeightCount);
      terrain::decode_hole_mask(*data, it->second.data());
    }
    auto hole = [&](int i, int j) { return it->second[size_t(j << c) * kHeightSamples + size_t(i << c)] != 0; };
    if (hole(ci, cj) || hole(ci + 1, cj + 1) || (a >= b ? hole(ci + 1, cj) : hole(ci, cj + 1))) return NAN;
  }
  return quad_height(h(ci, cj), h(ci + 1, cj), h(ci, cj + 1), h(ci + 1, cj + 1), a, b);
}

struct Row {
  std::string view;
  double target = 0;
  FrameRecord last;
  double traverse = 0, lodmap = 0, patches = 0, draw = 0, total = 0, wall = 0, cpu_ref = 0;
  double work = 0;  // process CPU time (all lavapipe threads) per frame: the work, robust to other jobs
  double err_mean = 0, err_p99 = 0, err_max = 0;
  size_t err_pixels = 0;
  // --profile: draw time of the same frame with a constant-colour fragment shader and with
  // rasterizer discard (vertex work only).
  double draw_flat = 0, draw_vertex = 0;
};

// Median GPU draw time of `frames` frames (after `warmup`) drawn with `profile`.
terrain::Status median_draw(Session& s, const Camera& cam, FrameSettings::DrawProfile profile, int warmup, int frames,
                            double& out) {
  const FrameSettings::DrawProfile saved = s.options.settings.profile;
  s.options.settings.profile = profile;
  std::vector<double> dr;
  FrameRecord rec;
  for (int f = 0; f < warmup + frames; ++f) {
    TERRAIN_TRY(render_frame(s, cam, false, rec));
    if (f >= warmup) dr.push_back(rec.gpu.gpu_draw_ms);
  }
  s.options.settings.profile = saved;
  out = median(dr);
  return terrain::Status::success();
}

// --chart: frame time (wall, the wait for the frame) and work time (process CPU per frame) against
// the p99 screen-space error each target leaves, a series per view, points labelled with the target.
terrain::chart::Chart view_chart(const std::vector<Row>& rows, const std::string& archive, unsigned w, unsigned h,
                                 const std::string& device, int frames, bool decimate) {
  namespace ch = terrain::chart;
  ch::Chart c;
  c.title = "terrain-view-bench: frame cost against the screen-space error it leaves";
  c.note = "Archive " + std::filesystem::path(archive).filename().string() + ", " + std::to_string(w) + "x" +
           std::to_string(h) + ", device " + device + ", median of " + std::to_string(frames) +
           " frames per point; error = p99 over terrain pixels of |drawn - full-detail height| in pixels; labels: the "
           "error target (px). " + ch::machine_note();
  ch::Panel frame, work;
  frame.title = "frame time";
  work.title = "work per frame (process CPU)";
  frame.x = work.x = {"measured screen-space error, p99, px", ch::Scale::linear, true};
  frame.y = {"frame ms", ch::Scale::linear, true};
  work.y = {"work ms", ch::Scale::linear, true};
  std::vector<std::string> views;
  for (const Row& r : rows)
    if (std::find(views.begin(), views.end(), r.view) == views.end()) views.push_back(r.view);
  for (const std::string& v : views) {
    ch::Series sf{decimate ? v : v + " (no decimation)", {}};
    sf.label_points = true;
    ch::Series sw = sf;
    for (const Row& r : rows) {
      if (r.view != v) continue;
      char label[32];
      std::snprintf(label, sizeof label, "%g", r.target);
      sf.points.push_back({r.err_p99, r.wall, label});
      sw.points.push_back({r.err_p99, r.work, label});
    }
    frame.series.push_back(sf);
    work.series.push_back(sw);
  }
  c.panels = {frame, work};
  return c;
}

}  // namespace
}  // namespace terrain::view

int main(int argc, char** argv) {
  using namespace terrain::view;
  CLI::App app{"terrain-view-bench: FC5 pipeline frame cost against the screen-space error it leaves"};
  std::string archive, size = "1280x720", targets_text = "0.5,1,2,4,8";
  int frames = 10, warmup = 3;
  uint32_t max_nodes = 4096;
  bool json_out = false, profile = false, no_decimate = false;
  app.add_option("archive", archive, "terrain archive")->required()->check(CLI::ExistingFile);
  app.add_option("--size", size, "image size WxH")->capture_default_str();
  app.add_option("--targets", targets_text, "error targets in pixels, comma separated")->capture_default_str();
  app.add_option("--frames", frames, "measured frames per row (median)")->capture_default_str();
  app.add_option("--warmup", warmup, "frames before measuring")->capture_default_str();
  app.add_option("--max-nodes", max_nodes, "most nodes to decode up front")->capture_default_str();
  app.add_flag("--json", json_out, "print the table as JSON on stdout");
  std::string chart;
  app.add_option("--chart", chart, "also write an SVG chart: frame and work ms against the measured error, per view");
  app.add_flag("--no-decimate", no_decimate, "no per-patch decimation of roots (the baseline it is measured against)");
  std::string far_light = "auto";
  app.add_option("--far-light", far_light, "far-field lighting as terrain-view's: texel, pixel, auto (texel on CPU devices)")
      ->capture_default_str()->check(CLI::IsMember({"auto", "texel", "pixel"}));
  app.add_flag("--profile", profile,
               "also split the draw: vertex work only (rasterizer discard), constant-colour fragments, shading");
  CLI11_PARSE(app, argc, argv);
  std::vector<double> targets;
  {
    std::stringstream ss(targets_text);
    std::string item;
    while (std::getline(ss, item, ',')) targets.push_back(std::stod(item));
  }
  ViewerOptions o;
  o.archive = archive;
  o.headless = true;
  o.load_all = true;
  o.quiet = true;
  o.settings.decimate = !no_decimate;
  o.far_light = far_light;
  unsigned w = 0, h = 0;
  char x = 0;
  std::istringstream sz(size);
  if (!(sz >> w >> x >> h) || x != 'x') {
    std::fprintf(stderr, "terrain-view-bench: --size expects WxH\n");
    return 2;
  }
  o.width = w;
  o.height = h;
  std::unique_ptr<Session> session;
  (void)max_nodes;
  terrain::Status st = open_session(o, {}, false, session);
  if (!st.ok()) {
    std::fprintf(stderr, "terrain-view-bench: %s\n", st.message.c_str());
    return is_no_device(st) ? 77 : 1;
  }
  Session& s = *session;
  s.capture_lists = true;

  // Views: the default overview (whole archive from the south) and a low oblique view.
  std::vector<std::pair<std::string, Camera>> views;
  const Camera overview = initial_camera(s);
  views.push_back({"overview", overview});
  {
    const terrain::WorldInfo& wi = s.source->world();
    int32_t lo = 0, hi = 0;
    s.source->height_range(lo, hi);
    const double extent = std::max(wi.extent_max_x_m - wi.extent_min_x_m, wi.extent_max_y_m - wi.extent_min_y_m);
    Camera low = overview;
    low.position[0] = 0.5 * (wi.extent_min_x_m + wi.extent_max_x_m);
    low.position[1] = wi.extent_min_y_m + 0.25 * (wi.extent_max_y_m - wi.extent_min_y_m);
    low.position[2] = hi / 1024.0 + 0.03 * extent;
    low.yaw = 0;
    low.pitch = -12 * M_PI / 180;
    low.near_m = 1.0;
    views.push_back({"low", low});
  }

  std::vector<Row> rows;
  for (const auto& [view_name, cam] : views) {
    // Full-detail reference: every node resident (load-all), split wherever it has children.
    s.options.settings.error_target_px = 0.0;
    FrameRecord rec;
    for (int f = 0; f < 2; ++f)
      if (!(st = render_frame(s, cam, true, rec)).ok()) {
        std::fprintf(stderr, "terrain-view-bench: %s\n", st.message.c_str());
        return 1;
      }
    std::vector<float> full_depth;
    read_depth(s.target, full_depth);
    const FrameRecord full = rec;
    for (double target : targets) {
      s.options.settings.error_target_px = target;
      Row row;
      row.view = view_name;
      row.target = target;
      std::vector<double> tv, lm, pa, dr, to, wa, cpu, wk;
      for (int f = 0; f < warmup + frames; ++f) {
        const double work0 = process_cpu_ms();
        if (!(st = render_frame(s, cam, f == warmup + frames - 1, rec)).ok()) {
          std::fprintf(stderr, "terrain-view-bench: %s\n", st.message.c_str());
          return 1;
        }
        if (f < warmup) continue;
        tv.push_back(rec.gpu.gpu_traverse_ms);
        lm.push_back(rec.gpu.gpu_lodmap_ms);
        pa.push_back(rec.gpu.gpu_patches_ms);
        dr.push_back(rec.gpu.gpu_draw_ms);
        to.push_back(rec.gpu.gpu_total_ms);
        wa.push_back(rec.wait_ms);
        wk.push_back(process_cpu_ms() - work0);
        // The CPU reference of the same frame: traversal, LOD map, patch list.
        const auto t0 = std::chrono::steady_clock::now();
        const FrameUniforms& u = s.renderer.uniforms();
        const NodeList list = reference_traverse(s.state, u, s.renderer.slot_cpu());
        const auto lod = reference_lod_map(s.state, u, list);
        const PatchList pl = reference_patches(s.state, u, list, lod, s.renderer.slot_cpu(), s.renderer.cone_sin2_table());
        cpu.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        if (pl.patches.size() != rec.gpu.patches_drawn)
          std::fprintf(stderr, "terrain-view-bench: CPU reference drew %zu patches, GPU %u\n", pl.patches.size(),
                       rec.gpu.patches_drawn);
      }
      row.last = rec;
      row.traverse = median(tv);
      row.lodmap = median(lm);
      row.patches = median(pa);
      row.draw = median(dr);
      row.total = median(to);
      row.wall = median(wa);
      row.work = median(wk);
      row.cpu_ref = median(cpu);
      if (profile) {
        for (auto [p, out] : {std::pair{FrameSettings::DrawProfile::kFlat, &row.draw_flat},
                              std::pair{FrameSettings::DrawProfile::kVertexOnly, &row.draw_vertex}})
          if (!(st = median_draw(s, cam, p, warmup, frames, *out)).ok()) {
            std::fprintf(stderr, "terrain-view-bench: %s\n", st.message.c_str());
            return 1;
          }
      }
      // Error left by this target against the full-detail surface, per pixel.
      NodeList nodes;
      std::vector<uint32_t> lod;
      std::vector<GpuPatch> patches;
      s.renderer.read_lists(nodes, lod, patches);
      const terrain::WorldInfo& wi = s.source->world();
      const double ppr = pixels_per_radian(cam.fovy, s.target.height);
      const DecimationMap dec = decimations(patches);
      HoleMasks holes;
      std::vector<double> errs;
      for (uint32_t py = 0; py < s.target.height; ++py)
        for (uint32_t px = 0; px < s.target.width; ++px) {
          const float d = full_depth[size_t(py) * s.target.width + px];
          if (!(d > 0)) continue;
          double rel[3];
          unproject(cam, s.target.width, s.target.height, px, py, d, rel);
          const double lx = cam.position[0] + rel[0] - wi.origin_x_m, ly = cam.position[1] + rel[1] - wi.origin_y_m;
          const double hl = drawn_height(s, lod, dec, holes, lx, ly);
          if (std::isnan(hl)) continue;
          const double dist = std::sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]);
          errs.push_back(std::abs(hl - (cam.position[2] + rel[2])) * ppr / dist);
        }
      row.err_pixels = errs.size();
      double sum = 0;
      for (double e : errs) sum += e;
      row.err_mean = errs.empty() ? 0 : sum / double(errs.size());
      row.err_p99 = percentile(errs, 0.99);
      row.err_max = errs.empty() ? 0 : *std::max_element(errs.begin(), errs.end());
      rows.push_back(row);
    }
    std::fprintf(stderr, "view %s: full detail %u nodes, %.2f M triangles, GPU %.1f ms\n", view_name.c_str(),
                 full.gpu.nodes, double(full.gpu.triangles) / 1e6, full.gpu.gpu_total_ms);
  }

  if (!chart.empty()) {
    const std::string e = terrain::chart::write_svg(
        view_chart(rows, archive, w, h, s.ctx.device_name, frames, !no_decimate), chart);
    if (!e.empty()) {
      std::fprintf(stderr, "terrain-view-bench: %s\n", e.c_str());
      return 1;
    }
    std::fprintf(stderr, "wrote %s\n", chart.c_str());
  }
  if (json_out) {
    nlohmann::json j = nlohmann::json::array();
    for (const Row& r : rows) {
      j.push_back({{"view", r.view}, {"target_px", r.target}, {"nodes", r.last.gpu.nodes},
                   {"patches_drawn", r.last.gpu.patches_drawn}, {"culled_frustum", r.last.gpu.culled_frustum},
                   {"culled_cone", r.last.gpu.culled_cone}, {"triangles", r.last.gpu.triangles}, {"patches_per_decimation", r.last.gpu.patches_decimated},
                   {"gpu_traversal_ms", r.traverse}, {"gpu_lodmap_ms", r.lodmap}, {"gpu_patches_ms", r.patches},
                   {"gpu_draw_ms", r.draw}, {"gpu_total_ms", r.total}, {"frame_ms", r.wall}, {"cpu_work_ms", r.work},
                   {"cpu_reference_ms", r.cpu_ref}, {"error_mean_px", r.err_mean}, {"error_p99_px", r.err_p99},
                   {"error_max_px", r.err_max}});
      if (profile) {
        j.back()["draw_vertex_ms"] = r.draw_vertex;
        j.back()["draw_flat_ms"] = r.draw_flat;
      }
    }
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("terrain-view-bench %s, %ux%u, device %s, median of %d frames\n", archive.c_str(), w, h,
              s.ctx.device_name.c_str(), frames);
  std::printf("%-9s %6s %6s %7s %7s %6s %8s %8s %8s %8s %8s %8s %8s %6s %8s %7s %7s %7s\n", "view", "target", "nodes",
              "patches", "frustum", "cone", "tris", "trav_ms", "cull_ms", "draw_ms", "gpu_ms", "frame_ms", "work_ms", "tc_%",
              "cpu_ref", "err_avg", "err_p99", "err_max");
  for (const Row& r : rows) {
    const double cull = r.lodmap + r.patches;
    std::printf("%-9s %6.2f %6u %7u %7u %6u %8llu %8.3f %8.3f %8.2f %8.2f %8.2f %8.2f %6.2f %8.3f %7.3f %7.3f %7.2f\n",
                r.view.c_str(), r.target, r.last.gpu.nodes, r.last.gpu.patches_drawn, r.last.gpu.culled_frustum,
                r.last.gpu.culled_cone, static_cast<unsigned long long>(r.last.gpu.triangles), r.traverse, cull, r.draw,
                r.total, r.wall, r.work, 100.0 * (r.traverse + cull) / std::max(r.total, 1e-9), r.cpu_ref, r.err_mean,
                r.err_p99, r.err_max);
  }
  std::printf("\npatches drawn per decimation e = 0..%d (16 >> e quads per side), near (splat) patches\n", TV_MAX_DECIMATE);
  for (const Row& r : rows) {
    std::printf("%-9s %6.2f ", r.view.c_str(), r.target);
    for (uint32_t n : r.last.gpu.patches_decimated) std::printf(" %6u", n);
    std::printf("   near %u\n", r.last.gpu.patches_near);
  }
  if (profile) {
    std::printf("\ndraw split (GPU ms, medians): vertex = rasterizer discard; raster = constant-colour draw - vertex; "
                "shade = full draw - constant-colour draw\n");
    std::printf("%-9s %6s %8s %8s %8s %8s %9s %9s\n", "view", "target", "tris", "draw_ms", "vertex", "raster", "shade",
                "ns/tri_vx");
    for (const Row& r : rows)
      std::printf("%-9s %6.2f %8llu %8.2f %8.2f %8.2f %8.2f %9.1f\n", r.view.c_str(), r.target,
                  static_cast<unsigned long long>(r.last.gpu.triangles), r.draw, r.draw_vertex,
                  r.draw_flat - r.draw_vertex, r.draw - r.draw_flat,
                  1e6 * r.draw_vertex / std::max<double>(1.0, double(r.last.gpu.triangles)));
  }
  std::printf("work_ms = CPU time of the process per frame (lavapipe's threads: the frame's work, ~2x frame_ms when "
              "both cores are busy, robust to other jobs)\n");
  std::printf("tc_%% = (traversal + culling) / GPU frame; cpu_ref = CPU reference traversal + LOD map + patch list of "
              "the same frame; err = |drawn - full-detail height| * pixels-per-radian / distance over terrain pixels\n");
  return 0;
}
