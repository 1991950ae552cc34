// libFuzzer target (CMake option TERRAIN_FUZZ, clang): arbitrary bytes as a VRT for the cooker's
// streamed XML reading (cooker/src/inputs/gdal/vrt_stream.h). Whatever the bytes, the read ends with a result,
// every source lies inside the file and in a band the header lists, and the same bytes read in
// chunks of 1 to 256 bytes give exactly what one 1 MB chunk gives (sources, bands, byte ranges,
// header, band positions). The first corpus directory, when empty, gets a gdalbuildvrt-like seed.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>
#include <vector>

#include "inputs/gdal/vrt_stream.h"

namespace {

std::string g_file;  // this process's scratch file

void require(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz_vrt_stream: broken invariant: %s\n", what);
    std::abort();
  }
}

const char kSeed[] =
    "<?xml version=\"1.0\"?>\n<VRTDataset rasterXSize=\"64\" rasterYSize=\"32\">\n"
    "  <SRS dataAxisToSRSAxisMapping=\"1,2\">EPSG:32605</SRS>\n"
    "  <GeoTransform>  2.0e+05,  1.0e+00,  0.0e+00,  2.2e+06,  0.0e+00, -1.0e+00</GeoTransform>\n"
    "  <VRTRasterBand dataType=\"Float32\" band=\"1\">\n    <NoDataValue>-9999</NoDataValue>\n"
    "    <ComplexSource>\n      <SourceFilename relativeToVRT=\"1\">a&amp;0.tif</SourceFilename>\n"
    "      <SourceBand>1</SourceBand>\n"
    "      <SourceProperties RasterXSize=\"32\" RasterYSize=\"32\" DataType=\"Float32\" BlockXSize=\"32\" BlockYSize=\"32\" />\n"
    "      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"32\" ySize=\"32\" />\n"
    "      <DstRect xOff=\"0\" yOff=\"0\" xSize=\"32\" ySize=\"32\" />\n      <NODATA>-9999</NODATA>\n"
    "    </ComplexSource>\n    <!-- c -->\n    <SimpleSource/>\n"
    "    <SimpleSource><SourceFilename relativeToVRT=\"1\">1.tif</SourceFilename><![CDATA[<x>]]>"
    "<DstRect xOff=\"32\" yOff=\"0\" xSize=\"32\" ySize=\"32\" /></SimpleSource>\n"
    "  </VRTRasterBand>\n</VRTDataset>\n";

using Visit = std::tuple<int, uint64_t, uint64_t>;

terrain::cook::VrtRead read(size_t chunk, terrain::cook::VrtStream& out, std::vector<Visit>& visits, uint64_t size) {
  visits.clear();
  return terrain::cook::read_vrt_stream(
      g_file, out,
      [&](const terrain::cook::VrtSourceVisit& v) {
        require(v.node != nullptr, "a source has its tree");
        require(v.begin < v.end && v.end <= size, "a source lies inside the file");
        require(v.band >= 0, "a source is in a band");
        visits.emplace_back(v.band, v.begin, v.end);
        return true;
      },
      chunk);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
  g_file = (std::filesystem::temp_directory_path() / ("fuzz_vrt_stream." + std::to_string(getpid()) + ".vrt")).string();
  for (int i = 1; i < *argc; ++i) {
    const std::string a = (*argv)[i];
    if (a.empty() || a[0] == '-') continue;
    std::error_code ec;
    if (std::filesystem::is_directory(a, ec) && std::filesystem::is_empty(a, ec))
      std::ofstream(std::filesystem::path(a) / "seed.vrt", std::ios::binary) << kSeed;
    break;
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const size_t chunk = size_t(data[0]) + 1;  // 1..256
  {
    std::ofstream f(g_file, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data + 1), std::streamsize(size - 1));
  }
  terrain::cook::VrtStream small, whole;
  std::vector<Visit> small_visits, whole_visits;
  const auto r_small = read(chunk, small, small_visits, size - 1);
  const auto r_whole = read(size_t(1) << 20, whole, whole_visits, size - 1);
  // Expat may report a malformed document a chunk later when fed in pieces, so the results and the
  // sources are compared where both reads ended well.
  if (r_small == terrain::cook::VrtRead::ok || r_whole == terrain::cook::VrtRead::ok) {
    require(r_small == r_whole, "the chunk size does not change the result");
    require(small_visits == whole_visits, "the chunk size does not change the sources");
    require(small.header == whole.header, "the chunk size does not change the header");
    require(small.band_sources_at == whole.band_sources_at, "the chunk size does not change the bands");
    require(!whole.header.empty() && whole.header[0] == '<', "the header starts at the root element");
    for (const Visit& v : whole_visits)
      require(size_t(std::get<0>(v)) < whole.band_sources_at.size(), "a source's band is listed");
    for (size_t at : whole.band_sources_at) require(at == std::string::npos || at <= whole.header.size(), "band positions lie in the header");
  }
  return 0;
}
