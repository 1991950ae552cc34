// Where the benchmarks find the shared DEMs and the checkout, fixed at configure time in one file
// (bench_paths.cpp): as defines of every benchmark they made a clone at another path miss ccache on
// each of them.
#pragma once

namespace terrain {

const char* bench_data_dir();  // ../shared/data beside the checkout, or -DTERRAIN_DATA_DIR
const char* bench_source_dir();  // the checkout

}  // namespace terrain
