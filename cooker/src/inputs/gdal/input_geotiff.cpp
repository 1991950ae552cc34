// GeoTIFF reader: libtiff decodes the samples, libgeotiff interprets the geokeys (never parsed by
// hand), GDAL_NODATA (tag 42113) gives the nodata value.
#include <geotiff/geo_normalize.h>
#include <geotiff/geotiff.h>
#include <geotiff/geovalues.h>
#include <geotiff/xtiffio.h>
#include <tiffio.h>

#include <cmath>
#include <cstdarg>
#include <cstdlib>
#include <cstring>
#include <fmt/format.h>
#include <memory>
#include <mutex>

#include "frame/crs.h"
#include "inputs/inputs.h"

namespace terrain::cook {
namespace {

constexpr ttag_t kTagGdalMetadata = 42112;
constexpr ttag_t kTagGdalNodata = 42113;

TIFFExtendProc g_parent_extender = nullptr;

void gdal_tags_extender(TIFF* tif) {
  static const TIFFFieldInfo fields[] = {
      {kTagGdalMetadata, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALMetadata")},
      {kTagGdalNodata, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")},
  };
  TIFFMergeFieldInfo(tif, fields, 2);
  if (g_parent_extender) g_parent_extender(tif);
}

void register_tags_once() {
  static std::once_flag once;
  std::call_once(once, [] {
    XTIFFInitialize();  // GeoTIFF tags
    g_parent_extender = TIFFSetTagExtender(gdal_tags_extender);
  });
}

// libtiff reports problems through handlers; keep the last error for our message.
int on_tiff_error(TIFF*, void* user, const char* module, const char* fmt_, va_list ap) {
  char buf[512];
  std::vsnprintf(buf, sizeof buf, fmt_, ap);
  *static_cast<std::string*>(user) = fmt::format("{}{}{}", module ? module : "", module ? ": " : "", buf);
  return 1;
}
int on_tiff_warning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

struct TiffCloser {
  void operator()(TIFF* t) const { XTIFFClose(t); }
};
struct GtifCloser {
  void operator()(GTIF* g) const { GTIFFree(g); }
};


const char* type_name(int bits, int format) {
  switch (format * 100 + bits) {
    case 108: return "UInt8";
    case 208: return "Int8";
    case 116: return "UInt16";
    case 216: return "Int16";
    case 132: return "UInt32";
    case 232: return "Int32";
    case 332: return "Float32";
    case 364: return "Float64";
    default: return nullptr;
  }
}

const char* compression_name(uint16_t c) {
  switch (c) {
    case COMPRESSION_NONE: return "uncompressed";
    case COMPRESSION_LZW: return "LZW";
    case COMPRESSION_ADOBE_DEFLATE:
    case COMPRESSION_DEFLATE: return "deflate";
    case COMPRESSION_PACKBITS: return "PackBits";
    case COMPRESSION_ZSTD: return "zstd";
    case COMPRESSION_LZMA: return "LZMA";
    case COMPRESSION_JPEG: return "JPEG";
    case COMPRESSION_WEBP: return "WebP";
    case COMPRESSION_LERC: return "LERC";
    default: return "compressed";
  }
}

}  // namespace

double sample_value(const uint8_t* p, int bits, int format) {
  switch (format * 100 + bits) {
    case 108: return p[0];
    case 208: return int8_t(p[0]);
    case 116: { uint16_t v; std::memcpy(&v, p, 2); return v; }
    case 216: { int16_t v; std::memcpy(&v, p, 2); return v; }
    case 132: { uint32_t v; std::memcpy(&v, p, 4); return v; }
    case 232: { int32_t v; std::memcpy(&v, p, 4); return v; }
    case 332: { float v; std::memcpy(&v, p, 4); return v; }
    case 364: { double v; std::memcpy(&v, p, 8); return v; }
    default: return NAN;
  }
}

Status read_geotiff(const std::string& path, const ReadOptions& options, Raster& out) {
  register_tags_once();
  std::string tiff_error;
  std::unique_ptr<TIFFOpenOptions, void (*)(TIFFOpenOptions*)> topts(TIFFOpenOptionsAlloc(), TIFFOpenOptionsFree);
  TIFFOpenOptionsSetErrorHandlerExtR(topts.get(), on_tiff_error, &tiff_error);
  TIFFOpenOptionsSetWarningHandlerExtR(topts.get(), on_tiff_warning, nullptr);
  std::unique_ptr<TIFF, TiffCloser> tif(TIFFOpenExt(path.c_str(), "r", topts.get()));
  if (!tif)
    return Status::failure(Error::io_open, fmt::format("{}: cannot open as TIFF ({})", path,
                                                       tiff_error.empty() ? "not a TIFF file?" : tiff_error));

  uint32_t width = 0, height = 0;
  uint16_t spp = 1, bits = 0, format = SAMPLEFORMAT_UINT, planar = PLANARCONFIG_CONTIG, compression = 0;
  TIFFGetField(tif.get(), TIFFTAG_IMAGEWIDTH, &width);
  TIFFGetField(tif.get(), TIFFTAG_IMAGELENGTH, &height);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLESPERPIXEL, &spp);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_BITSPERSAMPLE, &bits);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLEFORMAT, &format);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_PLANARCONFIG, &planar);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_COMPRESSION, &compression);
  const char* tname = type_name(bits, format);
  if (!tname)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: sample type {} bits, format {} is not supported (Int8..Int32, UInt8..UInt32, "
                                       "Float32, Float64)", path, bits, format));
  if (width == 0 || height == 0 || width > 200000 || height > 200000 || uint64_t(width) * height > (uint64_t(1) << 32))
    return Status::failure(Error::unsupported_input, fmt::format("{}: raster size {}x{} not supported", path, width, height));
  if (spp < 1) return Status::failure(Error::unsupported_input, fmt::format("{}: no samples per pixel", path));

  std::optional<double> nodata = options.nodata_value;
  if (!nodata) {
    char* text = nullptr;
    if (TIFFGetField(tif.get(), kTagGdalNodata, &text) && text) {
      char* end = nullptr;
      const double v = std::strtod(text, &end);
      if (end != text) nodata = v;
      else if (std::strstr(text, "nan") || std::strstr(text, "NaN")) nodata = NAN;
    }
  }

  const int bytes = bits / 8;
  // Band 1 only: with interleaved samples, the first of each pixel.
  const size_t pixel_stride = planar == PLANARCONFIG_CONTIG ? size_t(bytes) * spp : size_t(bytes);
  // The decode buffer (one tile or strip, whose size the header also states) and the raster
  // itself, checked against the budget before either is allocated.
  const tmsize_t block_bytes = TIFFIsTiled(tif.get()) ? TIFFTileSize(tif.get()) : TIFFStripSize(tif.get());
  if (block_bytes <= 0)
    return Status::failure(Error::unsupported_input, fmt::format("{}: inconsistent {} size ({})", path,
                                                                  TIFFIsTiled(tif.get()) ? "tile" : "strip", tiff_error));
  if (!options.header_only)
    TERRAIN_TRY(check_raster_memory(path, width, height, tname, options, uint64_t(block_bytes)));

  out = Raster{};
  out.path = path;
  out.width = int(width);
  out.height = int(height);
  out.nodata_declared = nodata.has_value();
  if (!options.header_only) out.values.assign(size_t(width) * height, NAN);
  const bool is_float = format == SAMPLEFORMAT_IEEEFP;
  const float nodata_f = nodata ? float(*nodata) : 0.0f;
  auto convert = [&](const uint8_t* src, float* dst, size_t count) {
    for (size_t i = 0; i < count; ++i, src += pixel_stride) {
      const double v = sample_value(src, bits, format);
      bool missing = std::isnan(v);
      if (nodata) missing = missing || (is_float ? float(v) == nodata_f : v == *nodata);
      dst[i] = missing ? NAN : float(v);
    }
  };

  std::vector<uint8_t> buf;
  if (options.header_only) {
    // No samples: the georeferencing below only.
  } else if (TIFFIsTiled(tif.get())) {
    uint32_t tw = 0, th = 0;
    TIFFGetField(tif.get(), TIFFTAG_TILEWIDTH, &tw);
    TIFFGetField(tif.get(), TIFFTAG_TILELENGTH, &th);
    buf.resize(size_t(block_bytes));
    if (tw == 0 || th == 0 || buf.size() < size_t(tw) * th * pixel_stride)
      return Status::failure(Error::unsupported_input, fmt::format("{}: inconsistent tile size", path));
    for (uint32_t ty = 0; ty < height; ty += th) {
      for (uint32_t tx = 0; tx < width; tx += tw) {
        const ttile_t tile = TIFFComputeTile(tif.get(), tx, ty, 0, 0);
        if (TIFFReadEncodedTile(tif.get(), tile, buf.data(), tmsize_t(buf.size())) < 0)
          return Status::failure(Error::io_read, fmt::format("{}: cannot decode tile at ({}, {}): {}", path, tx, ty, tiff_error));
        const uint32_t w = std::min(tw, width - tx), h = std::min(th, height - ty);
        for (uint32_t r = 0; r < h; ++r)
          convert(buf.data() + size_t(r) * tw * pixel_stride, &out.values[size_t(ty + r) * width + tx], w);
      }
    }
  } else {
    uint32_t rows_per_strip = height;
    TIFFGetFieldDefaulted(tif.get(), TIFFTAG_ROWSPERSTRIP, &rows_per_strip);
    rows_per_strip = std::min(std::max(rows_per_strip, 1u), height);
    buf.resize(size_t(block_bytes));
    if (buf.size() < size_t(width) * pixel_stride)
      return Status::failure(Error::unsupported_input, fmt::format("{}: inconsistent strip size", path));
    for (uint32_t row = 0; row < height; row += rows_per_strip) {
      const tstrip_t strip = TIFFComputeStrip(tif.get(), row, 0);
      const tmsize_t got = TIFFReadEncodedStrip(tif.get(), strip, buf.data(), tmsize_t(buf.size()));
      const uint32_t rows = std::min(rows_per_strip, height - row);
      if (got < tmsize_t(size_t(rows - 1) * width * pixel_stride + size_t(width) * pixel_stride))
        return Status::failure(Error::io_read, fmt::format("{}: cannot decode strip at row {}: {}", path, row,
                                                           tiff_error.empty() ? "short strip" : tiff_error));
      for (uint32_t r = 0; r < rows; ++r)
        convert(buf.data() + size_t(r) * width * pixel_stride, &out.values[size_t(row + r) * width], width);
    }
  }

  // Georeferencing: GTIFImageToPCS maps raster space (pixel corners at integers) to model space.
  std::unique_ptr<GTIF, GtifCloser> gtif(GTIFNew(tif.get()));
  bool point = false;
  if (gtif) {
    unsigned short raster_type = RasterPixelIsArea;
    if (GTIFKeyGetSHORT(gtif.get(), GTRasterTypeGeoKey, &raster_type, 0, 1) == 1)
      point = raster_type == RasterPixelIsPoint;
    // Sample centre (col, row) is raster point (col + 0.5, row + 0.5) for PixelIsArea, (col, row) for PixelIsPoint.
    const double shift = point ? 0.0 : 0.5;
    double x0 = shift, y0 = shift, x1 = 1 + shift, y1 = shift, x2 = shift, y2 = 1 + shift;
    if (GTIFImageToPCS(gtif.get(), &x0, &y0) && GTIFImageToPCS(gtif.get(), &x1, &y1) &&
        GTIFImageToPCS(gtif.get(), &x2, &y2)) {
      out.geo = sample_geo_from_points(x0, y0, x1, y1, x2, y2, point);
    }
    double cx = 0, cy = 0;
    AffineMap::from(out.geo).to_model(0.5 * (width - 1), 0.5 * (height - 1), cx, cy);
    out.crs = crs_from_geotiff(gtif.get(), cx, cy);
    // File units (e.g. US feet, grads) to metres / degrees.
    if (out.crs.kind != CrsKind::none && out.crs.model_unit != 1.0)
      for (double& c : out.geo.c) c *= out.crs.model_unit;
  }
  out.description = fmt::format("GeoTIFF {} {}x{} {} {}{}, {}", tname, width, height,
                                TIFFIsTiled(tif.get()) ? "tiled" : "strips", compression_name(compression),
                                nodata ? fmt::format(", nodata {}", *nodata) : "",
                                point ? "PixelIsPoint" : "PixelIsArea");
  return Status::success();
}

}  // namespace terrain::cook
