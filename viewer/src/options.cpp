#include <CLI/CLI.hpp>

#include <cstdio>
#include <sstream>

#include "app.h"
#include "cli_checks.h"
#include "terrain/output_paths.h"

namespace terrain::view {

bool parse_triple(const std::string& text, std::array<double, 3>& out) {
  std::istringstream in(text);
  char c1 = 0, c2 = 0;
  if (!(in >> out[0] >> c1 >> out[1] >> c2 >> out[2]) || c1 != ',' || c2 != ',') return false;
  in >> std::ws;
  return in.eof();
}

bool parse_viewer_options(int argc, char** argv, ViewerOptions& o, int& exit_code) {
  CLI::App app{
      "terrain-view: renders a terrain archive the Far Cry 5 way (GPU traversal, LOD map, patch culling, "
      "stitching, splat shading) to check what was cooked. Window by default; --headless renders offscreen."};
  app.footer(
      "Coordinates are the archive's frame metres (x east, y north, z height), e.g. UTM.\n"
      "Exit codes: 0 ok, 1 failure, 2 usage error, 77 no Vulkan device.\n"
      "Device: $TERRAIN_VIEW_DEVICE (index or name substring) overrides the choice; on a machine without a GPU\n"
      "set VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json for lavapipe.\n"
      "Window keys: WASD move, Q/E down/up, drag to look, wheel = speed, 0-8 debug views, C print camera.");
  std::string camera, look_at, size = "1280x720", clear, debug = "none";
  app.add_option("archive", o.archive, "terrain archive (.terrain), or its http:// or https:// URL")->required();
  app.add_flag("--headless", o.headless, "render offscreen (no window); needs --out or --stats");
  app.add_option("--out", o.out_png, "PNG of the last frame (headless)");
  app.add_option("--camera", camera, "camera position X,Y,Z (frame metres)");
  app.add_option("--look-at", look_at, "point to look at X,Y,Z (frame metres)");
  app.add_option("--yaw", o.yaw_deg, "heading in degrees (0 north, 90 east), instead of --look-at");
  app.add_option("--pitch", o.pitch_deg, "pitch in degrees (negative looks down)");
  app.add_option("--fov", o.fovy_deg, "vertical field of view, degrees")->check(CLI::Range(5.0, 150.0));
  app.add_option("--size", size, "image size WxH")->capture_default_str();
  app.add_option("--frames", o.frames,
                 "frames to render (headless default: until streaming settles, at most --max-frames)");
  app.add_option("--max-frames", o.max_frames, "cap of the settle loop")->capture_default_str();
  app.add_option("--path", o.path_file, "camera path file: one key per line, 'X Y Z LX LY LZ' or 'X Y Z YAW PITCH'");
  app.add_option("--stats", o.stats_json, "write per-frame timings and counts as JSON");
  app.add_option("--clear", clear, "background colour R,G,B (0..1, or 0..255)");
  app.add_option("--debug", debug, "validation view: lod, nodes, patches, cones, holes, normals, splat, wire")
      ->check(CLI::IsMember({"none", "lod", "nodes", "patches", "cones", "holes", "normals", "splat", "wire"}));
  app.add_option("--error", o.settings.error_target_px, "screen-space error target, pixels")
      ->capture_default_str()->check(terrain::cli::number_check("> 0 and <= 1000", [](double v) { return v > 0 && v <= 1000; }));
  app.add_option("--budget", o.budget_nodes, "resident node budget of the streamer; 0 = automatic (512, or roots + 512 for an archive without overview levels)")
      ->capture_default_str()->check(terrain::cli::int_range(1, 65534));
  app.add_option("--threads", o.worker_threads, "streamer worker threads (0 = all cores)")->check(terrain::cli::int_range(0, 256));
  app.add_option("--cache-dir", o.cache_dir,
                 "an http(s):// archive: keep the ranges read in this folder (made when absent), so the next run reads "
                 "them from disk; versions least recently opened are evicted to stay within --cache-limit-mb");
  app.add_option("--cache-limit-mb", o.cache_limit_mb, "disk the --cache-dir folder may take, MB")
      ->capture_default_str()->check(CLI::Range(uint64_t(1), uint64_t(1) << 30));
  app.add_option("--upload-threads", o.upload_threads,
                 "threads that prepare delivered nodes for upload: decoding, lighting, patch bounds and errors (0 = all cores)")
      ->check(terrain::cli::int_range(0, 256));
  app.add_option("--deliveries", o.max_deliveries, "most nodes uploaded per frame (small values show the streaming frontier)")
      ->capture_default_str()->check(CLI::Range(1u, 65535u));
  app.add_option("--atlas", o.atlas, "normal/albedo atlas format: bc (as cooked), rgba8 (decoded at upload), auto (rgba8 on CPU devices)")
      ->capture_default_str()->check(CLI::IsMember({"auto", "bc", "rgba8"}));
  app.add_option("--far-light", o.far_light,
                 "far-field lighting: texel (lit once per texel when a node arrives; one texture sample per pixel), "
                 "pixel (per pixel), auto (texel on CPU devices)")
      ->capture_default_str()->check(CLI::IsMember({"auto", "texel", "pixel"}));
  app.add_flag("--load-all", o.load_all, "decode every node up front instead of streaming (small archives)");
  bool no_frustum = false, no_cone = false, no_holes = false, no_splat = false, no_decimate = false;
  app.add_flag("--no-frustum-cull", no_frustum, "draw patches outside the view too");
  app.add_flag("--no-cone-cull", no_cone, "no patch-cone backface culling");
  app.add_flag("--no-holes", no_holes, "draw hole vertices as terrain");
  app.add_option("--hole-method", o.holes,
                 "how hole vertices drop their triangles: nan (FC5's NaN clip position, undefined by the spec), discard "
                 "(defined), auto (nan on lavapipe, where tests check it; discard elsewhere)")
      ->capture_default_str()->check(CLI::IsMember({"auto", "nan", "discard"}));
  app.add_flag("--no-splat", no_splat, "far (baked) shading everywhere");
  app.add_flag("--no-decimate", no_decimate, "draw every root patch with all its vertices (no per-patch decimation)");
  app.add_flag("--validation", o.validation, "enable the Khronos validation layer");
  app.add_flag("-q,--quiet", o.quiet, "no progress or summary on stderr");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    exit_code = app.exit(e) == 0 ? 0 : 2;
    return false;
  }
  auto usage = [&](const std::string& msg) {
    std::fprintf(stderr, "terrain-view: %s\nRun with --help for usage.\n", msg.c_str());
    exit_code = 2;
    return false;
  };
  if (!camera.empty()) {
    std::array<double, 3> v;
    if (!parse_triple(camera, v)) return usage("--camera expects X,Y,Z, got '" + camera + "'");
    o.camera = v;
  }
  if (!look_at.empty()) {
    std::array<double, 3> v;
    if (!parse_triple(look_at, v)) return usage("--look-at expects X,Y,Z, got '" + look_at + "'");
    o.look_at = v;
  }
  if (o.look_at && (o.yaw_deg || o.pitch_deg)) return usage("give either --look-at or --yaw/--pitch, not both");
  unsigned w = 0, h = 0;
  char x = 0;
  std::istringstream sz(size);
  if (!(sz >> w >> x >> h) || x != 'x' || w < 16 || h < 16 || w > 16384 || h > 16384)
    return usage("--size expects WxH between 16 and 16384, got '" + size + "'");
  o.width = w;
  o.height = h;
  if (!clear.empty()) {
    std::array<double, 3> c;
    if (!parse_triple(clear, c)) return usage("--clear expects R,G,B, got '" + clear + "'");
    const bool bytes = c[0] > 1 || c[1] > 1 || c[2] > 1;
    for (int k = 0; k < 3; ++k) {
      const double v = bytes ? c[size_t(k)] / 255.0 : c[size_t(k)];
      if (v < 0 || v > 1) return usage("--clear components must be 0..1 or 0..255");
      o.settings.clear[k] = float(v);
    }
  }
  const char* names[] = {"none", "lod", "nodes", "patches", "cones", "holes", "normals", "splat", "wire"};
  for (int i = 0; i < 9; ++i)
    if (debug == names[i]) o.settings.debug = i;
  o.settings.frustum_cull = !no_frustum;
  o.settings.cone_cull = !no_cone;
  o.settings.holes = !no_holes;
  o.settings.splat = !no_splat;
  o.settings.decimate = !no_decimate;
  if (o.headless && o.out_png.empty() && o.stats_json.empty()) return usage("--headless needs --out FILE.png or --stats FILE.json");
  if (o.frames < 0) return usage("--frames must be >= 0");
  // --out and --stats never replace the archive, the camera path, each other, a device or a FIFO.
  std::vector<NamedPath> inputs{{"archive", o.archive}}, outputs;
  if (!o.path_file.empty()) inputs.push_back({"--path", o.path_file});
  if (!o.out_png.empty()) outputs.push_back({"--out", o.out_png});
  if (!o.stats_json.empty()) outputs.push_back({"--stats", o.stats_json});
  if (const Status st = check_output_paths(inputs, outputs); !st.ok()) {
    if (st.code == Error::invalid_argument) return usage(st.message);
    std::fprintf(stderr, "terrain-view: %s\n", st.to_string().c_str());
    exit_code = 1;
    return false;
  }
  return true;
}

}  // namespace terrain::view
