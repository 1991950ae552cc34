// Fixed-size slots of memory carved from 2 MB-aligned slabs (16 slots, 2-16 MB) that ask for
// transparent huge pages.
// For buffers of about a megabyte that come and go by the dozen (the GeoTIFF reader's decoded
// blocks, tiff_blocks.cpp): operator new gives each its own mapping, so every process that fills
// such a cache faults 256 fresh 4 KB pages per MB, and faults are expensive under virtualisation
// (large_buffer.h; cooker/README.md, "Compressed GeoTIFFs"). A work unit is a fresh process that fills its cache again: those faults were
// the largest part of what units cost over one process. Slots go back to the pool, not to the
// system; a slab is returned once all its slots are free.
// Contents are never touched here (a slot is not zeroed): nothing written depends on the pool.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace terrain::cook {

class SlabPool {
 public:
  SlabPool() = default;
  ~SlabPool();
  SlabPool(const SlabPool&) = delete;
  SlabPool& operator=(const SlabPool&) = delete;

  // A slot of at least `bytes` (thread-safe); null when the system has no memory.
  uint8_t* take(size_t bytes);
  // Returns a slot taken from this pool.
  void give(uint8_t* slot);
  // Bytes of the slots handed out so far in the slabs held (4 KB pages; with huge pages on, up to
  // 2 MB more per slab are resident): what the pool holds, for memory budgets. A slab's untouched
  // slots cost address space only.
  uint64_t touched_bytes() const;
  // Bytes of the slabs held, touched or not.
  uint64_t reserved_bytes() const;

 private:
  struct Slab {
    uint8_t* base = nullptr;
    size_t slot = 0, bytes = 0;
    std::vector<uint32_t> free;  // free slot numbers
    uint32_t count = 0;          // slots in the slab
    uint32_t high = 0;           // slots below this number have been handed out (touched)
  };
  static void release(Slab& s);
  mutable std::mutex m_;
  std::vector<std::unique_ptr<Slab>> slabs_;
  uint64_t reserved_ = 0;
};

}  // namespace terrain::cook
