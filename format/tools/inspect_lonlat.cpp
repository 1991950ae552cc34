#include "inspect_lonlat.h"

#include <proj.h>
#include <proj_experimental.h>  // CRS builders (proj_create_projected_crs, ...), stable since PROJ 6

#include <cmath>
#include <fmt/core.h>
#include <regex>

namespace terrain::inspect {
namespace {

constexpr double kDegree = 0.017453292519943295;

// One owned PJ; PROJ objects are freed with proj_destroy (null accepted).
struct PjPtr {
  PJ* p = nullptr;
  PjPtr() = default;
  explicit PjPtr(PJ* q) : p(q) {}
  ~PjPtr() { proj_destroy(p); }
  PjPtr(const PjPtr&) = delete;
  PjPtr& operator=(const PjPtr&) = delete;
  PjPtr(PjPtr&& o) noexcept : p(o.p) { o.p = nullptr; }
  PjPtr& operator=(PjPtr&& o) noexcept {
    std::swap(p, o.p);
    return *this;
  }
};

bool is_geographic(PJ_TYPE t) {
  return t == PJ_TYPE_GEOGRAPHIC_2D_CRS || t == PJ_TYPE_GEOGRAPHIC_3D_CRS || t == PJ_TYPE_GEODETIC_CRS;
}

// The EPSG code the frame's datum is known by: its own, else the last "EPSG:n" of its name.
int frame_datum_epsg(const FrameCrs& f) {
  if (f.epsg > 0) return f.epsg;
  static const std::regex code("EPSG:([0-9]{3,6})");
  int found = 0;
  for (auto it = std::sregex_iterator(f.name.begin(), f.name.end(), code); it != std::sregex_iterator(); ++it)
    found = std::stoi((*it)[1].str());
  return found;
}

}  // namespace

struct LonLatToFrame::Impl {
  PJ_CONTEXT* ctx = nullptr;
  PjPtr op;
  std::string description;
  Impl() {
    ctx = proj_context_create();
    proj_log_func(ctx, nullptr, [](void*, int, const char*) {});  // errors reach the user as Status
  }
  ~Impl() {
    op = PjPtr();
    proj_context_destroy(ctx);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  // The frame's geodetic CRS: from its EPSG code when that CRS has the frame's ellipsoid, else a
  // CRS on the frame's ellipsoid with an unknown datum (PROJ then shifts nothing).
  PjPtr frame_geodetic(const FrameCrs& f, std::string& what) {
    if (const int code = frame_datum_epsg(f)) {
      PjPtr crs(proj_create(ctx, fmt::format("EPSG:{}", code).c_str()));
      if (crs.p && proj_get_type(crs.p) == PJ_TYPE_PROJECTED_CRS) crs = PjPtr(proj_crs_get_geodetic_crs(ctx, crs.p));
      if (crs.p && is_geographic(proj_get_type(crs.p))) {
        PjPtr ell(proj_get_ellipsoid(ctx, crs.p));
        double a = 0, b = 0, rf = 0;
        int computed = 0;
        if (ell.p && proj_ellipsoid_get_parameters(ctx, ell.p, &a, &b, &computed, &rf) &&
            std::fabs(a - f.semi_major_m) < 1e-3 && std::fabs(rf - f.inverse_flattening) < 1e-6) {
          what = fmt::format("{} (datum of EPSG:{})", proj_get_name(crs.p), code);
          return crs;
        }
      }
    }
    what = fmt::format("no named datum: longitude/latitude on the frame's ellipsoid (a={:.3f}, rf={:.9g})",
                       f.semi_major_m, f.inverse_flattening);
    PjPtr cs(proj_create_ellipsoidal_2D_cs(ctx, PJ_ELLPS2D_LONGITUDE_LATITUDE, "degree", kDegree));
    return PjPtr(proj_create_geographic_crs(ctx, "frame ellipsoid", "unknown", "frame ellipsoid", f.semi_major_m,
                                            f.inverse_flattening, "Greenwich", 0.0, "degree", kDegree, cs.p));
  }
};

LonLatToFrame::LonLatToFrame() : impl_(std::make_unique<Impl>()) {}
LonLatToFrame::~LonLatToFrame() = default;
LonLatToFrame::LonLatToFrame(LonLatToFrame&&) noexcept = default;
LonLatToFrame& LonLatToFrame::operator=(LonLatToFrame&&) noexcept = default;

Status LonLatToFrame::init(const FrameCrs& frame, const std::string& lonlat_crs) {
  if (frame.kind != ProjectionKind::transverse_mercator && frame.kind != ProjectionKind::proj)
    return Status::failure(Error::invalid_argument,
                           "this archive's frame is 'local' (no geodetic meaning): give frame metres with --sample/--sample-file "
                           "instead of longitude/latitude");
  Impl& m = *impl_;
  if (!m.ctx) return Status::failure(Error::internal, "PROJ: cannot create a context");
  const std::string from_name = lonlat_crs.empty() ? kDefaultLonLatCrs : lonlat_crs;
  PjPtr from(proj_create(m.ctx, from_name.c_str()));
  if (!from.p)
    return Status::failure(Error::invalid_argument,
                           fmt::format("--lonlat-crs {}: not a CRS PROJ knows (e.g. EPSG:4326, EPSG:4267, EPSG:4258)", from_name));
  if (!is_geographic(proj_get_type(from.p)))
    return Status::failure(Error::invalid_argument,
                           fmt::format("--lonlat-crs {}: {} is not a geographic (longitude/latitude) CRS", from_name,
                                       proj_get_name(from.p)));
  std::string datum;
  if (frame.kind == ProjectionKind::proj) {  // format v2: the WKT2 defines the frame, datum included
    PjPtr to(proj_create(m.ctx, frame.definition.c_str()));
    if (!to.p || proj_get_type(to.p) != PJ_TYPE_PROJECTED_CRS)
      return Status::failure(Error::invalid_argument, "PROJ cannot read the archive's frame definition (WKT2)");
    PjPtr op(proj_create_crs_to_crs_from_pj(m.ctx, from.p, to.p, nullptr, nullptr));
    if (op.p) op = PjPtr(proj_normalize_for_visualization(m.ctx, op.p));
    if (!op.p)
      return Status::failure(Error::invalid_argument,
                             fmt::format("PROJ finds no conversion from {} to the archive's frame ({})", from_name,
                                         proj_get_name(to.p)));
    m.op = std::move(op);
    m.description = fmt::format("{} ({}) -> frame {} (WKT2 of the archive)", from_name, proj_get_name(from.p),
                                proj_get_name(to.p));
    return Status::success();
  }
  PjPtr base = m.frame_geodetic(frame, datum);
  // The archive's own parameters define the frame (format/SPEC.md 6.2); the EPSG code only names its datum.
  PjPtr conv(proj_create_conversion_transverse_mercator(m.ctx, frame.lat0_deg, frame.lon0_deg, frame.scale_k0,
                                                        frame.false_easting_m, frame.false_northing_m, "degree",
                                                        kDegree, "metre", 1.0));
  PjPtr cs(proj_create_cartesian_2D_cs(m.ctx, PJ_CART2D_EASTING_NORTHING, "metre", 1.0));
  PjPtr to(base.p && conv.p && cs.p ? proj_create_projected_crs(m.ctx, "archive frame", base.p, conv.p, cs.p) : nullptr);
  PjPtr op(to.p ? proj_create_crs_to_crs_from_pj(m.ctx, from.p, to.p, nullptr, nullptr) : nullptr);
  if (op.p) op = PjPtr(proj_normalize_for_visualization(m.ctx, op.p));  // lon, lat in; easting, northing out
  if (!op.p)
    return Status::failure(Error::invalid_argument,
                           fmt::format("PROJ finds no conversion from {} to the archive's frame ({})", from_name, datum));
  m.op = std::move(op);
  m.description = fmt::format("{} ({}) -> frame on {}", from_name, proj_get_name(from.p), datum);
  return Status::success();
}

Status LonLatToFrame::convert(double lon_deg, double lat_deg, double& x, double& y) const {
  if (!(std::fabs(lat_deg) <= 90) || !std::isfinite(lon_deg))
    return Status::failure(Error::invalid_argument, fmt::format("latitude {} / longitude {} out of range", lat_deg, lon_deg));
  if (!impl_->op.p) return Status::failure(Error::internal, "LonLatToFrame::convert before init");
  proj_errno_reset(impl_->op.p);
  const PJ_COORD out = proj_trans(impl_->op.p, PJ_FWD, proj_coord(lon_deg, lat_deg, 0, 0));
  if (!std::isfinite(out.xy.x) || !std::isfinite(out.xy.y) || out.xy.x == HUGE_VAL)
    return Status::failure(Error::invalid_argument,
                           fmt::format("longitude {} / latitude {}: PROJ cannot convert it ({})", lon_deg, lat_deg,
                                       proj_context_errno_string(impl_->ctx, proj_errno(impl_->op.p))));
  x = out.xy.x;
  y = out.xy.y;
  return Status::success();
}

const std::string& LonLatToFrame::description() const { return impl_->description; }

}  // namespace terrain::inspect
