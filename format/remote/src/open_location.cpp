// A path or a URL (terrain/remote_source.h).
#include "terrain/remote_source.h"

#include <cctype>

namespace terrain {

bool is_url(std::string_view location) {
  auto starts = [&](std::string_view scheme) {
    if (location.size() < scheme.size()) return false;
    for (size_t i = 0; i < scheme.size(); ++i)
      if (std::tolower(static_cast<unsigned char>(location[i])) != scheme[i]) return false;
    return true;
  };
  return starts("http://") || starts("https://");
}

Status open_location(const std::string& location, std::unique_ptr<ByteSource>& out, const HttpOptions& options) {
  if (is_url(location)) return open_http_source(location, options, out);
  return open_file_source(location, out);
}

Status open_archive(ArchiveReader& reader, const std::string& location, const HttpOptions& options, DirectoryLoad load) {
  std::unique_ptr<ByteSource> source;
  TERRAIN_TRY(open_location(location, source, options));
  return reader.open(std::move(source), load);
}

}  // namespace terrain
