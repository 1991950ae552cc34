// PNG output of viewer frames (OpenImageIO, confined to image_io.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "terrain/status.h"

namespace terrain::view {

// Writes RGBA8 (sRGB-encoded) rows top to bottom as an RGB PNG.
Status write_png(const std::string& path, const std::vector<uint8_t>& rgba, uint32_t width, uint32_t height);

}  // namespace terrain::view
