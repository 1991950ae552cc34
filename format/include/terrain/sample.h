// Heights as a renderer sees them: the finest node covering a frame point, its vertices
// dequantized, each quad split along its south-west to north-east diagonal, and triangles
// touching a hole vertex dropped (format/SPEC.md "Surface").
#pragma once
#include <memory>
#include <optional>

#include "terrain/archive_reader.h"

namespace terrain {

struct SurfaceSample {
  double height_m = 0;
  NodeKey node;  // the node that answered
};

// Height at frame point (x, y) in metres; nullopt where there is no terrain or a hole.
// Not thread-safe (keeps a small decode cache); use one sampler per thread.
class SurfaceSampler {
 public:
  explicit SurfaceSampler(const ArchiveReader& reader);
  ~SurfaceSampler();
  Status sample(double frame_x, double frame_y, std::optional<SurfaceSample>& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terrain
