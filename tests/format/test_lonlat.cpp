// terrain-inspect's longitude/latitude input (issue 11, item 11): WGS 84 by default through PROJ,
// --lonlat-crs for other datums. Oracles: GeographicLib's exact Transverse Mercator where no datum
// shift applies, GDAL's gdaltransform (a separate program) where one does.
#include <GeographicLib/TransverseMercatorExact.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "inspect.h"
#include "inspect_lonlat.h"

namespace terrain {
namespace {

FrameCrs utm_frame(int epsg, double lon0, double a, double rf, const char* name) {
  FrameCrs f;
  f.kind = ProjectionKind::transverse_mercator;
  f.epsg = epsg;
  f.semi_major_m = a;
  f.inverse_flattening = rf;
  f.lon0_deg = lon0;
  f.scale_k0 = 0.9996;
  f.false_easting_m = 500000;
  f.name = name;
  return f;
}

// The frame position of (lon, lat) on the frame's own ellipsoid, with no datum shift.
void direct(const FrameCrs& f, double lon, double lat, double& x, double& y) {
  const GeographicLib::TransverseMercatorExact tm(f.semi_major_m, 1.0 / f.inverse_flattening, f.scale_k0);
  double x0 = 0, y0 = 0;
  tm.Forward(f.lon0_deg, f.lat0_deg, f.lon0_deg, x0, y0);
  tm.Forward(f.lon0_deg, lat, lon, x, y);
  x += f.false_easting_m;
  y += f.false_northing_m - y0;
}

// gdaltransform's answer for lon/lat on `from` in `to` (easting northing); false when it cannot run.
bool gdaltransform(const char* from, const char* to, double lon, double lat, double& x, double& y) {
  const std::string cmd = std::string("echo '") + std::to_string(lon) + " " + std::to_string(lat) +
                          "' | gdaltransform -s_srs " + from + " -t_srs " + to + " -output_xy 2>/dev/null";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return false;
  const int n = std::fscanf(p, "%lf %lf", &x, &y);
  return pclose(p) == 0 && n == 2;
}

constexpr double kWgs84A = 6378137.0, kWgs84Rf = 298.257223563, kGrs80Rf = 298.257222101;
constexpr double kClarke1866A = 6378206.4, kClarke1866Rf = 294.978698213898;

}  // namespace

// WGS 84 in, a WGS 84 frame: PROJ must add nothing to the projection (bound 1e-6 m vs GeographicLib).
TEST(LonLat, Wgs84OnAWgs84FrameIsTheProjectionAlone) {
  const FrameCrs f = utm_frame(32605, -153, kWgs84A, kWgs84Rf, "WGS 84 / UTM zone 5N");
  inspect::LonLatToFrame conv;
  ASSERT_TRUE(conv.init(f, "").ok());
  for (auto [lon, lat] : {std::pair{-155.28, 19.41}, {-153.0, 0.5}, {-156.9, 22.1}, {-150.2, 60.3}}) {
    double x = 0, y = 0, dx = 0, dy = 0;
    ASSERT_TRUE(conv.convert(lon, lat, x, y).ok());
    direct(f, lon, lat, dx, dy);
    EXPECT_NEAR(x, dx, 1e-6) << lon << "," << lat;
    EXPECT_NEAR(y, dy, 1e-6) << lon << "," << lat;
  }
}

// WGS 84 in, an ETRS89 frame (by its EPSG code, and a cooker-centred frame whose name cites the
// input's EPSG:4258): EPSG's ETRS89 -> WGS 84 transformation is the null one, so again 1e-6 m.
TEST(LonLat, Wgs84OnAnEtrs89FrameIsTheProjectionAlone) {
  FrameCrs utm = utm_frame(25833, 15, kWgs84A, kGrs80Rf, "ETRS89 / UTM zone 33N");
  FrameCrs centred = utm;
  centred.epsg = 0;
  centred.lon0_deg = 14.5;
  centred.scale_k0 = 1;
  centred.false_easting_m = 0;
  centred.name = "Transverse Mercator centred on the data (lon0 14.500000, EPSG:4258)";
  for (const FrameCrs& f : {utm, centred}) {
    inspect::LonLatToFrame conv;
    ASSERT_TRUE(conv.init(f, "").ok());
    EXPECT_NE(conv.description().find("ETRS89"), std::string::npos) << conv.description();
    for (auto [lon, lat] : {std::pair{14.5, 46.05}, {13.4, 52.5}, {16.2, 48.2}}) {
      double x = 0, y = 0, dx = 0, dy = 0;
      ASSERT_TRUE(conv.convert(lon, lat, x, y).ok());
      direct(f, lon, lat, dx, dy);
      EXPECT_NEAR(x, dx, 1e-6) << f.name << " " << lon << "," << lat;
      EXPECT_NEAR(y, dy, 1e-6) << f.name << " " << lon << "," << lat;
    }
  }
}

// WGS 84 in, a NAD27 frame (EPSG:26711, NAD27 / UTM zone 11N). Debian's proj-data ships no NAD27
// grid (no conus / ntv2_0 / us_noaa files), so PROJ (and gdaltransform with it) falls back to
// EPSG's 3-parameter NAD27 -> WGS 84 transformations, good to some metres against the grid
// answer; the test therefore checks agreement with gdaltransform to 1 mm (the same PROJ database
// through another program), and that the shift PROJ applies is the tens of metres the datums differ
// (the old answer, on the frame's ellipsoid with no shift, was 51 m off in the issue).
TEST(LonLat, Wgs84OnANad27FrameAgreesWithGdaltransform) {
  const FrameCrs f = utm_frame(26711, -117, kClarke1866A, kClarke1866Rf, "NAD27 / UTM zone 11N");
  inspect::LonLatToFrame conv;
  ASSERT_TRUE(conv.init(f, "").ok());
  for (auto [lon, lat] : {std::pair{-117.5, 34.0}, {-118.2, 36.5}, {-116.1, 33.2}}) {
    double x = 0, y = 0, ox = 0, oy = 0, dx = 0, dy = 0;
    ASSERT_TRUE(conv.convert(lon, lat, x, y).ok());
    ASSERT_TRUE(gdaltransform("EPSG:4326", "EPSG:26711", lon, lat, ox, oy)) << "gdaltransform (gdal-bin) failed";
    EXPECT_NEAR(x, ox, 1e-3) << lon << "," << lat;
    EXPECT_NEAR(y, oy, 1e-3) << lon << "," << lat;
    direct(f, lon, lat, dx, dy);
    EXPECT_GT(std::hypot(x - dx, y - dy), 20.0) << "no datum shift applied at " << lon << "," << lat;
    EXPECT_LT(std::hypot(x - dx, y - dy), 200.0) << lon << "," << lat;
  }
}

// --lonlat-crs EPSG:4267 on the NAD27 frame: lon/lat already on its datum, so the projection
// alone (1e-6 m), and gdaltransform agrees.
TEST(LonLat, LonLatOnTheFramesOwnDatumIsNotShifted) {
  const FrameCrs f = utm_frame(26711, -117, kClarke1866A, kClarke1866Rf, "NAD27 / UTM zone 11N");
  inspect::LonLatToFrame conv;
  ASSERT_TRUE(conv.init(f, "EPSG:4267").ok());
  double x = 0, y = 0, dx = 0, dy = 0, ox = 0, oy = 0;
  ASSERT_TRUE(conv.convert(-117.5, 34.0, x, y).ok());
  direct(f, -117.5, 34.0, dx, dy);
  EXPECT_NEAR(x, dx, 1e-6);
  EXPECT_NEAR(y, dy, 1e-6);
  ASSERT_TRUE(gdaltransform("EPSG:4267", "EPSG:26711", -117.5, 34.0, ox, oy));
  EXPECT_NEAR(x, ox, 1e-3);
  EXPECT_NEAR(y, oy, 1e-3);
}

// A frame that names no datum (epsg 0, no EPSG code in its name): lon/lat on its ellipsoid.
TEST(LonLat, FrameWithoutADatumTakesItsOwnEllipsoid) {
  FrameCrs f = utm_frame(0, -117, kClarke1866A, kClarke1866Rf, "Transverse Mercator (explicit parameters)");
  inspect::LonLatToFrame conv;
  ASSERT_TRUE(conv.init(f, "").ok());
  EXPECT_NE(conv.description().find("no named datum"), std::string::npos) << conv.description();
  double x = 0, y = 0, dx = 0, dy = 0;
  ASSERT_TRUE(conv.convert(-117.5, 34.0, x, y).ok());
  direct(f, -117.5, 34.0, dx, dy);
  EXPECT_NEAR(x, dx, 1e-6);
  EXPECT_NEAR(y, dy, 1e-6);
}

TEST(LonLat, BadLonLatCrsIsAUsageErrorNamingIt) {
  const FrameCrs f = utm_frame(32605, -153, kWgs84A, kWgs84Rf, "WGS 84 / UTM zone 5N");
  for (const char* bad : {"EPSG:32633", "EPSG:999999", "nad27-ish"}) {
    inspect::LonLatToFrame conv;
    const Status s = conv.init(f, bad);
    EXPECT_EQ(s.code, Error::invalid_argument) << bad;
    EXPECT_NE(s.message.find(bad), std::string::npos) << s.message;
  }
  inspect::LonLatToFrame conv;
  EXPECT_EQ(conv.init(FrameCrs{}, "").code, Error::invalid_argument);  // local frame
}

}  // namespace terrain
