// The merge of a plan's unit files into the archive (`terrain-cook merge`, format/SPEC.md section
// 18): every unit checked (present, complete, checksum, fingerprints, the heights along the edges
// units share), their nodes copied in canonical order through an ordered writer, the overview
// levels built from the units' roots, the archive finished as the one-process cook finishes it.
// Also the ordered writer's parts the one-process cook shares: the overview levels spooled, and
// the shape of spooled nodes.
#pragma once
#include <initializer_list>
#include <string>

#include "terrain/archive_writer.h"
#include "terrain/cook.h"
#include "terrain/progress.h"
#include "terrain/status.h"

namespace terrain::cook {

struct CookSession;
class NodeSpool;
struct PlanData;
struct RootSource;

// Merges the units of the plan `data` (read_plan, plan_file.h) in `work_dir` into the archive
// `output`, the overview levels built with `threads` (0: all cores), and fills `report` once, at
// the end, from the plan's part and the units' stats (its memory limit and threads are the
// caller's to set). On failure the archive is not written (the writer is aborted) and the failure
// names the unit.
Status merge_into(const PlanData& data, const std::string& work_dir, const std::string& output, int threads,
                  const ProgressFn& progress, CookReport& report);

// The overview levels from the cooked roots (SPEC 19), when the plan has any, into a spool next
// to `output`: their nodes follow every other node, and an ordered writer must know their count
// and bytes before the first node (the directory's place). Their count, largest error and CPU
// seconds go to `report`.
Status spool_overview_levels(const CookSession& s, const RootSource& roots, const std::string& output, NodeSpool& spool,
                             CookReport& report);
// The shape of an archive of `parts`' nodes (an ordered writer's, archive_writer.h).
ArchiveShape shape_of(std::initializer_list<const NodeSpool*> parts, ArchiveShape shape = {});

}  // namespace terrain::cook
