#include "frame/frame.h"

#include <GeographicLib/TransverseMercatorExact.hpp>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "frame/crs.h"

namespace terrain::cook {
namespace {

constexpr double kFrameAnchorStepM = 512.0;  // frame -> sample anchors
constexpr int kSampleAnchorStep = 16;         // sample -> frame anchors, in samples

// Sample bounds of the raster's valid data (`data` when the caller knows them: a header without
// values), or the whole raster when it holds none.
void data_or_raster_bounds(const Raster& r, const SampleRect* data, int& c0, int& r0, int& c1, int& r1) {
  uint64_t valid = 0;
  if (data && !data->empty()) {
    c0 = data->c0;
    r0 = data->r0;
    c1 = data->c1;
    r1 = data->r1;
    return;
  }
  if (!data && valid_bounds(r, c0, r0, c1, r1, valid)) return;
  c0 = r0 = 0;
  c1 = r.width - 1;
  r1 = r.height - 1;
}

// Data centre longitude/latitude of a geographic raster (the middle of its valid samples).
void data_centre(const Raster& r, const SampleRect* data, double& lon, double& lat) {
  int c0 = 0, r0 = 0, c1 = 0, r1 = 0;
  data_or_raster_bounds(r, data, c0, r0, c1, r1);
  AffineMap::from(r.geo).to_model(0.5 * (c0 + c1), 0.5 * (r0 + r1), lon, lat);
}

// Longitude is singular at the poles: near one, the frame -> sample map (interpolated between
// anchors kFrameAnchorStepM apart) bends faster than its Catmull-Rom interpolation follows. Its
// error in ground metres falls with the distance d to the pole roughly as step^3 / d^2; measured
// against the exact chain (tests/cooker/test_geodesy.cpp) it stays below 1 mm up to this latitude.
constexpr double kMaxGeographicLatDeg = 89.0;

// Refuses geographic input whose footprint (sample centres +- half a sample) reaches beyond
// kMaxGeographicLatDeg, naming the way round: a Transverse Mercator raster is mapped exactly.
Status check_polar_reach(const Raster& r) {
  const AffineMap map = AffineMap::from(r.geo);
  double reach = 0, lon = 0, lat = 0, lon_c = 0, lat_c = 0;
  for (double c : {-0.5, r.width - 0.5})
    for (double row : {-0.5, r.height - 0.5}) {
      map.to_model(c, row, lon, lat);
      if (std::fabs(lat) > std::fabs(reach)) reach = lat;
    }
  if (std::fabs(reach) <= kMaxGeographicLatDeg) return Status::success();
  map.to_model(0.5 * (r.width - 1), 0.5 * (r.height - 1), lon_c, lat_c);
  return Status::failure(
      Error::unsupported_input,
      fmt::format("{}: the data reach latitude {:.4f}, closer to the {} pole than {} degrees; geographic input is "
                  "mapped to the frame within 1 mm only up to {} N/S (longitude is singular at a pole). Reproject it to "
                  "a Transverse Mercator first and cook that: gdalwarp -t_srs \"+proj=tmerc +lat_0=0 +lon_0={:.4f} +k=1 "
                  "+x_0=0 +y_0=0 +a={:.3f} +rf={:.9f} +units=m\" -r cubic -dstnodata -32768 {} polar_tm.tif (a polar stereographic "
                  "frame such as EPSG:{} is not one this archive format has)",
                  r.path, reach, reach > 0 ? "north" : "south", 90.0 - kMaxGeographicLatDeg, kMaxGeographicLatDeg,
                  std::remainder(lon_c, 360.0), r.crs.tm.semi_major_m, r.crs.tm.inverse_flattening, r.path,
                  reach > 0 ? 3413 : 3031));
}

// A frame from a projection: TM through GeographicLib (exact, as in format v1), other projected
// CRSs through PROJ.
Status make_projection(const FrameCrs& crs, std::shared_ptr<const Projection>& out) {
  if (crs.kind == ProjectionKind::transverse_mercator) {
    out = std::make_shared<TmProjection>(crs);
    return Status::success();
  }
  std::shared_ptr<const ProjProjection> p;
  TERRAIN_TRY(ProjProjection::create(crs.definition, p));
  out = p;
  return Status::success();
}

// Transverse Mercator centred on the data (lon0 the centre longitude rounded to an arc-second).
FrameCrs centred_tm(const SourceCrs& src, double lon, double lat, std::string& reason, const std::string& why) {
  FrameCrs out;
  out.kind = ProjectionKind::transverse_mercator;
  out.semi_major_m = src.tm.semi_major_m;
  out.inverse_flattening = src.tm.inverse_flattening;
  // In [-180, 180] (format/SPEC.md 6.2) also for data east of the antimeridian (lon > 180).
  out.lon0_deg = std::remainder(std::round(lon * 3600.0) / 3600.0, 360.0);
  out.lat0_deg = 0;
  out.scale_k0 = 1.0;
  out.name = fmt::format("Transverse Mercator centred on the data (lon0 {:.6f}, {})", out.lon0_deg, src.name);
  reason = fmt::format("{} projected to a Transverse Mercator whose central meridian is the data's "
                       "centre longitude ({:.6f}, centre latitude {:.6f})", why, out.lon0_deg, lat);
  return out;
}

// Keeps a projected input's own CRS as the frame when it is metric east/north and its scale error
// over the data (a 9 x 9 grid of the valid samples' footprint) is within kMaxFrameScaleError;
// else the centred Transverse Mercator.
Status frame_for_projected(const Raster& r, const SampleRect* data, FrameCrs& out, std::string& reason) {
  const SourceCrs& src = r.crs;
  std::shared_ptr<const ProjProjection> proj;
  TERRAIN_TRY(ProjProjection::create(src.tm.definition, proj));
  int c0 = 0, r0 = 0, c1 = 0, r1 = 0;
  data_or_raster_bounds(r, data, c0, r0, c1, r1);
  const AffineMap map = AffineMap::from(r.geo);
  constexpr int kGrid = 9;
  std::vector<double> lat, lon;
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) {
      double x = 0, y = 0, la = 0, lo = 0;
      map.to_model(c0 - 0.5 + (c1 - c0 + 1.0) * i / (kGrid - 1), r0 - 0.5 + (r1 - r0 + 1.0) * j / (kGrid - 1), x, y);
      proj->reverse(x, y, la, lo);
      if (!std::isfinite(la) || !std::isfinite(lo))
        return Status::failure(Error::unsupported_input,
                               fmt::format("{}: PROJ cannot take ({:.3f}, {:.3f}) of {} back to latitude/longitude",
                                           r.path, x, y, describe_crs(src)));
      lat.push_back(la);
      lon.push_back(lo);
    }
  const double err = proj->max_scale_error(lat.data(), lon.data(), int(lat.size()));
  if (proj->metric_east_north() && err <= kMaxFrameScaleError) {
    out = src.tm;
    reason = fmt::format("the input's own projected CRS is kept (scale error at most {:.3f} % over the data, bound {:.1f} %)",
                         100 * err, 100 * kMaxFrameScaleError);
    return Status::success();
  }
  const std::string why =
      !proj->metric_east_north()
          ? fmt::format("input in {} (axes not metres east/north)", src.name)
          : fmt::format("input in {} (scale error {:.3f} % over the data, above the {:.1f} % bound)", src.name, 100 * err,
                        100 * kMaxFrameScaleError);
  out = centred_tm(src, lon[kGrid * kGrid / 2], lat[kGrid * kGrid / 2], reason, why);
  return Status::success();
}

}  // namespace

