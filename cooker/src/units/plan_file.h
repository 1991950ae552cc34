// The plan of a work-unit cook (format/SPEC.md section 18, "Plan" and "Input lists"): W/plan.json
// (every global decision of the cook and the list of units: root-aligned blocks of roots,
// pyramid.h), W/inputs-<fingerprint>.json (every input file with its fingerprint) and per unit
// W/units/unit-<i>-<unit fingerprint>.inputs.json (the input files it reads), with their
// fingerprints (fingerprints.h). A unit's fingerprint is of the plan's global decisions, its roots,
// its source window and the fingerprints of the input files whose footprint meets that window, so
// re-planning after a change keeps every unit the change does not touch.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "session/cook_session.h"
#include "terrain/output_paths.h"
#include "units/fingerprints.h"

namespace terrain::cook {

struct UnitPlan {
  uint32_t index = 0;
  RootBlock roots;
  SampleRect window;        // the source samples the unit reads (its cook window, void-plan grown)
  std::string fingerprint;  // hex
};

struct PlanFile {
  std::string fingerprint;  // of the global decisions (not of the unit list)
  std::vector<InputFile> files;
  std::vector<UnitPlan> units;
  // Per unit, the indices in `files` of those its window meets (made by plan_units; not read back).
  std::vector<std::vector<uint32_t>> unit_files;
};

// The plan of a session whose steps are decided: input files and units with their fingerprints.
Status plan_units(CookSession& s, PlanFile& plan);
Status write_plan(const CookSession& s, const CookReport& report, const PlanFile& plan, const std::string& path);

// What plan.json holds, read back without opening any input (the merge needs none).
struct PlanData {
  CookOptions options;   // as given to `plan`: its paths as typed (the cook info records them)
  CookOptions resolved;  // the same with every path absolute, resolved by `plan`: what is opened
  PlanFile plan;
  FrameCrs frame;
  WorldInfo world;  // frame, grid, footprint
  std::array<uint8_t, kLevelCount> steps{};
  uint32_t unit_roots = 0;
  int source_width = 0, source_height = 0;
  VoidPlan voids;
  CookReport report;  // the plan's part: inputs, voids, frame, grid, finest level, warnings
  std::vector<std::pair<std::string, std::string>> descriptions;
};
// With `unit`, the input files are that unit's only (its own list, unit_inputs_file): what it
// reads does not grow with the number of tiles of the whole input.
Status read_plan(const std::string& work_dir, PlanData& out, std::optional<uint32_t> unit = std::nullopt);
// `o` with every input path (inputs, materials, overlays) made absolute against the working
// directory, symbolic links kept.
CookOptions resolved_options(CookOptions o);
// True when a plan made with `planned` is the plan `given` would make from the same inputs (every
// option that changes a byte; threads, the memory limit and the output path do not).
bool same_plan_options(const CookOptions& planned, const CookOptions& given);
// Every input file of the plan is as the plan saw it (size, mtime, inode, ctime): else a named error. With
// `unit`, only the files that meet its window: those its fingerprint holds, the only ones it reads
// (one stat per tile it may read, not one per tile of a national mosaic).
Status check_plan_inputs(const PlanFile& plan, std::optional<uint32_t> unit = std::nullopt);
// The files the merge writes (`outputs`: the archive, the report) against the plan, before
// anything is written: output_paths.h's rule with every input file of the plan (a VRT's tiles, the
// overlays and the materials too) as the inputs, and none may be a file of the work dir
// (work_dir_owns, cook.h): invalid_argument naming both.
Status check_merge_outputs(const std::string& work_dir, const PlanFile& plan, const std::vector<NamedPath>& outputs);
// For `plan`: writes every unit's list and cut and removes the cuts of earlier plans (write_plan
// removes their lists once the new plan is in place).
Status write_unit_inputs(const CookSession& s, const PlanFile& plan, const std::string& work_dir);
// For `unit`: opens the inputs of the plan into a session and restores the plan's decisions (frame,
// grid, steps, voids). The caller has checked the files it reads with check_plan_inputs; the
// inputs' own per-file existence checks (a VRT's tiles) are not repeated.
Status open_session_from_plan(const PlanData& data, int threads, CookSession& s);

}  // namespace terrain::cook
