// Node payloads: a 64-byte section table, then five sections, each stored, zstd, or (heights)
// the hierarchical predictor's residual planes in zstd, or one value for a constant grid.
#include "payload.h"

#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "terrain/detail/bytes.h"
#include "terrain/archive_writer.h"
#include "terrain/bc_decode.h"
#include "terrain/derived_normals.h"
#include "terrain/cpu_clock.h"
#include "terrain/height_codec.h"
#include "terrain/zstd_context.h"

namespace terrain {
namespace detail {

Status parse_payload_table(std::span<const uint8_t> payload, PayloadTable& out) {
  return parse_payload_table(payload.first(std::min<size_t>(payload.size(), layout::kPayloadHeaderSize)), payload.size(), out);
}

Status parse_payload_table(std::span<const uint8_t> table, uint64_t payload_size, PayloadTable& out) {
  auto bad = [](std::string msg) { return Status::failure(Error::payload_invalid, std::move(msg)); };
  if (payload_size < layout::kPayloadHeaderSize)
    return bad("payload is " + std::to_string(payload_size) + " bytes, shorter than its 64-byte section table");
  if (table.size() < layout::kPayloadHeaderSize)
    return bad("section table is " + std::to_string(table.size()) + " bytes, expected 64");
  const uint8_t* p = table.data();
  if (p[0] != layout::kSectionCount) return bad("section_count is " + std::to_string(p[0]) + ", expected 5");
  if (p[1] != 0 || p[2] != 0 || p[3] != 0) return bad("reserved payload header bytes are not zero");
  uint64_t at = layout::kPayloadHeaderSize;
  for (uint32_t s = 0; s < layout::kSectionCount; ++s) {
    const uint8_t* e = p + 4 + s * layout::kPayloadTableEntrySize;
    const std::string name = layout::kSectionName[s];
    if (e[0] != s) return bad("section entry " + std::to_string(s) + " has id " + std::to_string(e[0]) + ", expected " + std::to_string(s));
    const uint8_t codec = e[1];
    const bool heights = s == uint32_t(layout::SectionId::heights);
    // Byte 2 is height_shift for the height predictor, reserved otherwise; byte 3 is reserved.
    const bool has_shift = heights && codec == uint8_t(layout::Codec::height_predictor);
    if ((!has_shift && e[2] != 0) || e[3] != 0) return bad(name + " section entry has reserved bytes set");
    if (has_shift && e[2] > 15) return bad("height_shift " + std::to_string(e[2]) + " outside 0..15");
    const bool height_only = codec == uint8_t(layout::Codec::height_predictor) || codec == uint8_t(layout::Codec::height_constant);
    const bool normals_only = codec == uint8_t(layout::Codec::normals_derived);
    if (codec > uint8_t(layout::Codec::normals_derived) || (height_only && !heights) ||
        (normals_only && s != uint32_t(layout::SectionId::normals)))
      return bad(name + " section has unknown codec " + std::to_string(codec));
    PayloadSection& sec = out[s];
    sec.codec = layout::Codec(codec);
    sec.height_shift = has_shift ? e[2] : 0;
    sec.stored_size = load_u32(e + 4);
    sec.raw_size = load_u32(e + 8);
    if (sec.raw_size != layout::kSectionRawSize[s])
      return bad(name + " section raw_size is " + std::to_string(sec.raw_size) + ", expected " + std::to_string(layout::kSectionRawSize[s]));
    if (sec.codec == layout::Codec::stored && sec.stored_size != sec.raw_size)
      return bad(name + " section is stored but stored_size != raw_size");
    if (sec.codec == layout::Codec::height_constant && sec.stored_size != 2)
      return bad(name + " section is constant but stored_size is " + std::to_string(sec.stored_size) + ", expected 2");
    if (sec.stored_size == 0) return bad(name + " section is empty");
    if (sec.stored_size > payload_size - at)
      return bad(name + " section (" + std::to_string(sec.stored_size) + " bytes at " + std::to_string(at) + ") runs past the payload end (" +
                 std::to_string(payload_size) + ")");
    sec.data_offset = uint32_t(at);
    at += sec.stored_size;
  }
  if (at != payload_size)
    return bad(std::to_string(payload_size - at) + " trailing bytes after the last section");
  return Status::success();
}

namespace {

// Height residual planes at levels 9..18 (the cooker's is 9): optimal parsing (btopt) with a
// single search attempt and 32 KB tables. Measured on the real DEM tiles (terrain-format-bench):
// within 1 % of level 19's bytes and 0.5-18 % fewer than plain level 9's; non-optimal strategies
// (lazy2, btlazy2) with the same tables and one attempt lose the gain (with 16, lazy2 keeps most
// of it: level 9's second parse). Matches of at least 6 bytes, and taking any
// match of 32 bytes at once, cost the parser far less (residual planes hold few short repeats worth
// a sequence): on 200 nodes each of cooked Kilauea, Jacksboro and a 1 m lidar-like square, 0.78 %,
// 0.66 % and 0.08 % fewer bytes than btopt's level-19 defaults (3 and 256) at 30-52 % less encode
// CPU (1.06 -> 0.74, 1.24 -> 0.77, 0.91 -> 0.43 ms per node), and the fewer, longer sequences
// decode 40-60 % faster (zstd alone: 0.9-1.05 -> 1.3-1.6 GB/s of residual bytes per CPU second).
// Levels below 9 stay fast; 19 and up are zstd's own.
// Level 9's second parse is lazy2 with 16 search attempts on the same tables (see compress_section).
void set_height_residual_params(ZSTD_CCtx* cctx, int level, ZSTD_strategy strategy) {
  if (level < 9 || level >= 19) return;
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, 19);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_strategy, strategy);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_searchLog, strategy == ZSTD_lazy2 ? 4 : 1);
  // lazy2's row-based match finder, named rather than left to zstd's build-time SIMD test (it
  // decides which frame is written; ZSTD_c_useRowMatchFinder = 1, ZSTD_ps_enable).
  if (strategy == ZSTD_lazy2) ZSTD_CCtx_setParameter(cctx, ZSTD_c_experimentalParam14, 1);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_windowLog, 15);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_chainLog, 15);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_hashLog, 15);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_minMatch, 6);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_targetLength, strategy == ZSTD_btopt ? 32 : 0);
}

