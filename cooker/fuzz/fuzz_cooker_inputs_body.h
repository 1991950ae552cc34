// One fuzz input for the cooker's own input parsing (what is not read through libtiff/GDAL): SRTM
// HGT plain, .zip and .gz, raw .r16/.r32 heightmaps, NumPy .npz, PNG heightmaps. Property: never
// crashes, hangs, leaks, trips a sanitizer or allocates beyond the memory budget; a raster that
// loads is consistent. Shared by the libFuzzer target and the seed-replay test.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace terrain::fuzz {

// Input layout: byte 0 picks the format (and file name), bytes 1-2 the raw width and height,
// the rest is the file's content, written into `dir` and loaded with load_inputs(). Returns 1
// when it loaded, else 0. Aborts on a broken invariant.
int cooker_inputs_one_input(const uint8_t* data, size_t size, const std::string& dir);

// Small valid inputs of every format (generated, nothing committed): the fuzzer's seeds.
std::vector<std::vector<uint8_t>> cooker_inputs_seeds(const std::string& dir);

}  // namespace terrain::fuzz
