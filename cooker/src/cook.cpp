// The public entry points: cook() in one process, and the work-unit commands plan_cook(),
// cook_unit() and merge_units() (issue 14). All run the stages of cook_session.h, so a plan +
// units + merge gives the bytes of the one-process cook.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <fmt/format.h>

#include "session/cook_session.h"
#include "pyramid/node_spool.h"
#include "pyramid/overview_levels.h"
#include "terrain/cook.h"
#include "terrain/output_paths.h"
#include "units/merge.h"
#include "units/plan_file.h"
#include "units/unit_file.h"
#include "units/work_dir.h"

namespace terrain::cook {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
// CPU seconds (user + system) of the whole process so far.
double process_cpu() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

ProgressFn part(const ProgressFn& p, double lo, double hi) { return p ? scaled_progress(p, lo, hi) : ProgressFn{}; }

// Everything global: inputs, first pass, frame and grid, surface rules and overlays, steps. The
// report gets the timings only.
Status prepare(const CookOptions& options, const ProgressFn& progress, CookSession& s, CookReport& report) {
  const auto t0 = Clock::now();
  if (progress && !progress(0.0, "reading")) return Status::failure(Error::cancelled, "cancelled");
  TERRAIN_TRY(open_inputs(options, s));
  report.seconds_read = seconds_since(t0);
  const auto t1 = Clock::now();
  const double c1 = process_cpu();
  TERRAIN_TRY(first_pass(s, part(progress, 0.0, 0.1)));
  const double c2 = process_cpu();
  report.cpu_first_pass = c2 - c1;
  TERRAIN_TRY(frame_and_grid(s, nullptr));
  TERRAIN_TRY(surface_setup(s));
  const double c3 = process_cpu();
  choose_session_steps(s);
  report.cpu_steps = process_cpu() - c3;
  report.seconds_prepare = seconds_since(t1);
  return Status::success();
}

void finish_timing(const Clock::time_point t_start, CookReport& report) {
  report.seconds_total = seconds_since(t_start);
  report.cpu_total = process_cpu();
  report.source_samples_per_second = double(report.source_samples) / report.seconds_total;
}

Status plan_in_session(const CookOptions& options, const ProgressFn& progress, CookSession& s, PlanFile& plan,
                       PlanSummary& summary, CookReport& report);
Status merge_work_dir(const std::string& work_dir, const std::string& output, int threads, const ProgressFn& progress,
                      CookReport& report, const std::vector<NamedPath>& outputs);
Status cook_in_session(const CookOptions& options, const ProgressFn& progress, CookSession& s, PyramidTotals& totals,
                       CookReport& report);

// Block indices in cooking order: row by row; or shuffled by `seed` (tests).
std::vector<uint32_t> block_order(uint32_t count, uint64_t seed) {
  std::vector<uint32_t> order(count);
  for (uint32_t i = 0; i < count; ++i) order[i] = i;
  if (seed) {
    uint64_t x = seed;
    for (uint32_t i = count; i > 1; --i) {
      x ^= x << 13, x ^= x >> 7, x ^= x << 17;  // xorshift64: the same order on every platform
      std::swap(order[i - 1], order[size_t(x % i)]);
    }
  }
  return order;
}

// The roots of a spooled cook, for the overview levels (they read the payloads back).
RootSource spool_roots(const NodeSpool& spool) {
  auto entries = std::make_shared<std::vector<NodeSpool::Entry>>();
  for (const NodeSpool::Entry& e : spool.sorted_entries())
    if (e.record.key.level == uint32_t(kRootLevel)) entries->push_back(e);
  RootSource src;
  for (const NodeSpool::Entry& e : *entries) src.roots.push_back(e.record);
  src.read = [&spool, entries](size_t i, std::vector<uint8_t>& out) { return spool.read((*entries)[i], out); };
  return src;
}

}  // namespace

