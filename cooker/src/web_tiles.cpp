// Web elevation tiles: decoded from their RGB through GDAL (PNG, WebP), placed by their z/x/y.
#include "web_tiles.h"

#include <cpl_error.h>
#include <gdal_priv.h>

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

class WebTileSource final : public SourceRaster {
 public:
  WebTileSource(std::unique_ptr<GDALDataset> ds, TileEncoding enc) : ds_(std::move(ds)), enc_(enc) {}
  SourceInfo& info_mut() { return info_; }
  uint64_t scratch_bytes(int w, int h) const override { return uint64_t(w) * uint64_t(h) * 4; }

  Status read_window(int x0, int y0, int w, int h, float* out) override {
    if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > info_.width || y0 + h > info_.height)
      return Status::failure(Error::invalid_argument, fmt::format("{}: window outside the tile", info_.path));
    const int bands = std::min(ds_->GetRasterCount(), 4);
    const size_t n = size_t(w) * size_t(h);
    buf_.resize(n * size_t(bands));
    int band_map[4] = {1, 2, 3, 4};
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
    const CPLErr err = ds_->RasterIO(GF_Read, x0, y0, w, h, buf_.data(), w, h, GDT_Byte, bands, band_map, 0, 0, 0,
                                     nullptr);
    const std::string msg = CPLGetLastErrorMsg();
    CPLPopErrorHandler();
    if (err != CE_None)
      return Status::failure(Error::io_read, fmt::format("{}: cannot decode the tile: {}", info_.path, msg));
    info_.bytes_read += n * size_t(bands);
    const uint8_t* r = buf_.data();
    const uint8_t* g = r + n;
    const uint8_t* b = g + n;
    const uint8_t* a = bands == 4 ? b + n : nullptr;
    for (size_t i = 0; i < n; ++i) {
      if (a && a[i] == 0) {
        out[i] = NAN;
        continue;
      }
      out[i] = float(enc_ == TileEncoding::terrarium ? terrarium_height(r[i], g[i], b[i]) : mapbox_height(r[i], g[i], b[i]));
    }
    return Status::success();
  }

 private:
  std::unique_ptr<GDALDataset> ds_;
  TileEncoding enc_;
  std::vector<uint8_t> buf_;
};

}  // namespace

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

Status open_web_tile(const std::string& path, const TileAddress& t, TileEncoding enc,
                     std::unique_ptr<SourceRaster>& out) {
  init_gdal();
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLErrorReset();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  const std::string msg = CPLGetLastErrorMsg();
  CPLPopErrorHandler();
  if (!ds)
    return Status::failure(Error::io_open, fmt::format("{}: GDAL cannot open the web tile: {}", path,
                                                       msg.empty() ? "no reason given" : msg));
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  if (ds->GetRasterCount() < 3 || w != h || w < 2 || w > 4096)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {}x{} with {} band(s); a web elevation tile is square RGB(A)", path, w, h,
                                       ds->GetRasterCount()));
  const std::string driver = ds->GetDriver() ? ds->GetDriver()->GetDescription() : "?";
  auto src = std::make_unique<WebTileSource>(std::move(ds), enc);
  SourceInfo& info = src->info_mut();
  info.path = path;
  info.width = w;
  info.height = h;
  info.sample_type = "RGB8";
  info.geo = web_tile_geo(t, w);
  info.crs = web_mercator_crs();
  // Where the tile is (for the gdalwarp hint while 3857 cannot be a frame).
  const double n = double(int64_t(1) << t.z);
  info.crs.center_lon = (t.x + 0.5) / n * 360.0 - 180.0;
  info.crs.center_lat = std::atan(std::sinh(M_PI * (1.0 - 2.0 * (t.y + 0.5) / n))) * 180.0 / M_PI;
  info.description = fmt::format("{} web tile z{} x{} y{} {}x{} ({})", driver, t.z, t.x, t.y, w, h,
                                 enc == TileEncoding::terrarium ? "terrarium" : "Mapbox terrain-RGB");
  out = std::move(src);
  return Status::success();
}

}  // namespace terrain::cook