// One zstd frame of `raw` at `level` (height residual planes: with `strategy` at levels 9..18)
// into out[start ..]; returns its size or a zstd error code.
size_t zstd_frame(ZSTD_CCtx* cctx, std::span<const uint8_t> raw, int level, bool residuals, ZSTD_strategy strategy,
                  std::vector<uint8_t>& out, size_t start) {
  const size_t bound = ZSTD_compressBound(raw.size());
  out.resize(start + bound);
  ZSTD_CCtx_reset(cctx, ZSTD_reset_session_and_parameters);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 1);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_checksumFlag, 0);
  if (residuals) set_height_residual_params(cctx, level, strategy);
  return ZSTD_compress2(cctx, out.data() + start, bound, raw.data(), raw.size());
}

// log2(x) for x > 0 from frexp (exact) and a degree-5 fit of log2(1 + t) on [0, 1), error under
// 1e-4: plain IEEE operations, so the same bits on every CPU (libm's log2 may differ in the last
// bit between its FMA and plain forms, and a decision below rests on it).
double log2_fit(double x) {
  int e = 0;
  const double t = 2.0 * std::frexp(x, &e) - 1.0;  // x = (1 + t) 2^(e - 1)
  return double(e - 1) + ((((0.0434295124 * t - 0.1877250146) * t + 0.4087248537) * t - 0.7057058643) * t + 1.4412677980) * t;
}

