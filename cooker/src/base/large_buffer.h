// Vectors for the cook's large per-block buffers (a block's window of samples, the void fill's
// flags). Two things the plain std::vector does at a cost that dominated a work unit's set-up:
//  - resize() zero-fills what the caller overwrites anyway;
//  - every fresh 4 KB page costs a fault, and page faults are expensive under virtualisation
//    (cooker/README.md, "Figures behind the code").
// LargeAllocator leaves elements default-initialised (uninitialised for arithmetic types) and,
// from 4 MB up, allocates 2 MB-aligned memory and asks for transparent huge pages (madvise; a
// no-op where the kernel has them off). The contents never depend on it.
#pragma once
#include <sys/mman.h>

#include <cstddef>
#include <cstdlib>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace terrain::cook {

template <class T>
struct LargeAllocator {
  using value_type = T;
  static constexpr size_t kHugePage = size_t(2) << 20;
  static constexpr size_t kLarge = size_t(4) << 20;

  LargeAllocator() = default;
  template <class U>
  LargeAllocator(const LargeAllocator<U>&) noexcept {}

  T* allocate(size_t n) {
    const size_t bytes = n * sizeof(T);
    if (bytes < kLarge) return static_cast<T*>(::operator new(bytes));
    const size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
    void* p = std::aligned_alloc(kHugePage, rounded);
    if (!p) throw std::bad_alloc();
    ::madvise(p, rounded, MADV_HUGEPAGE);
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) noexcept {
    if (n * sizeof(T) < kLarge) ::operator delete(p);
    else std::free(p);
  }
  // Value-less construction default-initialises: resize() does not zero-fill.
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <class U>
  bool operator==(const LargeAllocator<U>&) const noexcept {
    return true;
  }
};

template <class T>
using LargeVector = std::vector<T, LargeAllocator<T>>;

}  // namespace terrain::cook
