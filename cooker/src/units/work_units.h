// Work units (issue 14): the plan file, the unit files and their merge.
//
// A work dir W holds W/plan.json (every global decision of the cook and the list of units:
// root-aligned blocks of roots, pyramid.h), W/inputs-<fingerprint>.json (every input file with its
// fingerprint), per unit W/units/unit-<i>-<unit fingerprint>.inputs.json (the input files it reads)
// and W/units/unit-<i>.tcu, one file per unit written atomically (temp file + rename).
// format/SPEC.md section 18 (Work units, with its "Input lists") specifies them so another tool
// could merge them.
//
// Fingerprints are 64-bit FNV-1a hashes, written as 16 hex digits: of a file, its absolute path
// (resolved at plan time, so `unit` and `merge` run from any working directory), size, modification
// time, inode number and status change time (a file rewritten or replaced gets a new ctime even
// where `cp -p`, `rsync -t` or `tar` keep its size and mtime; no tool can set ctime back; contents
// are never hashed: national inputs are terabytes); of a unit, the plan's global decisions, its roots, its source window and the
// fingerprints of the input files whose footprint meets that window. A unit file is valid for a
// plan when its unit fingerprint is the plan's for that unit, so re-planning after a change keeps
// every unit the change does not touch.
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "session/cook_session.h"
#include "terrain/output_paths.h"

namespace terrain::cook {

std::string plan_file(const std::string& work_dir);
std::string units_dir(const std::string& work_dir);  // <work_dir>/units: the unit files
// <work_dir>/inputs-<fingerprint>.json: every input file of the plan (plan.json names it).
std::string inputs_file(const std::string& work_dir, const std::string& fingerprint);
std::string unit_file(const std::string& work_dir, uint32_t index);

struct UnitPlan {
  uint32_t index = 0;
  RootBlock roots;
  SampleRect window;        // the source samples the unit reads (its cook window, void-plan grown)
  std::string fingerprint;  // hex
};

struct InputFile {
  std::string path, fingerprint;  // path: absolute, resolved at plan time
  uint64_t size = 0;
  int64_t mtime_ns = 0;
  uint64_t inode = 0;    // st_ino
  int64_t ctime_ns = 0;  // st_ctim: changes with every write, rename onto, chmod or new hard link
  SampleRect footprint;  // mosaic samples it may contribute to (the whole mosaic when unknown)
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
// The VRT a unit reads when the cook's one input is a VRT mosaic: the plan cuts it to the unit's
// window (write_vrt_windows, source_raster.h), named by the unit's fingerprint so that a cut is
// never one of another plan or window. A unit without one (an earlier version's plan, or not
// written) reads the input itself; the bytes are the same.
std::string unit_vrt_file(const std::string& work_dir, const UnitPlan& unit);
// A unit's list of the input files its window meets (those its fingerprint holds), named by its
// fingerprint: what `unit` reads of the inputs instead of the plan's whole list.
std::string unit_inputs_file(const std::string& work_dir, const UnitPlan& unit);
// For `plan`: writes every unit's list and cut and removes the cuts of earlier plans (write_plan
// removes their lists once the new plan is in place).
Status write_unit_inputs(const CookSession& s, const PlanFile& plan, const std::string& work_dir);
// For `unit`: opens the inputs of the plan into a session and restores the plan's decisions (frame,
// grid, steps, voids). The caller has checked the files it reads with check_plan_inputs; the
// inputs' own per-file existence checks (a VRT's tiles) are not repeated.
Status open_session_from_plan(const PlanData& data, int threads, CookSession& s);

// The roots of every unit file (checked as the merge checks them), for the overview levels: their
// records and a reader of their payloads.
struct RootSource;
Status unit_roots(const std::string& work_dir, const PlanFile& plan, RootSource& out);

// Statistics a unit adds to the cook's report, stored in its file for the merge.
struct UnitStats {
  PyramidTotals totals;
  CookReport part;  // the fields cook_block and the window reads fill (report_blocks of `totals`)
};

// Cooks unit `index` of the session into its unit file (atomically: temp file, fsync, rename).
Status write_unit(CookSession& s, const PlanFile& plan, uint32_t index, const std::string& work_dir);

// Checks unit `index`'s file against the plan: present, complete, checksum, fingerprints.
// `why` says what is wrong (empty when valid).
bool unit_file_valid(const std::string& work_dir, const PlanFile& plan, uint32_t index, std::string& why);
// The same without the payloads' CRC (reads the header, table, stats and trailer only): for a plan
// deciding which units of an earlier plan to keep. A unit damaged inside its payloads passes; the
// unit command (unit_file_valid) redoes it and the merge names it.
bool unit_file_usable(const std::string& work_dir, const PlanFile& plan, uint32_t index, std::string& why);

// Merges every unit of the plan into `writer`, which it opens (ordered, ArchiveWriter::open_ordered)
// on `output`, in canonical order, and sums their stats (in unit order) into `totals` and
// `report`. Reads each unit's head, then each unit file front to back once (its CRC checked as its
// payloads are copied). Memory does not grow with the archive: one unit's node table at a time
// (56 bytes per node of the largest unit) while checking, then a read buffer per unit of a band
// (64-256 KB, 4 MB in all) and the writer's buffers. Fails naming a unit that is missing or
// bad, or two units whose heights disagree along the edge they share (the check terrain-inspect
// --verify makes between neighbours, made on the nodes of the units' edges only, decoded with the
// plan's quantization `steps`); the caller then aborts the writer. `extend_shape` (optional), called once every unit is
// checked and before the writer opens, adds the nodes the caller will add after the units' (the
// overview levels).
Status merge_unit_files(const std::string& work_dir, const PlanFile& plan, const std::array<uint8_t, kLevelCount>& steps,
                        const std::string& output, ArchiveWriter& writer, PyramidTotals& totals, CookReport& report,
                        const ProgressFn& progress, const std::function<Status(ArchiveShape&)>& extend_shape = {});

}  // namespace terrain::cook
