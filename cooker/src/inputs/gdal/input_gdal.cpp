// Inputs read through GDAL: any raster GDAL opens (GeoTIFF, COG, VRT, DTED, netCDF, ...), band 1,
// by windows with RasterIO. The geotransform gives the sample positions, the spatial reference the
// CRS (mapped to what the cooker understands: geographic, Transverse Mercator, or a named
// unsupported CRS for the gdalwarp hint).
#include <cpl_conv.h>
#include <cpl_minixml.h>
#include <cpl_error.h>
#include <cpl_vsi.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <mutex>
#include <thread>
#include <vector>

#include "frame/crs.h"
#include "inputs/height_units.h"
#include "inputs/inputs.h"
#include "inputs/source_raster.h"
#include "inputs/tiff_blocks.h"
#include "inputs/gdal/vrt_tiles.h"
#include "inputs/gdal/vrt_stream.h"
#include "inputs/gdal/vrt_xml.h"

namespace terrain::cook {
namespace {

// GDAL's block cache defaults to 5 % of RAM; a cook reads each block about once, so a small cache
// costs nothing and keeps the budget honest. An explicit GDAL_CACHEMAX wins.
constexpr int64_t kGdalCacheBytes = int64_t(64) << 20;
// Rows of scratch (doubles) per RasterIO call when a window is read band by band.
constexpr uint64_t kScratchBytes = uint64_t(8) << 20;

// Threads that decode a window's compressed blocks (set_gdal_decode_threads), for TiffBlockReader.
std::atomic<int> g_decode_threads{1};

// The thread that set GDAL up (the cook's own).
std::thread::id g_gdal_home_thread;

// GDAL's messages as before, but for failures raised on other threads: GDAL's decoding threads
// (the read that waited on them fails, and names the cause: why_read_failed) and the first pass's
// read-ahead thread (whose reads return their own failures as a Status), so they are not printed.
void CPL_STDCALL gdal_error_handler(CPLErr level, CPLErrorNum number, const char* message) {
  if (level >= CE_Failure && std::this_thread::get_id() != g_gdal_home_thread) return;
  CPLDefaultErrorHandler(level, number, message);
}

void init_gdal_once() {
  static std::once_flag once;
  std::call_once(once, [] {
    g_gdal_home_thread = std::this_thread::get_id();
    CPLSetErrorHandler(gdal_error_handler);
    GDALAllRegister();
    // PixelIsPoint GeoTIFFs: keep the tie point on the sample (as libgeotiff reports it) instead
    // of GDAL's half-pixel shift, so positions stay bit-identical to the libgeotiff reader's.
    CPLSetConfigOption("GTIFF_POINT_GEO_IGNORE", "TRUE");
    if (!CPLGetConfigOption("GDAL_CACHEMAX", nullptr)) GDALSetCacheMax64(kGdalCacheBytes);
    // By default every open lists the file's folder to find its side-cars (.aux.xml, .ovr, .tfw):
    // a VRT over thousands of tiles in one folder re-opens tiles as its dataset pool turns over,
    // each open a listing of thousands. GDAL then looks for each side-car by name (same files
    // found). 4096-tile mosaic read by GDAL: 23-24 -> 18-19 CPU s, 18.6-20.1 -> 14.7-15.3 s.
    if (!CPLGetConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", nullptr))
      CPLSetConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", "TRUE");
  });
}

// Collects GDAL's last error instead of printing it.
struct QuietErrors {
  QuietErrors() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietErrors() { CPLPopErrorHandler(); }
  QuietErrors(const QuietErrors&) = delete;
  QuietErrors& operator=(const QuietErrors&) = delete;
  static std::string last() {
    const char* m = CPLGetLastErrorMsg();
    return m && *m ? m : "no reason given";
  }
};

// Why a read failed when GDAL's decoding threads (set_gdal_decode_threads) reported it on their own
// threads, out of the caller's reach: the same read on a single-threaded handle, for its message.
std::string why_read_failed(const std::string& path, int band, int x0, int y0, int w, int h) {
  QuietErrors quiet;
  const char* open_options[] = {"NUM_THREADS=1", nullptr};
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, open_options, nullptr));
  if (ds && band >= 1 && band <= ds->GetRasterCount()) {
    std::vector<float> scratch(size_t(w) * size_t(std::min(h, 64)));
    for (int y = y0; y < y0 + h; y += 64)
      if (ds->GetRasterBand(band)->RasterIO(GF_Read, x0, y, w, std::min(64, y0 + h - y), scratch.data(), w,
                                            std::min(64, y0 + h - y), GDT_Float32, 0, 0, nullptr) != CE_None)
        break;
  }
  return QuietErrors::last();
}

double inverse_flattening(double a, double b) { return a == b ? 0.0 : a / (a - b); }

int authority_code(const OGRSpatialReference& srs, const char* node) {
  const char* auth = srs.GetAuthorityName(node);
  const char* code = srs.GetAuthorityCode(node);
  if (!auth || !code || !EQUAL(auth, "EPSG")) return 0;
  return std::atoi(code);
}

// The CRS as the libgeotiff reader (crs.cpp) would state it.
SourceCrs crs_from_srs(const OGRSpatialReference* srs_in, double center_x, double center_y) {
  SourceCrs crs;
  if (!srs_in || srs_in->IsEmpty()) return crs;  // kind none
  OGRSpatialReference srs(*srs_in);
  if (srs.IsCompound()) srs.StripVertical();
  OGRErr err = OGRERR_NONE;
  const double a = srs.GetSemiMajor(&err);
  const double b = srs.GetSemiMinor(&err);
  crs.tm.semi_major_m = a;
  crs.tm.inverse_flattening = inverse_flattening(a, b);
  const char* pcs_name = srs.GetName();
  // GDAL's LOCAL_CS["unnamed"] for a GeoTIFF without geokeys: no CRS, as the libgeotiff reader
  // said (the user names it with --crs, e.g. local).
  if (srs.IsLocal()) return SourceCrs{};
  if (srs.IsGeocentric()) {
    crs.kind = CrsKind::unsupported;
    crs.projection = "geocentric";
    crs.name = pcs_name ? pcs_name : "";
    return crs;
  }
  if (const double pm = srs.GetPrimeMeridian(); pm != 0.0) {
    crs.kind = CrsKind::unsupported;
    crs.projection = fmt::format("prime meridian {} deg from Greenwich", pm);
    crs.name = pcs_name ? pcs_name : "";
    return crs;
  }
  if (srs.IsGeographic()) {
    crs.kind = CrsKind::geographic;
    crs.epsg = authority_code(srs, srs.IsProjected() ? "GEOGCS" : nullptr);
    crs.name = crs.epsg ? fmt::format("EPSG:{}", crs.epsg) : "geographic (lon/lat)";
    if (crs.epsg == 4326) crs.name = "WGS 84 (EPSG:4326)";
    crs.model_unit = srs.GetAngularUnits() * 180.0 / M_PI;
    if (!(a > 0)) {
      crs.kind = CrsKind::unsupported;
      crs.projection = "geographic CRS without a known ellipsoid";
    }
    return crs;
  }
  if (!srs.IsProjected()) return SourceCrs{};
  crs.epsg = authority_code(srs, "PROJCS");
  crs.name = pcs_name && *pcs_name && !EQUAL(pcs_name, "unknown") ? pcs_name
                                                                  : (crs.epsg ? fmt::format("EPSG:{}", crs.epsg) : "");
  crs.model_unit = srs.GetLinearUnits();
  const char* method = srs.GetAttrValue("PROJECTION");
  if (!method || !EQUAL(method, SRS_PT_TRANSVERSE_MERCATOR) || !(a > 0)) {
    // Any other projection: through PROJ (crs.cpp), by its EPSG code when the file names one, else
    // by its WKT2, as the libgeotiff reader resolves it.
    std::string definition = crs.epsg ? fmt::format("EPSG:{}", crs.epsg) : "";
    if (definition.empty()) {
      char* wkt = nullptr;
      const char* options[] = {"FORMAT=WKT2_2019", nullptr};
      if (srs.exportToWkt(&wkt, options) == OGRERR_NONE && wkt) definition = wkt;
      CPLFree(wkt);
    }
    if (SourceCrs resolved; !definition.empty() && parse_crs_spec(definition, resolved).ok() &&
                            resolved.kind == CrsKind::projected) {
      if (pcs_name && *pcs_name && !EQUAL(pcs_name, "unknown")) resolved.name = resolved.tm.name = pcs_name;
      if (crs.epsg) resolved.epsg = resolved.tm.epsg = crs.epsg;
      // The file's coordinates are in the CRS's unit (US survey feet for EPSG:2229): the reader
      // turns them into metres by it, as for a Transverse Mercator and as the libgeotiff reader does.
      resolved.model_unit = crs.model_unit;
      return resolved;
    }
    crs.kind = CrsKind::unsupported;
    crs.projection = method ? method : "unknown projection";
    // Where the data is, for the gdalwarp hint.
    OGRSpatialReference geo;
    geo.CopyGeogCSFrom(&srs);
    geo.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&srs, &geo));
    double x = center_x, y = center_y;
    if (ct && ct->Transform(1, &x, &y)) {
      crs.center_lon = x;
      crs.center_lat = y;
    }
    return crs;
  }
  // An EPSG-coded TM expands exactly as --crs / --frame EPSG:<code> does (crs.cpp), so a file and a
  // flag naming the same code agree to the bit (libgeotiff turns EPSG:3794's lon0 15 into
  // 14.999999999999998 through radians; GDAL keeps 15).
  if (SourceCrs by_code; crs.epsg && parse_crs_spec(fmt::format("EPSG:{}", crs.epsg), by_code).ok() &&
                         by_code.kind == CrsKind::transverse_mercator) {
    by_code.model_unit = crs.model_unit;
    return by_code;
  }
  crs.kind = CrsKind::transverse_mercator;
  crs.tm.kind = ProjectionKind::transverse_mercator;
  crs.tm.epsg = crs.epsg;
  crs.tm.lat0_deg = srs.GetNormProjParm(SRS_PP_LATITUDE_OF_ORIGIN, 0.0);
  crs.tm.lon0_deg = srs.GetNormProjParm(SRS_PP_CENTRAL_MERIDIAN, 0.0);
  crs.tm.scale_k0 = srs.GetNormProjParm(SRS_PP_SCALE_FACTOR, 1.0);
  crs.tm.false_easting_m = srs.GetNormProjParm(SRS_PP_FALSE_EASTING, 0.0);
  crs.tm.false_northing_m = srs.GetNormProjParm(SRS_PP_FALSE_NORTHING, 0.0);
  if (crs.name.empty()) {
    const std::string utm = utm_zone_name(crs.tm);
    crs.name = utm.empty() ? "Transverse Mercator (explicit parameters)" : utm + " (explicit parameters)";
  }
  crs.tm.name = crs.name;
  return crs;
}