Status cook(const CookOptions& options, const ProgressFn& progress, CookReport& report) {
  report = CookReport{};
  const auto t_start = Clock::now();
  if (options.output.empty()) return Status::failure(Error::invalid_argument, "no output archive given");
  if (!options.work_dir.empty()) {
    // Plan + the units not already valid + merge: after a kill, the same call resumes.
    // A plan already in the work dir for these options and unchanged inputs is resumed as it is
    // (re-planning would read the whole input again); otherwise plan now.
    PlanSummary summary;
    CookSession s;
    PlanFile plan;
    PlanData existing;
    if (std::filesystem::exists(plan_file(options.work_dir)) && read_plan(options.work_dir, existing).ok() &&
        same_plan_options(existing.options, options) && same_plan_options(existing.resolved, resolved_options(options)) &&
        (options.unit_roots == 0 || options.unit_roots == existing.unit_roots) && check_plan_inputs(existing.plan).ok()) {
      TERRAIN_TRY(open_session_from_plan(existing, options.threads, s));
      plan = existing.plan;
      summary.unit_count = uint32_t(plan.units.size());
    } else if (Status st = plan_in_session(options, part(progress, 0.0, 0.1), s, plan, summary, report); !st.ok()) {
      return st;
    }
    for (uint32_t i = 0; i < summary.unit_count; ++i) {
      if (!check_unit_file(options.work_dir, plan, i).ok())
        TERRAIN_TRY(write_unit(s, plan, i, options.work_dir));
      if (progress && !progress(0.1 + 0.8 * double(i + 1) / summary.unit_count, fmt::format("unit {}/{}", i + 1, summary.unit_count)))
        return Status::failure(Error::cancelled, "cancelled");
    }
    CookReport merged;
    if (Status st = merge_work_dir(options.work_dir, options.output, s.threads, part(progress, 0.9, 1.0), merged, {});
        !st.ok())
      return st;
    merged.memory_limit_bytes = s.decided.memory_limit_bytes;
    merged.threads = s.threads;
    report = merged;
    finish_timing(t_start, report);
    return Status::success();
  }
  CookSession s;
  PyramidTotals totals;
  const Status st = cook_in_session(options, progress, s, totals, report);
  // The report from what the stages returned; on failure too (the warnings so far).
  fill_report(s, totals, report);
  if (!st.ok()) return st;
  finish_timing(t_start, report);
  if (progress) progress(1.0, "done");
  return Status::success();
}

