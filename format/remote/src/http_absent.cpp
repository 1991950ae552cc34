// A build without HTTP (-DTERRAIN_HTTP=OFF): URLs are refused with a message that says so.
#include "terrain/remote_source.h"

namespace terrain {

bool http_supported() { return false; }

Status open_http_source(const std::string& url, const HttpOptions&, std::unique_ptr<ByteSource>& out) {
  out.reset();
  return Status::failure(Error::unsupported_input,
                         url + ": this build reads no URLs (configured with -DTERRAIN_HTTP=OFF; libcurl is needed)");
}

bool http_stats(const ByteSource&, HttpStats&) { return false; }

}  // namespace terrain
