// A plain GeoTIFF's blocks decoded without GDAL (tiff_blocks.h says when and why).
#include "inputs/tiff_blocks.h"

#include <fcntl.h>
#include <libdeflate.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <atomic>
#include <cstdarg>
#include <cstdlib>
#include <cstring>
#include <fmt/format.h>
#include <list>
#include <mutex>
#include <unordered_map>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "base/parallel.h"
#include "base/slab_pool.h"
#include "terrain/zstd_context.h"

namespace terrain::cook {
namespace {

constexpr int kCompressionNone = 1, kCompressionLzw = 5, kCompressionDeflate = 8, kCompressionAdobeDeflate = 32946,
              kCompressionZstd = 50000;
// Bytes past a decoded block that its buffer keeps, so that the LZW decoder may store 16 at a time.
constexpr size_t kBlockSlack = 16;

// Where decoded blocks live: slots of huge-page slabs (slab_pool.h). A fresh block on a fresh page
// cost the first pass more than its inflating did, and every work unit pays that fill again.
// Never destroyed: a block may be dropped by a static's destructor (the cache's) after it.
SlabPool& block_pool() {
  static SlabPool* pool = new SlabPool();
  return *pool;
}

// The process-wide cache of decoded blocks: key = reader id << 32 | block index. A block it drops
// goes back to the pool once nobody holds it, for the next decode to write into.
class BlockCache {
 public:
  using Block = std::shared_ptr<TiffBlockBytes>;
  static BlockCache& get() {
    static BlockCache cache;
    return cache;
  }
  void set_budget(uint64_t bytes) {
    std::lock_guard<std::mutex> lock(m_);
    budget_ = bytes;
    evict();
  }
  uint64_t used() { return block_pool().touched_bytes(); }  // cached, held and free blocks
  Block find(uint64_t key) {
    std::lock_guard<std::mutex> lock(m_);
    auto it = map_.find(key);
    if (it == map_.end()) return nullptr;
    lru_.splice(lru_.begin(), lru_, it->second.pos);  // most recent first
    return it->second.block;
  }
  void put(uint64_t key, const Block& b) {
    std::lock_guard<std::mutex> lock(m_);
    if (map_.count(key)) return;  // another thread decoded it too (the same bytes)
    lru_.push_front(key);
    map_.emplace(key, Entry{b, lru_.begin()});
    bytes_ += b->size;
    evict();
  }
  // A block of `size` bytes to decode into (not zeroed: every byte is written by the decode);
  // its bytes are null when the system has no memory left.
  static Block fresh(size_t size) {
    auto b = std::make_shared<TiffBlockBytes>();
    b->bytes = block_pool().take(size + kBlockSlack);
    b->size = size;
    return b;
  }
  void forget(uint64_t id) {
    std::lock_guard<std::mutex> lock(m_);
    for (auto it = lru_.begin(); it != lru_.end();) {
      if ((*it >> 32) != id) {
        ++it;
        continue;
      }
      auto e = map_.find(*it);
      bytes_ -= e->second.block->size;
      map_.erase(e);
      it = lru_.erase(it);
    }
  }