namespace {

// The one-process cook: prepare, every block, the overview levels, the archive. The report gets
// the timings and the spool's and the overview levels' counts (fill_report the rest).
Status cook_in_session(const CookOptions& options, const ProgressFn& progress, CookSession& s, PyramidTotals& totals,
                       CookReport& report) {
  if (Status st = prepare(options, progress, s, report); !st.ok()) return st;

  // ---- pyramid: block by block ----
  const auto t_pyr = Clock::now();
  const double c_pyr = process_cpu();
  ArchiveWriter writer;
  TERRAIN_TRY(writer.open(options.output));
  NodeSpool spool;
  // Overview levels read the roots back from the spool: such cooks always spool.
  const bool spooled = s.grid.count() > 1 || !s.world.overview_step_log2.empty();
  if (spooled)
    TERRAIN_TRY(spool.open(staging_path(options.output, "spool")));
  const NodeSink sink = [&](NodeResult& r) {
    return spooled ? spool.add(r.record, r.payload) : writer.add_node(r.record, r.payload);
  };
  const std::vector<uint32_t> order = block_order(s.grid.count(), options.block_order);
  for (size_t n = 0; n < order.size(); ++n) {
    if (Status st = cook_block_of_session(s, order[n], sink, totals); !st.ok()) {
      writer.abort();
      return st;
    }
    if (progress && !progress(0.1 + 0.85 * double(n + 1) / double(order.size()), fmt::format("block {}/{}", n + 1, order.size())))
      return Status::failure(Error::cancelled, "cancelled");
  }
  s.window = SampleWindow{};
  if (spooled) {
    // The ordered writer: the directory written in place, nothing held per node but the spools'
    // records.
    report.spool_bytes = spool.bytes();
    NodeSpool overview;
    TERRAIN_TRY(spool_overview_levels(s, spool_roots(spool), options.output, overview, report));
    TERRAIN_TRY(writer.open_ordered(options.output, shape_of({&spool, &overview})));
    TERRAIN_TRY(spool.drain(writer));
    TERRAIN_TRY(overview.drain(writer));
    report.spool_bytes_returned = spool.punched_bytes() + overview.punched_bytes();
  }
  finish_levels(s, totals);
  report.seconds_pyramid = seconds_since(t_pyr);
  report.cpu_blocks = process_cpu() - c_pyr;

  // ---- finish ----
  const auto t_fin = Clock::now();
  CookReport decided;  // what the cook info records
  report_decisions(s, decided);
  TERRAIN_TRY(finish_archive(s, totals, decided, writer));
  report.seconds_finish = seconds_since(t_fin);
  return Status::success();
}

// plan_cook's work, keeping the session and the plan for a caller that cooks the units in this
// process (cook() with a work dir: no input is opened twice).
Status plan_in_session(const CookOptions& options, const ProgressFn& progress, CookSession& s, PlanFile& plan,
                       PlanSummary& summary, CookReport& report) {
  summary = PlanSummary{};
  if (options.work_dir.empty()) return Status::failure(Error::invalid_argument, "plan: no --work-dir given");
  std::error_code ec;
  std::filesystem::create_directories(options.work_dir + "/units", ec);
  if (ec)
    return Status::failure(Error::io_write, fmt::format("{}: cannot create the work dir: {}", options.work_dir, ec.message()));
  const Status prepared = prepare(options, progress, s, report);
  report_decisions(s, report);  // the plan's part of the report (write_plan records it)
  if (!prepared.ok()) return prepared;
  TERRAIN_TRY(plan_units(s, plan));
  // An input among the files the work dir's tools rewrite or remove would be lost (a VRT's tiles
  // too, known only now).
  for (const InputFile& f : plan.files)
    if (work_dir_owns(options.work_dir, f.path))
      return Status::failure(Error::invalid_argument,
                             fmt::format("{}: an input lies among the files of the work dir {} (its plan, input lists "
                                         "and units), which plan, unit and merge rewrite or remove; move it out or "
                                         "give another --work-dir", f.path, options.work_dir));
  summary.plan_path = plan_file(options.work_dir);
  summary.unit_count = uint32_t(plan.units.size());
  // An earlier plan in the work dir: keep the unit files this plan can use, say why others go.
  PlanData old;
  const bool had_plan = std::filesystem::exists(summary.plan_path) && read_plan(options.work_dir, old).ok();
  if (had_plan && old.plan.fingerprint != plan.fingerprint)
    summary.changes.push_back("the global decisions changed (options, frame, grid or a level's quantization step): "
                              "every unit is cooked again");
  if (had_plan) {
    std::map<std::string, std::string> old_fp;
    for (const InputFile& f : old.plan.files) old_fp[f.path] = f.fingerprint;
    for (const InputFile& f : plan.files) {
      const auto it = old_fp.find(f.path);
      if (it == old_fp.end()) summary.changes.push_back(fmt::format("{}: new input", f.path));
      else if (it->second != f.fingerprint) summary.changes.push_back(fmt::format("{}: changed", f.path));
      if (it != old_fp.end()) old_fp.erase(it);
    }
    for (const auto& [p, fp] : old_fp) summary.changes.push_back(fmt::format("{}: no longer an input", p));
  }
  // Structure and fingerprints only: re-reading every unit's payloads for their CRC would cost a
  // read of the whole archive per plan; a unit damaged inside is redone by `unit` (which checks
  // its CRC before skipping) and named by the merge.
  for (const UnitPlan& u : plan.units) {
    if (check_unit_file_head(options.work_dir, plan, u.index).ok()) ++summary.units_valid;
    else std::filesystem::remove(unit_file(options.work_dir, u.index), ec);  // stale or broken: redo
  }
  // Unit files beyond the new unit count belong to no unit any more.
  for (uint32_t i = summary.unit_count; std::filesystem::exists(unit_file(options.work_dir, i), ec); ++i)
    std::filesystem::remove(unit_file(options.work_dir, i), ec);
  remove_stale_staging_in(units_dir(options.work_dir));  // staged files of unit runs killed on this host
  TERRAIN_TRY(write_unit_inputs(s, plan, options.work_dir));
  return write_plan(s, report, plan, summary.plan_path);
}

}  // namespace

