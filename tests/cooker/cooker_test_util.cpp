#include <nlohmann/json.hpp>
#include "cooker_test_util.h"

#include <cstdio>
#include <gtest/gtest.h>

#include <geotiff/geo_normalize.h>
#include <geotiff/geotiff.h>
#include <geotiff/geovalues.h>
#include <geotiff/xtiffio.h>
#include <tiffio.h>

#include <GeographicLib/TransverseMercatorExact.hpp>
#include <cstring>
#include <map>
#include <mutex>

#include "inputs/raster.h"
#include "terrain/bc_decode.h"

namespace terrain::test {
namespace {

TIFFExtendProc g_parent = nullptr;
void nodata_tag_extender(TIFF* tif) {
  static const TIFFFieldInfo fields[] = {
      {42113, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")}};
  TIFFMergeFieldInfo(tif, fields, 1);
  if (g_parent) g_parent(tif);
}

}  // namespace

bool write_geotiff(const std::string& path, const SyntheticDem& dem, bool tiled, std::string& error) {
  static std::once_flag once;
  std::call_once(once, [] {
    XTIFFInitialize();
    g_parent = TIFFSetTagExtender(nodata_tag_extender);
  });
  TIFF* tif = XTIFFOpen(path.c_str(), "w");
  if (!tif) {
    error = "cannot create " + path;
    return false;
  }
  const int bytes = dem.int16 ? 2 : 4;
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(dem.width));
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(dem.height));
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(1));
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(bytes * 8));
  TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, uint16_t(dem.int16 ? SAMPLEFORMAT_INT : SAMPLEFORMAT_IEEEFP));
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, uint16_t(PHOTOMETRIC_MINISBLACK));
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, uint16_t(PLANARCONFIG_CONTIG));
  TIFFSetField(tif, TIFFTAG_COMPRESSION, uint16_t(tiled ? COMPRESSION_ADOBE_DEFLATE : COMPRESSION_NONE));
  if (dem.nodata) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", *dem.nodata);
    TIFFSetField(tif, 42113, buf);
  }
  // Raster space (0, 0) is the NW pixel corner for PixelIsArea, the NW sample for PixelIsPoint.
  const double tie_x = dem.point ? dem.x0 : dem.x0 - 0.5 * dem.dx;
  const double tie_y = dem.point ? dem.y0 : dem.y0 + 0.5 * dem.dy;
  double tiepoint[6] = {0, 0, 0, tie_x, tie_y, 0};
  double scale[3] = {dem.dx, dem.dy, 0};
  TIFFSetField(tif, TIFFTAG_GEOTIEPOINTS, 6, tiepoint);
  TIFFSetField(tif, TIFFTAG_GEOPIXELSCALE, 3, scale);
  GTIF* gtif = GTIFNew(tif);
  if (dem.epsg_geographic) {
    GTIFKeySet(gtif, GTModelTypeGeoKey, TYPE_SHORT, 1, ModelTypeGeographic);
    GTIFKeySet(gtif, GeographicTypeGeoKey, TYPE_SHORT, 1, dem.epsg_geographic);
  } else if (dem.epsg_projected) {
    GTIFKeySet(gtif, GTModelTypeGeoKey, TYPE_SHORT, 1, ModelTypeProjected);
    GTIFKeySet(gtif, ProjectedCSTypeGeoKey, TYPE_SHORT, 1, dem.epsg_projected);
  }
  GTIFKeySet(gtif, GTRasterTypeGeoKey, TYPE_SHORT, 1, dem.point ? RasterPixelIsPoint : RasterPixelIsArea);
  GTIFWriteKeys(gtif);
  GTIFFree(gtif);

  auto encode = [&](double v, uint8_t* p) {
    if (std::isnan(v) && dem.nodata) v = *dem.nodata;
    if (dem.int16) {
      const int16_t s = int16_t(std::lround(v));
      std::memcpy(p, &s, 2);
    } else {
      const float f = float(v);
      std::memcpy(p, &f, 4);
    }
  };
  bool ok = true;
  if (tiled) {
    const uint32_t t = 64;
    TIFFSetField(tif, TIFFTAG_TILEWIDTH, t);
    TIFFSetField(tif, TIFFTAG_TILELENGTH, t);
    std::vector<uint8_t> buf(size_t(t) * t * size_t(bytes));
    for (uint32_t ty = 0; ty < uint32_t(dem.height) && ok; ty += t)
      for (uint32_t tx = 0; tx < uint32_t(dem.width) && ok; tx += t) {
        std::fill(buf.begin(), buf.end(), 0);
        for (uint32_t r = 0; r < t; ++r)
          for (uint32_t c = 0; c < t; ++c)
            if (ty + r < uint32_t(dem.height) && tx + c < uint32_t(dem.width))
              encode(dem.values[size_t(ty + r) * size_t(dem.width) + tx + c], &buf[(size_t(r) * t + c) * size_t(bytes)]);
        ok = TIFFWriteTile(tif, buf.data(), tx, ty, 0, 0) >= 0;
      }
  } else {
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, uint32_t(8));
    std::vector<uint8_t> row(size_t(dem.width) * size_t(bytes));
    for (int r = 0; r < dem.height && ok; ++r) {
      for (int c = 0; c < dem.width; ++c) encode(dem.values[size_t(r) * size_t(dem.width) + size_t(c)], &row[size_t(c) * size_t(bytes)]);
      ok = TIFFWriteScanline(tif, row.data(), uint32_t(r), 0) >= 0;
    }
  }
  XTIFFClose(tif);
  if (!ok) error = "write failed: " + path;
  return ok;
}