 private:
  struct Entry {
    Block block;
    std::list<uint64_t>::iterator pos;
  };
  void evict() {
    while (bytes_ > budget_ && !lru_.empty()) {
      auto e = map_.find(lru_.back());
      bytes_ -= e->second.block->size;
      map_.erase(e);
      lru_.pop_back();
    }
  }
  std::mutex m_;
  std::unordered_map<uint64_t, Entry> map_;
  std::list<uint64_t> lru_;
  uint64_t bytes_ = 0, budget_ = uint64_t(64) << 20;
};

std::atomic<uint64_t> g_next_reader_id{1};
// The largest block_h x bytes per sample of any reader opened (tiff_block_rows_bytes).
std::atomic<uint64_t> g_tallest_block_column{0};

// Per decoding thread: the deflate inflater, the compressed bytes and a scratch row for the
// floating-point predictor (zstd's context is the thread's one, terrain/zstd_context.h).
struct ThreadDecoders {
  libdeflate_decompressor* deflate = nullptr;
  std::vector<uint8_t> compressed, row;
  ~ThreadDecoders() {
    if (deflate) libdeflate_free_decompressor(deflate);
  }
};
ThreadDecoders& thread_decoders() {
  thread_local ThreadDecoders d;
  return d;
}

// libtiff's messages are not ours to print: a file the reader refuses is read by GDAL, which
// names what is wrong with it.
int quiet(TIFF*, void*, const char*, const char*, va_list) { return 1; }

// Reads the layout of `path`'s first image with libtiff; an empty string when it is one this
// reader decodes, else what it is instead.
std::string read_layout(const std::string& path, TiffBlockLayout& out) {
  TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
  TIFFOpenOptionsSetErrorHandlerExtR(opts, quiet, nullptr);
  TIFFOpenOptionsSetWarningHandlerExtR(opts, quiet, nullptr);
  TIFF* tif = TIFFOpenExt(path.c_str(), "r", opts);
  TIFFOpenOptionsFree(opts);
  if (!tif) return "libtiff cannot open it";
  struct Close {
    TIFF* t;
    ~Close() { TIFFClose(t); }
  } close{tif};
  if (TIFFIsByteSwapped(tif)) return "byte order other than the host's";
  uint32_t w = 0, h = 0;
  uint16_t spp = 1, bps = 0, format = SAMPLEFORMAT_UINT, compression = 1, predictor = 1, fill = FILLORDER_MSB2LSB;
  TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w);
  TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
  TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bps);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &format);
  TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
  TIFFGetFieldDefaulted(tif, TIFFTAG_FILLORDER, &fill);
  TIFFGetFieldDefaulted(tif, TIFFTAG_PREDICTOR, &predictor);
  if (spp != 1) return fmt::format("{} samples per pixel", spp);
  if (bps != 8 && bps != 16 && bps != 32) return fmt::format("{}-bit samples", bps);
  if (format != SAMPLEFORMAT_UINT && format != SAMPLEFORMAT_INT && format != SAMPLEFORMAT_IEEEFP)
    return fmt::format("sample format {}", format);
  if (format == SAMPLEFORMAT_IEEEFP && bps != 32) return fmt::format("{}-bit floating point", bps);
  // Uncompressed samples GDAL copies straight from the file, reading only a window's columns of a
  // strip: no decoding to save (1-row strips in 2048-wide windows: 0.19 CPU s here, GDAL 0.11).
  if (compression == kCompressionNone) return "no compression (GDAL reads it in place)";
  if (compression != kCompressionLzw && compression != kCompressionDeflate &&
      compression != kCompressionAdobeDeflate && compression != kCompressionZstd)
    return fmt::format("compression {}", compression);
  if (predictor != 1 && predictor != 2 && predictor != 3) return fmt::format("predictor {}", predictor);
  if (predictor == 3 && format != SAMPLEFORMAT_IEEEFP) return "floating-point predictor on integers";
  if (fill != FILLORDER_MSB2LSB) return "reversed bit fill order";
  out.width = int(w);
  out.height = int(h);
  out.bytes_per_sample = bps / 8;
  out.sample_format = format;
  out.compression = compression;
  out.predictor = predictor;
  out.tiled = TIFFIsTiled(tif) != 0;
  uint64_t* offsets = nullptr;
  uint64_t* counts = nullptr;
  uint32_t blocks = 0;
  if (out.tiled) {
    uint32_t tw = 0, th = 0;
    TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw);
    TIFFGetField(tif, TIFFTAG_TILELENGTH, &th);
    out.block_w = int(tw);
    out.block_h = int(th);
    blocks = TIFFNumberOfTiles(tif);
    if (!TIFFGetField(tif, TIFFTAG_TILEOFFSETS, &offsets) || !TIFFGetField(tif, TIFFTAG_TILEBYTECOUNTS, &counts))
      return "no tile offsets";
  } else {
    uint32_t rps = 0;
    TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rps);
    out.block_w = int(w);
    out.block_h = int(std::min(rps, h));
    blocks = TIFFNumberOfStrips(tif);
    if (!TIFFGetField(tif, TIFFTAG_STRIPOFFSETS, &offsets) || !TIFFGetField(tif, TIFFTAG_STRIPBYTECOUNTS, &counts))
      return "no strip offsets";
  }
  if (out.block_w <= 0 || out.block_h <= 0 || w == 0 || h == 0) return "empty blocks";
  const uint64_t across = (uint64_t(w) + uint64_t(out.block_w) - 1) / uint64_t(out.block_w);
  const uint64_t down = (uint64_t(h) + uint64_t(out.block_h) - 1) / uint64_t(out.block_h);
  if (across * down != blocks || blocks > (uint64_t(1) << 31)) return "block count does not match the image";
  // Lidar tiles are at most a few MB; a larger block is left to GDAL's own checks.
  if (uint64_t(out.block_w) * uint64_t(out.block_h) * uint64_t(out.bytes_per_sample) > (uint64_t(1) << 28))
    return "blocks larger than 256 MB";
  out.offsets.assign(offsets, offsets + blocks);
  out.byte_counts.assign(counts, counts + blocks);
  return "";
}

