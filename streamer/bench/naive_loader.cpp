#include "naive_loader.h"

namespace terrain::bench {

NaiveLoader::NaiveLoader(const ArchiveReader& reader, const StreamerConfig& config)
    : reader_(reader), config_(config), tree_(detail::build_node_tree(reader)) {
  params_ = detail::make_wanted_params(config, uint32_t(tree_.tops.size()));
  data_.resize(tree_.nodes.size());
  failed_.assign(tree_.nodes.size(), 0);
  wanted_flag_.assign(tree_.nodes.size(), 0);
}

NaiveLoader::FrameStats NaiveLoader::update(std::span<const View> views) {
  FrameStats fs;
  detail::compute_wanted_set(tree_, failed_, views, params_, wanted_);
  std::fill(wanted_flag_.begin(), wanted_flag_.end(), 0);
  for (const detail::WantedNode& w : wanted_) wanted_flag_[w.index] = 1;
  for (size_t i = 0; i < data_.size(); ++i)
    if (data_[i] && !wanted_flag_[i]) {
      data_[i].reset();
      --resident_count_;
      ++fs.evicted;
    }
  // Parents come before children in the wanted list, so the tree stays closed.
  for (const detail::WantedNode& w : wanted_) {
    if (data_[w.index] || failed_[w.index]) continue;
    auto d = std::make_unique<NodeData>();
    if (Status s = reader_.decode_node(w.index, *d, config_.sections); !s.ok()) {
      failed_[w.index] = 1;
      if (fs.failed++ == 0) fs.first_failure = s.to_string();
      continue;
    }
    fs.bytes_read += reader_.nodes()[w.index].payload_size;
    data_[w.index] = std::move(d);
    ++resident_count_;
    ++fs.loaded;
  }
  return fs;
}

}  // namespace terrain::bench
