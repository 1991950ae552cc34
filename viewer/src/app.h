// terrain-view as a library call: options in, exit code out (0 ok, 1 failure, 2 usage error,
// 77 no Vulkan device). main() only parses and calls run_viewer().
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "camera.h"
#include "renderer.h"

namespace terrain::view {

struct ViewerOptions {
  std::string archive;
  bool headless = false;
  std::string out_png;
  std::optional<std::array<double, 3>> camera, look_at;
  std::optional<double> yaw_deg, pitch_deg;
  double fovy_deg = 60;
  uint32_t width = 1280, height = 720;
  int frames = 0;              // 0: headless renders until streaming settles (at most max_frames)
  int max_frames = 400;
  std::string path_file;       // camera path: "X Y Z LX LY LZ" or "X Y Z YAW PITCH" per line (degrees)
  std::string stats_json;
  FrameSettings settings;      // error target, culling, holes, debug view, clear colour ...
  uint32_t budget_nodes = 0;  // 0 = automatic: 512, or roots + 512 without overview levels
  uint32_t worker_threads = 0;
  uint32_t upload_threads = 0;     // RendererConfig::upload_threads
  uint32_t max_deliveries = 128;  // nodes the streamer hands over per frame
  std::string cache_dir;           // an http(s) archive's ranges kept here across runs (HttpOptions::cache_dir)
  uint64_t cache_limit_mb = 1024;
  bool load_all = false;       // decode every node up front instead of streaming
  std::string atlas = "auto";      // bc | rgba8 | auto (rgba8 on CPU devices: see RendererConfig::decode_bc)
  std::string far_light = "auto";  // texel | pixel | auto (texel on CPU devices: see RendererConfig::prelit_far)
  std::string holes = "auto";  // nan | discard | auto (nan on lavapipe, where a test checks it; discard elsewhere)
  bool validation = false;
  bool quiet = false;
};

// Parses argv; returns false with `exit_code` set when the program should stop (help: 0, usage: 2).
bool parse_viewer_options(int argc, char** argv, ViewerOptions& out, int& exit_code);

// Writes the last headless frame (RGBA8 sRGB-encoded, rows top to bottom). main() passes the
// OpenImageIO PNG writer (image_io.h); tests pass their own, so they never load OpenImageIO.
using ImageWriter = Status (*)(const std::string& path, const std::vector<uint8_t>& rgba, uint32_t width, uint32_t height);

int run_viewer(const ViewerOptions& options, ImageWriter write_image);

// Camera path keys (frame coordinates); loaded from a file.
struct PathKey {
  Camera camera;
};
Status load_camera_path(const std::string& path, double fovy_rad, std::vector<PathKey>& out);
// Camera at parameter t in [0, 1] along the keys (linear in position and angles).
Camera sample_path(const std::vector<PathKey>& keys, double t);

// Parses "A,B,C" into three doubles.
bool parse_triple(const std::string& text, std::array<double, 3>& out);

}  // namespace terrain::view
