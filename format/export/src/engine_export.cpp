// terrain-export as a library: plan (lattice, tiles, file names), then one pass per tile that reads
// the surface band by band and streams the rows into the images (memory: a few rows per output,
// whatever the export's size).
#include "terrain/engine_export.h"

#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <unordered_map>

#include "terrain/sample.h"

namespace terrain::engine_export {

// ---- Unreal size and Z rules ------------------------------------------------------------------

bool is_unreal_size(int side) { return std::find(std::begin(kUnrealSizes), std::end(kUnrealSizes), side) != std::end(kUnrealSizes); }

int unreal_size_for(int samples) {
  for (int s : kUnrealSizes)
    if (s >= samples) return s;
  return 0;
}

UnrealZ unreal_z_for(double min_m, double max_m) {
  UnrealZ z;
  // Centre to 0.01 cm (two decimals print exactly), then the Z scale that reaches both ends from it:
  // 32767 steps above and 32768 below value 32768. Rounded up to 1e-4 so the printed value covers
  // the range; at least 0.01 so a flat export still has a usable scale.
  z.location_z_cm = std::round((min_m + max_m) * 0.5 * 100.0 * 100.0) / 100.0;
  const double centre_m = z.location_z_cm / 100.0;
  const double half_m = std::max(max_m - centre_m, centre_m - min_m);
  double scale = half_m * 12800.0 / 32767.0;
  scale = std::ceil(scale * 1e4 * (1 + 1e-12)) / 1e4;
  z.z_scale = std::max(scale, 0.01);
  z.step_m = z.z_scale / 12800.0;
  return z;
}

uint16_t unreal_encode(const UnrealZ& z, double height_m) {
  const double v = std::round(32768.0 + (height_m - z.location_z_cm / 100.0) / z.step_m);
  return uint16_t(std::clamp(v, 1.0, 65535.0));  // 0 is the hole value
}

double unreal_decode(const UnrealZ& z, uint16_t v) { return z.location_z_cm / 100.0 + (double(v) - 32768.0) * z.step_m; }

// ---- Plan -------------------------------------------------------------------------------------
namespace {

Status bad(std::string msg) { return Status::failure(Error::invalid_argument, std::move(msg)); }

bool name_ok(const std::string& n) {
  if (n.empty() || n.size() > 100) return false;
  return std::all_of(n.begin(), n.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_'; });
}

// Material names as file name parts: other characters become '_'; a clash gets the palette index.
std::vector<std::string> layer_names(const WorldInfo& w) {
  std::vector<std::string> out;
  for (size_t i = 0; i < w.palette.size(); ++i) {
    std::string n = w.palette[i].name.empty() ? fmt::format("material{}", i) : w.palette[i].name;
    for (char& c : n)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_')) c = '_';
    if (std::find(out.begin(), out.end(), n) != out.end()) n += fmt::format("_{}", i);
    out.push_back(n);
  }
  return out;
}

std::string tile_suffix(const Plan& p, int tx, int ty) { return p.tiled ? fmt::format("_x{}_y{}", tx, ty) : std::string(); }
std::string path_in(const Plan& p, const std::string& file) { return (std::filesystem::path(p.options.out_dir) / file).string(); }

struct TileFiles {
  std::string height, holes_or_control;
  std::vector<std::string> weights;  // unreal: one per palette material
};
TileFiles tile_files(const Plan& p, const std::vector<std::string>& layers, int tx, int ty) {
  const std::string base = p.options.name, sfx = tile_suffix(p, tx, ty);
  TileFiles f;
  if (p.options.target == Target::unreal) {
    f.height = path_in(p, base + sfx + ".png");
    f.holes_or_control = path_in(p, base + "_visibility" + sfx + ".png");
    for (const std::string& l : layers) f.weights.push_back(path_in(p, base + "_weight_" + l + sfx + ".png"));
  } else {
    f.height = path_in(p, base + sfx + "_height.exr");
    f.holes_or_control = path_in(p, base + sfx + "_control.png");
  }
  return f;
}
std::string json_path(const Plan& p) { return path_in(p, p.options.name + ".json"); }

// The terrain-cook flags that cook tile (tx, ty)'s heightmap back into frame metres: its own
// south-west sample as the origin, holes (Unreal's 0, Godot's NaN) kept as holes.
std::string cook_back_flags(const Plan& p, const UnrealZ& z, int tx, int ty) {
  const TileOrigin o = tile_origin(p, tx, ty);
  std::string f = fmt::format("--crs local --spacing {:.17g} --origin {:.17g},{:.17g}", p.spacing_m, o.x_m, o.y_m);
  if (p.options.target == Target::unreal)
    f += fmt::format(" --height-scale {:.17g} --height-offset {:.17g} --nodata-value {}", z.step_m,
                     z.location_z_cm / 100.0 - 32768.0 * z.step_m, kUnrealHoleValue);
  return f + " --nodata hole";
}
std::string collision_path(const Plan& p) { return path_in(p, p.options.name + "_collision.f32"); }
std::string collision_holes_path(const Plan& p) { return path_in(p, p.options.name + "_collision_holes.u8"); }

}  // namespace

TileOrigin tile_origin(const Plan& p, int tx, int ty) {
  return {p.west_x_m + double(tx) * p.tile_step * p.spacing_m,
          p.north_y_m - (double(ty) * p.tile_step + (p.tile_size - 1)) * p.spacing_m};
}

Status plan_export(const ArchiveReader& reader, const Options& o, Plan& plan) {
  plan = Plan{};
  plan.options = o;
  if (!reader.is_open()) return bad("archive is not open");
  if (o.out_dir.empty()) return bad("no output directory");
  if (!name_ok(o.name)) return bad("--name '" + o.name + "': expects 1..100 letters, digits, '-' or '_'");
  const WorldInfo& w = reader.world();
  const auto per_level = reader.nodes_per_level();
  int level = o.level;
  if (level < 0) {
    for (level = 0; level < kLevelCount && per_level[size_t(level)] == 0; ++level) {
    }
    if (level == kLevelCount) return Status::failure(Error::no_data, "the archive has no nodes");
  }
  if (level >= kLevelCount) return bad(fmt::format("--level {}: expects 0..{}", level, kRootLevel));
  plan.level = level;
  const double s = vertex_spacing_m(level);
  plan.spacing_m = s;
  Rect r = o.rect.value_or(Rect{w.extent_min_x_m, w.extent_min_y_m, w.extent_max_x_m, w.extent_max_y_m});
  for (double v : {r.min_x, r.min_y, r.max_x, r.max_y})
    if (!std::isfinite(v)) return bad("rectangle: coordinates must be finite");
  if (!(r.max_x > r.min_x && r.max_y > r.min_y)) return bad("rectangle: expects MIN_X < MAX_X and MIN_Y < MAX_Y");
  const double frame_max_x = w.origin_x_m + w.roots_x * node_size_m(kRootLevel);
  const double frame_max_y = w.origin_y_m + w.roots_y * node_size_m(kRootLevel);
  if (r.max_x <= w.origin_x_m || r.min_x >= frame_max_x || r.max_y <= w.origin_y_m || r.min_y >= frame_max_y)
    return bad(fmt::format("rectangle {},{} .. {},{} lies outside the archive's frame (x {} .. {}, y {} .. {})", r.min_x, r.min_y,
                           r.max_x, r.max_y, w.origin_x_m, frame_max_x, w.origin_y_m, frame_max_y));
  // Widen to the level's vertex lattice (a tiny tolerance keeps a rectangle already on it as is).
  const double k_w = std::floor((r.min_x - w.origin_x_m) / s + 1e-9), k_e = std::ceil((r.max_x - w.origin_x_m) / s - 1e-9);
  const double k_s = std::floor((r.min_y - w.origin_y_m) / s + 1e-9), k_n = std::ceil((r.max_y - w.origin_y_m) / s - 1e-9);
  if (k_e - k_w + 1 > 262144 || k_n - k_s + 1 > 262144)
    return bad(fmt::format("rectangle is {} x {} samples at level {} ({} m): at most 262144 per side; use a coarser level or "
                           "a smaller rectangle",
                           k_e - k_w + 1, k_n - k_s + 1, level, s));
  plan.west_x_m = w.origin_x_m + k_w * s;
  plan.north_y_m = w.origin_y_m + k_n * s;
  plan.width = int(k_e - k_w) + 1;
  plan.height = int(k_n - k_s) + 1;

  if (o.target == Target::unreal) {
    const int max_side = o.tile_size == 0 ? kUnrealMaxSize : o.tile_size;
    if (!is_unreal_size(max_side))
      return bad(fmt::format("--tile-size {}: Unreal tiles must be a recommended size (127, 253, 505, 1009, 2017, 4033, 8129)",
                             o.tile_size));
    const int need = std::max(plan.width, plan.height);
    if (need <= max_side) {  // one square heightmap, no suffix
      plan.tile_size = unreal_size_for(need);
      plan.tile_step = plan.tile_size - 1;
    } else {  // World Partition tiles sharing their edge rows
      plan.tiled = true;
      plan.tile_size = max_side;
      plan.tile_step = max_side - 1;
      plan.tiles_x = (plan.width - 1 + plan.tile_step - 1) / plan.tile_step;
      plan.tiles_y = (plan.height - 1 + plan.tile_step - 1) / plan.tile_step;
    }
    plan.image_width = plan.tiles_x * plan.tile_step + 1;
    plan.image_height = plan.tiles_y * plan.tile_step + 1;
  } else {
    const int region = o.tile_size == 0 ? 1024 : o.tile_size;
    if (region < 16 || region > 8192) return bad(fmt::format("--tile-size {}: Godot regions are 16..8192 samples", o.tile_size));
    plan.tiled = true;
    plan.tile_size = region;
    plan.tile_step = region;
    plan.tiles_x = (plan.width + region - 1) / region;
    plan.tiles_y = (plan.height + region - 1) / region;
    plan.image_width = plan.tiles_x * region;
    plan.image_height = plan.tiles_y * region;
  }
  const std::vector<std::string> layers = layer_names(w);
  for (int ty = 0; ty < plan.tiles_y; ++ty)
    for (int tx = 0; tx < plan.tiles_x; ++tx) {
      TileFiles f = tile_files(plan, layers, tx, ty);
      plan.files.push_back(f.height);
      plan.files.push_back(f.holes_or_control);
      plan.files.insert(plan.files.end(), f.weights.begin(), f.weights.end());
    }
  if (o.target == Target::godot) {
    plan.files.push_back(collision_path(plan));
    plan.files.push_back(collision_holes_path(plan));
  }
  plan.files.push_back(json_path(plan));
  return Status::success();
}

// ---- Run --------------------------------------------------------------------------------------
namespace {

// Splat weights at a sample: the answering node's 65x65 splat map, bilinear over the one-hot ids of
// the 4 splat samples around the point (splat sample (i, j) is at vertex (2i, 2j)).
struct SplatReader {
  const ArchiveReader& reader;
  std::unordered_map<int64_t, std::unique_ptr<uint8_t[]>> cache;  // per tile: bounded by the tile's nodes
  std::unique_ptr<NodeData> scratch = std::make_unique<NodeData>();

