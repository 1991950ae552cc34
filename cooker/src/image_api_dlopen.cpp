// image_api() loading terrain-image-oiio.so on first use (terrain-cook): a cook without image
// inputs, such as every `terrain-cook unit` and `merge` of a work dir, never maps OpenImageIO and
// its ~150 libraries (image_oiio.h). The module sits next to the executable in the build tree and
// in TERRAIN_IMAGE_MODULE_DIR (relative to the executable's folder) once installed.
#include <dlfcn.h>

#include <filesystem>
#include <mutex>
#include <fmt/format.h>

#include "image_oiio.h"

#ifndef TERRAIN_IMAGE_MODULE_DIR
#define TERRAIN_IMAGE_MODULE_DIR "."
#endif

namespace terrain::cook {

Status image_api(const ImageApi*& api) {
  static std::once_flag once;
  static ImageApi loaded;
  static std::string error;
  std::call_once(once, [] {
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::canonical("/proc/self/exe", ec).parent_path();
    std::string tried;
    for (const std::filesystem::path& dir : {self, self / TERRAIN_IMAGE_MODULE_DIR}) {
      const std::string path = (dir / "terrain-image-oiio.so").lexically_normal().string();
      void* h = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!h) {
        tried += fmt::format("; {}", ::dlerror());
        continue;
      }
      loaded.open = reinterpret_cast<decltype(loaded.open)>(::dlsym(h, "terrain_image_open"));
      loaded.read_channel0 = reinterpret_cast<decltype(loaded.read_channel0)>(::dlsym(h, "terrain_image_read_channel0"));
      loaded.close = reinterpret_cast<decltype(loaded.close)>(::dlsym(h, "terrain_image_close"));
      if (loaded.open && loaded.read_channel0 && loaded.close) return;
      tried += fmt::format("; {}: not the image module", path);
      loaded = ImageApi{};
    }
    error = "the image reader module terrain-image-oiio.so was not found next to terrain-cook" + tried;
  });
  if (!loaded.open) return Status::failure(Error::unsupported_input, error);
  api = &loaded;
  return Status::success();
}

}  // namespace terrain::cook