#if defined(__SSE2__)
// Running sums within one 16-byte vector, lanes of 1, 2 or 4 bytes.
inline __m128i prefix8(__m128i x) {
  x = _mm_add_epi8(x, _mm_slli_si128(x, 1));
  x = _mm_add_epi8(x, _mm_slli_si128(x, 2));
  x = _mm_add_epi8(x, _mm_slli_si128(x, 4));
  return _mm_add_epi8(x, _mm_slli_si128(x, 8));
}
inline __m128i prefix16(__m128i x) {
  x = _mm_add_epi16(x, _mm_slli_si128(x, 2));
  x = _mm_add_epi16(x, _mm_slli_si128(x, 4));
  return _mm_add_epi16(x, _mm_slli_si128(x, 8));
}
inline __m128i prefix32(__m128i x) {
  x = _mm_add_epi32(x, _mm_slli_si128(x, 4));
  return _mm_add_epi32(x, _mm_slli_si128(x, 8));
}
// The last lane of v in every lane.
inline __m128i last8(__m128i v) {
  const __m128i b = _mm_srli_si128(v, 15);
  const __m128i w = _mm_unpacklo_epi8(b, b);
  return _mm_shuffle_epi32(_mm_shufflelo_epi16(w, 0), 0);
}
inline __m128i last16(__m128i v) { return _mm_shuffle_epi32(_mm_shufflehi_epi16(v, 0xFF), 0xFF); }
inline __m128i last32(__m128i v) { return _mm_shuffle_epi32(v, 0xFF); }

// Running sum of n bytes in place (the carry in `carry`'s lanes); returns the new carry.
template <int Lane>
__m128i running_sum(uint8_t* p, size_t n, __m128i carry) {
  size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + i));
    if constexpr (Lane == 1) x = _mm_add_epi8(prefix8(x), carry), carry = last8(x);
    if constexpr (Lane == 2) x = _mm_add_epi16(prefix16(x), carry), carry = last16(x);
    if constexpr (Lane == 4) x = _mm_add_epi32(prefix32(x), carry), carry = last32(x);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(p + i), x);
  }
  (void)n;
  return carry;
}
#endif

template <typename T>
void running_sum_scalar(uint8_t* p, size_t from, size_t samples) {
  for (size_t i = std::max<size_t>(from, 1); i < samples; ++i) {
    T a, b;
    std::memcpy(&a, p + (i - 1) * sizeof(T), sizeof(T));
    std::memcpy(&b, p + i * sizeof(T), sizeof(T));
    b = T(a + b);
    std::memcpy(p + i * sizeof(T), &b, sizeof(T));
  }
}

}  // namespace

