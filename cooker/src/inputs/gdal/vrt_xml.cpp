// A VRT's XML as GDAL's VRT driver reads it (see vrt_xml.h).
#include "inputs/gdal/vrt_xml.h"

#include <cpl_conv.h>
#include <cpl_minixml.h>

#include <cmath>
#include <cstdlib>


namespace terrain::cook {

std::string vrt_folder(const std::string& vrt_path) { return CPLGetPath(vrt_path.c_str()); }

bool vrt_name_is_relative(const CPLXMLNode* source_filename) {
  return std::atoi(CPLGetXMLValue(source_filename, "relativeToVRT", "0")) != 0;  // GDAL's test
}

std::string vrt_source_file(const CPLXMLNode* source_filename, const std::string& vrt_folder) {
  const char* name = CPLGetXMLValue(source_filename, nullptr, "");
  if (!vrt_name_is_relative(source_filename)) return name;
  return CPLProjectRelativeFilename(vrt_folder.c_str(), name);  // GDAL's thread-local buffer: copied here
}

bool plain_file_name(std::string_view name) {
  return !name.starts_with("/vsi") && name.find(':') == std::string_view::npos;
}

bool is_vrt_source_name(std::string_view element) { return element.ends_with("Source"); }

bool is_vrt_source(const CPLXMLNode* child) { return child->eType == CXT_Element && is_vrt_source_name(child->pszValue); }

bool vrt_dst_rect(const CPLXMLNode* source, VrtRect& rect) {
  const CPLXMLNode* d = CPLGetXMLNode(source, "DstRect");
  if (!d) return false;
  rect.x = CPLAtofM(CPLGetXMLValue(d, "xOff", "0"));
  rect.y = CPLAtofM(CPLGetXMLValue(d, "yOff", "0"));
  rect.w = CPLAtofM(CPLGetXMLValue(d, "xSize", "0"));
  rect.h = CPLAtofM(CPLGetXMLValue(d, "ySize", "0"));
  return std::isfinite(rect.x + rect.y + rect.w + rect.h);
}

}  // namespace terrain::cook