void lonlat_to_frame(const FrameCrs& crs, double lon, double lat, double& x, double& y) {
  const GeographicLib::TransverseMercatorExact tm(crs.semi_major_m, 1.0 / crs.inverse_flattening, crs.scale_k0);
  double x0 = 0, y0 = 0, e = 0, n = 0;
  tm.Forward(crs.lon0_deg, crs.lat0_deg, crs.lon0_deg, x0, y0);
  tm.Forward(crs.lon0_deg, lat, lon, e, n);
  x = crs.false_easting_m + e;
  y = crs.false_northing_m + n - y0;
}

uint64_t count_seam_mismatches(const ArchiveReader& reader, uint64_t& compared, std::string& first_problem) {
  compared = 0;
  uint64_t mismatches = 0;
  const auto nodes = reader.nodes();
  // Decoded heights (float bits as the shader computes them) and holes per node, on demand.
  struct Decoded {
    std::vector<float> h;
    std::vector<uint8_t> hole;
  };
  std::map<size_t, Decoded> cache;
  auto decoded = [&](size_t index) -> const Decoded& {
    auto it = cache.find(index);
    if (it != cache.end()) return it->second;
    auto data = std::make_unique<NodeData>();
    Decoded d;
    if (reader.decode_node(index, *data, kSectionHeights | kSectionAlbedo).ok()) {
      d.hole.resize(kHeightCount);
      decode_hole_mask(*data, d.hole.data());
      d.h.resize(kHeightCount);
      const NodeRecord& rec = nodes[index];
      for (size_t k = 0; k < size_t(kHeightCount); ++k)
        d.h[k] = units_to_metres_f32(vertex_units(rec.height_offset, data->heights[k], level_step_log2(reader.world(), int(rec.key.level))));
    }
    return cache.emplace(index, std::move(d)).first->second;
  };
  auto compare = [&](size_t a, int ia, int ja, size_t b, int ib, int jb) {
    const Decoded& da = decoded(a);
    const Decoded& db = decoded(b);
    if (da.h.empty() || db.h.empty()) {
      ++mismatches;
      if (first_problem.empty()) first_problem = "a node does not decode";
      return;
    }
    const size_t ka = size_t(ja) * kHeightSamples + size_t(ia), kb = size_t(jb) * kHeightSamples + size_t(ib);
    ++compared;
    const bool same = da.hole[ka] == db.hole[kb] &&
                      (da.hole[ka] || std::memcmp(&da.h[ka], &db.h[kb], sizeof(float)) == 0);
    if (!same) {
      ++mismatches;
      if (first_problem.empty()) {
        const NodeKey& A = nodes[a].key;
        const NodeKey& B = nodes[b].key;
        first_problem = "node " + std::to_string(A.level) + "/" + std::to_string(A.x) + "/" + std::to_string(A.y) +
                        " vertex (" + std::to_string(ia) + "," + std::to_string(ja) + ") = " + std::to_string(da.h[ka]) +
                        (da.hole[ka] ? " (hole)" : "") + " vs node " + std::to_string(B.level) + "/" +
                        std::to_string(B.x) + "/" + std::to_string(B.y) + " vertex (" + std::to_string(ib) + "," +
                        std::to_string(jb) + ") = " + std::to_string(db.h[kb]) + (db.hole[kb] ? " (hole)" : "");
      }
    }
  };
  const int n = kHeightSamples - 1;
  for (size_t a = 0; a < nodes.size(); ++a) {
    if (cache.size() > 1024) cache.clear();  // bounded memory; references are only held within one node
    const NodeKey k = nodes[a].key;
    // East and north neighbours at the same level share an edge column / row.
    const int64_t east = reader.find({k.level, k.x + 1, k.y});
    if (east >= 0)
      for (int j = 0; j <= n; ++j) compare(a, n, j, size_t(east), 0, j);
    const int64_t north = reader.find({k.level, k.x, k.y + 1});
    if (north >= 0)
      for (int i = 0; i <= n; ++i) compare(a, i, n, size_t(north), i, 0);
    // Parent: child vertex (2i, 2j) is parent vertex (64 * cx + i, 64 * cy + j).
    if (int(k.level) < kRootLevel) {
      const int64_t parent = reader.find(parent_of(k));
      if (parent >= 0) {
        const int ox = int(k.x & 1) * (n / 2), oy = int(k.y & 1) * (n / 2);
        for (int j = 0; j <= n / 2; ++j)
          for (int i = 0; i <= n / 2; ++i) compare(a, 2 * i, 2 * j, size_t(parent), ox + i, oy + j);
      }
    }
  }
  return mismatches;
}

