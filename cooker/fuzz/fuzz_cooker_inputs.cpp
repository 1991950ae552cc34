// libFuzzer target (CMake option TERRAIN_FUZZ, clang): arbitrary bytes as the cooker's own input
// formats. The first corpus directory, when empty, is filled with the generated seeds.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "fuzz_cooker_inputs_body.h"

namespace {
std::string g_dir;  // scratch folder of this process for the input files
}

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
  g_dir = (std::filesystem::current_path() / ("fuzz-cooker-scratch-" + std::to_string(getpid()))).string();
  std::filesystem::create_directories(g_dir);
  for (int i = 1; i < *argc; ++i) {
    const std::filesystem::path corpus = (*argv)[i];
    if ((*argv)[i][0] == '-' || !std::filesystem::is_directory(corpus)) continue;
    if (std::filesystem::is_empty(corpus)) {
      int k = 0;
      for (const auto& seed : terrain::fuzz::cooker_inputs_seeds(g_dir)) {
        std::ofstream f(corpus / ("seed" + std::to_string(k++)), std::ios::binary);
        f.write(reinterpret_cast<const char*>(seed.data()), std::streamsize(seed.size()));
      }
    }
    break;
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  terrain::fuzz::cooker_inputs_one_input(data, size, g_dir);
  return 0;
}
