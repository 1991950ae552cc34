// What reads inputs, resolves CRSs and projects (GDAL, PROJ, libgeotiff: input_gdal.cpp,
// vrt_tiles.cpp, web_tile_source.cpp, crs_resolve.cpp, frame_proj.cpp, overlays.cpp) for
// terrain-cook-merge, which does none of it: mapping those libraries cost each merge ~0.09 s of
// CPU before main (terrain_cook_dispatch.cpp). Nothing here is reached; if it were, the error says
// so instead of reading nothing.
#include <cmath>
#include <fmt/format.h>

#include "frame/crs.h"
#include "frame/frame.h"
#include "overlays/overlays.h"
#include "inputs/source_raster.h"
#include "inputs/web_tiles.h"

namespace terrain::cook {
namespace {

Status absent(const std::string& what) {
  return Status::failure(Error::internal,
                         fmt::format("{}: terrain-cook-merge reads no input and projects nothing; run terrain-cook", what));
}

}  // namespace

Status open_gdal_source(const std::string& path, const ReadOptions&, std::unique_ptr<SourceRaster>&) {
  return absent(path);
}
Status open_web_tile(const std::string& path, const TileAddress&, TileEncoding, std::unique_ptr<SourceRaster>&) {
  return absent(path);
}
Status open_encoded_image(const std::string& path, TileEncoding, const SampleGeo&, const SourceCrs&,
                          std::unique_ptr<SourceRaster>&) {
  return absent(path);
}
Status check_vrt_tiles(const std::string& path) { return absent(path); }
Status write_vrt_windows(const std::string& path, const std::vector<std::array<int, 4>>&, const std::vector<std::string>&,
                         bool&) {
  return absent(path);
}
void init_gdal() {}
void set_gdal_cache_bytes(uint64_t) {}
void set_gdal_decode_threads(int) {}
uint64_t gdal_cache_used_bytes() { return 0; }
SourceCrs gdal_crs_of_epsg(int) { return SourceCrs{}; }
std::vector<FilePlacement> gdal_file_placements(const std::string& path) {
  FilePlacement f;
  f.path = path;
  return {f};
}
CrsTransformStatus gdal_point_transforms(const SourceCrs&, const SourceCrs&, PointTransform&, PointTransform&) {
  return CrsTransformStatus::no_transformation;
}

Status parse_crs_spec(const std::string& spec, SourceCrs&) { return absent(spec); }

Status ProjProjection::create(const std::string& definition, std::shared_ptr<const ProjProjection>&) {
  return absent(definition);
}
struct ProjProjection::Impl {};
ProjProjection::ProjProjection() = default;
ProjProjection::~ProjProjection() = default;
void ProjProjection::forward(double, double, double& x, double& y) const { x = y = NAN; }
void ProjProjection::reverse(double, double, double& lat, double& lon) const { lat = lon = NAN; }
double ProjProjection::max_scale_error(const double*, const double*, int) const { return INFINITY; }
bool ProjProjection::metric_east_north() const { return false; }
double ProjProjection::unit_m() const { return 1.0; }

Status load_overlays(const OverlayOptions&, const FrameCrs&, const std::vector<Material>&, double, double, double, double,
                     int, std::unique_ptr<SurfaceOverlays>&) {
  return absent("overlays");
}
Status prepare_overlays_block(SurfaceOverlays&, double, double, double, double) { return absent("overlays"); }

}  // namespace terrain::cook