// Order-0 entropy of each half of `raw` (the low and the high residual plane), estimated from
// every fourth byte, in bytes: integer counts, then double sums in a fixed order.
size_t order0_bytes(std::span<const uint8_t> raw) {
  const size_t half = raw.size() / 2;
  double bytes = 0;
  for (size_t plane = 0; plane < 2; ++plane) {
    uint32_t counts[256] = {};
    const uint8_t* p = raw.data() + plane * half;
    uint32_t n = 0;
    for (size_t i = 0; i < half; i += 4, ++n) ++counts[p[i]];
    double bits = 0;  // of the n samples
    for (int v = 0; v < 256; ++v)
      if (counts[v]) bits += double(counts[v]) * log2_fit(double(n) / double(counts[v]));
    bytes += bits / 8.0 * double(half) / double(n);
  }
  return size_t(bytes);
}

Status compress_section(std::span<const uint8_t> raw, int level, layout::Codec codec_if_compressed, std::vector<uint8_t>& out,
                        uint8_t* entry) {
  ZSTD_CCtx* cctx = thread_cctx();
  if (!cctx) return Status::failure(Error::internal, "cannot create a zstd compression context");
  const size_t start = out.size();
  const bool residuals = codec_if_compressed == layout::Codec::height_predictor;
  // Level 9 (the cooker's) parses residual planes the quick way (strategy dfast, same tables)
  // first, and with lazy2 (16 attempts) as well only when that frame is under a quarter of the
  // raw bytes, keeping the smaller frame. On rough grids (1 m lidar, first returns) a second
  // parse saved 0-2.9 % of the height bytes for 5-12x the encode CPU; on smooth, sea- or
  // void-heavy grids (30 m DEMs, SRTM coasts, 0.5 m bare earth) the optimal parse of levels
  // 10-18 is 2-20 % smaller than dfast. There lazy2 keeps most of that: on 336 cooked Oetztal and
  // 407 Kilauea nodes +1.5 % and +0.7 % height bytes against the optimal parse at 0.38 and 0.41x
  // its encode CPU (0.40 against 1.05, 0.29 against 0.70 ms per node), and its fewer, longer
  // matches decode 6-18 % faster.
  const bool probe = residuals && level == 9;
  // Planes whose order-0 entropy (sampled) is under a fifth of their bytes skip the quick frame and
  // parse with lazy2 only. On every node of seven real DEMs' cooks (Oetztal, Kilauea, N22W160,
  // Slovenia, both Tahoe tiles, the lidar-like square at 0.05 m) no plane under that entropy (full
  // planes) had a quick frame over a quarter, so lazy2 ran on them anyway. Oetztal: zstd of the heights 0.385 -> 0.355 ms per
  // node, archive identical; Slovenia +17 and S46W066 +6 bytes (nodes where dfast's frame had won).
  const bool smooth = probe && order0_bytes(raw) * 5 < raw.size();
  size_t n = zstd_frame(cctx, raw, level, residuals, smooth ? ZSTD_lazy2 : probe ? ZSTD_dfast : ZSTD_btopt, out, start);
  if (ZSTD_isError(n)) return Status::failure(Error::internal, std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
  if (probe && !smooth && n * 4 < raw.size()) {
    static thread_local std::vector<uint8_t> second;
    const size_t m = zstd_frame(cctx, raw, level, residuals, ZSTD_lazy2, second, 0);
    if (ZSTD_isError(m)) return Status::failure(Error::internal, std::string("zstd compression failed: ") + ZSTD_getErrorName(m));
    if (m < n) {
      std::memcpy(out.data() + start, second.data(), m);
      n = m;
    }
  }
  layout::Codec codec = codec_if_compressed;
  size_t stored = n;
  if (n >= raw.size() && codec_if_compressed == layout::Codec::zstd) {  // incompressible: store as is
    std::memcpy(out.data() + start, raw.data(), raw.size());
    stored = raw.size();
    codec = layout::Codec::stored;
  }
  out.resize(start + stored);
  entry[1] = uint8_t(codec);
  store_u32(entry + 4, uint32_t(stored));
  store_u32(entry + 8, uint32_t(raw.size()));
  return Status::success();
}

Status decompress_into(std::span<const uint8_t> src, uint8_t* dst, size_t dst_size, const char* name) {
  ZSTD_DCtx* dctx = thread_dctx();
  if (!dctx) return Status::failure(Error::internal, "cannot create a zstd decompression context");
  // Exactly one frame that fills the whole stored size.
  const size_t frame = ZSTD_findFrameCompressedSize(src.data(), src.size());
  if (ZSTD_isError(frame) || frame != src.size())
    return Status::failure(Error::decompress_failed, std::string(name) + " section is not exactly one zstd frame");
  const unsigned long long content = ZSTD_getFrameContentSize(src.data(), src.size());
  if (content != dst_size)
    return Status::failure(Error::decompress_failed, std::string(name) + " section's zstd frame does not declare " +
                                                         std::to_string(dst_size) + " bytes of content");
  const size_t n = ZSTD_decompressDCtx(dctx, dst, dst_size, src.data(), src.size());
  if (ZSTD_isError(n)) return Status::failure(Error::decompress_failed, std::string(name) + " section: zstd: " + ZSTD_getErrorName(n));
  if (n != dst_size)
    return Status::failure(Error::decompress_failed, std::string(name) + " section decompressed to " + std::to_string(n) + " bytes, expected " +
                                                         std::to_string(dst_size));
  return Status::success();
}

}  // namespace
}  // namespace detail