Status choose_frame(const Raster& source, const std::string& frame_spec, FrameCrs& out, std::string& reason,
                    const SampleRect* data) {
  const SourceCrs& src = source.crs;
  if (!frame_spec.empty()) {
    SourceCrs f;
    TERRAIN_TRY(parse_crs_spec(frame_spec, f));
    if (f.kind == CrsKind::local) {
      if (src.kind != CrsKind::local)
        return Status::failure(Error::invalid_argument,
                               fmt::format("--frame local: the input is in {}, a geodetic CRS; a local frame only takes "
                                           "local input", describe_crs(src)));
    } else if (f.kind == CrsKind::transverse_mercator || f.kind == CrsKind::projected) {
      if (f.kind == CrsKind::projected) {
        std::shared_ptr<const ProjProjection> p;
        TERRAIN_TRY(ProjProjection::create(f.tm.definition, p));
        if (!p->metric_east_north())
          return Status::failure(Error::invalid_argument,
                                 fmt::format("--frame {}: {} does not have metre easting/northing axes; a frame is "
                                             "metric", frame_spec, describe_crs(f)));
      }
      if (src.kind == CrsKind::local)
        return Status::failure(Error::invalid_argument,
                               "--frame: the input has local coordinates (no geodetic meaning) and cannot be projected; "
                               "give its CRS with --crs");
      if (!same_ellipsoid(f.tm, src.tm))
        return Status::failure(Error::invalid_argument,
                               fmt::format("--frame {} is on another ellipsoid than the input ({}); datum shifts are not "
                                           "done here: reproject with gdalwarp -t_srs instead", frame_spec, describe_crs(src)));
    } else {
      return Status::failure(Error::invalid_argument,
                             fmt::format("--frame {}: {} is not a projected CRS or local: a geographic or geocentric "
                                         "frame has no metric meaning", frame_spec, describe_crs(f)));
    }
    out = f.tm;
    out.epsg = f.kind == CrsKind::transverse_mercator || f.kind == CrsKind::projected ? f.epsg : 0;
    out.name = f.name;
    reason = "given by --frame";
    return Status::success();
  }
  switch (src.kind) {
    case CrsKind::local:
      out = FrameCrs{};
      out.kind = ProjectionKind::local;
      out.name = src.name.empty() ? "local" : src.name;
      reason = "the input has local coordinates";
      return Status::success();
    case CrsKind::transverse_mercator:
      out = src.tm;
      out.epsg = src.epsg;
      out.name = src.name;
      reason = "the input's own Transverse Mercator CRS is kept";
      return Status::success();
    case CrsKind::geographic: {
      double lon = 0, lat = 0;
      data_centre(source, data, lon, lat);
      out = centred_tm(src, lon, lat, reason, "geographic input");
      return Status::success();
    }
    case CrsKind::projected: return frame_for_projected(source, data, out, reason);
    default:
      return Status::failure(Error::unsupported_input, fmt::format("no frame for an input in {}", describe_crs(src)));
  }
}

