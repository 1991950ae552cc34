// Longitude/latitude on a named geodetic CRS (WGS 84 unless told otherwise: what GPS receivers and
// web maps give) to an archive's frame metres, through PROJ (datum shift included). PROJ stays
// inside inspect_lonlat.cpp.
#pragma once
#include <memory>
#include <string>

#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::inspect {

// The geographic CRS longitude/latitude are read on when no --lonlat-crs is given.
inline constexpr const char* kDefaultLonLatCrs = "EPSG:4326";

class LonLatToFrame {
 public:
  LonLatToFrame();
  ~LonLatToFrame();
  LonLatToFrame(LonLatToFrame&&) noexcept;
  LonLatToFrame& operator=(LonLatToFrame&&) noexcept;

  // Prepares lon/lat on `lonlat_crs` ("EPSG:4267", any geographic CRS PROJ knows; empty = WGS 84)
  // -> `frame`. The frame's datum is its EPSG code's, else the "EPSG:n" its name cites (the
  // cooker names the geographic CRS of the input there), else unknown: then lon/lat are taken on
  // the frame's own ellipsoid with no datum shift. invalid_argument for a local frame, a CRS PROJ
  // does not know or one that is not geographic. A proj frame (format v2) is the CRS of its WKT2
  // definition, datum included.
  Status init(const FrameCrs& frame, const std::string& lonlat_crs);
  Status convert(double lon_deg, double lat_deg, double& x, double& y) const;
  // "EPSG:4326 -> NAD27 (EPSG:4267) datum of the frame", for messages.
  const std::string& description() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terrain::inspect
