// The nodes of a synthetic world (tests/common/synthetic_archive.h) as StaticResidency input.
#pragma once
#include <vector>

#include "residency.h"
#include "synthetic_archive.h"

namespace terrain::view::test {

// Points into `world`, which must outlive the residency.
inline std::vector<MemoryNode> memory_nodes(const synthetic::World& world) {
  std::vector<MemoryNode> out;
  for (const auto& n : world.nodes) out.push_back({n.record, &n.data});
  return out;
}

}  // namespace terrain::view::test
