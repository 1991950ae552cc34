// A GDAL VRT's XML read where the cooker does not open the VRT (the plan's tile placements, the
// tiles' existence, the block reader's sources, the units' cuts): one definition of where a
// source's file is and where it is drawn, as GDAL's VRT driver reads them (vrtsources.cpp).
#pragma once
#include <string>
#include <string_view>

struct CPLXMLNode;  // cpl_minixml.h

namespace terrain::cook {

// The folder a VRT's relative source names are resolved from (GDAL's CPLGetPath of its name).
std::string vrt_folder(const std::string& vrt_path);

// The file a <SourceFilename> element names, as GDAL resolves it: a relative one (below) from
// `vrt_folder` (CPLProjectRelativeFilename: an absolute name stays as it is).
std::string vrt_source_file(const CPLXMLNode* source_filename, const std::string& vrt_folder);

// Whether a <SourceFilename> is relative to the VRT: its relativeToVRT read as GDAL reads it (a
// non-zero integer).
bool vrt_name_is_relative(const CPLXMLNode* source_filename);

// A source file name that names a file on disk: not a /vsi... path, not a DRIVER:... string.
bool plain_file_name(std::string_view name);

// A band child that is a source (<SimpleSource>, <ComplexSource>, <KernelFilteredSource>, ...).
bool is_vrt_source(const CPLXMLNode* child);
bool is_vrt_source_name(std::string_view element);

// A source's <DstRect> in VRT samples; false when it has none or a value is not finite.
struct VrtRect {
  double x = 0, y = 0, w = 0, h = 0;
};
bool vrt_dst_rect(const CPLXMLNode* source, VrtRect& rect);

}  // namespace terrain::cook