struct TmProjection::Impl {
  GeographicLib::TransverseMercatorExact tm;
  double lon0, fe, fn, y_lat0;
  explicit Impl(const FrameCrs& c)
      : tm(c.semi_major_m, 1.0 / c.inverse_flattening, c.scale_k0),
        lon0(c.lon0_deg),
        fe(c.false_easting_m),
        fn(c.false_northing_m),
        y_lat0(0) {
    double x = 0;
    tm.Forward(lon0, c.lat0_deg, lon0, x, y_lat0);
  }
};

TmProjection::TmProjection(const FrameCrs& crs) : impl_(std::make_unique<Impl>(crs)) {}
TmProjection::~TmProjection() = default;
TmProjection::TmProjection(TmProjection&&) noexcept = default;
TmProjection& TmProjection::operator=(TmProjection&&) noexcept = default;

void TmProjection::forward(double lat, double lon, double& x, double& y) const {
  impl_->tm.Forward(impl_->lon0, lat, lon, x, y);
  x += impl_->fe;
  y += impl_->fn - impl_->y_lat0;
}

void TmProjection::reverse(double x, double y, double& lat, double& lon) const {
  impl_->tm.Reverse(impl_->lon0, x - impl_->fe, y - impl_->fn + impl_->y_lat0, lat, lon);
}

Status SourceMapping::init(const Raster& source, const FrameCrs& frame, int threads) {
  affine_map_ = AffineMap::from(source.geo);
  width_ = source.width;
  height_ = source.height;
  const SourceCrs& src = source.crs;
  if (frame.kind == ProjectionKind::local || src.kind == CrsKind::local) {
    chain_ = Chain::affine;
  } else if (src.kind == CrsKind::transverse_mercator || src.kind == CrsKind::projected) {
    SourceCrs frame_as_source;
    frame_as_source.kind = frame.kind == ProjectionKind::proj ? CrsKind::projected : CrsKind::transverse_mercator;
    frame_as_source.tm = frame;
    chain_ = same_crs(src, frame_as_source) ? Chain::affine : Chain::projected;
  } else if (src.kind == CrsKind::geographic) {
    chain_ = Chain::geographic;
    double lat = 0;
    affine_map_.to_model(0.5 * (width_ - 1), 0.5 * (height_ - 1), lon_centre_, lat);
    TERRAIN_TRY(check_polar_reach(source));
  } else {
    return Status::failure(Error::unsupported_input, fmt::format("cannot map {} to the frame", describe_crs(src)));
  }
  affine_ = chain_ == Chain::affine;
  if (affine_) return Status::success();
  TERRAIN_TRY(make_projection(frame, frame_tm_));
  if (chain_ == Chain::projected)
    TERRAIN_TRY(make_projection(src.tm, source_tm_));
  const int margin = 4;
  const int nx = (width_ + 2 * margin) / kSampleAnchorStep + 5;
  const int ny = (height_ + 2 * margin) / kSampleAnchorStep + 5;
  to_frame_.build(-margin - kSampleAnchorStep, -margin - kSampleAnchorStep, kSampleAnchorStep, nx, ny,
                  [this](double c, double r, double& x, double& y) { exact_sample_to_frame(c, r, x, y); }, threads);
  return Status::success();
}

