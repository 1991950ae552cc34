// One fuzz input for the archive reader: open arbitrary bytes, then use everything the reader
// offers. Property: never crashes, hangs, leaks or trips a sanitizer; invariants hold when it opens.
// Shared by the libFuzzer target and the seed-replay regression test.
#pragma once
#include <cstddef>
#include <cstdint>

namespace terrain::fuzz {

// Returns 1 when the bytes opened as an archive, else 0. Aborts on a broken invariant.
int archive_reader_one_input(const uint8_t* data, size_t size);

}  // namespace terrain::fuzz
