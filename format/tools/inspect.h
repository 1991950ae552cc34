// terrain-inspect as a library: summary, verification, point sampling and node export of an
// archive. The tool's main() only parses arguments and maps the outcome to an exit code.
// GeographicLib stays inside inspect.cpp; the image writer (OpenImageIO) behind image_write.h.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/progress.h"
#include "terrain/status.h"

namespace terrain::inspect {

// Summary text (frame and CRS, extent, nodes per level, bytes per section, ratios, heights).
Status summary_text(const ArchiveReader& reader, const std::string& path, std::string& out);
// The same facts as a JSON document (doubles at full precision).
Status summary_json(const ArchiveReader& reader, const std::string& path, std::string& out);

// Frame coordinates of a geographic point on the archive's own ellipsoid (no datum shift;
// GeographicLib). Fails with invalid_argument for a `local` frame.
Status lonlat_to_frame(const FrameCrs& crs, double lon_deg, double lat_deg, double& x, double& y);

struct SamplePoint {
  double x = 0, y = 0;  // as given (frame metres, or lon/lat degrees)
  bool lonlat = false;
};
struct SampleAnswer {
  double frame_x = 0, frame_y = 0;
  std::optional<double> height_m;  // nullopt: nodata
  NodeKey node;
};
// Lon/lat points are read on `lonlat_crs` (a geographic CRS PROJ knows; empty = WGS 84, EPSG:4326)
// and converted with the datum shift PROJ finds to the archive's datum (inspect_lonlat.h).
Status sample(const ArchiveReader& reader, const std::vector<SamplePoint>& points, std::vector<SampleAnswer>& out,
              const std::string& lonlat_crs = "");
// Reads "a b" pairs (whitespace or comma separated; blank lines and # comments skipped).
Status read_point_file(const std::string& path, bool lonlat, std::vector<SamplePoint>& out);
// Parses "A,B" (two finite numbers).
bool parse_pair(const std::string& text, double& a, double& b);
// Parses "LEVEL/X/Y".
bool parse_key(const std::string& text, NodeKey& out);

// Writes heights.exr (float metres, NaN at holes), heights.png (16-bit stored R16 values),
// normals.png, albedo.png (alpha = hole mask), cones.png, splat.pgm (raw ids), splat.png
// (palette colours) and node.json into `dir` (created). Images are north up.
Status export_node(const ArchiveReader& reader, const NodeKey& key, const std::string& dir, std::vector<std::string>& written);
// The files export_node writes (terrain-inspect checks them against the archive before any work).
inline constexpr const char* kExportFiles[] = {"heights.exr", "heights.png", "normals.png", "albedo.png",
                                               "cones.png",   "splat.pgm",   "splat.png",   "node.json"};

// Full verification with a progress callback (may be empty).
Status verify(const ArchiveReader& reader, const ProgressFn& progress);

}  // namespace terrain::inspect
