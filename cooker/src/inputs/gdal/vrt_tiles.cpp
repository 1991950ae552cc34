// A VRT of plain GeoTIFF tiles read through the tiles' block readers (vrt_tiles.h says when).
#include "inputs/gdal/vrt_tiles.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_minixml.h>
#include <gdal_priv.h>

#include <algorithm>
#include <atomic>
#include <cfloat>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <map>

#include "inputs/source_raster.h"
#include "terrain/output_paths.h"
#include "inputs/tiff_blocks.h"
#include "inputs/gdal/vrt_stream.h"
#include "inputs/gdal/vrt_xml.h"

namespace terrain::cook {
namespace {

// VrtTileReader::state_ of a source's reader.
constexpr uint8_t kUntried = 0, kRefused = 1, kOpen = 2, kOpenUsed = 3;
std::atomic<size_t> open_tile_limit{16384};

enum class Type { none, u16, i16, u32, i32, f32 };

Type type_named(const char* name) {
  if (!name) return Type::none;
  const std::string n = name;
  if (n == "UInt16") return Type::u16;
  if (n == "Int16") return Type::i16;
  if (n == "UInt32") return Type::u32;
  if (n == "Int32") return Type::i32;
  if (n == "Float32") return Type::f32;
  return Type::none;
}

int bytes_of(Type t) { return t == Type::u16 || t == Type::i16 ? 2 : 4; }
// TIFF's SampleFormat of the type: 1 unsigned, 2 signed integer, 3 IEEE float.
int sample_format_of(Type t) { return t == Type::f32 ? 3 : t == Type::i16 || t == Type::i32 ? 2 : 1; }

// A native value of type `t` as its bytes in a 4-byte word (the slot's first bytes). False when
// `v` is not a value of the type (an integer type's nodata out of range or with a fraction).
bool native_bits(Type t, double v, uint32_t& bits) {
  bits = 0;
  auto whole = [&](double lo, double hi) { return std::isfinite(v) && v == std::floor(v) && v >= lo && v <= hi; };
  switch (t) {
    case Type::u16: { if (!whole(0, 65535)) return false; const uint16_t x = uint16_t(v); std::memcpy(&bits, &x, 2); return true; }
    case Type::i16: { if (!whole(-32768, 32767)) return false; const int16_t x = int16_t(v); std::memcpy(&bits, &x, 2); return true; }
    case Type::u32: { if (!whole(0, 4294967295.0)) return false; const uint32_t x = uint32_t(v); std::memcpy(&bits, &x, 4); return true; }
    case Type::i32: { if (!whole(-2147483648.0, 2147483647.0)) return false; const int32_t x = int32_t(v); std::memcpy(&bits, &x, 4); return true; }
    case Type::f32: { const float x = float(v); std::memcpy(&bits, &x, 4); return true; }
    case Type::none: return false;
  }
  return false;
}

// GDAL's rule for a ComplexSource's <NODATA> (vrtsources.cpp): the sample in its working type
// (float for 16-bit and Float32 buffers, double for 32-bit integers); NaN matches NaN, any other
// value ARE_REAL_EQUAL (a few ulps) to the NODATA in that type; nothing matches a NODATA out of
// the working type's range.
struct NodataRule {
  bool nan = false, in_range = false, wide = false;  // wide: double working type
  float f = 0;
  double d = 0;
  NodataRule(Type t, double nodata) {
    wide = t == Type::u32 || t == Type::i32;
    nan = std::isnan(nodata);
    in_range = !nan && (wide || std::fabs(nodata) <= double(FLT_MAX) || std::isinf(nodata));
    f = float(nodata);
    d = nodata;
  }
  bool matches(double v) const {
    if (wide) return nan ? std::isnan(v) : in_range && ARE_REAL_EQUAL(v, d);
    const float x = float(v);
    return nan ? std::isnan(x) : in_range && ARE_REAL_EQUAL(x, f);
  }
};

// Samples of type T (in 4-byte slots, `stride` slots apart row to row) that match `rule` become
// `fill`: what GDAL leaves where a ComplexSource does not draw and nothing lies under it.
template <class T>
void unmark(uint8_t* at, size_t stride, int w, int h, const NodataRule& rule, uint32_t fill) {
  for (int r = 0; r < h; ++r) {
    uint8_t* row = at + size_t(r) * stride * 4;
    for (int c = 0; c < w; ++c) {
      T v;
      std::memcpy(&v, row + 4 * c, sizeof(T));
      if (rule.matches(double(v))) std::memcpy(row + 4 * c, &fill, 4);
    }
  }
}

// Samples of `from` (w x h slots) drawn over `at` but those matching `rule`.
template <class T>
void draw(uint8_t* at, size_t stride, const uint8_t* from, int w, int h, const NodataRule& rule) {
  for (int r = 0; r < h; ++r) {
    uint8_t* row = at + size_t(r) * stride * 4;
    const uint8_t* src = from + size_t(r) * size_t(w) * 4;
    for (int c = 0; c < w; ++c) {
      T v;
      std::memcpy(&v, src + 4 * c, sizeof(T));
      if (!rule.matches(double(v))) std::memcpy(row + 4 * c, src + 4 * c, 4);
    }
  }
}

template <class F>
void by_type(Type t, F&& f) {
  switch (t) {
    case Type::u16: f(uint16_t{}); break;
    case Type::i16: f(int16_t{}); break;
    case Type::u32: f(uint32_t{}); break;
    case Type::i32: f(int32_t{}); break;
    case Type::f32: f(float{}); break;
    case Type::none: break;
  }
}

struct XmlTree {
  CPLXMLNode* root = nullptr;
  ~XmlTree() {
    if (root) CPLDestroyXMLNode(root);
  }
};

// A whole number of samples written as a decimal (gdalbuildvrt may write 1999.9999999997).
bool whole_samples(const char* text, int& out) {
  if (!text) return false;
  const double v = CPLAtof(text);
  const double r = std::round(v);
  if (!std::isfinite(v) || std::fabs(v - r) > 1e-6 || std::fabs(r) > 1e9) return false;
  out = int(r);
  return true;
}

bool rect_of(const CPLXMLNode* node, int& x, int& y, int& w, int& h) {
  return node && whole_samples(CPLGetXMLValue(node, "xOff", nullptr), x) &&
         whole_samples(CPLGetXMLValue(node, "yOff", nullptr), y) &&
         whole_samples(CPLGetXMLValue(node, "xSize", nullptr), w) &&
         whole_samples(CPLGetXMLValue(node, "ySize", nullptr), h);
}

// A <SourceFilename relativeToVRT="1"> anywhere under `node` (an overview or mask band's, which a
// cut in another folder would no longer find).
bool has_relative_name(const CPLXMLNode* node) {
  for (const CPLXMLNode* c = node; c; c = c->psNext) {
    if (c->eType != CXT_Element) continue;
    if (EQUAL(c->pszValue, "SourceFilename") && vrt_name_is_relative(c)) return true;
    if (has_relative_name(c->psChild)) return true;
  }
  return false;
}

}  // namespace

VrtTileReader::~VrtTileReader() = default;

Status VrtTileReader::open(const std::string& path, int width, int height, std::unique_ptr<VrtTileReader>& out) {
  out.reset();
  auto refuse = [](std::string why) { return Status::failure(Error::unsupported_input, std::move(why)); };
  if (!tiff_direct_enabled()) return refuse("TERRAIN_TIFF_DIRECT=0");
  // The dataset and its bands from the VRT without its sources, the sources one at a time after
  // (vrt_stream.h): a mosaic of a million tiles never stands in memory as one tree.
  VrtStream vrt;
  if (read_vrt_stream(path, vrt, {}) != VrtRead::ok) return refuse("not a VRT file the cooker's XML reader streams");
  XmlTree tree;
  CPLPushErrorHandler(CPLQuietErrorHandler);  // GDAL parsed it already; a refusal is not an error
  tree.root = CPLParseXMLString(vrt.header.c_str());
  CPLPopErrorHandler();
  const CPLXMLNode* ds = tree.root ? CPLGetXMLNode(tree.root, "=VRTDataset") : nullptr;
  if (!ds) return refuse("not a VRT file GDAL's XML reader parses");
  if (CPLGetXMLValue(ds, "subClass", nullptr)) return refuse("a derived VRT (warped, pansharpened, ...)");
  int w = 0, h = 0;
  if (!whole_samples(CPLGetXMLValue(ds, "rasterXSize", nullptr), w) ||
      !whole_samples(CPLGetXMLValue(ds, "rasterYSize", nullptr), h) || w != width || h != height)
    return refuse("its size is not the one GDAL reads");
  const CPLXMLNode* band = nullptr;
  for (const CPLXMLNode* n = ds->psChild; n; n = n->psNext)
    if (n->eType == CXT_Element && EQUAL(n->pszValue, "VRTRasterBand")) {  // band 0 of the stream
      band = n;
      break;
    }
  if (!band || std::strcmp(CPLGetXMLValue(band, "band", "1"), "1") != 0) return refuse("no first band");
  if (CPLGetXMLValue(band, "subClass", nullptr)) return refuse("a derived band (pixel function, warped, ...)");
  const Type type = type_named(CPLGetXMLValue(band, "dataType", nullptr));
  if (type == Type::none) return refuse(fmt::format("data type {}", CPLGetXMLValue(band, "dataType", "?")));

  std::unique_ptr<VrtTileReader> r(new VrtTileReader());
  r->width_ = width;
  r->height_ = height;
  // The window's first state (VRTSourcedRasterBand): the band's nodata, else 0.
  if (const char* nd = CPLGetXMLValue(band, "NoDataValue", nullptr)) {
    if (!native_bits(type, CPLAtofM(nd), r->fill_bits_)) return refuse(fmt::format("nodata {} for {}", nd, "its type"));
  }
  const std::string dir = vrt_folder(path);
  for (const CPLXMLNode* n = band->psChild; n; n = n->psNext) {
    if (n->eType != CXT_Element) continue;
    const std::string name = n->pszValue;
    if (name == "NoDataValue" || name == "ColorInterp" || name == "Description" || name == "Metadata" ||
        name == "Offset" || name == "Scale" || name == "UnitType" || name == "Histograms" || name == "Overview" ||
        name == "CategoryNames")
      continue;  // nothing a full-resolution read of raw values depends on (GDAL applies scale and offset after)
    return refuse(fmt::format("a <{}>", name));
  }
  std::string refusal;
  const auto add_source = [&](const VrtSourceVisit& visit) {
    if (visit.band != 0) return true;  // the first band only
    auto reject = [&](std::string why) {
      refusal = std::move(why);
      return false;
    };
    const CPLXMLNode* n = visit.node;
    const std::string name = n->pszValue;
    const bool complex = name == "ComplexSource";
    if (!complex && name != "SimpleSource") return reject(fmt::format("a <{}>", name));
    Source s;
    bool has_file = false, has_src = false, has_dst = false;
    int sw = 0, sh = 0;
    for (const CPLXMLNode* c = n->psChild; c; c = c->psNext) {
      if (c->eType != CXT_Element) continue;
      const std::string cn = c->pszValue;
      if (cn == "SourceFilename") {
        const char* f = CPLGetXMLValue(c, nullptr, "");
        if (!plain_file_name(f)) return reject(fmt::format("source {}", f));
        s.path = vrt_source_file(c, dir);
        has_file = true;
      } else if (cn == "SourceBand") {
        if (std::strcmp(CPLGetXMLValue(c, nullptr, ""), "1") != 0) return reject("a source band other than 1");
      } else if (cn == "SourceProperties") {
        if (!whole_samples(CPLGetXMLValue(c, "RasterXSize", nullptr), s.tile_w) ||
            !whole_samples(CPLGetXMLValue(c, "RasterYSize", nullptr), s.tile_h) ||
            type_named(CPLGetXMLValue(c, "DataType", nullptr)) != type)
          return reject("a source of another data type or without its size");
        int block_h = 0;  // for the block cache's size before the tile opens
        if (whole_samples(CPLGetXMLValue(c, "BlockYSize", nullptr), block_h) && block_h > 0)
          note_tiff_block_column(uint64_t(std::min(block_h, s.tile_h)) * uint64_t(bytes_of(type)));
      } else if (cn == "SrcRect") {
        has_src = rect_of(c, s.src_x, s.src_y, sw, sh);
        if (!has_src) return reject("a SrcRect off whole samples");
      } else if (cn == "DstRect") {
        has_dst = rect_of(c, s.dst_x, s.dst_y, s.w, s.h);
        if (!has_dst) return reject("a DstRect off whole samples");
      } else if (cn == "NODATA" && complex) {
        s.nodata_value = CPLAtofM(CPLGetXMLValue(c, nullptr, ""));
        const NodataRule rule(type, s.nodata_value);
        s.has_nodata = rule.nan || rule.in_range;  // out of the working type's range it matches nothing
      } else {
        return reject(fmt::format("a source with <{}>", cn));
      }
    }
    if (!has_file || !has_src || !has_dst || s.tile_w <= 0 || s.tile_h <= 0) return reject("a source without its rectangles");
    if (sw != s.w || sh != s.h || s.w <= 0 || s.h <= 0) return reject("a resampled source");
    if (s.src_x < 0 || s.src_y < 0 || s.src_x + s.w > s.tile_w || s.src_y + s.h > s.tile_h)
      return reject("a SrcRect outside its tile");
    // Clipped to the raster, as GDAL draws it; a source wholly outside draws nothing.
    const int cx0 = std::max(0, s.dst_x), cy0 = std::max(0, s.dst_y);
    const int cx1 = std::min(width, s.dst_x + s.w), cy1 = std::min(height, s.dst_y + s.h);
    if (cx0 >= cx1 || cy0 >= cy1) return true;
    s.src_x += cx0 - s.dst_x;
    s.src_y += cy0 - s.dst_y;
    s.dst_x = cx0;
    s.dst_y = cy0;
    s.w = cx1 - cx0;
    s.h = cy1 - cy0;
    r->sources_.push_back(std::move(s));
    return true;
  };
  if (const VrtRead read = read_vrt_stream(path, vrt, add_source); read != VrtRead::ok)
    return refuse(read == VrtRead::stopped ? refusal : "not a VRT file the cooker's XML reader streams");
  if (r->sources_.empty()) return refuse("no source");
  // A source is drawn sample by sample only where an earlier source may lie under it; else its
  // samples are read in place and those matching its NODATA set back to the band's fill.
  // Buckets as large as the largest source: each source lies in at most 2 x 2 of them.
  std::map<std::pair<int, int>, std::vector<size_t>> cells;
  int cell = 64;
  for (const Source& s : r->sources_) cell = std::max({cell, s.w, s.h});
  auto cell_of = [&](int v) { return int(std::floor(double(v) / cell)); };
  for (size_t i = 0; i < r->sources_.size(); ++i) {
    Source& s = r->sources_[i];
    for (int cy = cell_of(s.dst_y); cy <= cell_of(s.dst_y + s.h - 1); ++cy)
      for (int cx = cell_of(s.dst_x); cx <= cell_of(s.dst_x + s.w - 1); ++cx) {
        std::vector<size_t>& v = cells[{cx, cy}];
        for (size_t j : v) {
          const Source& e = r->sources_[j];
          if (e.dst_x < s.dst_x + s.w && s.dst_x < e.dst_x + e.w && e.dst_y < s.dst_y + s.h && s.dst_y < e.dst_y + e.h)
            s.composed = s.has_nodata;
        }
        v.push_back(i);
      }
  }
  // The grid: cells as large as the largest source (each source meets at most 2 x 2 of them), and
  // no more cells than about four per source (a few small tiles over a vast raster).
  const double per_cell = double(width) * double(height) / (4.0 * double(r->sources_.size()) + 1.0);
  cell = std::max(cell, int(std::min(std::ceil(std::sqrt(per_cell)), double(std::max(width, height)))));
  r->cell_ = cell;
  r->cells_x_ = (width + cell - 1) / cell;
  r->cells_y_ = (height + cell - 1) / cell;
  r->cell_start_.assign(size_t(r->cells_x_) * size_t(r->cells_y_) + 1, 0);
  const auto for_cells = [&](const Source& s, auto&& f) {
    for (int cy = s.dst_y / cell; cy <= (s.dst_y + s.h - 1) / cell; ++cy)
      for (int cx = s.dst_x / cell; cx <= (s.dst_x + s.w - 1) / cell; ++cx) f(size_t(cy) * size_t(r->cells_x_) + size_t(cx));
  };
  for (const Source& s : r->sources_) for_cells(s, [&](size_t k) { ++r->cell_start_[k + 1]; });
  for (size_t k = 1; k < r->cell_start_.size(); ++k) r->cell_start_[k] += r->cell_start_[k - 1];
  r->cell_sources_.resize(r->cell_start_.back());
  {
    std::vector<uint32_t> fill(r->cell_start_.begin(), r->cell_start_.end() - 1);
    for (size_t i = 0; i < r->sources_.size(); ++i) for_cells(r->sources_[i], [&](size_t k) { r->cell_sources_[fill[k]++] = uint32_t(i); });
  }
  r->type_ = int(type);
  r->tiles_.resize(r->sources_.size());
  r->state_.assign(r->sources_.size(), kUntried);
  out = std::move(r);
  return Status::success();
}

size_t VrtTileReader::set_open_tile_limit(size_t limit) { return open_tile_limit.exchange(limit); }

std::shared_ptr<const TiffBlockReader> VrtTileReader::tile(size_t i) const {
  std::lock_guard<std::mutex> lock(m_);
  if (state_[i] == kOpen || state_[i] == kOpenUsed) {
    state_[i] = kOpenUsed;
    return tiles_[i];
  }
  if (state_[i] == kRefused) return nullptr;
  const Source& s = sources_[i];
  const Type type = Type(type_);
  std::unique_ptr<TiffBlockReader> t;
  // A tile the block reader refuses is read by GDAL (the refusal's reason is not needed here). The
  // tile must hold the type its SourceProperties claim (GDAL converts what it finds; a stale VRT
  // over a replaced tile may claim another type of the same size).
  if (!TiffBlockReader::open(s.path, s.tile_w, s.tile_h, bytes_of(type), t).ok() ||
      t->layout().sample_format != sample_format_of(type)) {
    state_[i] = kRefused;
    return nullptr;
  }
  tiles_[i] = std::move(t);
  state_[i] = kOpenUsed;
  if (open_.size() < std::max<size_t>(1, open_tile_limit.load())) {
    open_.push_back(uint32_t(i));
    return tiles_[i];
  }
  // The clock: the first open reader not used since the hand last passed is closed (a read still
  // holding it keeps it until it ends), and this one takes its place.
  for (;; hand_ = (hand_ + 1) % open_.size()) {
    const uint32_t j = open_[hand_];
    if (state_[j] == kOpenUsed) {
      state_[j] = kOpen;
      continue;
    }
    tiles_[j].reset();
    state_[j] = kUntried;
    open_[hand_] = uint32_t(i);
    hand_ = (hand_ + 1) % open_.size();
    return tiles_[i];
  }
}

void VrtTileReader::sources_in(int x0, int y0, int w, int h, std::vector<uint32_t>& out) const {
  out.clear();
  const int cx0 = std::max(0, x0 / cell_), cx1 = std::min(cells_x_ - 1, (x0 + w - 1) / cell_);
  const int cy0 = std::max(0, y0 / cell_), cy1 = std::min(cells_y_ - 1, (y0 + h - 1) / cell_);
  for (int cy = cy0; cy <= cy1; ++cy)
    for (int cx = cx0; cx <= cx1; ++cx) {
      const size_t k = size_t(cy) * size_t(cells_x_) + size_t(cx);
      out.insert(out.end(), cell_sources_.begin() + cell_start_[k], cell_sources_.begin() + cell_start_[k + 1]);
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

uint64_t VrtTileReader::scratch_bytes(int w, int h) const {
  for (const Source& s : sources_)
    if (s.composed) return uint64_t(w) * uint64_t(h) * 4;
  return 0;
}

bool VrtTileReader::read_window(int x0, int y0, int w, int h, uint8_t* slots, int threads) const {
  if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > width_ || y0 + h > height_) return false;
  const Type type = Type(type_);
  auto overlap = [&](const Source& s, int& cx0, int& cy0, int& cx1, int& cy1) {
    cx0 = std::max(x0, s.dst_x), cx1 = std::min(x0 + w, s.dst_x + s.w);
    cy0 = std::max(y0, s.dst_y), cy1 = std::min(y0 + h, s.dst_y + s.h);
    return cx0 < cx1 && cy0 < cy1;
  };
  // Every tile of the window first: one left to GDAL makes the whole window GDAL's, before any
  // other tile is decoded for nothing.
  static thread_local std::vector<uint32_t> near;
  static thread_local std::vector<std::shared_ptr<const TiffBlockReader>> held;  // open for the whole read
  struct Release {  // however the read ends: a closed tile's reader goes with it
    ~Release() { held.clear(); }
  } release;
  sources_in(x0, y0, w, h, near);
  held.assign(near.size(), nullptr);
  for (size_t n = 0; n < near.size(); ++n) {
    int cx0, cy0, cx1, cy1;
    if (overlap(sources_[near[n]], cx0, cy0, cx1, cy1) && !(held[n] = tile(near[n]))) return false;
  }
  std::fill_n(reinterpret_cast<uint32_t*>(slots), size_t(w) * size_t(h), fill_bits_);  // slots are 4-byte words
  std::vector<uint8_t> scratch;
  for (size_t n = 0; n < near.size(); ++n) {
    const Source& s = sources_[near[n]];
    int cx0, cy0, cx1, cy1;
    if (!overlap(s, cx0, cy0, cx1, cy1)) continue;
    const TiffBlockReader* t = held[n].get();
    const int tx = s.src_x + (cx0 - s.dst_x), ty = s.src_y + (cy0 - s.dst_y), tw = cx1 - cx0, th = cy1 - cy0;
    uint8_t* at = slots + (size_t(cy0 - y0) * size_t(w) + size_t(cx0 - x0)) * 4;
    const NodataRule rule(type, s.nodata_value);
    if (!s.composed) {
      if (!t->read_window(tx, ty, tw, th, at, threads, size_t(w))) return false;
      // Nothing lies under it: a sample GDAL would not draw keeps the fill.
      if (s.has_nodata)
        by_type(type, [&](auto zero) { unmark<decltype(zero)>(at, size_t(w), tw, th, rule, fill_bits_); });
      continue;
    }
    scratch.resize(size_t(tw) * size_t(th) * 4);
    if (!t->read_window(tx, ty, tw, th, scratch.data(), threads)) return false;
    by_type(type, [&](auto zero) { draw<decltype(zero)>(at, size_t(w), scratch.data(), tw, th, rule); });
  }
  return true;
}

Status write_vrt_windows(const std::string& path, const std::vector<std::array<int, 4>>& windows,
                         const std::vector<std::string>& outputs, bool& written) {
  written = false;
  if (!path.ends_with(".vrt") || windows.size() != outputs.size()) return Status::success();
  const std::string dir = vrt_folder(std::filesystem::absolute(path).lexically_normal().string());
  // Each source's bytes in the VRT and its DstRect (x0, y0, x1, y1; infinite when it has none: it
  // is kept in every cut), streamed (vrt_stream.h): the cuts read the sources' text again.
  struct SourceSpan {
    int band = 0;
    uint64_t begin = 0, end = 0;
    std::array<double, 4> rect{-INFINITY, -INFINITY, INFINITY, INFINITY};
    bool relative = false;  // its SourceFilename is written out absolute
  };
  std::vector<SourceSpan> sources;
  const auto note = [&](const VrtSourceVisit& v) {
    SourceSpan s{v.band, v.begin, v.end};
    if (const CPLXMLNode* f = CPLGetXMLNode(v.node, "SourceFilename"); f && vrt_name_is_relative(f)) {
      // /vsi... and driver:prefixed names resolve relative to the VRT in GDAL's own ways.
      if (!plain_file_name(CPLGetXMLValue(f, nullptr, ""))) return false;
      s.relative = true;
    }
    if (VrtRect d; vrt_dst_rect(v.node, d)) s.rect = {d.x, d.y, d.x + d.w, d.y + d.h};
    sources.push_back(s);
    return true;
  };
  VrtStream vrt;
  if (read_vrt_stream(path, vrt, note) != VrtRead::ok) return Status::success();  // the units' open names what is wrong
  {
    XmlTree header;
    header.root = CPLParseXMLString(vrt.header.c_str());
    if (!header.root || has_relative_name(header.root)) return Status::success();  // left after the sources' own
  }
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> in(std::fopen(path.c_str(), "rb"), std::fclose);
  if (!in) return Status::success();
  // A source's text as the cut holds it: its bytes, or with its relative name made absolute.
  const auto source_text = [&](const SourceSpan& s, std::string& text) {
    text.resize(size_t(s.end - s.begin));
    if (fseeko(in.get(), off_t(s.begin), SEEK_SET) != 0 || std::fread(text.data(), 1, text.size(), in.get()) != text.size())
      return false;
    if (!s.relative) return true;
    XmlTree t;
    t.root = CPLParseXMLString(text.c_str());
    CPLXMLNode* f = t.root ? CPLGetXMLNode(t.root, "SourceFilename") : nullptr;
    if (!f) return false;
    const std::string full = vrt_source_file(f, dir);
    CPLSetXMLValue(f, "#relativeToVRT", "0");
    for (CPLXMLNode* c = f->psChild; c; c = c->psNext)
      if (c->eType == CXT_Text) {
        CPLFree(c->pszValue);
        c->pszValue = CPLStrdup(full.c_str());
      }
    char* xml = CPLSerializeXMLTree(t.root);
    text = xml ? xml : "";
    CPLFree(xml);
    return !text.empty();
  };
  std::string text;
  for (size_t w = 0; w < windows.size(); ++w) {
    // Samples c0..c1 cover [c0, c1 + 1); one more on every side for a source's edge.
    const auto& [c0, r0, c1, r1] = windows[w];
    const std::string temp = staging_path(outputs[w]);
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(temp.c_str(), "wb"), std::fclose);
    bool ok = f != nullptr, readable = true;
    int err = ok ? 0 : errno;
    const auto put = [&](std::string_view t) {
      if (ok && std::fwrite(t.data(), 1, t.size(), f.get()) != t.size()) ok = false, err = errno;
    };
    size_t at = 0;  // header bytes written
    for (size_t i = 0; ok && readable && i < sources.size(); ++i) {
      const SourceSpan& s = sources[i];
      if (i == 0 || sources[i - 1].band != s.band) {  // the band's sources stood here
        const size_t to = vrt.band_sources_at[size_t(s.band)];
        put(std::string_view(vrt.header).substr(at, to - at));
        at = to;
      }
      const auto& r = s.rect;
      if (!(r[0] < c1 + 2 && r[2] > c0 - 1 && r[1] < r1 + 2 && r[3] > r0 - 1)) continue;
      readable = source_text(s, text);
      put(text);
    }
    put(std::string_view(vrt.header).substr(at));
    if (ok && std::fclose(f.release()) != 0) ok = false, err = errno;
    if (ok && readable && std::rename(temp.c_str(), outputs[w].c_str()) != 0) ok = false, err = errno;
    if (!ok || !readable) {
      f.reset();
      std::remove(temp.c_str());
      // A VRT that changed under the plan gives no cut: the units' open names what is wrong.
      if (!readable) return Status::success();
      return Status::failure(Error::io_write, fmt::format("{}: cannot write: {}", outputs[w], std::strerror(err)));
    }
  }
  written = true;
  return Status::success();
}

}  // namespace terrain::cook