// The unit the file declares for its heights (terrain/cook.h HeightUnit): the vertical CRS's
// linear unit (PROJ gives its factor), else the band's unit type, looked up by name.
HeightUnit declared_height_unit(const OGRSpatialReference* srs, GDALRasterBand* band) {
  HeightUnit u;
  if (srs && (srs->IsCompound() || srs->IsVertical())) {
    const char* name = nullptr;
    const double metres = srs->GetTargetLinearUnits("VERT_CS", &name);
    if (name && *name && std::isfinite(metres) && metres > 0) {
      u.declared = name;
      u.declared_by = "vertical CRS";
      u.declared_m = metres;
      return u;
    }
  }
  const char* type = band->GetUnitType();
  if (type && *type) {
    u.declared = type;
    u.declared_by = "band unit type";
    u.declared_m = height_unit_metres(type);
  }
  return u;
}

std::string type_name(GDALDataType t, GDALRasterBand* band) {
  if (t == GDT_Byte) {
    const char* pt = band->GetMetadataItem("PIXELTYPE", "IMAGE_STRUCTURE");
    return pt && EQUAL(pt, "SIGNEDBYTE") ? "Int8" : "UInt8";
  }
  return GDALGetDataTypeName(t);
}

std::string compression_name(GDALDataset* ds) {
  const char* c = ds->GetMetadataItem("COMPRESSION", "IMAGE_STRUCTURE");
  if (!c) return "uncompressed";
  const std::string s = c;
  if (s == "DEFLATE") return "deflate";
  if (s == "PACKBITS") return "PackBits";
  if (s == "ZSTD") return "zstd";
  if (s == "LZMA") return "LZMA";
  if (s == "WEBP") return "WebP";
  if (s == "JPEG" || s == "LZW" || s == "LERC") return s;
  return "compressed";
}

