// terrain-format-bench: height codec (hierarchical predictor + zstd) against plain zstd on real
// R16 tiles. Per dataset: bytes, ratios, encode ms per tile, decode MB/s next to zstd's own
// decompression of plain-zstd tiles and memcpy; every decode is
// checked against the input before a number is printed. Timings: fastest of --runs passes, and
// "paired": plain zstd -19 and the codec decoded back to back in each run (median of the per-run
// ratios), the number to quote on a shared machine.
// Peer coder: JPEG-LS lossless (CharLS, when built with it) on the same tiles, timed and checked
// the same way. --dump-pgm writes every tile as a 16-bit PGM for external coders
// (tools/peer_lossless.sh runs JPEG-XL's cjxl over them). --chart FILE.svg draws bits per sample
// against decode MB/s per dataset (bench_chart.h).
#include <zip.h>
#include <zlib.h>
#include <zstd.h>

#include <CLI/CLI.hpp>
#include <OpenImageIO/imageio.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/core.h>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "section_bench.h"
#include "terrain/archive_reader.h"
#include "terrain/archive_writer.h"
#include "terrain/format.h"
#include "terrain/height_codec.h"
#include "bench_chart.h"
#include "bench_paths.h"

#if TERRAIN_HAVE_CHARLS
#include <charls/charls.h>
#endif

namespace {

using Clock = std::chrono::steady_clock;
using terrain::kHeightCount;
using terrain::kHeightSamples;
constexpr size_t kTileBytes = 2 * size_t(kHeightCount);

struct Tile {
  std::vector<uint16_t> r16;
};
struct Dataset {
  std::string name, source;
  int step_log2 = 0;        // step used: max(range step, floor); -1 for archive nodes
  int range_step_log2 = 0;  // smallest step whose 16 bits span every window's range
  std::vector<Tile> tiles;
};

// SRTM HGT (big-endian int16, square, rows north to south), plain, .zip (first .hgt member) or .gz,
// as metres; -32768 voids -> NaN.
bool read_hgt(const std::string& path, std::vector<float>& out, int& w, int& h) {
  std::vector<uint8_t> bytes;
  auto ends = [&](const char* e) { return path.size() >= std::strlen(e) && path.compare(path.size() - std::strlen(e), std::string::npos, e) == 0; };
  if (ends(".zip")) {
    int err = 0;
    zip_t* z = zip_open(path.c_str(), ZIP_RDONLY, &err);
    if (!z) return false;
    for (zip_int64_t i = 0; i < zip_get_num_entries(z, 0) && bytes.empty(); ++i) {
      zip_stat_t st;
      if (zip_stat_index(z, zip_uint64_t(i), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE)) continue;
      const std::string n = st.name ? st.name : "";
      if (n.size() < 4 || n.compare(n.size() - 4, 4, ".hgt") != 0) continue;
      zip_file_t* f = zip_fopen_index(z, zip_uint64_t(i), 0);
      if (!f) break;
      bytes.resize(size_t(st.size));
      if (zip_fread(f, bytes.data(), st.size) != zip_int64_t(st.size)) bytes.clear();
      zip_fclose(f);
    }
    zip_close(z);
  } else {
    gzFile f = gzopen(path.c_str(), "rb");  // also reads uncompressed files
    if (!f) return false;
    uint8_t buf[1 << 16];
    int n = 0;
    while ((n = gzread(f, buf, sizeof(buf))) > 0) bytes.insert(bytes.end(), buf, buf + n);
    gzclose(f);
  }
  const size_t count = bytes.size() / 2;
  const int side = int(std::lround(std::sqrt(double(count))));
  if (side < 2 || size_t(side) * size_t(side) * 2 != bytes.size()) return false;
  w = h = side;
  out.resize(count);
  for (size_t k = 0; k < count; ++k) {
    const int16_t v = int16_t(uint16_t(bytes[2 * k] << 8 | bytes[2 * k + 1]));
    out[k] = v == -32768 ? NAN : float(v);
  }
  return true;
}

// Reads band 0 of a raster as metres (value * scale); nodata -> NaN. Integer rasters are read in
// their own type so nodata compares exactly.
bool read_raster(const std::string& path, double scale, std::optional<double> nodata, std::vector<float>& out, int& w, int& h) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return false;
  const OIIO::ImageSpec& spec = in->spec();
  w = spec.width;
  h = spec.height;
  const size_t count = size_t(w) * size_t(h), nc = size_t(spec.nchannels);
  std::vector<double> values(count);
  auto fetch = [&](auto tag, OIIO::TypeDesc type) {
    std::vector<decltype(tag)> all(count * nc);
    if (!in->read_image(0, 0, 0, spec.nchannels, type, all.data())) return false;
    for (size_t k = 0; k < count; ++k) values[k] = double(all[k * nc]);
    return true;
  };
  bool ok = false;
  if (spec.format == OIIO::TypeDesc::INT16) ok = fetch(int16_t{}, OIIO::TypeDesc::INT16);
  else if (spec.format == OIIO::TypeDesc::UINT16) ok = fetch(uint16_t{}, OIIO::TypeDesc::UINT16);
  else if (spec.format == OIIO::TypeDesc::UINT8) ok = fetch(uint8_t{}, OIIO::TypeDesc::UINT8);
  else ok = fetch(float{}, OIIO::TypeDesc::FLOAT);
  if (!ok) return false;
  out.resize(count);
  for (size_t k = 0; k < count; ++k)
    out[k] = (nodata && values[k] == *nodata) ? NAN : float(values[k] * scale);
  return true;
}

