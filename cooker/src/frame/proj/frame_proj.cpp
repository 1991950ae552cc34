// ProjProjection (frame.h): any projected CRS through PROJ.
#include <proj.h>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <mutex>

#include "frame/frame.h"

namespace terrain::cook {

struct ProjProjection::Impl {
  PJ_CONTEXT* ctx = nullptr;
  PJ* crs = nullptr;
  PJ* op = nullptr;  // base geographic (lon, lat degrees) -> (east, north) CRS units
  double unit = 1.0;
  bool east_north = false;
  mutable std::mutex mutex;
  ~Impl() {
    proj_destroy(op);
    proj_destroy(crs);
    if (ctx) proj_context_destroy(ctx);
  }
};

ProjProjection::ProjProjection() : impl_(std::make_unique<Impl>()) {}
ProjProjection::~ProjProjection() = default;

Status ProjProjection::create(const std::string& definition, std::shared_ptr<const ProjProjection>& out) {
  std::shared_ptr<ProjProjection> p(new ProjProjection());
  Impl& m = *p->impl_;
  m.ctx = proj_context_create();
  if (!m.ctx) return Status::failure(Error::internal, "PROJ: cannot create a context");
  proj_log_func(m.ctx, nullptr, [](void*, int, const char*) {});
  m.crs = proj_create(m.ctx, definition.c_str());
  if (!m.crs || proj_get_type(m.crs) != PJ_TYPE_PROJECTED_CRS)
    return Status::failure(Error::unsupported_input,
                           fmt::format("PROJ cannot resolve '{}' as a projected CRS", definition.substr(0, 200)));
  PJ* base = proj_crs_get_geodetic_crs(m.ctx, m.crs);
  PJ* op = base ? proj_create_crs_to_crs_from_pj(m.ctx, base, m.crs, nullptr, nullptr) : nullptr;
  if (op) m.op = proj_normalize_for_visualization(m.ctx, op);  // lon, lat in; easting, northing out
  proj_destroy(op);
  proj_destroy(base);
  if (!m.op) return Status::failure(Error::unsupported_input, "PROJ finds no projection for " + definition.substr(0, 200));
  PJ* cs = proj_crs_get_coordinate_system(m.ctx, m.crs);
  bool east = false, north = false, metres = cs != nullptr;
  for (int i = 0; cs && i < proj_cs_get_axis_count(m.ctx, cs); ++i) {
    const char* dir = nullptr;
    double factor = 0;
    proj_cs_get_axis_info(m.ctx, cs, i, nullptr, nullptr, &dir, &factor, nullptr, nullptr, nullptr);
    const std::string d = dir ? dir : "";
    east = east || d == "east";
    north = north || d == "north";
    if (i == 0) m.unit = factor > 0 ? factor : 1.0;
    metres = metres && factor == 1.0;
  }
  proj_destroy(cs);
  m.east_north = east && north && metres;
  out = p;
  return Status::success();
}

void ProjProjection::forward(double lat, double lon, double& x, double& y) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const PJ_COORD c = proj_trans(impl_->op, PJ_FWD, proj_coord(lon, lat, 0, 0));
  const bool ok = c.xy.x != HUGE_VAL && std::isfinite(c.xy.x);
  x = ok ? c.xy.x * impl_->unit : NAN;
  y = ok ? c.xy.y * impl_->unit : NAN;
}

void ProjProjection::reverse(double x, double y, double& lat, double& lon) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const PJ_COORD c = proj_trans(impl_->op, PJ_INV, proj_coord(x / impl_->unit, y / impl_->unit, 0, 0));
  const bool ok = c.lp.lam != HUGE_VAL && std::isfinite(c.lp.lam);
  lon = ok ? c.lp.lam : NAN;
  lat = ok ? c.lp.phi : NAN;
}

double ProjProjection::max_scale_error(const double* lat, const double* lon, int n) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  constexpr double kDeg = 0.017453292519943295;
  double worst = 0;
  for (int i = 0; i < n; ++i) {
    const PJ_FACTORS f = proj_factors(impl_->crs, proj_coord(lon[i] * kDeg, lat[i] * kDeg, 0, 0));
    for (double k : {f.meridional_scale, f.parallel_scale, f.tissot_semimajor, f.tissot_semiminor})
      worst = std::isfinite(k) && k > 0 ? std::max(worst, std::fabs(k - 1)) : INFINITY;
  }
  return worst;
}

bool ProjProjection::metric_east_north() const { return impl_->east_north; }
double ProjProjection::unit_m() const { return impl_->unit; }

}  // namespace terrain::cook