void undo_horizontal_predictor(uint8_t* row, int samples, int bytes_per_sample, bool scalar) {
  if (samples <= 1) return;
  size_t done = 0;  // samples already summed
#if defined(__SSE2__)
  if (!scalar) {
    const size_t bytes = size_t(samples) * size_t(bytes_per_sample);
    const size_t vec = bytes / 16 * 16;
    const __m128i zero = _mm_setzero_si128();
    if (bytes_per_sample == 1) running_sum<1>(row, vec, zero);
    if (bytes_per_sample == 2) running_sum<2>(row, vec, zero);
    if (bytes_per_sample == 4) running_sum<4>(row, vec, zero);
    done = vec / size_t(bytes_per_sample);
  }
#endif
  (void)scalar;
  // The tail (and the whole row for the definition) continues from the last summed sample.
  if (bytes_per_sample == 1) running_sum_scalar<uint8_t>(row, done, size_t(samples));
  if (bytes_per_sample == 2) running_sum_scalar<uint16_t>(row, done, size_t(samples));
  if (bytes_per_sample == 4) running_sum_scalar<uint32_t>(row, done, size_t(samples));
}

void undo_float_predictor(uint8_t* row, int samples, uint8_t* out, bool scalar) {
  const size_t n = size_t(samples), bytes = 4 * n;
  // 1. Undo the byte differences along the whole row (4 planes, one after the other).
  undo_horizontal_predictor(row, int(bytes), 1, scalar);
  // 2. Interleave the planes: sample i = (p3[i], p2[i], p1[i], p0[i]) in little-endian order.
  const uint8_t *p0 = row, *p1 = row + n, *p2 = row + 2 * n, *p3 = row + 3 * n;
  size_t i = 0;
#if defined(__SSE2__)
  if (!scalar)
    for (; i + 16 <= n; i += 16) {
      const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p3 + i));
      const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p2 + i));
      const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p1 + i));
      const __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p0 + i));
      const __m128i ab_lo = _mm_unpacklo_epi8(a, b), ab_hi = _mm_unpackhi_epi8(a, b);
      const __m128i cd_lo = _mm_unpacklo_epi8(c, d), cd_hi = _mm_unpackhi_epi8(c, d);
      __m128i* o = reinterpret_cast<__m128i*>(out + 4 * i);
      _mm_storeu_si128(o + 0, _mm_unpacklo_epi16(ab_lo, cd_lo));
      _mm_storeu_si128(o + 1, _mm_unpackhi_epi16(ab_lo, cd_lo));
      _mm_storeu_si128(o + 2, _mm_unpacklo_epi16(ab_hi, cd_hi));
      _mm_storeu_si128(o + 3, _mm_unpackhi_epi16(ab_hi, cd_hi));
    }
#endif
  for (; i < n; ++i) {
    out[4 * i + 0] = p3[i];
    out[4 * i + 1] = p2[i];
    out[4 * i + 2] = p1[i];
    out[4 * i + 3] = p0[i];
  }
}

