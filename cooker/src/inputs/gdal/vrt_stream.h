// A GDAL VRT read as a stream (expat), one source at a time. CPLParseXMLFile holds the whole file
// as a tree, several times the file's size (cooker/README.md, "Mosaics of thousands of tiles"), so a national mosaic of a million tiles
// would need gigabytes in every process that reads its XML. Here the memory is one source's
// tree and the dataset's XML without its sources.
#pragma once
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

struct CPLXMLNode;  // cpl_minixml.h

namespace terrain::cook {

// A source: a child of a VRTRasterBand (the dataset's band `band`, 0-based) whose name ends in
// "Source" (is_vrt_source), as its own small tree (valid during the call), and its bytes in the file.
struct VrtSourceVisit {
  int band = 0;
  const CPLXMLNode* node = nullptr;
  uint64_t begin = 0, end = 0;
};

struct VrtStream {
  // The root <VRTDataset> element's bytes without its bands' sources: GDAL opens that text (it
  // starts with "<VRTDataset") with the VRT's size, georeferencing, bands and metadata.
  std::string header;
  // Per band: where in `header` its first source stood (sources are put back there when a VRT is
  // cut), or npos for a band without sources.
  std::vector<size_t> band_sources_at;
};

enum class VrtRead {
  ok,
  stopped,     // on_source returned false
  not_vrt,     // well-formed so far, but the root element is not <VRTDataset>
  unreadable,  // cannot be read, or not XML expat accepts (GDAL's own reader may still open it)
};

// Reads the VRT at `path` in 1 MB chunks (`chunk` bytes: tests split tokens with tiny ones),
// calling on_source (may be empty) for each source in file order.
VrtRead read_vrt_stream(const std::string& path, VrtStream& out,
                        const std::function<bool(const VrtSourceVisit&)>& on_source, size_t chunk = size_t(1) << 20);

// The VRT at `path` as XML text without its bands' sources (every is_vrt_source child): GDAL opens
// that with the size, georeferencing, band type, nodata, scale and metadata of the VRT, without an
// object per source (the cooker's own reader composes the tiles). Empty when the file is not a
// VRTDataset's XML.
std::string vrt_without_sources(const std::string& path);

}  // namespace terrain::cook
