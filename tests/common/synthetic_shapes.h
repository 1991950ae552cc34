// The two shapes of the synthetic generator (synthetic_archive.h), each handing its nodes, in the
// order they are written, to one sink. Private to terrain_test_synthetic.
#pragma once
#include <functional>

#include "synthetic_archive.h"

namespace terrain::synthetic {

// The analytic surface's height step, every level: 1/64 m, range 1024 m per node.
inline constexpr int kSurfaceStepLog2 = 4;

// Called once per node; `record` is the node's final record (child mask included). Data buffers
// are reused between calls.
using NodeSink = std::function<Status(const NodeRecord& record, const NodeData& data)>;

// Random sparse quadtrees, nodes in directory order (key_less).
Status generate_sparse_tree(const Spec& spec, const WorldInfo& world, const NodeSink& sink);

// The analytic surface, parents before children (level descending).
Status generate_analytic_surface(const Spec& spec, const NodeSink& sink);

}  // namespace terrain::synthetic
