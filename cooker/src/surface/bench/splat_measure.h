// Coherence figures of an archive's splat maps: isolated samples, neighbour id changes,
// material shares and agreement between a node and its children. Reads archives with the format
// reader only, so it measures what a viewer gets.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/status.h"

namespace terrain::cook::bench {

struct SplatMeasure {
  // Over every node of the archive; samples without data (albedo alpha 0 at the sample's vertex)
  // are left out, and so are pairs and neighbourhoods that touch one.
  uint64_t samples = 0;
  uint64_t isolated = 0, isolated_tested = 0;  // differ from all 4 neighbours (interior samples)
  uint64_t changes = 0, pairs = 0;             // horizontally and vertically adjacent samples
  std::array<uint64_t, 256> count{};           // samples per material id
  // Level agreement: coarse samples equal to a most common id of the 2x2 child samples they
  // cover (child samples (2i - 64 cx .. +1, 2j - 64 cy .. +1), clipped to the child's map).
  uint64_t lod_agree = 0, lod_tested = 0;
  // The same restricted to the finest level present (where lidar noise shows).
  uint64_t fine_isolated = 0, fine_isolated_tested = 0, fine_changes = 0, fine_pairs = 0;
  uint32_t finest_level = 0;
  // Shared edges: a node's east column / north row against its neighbour's west column / south
  // row (SPEC 16.4: must be equal).
  uint64_t seam_samples = 0, seam_mismatches = 0;

  double isolated_pct() const { return isolated_tested ? 100.0 * double(isolated) / double(isolated_tested) : 0; }
  double changes_pct() const { return pairs ? 100.0 * double(changes) / double(pairs) : 0; }
  double lod_agree_pct() const { return lod_tested ? 100.0 * double(lod_agree) / double(lod_tested) : 100; }
  double fine_isolated_pct() const {
    return fine_isolated_tested ? 100.0 * double(fine_isolated) / double(fine_isolated_tested) : 0;
  }
  double fine_changes_pct() const { return fine_pairs ? 100.0 * double(fine_changes) / double(fine_pairs) : 0; }
  double share_pct(int id) const { return samples ? 100.0 * double(count[size_t(id)]) / double(samples) : 0; }
};

Status measure_splat(const ArchiveReader& archive, SplatMeasure& out);
Status measure_splat_file(const std::string& path, SplatMeasure& out);

}  // namespace terrain::cook::bench
