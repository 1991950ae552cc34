#include "layout.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include "terrain/detail/bytes.h"

namespace terrain::detail {
namespace {

Status fail(Error e, std::string msg) { return Status::failure(e, std::move(msg)); }
bool all_zero(const uint8_t* p, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (p[i]) return false;
  return true;
}
bool finite(double v) { return std::isfinite(v); }

// Little-endian fixed-width fields, by the member's type.
void store_le(uint8_t* p, uint8_t v) { *p = v; }
void store_le(uint8_t* p, uint32_t v) { store_u32(p, v); }
void store_le(uint8_t* p, uint64_t v) { store_u64(p, v); }
void store_le(uint8_t* p, int32_t v) { store_i32(p, v); }
void store_le(uint8_t* p, float v) { store_f32(p, v); }
void store_le(uint8_t* p, double v) { store_f64(p, v); }
void load_le(const uint8_t* p, uint8_t& v) { v = *p; }
void load_le(const uint8_t* p, uint32_t& v) { v = load_u32(p); }
void load_le(const uint8_t* p, uint64_t& v) { v = load_u64(p); }
void load_le(const uint8_t* p, int32_t& v) { v = load_i32(p); }
void load_le(const uint8_t* p, float& v) { v = load_f32(p); }
void load_le(const uint8_t* p, double& v) { v = load_f64(p); }

// Each structure's fields as (offset, member), listed once: the encoder stores and the decoder loads
// the same list (`S` is the structure, const or not). Fields that are constants, enums or reserved
// are written and checked by hand.
template <class S, class F>
void header_fields(S& h, F&& f) {
  namespace o = layout::header;
  f(o::format_version, h.format_version);
  f(o::node_count, h.node_count);
  f(o::file_size, h.file_size);
  f(o::payload_offset, h.payload_offset);
  f(o::payload_size, h.payload_size);
  f(o::directory_offset, h.directory_offset);
  f(o::directory_size, h.directory_size);
  f(o::metadata_offset, h.metadata_offset);
  f(o::metadata_size, h.metadata_size);
  f(o::directory_crc32, h.directory_crc32);
  f(o::metadata_crc32, h.metadata_crc32);
}

template <class S, class F>
void world_fields(S& w, F&& f) {
  namespace o = layout::metadata;
  f(o::roots_x, w.roots_x);
  f(o::roots_y, w.roots_y);
  f(o::origin_x_m, w.origin_x_m);
  f(o::origin_y_m, w.origin_y_m);
  f(o::extent_min_x_m, w.extent_min_x_m);
  f(o::extent_min_y_m, w.extent_min_y_m);
  f(o::extent_max_x_m, w.extent_max_x_m);
  f(o::extent_max_y_m, w.extent_max_y_m);
  f(o::epsg, w.crs.epsg);
  f(o::semi_major_m, w.crs.semi_major_m);
  f(o::inverse_flattening, w.crs.inverse_flattening);
  f(o::lat0_deg, w.crs.lat0_deg);
  f(o::lon0_deg, w.crs.lon0_deg);
  f(o::scale_k0, w.crs.scale_k0);
  f(o::false_easting_m, w.crs.false_easting_m);
  f(o::false_northing_m, w.crs.false_northing_m);
}

// A palette record after its 32-byte name (SPEC "Metadata").
template <class S, class F>
void material_fields(S& m, F&& f) {
  f(32u, m.albedo_srgb[0]);
  f(33u, m.albedo_srgb[1]);
  f(34u, m.albedo_srgb[2]);
  f(35u, m.flags);
  f(36u, m.roughness);
  f(40u, m.detail_scale_m);
  f(44u, m.detail_strength);
  f(48u, m.height_blend);
}

// key.level is a u32 member stored in one byte: by hand.
template <class S, class F>
void entry_fields(S& r, F&& f) {
  namespace o = layout::entry;
  f(o::child_mask, r.child_mask);
  f(o::flags, r.flags);
  f(o::x, r.key.x);
  f(o::y, r.key.y);
  f(o::height_offset, r.height_offset);
  f(o::min_height, r.min_height);
  f(o::max_height, r.max_height);
  f(o::geometric_error_m, r.geometric_error_m);
  f(o::payload_crc32, r.payload_crc32);
  f(o::payload_offset, r.payload_offset);
  f(o::payload_size, r.payload_size);
}

// Field visitors that store into / load from the bytes at `p`.
auto storer(uint8_t* p) {
  return [p](uint32_t at, const auto& v) { store_le(p + at, v); };
}
auto loader(const uint8_t* p) {
  return [p](uint32_t at, auto& v) { load_le(p + at, v); };
}

}  // namespace

// ---- header ---------------------------------------------------------------------------------------
void encode_header(const Header& h, uint8_t out[layout::kHeaderSize]) {
  namespace f = layout::header;
  std::memset(out, 0, layout::kHeaderSize);
  std::memcpy(out + f::magic, layout::kMagic.data(), layout::kMagic.size());
  store_u32(out + f::header_size, layout::kHeaderSize);
  store_u32(out + f::header_flags, 0);
  header_fields(h, storer(out));
  if (h.format_version >= layout::kFormatVersionV3) store_u32(out + f::page_entries, h.page_entries);
  store_u32(out + f::header_crc32, crc32_of({out, f::header_crc32}));
}

Status decode_header(std::span<const uint8_t> head, uint64_t file_size, Header& h) {
  namespace f = layout::header;
  const uint8_t* p = head.data();
  if (head.size() < layout::kMagic.size() || std::memcmp(p, layout::kMagic.data(), layout::kMagic.size()) != 0)
    return fail(Error::bad_magic, "not a terrain archive (the first 8 bytes are not \"TERRAIN\\x1A\")");
  if (head.size() < 12) return fail(Error::truncated, "file ends inside the header (" + std::to_string(head.size()) + " bytes)");
  h.format_version = load_u32(p + f::format_version);
  if (h.format_version < layout::kFormatVersion || h.format_version > layout::kMaxFormatVersion)
    return fail(Error::unsupported_version, "archive format version " + std::to_string(h.format_version) +
                                                ", this reader supports versions 1, 2 and 3");
  if (head.size() < layout::kHeaderSize)
    return fail(Error::truncated, "file ends inside the header (" + std::to_string(head.size()) + " of 128 bytes)");
  const uint32_t stored_crc = load_u32(p + f::header_crc32);
  const uint32_t crc = crc32_of({p, f::header_crc32});
  if (stored_crc != crc) return fail(Error::header_checksum, "header CRC-32 mismatch");
  if (load_u32(p + f::header_size) != layout::kHeaderSize)
    return fail(Error::header_invalid, "header_size is " + std::to_string(load_u32(p + f::header_size)) + ", expected 128");
  if (load_u32(p + f::header_flags) != 0) return fail(Error::header_invalid, "reserved header_flags bits are set");
  const bool v3 = h.format_version >= layout::kFormatVersionV3;
  if (!v3 && !all_zero(p + f::reserved, f::header_crc32 - f::reserved))
    return fail(Error::header_invalid, "reserved header bytes 88..123 are not zero");
  if (v3 && !all_zero(p + f::reserved_v3, f::header_crc32 - f::reserved_v3))
    return fail(Error::header_invalid, "reserved header bytes 92..123 are not zero");
  header_fields(h, loader(p));
  h.page_entries = v3 ? load_u32(p + f::page_entries) : 0;
  if (v3 && (h.page_entries < layout::kMinPageEntries || h.page_entries > layout::kMaxPageEntries ||
             (h.page_entries & (h.page_entries - 1)) != 0))
    return fail(Error::header_invalid, "page_entries " + std::to_string(h.page_entries) +
                                           " is not a power of two in 1024 .. 2^20 (SPEC 20)");

  if (h.file_size > file_size)
    return fail(Error::truncated, "file is " + std::to_string(file_size) + " bytes, the header says " +
                                      std::to_string(h.file_size));
  if (h.file_size < file_size)
    return fail(Error::header_invalid, std::to_string(file_size - h.file_size) +
                                           " trailing bytes after the end the header declares (" +
                                           std::to_string(h.file_size) + ")");
  const uint32_t max_nodes = v3 ? layout::kMaxNodeCountV3 : layout::kMaxNodeCount;
  if (h.node_count > max_nodes)
    return fail(Error::header_invalid, "node_count " + std::to_string(h.node_count) + " exceeds the limit " +
                                           std::to_string(max_nodes));
  // Sections are contiguous: header | payloads | directory | metadata (sizes are bounded by the
  // file size before any sum, so nothing overflows).
  auto section_bad = [&](uint64_t off, uint64_t size) { return off > h.file_size || size > h.file_size - off; };
  if (h.payload_offset != layout::kHeaderSize || section_bad(h.payload_offset, h.payload_size))
    return fail(Error::section_out_of_bounds, "payload section [" + std::to_string(h.payload_offset) + ", +" +
                                                  std::to_string(h.payload_size) + ") is not inside the file after the header");
  if (h.directory_offset != h.payload_offset + h.payload_size || section_bad(h.directory_offset, h.directory_size))
    return fail(Error::section_out_of_bounds, "directory section at " + std::to_string(h.directory_offset) + " size " +
                                                  std::to_string(h.directory_size) + " does not follow the payloads inside the file");
  if (h.directory_size != uint64_t(h.node_count) * layout::kEntrySize + h.page_count() * layout::kPageRecordSize)
    return fail(Error::section_out_of_bounds, "directory_size " + std::to_string(h.directory_size) + " is not node_count (" +
                                                  std::to_string(h.node_count) + ") x 48" +
                                                  (v3 ? " + " + std::to_string(h.page_count()) + " pages x 16" : ""));
  if (h.metadata_offset != h.directory_offset + h.directory_size || section_bad(h.metadata_offset, h.metadata_size) ||
      h.metadata_offset + h.metadata_size != h.file_size)
    return fail(Error::section_out_of_bounds, "metadata section at " + std::to_string(h.metadata_offset) + " size " +
                                                  std::to_string(h.metadata_size) + " does not end the file after the directory");
  return Status::success();
}

// ---- metadata --------------------------------------------------------------------------------------
Status validate_world(const WorldInfo& w) {
  auto bad = [](std::string msg) { return fail(Error::metadata_invalid, std::move(msg)); };
  const FrameCrs& c = w.crs;
  if (c.kind != ProjectionKind::local && c.kind != ProjectionKind::transverse_mercator && c.kind != ProjectionKind::proj)
    return bad("unknown projection_kind " + std::to_string(int(c.kind)) + " (0 = local, 1 = transverse_mercator, 2 = proj)");
  for (double v : {c.semi_major_m, c.inverse_flattening, c.lat0_deg, c.lon0_deg, c.scale_k0, c.false_easting_m,
                   c.false_northing_m, w.origin_x_m, w.origin_y_m, w.extent_min_x_m, w.extent_min_y_m, w.extent_max_x_m,
                   w.extent_max_y_m})
    if (!finite(v)) return bad("a CRS, origin or extent value is not finite");
  if (c.epsg < 0) return bad("negative EPSG code " + std::to_string(c.epsg));
  if (c.kind == ProjectionKind::transverse_mercator) {
    if (!(c.semi_major_m > 0)) return bad("transverse_mercator needs semi_major_m > 0");
    if (!(c.inverse_flattening == 0 || c.inverse_flattening > 1)) return bad("inverse_flattening must be 0 (sphere) or > 1");
    if (!(c.scale_k0 > 0)) return bad("scale_k0 must be > 0");
    if (!(std::fabs(c.lat0_deg) <= 90 && std::fabs(c.lon0_deg) <= 180)) return bad("lat0/lon0 out of range");
  }
  if (c.kind == ProjectionKind::proj) {
    if (!(c.semi_major_m > 0)) return bad("projection_kind proj needs semi_major_m > 0");
    if (!(c.inverse_flattening == 0 || c.inverse_flattening > 1)) return bad("inverse_flattening must be 0 (sphere) or > 1");
    if (c.definition.empty()) return bad("projection_kind proj without a frame_definition record");
    if (c.definition.size() > layout::kMaxFrameDefinitionSize) return bad("frame_definition longer than 64 KiB");
    if (c.definition.find('\0') != std::string::npos) return bad("frame_definition contains NUL");
  } else if (!c.definition.empty()) {
    return bad("a frame_definition record with projection_kind " + std::to_string(int(c.kind)) + " (only proj has one)");
  }
  if (c.name.size() > layout::kMaxCrsNameSize) return bad("CRS name longer than 1024 bytes");
  if (w.roots_x < 1 || w.roots_y < 1 || w.roots_x > layout::kMaxRoots || w.roots_y > layout::kMaxRoots)
    return bad("root grid " + std::to_string(w.roots_x) + " x " + std::to_string(w.roots_y) + " is outside 1..65536");
  if (w.extent_min_x_m > w.extent_max_x_m || w.extent_min_y_m > w.extent_max_y_m) return bad("extent min > max");
  for (int l = 0; l < kLevelCount; ++l)
    if (w.step_log2[l] > layout::kMaxStepLog2)
      return bad("step_log2[" + std::to_string(l) + "] = " + std::to_string(w.step_log2[l]) + " exceeds 14");
  if (w.overview_step_log2.size() > size_t(kMaxOverviewLevels))
    return bad("overview_levels declares " + std::to_string(w.overview_step_log2.size()) + " levels, more than 14");
  for (size_t k = 0; k < w.overview_step_log2.size(); ++k) {
    const int level = kLevelCount + int(k);
    if (w.overview_step_log2[k] > layout::kMaxStepLog2)
      return bad("overview_levels: step_log2 of level " + std::to_string(level) + " = " + std::to_string(w.overview_step_log2[k]) + " exceeds 14");
    // Section 7's crack-free rule needs a coarser level's step to be a multiple of every finer one.
    if (w.overview_step_log2[k] < level_step_log2(w, level - 1))
      return bad("overview_levels: step_log2 of level " + std::to_string(level) + " (" + std::to_string(w.overview_step_log2[k]) +
                 ") is below level " + std::to_string(level - 1) + "'s (" + std::to_string(level_step_log2(w, level - 1)) +
                 "): steps never decrease upward");
  }
  if (w.palette.size() > layout::kMaxPaletteCount) return bad("palette has more than 256 materials");
  for (size_t i = 0; i < w.palette.size(); ++i) {
    const Material& m = w.palette[i];
    if (m.name.size() >= layout::kMaterialNameBytes || m.name.find('\0') != std::string::npos)
      return bad("material " + std::to_string(i) + " name is longer than 31 bytes or contains NUL");
    if (m.flags != 0) return bad("material " + std::to_string(i) + " has reserved flags set");
    for (float v : {m.roughness, m.detail_scale_m, m.detail_strength, m.height_blend})
      if (!std::isfinite(v)) return bad("material " + std::to_string(i) + " has a non-finite parameter");
  }
  if (w.cook_info_json.size() > layout::kMaxCookInfoSize) return bad("cook_info larger than 16 MiB");
  if (!w.cook_info_json.empty()) {
    const auto j = nlohmann::json::parse(w.cook_info_json, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded() || !j.is_object()) return bad("cook_info is not a JSON object");
  }
  return Status::success();
}

namespace {
size_t padded4(size_t n) { return (n + 3) & ~size_t(3); }
// The v2 extension records of `w` (SPEC 6.5), in tag order.
std::vector<uint8_t> encode_extensions(const WorldInfo& w) {
  std::vector<uint8_t> out;
  auto add = [&out](uint32_t tag, const std::string& bytes) {
    const size_t at = out.size();
    out.resize(at + layout::kExtensionHeaderSize + padded4(bytes.size()), 0);
    store_u32(out.data() + at, tag);
    store_u32(out.data() + at + 4, uint32_t(bytes.size()));
    std::memcpy(out.data() + at + layout::kExtensionHeaderSize, bytes.data(), bytes.size());
  };
  if (w.crs.kind == ProjectionKind::proj) add(layout::kExtensionFrameDefinition, w.crs.definition);
  if (!w.overview_step_log2.empty()) {
    std::string record(1, char(w.overview_step_log2.size()));
    record.append(w.overview_step_log2.begin(), w.overview_step_log2.end());
    add(layout::kExtensionOverviewLevels, record);
  }
  if (w.derived_normals) add(layout::kExtensionDerivedNormals, std::string());
  return out;
}

Status decode_extensions(std::span<const uint8_t> bytes, WorldInfo& w) {
  auto bad = [](std::string msg) { return fail(Error::metadata_invalid, "extension records: " + std::move(msg)); };
  size_t at = 0;
  uint64_t last_tag = 0;
  while (at < bytes.size()) {
    if (bytes.size() - at < layout::kExtensionHeaderSize) return bad("a record header is cut by the end of the metadata");
    const uint32_t tag = load_u32(bytes.data() + at), size = load_u32(bytes.data() + at + 4);
    if (tag == 0 || tag <= last_tag) return bad("tag " + std::to_string(tag) + " is zero or not after the previous one");
    last_tag = tag;
    const size_t body = at + layout::kExtensionHeaderSize;
    if (size > bytes.size() - body || padded4(size) > bytes.size() - body)
      return bad("record " + std::to_string(tag) + " of " + std::to_string(size) + " bytes runs past extension_size");
    if (!all_zero(bytes.data() + body + size, padded4(size) - size)) return bad("padding bytes are not zero");
    const char* text = reinterpret_cast<const char*>(bytes.data() + body);
    if (tag == layout::kExtensionFrameDefinition) {
      if (size == 0 || size > layout::kMaxFrameDefinitionSize) return bad("frame_definition size " + std::to_string(size));
      w.crs.definition.assign(text, size);
    } else if (tag == layout::kExtensionOverviewLevels) {
      const uint8_t* data = bytes.data() + body;
      if (size < 2 || size != 1u + data[0] || data[0] == 0)
        return bad("overview_levels record of " + std::to_string(size) + " bytes: expected 1 + K bytes with K >= 1");
      w.overview_step_log2.assign(data + 1, data + size);  // ranges: validate_world
    } else if (tag == layout::kExtensionDerivedNormals) {
      if (size != 0) return bad("derived_normals record of " + std::to_string(size) + " bytes: expected 0");
      w.derived_normals = true;
    } else if (!(tag & layout::kExtensionOptional)) {
      return bad("unknown required tag " + std::to_string(tag) + " (written by a newer writer)");
    }
    at = body + padded4(size);
  }
  return Status::success();
}
}  // namespace

void encode_metadata(const WorldInfo& w, std::vector<uint8_t>& out) {
  namespace f = layout::metadata;
  const std::vector<uint8_t> ext = encode_extensions(w);
  const size_t size = layout::kMetadataFixedSize + w.crs.name.size() + w.palette.size() * layout::kMaterialRecordSize +
                      w.cook_info_json.size() + ext.size();
  out.assign(size, 0);
  uint8_t* p = out.data();
  store_u32(p + f::level_count, kLevelCount);
  store_u32(p + f::height_samples, kHeightSamples);
  store_f64(p + f::level0_node_size_m, kLevel0NodeSizeM);
  store_i32(p + f::height_unit_log2, kHeightUnitLog2);
  world_fields(w, storer(p));
  for (int l = 0; l < kLevelCount; ++l) p[f::step_log2 + l] = w.step_log2[l];
  p[f::projection_kind] = uint8_t(w.crs.kind);
  store_u32(p + f::crs_name_size, uint32_t(w.crs.name.size()));
  store_u32(p + f::palette_count, uint32_t(w.palette.size()));
  store_u32(p + f::cook_info_size, uint32_t(w.cook_info_json.size()));
  size_t at = layout::kMetadataFixedSize;
  std::memcpy(p + at, w.crs.name.data(), w.crs.name.size());
  at += w.crs.name.size();
  for (const Material& m : w.palette) {
    uint8_t* r = p + at;
    std::memcpy(r, m.name.data(), std::min<size_t>(m.name.size(), layout::kMaterialNameBytes - 1));
    material_fields(m, storer(r));
    at += layout::kMaterialRecordSize;
  }
  std::memcpy(p + at, w.cook_info_json.data(), w.cook_info_json.size());
  at += w.cook_info_json.size();
  if (!ext.empty()) {  // versions 2 and 3; 0 when there are no records
    store_u32(p + f::extension_size, uint32_t(ext.size()));
    std::memcpy(p + at, ext.data(), ext.size());
  }
}

Status decode_metadata(std::span<const uint8_t> bytes, uint32_t format_version, WorldInfo& w) {
  namespace f = layout::metadata;
  auto bad = [](std::string msg) { return fail(Error::metadata_invalid, std::move(msg)); };
  if (bytes.size() < layout::kMetadataFixedSize)
    return bad("metadata is " + std::to_string(bytes.size()) + " bytes, shorter than its 168-byte fixed part");
  const uint8_t* p = bytes.data();
  if (load_u32(p + f::level_count) != kLevelCount) return bad("level_count is not 6");
  if (load_u32(p + f::height_samples) != kHeightSamples) return bad("height_samples is not 129");
  if (load_f64(p + f::level0_node_size_m) != kLevel0NodeSizeM) return bad("level0_node_size_m is not 64");
  if (load_i32(p + f::height_unit_log2) != kHeightUnitLog2) return bad("height_unit_log2 is not -10");
  const bool v2 = format_version >= layout::kFormatVersionV2;
  if (load_u16(p + f::reserved0) != 0 || load_u32(p + f::reserved1) != 0 || !all_zero(p + f::reserved2, 3) ||
      (!v2 && load_u32(p + f::reserved3) != 0))
    return bad("reserved metadata bytes are not zero");
  w = WorldInfo{};
  world_fields(w, loader(p));
  for (int l = 0; l < kLevelCount; ++l) w.step_log2[l] = p[f::step_log2 + l];
  w.crs.kind = ProjectionKind(p[f::projection_kind]);
  const uint64_t name_size = load_u32(p + f::crs_name_size);
  const uint64_t palette_count = load_u32(p + f::palette_count);
  const uint64_t cook_size = load_u32(p + f::cook_info_size);
  if (name_size > layout::kMaxCrsNameSize) return bad("crs_name_size " + std::to_string(name_size) + " exceeds 1024");
  if (palette_count > layout::kMaxPaletteCount) return bad("palette_count " + std::to_string(palette_count) + " exceeds 256");
  if (cook_size > layout::kMaxCookInfoSize) return bad("cook_info_size exceeds 16 MiB");
  const uint64_t ext_size = v2 ? load_u32(p + f::extension_size) : 0;
  if (ext_size > layout::kMaxExtensionSize) return bad("extension_size exceeds 16 MiB");
  if (ext_size % 4) return bad("extension_size " + std::to_string(ext_size) + " is not a multiple of 4");
  const uint64_t expected =
      layout::kMetadataFixedSize + name_size + palette_count * layout::kMaterialRecordSize + cook_size + ext_size;
  if (expected != bytes.size())
    return bad("metadata_size is " + std::to_string(bytes.size()) + " but its fields add up to " + std::to_string(expected));
  size_t at = layout::kMetadataFixedSize;
  w.crs.name.assign(reinterpret_cast<const char*>(p + at), name_size);
  at += name_size;
  w.palette.resize(palette_count);
  for (uint64_t i = 0; i < palette_count; ++i) {
    const uint8_t* r = p + at;
    Material& m = w.palette[i];
    const size_t len = size_t(std::find(r, r + layout::kMaterialNameBytes, uint8_t(0)) - r);
    if (len >= layout::kMaterialNameBytes || !all_zero(r + len, layout::kMaterialNameBytes - len))
      return bad("material " + std::to_string(i) + " name is not NUL-terminated and zero-padded");
    m.name.assign(reinterpret_cast<const char*>(r), len);
    material_fields(m, loader(r));
    at += layout::kMaterialRecordSize;
  }
  w.cook_info_json.assign(reinterpret_cast<const char*>(p + at), cook_size);
  at += cook_size;
  TERRAIN_TRY(decode_extensions(bytes.subspan(at, ext_size), w));
  if (w.crs.kind == ProjectionKind::proj && !v2) return bad("projection_kind 2 (proj) in a version 1 file");
  return validate_world(w);
}

// ---- directory -------------------------------------------------------------------------------------
void encode_entry(const NodeRecord& r, uint8_t out[layout::kEntrySize]) {
  namespace f = layout::entry;
  std::memset(out, 0, layout::kEntrySize);
  out[f::level] = uint8_t(r.key.level);
  entry_fields(r, storer(out));
}

Status validate_record(const NodeRecord& r, const WorldInfo* world) {
  const std::string where = "node " + node_name(r.key) + ": ";
  auto bad = [&](std::string msg) { return fail(Error::directory_invalid, where + msg); };
  const int levels = world ? level_count(*world) : kMaxLevels;
  if (r.key.level >= uint32_t(levels))
    return bad("level must be 0.." + std::to_string(levels - 1) +
               (world && levels == kLevelCount ? " (the archive declares no overview levels)" : ""));
  if (world) {
    const uint64_t nx = level_grid_cells(world->roots_x, int(r.key.level));
    const uint64_t ny = level_grid_cells(world->roots_y, int(r.key.level));
    if (r.key.x >= nx || r.key.y >= ny)
      return bad("outside the level's node grid " + std::to_string(nx) + " x " + std::to_string(ny));
  }
  if (r.key.level == 0 && r.child_mask != 0) return bad("a level-0 node cannot have children");
  if (r.child_mask > 0xF) return bad("child_mask uses reserved bits 4..7");
  if (r.flags & ~kNodeFlagHasHoles) return bad("reserved flag bits are set");
  for (int32_t v : {r.height_offset, r.min_height, r.max_height})
    if (v < -kMaxHeightUnits || v > kMaxHeightUnits) return bad("height value " + std::to_string(v) + " outside +-(2^24-1) units");
  if (r.min_height > r.max_height) return bad("min_height > max_height");
  if (!std::isfinite(r.geometric_error_m) || r.geometric_error_m < 0) return bad("geometric_error_m is negative or not finite");
  if (r.payload_size < layout::kPayloadHeaderSize || r.payload_size > layout::kMaxPayloadSize)
    return fail(Error::payload_out_of_bounds, where + "payload_size " + std::to_string(r.payload_size) + " outside 64..1 MiB");
  return Status::success();
}

namespace {
Status decode_entries(std::span<const uint8_t> bytes, size_t first_index, const WorldInfo& world, const Header& header,
                      NodeRecord* out) {
  namespace f = layout::entry;
  const size_t count = bytes.size() / layout::kEntrySize;
  for (size_t n = 0; n < count; ++n) {
    const uint8_t* e = bytes.data() + n * layout::kEntrySize;
    NodeRecord& r = out[n];
    r = NodeRecord{};
    r.key.level = e[f::level];
    entry_fields(r, loader(e));
    if (e[f::reserved0] != 0 || load_u32(e + f::reserved1) != 0)
      return fail(Error::directory_invalid, "entry " + std::to_string(first_index + n) + " (node " + node_name(r.key) +
                                                "): reserved bytes are not zero");
    TERRAIN_TRY(validate_record(r, &world));
    if (r.payload_offset < header.payload_offset || r.payload_offset - header.payload_offset > header.payload_size ||
        r.payload_size > header.payload_size - (r.payload_offset - header.payload_offset))
      return fail(Error::payload_out_of_bounds, "node " + node_name(r.key) + ": payload [" + std::to_string(r.payload_offset) +
                                                    ", +" + std::to_string(r.payload_size) + ") is outside the payload section");
  }
  return Status::success();
}

bool directory_record_less(const NodeRecord& a, const NodeRecord& b) { return directory_less(a.key, b.key); }
}  // namespace

Status decode_directory(std::span<const uint8_t> bytes, const WorldInfo& world, const Header& header,
                        std::vector<NodeRecord>& out) {
  out.clear();
  if (bytes.size() != header.directory_size) return fail(Error::directory_invalid, "directory size mismatch");
  out.resize(header.node_count);
  if (header.page_entries == 0) {  // versions 1 and 2: one CRC, row order; sorted into directory order
    if (crc32_of(bytes) != header.directory_crc32)
      return fail(Error::directory_checksum, "directory CRC-32 mismatch (section at offset " + std::to_string(header.directory_offset) + ")");
    TERRAIN_TRY(decode_entries(bytes, 0, world, header, out.data()));
    for (size_t i = 1; i < out.size(); ++i)
      if (!key_less(out[i - 1].key, out[i].key))
        return fail(Error::directory_invalid, "entry " + std::to_string(i) + " (node " + node_name(out[i].key) +
                                                  ") is not after node " + node_name(out[i - 1].key) +
                                                  " (keys must be unique and sorted by level, y, x)");
    std::sort(out.begin(), out.end(), directory_record_less);
  } else {
    const size_t entries = size_t(header.node_count) * layout::kEntrySize;
    const auto table_bytes = bytes.subspan(entries);
    if (crc32_of(table_bytes) != header.directory_crc32)
      return fail(Error::directory_checksum, "page table CRC-32 mismatch (at offset " + std::to_string(header.page_table_offset()) + ")");
    std::vector<PageRecord> table;
    TERRAIN_TRY(decode_page_table(table_bytes, world, header, table));
    const size_t page_bytes = size_t(header.page_entries) * layout::kEntrySize;
    for (uint64_t p = 0; p < table.size(); ++p) {
      const size_t at = size_t(p) * page_bytes;
      TERRAIN_TRY(decode_page(bytes.subspan(at, std::min(page_bytes, entries - at)), p, table, world, header,
                              out.data() + size_t(p) * header.page_entries));
    }
  }
  return validate_directory(out, header.payload_offset, header.payload_size, top_level(world));
}

Status decode_page_table(std::span<const uint8_t> bytes, const WorldInfo& world, const Header& header, std::vector<PageRecord>& out) {
  namespace f = layout::page_record;
  out.clear();
  if (bytes.size() != header.page_count() * layout::kPageRecordSize) return fail(Error::directory_invalid, "page table size mismatch");
  out.resize(size_t(header.page_count()));
  const int levels = level_count(world);
  for (size_t p = 0; p < out.size(); ++p) {
    const uint8_t* e = bytes.data() + p * layout::kPageRecordSize;
    PageRecord& r = out[p];
    r.first = {e[f::level], load_u32(e + f::x), load_u32(e + f::y)};
    r.crc32 = load_u32(e + f::page_crc32);
    const std::string where = "directory page " + std::to_string(p) + " (first node " + node_name(r.first) + "): ";
    if (!all_zero(e + f::reserved, 3)) return fail(Error::directory_invalid, where + "reserved bytes are not zero");
    if (r.first.level >= uint32_t(levels) || r.first.x >= level_grid_cells(world.roots_x, int(r.first.level)) ||
        r.first.y >= level_grid_cells(world.roots_y, int(r.first.level)))
      return fail(Error::directory_invalid, where + "the first key is outside the archive's levels and grids");
    if (p > 0 && !directory_less(out[p - 1].first, r.first))
      return fail(Error::directory_invalid, where + "the first key is not after page " + std::to_string(p - 1) + "'s (SPEC 20)");
  }
  return Status::success();
}

Status decode_page(std::span<const uint8_t> bytes, uint64_t page, std::span<const PageRecord> table, const WorldInfo& world,
                   const Header& header, NodeRecord* out) {
  const uint64_t first = page * header.page_entries;
  const uint64_t count = std::min<uint64_t>(header.page_entries, header.node_count - first);
  const std::string where = "directory page " + std::to_string(page) + ": ";
  if (bytes.size() != count * layout::kEntrySize) return fail(Error::directory_invalid, where + "size mismatch");
  if (crc32_of(bytes) != table[size_t(page)].crc32)
    return fail(Error::directory_checksum, where + "CRC-32 mismatch (at offset " +
                                               std::to_string(header.directory_offset + first * layout::kEntrySize) + ")");
  TERRAIN_TRY(decode_entries(bytes, size_t(first), world, header, out));
  if (!(out[0].key == table[size_t(page)].first))
    return fail(Error::directory_invalid, where + "its first node " + node_name(out[0].key) + " is not the page table's " +
                                              node_name(table[size_t(page)].first));
  for (size_t i = 1; i < count; ++i)
    if (!directory_less(out[i - 1].key, out[i].key))
      return fail(Error::directory_invalid, "entry " + std::to_string(first + i) + " (node " + node_name(out[i].key) +
                                                ") is not after node " + node_name(out[i - 1].key) +
                                                " (keys must be unique and in directory order, SPEC 20)");
  if (page + 1 < table.size() && !directory_less(out[count - 1].key, table[size_t(page) + 1].first))
    return fail(Error::directory_invalid, where + "its last node " + node_name(out[count - 1].key) +
                                              " is not before the next page's first node " + node_name(table[size_t(page) + 1].first));
  return Status::success();
}

void encode_page_table(std::span<const uint8_t> entries, std::span<const NodeRecord> nodes, uint32_t page_entries,
                       std::vector<uint8_t>& out) {
  namespace f = layout::page_record;
  const size_t pages = (nodes.size() + page_entries - 1) / page_entries;
  out.assign(pages * layout::kPageRecordSize, 0);
  for (size_t p = 0; p < pages; ++p) {
    const size_t first = p * page_entries, count = std::min<size_t>(page_entries, nodes.size() - first);
    uint8_t* e = out.data() + p * layout::kPageRecordSize;
    e[f::level] = uint8_t(nodes[first].key.level);
    store_u32(e + f::x, nodes[first].key.x);
    store_u32(e + f::y, nodes[first].key.y);
    store_u32(e + f::page_crc32, crc32_of(entries.subspan(first * layout::kEntrySize, count * layout::kEntrySize)));
  }
}

Status validate_directory(std::span<const NodeRecord> nodes, uint64_t payload_offset, uint64_t payload_size, int top) {
  for (size_t i = 1; i < nodes.size(); ++i)
    if (!directory_less(nodes[i - 1].key, nodes[i].key))
      return fail(Error::directory_invalid, "entry " + std::to_string(i) + " (node " + node_name(nodes[i].key) +
                                                ") is not after node " + node_name(nodes[i - 1].key) +
                                                " (keys must be unique and in directory order, SPEC 20)");
  // Payloads tile the payload section exactly: no gaps, no overlaps.
  std::vector<std::pair<uint64_t, uint32_t>> spans;
  spans.reserve(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) spans.emplace_back(nodes[i].payload_offset, uint32_t(i));
  std::sort(spans.begin(), spans.end());
  uint64_t at = payload_offset;
  for (const auto& [off, i] : spans) {
    if (off != at)
      return fail(Error::payload_out_of_bounds, "node " + node_name(nodes[i].key) + ": payload at " + std::to_string(off) +
                                                    (off < at ? " overlaps the previous payload" : " leaves a gap") +
                                                    " (expected offset " + std::to_string(at) + ")");
    at += nodes[i].payload_size;
  }
  if (at != payload_offset + payload_size)
    return fail(Error::payload_out_of_bounds, "payloads end at " + std::to_string(at) + " but the payload section ends at " +
                                                  std::to_string(payload_offset + payload_size));
  auto exists = [&](const NodeKey& k) {
    return std::binary_search(nodes.begin(), nodes.end(), NodeRecord{.key = k},
                              directory_record_less);
  };
  for (const NodeRecord& r : nodes) {
    if (r.key.level > 0)
      for (int c = 0; c < 4; ++c) {
        const bool has = exists(child_of(r.key, c));
        if (has != bool(r.child_mask & (1u << c)))
          return fail(Error::directory_invalid, "node " + node_name(r.key) + ": child_mask bit " + std::to_string(c) +
                                                    (has ? " is clear but child " : " is set but child ") +
                                                    node_name(child_of(r.key, c)) + (has ? " exists" : " is absent"));
      }
    if (r.key.level < uint32_t(top) && !exists(parent_of(r.key)))
      return fail(Error::directory_invalid, "node " + node_name(r.key) + ": parent " + node_name(parent_of(r.key)) + " is absent" +
                                                (r.key.level >= uint32_t(kRootLevel) ? " (overview levels are closed upward, SPEC 19)" : ""));
  }
  if (top > kRootLevel) {  // SPEC 19: a small top that a runtime can keep resident
    const auto top_nodes = size_t(std::count_if(nodes.begin(), nodes.end(), [top](const NodeRecord& r) { return r.key.level == uint32_t(top); }));
    if (top_nodes > kMaxTopNodes)
      return fail(Error::directory_invalid, "the top level " + std::to_string(top) + " has " + std::to_string(top_nodes) +
                                                " nodes, more than " + std::to_string(kMaxTopNodes) + " (SPEC 19)");
  }
  return Status::success();
}

}  // namespace terrain::detail