void SourceMapping::cover_frame_area(double x0, double y0, double x1, double y1, int threads) {
  if (affine_) return;
  const double step = kFrameAnchorStepM;
  const double ax = std::floor(x0 / step) * step - 2 * step, ay = std::floor(y0 / step) * step - 2 * step;
  const int nx = int(std::ceil((x1 - ax) / step)) + 3, ny = int(std::ceil((y1 - ay) / step)) + 3;
  to_sample_.build(ax, ay, step, nx, ny,
                   [this](double x, double y, double& c, double& r) { exact_frame_to_sample(x, y, c, r); }, threads);
}

void SourceMapping::exact_sample_to_frame(double col, double row, double& x, double& y) const {
  double mx = 0, my = 0;
  affine_map_.to_model(col, row, mx, my);
  switch (chain_) {
    case Chain::affine: x = mx; y = my; return;
    case Chain::geographic: frame_tm_->forward(my, mx, x, y); return;
    case Chain::projected: {
      double lat = 0, lon = 0;
      source_tm_->reverse(mx, my, lat, lon);
      frame_tm_->forward(lat, lon, x, y);
      return;
    }
  }
}

void SourceMapping::exact_frame_to_sample(double x, double y, double& col, double& row) const {
  double mx = x, my = y;
  switch (chain_) {
    case Chain::affine: break;
    case Chain::geographic:
      frame_tm_->reverse(x, y, my, mx);
      // The projection answers in [-180, 180]; a raster crossing the antimeridian has columns
      // beyond it (lon 179.9 .. 180.1, or -180.1 .. -179.9), so take the longitude within half a
      // turn of the raster's centre.
      mx = lon_centre_ + std::remainder(mx - lon_centre_, 360.0);
      break;
    case Chain::projected: {
      double lat = 0, lon = 0;
      frame_tm_->reverse(x, y, lat, lon);
      source_tm_->forward(lat, lon, mx, my);
      break;
    }
  }
  affine_map_.to_sample(mx, my, col, row);
}

void SourceMapping::frame_to_sample(double x, double y, double& col, double& row) const {
  if (affine_) {
    affine_map_.to_sample(x, y, col, row);
    return;
  }
  to_sample_.eval(x, y, col, row);
}

void SourceMapping::sample_to_frame(double col, double row, double& x, double& y) const {
  if (affine_) {
    affine_map_.to_model(col, row, x, y);
    return;
  }
  to_frame_.eval(col, row, x, y);
}

void SourceMapping::map_frame_row(double y, const double* x, int n, double* col, double* row) const {
  if (affine_) {
    for (int k = 0; k < n; ++k) affine_map_.to_sample(x[k], y, col[k], row[k]);
    return;
  }
  to_sample_.eval_row(y, x, n, col, row);
}

void SourceMapping::map_sample_row(int row, int c0, int n, double* x, double* y) const {
  if (affine_) {
    for (int k = 0; k < n; ++k) affine_map_.to_model(double(c0 + k), double(row), x[k], y[k]);
    return;
  }
  thread_local std::vector<double> cols;
  cols.resize(size_t(std::max(n, 0)));
  for (int k = 0; k < n; ++k) cols[size_t(k)] = double(c0 + k);
  to_frame_.eval_row(double(row), cols.data(), n, x, y);
}

void SourceMapping::frame_bounds(int c0, int r0, int c1, int r1, double m, double& x0, double& y0, double& x1,
                                 double& y1) const {
  x0 = y0 = INFINITY;
  x1 = y1 = -INFINITY;
  const int n = 64;
  auto add = [&](double c, double r) {
    double x = 0, y = 0;
    exact_sample_to_frame(c, r, x, y);
    x0 = std::min(x0, x);
    y0 = std::min(y0, y);
    x1 = std::max(x1, x);
    y1 = std::max(y1, y);
  };
  const double ca = c0 - m, cb = c1 + m, ra = r0 - m, rb = r1 + m;
  for (int i = 0; i <= n; ++i) {
    const double t = double(i) / n;
    add(ca + t * (cb - ca), ra);
    add(ca + t * (cb - ca), rb);
    add(ca, ra + t * (rb - ra));
    add(cb, ra + t * (rb - ra));
  }
}

void SourceMapping::spacing_m(double& sx, double& sy) const {
  const double c = 0.5 * (width_ - 1), r = 0.5 * (height_ - 1);
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0, x2 = 0, y2 = 0;
  exact_sample_to_frame(c, r, x0, y0);
  exact_sample_to_frame(c + 1, r, x1, y1);
  exact_sample_to_frame(c, r + 1, x2, y2);
  sx = std::hypot(x1 - x0, y1 - y0);
  sy = std::hypot(x2 - x0, y2 - y0);
}

}  // namespace terrain::cook
