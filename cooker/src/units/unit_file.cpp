#include "units/unit_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "pyramid/node_spool.h"
#include "session/cook_session.h"
#include "terrain/detail/bytes.h"  // format/internal: little-endian loads and stores, CRC-32
#include "terrain/output_paths.h"
#include "units/file_io.h"
#include "units/plan_file.h"
#include "units/work_dir.h"

namespace terrain::cook {
namespace {

using json = nlohmann::ordered_json;
using detail::load_u32;
using detail::load_u64;
using detail::store_u32;
using detail::store_u64;

constexpr char kUnitMagic[8] = {'T', 'C', 'U', 'N', 'I', 'T', '1', '\0'};
constexpr char kUnitEnd[4] = {'T', 'C', 'U', 'E'};

uint32_t crc_update(uint32_t crc, const uint8_t* p, size_t n) { return detail::crc32_update(crc, {p, n}); }

json error_json(const ErrorStats& e) { return {e.max_m, e.sum_sq, e.samples, e.uncovered}; }
ErrorStats error_of(const json& j) {
  ErrorStats e;
  e.max_m = j.at(0);
  e.sum_sq = j.at(1);
  e.samples = j.at(2);
  e.uncovered = j.at(3);
  return e;
}

json stats_json(const UnitStats& u) {
  const CookReport& r = u.part;
  json levels = json::array(), errors = json::array(), level_cpu = json::array();
  for (int l = 0; l < kLevelCount; ++l) {
    const LevelStats& ls = r.levels[size_t(l)];
    levels.push_back({ls.nodes, ls.vertices});
    errors.push_back(error_json(u.totals.level_error[size_t(l)]));
    level_cpu.push_back({{"stages", {ls.cpu_heights, ls.cpu_error, ls.cpu_surface, ls.cpu_encode}},
                         {"parts", ls.cpu_parts}});
  }
  const SurfaceTotals& t = r.surface;
  return {{"levels", levels},
          {"level_error", errors},
          {"leaf", error_json(u.totals.leaf)},
          {"cpu", {r.cpu_heights, r.cpu_error, r.cpu_surface, r.cpu_encode}},
          {"surface",
           {t.cpu_normals, t.cpu_albedo, t.cpu_splat, t.cpu_cones, t.normal_err_max_deg, t.normal_err_sum_deg,
            t.normal_samples, t.albedo_sq_err_sum, t.albedo_samples, t.albedo_hole_texels, t.albedo_alpha_mismatches,
            t.cone_exact_deg_sum, t.cone_encoded_deg_sum, t.cone_patches, t.cone_patches_never_cull}},
          {"cpu_parts", t.cpu_parts},  // absent in units of older tools: read as zeros
          {"level_cpu", level_cpu},    // ditto
          {"surface_nodes", {t.nodes, t.checked_nodes}},  // ditto
          {"void_fill_residual_m", r.void_fill_residual_m},
          {"window_samples", r.block_window_samples_max},
          {"input_bytes_read", r.input_bytes_read},
          {"family_levels", u.totals.family_finest_level}};  // absent in units of older tools: none
}

// Adds one unit's stats to the cook's (the sums cook_block and the window reads make, in unit
// order): the bytes its inputs read to `r`, the rest to `totals`.
void add_stats(const json& j, PyramidTotals& totals, CookReport& r) {
  for (int l = 0; l < kLevelCount; ++l) {
    totals.levels[size_t(l)].nodes += j.at("levels").at(l).at(0).get<uint32_t>();
    totals.levels[size_t(l)].vertices += j.at("levels").at(l).at(1).get<uint64_t>();
    totals.level_error[size_t(l)].add(error_of(j.at("level_error").at(l)));
    if (j.contains("level_cpu")) {
      LevelStats& ls = totals.levels[size_t(l)];
      const json& c = j.at("level_cpu").at(l);
      const auto stages = c.at("stages").get<std::vector<double>>();
      ls.cpu_heights += stages.at(0);
      ls.cpu_error += stages.at(1);
      ls.cpu_surface += stages.at(2);
      ls.cpu_encode += stages.at(3);
      const auto parts = c.at("parts").get<std::vector<double>>();
      for (size_t k = 0; k < std::min(parts.size(), ls.cpu_parts.size()); ++k) ls.cpu_parts[k] += parts[k];
    }
  }
  totals.leaf.add(error_of(j.at("leaf")));
  const json& c = j.at("cpu");
  totals.cpu_heights += c.at(0).get<double>();
  totals.cpu_error += c.at(1).get<double>();
  totals.cpu_surface += c.at(2).get<double>();
  totals.cpu_encode += c.at(3).get<double>();
  const json& s = j.at("surface");
  SurfaceTotals& t = totals.surface;
  t.cpu_normals += s.at(0).get<double>();
  t.cpu_albedo += s.at(1).get<double>();
  t.cpu_splat += s.at(2).get<double>();
  t.cpu_cones += s.at(3).get<double>();
  t.normal_err_max_deg = std::max(t.normal_err_max_deg, s.at(4).get<double>());
  t.normal_err_sum_deg += s.at(5).get<double>();
  t.normal_samples += s.at(6).get<uint64_t>();
  t.albedo_sq_err_sum += s.at(7).get<double>();
  t.albedo_samples += s.at(8).get<uint64_t>();
  t.albedo_hole_texels += s.at(9).get<uint64_t>();
  t.albedo_alpha_mismatches += s.at(10).get<uint64_t>();
  t.cone_exact_deg_sum += s.at(11).get<double>();
  t.cone_encoded_deg_sum += s.at(12).get<double>();
  t.cone_patches += s.at(13).get<uint64_t>();
  t.cone_patches_never_cull += s.at(14).get<uint64_t>();
  if (j.contains("surface_nodes")) {
    t.nodes += j.at("surface_nodes").at(0).get<uint64_t>();
    t.checked_nodes += j.at("surface_nodes").at(1).get<uint64_t>();
  }
  if (j.contains("cpu_parts")) {
    const auto parts = j.at("cpu_parts").get<std::vector<double>>();
    for (size_t k = 0; k < std::min(parts.size(), t.cpu_parts.size()); ++k) t.cpu_parts[k] += parts[k];
  }
  totals.void_fill_residual_m = std::max(totals.void_fill_residual_m, j.at("void_fill_residual_m").get<double>());
  totals.window_samples_max = std::max(totals.window_samples_max, j.at("window_samples").get<uint64_t>());
  if (j.contains("family_levels")) {
    const auto levels = j.at("family_levels").get<std::vector<int>>();
    for (size_t f = 0; f < levels.size(); ++f) totals.reach_family_level(f, levels[f]);
  }
  const auto bytes = j.at("input_bytes_read").get<std::vector<uint64_t>>();
  if (r.input_bytes_read.size() < bytes.size()) r.input_bytes_read.resize(bytes.size());
  for (size_t i = 0; i < bytes.size(); ++i) r.input_bytes_read[i] += bytes[i];
}

}  // namespace

NodeRecord unit_record(const uint8_t* p) {
  NodeRecord r;
  r.key = {load_u32(p), load_u32(p + 4), load_u32(p + 8)};
  r.child_mask = p[12];
  r.flags = p[13];
  r.height_offset = int32_t(load_u32(p + 16));
  r.min_height = int32_t(load_u32(p + 20));
  r.max_height = int32_t(load_u32(p + 24));
  r.geometric_error_m = detail::load_f32(p + 28);
  return r;
}
uint32_t unit_record_payload_size(const uint8_t* p) { return load_u32(p + 40); }

Status add_unit_stats(const UnitContents& c, uint32_t index, PyramidTotals& totals, CookReport& report) {
  try {
    add_stats(json::parse(c.stats), totals, report);
  } catch (const std::exception& e) {
    return Status::failure(Error::invalid_argument, fmt::format("unit {}: bad stats ({})", index, e.what()));
  }
  return Status::success();
}

bool crc_range(int fd, uint64_t from, uint64_t to, uint32_t& crc, const std::string& path) {
  std::vector<uint8_t> buf(size_t(std::min<uint64_t>(to - from, uint64_t(1) << 20)));
  for (uint64_t off = from; off < to;) {
    const size_t n = size_t(std::min<uint64_t>(buf.size(), to - off));
    if (!read_at(fd, buf.data(), n, off, path).ok()) return false;
    crc = crc_update(crc, buf.data(), n);
    off += n;
  }
  return true;
}

Status read_unit(const std::string& path, uint32_t index, const std::string& expected_unit_fp, UnitCheck check,
                 UnitContents& out) {
  auto bad = [](std::string why) { return Status::failure(Error::no_data, std::move(why)); };
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0)
    return Status::failure(Error::io_open,
                           errno == ENOENT ? "missing" : fmt::format("cannot open: {}", std::strerror(errno)));
  struct Closer { int fd; ~Closer() { ::close(fd); } } closer{fd};
  struct stat st {};
  ::fstat(fd, &st);
  const uint64_t size = uint64_t(st.st_size);
  if (size < kUnitHeader + 8) return bad(fmt::format("truncated ({} bytes)", size));
  uint8_t h[kUnitHeader];
  if (!read_at(fd, h, kUnitHeader, 0, path).ok() || std::memcmp(h, kUnitMagic, 8) != 0)
    return bad("not a unit file (bad magic)");
  if (load_u32(h + 8) != 1) return bad(fmt::format("unit file version {} (this tool reads 1)", load_u32(h + 8)));
  if (load_u32(h + 12) != index) return bad(fmt::format("holds unit {}", load_u32(h + 12)));
  out.plan_fp.assign(reinterpret_cast<const char*>(h + 16), 16);
  out.unit_fp.assign(reinterpret_cast<const char*>(h + 32), 16);
  const uint32_t count = load_u32(h + 48), stats_bytes = load_u32(h + 52);
  const uint64_t payload_bytes = load_u64(h + 56);
  const uint64_t expect = kUnitHeader + uint64_t(count) * kUnitRecord + stats_bytes + payload_bytes + 8;
  if (expect != size) return bad(fmt::format("truncated or padded: {} bytes, its header says {}", size, expect));
  // Table and stats in one read; the CRC of everything before the payloads.
  const uint64_t payload_start = kUnitHeader + uint64_t(count) * kUnitRecord + stats_bytes;
  std::vector<uint8_t> head(size_t(payload_start - kUnitHeader));
  uint8_t tail[8];
  if (!read_at(fd, head.data(), head.size(), kUnitHeader, path).ok() || !read_at(fd, tail, 8, size - 8, path).ok())
    return bad("unreadable");
  out.head_crc = crc_update(crc_update(0, h, kUnitHeader), head.data(), head.size());
  out.stored_crc = load_u32(tail);
  out.payload_start = payload_start;
  out.size = size;
  // The payloads' CRC, computed at most once, and only when needed.
  int damaged = -1;
  auto is_damaged = [&] {
    if (damaged < 0) {
      uint32_t crc = out.head_crc;
      damaged = !crc_range(fd, payload_start, size - 8, crc, path) || crc != out.stored_crc ? 1 : 0;
    }
    return damaged == 1;
  };
  auto fail = [&](std::string reason) {
    return bad(std::memcmp(tail + 4, kUnitEnd, 4) != 0 || is_damaged() ? std::string(kUnitDamaged) : std::move(reason));
  };
  if (std::memcmp(tail + 4, kUnitEnd, 4) != 0) return fail("");
  if (check == UnitCheck::full && is_damaged()) return fail("");
  if (out.unit_fp != expected_unit_fp)
    return fail(fmt::format("from another plan or stale inputs (unit fingerprint {}, the plan's {})", out.unit_fp,
                            expected_unit_fp));
  out.stats.assign(head.begin() + ptrdiff_t(count) * ptrdiff_t(kUnitRecord), head.end());
  if (!json::accept(out.stats)) return fail("bad stats");
  out.nodes.clear();
  out.nodes.reserve(count);
  uint64_t next = 0;  // payloads back to back, in table order
  for (uint32_t i = 0; i < count; ++i) {
    const uint8_t* p = &head[size_t(i) * kUnitRecord];
    NodeRecord r = unit_record(p);
    r.payload_offset = load_u64(p + 32);
    r.payload_size = unit_record_payload_size(p);
    if (r.payload_offset + r.payload_size > payload_bytes || r.key.level >= uint32_t(kLevelCount))
      return fail(fmt::format("node {} lies outside the unit's payloads", i));
    // The merge reads each unit's payloads in file order (one pass, its CRC computed as it copies).
    if (r.payload_offset != next || (i > 0 && !payload_order_less(out.nodes.back().first.key, r.key)))
      return fail(fmt::format("node {} is not in canonical order with its payload after the previous one's", i));
    next += r.payload_size;
    out.nodes.emplace_back(r, payload_start + r.payload_offset);
  }
  if (next != payload_bytes) return fail(fmt::format("the node payloads cover {} of {} payload bytes", next, payload_bytes));
  return Status::success();
}

