#include "resample_inputs.h"

#include <algorithm>
#include <cmath>
#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <fmt/format.h>
#include <gdal.h>
#include <gdalwarper.h>
#include <memory>
#include <ogr_spatialref.h>

#include "crs.h"
#include "memory_budget.h"

namespace terrain::cook {
namespace {

// The warper's working buffer (GDALWarpOptions::dfWarpMemoryLimit): what the whole warp needs in
// its Float64 working type (source and destination), at least 1 MB, at most 64 MB (it chunks).
uint64_t warp_buffer_bytes(uint64_t src_samples, uint64_t dst_samples) {
  return std::clamp<uint64_t>(2 * sizeof(double) * (src_samples + dst_samples), 1ull << 20, 64ull << 20);
}

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

// GDAL's geotransform (pixel corners) of a SampleGeo (sample centres).
void geotransform_of(const SampleGeo& g, double gt[6]) {
  gt[0] = g.c[0] - 0.5 * g.c[1] - 0.5 * g.c[2];
  gt[1] = g.c[1];
  gt[2] = g.c[2];
  gt[3] = g.c[3] - 0.5 * g.c[4] - 0.5 * g.c[5];
  gt[4] = g.c[4];
  gt[5] = g.c[5];
}

struct DatasetCloser {
  void operator()(void* ds) const { GDALClose(GDALDatasetH(ds)); }
};
using Dataset = std::unique_ptr<void, DatasetCloser>;

// A one-band Float32 MEM dataset over `values` (no copy), georeferenced by `geo` in `wkt`.
Dataset memory_dataset(float* values, int width, int height, const SampleGeo& geo, const std::string& wkt) {
  GDALDriverH mem = GDALGetDriverByName("MEM");
  if (!mem) return nullptr;
  Dataset ds(GDALCreate(mem, "", width, height, 0, GDT_Float32, nullptr));
  if (!ds) return nullptr;
  char pointer[64];
  CPLPrintPointer(pointer, values, sizeof(pointer));
  const std::string option = std::string("DATAPOINTER=") + pointer;
  char* options[] = {const_cast<char*>(option.c_str()), nullptr};
  if (GDALAddBand(ds.get(), GDT_Float32, options) != CE_None) return nullptr;
  double gt[6];
  geotransform_of(geo, gt);
  GDALSetGeoTransform(ds.get(), gt);
  GDALSetProjection(ds.get(), wkt.c_str());
  GDALSetRasterNoDataValue(GDALGetRasterBand(ds.get(), 1), NAN);
  return ds;
}

std::string wkt_of(const OGRSpatialReference& srs) {
  char* w = nullptr;
  srs.exportToWkt(&w);
  std::string s = w ? w : "";
  CPLFree(w);
  return s;
}

}  // namespace

bool needs_resampling(const Raster& ref, const Raster& r) {
  if (!same_crs(r.crs, ref.crs)) return true;
  for (int k : {1, 2, 4, 5})
    if (std::fabs(r.geo.c[k] - ref.geo.c[k]) > 1e-9 * (std::fabs(ref.geo.c[1]) + std::fabs(ref.geo.c[5]))) return true;
  return false;
}

Status resample_onto_grid(const Raster& ref, const Raster& in, uint64_t held_bytes, uint64_t memory_limit_bytes,
                          Raster& out) {
  if (!GDALGetDriverByName("MEM")) GDALAllRegister();
  OGRSpatialReference ref_srs, in_srs;
  if (!spatial_reference(ref.crs, ref_srs) || !spatial_reference(in.crs, in_srs))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} ({}) and {} ({}) differ in CRS or sample spacing and one of them has no "
                                       "geodetic CRS to resample through; give inputs one pixel grid",
                                       ref.path, describe_crs(ref.crs), in.path, describe_crs(in.crs)));
  // Where `in` lands on ref's grid: its border (sample centres, densified) through the CRS change.
  std::unique_ptr<OGRCoordinateTransformation> to_ref(OGRCreateCoordinateTransformation(&in_srs, &ref_srs));
  if (!to_ref)
    return Status::failure(Error::unsupported_input,
                           fmt::format("no transformation from {} to {}", describe_crs(in.crs), describe_crs(ref.crs)));
  const AffineMap in_map = AffineMap::from(in.geo), ref_map = AffineMap::from(ref.geo);
  double cmin = INFINITY, rmin = INFINITY, cmax = -INFINITY, rmax = -INFINITY;
  constexpr int kEdgePoints = 256;
  for (int e = 0; e < 4; ++e)
    for (int k = 0; k <= kEdgePoints; ++k) {
      const double t = double(k) / kEdgePoints;
      // Half a sample beyond the outer centres: pixel areas reach that far.
      const double lo_c = -0.5, hi_c = in.width - 0.5, lo_r = -0.5, hi_r = in.height - 0.5;
      const double col = e == 0 ? lo_c + t * (hi_c - lo_c) : e == 1 ? hi_c : e == 2 ? hi_c - t * (hi_c - lo_c) : lo_c;
      const double row = e == 0 ? lo_r : e == 1 ? lo_r + t * (hi_r - lo_r) : e == 2 ? hi_r : hi_r - t * (hi_r - lo_r);
      double x = 0, y = 0;
      in_map.to_model(col, row, x, y);
      if (!to_ref->Transform(1, &x, &y)) continue;
      double c = 0, r = 0;
      ref_map.to_sample(x, y, c, r);
      cmin = std::min(cmin, c);
      cmax = std::max(cmax, c);
      rmin = std::min(rmin, r);
      rmax = std::max(rmax, r);
    }
  if (!(cmin <= cmax && rmin <= rmax))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} cannot be placed in {}'s CRS ({})", in.path, ref.path, describe_crs(ref.crs)));
  const double c0 = std::floor(cmin), r0 = std::floor(rmin), c1 = std::ceil(cmax), r1 = std::ceil(rmax);
  const double wd = c1 - c0 + 1, hd = r1 - r0 + 1;
  if (wd * hd > double(int64_t(1) << 32) || wd > 1e9 || hd > 1e9)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} resampled onto {}'s grid would be {:.0f}x{:.0f} samples: too large", in.path,
                                       ref.path, wd, hd));
  const int w = int(wd), h = int(hd);
  const uint64_t warp_bytes = warp_buffer_bytes(in.values.size(), uint64_t(w) * uint64_t(h));
  if (Status st = check_memory(held_bytes + uint64_t(w) * uint64_t(h) * sizeof(float) + warp_bytes,
                               memory_limit_bytes, fmt::format("resampling {} onto {}'s grid", in.path, ref.path),
                               fmt::format("{} samples of {}x{} and the inputs held", format_count(uint64_t(w) * h), w, h),
                               "raise --memory-limit, or reproject the inputs to one grid with gdalwarp first");
      !st.ok())
    return st;

  Raster r;
  r.path = in.path;
  r.width = w;
  r.height = h;
  r.crs = ref.crs;
  r.geo = ref.geo;
  r.geo.point_samples = ref.geo.point_samples;
  ref_map.to_model(c0, r0, r.geo.c[0], r.geo.c[3]);
  r.values.assign(size_t(w) * size_t(h), NAN);
  r.nodata_declared = in.nodata_declared;
  r.implausible = in.implausible;

  const std::string ref_wkt = wkt_of(ref_srs), in_wkt = wkt_of(in_srs);
  // GDAL reads the source through the MEM band only; the const_cast never leads to a write.
  Dataset src = memory_dataset(const_cast<float*>(in.values.data()), in.width, in.height, in.geo, in_wkt);
  Dataset dst = memory_dataset(r.values.data(), w, h, r.geo, ref_wkt);
  if (!src || !dst) return Status::failure(Error::io_read, "GDAL's MEM driver is not available for resampling");
  void* transformer = GDALCreateGenImgProjTransformer2(src.get(), dst.get(), nullptr);
  if (!transformer)
    return Status::failure(Error::unsupported_input, fmt::format("GDAL cannot transform {} to {}'s grid: {}", in.path,
                                                                 ref.path, CPLGetLastErrorMsg()));
  GDALWarpOptions* wo = GDALCreateWarpOptions();
  wo->hSrcDS = src.get();
  wo->hDstDS = dst.get();
  wo->nBandCount = 1;
  wo->panSrcBands = static_cast<int*>(CPLMalloc(sizeof(int)));
  wo->panSrcBands[0] = 1;
  wo->panDstBands = static_cast<int*>(CPLMalloc(sizeof(int)));
  wo->panDstBands[0] = 1;
  wo->padfSrcNoDataReal = static_cast<double*>(CPLMalloc(sizeof(double)));
  wo->padfSrcNoDataReal[0] = NAN;
  wo->padfDstNoDataReal = static_cast<double*>(CPLMalloc(sizeof(double)));
  wo->padfDstNoDataReal[0] = NAN;
  wo->eResampleAlg = GRA_Bilinear;
  wo->eWorkingDataType = GDT_Float64;
  wo->dfWarpMemoryLimit = double(warp_bytes);
  wo->pfnTransformer = GDALGenImgProjTransform;  // exact per pixel: no approximating transformer
  wo->pTransformerArg = transformer;
  wo->papszWarpOptions = CSLSetNameValue(wo->papszWarpOptions, "INIT_DEST", "NO_DATA");
  // Single-threaded and exact: the result depends only on the inputs (byte-identical archives).
  wo->papszWarpOptions = CSLSetNameValue(wo->papszWarpOptions, "NUM_THREADS", "1");
  GDALWarpOperationH op = GDALCreateWarpOperation(wo);
  CPLErr err = op ? GDALChunkAndWarpImage(op, 0, 0, w, h) : CE_Failure;
  const std::string gdal_error = CPLGetLastErrorMsg();
  if (op) GDALDestroyWarpOperation(op);
  GDALDestroyGenImgProjTransformer(transformer);
  GDALDestroyWarpOptions(wo);
  dst.reset();
  src.reset();
  if (err != CE_None)
    return Status::failure(Error::io_read, fmt::format("resampling {} onto {}'s grid failed: {}", in.path, ref.path, gdal_error));
  r.description = fmt::format("{}, resampled (bilinear) from {} onto the first input's grid as {}x{}", in.description,
                              describe_crs(in.crs), w, h);
  out = std::move(r);
  return Status::success();
}

}  // namespace terrain::cook
