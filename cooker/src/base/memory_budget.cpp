// --memory-limit: parsing, the default, and the check every input-sized allocation goes through.
//
// kCookBytesPerSample, measured with /usr/bin/time -v (peak RSS) on Kilauea (30 m UTM) resampled to
// 2000 x 2000 and 4000 x 4000 Float32 at 30 m, heights only, one thread: peaks of 166 MB and
// 257 MB, so 7.8 B per extra sample (the raster 4 B, the void-fill flags 2 B, the range index ~1 B,
// the mapping). Issue 13 measured ~17 B per sample for whole cooks (surface layers included) at
// 64 M samples of 1 m lidar-like data; 16 B covers the full cook's per-sample state, and the
// ~150 MB fixed cost stays outside the estimate.
#include "base/memory_budget.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fmt/format.h>
#include <fstream>

#include "terrain/cook.h"

namespace terrain::cook {
namespace {

// cgroup v2 memory.max of this process's group (containers), or 0 when none is set.
uint64_t cgroup_memory_max() {
  std::ifstream f("/sys/fs/cgroup/memory.max");
  std::string text;
  if (!(f >> text) || text == "max") return 0;
  uint64_t v = 0;
  const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  return ec == std::errc() ? v : 0;
}

}  // namespace

bool parse_byte_size(const std::string& text, uint64_t& out) {
  if (text.empty()) return false;
  double v = 0;
  const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || !std::isfinite(v) || v <= 0) return false;
  std::string suffix(p, text.data() + text.size());
  for (char& c : suffix) c = char(std::toupper(static_cast<unsigned char>(c)));
  if (!suffix.empty() && suffix.back() == 'B') suffix.pop_back();  // "2GB" as "2G"
  if (!suffix.empty() && suffix.back() == 'I') suffix.pop_back();  // "2GiB" as "2G"
  double scale = 1;
  if (suffix == "K") scale = 1024.0;
  else if (suffix == "M") scale = 1024.0 * 1024;
  else if (suffix == "G") scale = 1024.0 * 1024 * 1024;
  else if (suffix == "T") scale = 1024.0 * 1024 * 1024 * 1024;
  else if (!suffix.empty()) return false;
  const double bytes = v * scale;
  if (bytes < 1024 * 1024 || bytes > 9.0e18) return false;  // at least 1 MB; fits in 64 bits
  out = uint64_t(bytes);
  return true;
}

uint64_t default_memory_limit_bytes() {
  uint64_t avail = uint64_t(sysconf(_SC_PHYS_PAGES)) * uint64_t(sysconf(_SC_PAGESIZE));
  if (const uint64_t cg = cgroup_memory_max(); cg) avail = std::min(avail, cg);
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) avail = std::min(avail, uint64_t(as.rlim_cur));
  // 2 GB keeps a cook of any size well inside a workstation and lets two run on a 24 GB node
  // with room to spare; the block-wise cook needs no more (a larger limit only makes blocks larger).
  return std::max<uint64_t>(std::min<uint64_t>(avail / 2, uint64_t(2) << 30), 64u << 20);
}

MemoryShares memory_shares(uint64_t limit_bytes) {
  MemoryShares s;
  s.reserve = std::min<uint64_t>(limit_bytes / 2, uint64_t(200) << 20);
  const uint64_t rest = limit_bytes - s.reserve;
  // GDAL's cache holds what the next pass reads again: all of a mid-size input (8 km of 1 m float
  // lidar is 256 MB: its second and third reads then decode nothing), a few block rows of a large one.
  s.gdal_cache = std::min<uint64_t>(rest / 4, uint64_t(320) << 20);
  s.inputs = (rest - s.gdal_cache) / 4;
  // The window: blocks of 2 x 2 roots of 1 m data (23 M samples) at the default 2 GB, so memory
  // stays flat from a few km to a country; a larger --memory-limit buys larger blocks (fewer
  // window margins read twice).
  const uint64_t base = uint64_t(384) << 20, two_gb = uint64_t(2) << 30;
  const uint64_t want = base + (limit_bytes > two_gb ? (limit_bytes - two_gb) / 2 : 0);
  s.window = std::min(rest - s.gdal_cache - s.inputs, want);
  return s;
}

uint64_t memory_limit_of(const CookOptions& options) { return memory_limit_of(options.memory_limit_bytes); }

uint64_t memory_limit_of(uint64_t given_bytes) { return given_bytes ? given_bytes : default_memory_limit_bytes(); }

std::string format_bytes(uint64_t bytes) {
  const double b = double(bytes);
  if (b >= 1024.0 * 1024 * 1024) return fmt::format("{:.1f} GB", b / (1024.0 * 1024 * 1024));
  if (b >= 1024.0 * 1024) return fmt::format("{:.0f} MB", b / (1024.0 * 1024));
  if (b >= 1024.0) return fmt::format("{:.0f} KB", b / 1024.0);
  return fmt::format("{} bytes", bytes);
}

std::string format_count(uint64_t n) {
  if (n >= 1'000'000'000) return fmt::format("{:.1f} G", double(n) / 1e9);
  if (n >= 1'000'000) return fmt::format("{:.1f} M", double(n) / 1e6);
  return fmt::format("{}", n);
}

Status check_memory(uint64_t need_bytes, uint64_t limit_bytes, const std::string& what, const std::string& purpose,
                    const std::string& advice) {
  if (need_bytes <= limit_bytes) return Status::success();
  return Status::failure(Error::unsupported_input,
                         fmt::format("{}: needs {} for {}, over --memory-limit {}{}{}", what, format_bytes(need_bytes),
                                     purpose, format_bytes(limit_bytes), advice.empty() ? "" : "; ", advice));
}

}  // namespace terrain::cook
