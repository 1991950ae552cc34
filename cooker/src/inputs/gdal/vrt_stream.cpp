// A VRT's XML streamed through expat (see vrt_stream.h).
#include "inputs/gdal/vrt_stream.h"

#include <cpl_minixml.h>
#include <expat.h>

#include <cctype>
#include <cstdio>
#include <memory>
#include <string_view>

#include "inputs/gdal/vrt_xml.h"

namespace terrain::cook {
namespace {

// Element names as GDAL's VRT driver compares them (EQUAL: ASCII, case-insensitive).
bool same_name(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i]))) return false;
  return true;
}

struct Parse {
  XML_Parser parser = nullptr;
  const std::function<bool(const VrtSourceVisit&)>* on_source = nullptr;
  VrtStream* out = nullptr;
  // File bytes [base, base + buf.size()): everything from `copied` on (the header's next bytes, or
  // the source being read), so an element split across chunks is still whole here at its end.
  std::string buf;
  uint64_t base = 0, copied = 0;
  int depth = 0;
  bool root_started = false, root_is_vrt = false, root_done = false, in_band = false, in_source = false;
  int band = -1;
  uint64_t source_begin = 0, source_start_bytes = 0, root_begin = 0;
  bool stopped = false;

  std::string_view bytes(uint64_t from, uint64_t to) const { return std::string_view(buf).substr(from - base, to - from); }
  // Where the current end tag ends: expat gives no byte count for the end of an empty element
  // (<A/>), which ends where its start tag does.
  uint64_t end_of_element(uint64_t begin, uint64_t start_bytes) const {
    const int n = XML_GetCurrentByteCount(parser);
    return n > 0 ? uint64_t(XML_GetCurrentByteIndex(parser)) + uint64_t(n) : begin + start_bytes;
  }
  void stop() {
    stopped = true;
    XML_StopParser(parser, XML_FALSE);
  }
};

void XMLCALL on_start(void* user, const XML_Char* name, const XML_Char**) {
  Parse& p = *static_cast<Parse*>(user);
  ++p.depth;
  const std::string_view n(name);
  if (p.depth == 1) {
    p.root_started = true;
    p.root_is_vrt = same_name(n, "VRTDataset");
    if (!p.root_is_vrt) return p.stop();
    p.root_begin = p.copied = uint64_t(XML_GetCurrentByteIndex(p.parser));
  } else if (p.depth == 2 && same_name(n, "VRTRasterBand")) {
    p.in_band = true;
    ++p.band;
    p.out->band_sources_at.push_back(std::string::npos);
  } else if (p.depth == 3 && p.in_band && is_vrt_source_name(n)) {
    p.in_source = true;
    p.source_begin = uint64_t(XML_GetCurrentByteIndex(p.parser));
    p.source_start_bytes = uint64_t(XML_GetCurrentByteCount(p.parser));
  }
}

void XMLCALL on_end(void* user, const XML_Char*) {
  Parse& p = *static_cast<Parse*>(user);
  if (p.depth == 3 && p.in_source) {
    p.in_source = false;
    const uint64_t end = p.end_of_element(p.source_begin, p.source_start_bytes);
    p.out->header.append(p.bytes(p.copied, p.source_begin));
    size_t& at = p.out->band_sources_at[size_t(p.band)];
    if (at == std::string::npos) at = p.out->header.size();
    if (*p.on_source) {
      const std::string text(p.bytes(p.source_begin, end));
      CPLXMLNode* node = CPLParseXMLString(text.c_str());
      const bool go_on = node && (*p.on_source)(VrtSourceVisit{p.band, node, p.source_begin, end});
      if (node) CPLDestroyXMLNode(node);
      if (!go_on) p.stop();
    }
    p.copied = end;
  } else if (p.depth == 2) {
    p.in_band = false;
  } else if (p.depth == 1) {
    const uint64_t end = p.end_of_element(p.root_begin, 0);
    p.out->header.append(p.bytes(p.copied, end));
    p.copied = end;
    p.root_done = true;
  }
  --p.depth;
}

}  // namespace

VrtRead read_vrt_stream(const std::string& path, VrtStream& out,
                        const std::function<bool(const VrtSourceVisit&)>& on_source, size_t chunk) {
  out = VrtStream{};
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), std::fclose);
  if (!f) return VrtRead::unreadable;
  std::unique_ptr<XML_ParserStruct, void (*)(XML_Parser)> parser(XML_ParserCreate(nullptr), XML_ParserFree);
  if (!parser) return VrtRead::unreadable;
  Parse p;
  p.parser = parser.get();
  p.on_source = &on_source;
  p.out = &out;
  XML_SetUserData(p.parser, &p);
  XML_SetElementHandler(p.parser, on_start, on_end);
  std::string data(chunk == 0 ? 1 : chunk, '\0');
  for (;;) {
    const size_t n = std::fread(data.data(), 1, data.size(), f.get());
    if (n == 0 && std::ferror(f.get())) return VrtRead::unreadable;
    const bool last = n < data.size();
    p.buf.append(data.data(), n);
    if (XML_Parse(p.parser, data.data(), int(n), last) == XML_STATUS_ERROR) {
      if (p.stopped) return p.root_is_vrt ? VrtRead::stopped : VrtRead::not_vrt;
      return VrtRead::unreadable;
    }
    // Keep only what is not yet in the header (before the root: all, as its start tag may be split).
    const uint64_t keep = p.root_started ? p.copied : p.base;
    if (keep > p.base) {
      p.buf.erase(0, size_t(keep - p.base));
      p.base = keep;
    }
    if (last) break;
  }
  if (!p.root_is_vrt) return VrtRead::not_vrt;
  return p.root_done ? VrtRead::ok : VrtRead::unreadable;
}

std::string vrt_without_sources(const std::string& path) {
  VrtStream vrt;
  return read_vrt_stream(path, vrt, {}) == VrtRead::ok ? std::move(vrt.header) : std::string();
}

}  // namespace terrain::cook
