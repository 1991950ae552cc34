// terrain-format-bench --sections (section_bench.cpp): zstd levels and trained dictionaries for the
// surface sections of cooked archives, bytes against encode and decode speed.
#pragma once
#include <cstddef>
#include <string>
#include <vector>

namespace terrain::bench {

// Prints the table for each archive; 1 when an archive cannot be read or a round trip fails.
int sections_main(const std::vector<std::string>& archives, size_t max_nodes, int runs);

}  // namespace terrain::bench
