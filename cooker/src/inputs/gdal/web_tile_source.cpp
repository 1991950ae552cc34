// Web elevation tiles decoded from their RGB through GDAL (PNG, WebP), placed by their z/x/y
// (web_tiles.h).
#include <cpl_error.h>
#include <gdal_priv.h>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <vector>

#include "inputs/web_tiles.h"

namespace terrain::cook {
namespace {

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

namespace {

// Opens an RGB(A) image of encoded heights through GDAL: the source, not yet placed.
Status open_rgb(const std::string& path, TileEncoding enc, bool square_tile, std::unique_ptr<WebTileSource>& out,
                std::string& driver) {
  init_gdal();
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLErrorReset();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  const std::string msg = CPLGetLastErrorMsg();
  CPLPopErrorHandler();
  if (!ds)
    return Status::failure(Error::io_open, fmt::format("{}: GDAL cannot open the {}: {}", path,
                                                       square_tile ? "web tile" : "encoded heights image",
                                                       msg.empty() ? "no reason given" : msg));
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  const char* what = enc == TileEncoding::terrarium ? "terrarium" : "mapbox";
  if (ds->GetRasterCount() < 3)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {} band(s); --tile-encoding {} reads heights encoded in red, green and blue "
                                       "(an RGB or RGBA image): a grey image is a plain heightmap, cook it without "
                                       "--tile-encoding", path, ds->GetRasterCount(), what));
  for (int b = 1; b <= std::min(ds->GetRasterCount(), 4); ++b)
    if (ds->GetRasterBand(b)->GetRasterDataType() != GDT_Byte)
      return Status::failure(Error::unsupported_input,
                             fmt::format("{}: band {} is {}, not 8-bit; --tile-encoding {} reads 8-bit RGB(A)", path, b,
                                         GDALGetDataTypeName(ds->GetRasterBand(b)->GetRasterDataType()), what));
  if (square_tile ? (w != h || w < 2 || w > 4096) : (w < 2 || h < 2 || w > 200000 || h > 200000))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {}x{} with {} band(s); {}", path, w, h, ds->GetRasterCount(),
                                       square_tile ? "a web elevation tile is square RGB(A)"
                                                   : "an encoded heights image is 2 .. 200000 samples a side"));
  driver = ds->GetDriver() ? ds->GetDriver()->GetDescription() : "?";
  out = std::make_unique<WebTileSource>(std::move(ds), enc);
  SourceInfo& info = out->info_mut();
  info.path = path;
  info.width = w;
  info.height = h;
  info.sample_type = "RGB8";
  return Status::success();
}

const char* encoding_name(TileEncoding enc) { return enc == TileEncoding::terrarium ? "terrarium" : "Mapbox terrain-RGB"; }

}  // namespace

Status open_web_tile(const std::string& path, const TileAddress& t, TileEncoding enc,
                     std::unique_ptr<SourceRaster>& out) {
  std::unique_ptr<WebTileSource> src;
  std::string driver;
  TERRAIN_TRY(open_rgb(path, enc, true, src, driver));
  SourceInfo& info = src->info_mut();
  const int w = info.width, h = info.height;
  info.geo = web_tile_geo(t, w);
  info.crs = web_mercator_crs();
  // Where the tile is (for the gdalwarp hint while 3857 cannot be a frame).
  const double n = double(int64_t(1) << t.z);
  info.crs.center_lon = (t.x + 0.5) / n * 360.0 - 180.0;
  info.crs.center_lat = std::atan(std::sinh(M_PI * (1.0 - 2.0 * (t.y + 0.5) / n))) * 180.0 / M_PI;
  info.description = fmt::format("{} web tile z{} x{} y{} {}x{} ({})", driver, t.z, t.x, t.y, w, h, encoding_name(enc));
  out = std::move(src);
  return Status::success();
}

Status open_encoded_image(const std::string& path, TileEncoding enc, const SampleGeo& geo, const SourceCrs& crs,
                          std::unique_ptr<SourceRaster>& out) {
  std::unique_ptr<WebTileSource> src;
  std::string driver;
  TERRAIN_TRY(open_rgb(path, enc, false, src, driver));
  SourceInfo& info = src->info_mut();
  info.geo = geo;
  info.crs = crs;
  info.description = fmt::format("{} image {}x{} of {} encoded heights", driver, info.width, info.height,
                                 encoding_name(enc));
  out = std::move(src);
  return Status::success();
}

}  // namespace terrain::cook