void write_cook_input(const std::filesystem::path& dir, const std::string& stem, const SyntheticDem& dem, bool tiled,
                      cook::CookOptions& options) {
  const std::string tif = (dir / (stem + ".tif")).string();
  std::string error;
  ASSERT_TRUE(write_geotiff(tif, dem, tiled, error)) << error;
  options.inputs = {tif};
  options.output = (dir / (stem + ".terrain")).string();
}

void expect_refusal(const Status& st, Error code, std::initializer_list<std::string_view> fragments) {
  EXPECT_EQ(st.code, code) << st.to_string();
  for (std::string_view f : fragments) EXPECT_NE(st.message.find(f), std::string::npos) << st.message;
}

void cook_and_verify(const cook::CookOptions& options, cook::CookReport& report, CookedArchive& archive,
                     uint64_t& compared) {
  const Status st = cook::cook(options, {}, report);
  ASSERT_TRUE(st.ok()) << st.to_string();
  ASSERT_TRUE(archive.open(options.output).ok());
  const Status v = archive.reader.verify();
  ASSERT_TRUE(v.ok()) << v.to_string();
  compared = 0;
  std::string problem;
  EXPECT_EQ(count_seam_mismatches(archive.reader, compared, problem), 0u) << problem;
}

bool run_command(const std::string& cmd, std::string& out) {
  out.clear();
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return false;
  char buf[1 << 16];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  return pclose(p) == 0;
}

void expect_same_raster(const cook::Raster& a, const cook::Raster& b) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  ASSERT_EQ(a.values.size(), b.values.size());
  EXPECT_EQ(std::memcmp(a.values.data(), b.values.data(), a.values.size() * sizeof(float)), 0) << "values differ";
  for (int i = 0; i < 6; ++i) EXPECT_EQ(a.geo.c[i], b.geo.c[i]) << "geo.c[" << i << "]";
  EXPECT_EQ(a.geo.valid, b.geo.valid);
  EXPECT_EQ(a.geo.point_samples, b.geo.point_samples);
  EXPECT_EQ(a.nodata_declared, b.nodata_declared);
  EXPECT_EQ(a.description, b.description);
  EXPECT_EQ(a.crs.kind, b.crs.kind);
  EXPECT_EQ(a.crs.epsg, b.crs.epsg);
  EXPECT_EQ(a.crs.name, b.crs.name);
  EXPECT_EQ(a.crs.model_unit, b.crs.model_unit);
  EXPECT_EQ(std::memcmp(&a.crs.tm.lon0_deg, &b.crs.tm.lon0_deg, sizeof(double)), 0) << "lon0 bits";
  EXPECT_EQ(a.crs.tm.lat0_deg, b.crs.tm.lat0_deg);
  EXPECT_EQ(a.crs.tm.scale_k0, b.crs.tm.scale_k0);
  EXPECT_EQ(a.crs.tm.false_easting_m, b.crs.tm.false_easting_m);
  EXPECT_EQ(a.crs.tm.false_northing_m, b.crs.tm.false_northing_m);
  EXPECT_EQ(a.crs.tm.semi_major_m, b.crs.tm.semi_major_m);
  EXPECT_EQ(a.crs.tm.inverse_flattening, b.crs.tm.inverse_flattening);
}

double CookedArchive::tolerance() const {
  const auto j = nlohmann::json::parse(reader.world().cook_info_json, nullptr, false);
  return j.is_object() && j.contains("options") ? j["options"].value("tolerance_m", 0.0) : 0.0;
}

}  // namespace terrain::test
