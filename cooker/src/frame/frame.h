// The archive's frame (a metric Transverse Mercator, any projected CRS PROJ knows, or a local
// plane) and the mapping between frame metres and source sample coordinates.
//
// Frame choice: geographic input -> Transverse Mercator on the input's ellipsoid, central meridian
// at the data's centre longitude (rounded to a whole arc-second), lat0 0, k0 1, no false
// easting/northing. UTM and any other TM input keep their CRS as the frame (so separately cooked
// neighbouring areas share one). Any other projected input (Lambert-93, RD, LV95, Albers, State
// Plane, ...) keeps its CRS as the frame (kind proj, format v2) when its axes are metres east/north
// and its scale error over the data stays within kMaxFrameScaleError; otherwise (Web Mercator away
// from the equator, feet) it gets the centred Transverse Mercator of geographic input. Local input
// keeps a local frame. --frame overrides (TM, any projected CRS, or local); a geographic or
// geocentric --frame has no metric meaning and is refused.
// Geographic longitudes are taken within half a turn of the raster's centre, so a raster crossing
// the antimeridian (179.9 .. 180.1 or -180.1 .. -179.9) maps whole; lon0 is kept in [-180, 180].
// Geographic data reaching beyond 89 N/S are refused (frame.cpp: longitude's pole singularity
// breaks the interpolated mapping), with a gdalwarp line to a Transverse Mercator raster.
#pragma once
#include <memory>
#include <string>

#include "frame/anchor_grid.h"
#include "inputs/raster.h"
#include "base/sample_window.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

// The largest |scale - 1| (Tissot's semi-axes over the data) for which a projected input's own
// CRS is kept as the frame: 0.5 %, so a frame metre is a ground metre within 5 mm per metre.
inline constexpr double kMaxFrameScaleError = 0.005;

// `data`: the valid samples' bounds when `source` is a header without values (the block-wise cook
// knows them from its first pass); null: found in source.values.
Status choose_frame(const Raster& source, const std::string& frame_spec, FrameCrs& out, std::string& reason,
                    const SampleRect* data = nullptr);

// Latitude/longitude on a CRS's own ellipsoid <-> its projected metres.
class Projection {
 public:
  virtual ~Projection() = default;
  virtual void forward(double lat, double lon, double& x, double& y) const = 0;
  virtual void reverse(double x, double y, double& lat, double& lon) const = 0;
};

// Transverse Mercator of a FrameCrs (GeographicLib TransverseMercatorExact), with lat0, false
// easting and false northing applied: y = FN + k0 (M(lat) - M(lat0)) on the central meridian.
class TmProjection final : public Projection {
 public:
  explicit TmProjection(const FrameCrs& crs);
  ~TmProjection() override;
  TmProjection(TmProjection&&) noexcept;
  TmProjection& operator=(TmProjection&&) noexcept;
  void forward(double lat, double lon, double& x, double& y) const override;
  void reverse(double x, double y, double& lat, double& lon) const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Any projected CRS through PROJ (the conversion from its base geographic CRS only: no datum
// shift), x east and y north in metres (CRS units times unit_m()). Calls are serialised (a PJ is
// not thread-safe); PROJ answers the same bits for the same input, so mappings stay deterministic.
class ProjProjection final : public Projection {
 public:
  static Status create(const std::string& definition, std::shared_ptr<const ProjProjection>& out);
  ~ProjProjection() override;
  void forward(double lat, double lon, double& x, double& y) const override;
  void reverse(double x, double y, double& lat, double& lon) const override;
  // Largest |scale - 1| over the points (Tissot semi-axes, meridional and parallel scale).
  double max_scale_error(const double* lat, const double* lon, int n) const;
  // True when the CRS's axes are easting and northing (either order) in metres.
  bool metric_east_north() const;
  double unit_m() const;

 private:
  ProjProjection();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

class SourceMapping {
 public:
  // Prepares the exact transforms and the sample -> frame anchors.
  Status init(const Raster& source, const FrameCrs& frame, int threads);
  // Builds the frame -> sample anchors over a frame rectangle (the node grid plus margins).
  void cover_frame_area(double x0, double y0, double x1, double y1, int threads);

  void frame_to_sample(double x, double y, double& col, double& row) const;
  void sample_to_frame(double col, double row, double& x, double& y) const;
  // The canonical batch forms. Every node vertex goes through map_frame_row, so a vertex shared by
  // several nodes maps to the same bits in each (the single-point forms may differ in the last bit).
  void map_frame_row(double y, const double* x, int n, double* col, double* row) const;
  // Frame positions of source samples (c, row) for c = c0 .. c0 + n - 1.
  void map_sample_row(int row, int c0, int n, double* x, double* y) const;
  // The exact chain (GeographicLib per call): for footprints, spacing and tests.
  void exact_frame_to_sample(double x, double y, double& col, double& row) const;
  void exact_sample_to_frame(double col, double row, double& x, double& y) const;

  // True when frame and source coordinates differ by an affine map only (no anchors involved).
  bool affine() const { return affine_; }
  // The frame -> sample anchors behind map_frame_row when not affine (null when affine): callers
  // mapping many rows of the same x plan the row once (AnchorGrid::plan_row), same bits.
  const AnchorGrid* frame_to_sample_anchors() const { return affine_ ? nullptr : &to_sample_; }
  // Affine without rotation: a vertex's sample column depends on its frame x only and its sample
  // row on y only (exactly: the cross terms are zero), so rows and columns of vertices share them.
  bool axis_aligned() const { return affine_ && affine_map_.inv[2] == 0.0 && affine_map_.inv[4] == 0.0; }
  // Axis-aligned only: the frame position of sample (0, 0) and the frame steps from one sample to
  // the next along a row and a column (signed: rows usually run south).
  void sample_grid(double& x00, double& y00, double& step_x, double& step_y) const {
    x00 = affine_map_.c[0];
    y00 = affine_map_.c[3];
    step_x = affine_map_.c[1];
    step_y = affine_map_.c[5];
  }
  // Frame bounding box of the sample rectangle [c0 - m, c1 + m] x [r0 - m, r1 + m].
  void frame_bounds(int c0, int r0, int c1, int r1, double m, double& x0, double& y0, double& x1, double& y1) const;
  // Source sample spacing in frame metres at the raster centre (x, y).
  void spacing_m(double& sx, double& sy) const;

 private:
  AffineMap affine_map_{};
  bool affine_ = true;
  int width_ = 0, height_ = 0;
  // projected: source projection reversed to lat/lon, then the frame's forward (TM through
  // GeographicLib, other projected CRSs through PROJ).
  enum class Chain { affine, geographic, projected } chain_ = Chain::affine;
  double lon_centre_ = 0;  // geographic: the raster centre's longitude (model units)
  std::shared_ptr<const Projection> frame_tm_, source_tm_;
  AnchorGrid to_frame_, to_sample_;
};

}  // namespace terrain::cook
