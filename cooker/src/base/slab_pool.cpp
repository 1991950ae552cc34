#include "base/slab_pool.h"

#include <sanitizer/asan_interface.h>
#include <sys/mman.h>

#include <algorithm>
#include <cstdlib>

namespace terrain::cook {
namespace {

constexpr size_t kHugePage = size_t(2) << 20;
// A slab holds 16 slots within 2-16 MB (at least one slot): a few slabs cover a cache of
// 16-128 MB of megabyte tiles, and small blocks do not take 16 MB each.
constexpr size_t kMinSlabBytes = size_t(2) << 20, kMaxSlabBytes = size_t(16) << 20;
constexpr size_t kSlotAlign = 64;
#if defined(TERRAIN_SLAB_POOL_PLAIN)
// One slot per slab, a plain allocation: the block reader's fuzzer opens and drops a reader per
// input, and a fresh poisoned 2-16 MB slab per input cost it 90 % of its runs (it checks decoders).
constexpr bool kOneSlotPerSlab = true;
#else
constexpr bool kOneSlotPerSlab = false;
#endif

}  // namespace

SlabPool::~SlabPool() {
  for (const auto& s : slabs_) release(*s);
}

void SlabPool::release(Slab& s) {
  ASAN_UNPOISON_MEMORY_REGION(s.base, s.bytes);  // the allocator may reuse it
  std::free(s.base);
}

uint8_t* SlabPool::take(size_t bytes) {
  const size_t slot = (std::max<size_t>(bytes, 1) + kSlotAlign - 1) / kSlotAlign * kSlotAlign;
  std::lock_guard<std::mutex> lock(m_);
  for (const auto& s : slabs_)
    if (s->slot == slot && !s->free.empty()) {
      const uint32_t i = s->free.back();
      s->free.pop_back();
      s->high = std::max(s->high, i + 1);
      uint8_t* p = s->base + size_t(i) * slot;
      ASAN_UNPOISON_MEMORY_REGION(p, bytes);
      return p;
    }
  auto s = std::make_unique<Slab>();
  s->slot = slot;
  if (kOneSlotPerSlab) {
    s->count = 1;
    s->bytes = slot;
    s->base = static_cast<uint8_t*>(std::malloc(slot));
    if (!s->base) return nullptr;
  } else {
    s->count = uint32_t(std::max<size_t>(std::clamp(16 * slot, kMinSlabBytes, kMaxSlabBytes) / slot, 1));
    s->bytes = (size_t(s->count) * slot + kHugePage - 1) / kHugePage * kHugePage;
    s->base = static_cast<uint8_t*>(std::aligned_alloc(kHugePage, s->bytes));
    if (!s->base) return nullptr;
    ::madvise(s->base, s->bytes, MADV_HUGEPAGE);  // a no-op where the kernel has them off
  }
  // Under AddressSanitizer only the bytes asked for are addressable, as with one allocation per
  // buffer: a decoder writing past its block is caught, not hidden in the next slot.
  ASAN_POISON_MEMORY_REGION(s->base, s->bytes);
  // Slot 0 is handed out now; the others are taken from the front, so that the pages a slab
  // touches grow from its start.
  for (uint32_t i = s->count; i-- > 1;) s->free.push_back(i);
  reserved_ += s->bytes;
  s->high = 1;
  uint8_t* p = s->base;
  ASAN_UNPOISON_MEMORY_REGION(p, bytes);
  slabs_.push_back(std::move(s));
  return p;
}

void SlabPool::give(uint8_t* slot) {
  if (!slot) return;
  std::lock_guard<std::mutex> lock(m_);
  for (size_t k = 0; k < slabs_.size(); ++k) {
    Slab& s = *slabs_[k];
    if (slot < s.base || slot >= s.base + size_t(s.count) * s.slot) continue;
    ASAN_POISON_MEMORY_REGION(slot, s.slot);
    s.free.push_back(uint32_t(size_t(slot - s.base) / s.slot));
    if (s.free.size() < s.count) return;
    // All free (every reader of its blocks closed): back to the system.
    reserved_ -= s.bytes;
    release(s);
    slabs_.erase(slabs_.begin() + std::ptrdiff_t(k));
    return;
  }
}

uint64_t SlabPool::touched_bytes() const {
  std::lock_guard<std::mutex> lock(m_);
  uint64_t n = 0;
  for (const auto& s : slabs_) n += (uint64_t(s->high) * s->slot + 4095) / 4096 * 4096;
  return n;
}

uint64_t SlabPool::reserved_bytes() const {
  std::lock_guard<std::mutex> lock(m_);
  return reserved_;
}

}  // namespace terrain::cook