class GdalSource final : public SourceRaster {
 public:
  // `reads_from`: where GDAL reads samples when `ds` is a VRT opened without its sources (empty:
  // from `ds`).
  GdalSource(std::unique_ptr<GDALDataset> ds, GDALRasterBand* band, bool is_float, bool signed_byte,
             std::unique_ptr<TiffBlockReader> tiff, std::unique_ptr<VrtTileReader> vrt, std::string reads_from)
      : ds_(std::move(ds)),
        band_(band),
        is_float_(is_float),
        signed_byte_(signed_byte),
        tiff_(std::move(tiff)),
        vrt_(std::move(vrt)),
        reads_from_(std::move(reads_from)) {}
  SourceInfo& info_mut() { return info_; }

  // Types of 4 bytes or fewer are decoded in place in `out` (no scratch); wider ones (Float64,
  // 64-bit integers) through a band of rows of doubles. GDAL holds at least one decoded block.
  uint64_t scratch_bytes(int w, int h) const override {
    int bw = 0, bh = 0;
    band_->GetBlockSize(&bw, &bh);
    const uint64_t block = uint64_t(std::max(bw, 1)) * uint64_t(std::max(bh, 1)) * uint64_t(type_bytes());
    const uint64_t rows = in_place() ? 0 : std::min<uint64_t>(rows_per_call(w, h), uint64_t(h));
    // Decoded here, a window holds one row of its blocks while it copies them (tiff_blocks.h).
    const uint64_t block_row = tiff_ ? (uint64_t(w) / uint64_t(std::max(bw, 1)) + 2) * block : 0;
    // Through a VRT's tiles: a row of the tiles' blocks and the scratch of a source drawn over others.
    const uint64_t vrt = vrt_ ? tiff_block_rows_bytes(w) / 2 + vrt_->scratch_bytes(w, h) : 0;
    return rows * uint64_t(w) * 8 + block + block_row + vrt;
  }

