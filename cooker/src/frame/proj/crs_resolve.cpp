// CRS resolution through PROJ and libgeotiff (crs.h): --crs / --frame spellings, GeoTIFF keys.
#include "frame/crs.h"

#include <geotiff/geo_normalize.h>
#include <geotiff/geo_simpletags.h>
#include <geotiff/geo_tiffp.h>
#include <geotiff/geotiff.h>
#include <geotiff/geovalues.h>
#include <proj.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fmt/format.h>
#include <iterator>
#include <memory>
#include <utility>

namespace terrain::cook {
namespace {

constexpr int kUserDefined = 32767;  // GeoTIFF "user-defined / unknown" code

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

// PROJ prints lookup misses ("crs not found") to stderr by default; errors reach the user through
// our own messages instead.
struct ProjContext {
  PJ_CONTEXT* ctx = nullptr;
  ProjContext() {
    ctx = proj_context_create();
    if (ctx) proj_log_func(ctx, nullptr, [](void*, int, const char*) {});
  }
  ~ProjContext() {
    if (ctx) proj_context_destroy(ctx);
  }
  ProjContext(const ProjContext&) = delete;
  ProjContext& operator=(const ProjContext&) = delete;
};

double inverse_flattening(double a, double b) { return a == b ? 0.0 : a / (a - b); }

struct PjPtr {
  PJ* p = nullptr;
  explicit PjPtr(PJ* q) : p(q) {}
  ~PjPtr() { proj_destroy(p); }
  PjPtr(const PjPtr&) = delete;
  PjPtr& operator=(const PjPtr&) = delete;
};

// A CRS PROJ resolves from `definition` (EPSG:n, ESRI:n, a PROJ string, WKT): projected -> kind
// projected with its WKT2:2019 as the definition; geographic -> kind geographic. Anything else
// PROJ cannot identify, or without a metric meaning here (geocentric, vertical, ...), fails.
Status resolve_with_proj(const std::string& definition, SourceCrs& out) {
  ProjContext proj;
  // A bare PROJ string defines a conversion; "+type=crs" makes it the CRS it implies.
  std::string text = definition;
  if (text.rfind("+proj=", 0) == 0 && text.find("+type=crs") == std::string::npos) text += " +type=crs";
  PjPtr crs(proj.ctx ? proj_create(proj.ctx, text.c_str()) : nullptr);
  if (!crs.p)
    return Status::failure(Error::invalid_argument,
                           fmt::format("PROJ cannot resolve the CRS '{}' (give EPSG:<code>, a PROJ string or WKT)", definition));
  PJ_TYPE type = proj_get_type(crs.p);
  if (type == PJ_TYPE_BOUND_CRS) {  // +towgs84 and the like: the datum shift is not ours to apply
    PjPtr base(proj_get_source_crs(proj.ctx, crs.p));
    if (base.p) std::swap(crs.p, base.p);
    type = proj_get_type(crs.p);
  }
  const bool geographic = type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS;
  if (type != PJ_TYPE_PROJECTED_CRS && !geographic)
    return Status::failure(Error::unsupported_input,
                           fmt::format("'{}' ({}) is neither a projected nor a geographic CRS: it has no metric frame "
                                       "meaning here", definition, proj_get_name(crs.p) ? proj_get_name(crs.p) : "?"));
  PjPtr ell(proj_get_ellipsoid(proj.ctx, crs.p));
  double a = 0, b = 0, rf = 0;
  int computed = 0;
  if (!ell.p || !proj_ellipsoid_get_parameters(proj.ctx, ell.p, &a, &b, &computed, &rf) || !(a > 0))
    return Status::failure(Error::unsupported_input, fmt::format("'{}': PROJ finds no ellipsoid for it", definition));
  SourceCrs c;
  c.tm.semi_major_m = a;
  c.tm.inverse_flattening = inverse_flattening(a, b);
  const char* auth = proj_get_id_auth_name(crs.p, 0);
  const char* code = proj_get_id_code(crs.p, 0);
  if (auth && code && std::string(auth) == "EPSG") c.epsg = std::atoi(code);
  const char* name = proj_get_name(crs.p);
  c.name = name ? name : definition;
  if (geographic) {
    c.kind = CrsKind::geographic;
    out = c;
    return Status::success();
  }
  const char* wkt = proj_as_wkt(proj.ctx, crs.p, PJ_WKT2_2019, nullptr);
  if (!wkt) return Status::failure(Error::unsupported_input, fmt::format("'{}': PROJ cannot write it as WKT2", definition));
  c.kind = CrsKind::projected;
  c.tm.kind = ProjectionKind::proj;
  c.tm.epsg = c.epsg;
  c.tm.definition = wkt;
  c.tm.lat0_deg = c.tm.lon0_deg = c.tm.false_easting_m = c.tm.false_northing_m = 0;
  c.tm.scale_k0 = 1;
  c.tm.name = c.name;
  out = c;
  return Status::success();
}

std::string take_name(char* name) {
  std::string s = name ? name : "";
  if (name) GTIFFreeMemory(name);
  return s;
}

// Fills `out` from a normalized definition (file keys or an EPSG code expanded by libgeotiff).
SourceCrs crs_from_defn(const GTIFDefn& d, const std::string& pcs_name) {
  SourceCrs crs;
  if (!d.DefnSet) return crs;  // kind none
  crs.tm.semi_major_m = d.SemiMajor;
  crs.tm.inverse_flattening = inverse_flattening(d.SemiMajor, d.SemiMinor);
  if (d.PM != kUserDefined && d.PMLongToGreenwich != 0.0) {
    crs.kind = CrsKind::unsupported;
    crs.projection = fmt::format("prime meridian {} deg from Greenwich", d.PMLongToGreenwich);
    crs.name = pcs_name;
    return crs;
  }
  if (d.Model == ModelTypeGeographic) {
    crs.kind = CrsKind::geographic;
    crs.epsg = d.GCS != kUserDefined ? d.GCS : 0;
    crs.name = crs.epsg ? fmt::format("EPSG:{}", crs.epsg) : "geographic (lon/lat)";
    if (crs.epsg == 4326) crs.name = "WGS 84 (EPSG:4326)";
    if (d.SemiMajor <= 0) {
      crs.kind = CrsKind::unsupported;
      crs.projection = "geographic CRS without a known ellipsoid";
    }
    return crs;
  }
  if (d.Model == ModelTypeGeocentric) {
    crs.kind = CrsKind::unsupported;
    crs.projection = "geocentric";
    crs.name = pcs_name;
    return crs;
  }
  if (d.Model != ModelTypeProjected) return SourceCrs{};  // keys without a model type: no CRS
  crs.epsg = d.PCS != kUserDefined ? d.PCS : 0;
  crs.name = !pcs_name.empty() ? pcs_name : (crs.epsg ? fmt::format("EPSG:{}", crs.epsg) : "");
  if (d.CTProjection != CT_TransverseMercator || d.SemiMajor <= 0) {
    // Any other projection: through PROJ, by its EPSG code when the file names one, else by the
    // PROJ string libgeotiff writes from the keys.
    std::string definition = crs.epsg ? fmt::format("EPSG:{}", crs.epsg) : "";
    if (definition.empty()) {
      char* p4 = GTIFGetProj4Defn(const_cast<GTIFDefn*>(&d));
      if (p4) {
        definition = std::string(p4) + " +type=crs";
        GTIFFreeMemory(p4);
      }
    }
    SourceCrs resolved;
    if (!definition.empty() && resolve_with_proj(definition, resolved).ok() && resolved.kind == CrsKind::projected) {
      if (!pcs_name.empty()) resolved.name = resolved.tm.name = pcs_name;
      if (crs.epsg) resolved.epsg = resolved.tm.epsg = crs.epsg;
      return resolved;
    }
    crs.kind = CrsKind::unsupported;
    const char* method = GTIFValueName(ProjCoordTransGeoKey, d.CTProjection);
    crs.projection = d.CTProjection == kUserDefined ? "unknown projection"
                                                    : (method ? method : fmt::format("projection {}", d.CTProjection));
    return crs;
  }
  crs.kind = CrsKind::transverse_mercator;
  crs.tm.kind = ProjectionKind::transverse_mercator;
  crs.tm.epsg = crs.epsg;
  crs.tm.scale_k0 = 1.0;
  for (int i = 0; i < d.nParms; ++i) {
    switch (d.ProjParmId[i]) {
      case ProjNatOriginLatGeoKey: crs.tm.lat0_deg = d.ProjParm[i]; break;
      case ProjNatOriginLongGeoKey: crs.tm.lon0_deg = d.ProjParm[i]; break;
      case ProjScaleAtNatOriginGeoKey: crs.tm.scale_k0 = d.ProjParm[i]; break;
      case ProjFalseEastingGeoKey: crs.tm.false_easting_m = d.ProjParm[i]; break;
      case ProjFalseNorthingGeoKey: crs.tm.false_northing_m = d.ProjParm[i]; break;
      default: break;
    }
  }
  if (crs.name.empty()) {
    const std::string utm = utm_zone_name(crs.tm);
    crs.name = utm.empty() ? "Transverse Mercator (explicit parameters)" : utm + " (explicit parameters)";
  }
  crs.tm.name = crs.name;
  return crs;
}

// Expands an EPSG code through libgeotiff's normalization (which asks PROJ's database).
Status crs_from_epsg(int code, SourceCrs& out) {
  if (code <= 0 || code >= kUserDefined)
    return Status::failure(Error::invalid_argument,
                           fmt::format("EPSG:{} is out of the range GeoTIFF keys can hold (1..32766)", code));
  ProjContext proj;
  char* name = nullptr;
  short proj_op = 0, uom = 0, gcs = 0;
  const bool projected = GTIFGetPCSInfoEx(proj.ctx, code, &name, &proj_op, &uom, &gcs) != 0;
  std::string pcs_name = take_name(name);
  bool geographic = false;
  if (!projected) {
    short datum = 0, pm = 0, angle = 0;
    geographic = GTIFGetGCSInfoEx(proj.ctx, code, &name, &datum, &pm, &angle) != 0;
    pcs_name = take_name(name);
  }
  if (!projected && !geographic) {
    // Codes libgeotiff's tables do not expand (e.g. compound or newer CRSs): ask PROJ itself.
    if (resolve_with_proj(fmt::format("EPSG:{}", code), out).ok()) return Status::success();
    return Status::failure(Error::invalid_argument,
                           fmt::format("EPSG:{} is not a projected or geographic CRS in PROJ's database", code));
  }

  TIFFMethod methods;
  GTIFSetSimpleTagsMethods(&methods);
  std::unique_ptr<ST_TIFF, void (*)(ST_TIFF*)> st(ST_Create(), ST_Destroy);
  std::unique_ptr<GTIF, void (*)(GTIF*)> gtif(GTIFNewWithMethods(st.get(), &methods), GTIFFree);
  if (!gtif) return Status::failure(Error::internal, "libgeotiff: cannot create an in-memory key set");
  GTIFAttachPROJContext(gtif.get(), proj.ctx);
  if (projected) {
    GTIFKeySet(gtif.get(), GTModelTypeGeoKey, TYPE_SHORT, 1, ModelTypeProjected);
    GTIFKeySet(gtif.get(), ProjectedCSTypeGeoKey, TYPE_SHORT, 1, code);
  } else {
    GTIFKeySet(gtif.get(), GTModelTypeGeoKey, TYPE_SHORT, 1, ModelTypeGeographic);
    GTIFKeySet(gtif.get(), GeographicTypeGeoKey, TYPE_SHORT, 1, code);
  }
  GTIFDefn defn;
  if (!GTIFGetDefn(gtif.get(), &defn))
    return Status::failure(Error::invalid_argument, fmt::format("EPSG:{}: libgeotiff cannot expand this code", code));
  out = crs_from_defn(defn, pcs_name);
  if (out.kind == CrsKind::projected) return Status::success();
  if (geographic && out.kind == CrsKind::geographic) out.name = pcs_name + fmt::format(" (EPSG:{})", code);
  out.epsg = code;
  out.tm.epsg = out.kind == CrsKind::transverse_mercator ? code : 0;
  return Status::success();
}

bool parse_double(std::string_view text, double& v) {
  const char* b = text.data();
  const char* e = text.data() + text.size();
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e && std::isfinite(v);
}

Status parse_tm(const std::string& spec, SourceCrs& out) {
  const std::string body = spec.substr(3);
  SourceCrs crs;
  crs.kind = CrsKind::transverse_mercator;
  crs.tm.kind = ProjectionKind::transverse_mercator;
  crs.tm.semi_major_m = kWgs84A;
  crs.tm.inverse_flattening = kWgs84Rf;
  crs.tm.scale_k0 = 1.0;
  bool have_lon0 = false;
  size_t pos = 0;
  while (pos <= body.size()) {
    size_t end = body.find(',', pos);
    if (end == std::string::npos) end = body.size();
    const std::string item = body.substr(pos, end - pos);
    pos = end + 1;
    if (item.empty()) continue;
    const size_t eq = item.find('=');
    if (eq == std::string::npos)
      return Status::failure(Error::invalid_argument, fmt::format("--crs {}: '{}' is not key=value", spec, item));
    const std::string key = lower(item.substr(0, eq));
    const std::string value = item.substr(eq + 1);
    if (key == "ellps") {
      const std::string v = lower(value);
      if (v == "wgs84") {
        crs.tm.semi_major_m = kWgs84A;
        crs.tm.inverse_flattening = kWgs84Rf;
      } else if (v == "grs80") {
        crs.tm.semi_major_m = kGrs80A;
        crs.tm.inverse_flattening = kGrs80Rf;
      } else {
        return Status::failure(Error::invalid_argument,
                               fmt::format("--crs {}: ellps={} unknown (WGS84, GRS80, or give a= and rf=)", spec, value));
      }
      continue;
    }
    double v = 0;
    if (!parse_double(value, v))
      return Status::failure(Error::invalid_argument, fmt::format("--crs {}: {}={} is not a number", spec, key, value));
    const std::pair<const char*, double*> numeric_keys[] = {
        {"lon0", &crs.tm.lon0_deg},        {"lat0", &crs.tm.lat0_deg},          {"k0", &crs.tm.scale_k0},
        {"x0", &crs.tm.false_easting_m},   {"y0", &crs.tm.false_northing_m},    {"a", &crs.tm.semi_major_m},
        {"rf", &crs.tm.inverse_flattening}};
    const auto it = std::find_if(std::begin(numeric_keys), std::end(numeric_keys),
                                 [&](const auto& k) { return key == k.first; });
    if (it == std::end(numeric_keys))
      return Status::failure(Error::invalid_argument,
                             fmt::format("--crs {}: unknown key '{}' (lon0, lat0, k0, x0, y0, ellps, a, rf)", spec, key));
    *it->second = v;
    have_lon0 = have_lon0 || key == "lon0";
  }
  if (!have_lon0) return Status::failure(Error::invalid_argument, fmt::format("--crs {}: lon0= is required", spec));
  if (std::fabs(crs.tm.lon0_deg) > 180 || std::fabs(crs.tm.lat0_deg) >= 90 || !(crs.tm.scale_k0 > 0) ||
      !(crs.tm.semi_major_m > 0) || crs.tm.inverse_flattening < 0 || (crs.tm.inverse_flattening > 0 && crs.tm.inverse_flattening < 2))
    return Status::failure(Error::invalid_argument, fmt::format("--crs {}: parameter out of range", spec));
  if (crs.tm.inverse_flattening == 0)
    return Status::failure(Error::invalid_argument, fmt::format("--crs {}: a sphere (rf=0) is not supported", spec));
  const std::string utm = utm_zone_name(crs.tm);
  crs.name = utm.empty() ? fmt::format("Transverse Mercator ({})", body) : utm + fmt::format(" ({})", body);
  crs.tm.name = crs.name;
  out = crs;
  return Status::success();
}

}  // namespace

Status parse_crs_spec(const std::string& spec_in, SourceCrs& out) {
  const std::string spec = lower(spec_in);
  if (spec == "local") {
    out = SourceCrs{};
    out.kind = CrsKind::local;
    out.name = "local metric frame (no geodetic meaning)";
    out.tm.kind = ProjectionKind::local;
    out.tm.name = out.name;
    return Status::success();
  }
  if (spec.rfind("tm:", 0) == 0) return parse_tm(spec_in, out);
  if (spec.rfind("epsg:", 0) == 0) {
    int code = 0;
    const char* b = spec.data() + 5;
    const char* e = spec.data() + spec.size();
    auto [p, ec] = std::from_chars(b, e, code);
    if (ec != std::errc() || p != e)
      return Status::failure(Error::invalid_argument, fmt::format("'{}': expected EPSG:<number>", spec_in));
    return crs_from_epsg(code, out);
  }
  // Anything else PROJ resolves: a PROJ string, WKT, ESRI:/IGNF: codes.
  if (Status st = resolve_with_proj(spec_in, out); st.ok()) return st;
  return Status::failure(Error::invalid_argument,
                         fmt::format("'{}' is not a CRS this tool reads (PROJ cannot resolve it): use EPSG:<code> (e.g. "
                                     "EPSG:4326, EPSG:32633, EPSG:2154), a PROJ string (+proj=lcc ...) or WKT, "
                                     "tm:lon0=..,lat0=..,k0=..,x0=..,y0=..,ellps=WGS84|GRS80, or local",
                                     spec_in));
}

SourceCrs crs_from_geotiff(gtiff* gtif, double center_x, double center_y) {
  ProjContext proj;
  GTIFAttachPROJContext(gtif, proj.ctx);
  GTIFDefn defn;
  if (!GTIFGetDefn(gtif, &defn)) {
    GTIFAttachPROJContext(gtif, nullptr);
    return SourceCrs{};
  }
  std::string pcs_name;
  if (defn.Model == ModelTypeProjected && defn.PCS != kUserDefined) {
    char* name = nullptr;
    short op = 0, uom = 0, gcs = 0;
    if (GTIFGetPCSInfoEx(proj.ctx, defn.PCS, &name, &op, &uom, &gcs)) pcs_name = take_name(name);
  }
  SourceCrs crs = crs_from_defn(defn, pcs_name);
  const double unit = defn.Model == ModelTypeGeographic ? defn.UOMAngleInDegrees : defn.UOMLengthInMeters;
  if (unit > 0) crs.model_unit = unit;
  if (crs.kind == CrsKind::unsupported && defn.Model == ModelTypeProjected) {
    double x = center_x, y = center_y;
    if (GTIFProj4ToLatLong(&defn, 1, &x, &y)) {
      crs.center_lon = x;
      crs.center_lat = y;
    }
  }
  GTIFAttachPROJContext(gtif, nullptr);
  return crs;
}

}  // namespace terrain::cook