Status encode_node_payload(const NodeData& data, const PayloadOptions& options, std::vector<uint8_t>& out,
                           PayloadTiming* timing, const NormalsDerivation* derived_normals) {
  using namespace detail;
  if (options.zstd_level < -7 || options.zstd_level > 22)
    return Status::failure(Error::invalid_argument, "zstd_level " + std::to_string(options.zstd_level) + " outside -7..22");
  const int surface_level = options.surface_zstd_level.value_or(options.zstd_level);
  if (surface_level < -7 || surface_level > 22)
    return Status::failure(Error::invalid_argument, "surface_zstd_level " + std::to_string(surface_level) + " outside -7..22");
  out.assign(layout::kPayloadHeaderSize, 0);
  out.reserve(layout::kPayloadHeaderSize + 40000);
  out[0] = uint8_t(layout::kSectionCount);
  uint8_t entries[layout::kSectionCount][layout::kPayloadTableEntrySize] = {};
  const std::span<const uint8_t> raw[layout::kSectionCount] = {
      {reinterpret_cast<const uint8_t*>(data.heights.data()), sizeof(data.heights)},
      {data.normals_bc3.data(), data.normals_bc3.size()},
      {data.albedo_bc1.data(), data.albedo_bc1.size()},
      {data.splat.data(), data.splat.size()},
      {data.cones_bc3.data(), data.cones_bc3.size()}};
  // Per-thread scratch: a node's residual planes and the plain-zstd trial reuse one buffer each.
  static thread_local std::vector<uint8_t> scratch, plain;
  for (uint32_t s = 0; s < layout::kSectionCount; ++s) {
    entries[s][0] = uint8_t(s);
    Status st;
    if (s == uint32_t(layout::SectionId::heights)) {
      if (options.height_predictor &&
          std::all_of(data.heights.begin(), data.heights.end(), [&](uint16_t v) { return v == data.heights[0]; })) {
        // Constant grid (sea, flat fill): 2 bytes instead of a ~20-byte zstd frame, and a fill to decode.
        out.push_back(uint8_t(data.heights[0]));
        out.push_back(uint8_t(data.heights[0] >> 8));
        entries[s][1] = uint8_t(layout::Codec::height_constant);
        store_u32(entries[s] + 4, 2);
        store_u32(entries[s] + 8, uint32_t(2 * kHeightCount));
      } else if (options.height_predictor) {
        const int shift = heights_common_shift(data.heights);
        heights_to_residuals(data.heights, shift, scratch);
        const size_t start = out.size();
        st = compress_section(scratch, options.zstd_level, layout::Codec::height_predictor, out, entries[s]);
        entries[s][2] = uint8_t(shift);
        // Noisy grids (spiky first-return lidar) can predict worse than they repeat: when the
        // predictor saves less than a quarter, also try plain zstd of the R16 bytes and keep the
        // smaller (measured: below that the plain form never won, and trying costs a second pass).
        if (st.ok() && (out.size() - start) * 4 > scratch.size() * 3) {
          plain.assign(out.begin(), out.begin() + std::ptrdiff_t(start));
          uint8_t plain_entry[layout::kPayloadTableEntrySize] = {uint8_t(s)};
          for (int i = 0; i < kHeightCount; ++i) store_u16(scratch.data() + 2 * i, data.heights[size_t(i)]);
          st = compress_section(scratch, options.zstd_level, layout::Codec::zstd, plain, plain_entry);
          if (st.ok() && plain.size() < out.size()) {
            out.swap(plain);
            std::memcpy(entries[s], plain_entry, sizeof(plain_entry));
          }
        }
      } else {
        // Plain R16 little-endian bytes (benchmarks): serialise explicitly, not via host order.
        scratch.resize(2 * size_t(kHeightCount));
        for (int i = 0; i < kHeightCount; ++i) store_u16(scratch.data() + 2 * i, data.heights[size_t(i)]);
        st = compress_section(scratch, options.zstd_level, layout::Codec::zstd, out, entries[s]);
      }
    } else if (s == uint32_t(layout::SectionId::normals) && derived_normals) {
      uint8_t bytes[kNormalsDerivationBytes];
      store_normals_derivation(*derived_normals, bytes);
      NormalsDerivation check;
      if (!load_normals_derivation(bytes, sizeof(bytes), check))
        return Status::failure(Error::invalid_argument, "derived normals: rise_per_unit must be in (0, 1024], AO values <= 31");
      st = compress_section(bytes, surface_level, layout::Codec::normals_derived, out, entries[s]);
      store_u32(entries[s] + 8, layout::kSectionRawSize[s]);  // raw_size: the decoded BC3 section
    } else {
      st = compress_section(raw[s], surface_level, layout::Codec::zstd, out, entries[s]);
    }
    if (!st.ok()) return st;
    if (timing) timing->section_end_s[s] = thread_cpu_seconds();
  }
  for (uint32_t s = 0; s < layout::kSectionCount; ++s)
    std::memcpy(out.data() + 4 + s * layout::kPayloadTableEntrySize, entries[s], layout::kPayloadTableEntrySize);
  return Status::success();
}