  Status read_window(int x0, int y0, int w, int h, float* out) override {
    if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > info_.width || y0 + h > info_.height)
      return Status::failure(Error::invalid_argument,
                             fmt::format("{}: window {}x{} at ({}, {}) outside the {}x{} raster", info_.path, w, h, x0,
                                         y0, info_.width, info_.height));
    const GDALDataType type = band_->GetRasterDataType();
    if (in_place()) {
      // Native samples into out's 4-byte slots, then each slot converted where it lies. A plain
      // GeoTIFF's blocks are decoded here (tiff_blocks.h); GDAL reads the rest, and any block
      // that does not decode, so that it names the damage.
      QuietErrors quiet;
      uint8_t* bytes = reinterpret_cast<uint8_t*>(out);
      const int threads = g_decode_threads.load();
      if (!(tiff_ && tiff_->read_window(x0, y0, w, h, bytes, threads)) &&
          !(vrt_ && vrt_->read_window(x0, y0, w, h, bytes, threads))) {
        GDALRasterBand* band = gdal_band();
        if (!band || band->RasterIO(GF_Read, x0, y0, w, h, out, w, h, type, 4, GSpacing(w) * 4, nullptr) != CE_None)
          return Status::failure(Error::io_read, fmt::format("{}: cannot read rows {}..{}: {}", info_.path, y0,
                                                             y0 + h - 1, reason(x0, y0, w, h)));
      }
      info_.bytes_read += uint64_t(w) * uint64_t(h) * uint64_t(type_bytes());
      const size_t n = size_t(w) * size_t(h);
      if (type == GDT_Float32 && info_.scale == 1.0 && info_.offset == 0.0) {
        // Float32 in metres: convert() is the identity but for the nodata value (NaN stays NaN).
        if (info_.nodata) {
          const float nd = float(*info_.nodata);
          for (size_t i = 0; i < n; ++i) out[i] = out[i] == nd ? NAN : out[i];
        }
        return Status::success();
      }
      uint8_t* slots = reinterpret_cast<uint8_t*>(out);
      for (size_t i = 0; i < n; ++i) out[i] = convert(native(slots + i * 4, type));
      return Status::success();
    }
    // Doubles: 64-bit values and their nodata compare exactly.
    const int rows_per = rows_per_call(w, h);
    buf_.resize(size_t(w) * size_t(rows_per));
    for (int r = 0; r < h; r += rows_per) {
      const int rows = std::min(rows_per, h - r);
      QuietErrors quiet;
      GDALRasterBand* band = gdal_band();
      if (!band || band->RasterIO(GF_Read, x0, y0 + r, w, rows, buf_.data(), w, rows, GDT_Float64, 0, 0, nullptr) != CE_None)
        return Status::failure(Error::io_read, fmt::format("{}: cannot read rows {}..{}: {}", info_.path, y0 + r,
                                                           y0 + r + rows - 1, reason(x0, y0 + r, w, rows)));
      info_.bytes_read += uint64_t(w) * uint64_t(rows) * uint64_t(type_bytes());
      float* dst = out + size_t(r) * size_t(w);
      const size_t n = size_t(w) * size_t(rows);
      for (size_t i = 0; i < n; ++i) dst[i] = convert(buf_[i]);
    }
    return Status::success();
  }

 private:
  // The band GDAL reads samples from: the VRT's own, opened with its sources on the first read the
  // cooker's readers leave to GDAL (a tile they do not decode, or a damaged one).
  GDALRasterBand* gdal_band() {
    if (reads_from_.empty()) return band_;
    std::lock_guard<std::mutex> lock(whole_m_);
    if (!whole_) {
      whole_.reset(GDALDataset::Open(reads_from_.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR));
      if (!whole_ || whole_->GetRasterCount() < 1 || whole_->GetRasterXSize() != info_.width ||
          whole_->GetRasterYSize() != info_.height)
        return nullptr;
    }
    return whole_->GetRasterBand(1);
  }
  // The message of the failed read on this thread, else the single-threaded read's.
  std::string reason(int x0, int y0, int w, int h) const {
    const char* m = CPLGetLastErrorMsg();
    if (m && *m) return m;
    if (!reads_from_.empty()) {
      std::lock_guard<std::mutex> lock(whole_m_);
      if (!whole_) return fmt::format("GDAL cannot open {}", reads_from_);
    }
    return why_read_failed(reads_from_.empty() ? ds_->GetDescription() : reads_from_, 1, x0, y0, w, h);
  }
  int type_bytes() const { return GDALGetDataTypeSizeBytes(band_->GetRasterDataType()); }
  bool in_place() const {
    switch (band_->GetRasterDataType()) {
      case GDT_Byte: case GDT_UInt16: case GDT_Int16: case GDT_UInt32: case GDT_Int32: case GDT_Float32: return true;
      default: return false;
    }
  }
  // One native sample (Byte as Int8 when the band says SIGNEDBYTE) as a double.
  double native(const uint8_t* p, GDALDataType type) const {
    switch (type) {
      case GDT_Byte: return signed_byte_ ? double(int8_t(p[0])) : double(p[0]);
      case GDT_UInt16: { uint16_t v; std::memcpy(&v, p, 2); return v; }
      case GDT_Int16: { int16_t v; std::memcpy(&v, p, 2); return v; }
      case GDT_UInt32: { uint32_t v; std::memcpy(&v, p, 4); return v; }
      case GDT_Int32: { int32_t v; std::memcpy(&v, p, 4); return v; }
      case GDT_Float32: { float v; std::memcpy(&v, p, 4); return v; }
      default: return NAN;
    }
  }
  // The file's value to a height: nodata (declared, NaN) to NaN, then scale and offset. Floats
  // compare with the nodata value in float, integers exactly (as the libgeotiff reader did).
  float convert(double v) const {
    bool missing = std::isnan(v);
    if (info_.nodata) missing = missing || (is_float_ ? float(v) == float(*info_.nodata) : v == *info_.nodata);
    if (missing) return NAN;
    return float(info_.scale != 1.0 || info_.offset != 0.0 ? v * info_.scale + info_.offset : v);
  }
  static int rows_per_call(int w, int h) {
    return int(std::clamp<uint64_t>(kScratchBytes / (uint64_t(w) * 8), 1, uint64_t(h)));
  }
  std::unique_ptr<GDALDataset> ds_;
  GDALRasterBand* band_;
  bool is_float_;
  bool signed_byte_;
  std::unique_ptr<TiffBlockReader> tiff_;  // null: GDAL decodes every block
  std::unique_ptr<VrtTileReader> vrt_;     // a VRT of plain GeoTIFF tiles, read through theirs
  std::string reads_from_;                 // non-empty: ds_ is that VRT without its sources
  mutable std::mutex whole_m_;
  std::unique_ptr<GDALDataset> whole_;     // reads_from_ with its sources, once GDAL must read
  std::vector<double> buf_;
};

}  // namespace

