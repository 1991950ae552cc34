// The baseline the benchmark compares against: what an engine writes first. Same wanted set as
// the streamer (same rule, same budget), but every missing node is read and decoded synchronously
// on the caller's thread inside update(), into a freshly allocated buffer.
#pragma once
#include <memory>
#include <string>
#include <span>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/streamer.h"
#include "wanted_set.h"

namespace terrain::bench {

class NaiveLoader {
 public:
  struct FrameStats {
    uint32_t loaded = 0;
    uint32_t evicted = 0;
    uint64_t bytes_read = 0;
    uint64_t failed = 0;
    std::string first_failure;  // Status::to_string() of the first failed load, empty when none
  };

  NaiveLoader(const ArchiveReader& reader, const StreamerConfig& config);
  FrameStats update(std::span<const View> views);
  uint32_t resident() const { return resident_count_; }
  uint32_t wanted() const { return uint32_t(wanted_.size()); }
  uint64_t buffer_bytes() const { return uint64_t(resident_count_) * sizeof(NodeData); }

 private:
  const ArchiveReader& reader_;
  StreamerConfig config_;
  detail::NodeTree tree_;
  detail::WantedParams params_;
  std::vector<std::unique_ptr<NodeData>> data_;  // by directory index; null = not resident
  std::vector<uint8_t> failed_;
  std::vector<uint8_t> wanted_flag_;
  std::vector<detail::WantedNode> wanted_;
  uint32_t resident_count_ = 0;
};

}  // namespace terrain::bench
