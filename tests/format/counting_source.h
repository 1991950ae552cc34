// A ByteSource decorator that counts the reads reaching the source and their bytes, for tests that
// state how many reads an operation costs (an open, a payload run, a directory page).
#pragma once
#include <atomic>
#include <memory>

#include "terrain/byte_source.h"

namespace terrain::test {

class CountingSource : public ByteSource {
 public:
  explicit CountingSource(std::unique_ptr<ByteSource> inner) : inner_(std::move(inner)) {}
  uint64_t size() const override { return inner_->size(); }
  Status read(uint64_t offset, std::span<uint8_t> dst) const override {
    ++reads;
    bytes += dst.size();
    return inner_->read(offset, dst);
  }
  const std::string& name() const override { return inner_->name(); }
  mutable std::atomic<int> reads{0};
  mutable std::atomic<uint64_t> bytes{0};

 private:
  std::unique_ptr<ByteSource> inner_;
};

}  // namespace terrain::test
