// terrain-format-bench --sections: zstd level and trained-dictionary choices for the surface
// sections (normals, albedo, splat, cones) of cooked archives, against their decode speed (issue 17).
// Per archive and section: the raw sections of up to --max-nodes nodes (spread over the archive); a
// quarter of them (every 4th) trains the dictionaries, the other three quarters are measured:
// stored bytes, compression CPU per node, decompression MB/s of raw output (fastest of --runs).
#include "section_bench.h"

#include <zdict.h>
#include <zstd.h>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/cpu_clock.h"

namespace terrain::bench {
namespace {

struct Config {
  std::string name;
  int level = 6;
  size_t dict_bytes = 0;  // 0: no dictionary
};

struct Result {
  size_t stored = 0, raw = 0, dict = 0;
  double enc_ms_per_node = 0, dec_mb_s = 0;
};

Result measure(const std::vector<std::vector<uint8_t>>& train, const std::vector<std::vector<uint8_t>>& test,
               const Config& c, int runs, bool& ok) {
  Result r;
  std::vector<uint8_t> dict;
  if (c.dict_bytes) {
    std::vector<uint8_t> samples;
    std::vector<size_t> sizes;
    for (const auto& s : train) samples.insert(samples.end(), s.begin(), s.end()), sizes.push_back(s.size());
    dict.resize(c.dict_bytes);
    const size_t n =
        ZDICT_trainFromBuffer(dict.data(), dict.size(), samples.data(), sizes.data(), unsigned(sizes.size()));
    if (ZDICT_isError(n)) {
      fmt::print(stderr, "dictionary training failed: {}\n", ZDICT_getErrorName(n));
      ok = false;
      return r;
    }
    dict.resize(n);
  }
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  ZSTD_DCtx* dctx = ZSTD_createDCtx();
  ZSTD_CDict* cdict = dict.empty() ? nullptr : ZSTD_createCDict(dict.data(), dict.size(), c.level);
  ZSTD_DDict* ddict = dict.empty() ? nullptr : ZSTD_createDDict(dict.data(), dict.size());
  std::vector<std::vector<uint8_t>> packed(test.size());
  const double t0 = process_cpu_seconds();
  for (size_t i = 0; i < test.size(); ++i) {
    packed[i].resize(ZSTD_compressBound(test[i].size()));
    const size_t n =
        cdict
            ? ZSTD_compress_usingCDict(cctx, packed[i].data(), packed[i].size(), test[i].data(), test[i].size(), cdict)
            : ZSTD_compressCCtx(cctx, packed[i].data(), packed[i].size(), test[i].data(), test[i].size(), c.level);
    if (ZSTD_isError(n)) {
      ok = false;
      break;
    }
    packed[i].resize(n);
    r.stored += n;
    r.raw += test[i].size();
  }
  r.enc_ms_per_node = (process_cpu_seconds() - t0) * 1e3 / double(std::max<size_t>(1, test.size()));
  std::vector<uint8_t> out;
  double best = 1e30;
  for (int k = 0; k < runs && ok; ++k) {
    const double t1 = process_cpu_seconds();
    for (size_t i = 0; i < test.size(); ++i) {
      out.resize(test[i].size());
      const size_t n =
          ddict ? ZSTD_decompress_usingDDict(dctx, out.data(), out.size(), packed[i].data(), packed[i].size(), ddict)
                : ZSTD_decompressDCtx(dctx, out.data(), out.size(), packed[i].data(), packed[i].size());
      if (ZSTD_isError(n) || n != test[i].size() || !std::equal(out.begin(), out.end(), test[i].begin())) ok = false;
    }
    best = std::min(best, process_cpu_seconds() - t1);
  }
  r.dec_mb_s = best > 0 ? double(r.raw) / best / 1e6 : 0;
  r.dict = dict.size();
  ZSTD_freeCDict(cdict);
  ZSTD_freeDDict(ddict);
  ZSTD_freeCCtx(cctx);
  ZSTD_freeDCtx(dctx);
  return r;
}

}  // namespace

int sections_main(const std::vector<std::string>& archives, size_t max_nodes, int runs) {
  const char* names[4] = {"normals", "albedo", "splat", "cones"};
  const std::vector<Config> configs = {{"zstd 1", 1, 0},
                                       {"zstd 3", 3, 0},
                                       {"zstd 4", 4, 0},
                                       {"zstd 5", 5, 0},
                                       {"zstd 6 (cooker)", 6, 0},
                                       {"zstd 9", 9, 0},
                                       {"zstd 19", 19, 0},
                                       {"6 + dict 16K", 6, 16 << 10},
                                       {"6 + dict 64K", 6, 64 << 10},
                                       {"19 + dict 64K", 19, 64 << 10}};
  fmt::print(
      "terrain-format-bench --sections: surface sections of cooked archives; every 4th node trains the "
      "dictionaries, the other nodes are measured (dictionary bytes not included: one per archive); "
      "dec MB/s = raw bytes out per CPU second, fastest of {} runs\n\n",
      runs);
  fmt::print("{:<20} {:<8} {:<16} {:>6} {:>11} {:>7} {:>7} {:>9} {:>9}\n", "archive", "section", "config", "nodes",
             "stored B", "dict B", "x zstd6", "enc ms/n", "dec MB/s");
  bool all_ok = true;
  for (const std::string& path : archives) {
    ArchiveReader reader;
    if (Status st = reader.open(path); !st.ok()) {
      fmt::print(stderr, "terrain-format-bench: {}: {}\n", path, st.to_string());
      return 1;
    }
    const size_t total = reader.nodes().size();
    const size_t stride = std::max<size_t>(1, total / std::max<size_t>(1, max_nodes));
    std::vector<std::vector<uint8_t>> train[4], test[4];
    NodeData node;
    size_t picked = 0;
    for (size_t i = 0; i < total; i += stride, ++picked) {
      if (Status st = reader.decode_node(i, node, kSectionNormals | kSectionAlbedo | kSectionSplat | kSectionCones);
          !st.ok()) {
        fmt::print(stderr, "terrain-format-bench: {} node {}: {}\n", path, i, st.to_string());
        return 1;
      }
      const std::span<const uint8_t> raw[4] = {{node.normals_bc3.data(), node.normals_bc3.size()},
                                               {node.albedo_bc1.data(), node.albedo_bc1.size()},
                                               {node.splat.data(), node.splat.size()},
                                               {node.cones_bc3.data(), node.cones_bc3.size()}};
      for (int s = 0; s < 4; ++s) (picked % 4 == 0 ? train[s] : test[s]).emplace_back(raw[s].begin(), raw[s].end());
    }
    const std::string label = std::filesystem::path(path).stem().string();
    for (int s = 0; s < 4; ++s) {
      Result base;
      std::vector<Result> rows;
      for (const Config& c : configs) {
        bool ok = true;
        rows.push_back(measure(train[s], test[s], c, runs, ok));
        all_ok = all_ok && ok;
        if (c.level == 6 && c.dict_bytes == 0) base = rows.back();
      }
      for (size_t k = 0; k < configs.size(); ++k)
        fmt::print("{:<20} {:<8} {:<16} {:>6} {:>11} {:>7} {:>7.3f} {:>9.4f} {:>9.0f}\n", label, names[s],
                   configs[k].name, test[s].size(), rows[k].stored, rows[k].dict,
                   double(rows[k].stored) / double(std::max<size_t>(1, base.stored)), rows[k].enc_ms_per_node,
                   rows[k].dec_mb_s);
    }
  }
  if (!all_ok) fmt::print(stderr, "terrain-format-bench: a round trip failed\n");
  return all_ok ? 0 : 1;
}

}  // namespace terrain::bench