// TIFF's LZW (TIFF 6.0 section 13: codes of 9 to 12 bits, most significant bit first, Clear 256,
// EndOfInformation 257, the width growing one code early) into out[0, need), which has kBlockSlack
// writable bytes past it. Every table entry is the previous code's string plus one byte, and the
// output holds that string where the previous code was written, so an entry is kept as a start in
// the output and a length: decoding copies ranges of the output, with no prefix chains to walk.
// False wherever libtiff's decoder fails (no Clear first, a code not yet in the table, a literal
// expected after Clear, too little data) and on the pre-6.0 bit order (left to GDAL).
bool lzw_decode(const uint8_t* in, size_t n, uint8_t* out, size_t need) {
  if (n >= 2 && in[0] == 0 && (in[1] & 1)) return false;  // old-style LZW (libtiff's "compat" decoder)
  constexpr int kClear = 256, kEnd = 257, kFirst = 258, kMaxCodes = 4096;
  static_assert(kBlockSlack >= 16, "the copies below store 16 bytes at a time");
  uint32_t start[kMaxCodes], length[kMaxCodes];
  uint64_t bits = 0;  // the next input bits, most significant first: `have` of them
  int have = 0;
  size_t at = 0;      // next input byte
  auto read_code = [&](int width) -> int {
    if (have < width) {
      if (at + 8 <= n) {  // whole bytes, as many as fit
        uint64_t w;
        std::memcpy(&w, in + at, 8);
        w = __builtin_bswap64(w);
        const int take = (64 - have) / 8;  // 6 to 8: have < width <= 12
        if (take < 8) w &= ~uint64_t(0) << (64 - 8 * take);
        bits |= w >> have;
        at += size_t(take);
        have += 8 * take;
      } else {
        while (have <= 56 && at < n) {
          bits |= uint64_t(in[at++]) << (56 - have);
          have += 8;
        }
        if (have < width) return kEnd;  // the data ended without EndOfInformation
      }
    }
    const int code = int(bits >> (64 - width));
    bits <<= width;
    have -= width;
    return code;
  };
  int width = 9, next = kFirst;
  bool cleared = false;       // libtiff's streams start with Clear
  size_t pos = 0;             // next output byte
  size_t prev_at = 0;         // where the previous code's string was written ...
  uint32_t prev_len = 0;      // ... and its length; 0 just after a Clear
  while (pos < need) {
    const int code = read_code(width);
    if (code == kEnd) break;
    if (code == kClear) {
      width = 9;
      next = kFirst;
      prev_len = 0;
      cleared = true;
      continue;
    }
    if (!cleared) return false;
    const size_t here = pos;
    uint32_t len = 0;
    if (code < 256) {
      out[pos] = uint8_t(code);
      len = 1;
      pos += 1;
    } else if (prev_len == 0) {
      return false;  // after Clear a literal must come
    } else if (code < next) {
      len = length[code];
      const size_t copy = std::min<size_t>(len, need - pos);
      const uint8_t* from = out + start[code];  // a string written before `here`
      if (copy <= 16) {
        uint8_t tmp[16];
        std::memcpy(tmp, from, 16);  // may read past the string, never past the buffer's slack
        std::memcpy(out + pos, tmp, 16);
      } else {
        std::memcpy(out + pos, from, copy);
      }
      pos += copy;
    } else if (code == next) {
      // The previous string and its own first byte: copied forward, overlapping itself.
      len = prev_len + 1;
      const size_t copy = std::min<size_t>(len, need - pos);
      const uint8_t* from = out + prev_at;
      for (size_t i = 0; i < copy; ++i) out[pos + i] = from[i];
      pos += copy;
    } else {
      return false;  // a code beyond the table
    }
    if (prev_len > 0 && next < kMaxCodes) {
      // The previous string plus this one's first byte, which follows it in the output.
      start[next] = uint32_t(prev_at);
      length[next] = prev_len + 1;
      ++next;
      if (next == (1 << width) - 1 && width < 12) ++width;
    }
    prev_at = here;
    prev_len = len;
  }
  return pos == need;
}

void set_tiff_block_cache_bytes(uint64_t bytes) { BlockCache::get().set_budget(bytes); }

uint64_t tiff_block_cache_used_bytes() { return BlockCache::get().used(); }

uint64_t tiff_block_rows_bytes(int width) {
  return 2 * uint64_t(std::max(width, 0)) * g_tallest_block_column.load();
}

void note_tiff_block_column(uint64_t column) {
  for (uint64_t seen = g_tallest_block_column.load(); column > seen;)
    if (g_tallest_block_column.compare_exchange_weak(seen, column)) break;
}

bool tiff_direct_enabled() {
  const char* v = std::getenv("TERRAIN_TIFF_DIRECT");
  return !(v && std::strcmp(v, "0") == 0);
}

