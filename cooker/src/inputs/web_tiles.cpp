// Web elevation tiles: addresses, encodings and placement (decoded in web_tile_source.cpp).
#include "inputs/web_tiles.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <vector>

namespace terrain::cook {
namespace {

// Half the EPSG:3857 world width: pi * 6378137.
constexpr double kWebMercatorHalf = 20037508.342789244;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

bool parse_int(const std::string& s, int& v) {
  if (s.empty() || s.size() > 9) return false;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && p == s.data() + s.size() && v >= 0;
}

}  // namespace

bool is_encoded_image_name(const std::string& path) {
  const std::string ext = lower(std::filesystem::path(path).extension().string());
  return ext == ".png" || ext == ".webp" || ext == ".pngraw";
}

bool parse_tile_address(const std::string& path, TileAddress& out) {
  const std::filesystem::path p(path);
  const std::string ext = lower(p.extension().string());
  if (ext != ".png" && ext != ".webp" && ext != ".pngraw") return false;
  const std::string y = p.stem().string();
  const std::string x = p.parent_path().filename().string();
  const std::string z = p.parent_path().parent_path().filename().string();
  TileAddress t;
  if (!parse_int(z, t.z) || !parse_int(x, t.x) || !parse_int(y, t.y) || t.z > 30) return false;
  const int64_t n = int64_t(1) << t.z;
  if (t.x >= n || t.y >= n) return false;
  out = t;
  return true;
}

Status tile_encoding_of(const std::string& path, const std::string& flag, TileEncoding& out) {
  const std::string f = lower(flag);
  if (f == "terrarium") return out = TileEncoding::terrarium, Status::success();
  if (f == "mapbox" || f == "terrain-rgb") return out = TileEncoding::mapbox, Status::success();
  if (!f.empty())
    return Status::failure(Error::invalid_argument,
                           fmt::format("--tile-encoding {}: expected terrarium or mapbox", flag));
  const std::string p = lower(path);
  if (p.find("terrarium") != std::string::npos) return out = TileEncoding::terrarium, Status::success();
  if (p.find("mapbox") != std::string::npos || p.find("terrain-rgb") != std::string::npos)
    return out = TileEncoding::mapbox, Status::success();
  return Status::failure(Error::invalid_argument,
                         fmt::format("{}: a z/x/y web tile whose encoding its path does not name; give --tile-encoding "
                                     "terrarium (Mapzen / AWS Terrain Tiles) or mapbox (Mapbox / MapTiler terrain-RGB)",
                                     path));
}

SampleGeo web_tile_geo(const TileAddress& t, int size) {
  const double span = 2.0 * kWebMercatorHalf / double(int64_t(1) << t.z);
  const double px = span / size;
  SampleGeo g;
  g.c[0] = -kWebMercatorHalf + t.x * span + 0.5 * px;
  g.c[1] = px;
  g.c[2] = 0;
  g.c[3] = kWebMercatorHalf - t.y * span - 0.5 * px;
  g.c[4] = 0;
  g.c[5] = -px;
  g.valid = true;
  g.point_samples = false;
  return g;
}

SourceCrs web_mercator_crs() { return gdal_crs_of_epsg(3857); }

}  // namespace terrain::cook