void init_gdal() { init_gdal_once(); }

void set_gdal_cache_bytes(uint64_t bytes) {
  init_gdal_once();
  if (!CPLGetConfigOption("GDAL_CACHEMAX", nullptr))
    GDALSetCacheMax64(GIntBig(std::min<uint64_t>(bytes, uint64_t(INT64_MAX))));
}

void set_gdal_decode_threads(int threads) {
  init_gdal_once();
  static const bool user_set = CPLGetConfigOption("GDAL_NUM_THREADS", nullptr) != nullptr;
  if (!user_set) CPLSetConfigOption("GDAL_NUM_THREADS", std::to_string(std::max(threads, 1)).c_str());
  g_decode_threads = std::max(threads, 1);
}

uint64_t gdal_cache_used_bytes() { return uint64_t(std::max<GIntBig>(GDALGetCacheUsed64(), 0)); }

namespace {

// Every <SourceFilename> under `node` (nested VRTs' own tiles are checked when they are read).
void collect_source_files(const CPLXMLNode* node, const std::string& vrt_dir, std::vector<std::string>& out) {
  for (; node; node = node->psNext) {
    if (node->eType != CXT_Element) continue;
    if (EQUAL(node->pszValue, "SourceFilename")) {
      if (*CPLGetXMLValue(node, nullptr, "")) out.push_back(vrt_source_file(node, vrt_dir));
      continue;
    }
    collect_source_files(node->psChild, vrt_dir, out);
  }
}

}  // namespace

Status check_vrt_tiles(const std::string& path) {
  const std::string base = std::filesystem::path(path).filename().string();
  if (!ends_with(base, ".vrt")) return Status::success();
  init_gdal_once();
  QuietErrors quiet;
  const std::string dir = vrt_folder(path);
  std::string missing;
  // The first named file that is not there, checked as its element is read.
  const auto check = [&](const CPLXMLNode* node) {
    std::vector<std::string> files;
    collect_source_files(node, dir, files);
    for (const std::string& f : files) {
      // Names such as "MEM:::..." or "NETCDF:file:var" are not plain files: left to GDAL's read.
      if (f.find(':') != std::string::npos && !f.starts_with("/vsi")) continue;
      VSIStatBufL st;
      if (VSIStatL(f.c_str(), &st) != 0) {
        missing = f;
        return false;
      }
    }
    return true;
  };
  VrtStream vrt;
  const VrtRead read = read_vrt_stream(path, vrt, [&](const VrtSourceVisit& s) { return check(s.node); });
  if (read == VrtRead::ok) {  // then the files named outside the sources (a band's <Overview>, ...)
    CPLXMLNode* header = CPLParseXMLString(vrt.header.c_str());
    if (header) check(header);
    CPLDestroyXMLNode(header);
  }
  // A file GDAL opened but expat does not read: GDAL's reads name any problem.
  if (!missing.empty())
    return Status::failure(Error::io_read,
                           fmt::format("{}: cannot read its tile {}: No such file or directory", path, missing));
  return Status::success();
}

namespace {

// An OGR spatial reference for a source CRS: its EPSG code, else its WKT (projected) or the
// Transverse Mercator / geographic parameters it was resolved to. False for local and no CRS.
bool spatial_reference(const SourceCrs& crs, OGRSpatialReference& srs) {
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);  // x = easting/longitude, as SampleGeo
  if (crs.epsg > 0 && srs.importFromEPSG(crs.epsg) == OGRERR_NONE) return true;
  const FrameCrs& t = crs.tm;
  switch (crs.kind) {
    case CrsKind::projected:
      return !t.definition.empty() && srs.SetFromUserInput(t.definition.c_str()) == OGRERR_NONE;
    case CrsKind::transverse_mercator:
      return srs.importFromProj4(fmt::format("+proj=tmerc +lat_0={:.17g} +lon_0={:.17g} +k_0={:.17g} +x_0={:.17g} "
                                             "+y_0={:.17g} +a={:.17g} +rf={:.17g} +units=m +no_defs",
                                             t.lat0_deg, t.lon0_deg, t.scale_k0, t.false_easting_m, t.false_northing_m,
                                             t.semi_major_m, t.inverse_flattening)
                                     .c_str()) == OGRERR_NONE;
    case CrsKind::geographic:
      if (t.semi_major_m <= 0) return false;
      return srs.importFromProj4(fmt::format("+proj=longlat +a={:.17g} +rf={:.17g} +no_defs", t.semi_major_m,
                                             t.inverse_flattening)
                                     .c_str()) == OGRERR_NONE;
    default: return false;
  }
}

