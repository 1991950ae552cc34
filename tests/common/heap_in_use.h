// Heap bytes in use, for tests that bound how memory grows with the work. mallinfo2 does not see
// a sanitizer's heap, so such tests check only their results there (kSanitizedHeap).
#pragma once
#include <malloc.h>

#include <cstdint>

namespace terrain::test {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
inline constexpr bool kSanitizedHeap = true;
#else
inline constexpr bool kSanitizedHeap = false;
#endif

// Small blocks (uordblks) and the large ones malloc maps on their own (hblkhd).
inline int64_t heap_in_use() {
  const struct mallinfo2 m = mallinfo2();
  return int64_t(m.uordblks) + int64_t(m.hblkhd);
}

}  // namespace terrain::test