TiffBlockBytes::~TiffBlockBytes() { block_pool().give(bytes); }

TiffBlockReader::~TiffBlockReader() { BlockCache::get().forget(id_); }

Status TiffBlockReader::open(const std::string& path, int width, int height, int bytes_per_sample,
                             std::unique_ptr<TiffBlockReader>& out) {
  out.reset();
  auto refuse = [](std::string why) { return Status::failure(Error::unsupported_input, std::move(why)); };
  if (!tiff_direct_enabled()) return refuse("TERRAIN_TIFF_DIRECT=0");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return refuse("not a plain file");
  std::unique_ptr<TiffBlockReader> r(new TiffBlockReader());
  if (std::string why = read_layout(path, r->layout_); !why.empty()) return refuse(why);
  const TiffBlockLayout& l = r->layout_;
  if (l.width != width || l.height != height || l.bytes_per_sample != bytes_per_sample)
    return refuse("its first image is not the one GDAL reads");
  r->path_ = path;
  r->file_bytes_ = uint64_t(st.st_size);
  r->file_dev_ = uint64_t(st.st_dev);
  r->file_ino_ = uint64_t(st.st_ino);
  r->file_mtime_ns_ = int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
  r->id_ = g_next_reader_id.fetch_add(1);
  note_tiff_block_column(uint64_t(l.block_h) * uint64_t(l.bytes_per_sample));
  out = std::move(r);
  return Status::success();
}

bool TiffBlockReader::decode(int fd, uint32_t index, TiffBlockBytes& block) const {
  const TiffBlockLayout& l = layout_;
  const uint64_t offset = l.offsets[index], count = l.byte_counts[index];
  if (offset == 0 || count == 0 || offset > file_bytes_ || count > file_bytes_ - offset) return false;  // sparse, damaged
  const int by = int(index / uint32_t((l.width + l.block_w - 1) / l.block_w));
  // Rows the block holds: a tile is whole (padded past the image); the last strip is shorter.
  const int rows = l.tiled ? l.block_h : std::min(l.block_h, l.height - by * l.block_h);
  const size_t row_bytes = size_t(l.block_w) * size_t(l.bytes_per_sample), need = row_bytes * size_t(rows);
  if (block.size < need) return false;
  uint8_t* out = block.bytes;
  ThreadDecoders& d = thread_decoders();
  auto read_at = [&](uint8_t* dst, size_t bytes) {
    for (size_t got = 0; got < bytes;) {
      const ssize_t n = ::pread(fd, dst + got, bytes - got, off_t(offset + got));
      if (n <= 0) return false;
      got += size_t(n);
    }
    return true;
  };
  if (d.compressed.size() < count) d.compressed.resize(size_t(count));
  if (!read_at(d.compressed.data(), size_t(count))) return false;
  if (l.compression == kCompressionLzw) {
    if (!lzw_decode(d.compressed.data(), size_t(count), out, need)) return false;
  } else if (l.compression == kCompressionZstd) {
    ZSTD_DCtx* zstd = detail::thread_dctx();
    if (!zstd) return false;
    const size_t n = ZSTD_decompressDCtx(zstd, out, need, d.compressed.data(), size_t(count));
    if (ZSTD_isError(n) || n != need) return false;
  } else {
    if (!d.deflate) d.deflate = libdeflate_alloc_decompressor();
    size_t n = 0;
    if (!d.deflate ||
        libdeflate_zlib_decompress(d.deflate, d.compressed.data(), size_t(count), out, need, &n) != LIBDEFLATE_SUCCESS ||
        n != need)
      return false;
  }
  if (l.predictor == 2)
    for (int r = 0; r < rows; ++r) undo_horizontal_predictor(out + size_t(r) * row_bytes, l.block_w, l.bytes_per_sample);
  if (l.predictor == 3) {
    if (d.row.size() < row_bytes) d.row.resize(row_bytes);
    for (int r = 0; r < rows; ++r) {
      uint8_t* p = out + size_t(r) * row_bytes;
      std::memcpy(d.row.data(), p, row_bytes);
      undo_float_predictor(d.row.data(), l.block_w, p);
    }
  }
  return true;
}