// Metres (projected) or degrees (geographic) per coordinate unit of `srs`: the points handed to
// gdal_point_transforms are in metres and degrees (SampleGeo), OGR's in the CRS's own units (US
// survey feet for EPSG:2229).
double coordinate_unit(const OGRSpatialReference& srs) {
  const double u = srs.IsGeographic() ? srs.GetAngularUnits() * 180.0 / M_PI : srs.GetLinearUnits();
  // Degrees and metres exactly 1 (OGR's degree is pi/180 rounded: the points keep their bits).
  return std::isfinite(u) && u > 0 && std::fabs(u - 1.0) > 1e-12 ? u : 1.0;
}

}  // namespace

CrsTransformStatus gdal_point_transforms(const SourceCrs& a, const SourceCrs& b, PointTransform& a_to_b,
                                         PointTransform& b_to_a) {
  init_gdal_once();
  OGRSpatialReference a_srs, b_srs;
  if (!spatial_reference(a, a_srs) || !spatial_reference(b, b_srs)) return CrsTransformStatus::no_geodetic_crs;
  std::shared_ptr<OGRCoordinateTransformation> there(OGRCreateCoordinateTransformation(&a_srs, &b_srs));
  std::shared_ptr<OGRCoordinateTransformation> back(OGRCreateCoordinateTransformation(&b_srs, &a_srs));
  if (!there || !back) return CrsTransformStatus::no_transformation;
  const double ua = coordinate_unit(a_srs), ub = coordinate_unit(b_srs);
  const auto through = [](const std::shared_ptr<OGRCoordinateTransformation>& t, double from, double to) {
    return [t, from, to](double& x, double& y) {
      x /= from;
      y /= from;
      const bool ok = t->Transform(1, &x, &y) != 0;
      x *= to;
      y *= to;
      return ok;
    };
  };
  a_to_b = through(there, ua, ub);
  b_to_a = through(back, ub, ua);
  return CrsTransformStatus::ok;
}

SourceCrs gdal_crs_of_epsg(int code) {
  init_gdal_once();
  QuietErrors quiet;
  OGRSpatialReference srs;
  if (srs.importFromEPSG(code) != OGRERR_NONE) return SourceCrs{};
  return crs_from_srs(&srs, NAN, NAN);
}

namespace {

FilePlacement placement_of(const std::string& path, GDALDataset* ds) {
  FilePlacement p;
  p.path = path;
  p.opened = ds != nullptr;
  if (ds) {
    p.has_geotransform = ds->GetGeoTransform(p.gt) == CE_None;
    p.width = ds->GetRasterXSize();
    p.height = ds->GetRasterYSize();
  }
  return p;
}

// A VRT's tiles placed by its own XML: each source's file (named as GDAL's VRT driver names it) at
// its DstRect through the VRT's geotransform, without opening the tile. False (nothing added) when
// a source is not that plain: no DstRect, a /vsi or driver-prefixed name, or a VRT without a
// geotransform; the tiles are then opened one by one.
bool vrt_source_placements(const std::string& path, const FilePlacement& vrt, std::vector<FilePlacement>& out) {
  if (!ends_with(path, ".vrt") || !vrt.has_geotransform) return false;
  const std::string dir = vrt_folder(path);
  std::vector<FilePlacement> tiles;
  // One source at a time (vrt_stream.h): the tiles' list is all that grows with the VRT.
  const auto place = [&](const VrtSourceVisit& s) {
    const CPLXMLNode* c = s.node;
    const CPLXMLNode* f = CPLGetXMLNode(c, "SourceFilename");
    VrtRect d;
    if (!f || !vrt_dst_rect(c, d) || !plain_file_name(CPLGetXMLValue(f, nullptr, ""))) return false;
    FilePlacement t;
    t.path = vrt_source_file(f, dir);
    const double x = d.x, y = d.y, w = d.w, h = d.h;
    if (!(w > 0) || !(h > 0) || w > 1e9 || h > 1e9) return false;
    // One "sample" per DstRect here: footprint_of maps its corners, which is all it reads.
    const double* g = vrt.gt;
    t.opened = t.has_geotransform = true;
    t.width = 1;
    t.height = 1;
    t.gt[0] = g[0] + x * g[1] + y * g[2];
    t.gt[1] = w * g[1];
    t.gt[2] = h * g[2];
    t.gt[3] = g[3] + x * g[4] + y * g[5];
    t.gt[4] = w * g[4];
    t.gt[5] = h * g[5];
    tiles.push_back(std::move(t));
    return true;
  };
  VrtStream vrt_xml;
  if (read_vrt_stream(path, vrt_xml, place) != VrtRead::ok) return false;
  for (FilePlacement& t : tiles)
    if (t.path != path) out.push_back(std::move(t));
  return true;
}

}  // namespace

