// image_api() loading terrain-image-oiio.so on first use (terrain-cook): a cook without image
// inputs, such as every `terrain-cook unit` and `merge` of a work dir, never maps OpenImageIO and
// its ~150 libraries (image_oiio.h). Where the module is found: tool_module.h.
#include <dlfcn.h>

#include <mutex>
#include <string>

#include "inputs/image_oiio.h"
#include "tool_module.h"

namespace terrain::cook {

Status image_api(const ImageApi*& api) {
  static std::once_flag once;
  static ImageApi loaded;
  static std::string error;
  std::call_once(once, [] {
    constexpr const char* kModule = "terrain-image-oiio.so";
    void* h = open_tool_module(kModule, error);
    if (!h) {
      error = "the image reader module " + error;
      return;
    }
    loaded.open = reinterpret_cast<decltype(loaded.open)>(::dlsym(h, "terrain_image_open"));
    loaded.read_channel0 = reinterpret_cast<decltype(loaded.read_channel0)>(::dlsym(h, "terrain_image_read_channel0"));
    loaded.close = reinterpret_cast<decltype(loaded.close)>(::dlsym(h, "terrain_image_close"));
    if (!(loaded.open && loaded.read_channel0 && loaded.close)) {
      loaded = ImageApi{};
      error = std::string(kModule) + " is not the image reader module";
    }
  });
  if (!loaded.open) return Status::failure(Error::unsupported_input, error);
  api = &loaded;
  return Status::success();
}

}  // namespace terrain::cook
