// libFuzzer target (CMake option TERRAIN_FUZZ, clang): arbitrary bytes opened as an archive.
#include "fuzz_archive_reader_body.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  terrain::fuzz::archive_reader_one_input(data, size);
  return 0;
}