namespace detail {
namespace {

Status decode_heights(const PayloadSection& sec, std::span<const uint8_t> src, std::array<uint16_t, kHeightCount>& heights) {
  if (sec.codec == layout::Codec::height_constant) {  // stored_size == 2 checked by the table parser
    std::fill(heights.begin(), heights.end(), load_u16(src.data()));
    return Status::success();
  }
  alignas(64) uint8_t buffer[2 * kHeightCount];
  if (sec.codec == layout::Codec::stored) {
    std::memcpy(buffer, src.data(), sizeof(buffer));
  } else {
    TERRAIN_TRY(decompress_into(src, buffer, sizeof(buffer), "heights"));
  }
  if (sec.codec == layout::Codec::height_predictor) return residuals_to_heights(buffer, sec.height_shift, heights);
  for (int i = 0; i < kHeightCount; ++i) heights[size_t(i)] = load_u16(buffer + 2 * i);
  return Status::success();
}

// Codec 4 (SPEC 16.7): the texels from the node's heights, hole mask (albedo alpha), apron and AO.
Status decode_derived_normals(std::span<const uint8_t> src, const std::array<uint16_t, kHeightCount>& heights,
                              const uint8_t* albedo_bc1, uint8_t* normals_bc3) {
  uint8_t bytes[kNormalsDerivationBytes];
  TERRAIN_TRY(decompress_into(src, bytes, sizeof(bytes), "normals"));
  static thread_local NormalsDerivation d;
  if (!load_normals_derivation(bytes, sizeof(bytes), d))
    return Status::failure(Error::payload_invalid, "normals section (derived): rise_per_unit outside (0, 1024], or an AO value above 31");
  static thread_local std::array<uint8_t, kHeightCount> holes;
  holes.fill(0);
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      const uint16_t mask = bc1_transparent_mask(albedo_bc1 + 8 * size_t(by * kTexelBlocks + bx));
      if (!mask) continue;
      for (int p = 0; p < 16; ++p) {
        if (!(mask >> p & 1)) continue;
        const int i = bx * 4 + p % 4 - kApron, j = by * 4 + p / 4 - kApron;
        if (i >= 0 && i < kHeightSamples && j >= 0 && j < kHeightSamples) holes[size_t(j * kHeightSamples + i)] = 1;
      }
    }
  static thread_local std::array<uint8_t, kTexels * kTexels * 4> rgba;
  derive_normal_texels(heights.data(), holes.data(), d, rgba.data());
  encode_derived_normals_bc3(rgba.data(), normals_bc3);
  return Status::success();
}

}  // namespace
}  // namespace detail