std::vector<FilePlacement> gdal_file_placements(const std::string& path) {
  init_gdal_once();
  // A VRT mosaic of thousands of tiles: placed from its XML, not by opening every tile again, and
  // its own placement read by GDAL from the VRT without its sources (vrt_stream.h).
  if (const std::string header = ends_with(path, ".vrt") ? vrt_without_sources(path) : std::string(); !header.empty()) {
    QuietErrors quiet;
    std::unique_ptr<GDALDataset> h(GDALDataset::Open(header.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    std::vector<FilePlacement> out{placement_of(path, h.get())};
    if (h && vrt_source_placements(path, out[0], out)) return out;
  }
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  std::vector<FilePlacement> out{placement_of(path, ds.get())};
  if (!ds) return out;
  if (vrt_source_placements(path, out[0], out)) return out;
  char** list = ds->GetFileList();
  for (char** p = list; p && *p; ++p) {
    const std::string f = *p;
    if (f == path || ends_with(f, ".aux.xml") || ends_with(f, ".ovr")) continue;
    std::unique_ptr<GDALDataset> t(GDALDataset::Open(f.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    out.push_back(placement_of(f, t.get()));
  }
  CSLDestroy(list);
  return out;
}

Status open_gdal_source(const std::string& path, const ReadOptions& options, std::unique_ptr<SourceRaster>& out) {
  init_gdal_once();
  QuietErrors quiet;
  // A VRT mosaic the cooker composes from its tiles' blocks (vrt_tiles.h) is opened by GDAL without
  // its sources (vrt_stream.h), for its size, georeferencing and band: GDAL's VRT driver keeps an
  // object per source (28 MB of the one-process cook's peak for 62 500 tiles) and reads through
  // them only where the cooker's reader gives a window up, so the whole VRT is opened then
  // (GdalSource::gdal_band).
  std::unique_ptr<GDALDataset> ds;
  std::unique_ptr<VrtTileReader> vrt;
  Status vrt_refused;  // why the VRT reader left the VRT to GDAL
  std::string reads_from;
  bool vrt_tried = false;  // the reader has already read this VRT's XML (and refused it, if null)
  if (const std::string header = ends_with(path, ".vrt") ? vrt_without_sources(path) : std::string(); !header.empty()) {
    std::unique_ptr<GDALDataset> h(GDALDataset::Open(header.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    if (h && h->GetRasterCount() >= 1 && h->GetDriver() && std::strcmp(h->GetDriver()->GetDescription(), "VRT") == 0) {
      vrt_refused = VrtTileReader::open(path, h->GetRasterXSize(), h->GetRasterYSize(), vrt);
      vrt_tried = true;
    }
    if (vrt) {
      ds = std::move(h);
      reads_from = path;
    }
  }
  if (!ds) ds.reset(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR));
  if (!ds) {
    const std::string reason = QuietErrors::last();
    if (!GDALIdentifyDriverEx(path.c_str(), GDAL_OF_RASTER, nullptr, nullptr))
      return Status::failure(Error::unsupported_input,
                             fmt::format("{}: unknown input format: no GDAL raster driver recognises it ({}), and it is "
                                         "none of terrain-cook's own (.npz, raw .r16/.raw/.r32/.f32, SRTM .hgt/.hgt.zip/"
                                         ".hgt.gz, PNG/EXR heightmaps, z/x/y web tiles)", path, reason));
    return Status::failure(Error::io_open, fmt::format("{}: GDAL cannot open it as a raster: {}", path, reason));
  }
  if (ds->GetRasterCount() < 1)
    return Status::failure(Error::unsupported_input, fmt::format("{}: has no raster band", path));
  const std::string driver = ds->GetDriver() ? ds->GetDriver()->GetDescription() : "";
  // A multi-file dataset (e.g. a raster and its .hdr) missing a listed part is named before reading.
  // (GDAL lists only the VRT sources that exist: a missing tile fails the read, "No such file";
  // a VRT opened without its sources has nothing to list.)
  if (char** files = options.files_checked || !reads_from.empty() ? nullptr : ds->GetFileList()) {
    for (char** f = files; *f; ++f) {
      VSIStatBufL st;
      if (VSIStatL(*f, &st) != 0) {
        const std::string missing = *f;
        CSLDestroy(files);
        return Status::failure(Error::io_open, fmt::format("{}: names a file that does not exist: {}", path, missing));
      }
    }
    CSLDestroy(files);
  }
  GDALRasterBand* band = ds->GetRasterBand(1);
  const int width = ds->GetRasterXSize(), height = ds->GetRasterYSize();
  if (width <= 0 || height <= 0 || width > 200000 || height > 200000 || uint64_t(width) * uint64_t(height) > (uint64_t(1) << 32))
    return Status::failure(Error::unsupported_input, fmt::format("{}: raster size {}x{} not supported", path, width, height));
  const GDALDataType type = band->GetRasterDataType();
  if (GDALDataTypeIsComplex(type))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: complex samples ({}) are not elevations", path, GDALGetDataTypeName(type)));

  SourceInfo info;
  info.path = path;
  info.width = width;
  info.height = height;
  info.sample_type = type_name(type, band);
  info.nodata = options.nodata_value;
  if (!info.nodata) {
    int has = 0;
    const double v = band->GetNoDataValue(&has);
    if (has) info.nodata = v;
  }
  int has_scale = 0, has_offset = 0;
  const double scale = band->GetScale(&has_scale), offset = band->GetOffset(&has_offset);
  if (has_scale && std::isfinite(scale) && scale != 0.0) info.scale = scale;
  if (has_offset && std::isfinite(offset)) info.offset = offset;
  info.height_unit = declared_height_unit(ds->GetSpatialRef(), band);

  const char* aop = ds->GetMetadataItem(GDALMD_AREA_OR_POINT);
  const bool point = aop && EQUAL(aop, GDALMD_AOP_POINT);
  double gt[6];
  if (ds->GetGeoTransform(gt) == CE_None) {
    // Sample centre (col, row) is raster point (col + 0.5, row + 0.5), except in a PixelIsPoint
    // GeoTIFF read with GTIFF_POINT_GEO_IGNORE, whose geotransform already puts (0, 0) on the sample.
    const double shift = point && (driver == "GTiff" || driver == "COG") ? 0.0 : 0.5;
    auto model = [&](double px, double py, double& x, double& y) {
      x = gt[0] + px * gt[1] + py * gt[2];
      y = gt[3] + px * gt[4] + py * gt[5];
    };
    double x0, y0, x1, y1, x2, y2;
    model(shift, shift, x0, y0);
    model(1 + shift, shift, x1, y1);
    model(shift, 1 + shift, x2, y2);
    info.geo = sample_geo_from_points(x0, y0, x1, y1, x2, y2, point);
  }
  if (info.geo.valid) {
    double cx = 0, cy = 0;
    AffineMap::from(info.geo).to_model(0.5 * (width - 1), 0.5 * (height - 1), cx, cy);
    info.crs = crs_from_srs(ds->GetSpatialRef(), cx, cy);
    // File units (e.g. US feet, grads) to metres / degrees.
    if (info.crs.kind != CrsKind::none && info.crs.model_unit != 1.0)
      for (double& c : info.geo.c) c *= info.crs.model_unit;
  }

  const std::string nodata_text = info.nodata ? fmt::format(", nodata {}", *info.nodata) : "";
  const std::string scale_text =
      info.scale != 1.0 || info.offset != 0.0 ? fmt::format(", scale {} offset {}", info.scale, info.offset) : "";
  if (driver == "GTiff" || driver == "COG") {
    int bw = 0, bh = 0;
    band->GetBlockSize(&bw, &bh);
    // Strips span the width; tiles are narrower or wider (a 256 tile over 37 columns), or square
    // multiples of 16 (a strip as tall as the image is wide, and 16-aligned, reads as tiled here).
    const bool tiled = bw != width || (bw == bh && bw % 16 == 0 && bw >= 64 && bh < height);
    info.description = fmt::format("GeoTIFF {} {}x{} {} {}{}{}, {}", info.sample_type, width, height,
                                   tiled ? "tiled" : "strips", compression_name(ds.get()), nodata_text, scale_text,
                                   point ? "PixelIsPoint" : "PixelIsArea");
  } else {
    info.description = fmt::format("{} ({}) {} {}x{}{}{}, {}", driver, ds->GetDriver()->GetMetadataItem(GDAL_DMD_LONGNAME),
                                   info.sample_type, width, height, nodata_text, scale_text,
                                   point ? "pixel is point" : "pixel is area");
  }
  // A plain GeoTIFF of 1-, 2- or 4-byte samples: its blocks decoded by tiff_blocks.cpp.
  std::unique_ptr<TiffBlockReader> tiff;
  if (driver == "GTiff" && GDALDataTypeIsComplex(type) == 0 && GDALGetDataTypeSizeBytes(type) <= 4) {
    const Status direct = TiffBlockReader::open(path, width, height, GDALGetDataTypeSizeBytes(type), tiff);
    info.decoder = direct.ok() ? "blocks decoded by the cooker" : fmt::format("blocks decoded by GDAL ({})", direct.message);
  }
  // A VRT mosaic of such tiles (gdalbuildvrt's): composed here from the tiles' blocks (vrt_tiles.h).
  if (driver == "VRT") {
    if (!vrt_tried) vrt_refused = VrtTileReader::open(path, width, height, vrt);
    info.decoder = vrt ? fmt::format("{} tile sources composed by the cooker from their blocks (a tile it "
                                     "does not decode is read by GDAL)", vrt->sources())
                       : fmt::format("read by GDAL's VRT driver ({})", vrt_refused.message);
  }
  // The source owns the dataset from here on (the band pointer stays valid with it).
  auto src = std::make_unique<GdalSource>(std::move(ds), band, GDALDataTypeIsFloating(type) != 0,
                                           info.sample_type == "Int8", std::move(tiff), std::move(vrt),
                                           std::move(reads_from));
  src->info_mut() = std::move(info);
  out = std::move(src);
  return Status::success();
}

}  // namespace terrain::cook
