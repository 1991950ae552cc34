// image_writer() loading terrain-image-write-oiio.so on first use (terrain-inspect): a summary,
// --verify or --sample never maps OpenImageIO and its ~150 libraries (image_write.h).
#include <dlfcn.h>

#include <mutex>
#include <string>

#include "image_write.h"
#include "tool_module.h"

namespace terrain::inspect {

Status image_writer(ImageWriteFn& write) {
  static std::once_flag once;
  static ImageWriteFn loaded = nullptr;
  static std::string error;
  std::call_once(once, [] {
    constexpr const char* kModule = "terrain-image-write-oiio.so";
    void* h = open_tool_module(kModule, error);
    if (!h) return;
    loaded = reinterpret_cast<ImageWriteFn>(::dlsym(h, "terrain_image_write"));
    if (!loaded) error = std::string(kModule) + " is not the image writer module";
  });
  if (!loaded) return Status::failure(Error::io_write, "cannot write images: " + error);
  write = loaded;
  return Status::success();
}

}  // namespace terrain::inspect