// 129x129 windows on a 128 stride, rows flipped so row 0 is south; windows with nodata skipped;
// at most max_tiles of them, spread evenly over the raster. Quantized as the cooker does for one
// level: units of 2^-10 m; the level's step 2^s is the larger of the smallest step whose 16 bits
// span every window's range and the floor 2^step_floor (the cooker's tolerance/32 floor: 4 at the
// default 0.5 m); heights rounded to multiples of the step, offset = window minimum.
Dataset make_tiles(const std::string& name, const std::string& source, const std::vector<float>& m, int w, int h, size_t max_tiles,
                   int step_floor) {
  Dataset d{name, source, 0, 0, {}};
  std::vector<std::vector<double>> windows;
  for (int ty = 0; ty + kHeightSamples <= h; ty += 128)
    for (int tx = 0; tx + kHeightSamples <= w; tx += 128) {
      std::vector<double> u(static_cast<size_t>(kHeightCount));
      bool ok = true;
      for (int j = 0; j < kHeightSamples && ok; ++j)
        for (int i = 0; i < kHeightSamples; ++i) {
          const float v = m[size_t(ty + (kHeightSamples - 1 - j)) * size_t(w) + size_t(tx + i)];
          if (!std::isfinite(v)) {
            ok = false;
            break;
          }
          u[size_t(j * kHeightSamples + i)] = double(v) * 1024.0;
        }
      if (ok) windows.push_back(std::move(u));
    }
  if (windows.size() > max_tiles) {  // even spread, deterministic
    std::vector<std::vector<double>> keep;
    for (size_t k = 0; k < max_tiles; ++k) keep.push_back(std::move(windows[k * windows.size() / max_tiles]));
    windows.swap(keep);
  }
  double max_range = 0;
  for (const auto& u : windows) {
    const auto [lo, hi] = std::minmax_element(u.begin(), u.end());
    max_range = std::max(max_range, *hi - *lo);
  }
  while (std::ldexp(65535.0, d.range_step_log2) < max_range + std::ldexp(1.0, d.range_step_log2)) ++d.range_step_log2;
  d.step_log2 = std::max(d.range_step_log2, step_floor);
  const double scale = std::ldexp(1.0, -d.step_log2);
  for (const auto& u : windows) {
    std::vector<int64_t> q(u.size());
    for (size_t k = 0; k < u.size(); ++k) q[k] = int64_t(std::floor(u[k] * scale + 0.5));
    const int64_t lo = *std::min_element(q.begin(), q.end());
    Tile t;
    t.r16.resize(size_t(kHeightCount));
    for (size_t k = 0; k < q.size(); ++k) t.r16[k] = uint16_t(std::min<int64_t>(65535, q[k] - lo));
    d.tiles.push_back(std::move(t));
  }
  return d;
}

std::vector<uint8_t> le_bytes(const std::vector<uint16_t>& r16) {
  std::vector<uint8_t> b(kTileBytes);
  for (size_t k = 0; k < r16.size(); ++k) {
    b[2 * k] = uint8_t(r16[k]);
    b[2 * k + 1] = uint8_t(r16[k] >> 8);
  }
  return b;
}