bool TiffBlockReader::read_window(int x0, int y0, int w, int h, uint8_t* slots, int threads, size_t stride) const {
  const TiffBlockLayout& l = layout_;
  if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > l.width || y0 + h > l.height) return false;
  const int across = (l.width + l.block_w - 1) / l.block_w;
  const int bx0 = x0 / l.block_w, bx1 = (x0 + w - 1) / l.block_w;
  const int by0 = y0 / l.block_h, by1 = (y0 + h - 1) / l.block_h;
  const size_t nbx = size_t(bx1 - bx0 + 1);
  const size_t bps = size_t(l.bytes_per_sample), row_bytes = size_t(l.block_w) * bps;
  const size_t block_bytes = row_bytes * size_t(l.block_h);
  BlockCache& cache = BlockCache::get();
  // One row of blocks at a time: a window holds at most one row of decoded blocks beyond the cache.
  std::vector<std::shared_ptr<TiffBlockBytes>> blocks(nbx);
  std::vector<size_t> missing;
  int fd = -1;  // opened at the first block to decode
  struct CloseFd {
    int& fd;
    ~CloseFd() {
      if (fd >= 0) ::close(fd);
    }
  } close_fd{fd};
  for (int by = by0; by <= by1; ++by) {
    missing.clear();
    for (size_t k = 0; k < nbx; ++k)
      if (!(blocks[k] = cache.find(id_ << 32 | (uint32_t(by) * uint32_t(across) + uint32_t(bx0) + uint32_t(k)))))
        missing.push_back(k);
    if (!missing.empty() && fd < 0) {
      // The file, if it is still the one read at open (else GDAL reads the one it holds open).
      fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
      struct stat st {};
      if (fd < 0 || ::fstat(fd, &st) != 0 || uint64_t(st.st_size) != file_bytes_ || uint64_t(st.st_dev) != file_dev_ ||
          uint64_t(st.st_ino) != file_ino_ ||
          int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec != file_mtime_ns_)
        return false;
    }
    std::atomic<bool> ok{true};
    parallel_for(missing.size(), std::max(threads, 1), [&](size_t m) {
      const size_t k = missing[m];
      const uint32_t index = uint32_t(by) * uint32_t(across) + uint32_t(bx0) + uint32_t(k);
      std::shared_ptr<TiffBlockBytes> decoded = cache.fresh(block_bytes);
      if (!decoded->bytes || !decode(fd, index, *decoded)) {
        ok = false;
        return;
      }
      blocks[k] = decoded;
      cache.put(id_ << 32 | index, decoded);
    });
    if (!ok) return false;
    const int r0 = std::max(y0, by * l.block_h), r1 = std::min(y0 + h, (by + 1) * l.block_h);
    for (size_t k = 0; k < nbx; ++k) {
      const int bx = bx0 + int(k);
      const int c0 = std::max(x0, bx * l.block_w), c1 = std::min(x0 + w, (bx + 1) * l.block_w);
      const uint8_t* src = blocks[k]->bytes;
      for (int r = r0; r < r1; ++r) {
        const uint8_t* from = src + size_t(r - by * l.block_h) * row_bytes + size_t(c0 - bx * l.block_w) * bps;
        uint8_t* o = slots + (size_t(r - y0) * (stride ? stride : size_t(w)) + size_t(c0 - x0)) * 4;
        const size_t n = size_t(c1 - c0);
        if (bps == 4) {
          std::memcpy(o, from, n * 4);
        } else {
          for (size_t i = 0; i < n; ++i) std::memcpy(o + 4 * i, from + bps * i, bps);
        }
      }
      blocks[k].reset();
    }
  }
  return true;
}

}  // namespace terrain::cook
