#include "app.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "cli_checks.h"
#include "session.h"
#include "window.h"

namespace terrain::view {
namespace {

int fail(const Status& s) {
  std::fprintf(stderr, "terrain-view: %s: %s\n", error_name(s.code), s.message.c_str());
  // invalid_argument: a flag (or the --path file it names) the archive or device cannot take: usage.
  return is_no_device(s) ? 77 : s.code == Error::invalid_argument ? 2 : 1;
}

double wrap_angle(double a) { return std::remainder(a, 2 * M_PI); }

}  // namespace

Status load_camera_path(const std::string& path, double fovy, std::vector<PathKey>& out) {
  std::ifstream in(path);
  if (!in) return Status::failure(Error::io_open, "cannot open camera path " + path);
  std::string line;
  int number = 0;
  while (cli::next_line(in, line, number)) {
    std::istringstream ls(line);
    std::vector<double> v;
    double x;
    while (ls >> x) v.push_back(x);
    if (!ls.eof())
      return Status::failure(Error::invalid_argument, path + ":" + std::to_string(number) + ": expected numbers");
    if (v.empty()) continue;
    PathKey k;
    k.camera.fovy = fovy;
    for (int i = 0; i < 3 && i < int(v.size()); ++i) k.camera.position[i] = v[size_t(i)];
    if (v.size() == 6) {
      const double t[3] = {v[3], v[4], v[5]};
      look_at(k.camera, t);
    } else if (v.size() == 5) {
      k.camera.yaw = v[3] * M_PI / 180.0;
      k.camera.pitch = v[4] * M_PI / 180.0;
    } else {
      return Status::failure(Error::invalid_argument, path + ":" + std::to_string(number) +
                                                          ": expected 'X Y Z LX LY LZ' or 'X Y Z YAW PITCH', got " +
                                                          std::to_string(v.size()) + " numbers");
    }
    out.push_back(k);
  }
  if (out.empty()) return Status::failure(Error::invalid_argument, "camera path " + path + " has no keys");
  return Status::success();
}

Camera sample_path(const std::vector<PathKey>& keys, double t) {
  if (keys.size() == 1) return keys[0].camera;
  const double f = std::clamp(t, 0.0, 1.0) * double(keys.size() - 1);
  const size_t i = std::min(size_t(f), keys.size() - 2);
  const double a = f - double(i);
  const Camera& c0 = keys[i].camera;
  const Camera& c1 = keys[i + 1].camera;
  Camera c = c0;
  for (int k = 0; k < 3; ++k) c.position[k] = c0.position[k] + (c1.position[k] - c0.position[k]) * a;
  c.yaw = c0.yaw + wrap_angle(c1.yaw - c0.yaw) * a;
  c.pitch = c0.pitch + (c1.pitch - c0.pitch) * a;
  return c;
}

int run_viewer(const ViewerOptions& o, ImageWriter write_image) {
  if (!o.headless) return run_window(o);
  std::unique_ptr<Session> session;
  Status st = open_session(o, {}, false, session);
  if (!st.ok()) return fail(st);
  Session& s = *session;
  std::vector<PathKey> path;
  if (!o.path_file.empty()) {
    st = load_camera_path(o.path_file, o.fovy_deg * M_PI / 180.0, path);
    if (!st.ok()) return fail(st);
  }
  Camera camera = initial_camera(s);
  const int frames = o.frames > 0 ? o.frames : (path.empty() ? 0 : int(path.size()));
  FrameRecord rec;
  if (frames > 0) {
    for (int f = 0; f < frames; ++f) {
      if (!path.empty()) {
        camera = sample_path(path, frames == 1 ? 0.0 : double(f) / double(frames - 1));
        camera.near_m = initial_camera(s).near_m;
      }
      st = render_frame(s, camera, f == frames - 1, rec);
      if (!st.ok()) return fail(st);
    }
  } else {
    // Until streaming settles (nothing pending for this view), then one more frame to show it.
    int f = 0;
    for (; f < o.max_frames; ++f) {
      st = render_frame(s, camera, false, rec);
      if (!st.ok()) return fail(st);
      if (s.source->settled()) break;
    }
    st = render_frame(s, camera, true, rec);
    if (!st.ok()) return fail(st);
    if (!o.quiet && f == o.max_frames)
      std::fprintf(stderr, "terrain-view: streaming did not settle within %d frames\n", o.max_frames);
  }
  if (!o.out_png.empty()) {
    if (!write_image) return fail(Status::failure(Error::invalid_argument, "no image writer to write " + o.out_png));
    std::vector<uint8_t> rgba;
    read_color(s.target, rgba);
    st = write_image(o.out_png, rgba, s.target.width, s.target.height);
    if (!st.ok()) return fail(st);
  }
  if (!o.stats_json.empty()) {
    st = write_stats_json(s, o.stats_json);
    if (!st.ok()) return fail(st);
  }
  if (s.ctx.validation_errors > 0) {
    std::fprintf(stderr, "terrain-view: %u validation errors\n", s.ctx.validation_errors);
    return 1;
  }
  // A node that failed to load (bad payload, archive truncated or unreadable since open) is drawn as
  // its parent: the picture is not the archive's. Each failure was named on stderr as it happened.
  if (const uint32_t failed = s.source->stats().failed; failed > 0) {
    std::fprintf(stderr, "terrain-view: %u nodes failed to load (named above); their parents were drawn instead\n", failed);
    return 1;
  }
  if (!o.quiet) {
    const FrameRecord& last = s.records.back();
    std::fprintf(stderr,
                 "terrain-view: %zu frames, last: %u nodes, %u patches drawn (%u frustum-, %u cone-culled), %.2f M "
                 "triangles, GPU %.2f ms (traversal %.3f, LOD map %.3f, patches %.3f, draw %.2f), %u resident%s%s\n",
                 s.records.size(), last.gpu.nodes, last.gpu.patches_drawn, last.gpu.culled_frustum, last.gpu.culled_cone,
                 double(last.gpu.triangles) / 1e6, last.gpu.gpu_total_ms, last.gpu.gpu_traverse_ms, last.gpu.gpu_lodmap_ms,
                 last.gpu.gpu_patches_ms, last.gpu.gpu_draw_ms, last.source.resident, o.out_png.empty() ? "" : ", wrote ",
                 o.out_png.c_str());
  }
  return 0;
}

}  // namespace terrain::view