Status decode_node_payload(std::span<const uint8_t> bytes, unsigned sections, NodeData& out) {
  using namespace detail;
  PayloadTable table;
  TERRAIN_TRY(parse_payload_table(bytes, table));
  auto section_bytes = [&](layout::SectionId id) {
    const PayloadSection& sec = table[size_t(id)];
    return bytes.subspan(sec.data_offset, sec.stored_size);
  };
  uint8_t* dst[layout::kSectionCount] = {nullptr, out.normals_bc3.data(), out.albedo_bc1.data(), out.splat.data(),
                                         out.cones_bc3.data()};
  const bool derive = (sections & kSectionNormals) && table[size_t(layout::SectionId::normals)].codec == layout::Codec::normals_derived;
  for (uint32_t s = 0; s < layout::kSectionCount; ++s) {
    if (!(sections & (1u << s))) continue;
    const PayloadSection& sec = table[s];
    const auto src = bytes.subspan(sec.data_offset, sec.stored_size);
    if (s == uint32_t(layout::SectionId::heights)) {
      TERRAIN_TRY(decode_heights(sec, src, out.heights));
    } else if (s == uint32_t(layout::SectionId::normals) && derive) {
      continue;  // after the heights and the albedo, below
    } else if (sec.codec == layout::Codec::stored) {
      std::memcpy(dst[s], src.data(), sec.raw_size);
    } else {
      TERRAIN_TRY(decompress_into(src, dst[s], sec.raw_size, layout::kSectionName[s]));
    }
  }
  if (derive) {
    // The inputs the caller did not ask for are decoded into scratch, so only the asked sections of `out` change.
    static thread_local std::array<uint16_t, kHeightCount> heights;
    static thread_local std::array<uint8_t, kAlbedoBytes> albedo;
    const std::array<uint16_t, kHeightCount>* h = &out.heights;
    if (!(sections & kSectionHeights)) {
      TERRAIN_TRY(decode_heights(table[size_t(layout::SectionId::heights)], section_bytes(layout::SectionId::heights), heights));
      h = &heights;
    }
    const uint8_t* a = out.albedo_bc1.data();
    if (!(sections & kSectionAlbedo)) {
      const PayloadSection& sec = table[size_t(layout::SectionId::albedo)];
      if (sec.codec == layout::Codec::stored) {
        std::memcpy(albedo.data(), section_bytes(layout::SectionId::albedo).data(), sec.raw_size);
      } else {
        TERRAIN_TRY(decompress_into(section_bytes(layout::SectionId::albedo), albedo.data(), sec.raw_size, "albedo"));
      }
      a = albedo.data();
    }
    TERRAIN_TRY(decode_derived_normals(section_bytes(layout::SectionId::normals), *h, a, out.normals_bc3.data()));
  }
  return Status::success();
}

}  // namespace terrain
