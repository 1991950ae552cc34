// Where the viewer's nodes come from, frame by frame: the streaming library (the normal case) or
// everything decoded up front (`--load-all`, the benchmark's full-detail reference, tests).
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "camera.h"
#include "residency.h"
#include "terrain/archive_reader.h"
#include "terrain/remote_source.h"
#include "terrain/streamer.h"
#include "terrain_state.h"

namespace terrain::view {

struct SourceStats {
  uint32_t resident = 0, delivered = 0, evicted = 0, failed = 0;
  uint32_t pending = 0;           // wanted but not resident yet
  uint32_t required_missing = 0;  // the error target needs them: a coarser parent is drawn meanwhile
};

class NodeSource {
 public:
  virtual ~NodeSource() = default;
  virtual const WorldInfo& world() const = 0;
  virtual uint32_t slot_count() const = 0;
  // Heights of the roots (units), for a default camera.
  virtual void height_range(int32_t& min_units, int32_t& max_units) const = 0;
  // One frame: decide residency for `camera` (u holds its frustum and pixels per radian), write
  // the changes into `state` and append the node payloads to upload.
  virtual Status update(const Camera& camera, const FrameUniforms& u, TerrainState& state,
                        std::vector<NodeUpload>& uploads) = 0;
  // Nothing left to load for the current view.
  virtual bool settled() const = 0;
  virtual SourceStats stats() const = 0;
  // Decoded data of the node in `slot` (valid until the next update), or null.
  virtual const NodeData* slot_data(uint32_t slot) const = 0;
};

struct StreamSourceOptions {
  uint32_t budget_nodes = 0;  // 0 = automatic: 512, or roots + 512 without overview levels
  double error_target_px = 2.0;
  uint32_t worker_threads = 0;
  uint32_t max_deliveries_per_frame = 128;
  HttpOptions http;  // for an http(s):// archive (the cache folder among them)
};
Status open_stream_source(const std::string& archive, const StreamSourceOptions& options, std::unique_ptr<NodeSource>& out);

// Decodes every node of the archive (at most `max_nodes`, else an error naming the count) and keeps
// them all resident.
Status open_load_all_source(const std::string& archive, uint32_t max_nodes, std::unique_ptr<NodeSource>& out);

}  // namespace terrain::view