  struct Weights {
    uint8_t id[4] = {};
    double w[4] = {};
  };
  Status at(const NodeKey& key, double x, double y, Weights& out) {
    const int64_t index = reader.find(key);
    if (index < 0) return Status::failure(Error::internal, "sampler answered with a node that is not in the directory");
    auto it = cache.find(index);
    if (it == cache.end()) {
      TERRAIN_TRY(reader.decode_node(size_t(index), *scratch, kSectionSplat));
      auto copy = std::make_unique<uint8_t[]>(kSplatCount);
      std::copy(scratch->splat.begin(), scratch->splat.end(), copy.get());
      it = cache.emplace(index, std::move(copy)).first;
    }
    const WorldInfo& w = reader.world();
    const double size = node_size_m(int(key.level)), s2 = 2 * vertex_spacing_m(int(key.level));
    const double u = std::clamp((x - w.origin_x_m - key.x * size) / s2, 0.0, double(kSplatSamples - 1));
    const double v = std::clamp((y - w.origin_y_m - key.y * size) / s2, 0.0, double(kSplatSamples - 1));
    const int i = std::min(int(u), kSplatSamples - 2), j = std::min(int(v), kSplatSamples - 2);
    const double fu = u - i, fv = v - j;
    const uint8_t* sp = it->second.get();
    out.id[0] = sp[j * kSplatSamples + i];
    out.id[1] = sp[j * kSplatSamples + i + 1];
    out.id[2] = sp[(j + 1) * kSplatSamples + i];
    out.id[3] = sp[(j + 1) * kSplatSamples + i + 1];
    out.w[0] = (1 - fu) * (1 - fv);
    out.w[1] = fu * (1 - fv);
    out.w[2] = (1 - fu) * fv;
    out.w[3] = fu * fv;
    return Status::success();
  }
};

// Sequential scanline writer of one image (row 0 first = north).
struct ImageFile {
  std::unique_ptr<OIIO::ImageOutput> out;
  std::string path;
  OIIO::TypeDesc type;
  Status open(const std::string& p, int side, int channels, OIIO::TypeDesc t) {
    path = p;
    type = t;
    out = OIIO::ImageOutput::create(path);
    if (!out) return Status::failure(Error::io_write, path + ": no image writer (" + OIIO::geterror() + ")");
    OIIO::ImageSpec spec(side, side, channels, t);
    if (channels == 4) spec.attribute("oiio:UnassociatedAlpha", 1);  // straight alpha: RGB stays as written
    if (!out->open(path, spec)) return Status::failure(Error::io_write, path + ": " + out->geterror());
    return Status::success();
  }
  Status row(int y, const void* data) {
    if (!out->write_scanline(y, 0, type, data)) return Status::failure(Error::io_write, path + ": " + out->geterror());
    return Status::success();
  }
  Status close() {
    if (out && !out->close()) return Status::failure(Error::io_write, path + ": " + out->geterror());
    out.reset();
    return Status::success();
  }
};

// Lowest and highest height the answering nodes can give inside the lattice: nodes that may answer
// (not covered by all four children) and touch the padded lattice. Heights interpolate vertices,
// so they stay inside [min, max] of the node that answers.
void lattice_range(const ArchiveReader& reader, const Plan& p, double& lo, double& hi) {
  const WorldInfo& w = reader.world();
  const double x0 = p.west_x_m, x1 = p.west_x_m + (p.image_width - 1) * p.spacing_m;
  const double y1 = p.north_y_m, y0 = p.north_y_m - (p.image_height - 1) * p.spacing_m;
  lo = std::numeric_limits<double>::infinity();
  hi = -lo;
  for (const NodeRecord& r : reader.nodes()) {
    if (r.child_mask == 0xF) continue;
    const double size = node_size_m(int(r.key.level));
    const double nx0 = w.origin_x_m + r.key.x * size, ny0 = w.origin_y_m + r.key.y * size;
    if (nx0 > x1 || nx0 + size < x0 || ny0 > y1 || ny0 + size < y0) continue;
    if (r.min_height > r.max_height) continue;  // all holes
    lo = std::min(lo, units_to_metres(r.min_height));
    hi = std::max(hi, units_to_metres(r.max_height));
  }
  if (!(lo <= hi)) lo = hi = 0;
}

// One band of rows of a tile, sampled in 16x16 blocks so the sampler's node cache holds the
// nodes a block touches.
constexpr int kBand = 16;

struct Band {
  int rows = 0, cols = 0;
  std::vector<double> height;       // NaN: hole or no terrain
  std::vector<uint8_t> ids;         // 4 per sample
  std::vector<float> weights;       // 4 per sample
};

Status sample_band(SurfaceSampler& sampler, SplatReader& splat, const Plan& p, int row0, int col0, int rows, int cols,
                   bool want_splat, Band& b) {
  b.rows = rows;
  b.cols = cols;
  b.height.assign(size_t(rows) * cols, NAN);
  b.ids.assign(size_t(rows) * cols * 4, 0);
  b.weights.assign(size_t(rows) * cols * 4, 0.0f);
  for (int bc = 0; bc < cols; bc += kBand)
    for (int r = 0; r < rows; ++r)
      for (int c = bc; c < std::min(cols, bc + kBand); ++c) {
        const double x = p.west_x_m + double(col0 + c) * p.spacing_m;
        const double y = p.north_y_m - double(row0 + r) * p.spacing_m;
        std::optional<SurfaceSample> h;
        TERRAIN_TRY(sampler.sample(x, y, h));
        if (!h) continue;
        const size_t k = size_t(r) * cols + c;
        b.height[k] = h->height_m;
        if (!want_splat) continue;
        SplatReader::Weights sw;
        TERRAIN_TRY(splat.at(h->node, x, y, sw));
        for (int q = 0; q < 4; ++q) {
          b.ids[k * 4 + q] = sw.id[q];
          b.weights[k * 4 + q] = float(sw.w[q]);
        }
      }
  return Status::success();
}

// Merges the 4 corner weights by id; returns the ids sorted by weight, heaviest first.
int merged(const Band& b, size_t k, uint8_t* id, float* wt) {
  int n = 0;
  for (int q = 0; q < 4; ++q) {
    const uint8_t m = b.ids[k * 4 + q];
    const float v = b.weights[k * 4 + q];
    int f = 0;
    while (f < n && id[f] != m) ++f;
    if (f == n) {
      id[n] = m;
      wt[n++] = v;
    } else {
      wt[f] += v;
    }
  }
  for (int a = 1; a < n; ++a)  // tiny insertion sort, ties by id for determinism
    for (int c = a; c > 0 && (wt[c] > wt[c - 1] || (wt[c] == wt[c - 1] && id[c] < id[c - 1])); --c) {
      std::swap(wt[c], wt[c - 1]);
      std::swap(id[c], id[c - 1]);
    }
  return n;
}

Status pwrite_all(int fd, const void* data, size_t bytes, off_t offset, const std::string& path) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (bytes > 0) {
    const ssize_t n = ::pwrite(fd, p, bytes, offset);
    if (n <= 0) return Status::failure(Error::io_write, path + ": write failed");
    p += n;
    bytes -= size_t(n);
    offset += n;
  }
  return Status::success();
}

struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

Status run_export(const ArchiveReader& reader, const Plan& p, const ProgressFn& progress, Result& result) {
  result = Result{};
  const WorldInfo& w = reader.world();
  std::error_code ec;
  std::filesystem::create_directories(p.options.out_dir, ec);
  if (ec) return Status::failure(Error::io_write, p.options.out_dir + ": cannot create: " + ec.message());
  const bool unreal = p.options.target == Target::unreal;
  const std::vector<std::string> layers = layer_names(w);
  const size_t n_layers = layers.size();

  double range_lo = 0, range_hi = 0;
  lattice_range(reader, p, range_lo, range_hi);
  if (unreal) result.unreal = unreal_z_for(range_lo, range_hi);
  double lowest_sampled = std::numeric_limits<double>::infinity(), highest_sampled = -lowest_sampled;

  // Godot collision heightfield: the rectangle's samples (no padding), float32 little-endian
  // row-major from the north row, holes written as the lowest height of the range; mask 1 = hole.
  Fd coll, coll_holes;
  if (!unreal) {
    coll.fd = ::open(collision_path(p).c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    coll_holes.fd = ::open(collision_holes_path(p).c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (coll.fd < 0 || coll_holes.fd < 0) return Status::failure(Error::io_write, collision_path(p) + ": cannot create");
  }
  std::vector<uint64_t> layer_samples(n_layers, 0);  // samples with weight > 0, over all tiles
  SurfaceSampler sampler(reader);
  const double total = double(p.tiles_x) * p.tiles_y * double(p.tile_size) * p.tile_size;
  double done = 0;
  for (int ty = 0; ty < p.tiles_y; ++ty)
    for (int tx = 0; tx < p.tiles_x; ++tx) {
      const TileFiles files = tile_files(p, layers, tx, ty);
      const int T = p.tile_size, row0 = ty * p.tile_step, col0 = tx * p.tile_step;
      result.tile_hole_samples.push_back(0);
      ImageFile height, mask;
      std::vector<ImageFile> weight(unreal ? n_layers : 0);
      TERRAIN_TRY(height.open(files.height, T, 1, unreal ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::FLOAT));
      TERRAIN_TRY(mask.open(files.holes_or_control, T, unreal ? 1 : 4, OIIO::TypeDesc::UINT8));
      for (size_t m = 0; m < weight.size(); ++m)
        TERRAIN_TRY(weight[m].open(files.weights[m], T, 1, OIIO::TypeDesc::UINT8));
      SplatReader splat{reader, {}};
      Band band;
      std::vector<uint16_t> row16(static_cast<size_t>(T));
      std::vector<float> rowf(static_cast<size_t>(T));
      std::vector<uint8_t> row8(size_t(T) * (unreal ? 1 : 4));
      std::vector<std::vector<uint8_t>> roww(weight.size(), std::vector<uint8_t>(size_t(T)));
      for (int r0 = 0; r0 < T; r0 += kBand) {
        const int rows = std::min(kBand, T - r0);
        TERRAIN_TRY(sample_band(sampler, splat, p, row0 + r0, col0, rows, T, true, band));
        for (int r = 0; r < rows; ++r) {
          const int grow = row0 + r0 + r;
          for (int c = 0; c < T; ++c) {
            const size_t k = size_t(r) * T + c;
            const double h = band.height[k];
            const bool hole = std::isnan(h);
            ++result.samples;
            if (hole) {
              ++result.hole_samples;
              ++result.tile_hole_samples.back();
            } else {
              lowest_sampled = std::min(lowest_sampled, h);
              highest_sampled = std::max(highest_sampled, h);
            }
            uint8_t id[4];
            float wt[4];
            const int n = hole ? 0 : merged(band, k, id, wt);
            if (unreal) {
              row16[size_t(c)] = hole ? kUnrealHoleValue : unreal_encode(result.unreal, h);
              row8[size_t(c)] = hole ? 255 : 0;  // Unreal's visibility layer: painted (255) = hole
              for (auto& rw : roww) rw[size_t(c)] = 0;
              // Rounded weights that sum to exactly 255 (Unreal's weight-blended layers): the
              // rounding remainder (at most +-2) goes to the heaviest, which is >= 64.
              int v[4] = {}, sum = 0;
              for (int q = 0; q < n; ++q) sum += v[q] = int(std::lround(std::clamp(wt[q], 0.0f, 1.0f) * 255.0f));
              if (n > 0) v[0] += 255 - sum;
              for (int q = 0; q < n; ++q)
                if (id[q] < n_layers) {
                  roww[id[q]][size_t(c)] = uint8_t(v[q]);
                  if (v[q] > 0) ++layer_samples[id[q]];
                }
            } else {
              rowf[size_t(c)] = hole ? NAN : float(h);
              uint8_t* px = &row8[size_t(c) * 4];
              if (hole) {
                px[0] = px[1] = px[2] = px[3] = 0;
              } else {
                const uint8_t base = id[0], overlay = n > 1 ? id[1] : id[0];
                const float blend = n > 1 ? wt[1] / (wt[0] + wt[1]) : 0.0f;
                px[0] = base;
                px[1] = overlay;
                px[2] = uint8_t(std::lround(std::clamp(blend, 0.0f, 1.0f) * 255.0f));
                px[3] = 255;
                if (base < n_layers) ++layer_samples[base];
              }
            }
          }
          TERRAIN_TRY(height.row(r0 + r, unreal ? static_cast<const void*>(row16.data()) : rowf.data()));
          TERRAIN_TRY(mask.row(r0 + r, row8.data()));
          for (size_t m = 0; m < weight.size(); ++m)
            TERRAIN_TRY(weight[m].row(r0 + r, roww[m].data()));
          if (!unreal && grow < p.height && col0 < p.width) {  // collision rows inside the rectangle
            const int cols = std::min(T, p.width - col0);
            std::vector<float> cf(static_cast<size_t>(cols));
            std::vector<uint8_t> ch(static_cast<size_t>(cols));
            for (int c = 0; c < cols; ++c) {
              const bool hole = std::isnan(rowf[size_t(c)]);
              cf[size_t(c)] = hole ? float(range_lo) : rowf[size_t(c)];
              ch[size_t(c)] = hole ? 1 : 0;
            }
            const off_t at = off_t(grow) * p.width + col0;
            TERRAIN_TRY(pwrite_all(coll.fd, cf.data(), cf.size() * 4, at * 4, collision_path(p)));
            TERRAIN_TRY(pwrite_all(coll_holes.fd, ch.data(), ch.size(), at, collision_holes_path(p)));
          }
        }
        done += double(rows) * T;
        if (progress && !progress(done / total, "sampling and writing"))
          return Status::failure(Error::cancelled, "export cancelled");
      }
      for (ImageFile* f : {&height, &mask})
        TERRAIN_TRY(f->close());
      result.written.push_back(files.height);
      result.written.push_back(files.holes_or_control);
      for (size_t m = 0; m < weight.size(); ++m) {
        TERRAIN_TRY(weight[m].close());
        result.written.push_back(files.weights[m]);
      }
    }
  if (!unreal) {
    result.written.push_back(collision_path(p));
    result.written.push_back(collision_holes_path(p));
  }
  // Unreal: a layer absent from every tile has no weight map (its files are removed again).
  for (size_t m = 0; m < n_layers; ++m) {
    if (layer_samples[m] > 0) {
      result.layers.push_back(layers[m]);
      continue;
    }
    if (!unreal) continue;
    for (int ty = 0; ty < p.tiles_y; ++ty)
      for (int tx = 0; tx < p.tiles_x; ++tx) {
        const std::string f = tile_files(p, layers, tx, ty).weights[m];
        std::filesystem::remove(f, ec);
        result.written.erase(std::remove(result.written.begin(), result.written.end(), f), result.written.end());
      }
  }
  if (result.samples > result.hole_samples) {
    result.min_height_m = lowest_sampled;
    result.max_height_m = highest_sampled;
  }

  // The sidecar JSON: everything an import script needs.
  nlohmann::json j;
  j["format"] = "terrain-export";
  j["version"] = 1;
  j["target"] = unreal ? "unreal" : "godot";
  j["level"] = p.level;
  j["spacing_m"] = p.spacing_m;
  j["north_west_sample_m"] = {p.west_x_m, p.north_y_m};
  const double south_y = p.north_y_m - (p.image_height - 1) * p.spacing_m;
  j["south_west_sample_m"] = {p.west_x_m, south_y};
  j["rectangle_samples"] = {p.width, p.height};
  j["image_samples"] = {p.image_width, p.image_height};
  j["tile_size"] = p.tile_size;
  j["tile_step"] = p.tile_step;
  j["tiles"] = {p.tiles_x, p.tiles_y};
  j["frame_crs"] = w.crs.name;
  j["frame_epsg"] = w.crs.epsg;
  j["samples"] = result.samples;
  j["hole_samples"] = result.hole_samples;
  j["sampled_height_m"] = {result.min_height_m, result.max_height_m};
  nlohmann::json files = nlohmann::json::array();
  for (const std::string& f : result.written) files.push_back(std::filesystem::path(f).filename().string());
  j["files"] = files;
  j["layers"] = result.layers;
  nlohmann::json palette = nlohmann::json::array();
  for (size_t m = 0; m < n_layers; ++m) palette.push_back({{"id", m}, {"name", w.palette[m].name}, {"file_part", layers[m]}});
  j["palette"] = palette;
  if (unreal) {
    const UnrealZ& z = result.unreal;
    j["unreal"] = {{"scale", {p.spacing_m * 100.0, p.spacing_m * 100.0, z.z_scale}},
                   {"location_z_cm", z.location_z_cm},
                   {"height_step_m", z.step_m},
                   {"max_error_m", z.step_m / 2},
                   {"height_rule", "z_cm = location_z_cm + (v - 32768) * z_scale / 128"},
                   {"visibility", "8-bit, 255 = hole (Landscape visibility layer)"},
                   {"weights", "8-bit per material: bilinear weight of the splat map's material ids"}};
    // terrain-cook flags that read a heightmap back (the frame metres of this export).
    j["cook_back"] = {{"spacing", p.spacing_m},
                      {"height_scale", z.step_m},
                      {"height_offset", z.location_z_cm / 100.0 - 32768.0 * z.step_m},
                      {"nodata_value", kUnrealHoleValue}};
  } else {
    j["godot"] = {{"height", "EXR float32 metres, NaN = hole or no terrain"},
                  {"control", "RGBA8: R base material id, G overlay id, B overlay blend 0..255, A 0 = hole"},
                  {"collision", {{"file", std::filesystem::path(collision_path(p)).filename().string()},
                                 {"holes", std::filesystem::path(collision_holes_path(p)).filename().string()},
                                 {"width", p.width},
                                 {"depth", p.height},
                                 {"layout", "float32 little-endian, row-major, row 0 = north, column 0 = west"},
                                 {"hole_height_m", range_lo},
                                 {"holes_layout", "uint8 per sample, same order, 1 = hole"}}}};
    j["cook_back"] = {{"spacing", p.spacing_m}};
  }
  // Each tile cooks back on its own, from its own south-west sample; one tile: also "origin".
  nlohmann::json back_tiles = nlohmann::json::array();
  for (int ty = 0; ty < p.tiles_y; ++ty)
    for (int tx = 0; tx < p.tiles_x; ++tx) {
      const TileOrigin o = tile_origin(p, tx, ty);
      const uint64_t holes = result.tile_hole_samples[size_t(ty) * size_t(p.tiles_x) + size_t(tx)];
      back_tiles.push_back({{"file", std::filesystem::path(tile_files(p, layers, tx, ty).height).filename().string()},
                            {"tile", {tx, ty}},
                            {"origin", {o.x_m, o.y_m}},
                            {"hole_samples", holes},
                            {"flags", cook_back_flags(p, result.unreal, tx, ty)}});
    }
  if (p.tiles_x * p.tiles_y == 1) j["cook_back"]["origin"] = back_tiles[0]["origin"];
  j["cook_back"]["nodata"] = "hole";
  j["cook_back"]["tiles"] = back_tiles;
  result.json = j.dump(2) + "\n";
  {
    FILE* f = std::fopen(json_path(p).c_str(), "wb");
    if (!f) return Status::failure(Error::io_write, json_path(p) + ": cannot create");
    const bool ok = std::fwrite(result.json.data(), 1, result.json.size(), f) == result.json.size();
    if (std::fclose(f) != 0 || !ok) return Status::failure(Error::io_write, json_path(p) + ": write failed");
  }
  result.written.push_back(json_path(p));
  if (progress) progress(1.0, "done");
  return Status::success();
}

std::string import_instructions(const Plan& p, const Result& r) {
  std::string t;
  const double south_y = p.north_y_m - (p.image_height - 1) * p.spacing_m;
  t += fmt::format("lattice   level {} ({} m), {} x {} samples, image {} x {}{}\n", p.level, p.spacing_m, p.width, p.height,
                   p.image_width, p.image_height,
                   p.tiled ? fmt::format(" in {} x {} tiles of {}", p.tiles_x, p.tiles_y, p.tile_size) : std::string());
  t += fmt::format("corners   north-west sample ({:.3f}, {:.3f}) m, south-west ({:.3f}, {:.3f}) m (frame)\n", p.west_x_m,
                   p.north_y_m, p.west_x_m, south_y);
  t += fmt::format("heights   {:.3f} .. {:.3f} m, {} of {} samples are holes\n", r.min_height_m, r.max_height_m, r.hole_samples,
                   r.samples);
  if (p.options.target == Target::unreal) {
    const UnrealZ& z = r.unreal;
    t += "Unreal import (Landscape mode > Import from file):\n";
    t += fmt::format("  Scale     X {:.4f}  Y {:.4f}  Z {:.4f}\n", p.spacing_m * 100, p.spacing_m * 100, z.z_scale);
    t += fmt::format("  Location  Z {:.2f} (cm; X and Y as you like)\n", z.location_z_cm);
    t += fmt::format("  16-bit step {:.6f} m: heights within {:.6f} m of the archive's surface\n", z.step_m, z.step_m / 2);
    t += fmt::format("  layers    {} (weight maps), visibility = holes\n",
                     r.layers.empty() ? std::string("none") : fmt::format("{}", fmt::join(r.layers, ", ")));
  } else {
    t += "Godot / generic: EXR float heights (NaN = hole), RGBA control maps, collision float32 + uint8 hole mask\n";
  }
  // One command per tile: each has its own origin (holes stay holes).
  t += p.tiles_x * p.tiles_y == 1 ? "terrain-cook back:\n" : "terrain-cook back (one archive per tile):\n";
  const std::vector<std::string> no_layers;
  for (int ty = 0; ty < p.tiles_y; ++ty)
    for (int tx = 0; tx < p.tiles_x; ++tx) {
      const std::string file = tile_files(p, no_layers, tx, ty).height;
      const std::string stem = std::filesystem::path(file).stem().string();
      const size_t k = size_t(ty) * size_t(p.tiles_x) + size_t(tx);
      if (k < r.tile_hole_samples.size() && r.tile_hole_samples[k] == uint64_t(p.tile_size) * uint64_t(p.tile_size))
        t += fmt::format("  {}: all holes, nothing to cook back\n", file);
      else
        t += fmt::format("  terrain-cook {} -o {}.terrain {}\n", file, stem, cook_back_flags(p, r.unreal, tx, ty));
    }
  return t;
}

}  // namespace terrain::engine_export
