#include "bench_paths.h"

namespace terrain {

const char* bench_data_dir() { return TERRAIN_DEFAULT_DATA_DIR; }
const char* bench_source_dir() { return TERRAIN_SOURCE_DIR; }

}  // namespace terrain