Status write_unit(CookSession& s, const PlanFile& plan, uint32_t index, const std::string& work_dir) {
  const std::string path = unit_file(work_dir, index);
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path(), ec);
  // Host and pid in the staged name: the same unit re-run on another machine of a shared work dir
  // (a requeued array task) never writes into this one's file. What a killed run of a unit left is
  // removed by the next plan or merge (one listing of the units for all of them, not one per unit).
  const std::string temp = staging_path(path);
  NodeSpool spool;  // the unit's payloads as they come; the file gets them in canonical order
  TERRAIN_TRY(spool.open(temp + ".payloads"));
  UnitStats stats;
  std::vector<uint64_t> read_before;
  for (const MosaicSource::InputStat& in : s.source.inputs()) read_before.push_back(in.bytes_read);
  const NodeSink sink = [&](NodeResult& r) { return spool.add(r.record, r.payload); };
  TERRAIN_TRY(cook_unit_of_session(s, index, sink, stats.totals));
  report_blocks(s, stats.totals, stats.part);
  for (size_t i = 0; i < s.source.inputs().size(); ++i)
    stats.part.input_bytes_read.push_back(s.source.inputs()[i].bytes_read - (i < read_before.size() ? read_before[i] : 0));
  // The spool's entries in canonical order, their payloads copied behind the table.
  std::vector<NodeSpool::Entry> entries = spool.sorted_entries();
  const std::string stats_text = stats_json(stats).dump();
  uint64_t payload_bytes = 0;
  for (const auto& e : entries) payload_bytes += e.size;
  std::vector<uint8_t> head(kUnitHeader + entries.size() * kUnitRecord, 0);
  std::memcpy(head.data(), kUnitMagic, 8);
  store_u32(&head[8], 1);
  store_u32(&head[12], index);
  std::memcpy(&head[16], plan.fingerprint.data(), 16);
  std::memcpy(&head[32], plan.units[index].fingerprint.data(), 16);
  store_u32(&head[48], uint32_t(entries.size()));
  store_u32(&head[52], uint32_t(stats_text.size()));
  store_u64(&head[56], payload_bytes);
  uint64_t off = 0;
  for (size_t i = 0; i < entries.size(); ++i) {
    uint8_t* p = &head[kUnitHeader + i * kUnitRecord];
    const NodeRecord& r = entries[i].record;
    store_u32(p, r.key.level);
    store_u32(p + 4, r.key.x);
    store_u32(p + 8, r.key.y);
    p[12] = r.child_mask;
    p[13] = r.flags;
    store_u32(p + 16, uint32_t(r.height_offset));
    store_u32(p + 20, uint32_t(r.min_height));
    store_u32(p + 24, uint32_t(r.max_height));
    detail::store_f32(p + 28, r.geometric_error_m);
    store_u64(p + 32, off);
    store_u32(p + 40, entries[i].size);
    off += entries[i].size;
  }
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status::failure(Error::io_write, fmt::format("{}: {}", temp, std::strerror(errno)));
  uint32_t crc = crc_update(0, head.data(), head.size());
  crc = crc_update(crc, reinterpret_cast<const uint8_t*>(stats_text.data()), stats_text.size());
  Status st = write_all(fd, head.data(), head.size(), temp);
  if (st.ok()) st = write_all(fd, reinterpret_cast<const uint8_t*>(stats_text.data()), stats_text.size(), temp);
  std::vector<uint8_t> buf;
  for (size_t i = 0; st.ok() && i < entries.size(); ++i) {
    st = spool.read(entries[i], buf);
    if (st.ok()) {
      crc = crc_update(crc, buf.data(), buf.size());
      st = write_all(fd, buf.data(), buf.size(), temp);
    }
  }
  uint8_t tail[8];
  store_u32(tail, crc);
  std::memcpy(tail + 4, kUnitEnd, 4);
  if (st.ok()) st = write_all(fd, tail, 8, temp);
  if (st.ok() && ::fsync(fd) != 0) st = Status::failure(Error::io_write, fmt::format("{}: fsync: {}", temp, std::strerror(errno)));
  ::close(fd);
  if (st.ok() && ::rename(temp.c_str(), path.c_str()) != 0)
    st = Status::failure(Error::io_rename, fmt::format("{}: {}", path, std::strerror(errno)));
  if (!st.ok()) ::unlink(temp.c_str());
  return st;
}

Status check_unit_file(const std::string& work_dir, const PlanFile& plan, uint32_t index) {
  UnitContents c;
  return read_unit(unit_file(work_dir, index), index, plan.units[index].fingerprint, UnitCheck::full, c);
}

Status check_unit_file_head(const std::string& work_dir, const PlanFile& plan, uint32_t index) {
  UnitContents c;
  return read_unit(unit_file(work_dir, index), index, plan.units[index].fingerprint, UnitCheck::head, c);
}

}  // namespace terrain::cook