Status plan_cook(const CookOptions& options, const ProgressFn& progress, PlanSummary& summary, CookReport& report) {
  CookSession s;
  s.reads_source_again = false;  // the units read it, in their own processes
  PlanFile plan;
  return plan_in_session(options, progress, s, plan, summary, report);
}

Status cook_unit(const std::string& work_dir, uint32_t index, int threads, uint32_t block_roots, bool& skipped,
                 CookReport& report) {
  skipped = false;
  report = CookReport{};
  PlanData data;
  TERRAIN_TRY(read_plan(work_dir, data, index));
  if (const char* fail = std::getenv("TERRAIN_COOK_FAIL_UNITS")) {  // test hook: a unit that fails
    const std::string list = std::string(",") + fail + ",";
    if (list.find(fmt::format(",{},", index)) != std::string::npos)
      return Status::failure(Error::internal, fmt::format("unit {}: failing on purpose (TERRAIN_COOK_FAIL_UNITS)", index));
  }
  // A unit file from inputs that changed since the plan is not "complete": refuse before anything.
  TERRAIN_TRY(check_plan_inputs(data.plan, index));
  // Its unit file must not be one of the files it reads (nor a device, FIFO or directory).
  {
    std::vector<NamedPath> inputs;
    for (const InputFile& f : data.plan.files) inputs.push_back({"input of the plan", f.path});
    TERRAIN_TRY(check_output_paths(inputs, {{"unit file", unit_file(work_dir, index)}}));
  }
  if (check_unit_file(work_dir, data.plan, index).ok()) {
    skipped = true;
    return Status::success();
  }
  CookSession s;
  data.resolved.block_roots = block_roots;
  // A VRT mosaic cut to the unit's window by the plan: GDAL parses the tiles the unit reads, not
  // every tile of the mosaic; every read must then stay inside that window.
  const UnitPlan& unit = data.plan.units[index];
  const std::string cut = unit_vrt_file(work_dir, unit);
  const std::string input = data.resolved.inputs.size() == 1 ? data.resolved.inputs[0] : std::string();
  const bool use_cut = !input.empty() && std::filesystem::exists(cut);
  if (use_cut) {
    data.resolved.inputs = {cut};
    s.read_bounds = unit.window;
  }
  TERRAIN_TRY(open_session_from_plan(data, threads, s));
  report_decisions(s, report);
  if (use_cut) s.voids.source_name = input;  // messages name the user's input, not the cut
  return write_unit(s, data.plan, index, work_dir);
}

Status merge_units(const std::string& work_dir, const std::string& output, const ProgressFn& progress,
                   CookReport& report, const std::vector<NamedPath>& outputs) {
  return merge_work_dir(work_dir, output, /*threads=*/0, progress, report, outputs);
}

namespace {

// merge_units with the threads the overview levels are built with (0: all cores).
Status merge_work_dir(const std::string& work_dir, const std::string& output, int threads, const ProgressFn& progress,
                      CookReport& report, const std::vector<NamedPath>& outputs) {
  const auto t_start = Clock::now();
  PlanData data;
  TERRAIN_TRY(read_plan(work_dir, data));
  if (Status st = check_merge_outputs(work_dir, data.plan, outputs.empty() ? std::vector<NamedPath>{{"-o", output}} : outputs);
      !st.ok())
    return st;
  // Units cooked from inputs that changed since would mix two versions of the data.
  if (Status st = check_plan_inputs(data.plan); !st.ok()) return st;
  TERRAIN_TRY(merge_into(data, work_dir, output, threads, progress, report));
  finish_timing(t_start, report);
  return Status::success();
}

}  // namespace

}  // namespace terrain::cook
