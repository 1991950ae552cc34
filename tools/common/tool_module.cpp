#include "tool_module.h"

#include <dlfcn.h>

#include <filesystem>
#include <utility>

#ifndef TERRAIN_MODULE_DIR
#define TERRAIN_MODULE_DIR "."  // relative to the executable's folder (tools/common/CMakeLists.txt)
#endif

namespace terrain {

void* open_tool_module(const char* file_name, std::string& error) {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::canonical("/proc/self/exe", ec).parent_path();
  std::string why = std::string(file_name) + " was not found next to the executable";
  for (const std::filesystem::path& dir : {self, self / TERRAIN_MODULE_DIR}) {
    const std::string path = (dir / file_name).lexically_normal().string();
    if (void* h = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) return h;
    why += "; ";
    why += ::dlerror();
  }
  error = std::move(why);
  return nullptr;
}

}  // namespace terrain