std::vector<uint8_t> zstd_compress(const uint8_t* src, size_t n, int level) {
  std::vector<uint8_t> out(ZSTD_compressBound(n));
  const size_t c = ZSTD_compress(out.data(), out.size(), src, n, level);
  out.resize(ZSTD_isError(c) ? 0 : c);
  return out;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// Seconds of the fastest of `runs` passes of fn() after one warm-up pass (as zstd's benchmark
// does: the machine is shared, and the fastest run is the one least disturbed by others).
// The median is reported next to it.
struct Timing {
  double best = 0, median = 0;  // seconds
};
template <typename F>
Timing time_runs(int runs, F&& fn) {
  fn();
  std::vector<double> t;
  for (int r = 0; r < runs; ++r) {
    const auto a = Clock::now();
    fn();
    t.push_back(std::chrono::duration<double>(Clock::now() - a).count());
  }
  return {*std::min_element(t.begin(), t.end()), median(t)};
}

// Paired timing: each run decodes every tile with plain zstd -19 (zpass) and then with the other
// coder (ppass), back to back, so load from other processes hits both alike.
struct Paired {
  double pct = 0, zstd19_mbps = 0, mbps = 0;  // median of per-run speed ratios; median MB/s of each
};
template <typename Z, typename P>
Paired time_paired(int runs, double mb, Z&& zpass, P&& ppass) {
  zpass();
  ppass();
  std::vector<double> tz, tp, ratio;
  for (int r = 0; r < runs; ++r) {
    const auto a = Clock::now();
    zpass();
    const auto b = Clock::now();
    ppass();
    const auto c = Clock::now();
    tz.push_back(std::chrono::duration<double>(b - a).count());
    tp.push_back(std::chrono::duration<double>(c - b).count());
    ratio.push_back(tz.back() / tp.back());
  }
  return {100.0 * median(ratio), mb / median(tz), mb / median(tp)};
}

// JPEG-LS lossless (CharLS) of one tile: one component, 129x129, the fewest bits per sample that
// hold the tile's largest value (9..16; JPEG-LS codes against MAXVAL = 2^bits - 1), no optional
// marker segments. Empty on error.
#if TERRAIN_HAVE_CHARLS
std::vector<uint8_t> charls_encode(const std::vector<uint16_t>& r16) {
  const uint16_t hi = *std::max_element(r16.begin(), r16.end());
  int bits = 9;  // 2..8 bits would take one byte per sample
  while (bits < 16 && (uint32_t(hi) >> bits) != 0) ++bits;
  try {
    charls::jpegls_encoder enc;
    enc.frame_info({uint32_t(kHeightSamples), uint32_t(kHeightSamples), bits, 1})
        .near_lossless(0)
        .encoding_options(charls::encoding_options::none);
    std::vector<uint8_t> out(enc.estimated_destination_size());
    enc.destination(out);
    out.resize(enc.encode(r16.data(), r16.size() * sizeof(uint16_t)));
    return out;
  } catch (const std::exception& e) {
    fmt::print(stderr, "CharLS encode: {}\n", e.what());
    return {};
  }
}
bool charls_decode(const std::vector<uint8_t>& src, std::vector<uint16_t>& out) {
  try {
    charls::jpegls_decoder dec(src.data(), src.size(), true);
    const charls::frame_info f = dec.frame_info();
    if (f.width != uint32_t(kHeightSamples) || f.height != uint32_t(kHeightSamples) || f.component_count != 1 || f.bits_per_sample <= 8)
      return false;
    dec.decode(out.data(), out.size() * sizeof(uint16_t));
    return true;
  } catch (const std::exception&) {
    return false;
  }
}
#endif

struct PeerResult {
  bool measured = false;
  uint64_t bytes = 0;
  double encode_ms_per_tile = 0;
  double decode_mbps = 0, decode_mbps_median = 0;
  Paired paired;
};

struct LevelResult {
  int level = 0;
  uint64_t bytes = 0;
  double encode_ms_per_tile = 0;
  double decode_mbps = 0, decode_mbps_median = 0;
  // Paired: each run decodes every tile with plain zstd -19 and then with the codec, back to back,
  // so load from other processes hits both alike; the median of the per-run speed ratios.
  double paired_pct = 0, paired_zstd19_mbps = 0, paired_mbps = 0;
};
struct Result {
  std::string name, source;
  size_t tiles = 0;
  int step_log2 = 0, range_step_log2 = 0;
  uint64_t raw = 0, zstd19 = 0, zstd_default = 0;
  double zstd19_decode_mbps = 0, zstd_default_decode_mbps = 0, memcpy_mbps = 0;
  double zstd19_decode_mbps_median = 0;
  std::vector<LevelResult> levels;
  PeerResult charls;  // JPEG-LS lossless
};

bool run_dataset(const Dataset& d, const std::vector<int>& levels, int default_level, int runs, Result& res) {
  res.name = d.name;
  res.source = d.source;
  res.tiles = d.tiles.size();
  res.step_log2 = d.step_log2;
  res.range_step_log2 = d.range_step_log2;
  res.raw = d.tiles.size() * kTileBytes;
  const double mb = double(res.raw) / 1e6;
  std::vector<std::vector<uint8_t>> raw;
  for (const Tile& t : d.tiles) raw.push_back(le_bytes(t.r16));
  std::vector<uint8_t> out(kTileBytes), out2(kTileBytes);
  ZSTD_DCtx* dctx = ZSTD_createDCtx();
  std::vector<std::vector<uint8_t>> z19;
  auto plain = [&](int level, uint64_t& bytes, double& mbps, double& mbps_median) {
    std::vector<std::vector<uint8_t>> z;
    bytes = 0;
    for (const auto& r : raw) {
      z.push_back(zstd_compress(r.data(), r.size(), level));
      bytes += z.back().size();
    }
    for (size_t i = 0; i < z.size(); ++i) {  // verify
      const size_t n = ZSTD_decompressDCtx(dctx, out.data(), out.size(), z[i].data(), z[i].size());
      if (n != kTileBytes || std::memcmp(out.data(), raw[i].data(), kTileBytes) != 0) return false;
    }
    const Timing t = time_runs(runs, [&] {
      for (const auto& zi : z) ZSTD_decompressDCtx(dctx, out.data(), out.size(), zi.data(), zi.size());
    });
    mbps = mb / t.best;
    mbps_median = mb / t.median;
    if (level == 19) z19 = std::move(z);
    return true;
  };
  double unused = 0;
  if (!plain(19, res.zstd19, res.zstd19_decode_mbps, res.zstd19_decode_mbps_median) ||
      !plain(default_level, res.zstd_default, res.zstd_default_decode_mbps, unused)) {
    ZSTD_freeDCtx(dctx);
    return false;
  }
  ZSTD_freeDCtx(dctx);
  res.memcpy_mbps = mb / time_runs(runs, [&] {
                          for (const auto& r : raw) std::memcpy(out.data(), r.data(), kTileBytes);
                          asm volatile("" : : "r"(out.data()) : "memory");
                        }).best;
  auto data = std::make_unique<terrain::NodeData>();  // other sections stay zero (tiny, not counted)
  for (int level : levels) {
    LevelResult lr;
    lr.level = level;
    std::vector<std::vector<uint8_t>> payloads(d.tiles.size());
    terrain::PayloadOptions opt;
    opt.zstd_level = level;
    bool encoded = true;
    const Timing enc = time_runs(3, [&] {
      for (size_t i = 0; i < d.tiles.size(); ++i) {
        std::copy(d.tiles[i].r16.begin(), d.tiles[i].r16.end(), data->heights.begin());
        encoded &= terrain::encode_node_payload(*data, opt, payloads[i]).ok();
      }
    });
    if (!encoded) return false;
    lr.encode_ms_per_tile = 1e3 * enc.best / double(d.tiles.size());
    for (size_t i = 0; i < d.tiles.size(); ++i) {
      // Only the height section counts: its stored size is at table entry 0, bytes 4..7.
      const uint8_t* e = payloads[i].data() + 4;
      lr.bytes += uint64_t(e[4]) | (uint64_t(e[5]) << 8) | (uint64_t(e[6]) << 16) | (uint64_t(e[7]) << 24);
      if (!terrain::decode_node_payload(payloads[i], terrain::kSectionHeights, *data).ok()) return false;
      if (!std::equal(d.tiles[i].r16.begin(), d.tiles[i].r16.end(), data->heights.begin())) {
        fmt::print(stderr, "{}: level {}: tile {} decodes wrong\n", d.name, level, i);
        return false;
      }
    }
    const Timing t = time_runs(runs, [&] {
      for (const auto& p : payloads) (void)terrain::decode_node_payload(p, terrain::kSectionHeights, *data);
    });
    lr.decode_mbps = mb / t.best;
    lr.decode_mbps_median = mb / t.median;
    {
      ZSTD_DCtx* pctx = ZSTD_createDCtx();
      const Paired p = time_paired(
          runs, mb, [&] { for (const auto& zi : z19) ZSTD_decompressDCtx(pctx, out.data(), out.size(), zi.data(), zi.size()); },
          [&] { for (const auto& pl : payloads) (void)terrain::decode_node_payload(pl, terrain::kSectionHeights, *data); });
      ZSTD_freeDCtx(pctx);
      lr.paired_pct = p.pct;
      lr.paired_zstd19_mbps = p.zstd19_mbps;
      lr.paired_mbps = p.mbps;
    }
    res.levels.push_back(lr);
  }
#if TERRAIN_HAVE_CHARLS
  {
    PeerResult& pr = res.charls;
    std::vector<std::vector<uint8_t>> coded(d.tiles.size());
    bool encoded = true;
    const Timing enc = time_runs(1, [&] {
      for (size_t i = 0; i < d.tiles.size(); ++i) {
        coded[i] = charls_encode(d.tiles[i].r16);
        encoded &= !coded[i].empty();
      }
    });
    if (!encoded) return false;
    pr.encode_ms_per_tile = 1e3 * enc.best / double(d.tiles.size());
    std::vector<uint16_t> dec(static_cast<size_t>(kHeightCount));
    for (size_t i = 0; i < d.tiles.size(); ++i) {
      pr.bytes += coded[i].size();
      std::fill(dec.begin(), dec.end(), uint16_t(0));
      if (!charls_decode(coded[i], dec) || dec != d.tiles[i].r16) {
        fmt::print(stderr, "{}: JPEG-LS: tile {} decodes wrong\n", d.name, i);
        return false;
      }
    }
    auto cpass = [&] {
      for (const auto& c : coded) (void)charls_decode(c, dec);
    };
    const Timing t = time_runs(runs, cpass);
    pr.decode_mbps = mb / t.best;
    pr.decode_mbps_median = mb / t.median;
    ZSTD_DCtx* pctx = ZSTD_createDCtx();
    pr.paired = time_paired(
        runs, mb, [&] { for (const auto& zi : z19) ZSTD_decompressDCtx(pctx, out.data(), out.size(), zi.data(), zi.size()); }, cpass);
    ZSTD_freeDCtx(pctx);
    pr.measured = true;
  }
#endif
  return true;
}

// Every tile as a binary 16-bit PGM (P5, maxval 65535, big-endian samples, rows in memory order:
// row 0 = south first, the order every coder here scans): DIR/<dataset>/<index>.pgm.
bool dump_pgm(const std::string& dir, const Dataset& d) {
  const std::filesystem::path sub = std::filesystem::path(dir) / d.name;
  std::error_code ec;
  std::filesystem::create_directories(sub, ec);
  if (ec) {
    fmt::print(stderr, "--dump-pgm: cannot create {}: {}\n", sub.string(), ec.message());
    return false;
  }
  const std::string header = fmt::format("P5\n{} {}\n65535\n", kHeightSamples, kHeightSamples);
  std::vector<char> body(kTileBytes);
  for (size_t i = 0; i < d.tiles.size(); ++i) {
    for (size_t k = 0; k < d.tiles[i].r16.size(); ++k) {
      body[2 * k] = char(d.tiles[i].r16[k] >> 8);
      body[2 * k + 1] = char(d.tiles[i].r16[k] & 0xff);
    }
    const std::filesystem::path file = sub / fmt::format("{:05}.pgm", i);
    std::ofstream f(file, std::ios::binary | std::ios::trunc);
    f.write(header.data(), std::streamsize(header.size()));
    f.write(body.data(), std::streamsize(body.size()));
    if (!f.flush()) {
      fmt::print(stderr, "--dump-pgm: cannot write {}\n", file.string());
      return false;
    }
  }
  return true;
}

// Byte counts of the in-process coders next to the PGMs, for tools/peer_lossless.sh.
bool write_bytes_file(const std::string& dir, const Result& r) {
  const std::filesystem::path file = std::filesystem::path(dir) / r.name / "bench_bytes.tsv";
  std::ofstream f(file, std::ios::trunc);
  f << "tiles\t" << r.tiles << "\nraw\t" << r.raw << "\nzstd19\t" << r.zstd19 << "\n";
  for (const LevelResult& l : r.levels) f << "predictor_zstd" << l.level << "\t" << l.bytes << "\n";
  if (r.charls.measured) f << "jpegls_charls\t" << r.charls.bytes << "\n";
  if (!f.flush()) {
    fmt::print(stderr, "--dump-pgm: cannot write {}\n", file.string());
    return false;
  }
  return true;
}

// --chart: a panel per dataset, stored bits per height sample against decode MB/s (fastest of
// `runs`): predictor+zstd across its zstd levels as a line, the other coders measured in this run
// (plain zstd, JPEG-LS, memcpy of the raw R16 tiles) as named points.
terrain::chart::Chart format_chart(const std::vector<Result>& results, int default_level, int runs) {
  namespace ch = terrain::chart;
  ch::Chart c;
  c.title = "terrain-format-bench: height tiles, stored size against decode speed";
  c.note = fmt::format("129 x 129 R16 height tiles of each DEM (lossless); bits per sample = stored bytes x 8 / samples; "
                       "decode MB/s of R16 output, fastest of {} runs (one thread). JPEG-XL is measured outside this "
                       "program (tools/peer_lossless.sh) and is not drawn. {}",
                       runs, ch::machine_note());
  c.columns = 3;
  c.panel_width = 280;
  c.panel_height = 200;
  for (const Result& r : results) {
    const double samples = double(r.tiles) * double(kHeightCount);
    const auto bits = [&](uint64_t bytes) { return 8.0 * double(bytes) / samples; };
    ch::Panel p;
    p.title = fmt::format("{} ({} tiles)", r.name, r.tiles);
    p.x = {"bits per sample", ch::Scale::linear, true};
    p.y = {"decode, MB/s", ch::Scale::log10};
    ch::Series s{"predictor+zstd (labels: zstd level)", {}};
    s.label_points = true;
    for (const LevelResult& l : r.levels) s.points.push_back({bits(l.bytes), l.decode_mbps, fmt::format("-{}", l.level)});
    p.series.push_back(s);
    p.named.push_back({"zstd -19", bits(r.zstd19), r.zstd19_decode_mbps});
    if (default_level != 19) p.named.push_back({fmt::format("zstd -{}", default_level), bits(r.zstd_default), r.zstd_default_decode_mbps});
    if (r.charls.measured) p.named.push_back({"JPEG-LS", bits(r.charls.bytes), r.charls.decode_mbps});
    p.named.push_back({"memcpy", bits(r.raw), r.memcpy_mbps});
    c.panels.push_back(std::move(p));
  }
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"terrain-format-bench: height codec vs plain zstd on real R16 tiles"};
  std::string data_dir = terrain::bench_data_dir();
  if (const char* env = std::getenv("TERRAIN_DATA_DIR"); env && *env) data_dir = env;
  std::vector<std::string> archives;
  std::vector<int> levels = {1, 3, 6, 9, 19};
  int default_level = 9;
  int runs = 15;
  size_t max_tiles = 400;
  int step_floor = 4;
  bool json = false, archives_only = false;
  std::string dump_dir;
  app.add_option("--data", data_dir, "folder of the shared real DEMs")->capture_default_str();
  app.add_option("--archive", archives, "also benchmark the height grids of every node of these cooked archives");
  app.add_option("--levels", levels, "zstd levels for predictor+zstd")->capture_default_str();
  app.add_option("--default-level", default_level, "zstd level of the plain-zstd speed baseline")->capture_default_str();
  app.add_option("--runs", runs, "timed runs per measurement (the fastest is reported)")->capture_default_str()->check(CLI::Range(1, 1000));
  app.add_option("--max-tiles", max_tiles, "tiles per dataset (spread evenly over the DEM)")->capture_default_str();
  app.add_option("--step-floor", step_floor,
                 "smallest quantization step_log2 for DEM windows (the cooker's floor: largest power of two <= tolerance/32 "
                 "in 2^-10 m units, 4 at 0.5 m); 0 = range-driven step only")
      ->capture_default_str()
      ->check(CLI::Range(0, 14));
  app.add_flag("--archives-only", archives_only, "skip the shared DEMs: only the --archive datasets");
  app.add_option("--dump-pgm", dump_dir,
                 "write every tile as a 16-bit PGM to DIR/<dataset>/NNNNN.pgm (plus bench_bytes.tsv) for external coders "
                 "(tools/peer_lossless.sh)");
  app.add_flag("--json", json, "print JSON instead of the table");
  std::string chart;
  app.add_option("--chart", chart, "also write an SVG chart: bits per sample against decode MB/s per dataset");
  std::vector<std::string> section_archives;
  app.add_option("--sections", section_archives,
                 "instead: zstd levels and trained dictionaries for the normals, albedo, splat and cones sections of "
                 "these cooked archives (bytes, encode ms per node, decode MB/s; --max-tiles nodes, --runs)")
      ->check(CLI::ExistingFile);
  CLI11_PARSE(app, argc, argv);
  if (!section_archives.empty()) return terrain::bench::sections_main(section_archives, max_tiles, runs);

  std::vector<Dataset> sets;
  struct Source {
    const char* name;
    const char* file;
    double scale;
    std::optional<double> nodata;
    bool hgt = false;
  };
  const Source sources[] = {
      {"kilauea", "kilauea_utm5n.tif", 1.0, -32768.0},  {"oetztal", "srtm_oetztal.tif", 1.0, std::nullopt},
      {"slovenia", "slovenia_TM1_564_146.tif", 1.0, std::nullopt}, {"tahoe", "tahoe_lidar_bareearth.tif", 1.0, std::nullopt},
      {"tahoe_hh", "tahoe_lidar_highesthit.tif", 1.0, std::nullopt}, {"puget", "ps_height_1k.png", 0.1, std::nullopt},
      {"kauai_srtm3", "N22W160.hgt.zip", 1.0, std::nullopt, true},   {"hilo_srtm3", "N19W155.hgt.zip", 1.0, std::nullopt, true},
      {"sanjorge_srtm1", "S46W066.hgt.gz", 1.0, std::nullopt, true},
  };
  for (const Source& s : sources) {
    if (archives_only) break;
    const std::string path = (std::filesystem::path(data_dir) / s.file).string();
    std::vector<float> m;
    int w = 0, h = 0;
    if (!std::filesystem::exists(path) || !(s.hgt ? read_hgt(path, m, w, h) : read_raster(path, s.scale, s.nodata, m, w, h))) {
      fmt::print(stderr, "skipping {}: cannot read {}\n", s.name, path);
      continue;
    }
    Dataset d = make_tiles(s.name, s.file, m, w, h, max_tiles, step_floor);
    if (!d.tiles.empty()) sets.push_back(std::move(d));
  }
  for (const std::string& a : archives) {
    terrain::ArchiveReader reader;
    if (terrain::Status st = reader.open(a); !st.ok()) {
      fmt::print(stderr, "{}\n", st.to_string());
      return 1;
    }
    Dataset d{std::filesystem::path(a).filename().string(), a, -1, -1, {}};
    auto node = std::make_unique<terrain::NodeData>();
    const size_t n = reader.nodes().size(), take = std::min(n, max_tiles);
    for (size_t k = 0; k < take; ++k) {  // spread evenly over the directory (all levels)
      const size_t i = k * n / take;
      if (terrain::Status st = reader.decode_node(i, *node, terrain::kSectionHeights); !st.ok()) {
        fmt::print(stderr, "{}\n", st.to_string());
        return 1;
      }
      d.tiles.push_back({std::vector<uint16_t>(node->heights.begin(), node->heights.end())});
    }
    if (!d.tiles.empty()) sets.push_back(std::move(d));
  }
  if (sets.empty()) {
    fmt::print(stderr, "no data: set --data or TERRAIN_DATA_DIR\n");
    return 1;
  }

  std::vector<Result> results;
  for (const Dataset& d : sets) {
    if (!dump_dir.empty() && !dump_pgm(dump_dir, d)) return 1;
    Result r;
    if (!run_dataset(d, levels, default_level, runs, r)) {
      fmt::print(stderr, "{}: benchmark failed (decode mismatch or codec error)\n", d.name);
      return 1;
    }
    if (!dump_dir.empty() && !write_bytes_file(dump_dir, r)) return 1;
    results.push_back(std::move(r));
  }
  if (!chart.empty()) {
    if (const std::string e = terrain::chart::write_svg(format_chart(results, default_level, runs), chart); !e.empty()) {
      fmt::print(stderr, "terrain-format-bench: {}\n", e);
      return 1;
    }
    fmt::print(stderr, "wrote {}\n", chart);  // stderr: --json keeps stdout pure JSON
  }
  if (json) {
    nlohmann::json j = nlohmann::json::array();
    for (const Result& r : results) {
      nlohmann::json o = {{"dataset", r.name}, {"source", r.source}, {"tiles", r.tiles}, {"step_log2", r.step_log2}, {"range_step_log2", r.range_step_log2}, {"step_floor", step_floor},
                          {"raw_bytes", r.raw}, {"zstd19_bytes", r.zstd19}, {"zstd19_decode_mbps", r.zstd19_decode_mbps}, {"zstd19_decode_mbps_median", r.zstd19_decode_mbps_median},
                          {"zstd_default_level", default_level}, {"zstd_default_bytes", r.zstd_default},
                          {"zstd_default_decode_mbps", r.zstd_default_decode_mbps}, {"memcpy_mbps", r.memcpy_mbps}};
      for (const LevelResult& l : r.levels)
        o["predictor"].push_back({{"zstd_level", l.level}, {"bytes", l.bytes},
                                  {"ratio_vs_zstd19", double(l.bytes) / double(r.zstd19)},
                                  {"encode_ms_per_tile", l.encode_ms_per_tile}, {"decode_mbps", l.decode_mbps},
                                  {"decode_mbps_median", l.decode_mbps_median},
                                  {"decode_vs_zstd19", l.decode_mbps / r.zstd19_decode_mbps},
                                  {"paired_decode_pct_of_zstd19", l.paired_pct}, {"paired_decode_mbps", l.paired_mbps},
                                  {"paired_zstd19_decode_mbps", l.paired_zstd19_mbps}});
      if (r.charls.measured)
        o["jpegls_charls"] = {{"bytes", r.charls.bytes}, {"ratio_vs_zstd19", double(r.charls.bytes) / double(r.zstd19)},
                              {"encode_ms_per_tile", r.charls.encode_ms_per_tile}, {"decode_mbps", r.charls.decode_mbps},
                              {"decode_mbps_median", r.charls.decode_mbps_median},
                              {"decode_vs_zstd19", r.charls.decode_mbps / r.zstd19_decode_mbps},
                              {"paired_decode_pct_of_zstd19", r.charls.paired.pct}, {"paired_decode_mbps", r.charls.paired.mbps},
                              {"paired_zstd19_decode_mbps", r.charls.paired.zstd19_mbps}};
      j.push_back(o);
    }
    fmt::print("{}\n", j.dump(2));
    return 0;
  }
  fmt::print("# height codec benchmark: fastest of {} runs per timing (encode: fastest of 3 passes, per tile); MB/s of decoded R16 output\n", runs);
  for (const Result& r : results) {
    fmt::print("\n{} ({}): {} tiles of 129x129, step_log2 {} (range-driven {}, floor {}; -1: archive nodes), raw {} B\n", r.name,
               r.source, r.tiles, r.step_log2, r.range_step_log2, step_floor, r.raw);
    fmt::print("  plain zstd -19     {:>9} B  ratio {:5.2f}  decode {:7.0f} MB/s (median {:.0f})\n", r.zstd19,
               double(r.raw) / double(r.zstd19), r.zstd19_decode_mbps, r.zstd19_decode_mbps_median);
    fmt::print("  plain zstd -{:<2}     {:>9} B  ratio {:5.2f}  decode {:7.0f} MB/s\n", default_level, r.zstd_default,
               double(r.raw) / double(r.zstd_default), r.zstd_default_decode_mbps);
    fmt::print("  memcpy                                           {:7.0f} MB/s\n", r.memcpy_mbps);
    for (const LevelResult& l : r.levels)
      fmt::print("  predictor+zstd -{:<2} {:>9} B  ratio {:5.2f}  vs zstd19 {:4.2f}x  encode {:6.3f} ms/tile  decode {:7.0f} MB/s "
                 "({:3.0f}% of zstd19; medians {:.0f} MB/s, {:.0f}%; paired {:.0f}% = {:.0f} vs {:.0f} MB/s)\n",
                 l.level, l.bytes, double(r.raw) / double(l.bytes), double(l.bytes) / double(r.zstd19), l.encode_ms_per_tile,
                 l.decode_mbps, 100.0 * l.decode_mbps / r.zstd19_decode_mbps, l.decode_mbps_median,
                 100.0 * l.decode_mbps_median / r.zstd19_decode_mbps_median, l.paired_pct, l.paired_mbps, l.paired_zstd19_mbps);
    if (const PeerResult& c = r.charls; c.measured)
      fmt::print("  JPEG-LS (CharLS)   {:>9} B  ratio {:5.2f}  vs zstd19 {:4.2f}x  encode {:6.3f} ms/tile  decode {:7.0f} MB/s "
                 "({:3.0f}% of zstd19; medians {:.0f} MB/s, {:.0f}%; paired {:.0f}% = {:.0f} vs {:.0f} MB/s)\n",
                 c.bytes, double(r.raw) / double(c.bytes), double(c.bytes) / double(r.zstd19), c.encode_ms_per_tile, c.decode_mbps,
                 100.0 * c.decode_mbps / r.zstd19_decode_mbps, c.decode_mbps_median,
                 100.0 * c.decode_mbps_median / r.zstd19_decode_mbps_median, c.paired.pct, c.paired.mbps, c.paired.zstd19_mbps);
  }
  fmt::print("\n# summary (tab-separated)\ndataset\ttiles\tzstd19_B\tlevel\tpred_B\tratio_vs_zstd19\tencode_ms\tdecode_MBps\tzstd19_decode_MBps\tpct\tpct_median\tpaired_MBps\tpaired_zstd19_MBps\tpaired_pct\tmemcpy_MBps\n");
  for (const Result& r : results)
    for (const LevelResult& l : r.levels)
      fmt::print("{}\t{}\t{}\t{}\t{}\t{:.3f}\t{:.3f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\n", r.name, r.tiles, r.zstd19,
                 l.level, l.bytes, double(l.bytes) / double(r.zstd19), l.encode_ms_per_tile, l.decode_mbps, r.zstd19_decode_mbps,
                 100.0 * l.decode_mbps / r.zstd19_decode_mbps, 100.0 * l.decode_mbps_median / r.zstd19_decode_mbps_median,
                 l.paired_mbps, l.paired_zstd19_mbps, l.paired_pct, r.memcpy_mbps);
#if TERRAIN_HAVE_CHARLS
  fmt::print("\n# JPEG-LS lossless (CharLS {}.{}.{}; tab-separated)\ndataset\ttiles\tzstd19_B\tjpegls_B\tratio_vs_zstd19\tencode_ms\tdecode_MBps\tzstd19_decode_MBps\tpct\tpaired_MBps\tpaired_zstd19_MBps\tpaired_pct\n",
             CHARLS_VERSION_MAJOR, CHARLS_VERSION_MINOR, CHARLS_VERSION_PATCH);
  for (const Result& r : results)
    if (const PeerResult& c = r.charls; c.measured)
      fmt::print("{}\t{}\t{}\t{}\t{:.3f}\t{:.3f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\t{:.0f}\n", r.name, r.tiles, r.zstd19, c.bytes,
                 double(c.bytes) / double(r.zstd19), c.encode_ms_per_tile, c.decode_mbps, r.zstd19_decode_mbps,
                 100.0 * c.decode_mbps / r.zstd19_decode_mbps, c.paired.mbps, c.paired.zstd19_mbps, c.paired.pct);
#else
  fmt::print("\n# JPEG-LS column off: built without CharLS (libcharls-dev)\n");
#endif
  return 0;
}
