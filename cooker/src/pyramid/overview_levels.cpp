#include "pyramid/overview_levels.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fmt/format.h>
#include <memory>

#include "pyramid/node_cook.h"
#include "base/parallel.h"
#include "pyramid/quantize.h"
#include "terrain/bc_decode.h"

namespace terrain::cook {
namespace {

constexpr int kOverviewBase = kLevelCount;  // level 6: the first overview level
constexpr int kEven = kHeightSamples / 2 + 1;  // 65 even vertices per root side

// The level-6 vertex lattice, (roots_x * 64 + 1) x (roots_y * 64 + 1): the roots' even vertices.
// It lives in a scratch file (an int32 per vertex, kNoVertex where no root holds one), written
// root row by root row and read back by bands, so memory follows the lattice's width, not its
// area (10^5 roots: 1.6 GB on disk, bands of 13-26 MB).
constexpr int32_t kNoVertex = INT32_MIN;  // never a height: units are offsets plus 16-bit steps

struct LatticeFile {
  int fd = -1;
  std::string path;
  int64_t w = 0, h = 0;
  LatticeFile() = default;
  LatticeFile(const LatticeFile&) = delete;
  LatticeFile& operator=(const LatticeFile&) = delete;
  ~LatticeFile() {
    if (fd >= 0) ::close(fd);
  }
  Status io_error(const char* what) const {
    return Status::failure(what[0] == 'w' ? Error::io_write : Error::io_read,
                           fmt::format("overview levels: {} the lattice scratch file {}: {}", what, path, std::strerror(errno)));
  }
  Status write_rows(int64_t y, int64_t n, const int32_t* rows) const {
    const auto* p = reinterpret_cast<const uint8_t*>(rows);
    size_t size = size_t(n * w) * sizeof(int32_t), done = 0;
    const auto at = off_t(y * w * int64_t(sizeof(int32_t)));
    while (done < size) {
      const ssize_t k = ::pwrite(fd, p + done, size - done, at + off_t(done));
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) return io_error("writing");
      done += size_t(k);
    }
    return Status::success();
  }
  Status read_row(int64_t y, std::vector<int32_t>& row) const {
    row.resize(size_t(w));
    auto* p = reinterpret_cast<uint8_t*>(row.data());
    const size_t size = row.size() * sizeof(int32_t);
    const auto at = off_t(y * w * int64_t(sizeof(int32_t)));
    for (size_t done = 0; done < size;) {
      const ssize_t k = ::pread(fd, p + done, size - done, at + off_t(done));
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) return errno = k == 0 ? EIO : errno, io_error("reading");
      done += size_t(k);
    }
    return Status::success();
  }
};

// Rows [y0, y0 + rows * stride) of the level-6 lattice, every `stride`-th row and column: what the
// nodes of one row of a level read (their window with its margin; above level 6, the level
// below's vertices for the error bound).
struct Band {
  int64_t w = 0, h = 0;  // the whole lattice
  int64_t y0 = 0, rows = 0, cols = 0;
  int stride = 1;
  int stride_log2 = 0;  // stride = 2^stride_log2: shifts, not the divisions of a call per vertex
  std::vector<int32_t> units;
  // Level-6 lattice vertex (x, y), x and y - y0 multiples of the stride.
  bool get(int64_t x, int64_t y, int32_t& u) const {
    if (x < 0 || y < 0 || x >= w || y >= h) return false;
    if (y < y0) return false;  // never asked: the band covers every row its nodes read
    const int64_t r = (y - y0) >> stride_log2;
    if (r >= rows) return false;
    u = units[size_t(r * cols + (x >> stride_log2))];
    return u != kNoVertex;
  }
};

// One decoded root: its even vertices and its deviation from the level-6 surface over it.
struct RootEven {
  std::array<int32_t, kEven * kEven> units{};
  std::array<uint8_t, kEven * kEven> hole{};
  double deviation_m = 0;
  Status status = Status::success();
};

// Largest |fine - coarse| at the fine vertices with an odd index, the coarse surface being the
// one through the even vertices (quads split along the SW-NE diagonal, SPEC 10): on an edge the
// mean of its two even ends, in a cell the mean of the diagonal's ends. fine(i, j) returns false
// for a hole. Fine vertices 0..2n per side.
template <class Fine>
double deviation_of(int n, Fine&& fine) {
  double dev = 0;
  for (int j = 0; j <= 2 * n; ++j)
    for (int i = (j & 1) ? 0 : 1; i <= 2 * n; i += (j & 1) ? 1 : 2) {
      int32_t u = 0, a = 0, b = 0;
      if (!fine(i, j, u)) continue;
      const bool ok = (i & 1) && (j & 1)   ? fine(i - 1, j - 1, a) && fine(i + 1, j + 1, b)
                      : (i & 1)            ? fine(i - 1, j, a) && fine(i + 1, j, b)
                                           : fine(i, j - 1, a) && fine(i, j + 1, b);
      if (ok) dev = std::max(dev, std::fabs(double(u) - 0.5 * (double(a) + double(b))) * kHeightUnitM);
    }
  return dev;
}

void decode_root(const NodeRecord& rec, int step_log2, const std::vector<uint8_t>& bytes, RootEven& out) {
  static thread_local std::unique_ptr<NodeData> data_buffer;
  static thread_local std::vector<uint8_t> rgba;
  if (!data_buffer) data_buffer = std::make_unique<NodeData>();
  NodeData& d = *data_buffer;
  const bool holes = (rec.flags & kNodeFlagHasHoles) != 0;
  out.status = decode_node_payload(bytes, kSectionHeights | (holes ? kSectionAlbedo : 0u), d);
  if (!out.status.ok()) return;
  if (holes) {
    rgba.resize(size_t(kTexels) * kTexels * 4);
    decode_bc1_image(d.albedo_bc1.data(), kTexelBlocks, kTexelBlocks, rgba.data());
  }
  auto vertex = [&](int i, int j, int32_t& u) {
    if (i < 0 || j < 0 || i >= kHeightSamples || j >= kHeightSamples) return false;
    u = rec.height_offset + int32_t(uint32_t(d.heights[size_t(j * kHeightSamples + i)]) << step_log2);
    return !holes || rgba[(size_t(j + kApron) * kTexels + size_t(i + kApron)) * 4 + 3] != 0;
  };
  for (int j = 0; j < kEven; ++j)
    for (int i = 0; i < kEven; ++i) {
      int32_t u = 0;
      const bool ok = vertex(2 * i, 2 * j, u);
      out.units[size_t(j * kEven + i)] = ok ? u : 0;
      out.hole[size_t(j * kEven + i)] = ok ? 0 : 1;
    }
  out.deviation_m = deviation_of(kQuadsPerSide / 2, vertex);
}

// A level's nodes: which exist, and their geometric error (the children's bound for the next level).
struct LevelNodes {
  uint32_t nx = 0, ny = 0;
  std::vector<uint8_t> exists;
  std::vector<double> bound;  // level 5: error + deviation from level 6; above: the node's error
  bool has(uint32_t x, uint32_t y) const { return x < nx && y < ny && exists[size_t(y) * nx + x]; }
};

struct BuiltNode {
  NodeRecord record;
  std::vector<uint8_t> payload;
  Status status = Status::success();
};

// Writes the level-6 lattice file from the roots, root row by root row (the 65 lattice rows of
// one row of roots in memory; the row the next root row shares is carried over), and fills the
// root grid's existence and error bounds.
Status build_lattice(const OverviewSettings& s, const RootSource& src, LatticeFile& lat, LevelNodes& roots) {
  const int step5 = s.world.step_log2[kRootLevel];
  lat.w = int64_t(s.world.roots_x) * (kEven - 1) + 1;
  lat.h = int64_t(s.world.roots_y) * (kEven - 1) + 1;
  lat.path = s.scratch_path;
  lat.fd = ::open(lat.path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (lat.fd < 0) return lat.io_error("creating");
  ::unlink(lat.path.c_str());  // gone with the process, however it ends
  roots.nx = s.world.roots_x;
  roots.ny = s.world.roots_y;
  roots.exists.assign(size_t(roots.nx) * roots.ny, 0);
  roots.bound.assign(size_t(roots.nx) * roots.ny, 0.0);
  std::vector<size_t> order(src.roots.size());  // by root row, then column
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  for (const NodeRecord& rec : src.roots)
    if (rec.key.level != uint32_t(kRootLevel) || rec.key.x >= roots.nx || rec.key.y >= roots.ny)
      return Status::failure(Error::internal, "overview levels: a root outside the root grid");
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return key_less(src.roots[a].key, src.roots[b].key); });
  std::vector<int32_t> band(size_t(kEven * lat.w), kNoVertex);  // lattice rows 64 R .. 64 R + 64
  const size_t batch = size_t(16) * size_t(resolve_threads(s.threads));
  std::vector<std::vector<uint8_t>> bytes(batch);
  std::vector<RootEven> even(batch);
  size_t next = 0;
  for (uint32_t row = 0; row < roots.ny; ++row) {
    size_t end = next;
    while (end < order.size() && src.roots[order[end]].key.y == row) ++end;
    for (size_t start = next; start < end; start += batch) {
      const size_t n = std::min(batch, end - start);
      for (size_t i = 0; i < n; ++i)
        TERRAIN_TRY(src.read(order[start + i], bytes[i]));
      parallel_for(n, s.threads, [&](size_t i) { decode_root(src.roots[order[start + i]], step5, bytes[i], even[i]); });
      for (size_t i = 0; i < n; ++i) {  // in root order: the result does not depend on the threads
        const NodeRecord& rec = src.roots[order[start + i]];
        const RootEven& e = even[i];
        if (!e.status.ok())
          return Status::failure(e.status.code, fmt::format("overview levels: root {}/{}: {}", rec.key.x, rec.key.y,
                                                            e.status.message));
        const size_t rk = size_t(rec.key.y) * roots.nx + rec.key.x;
        roots.exists[rk] = 1;
        roots.bound[rk] = double(rec.geometric_error_m) + e.deviation_m;
        for (int j = 0; j < kEven; ++j)
          for (int ii = 0; ii < kEven; ++ii) {
            if (e.hole[size_t(j * kEven + ii)]) continue;
            int32_t& v = band[size_t(j * lat.w + int64_t(rec.key.x) * (kEven - 1) + ii)];
            const int32_t u = e.units[size_t(j * kEven + ii)];
            if (v != kNoVertex && v != u)  // neighbours share bit-identical heights (SPEC 7)
              return Status::failure(Error::internal,
                                     fmt::format("overview levels: roots disagree on a shared vertex ({} vs {} units)", v, u));
            v = u;
          }
      }
    }
    next = end;
    // Rows 64 R .. 64 R + 63 are final; row 64 R + 64 is the next root row's first.
    const bool last = row + 1 == roots.ny;
    TERRAIN_TRY(lat.write_rows(int64_t(row) * (kEven - 1), last ? kEven : kEven - 1, band.data()));
    std::copy(band.end() - lat.w, band.end(), band.begin());
    std::fill(band.begin() + lat.w, band.end(), kNoVertex);
  }
  return Status::success();
}

// The band that the nodes of row `y` of `level` read: their window's vertices (margin included),
// and above level 6 the vertices of the level below for the error bound (rows and columns every
// 2^(level - 7) of the level-6 lattice).
Status load_band(const LatticeFile& lat, int level, uint32_t y, Band& band, std::vector<int32_t>& row) {
  const int shift = level - kOverviewBase;
  band.w = lat.w;
  band.h = lat.h;
  band.stride_log2 = shift == 0 ? 0 : shift - 1;
  band.stride = 1 << band.stride_log2;
  const int64_t lo = std::max<int64_t>(0, (int64_t(y) * kQuadsPerSide - kWindowMargin) << shift);
  const int64_t hi = std::min<int64_t>(lat.h - 1, (int64_t(y + 1) * kQuadsPerSide + kWindowMargin) << shift);
  band.y0 = lo;
  band.rows = hi >= lo ? (hi - lo) / band.stride + 1 : 0;
  band.cols = (lat.w - 1) / band.stride + 1;
  band.units.resize(size_t(band.rows * band.cols));
  for (int64_t r = 0; r < band.rows; ++r) {
    TERRAIN_TRY(lat.read_row(lo + r * band.stride, row));
    int32_t* out = &band.units[size_t(r * band.cols)];
    for (int64_t c = 0; c < band.cols; ++c) out[c] = row[size_t(c * band.stride)];
  }
  return Status::success();
}

void build_node(const OverviewSettings& s, const Band& lat, const LevelNodes& below, const NodeKey& key,
                BuiltNode& out) {
  out = BuiltNode{};
  out.record.key = key;
  const int level = int(key.level);
  const int shift = level - kOverviewBase;
  const int step = s.world.overview_step_log2[size_t(level - kOverviewBase)];
  static thread_local std::vector<int32_t> units;
  static thread_local std::vector<uint8_t> hole;
  static thread_local std::vector<float> heights_m;
  static thread_local std::unique_ptr<NodeData> data_buffer;
  if (!data_buffer) data_buffer = std::make_unique<NodeData>();
  units.assign(kWindowCount, 0);
  hole.assign(kWindowCount, 1);
  // The level's lattice vertex (gi, gj) is level-6 lattice vertex (gi, gj) << shift.
  auto at = [&](int64_t gi, int64_t gj, int32_t& u) {
    return gi >= 0 && gj >= 0 && lat.get(gi << shift, gj << shift, u);
  };
  const int64_t gi0 = int64_t(key.x) * kQuadsPerSide, gj0 = int64_t(key.y) * kQuadsPerSide;
  for (int j = 0; j < kWindowSize; ++j)
    for (int i = 0; i < kWindowSize; ++i) {
      int32_t u = 0;
      const size_t k = size_t(j) * kWindowSize + size_t(i);
      if (at(gi0 + i - kWindowMargin, gj0 + j - kWindowMargin, u)) {
        units[k] = u;
        hole[k] = 0;
      }
    }
  NodeData& data = *data_buffer;
  data = NodeData{};
  const size_t inner = size_t(kWindowMargin) * kWindowSize + kWindowMargin;
  Status st = pack_heights(&units[inner], &hole[inner], kWindowSize, step, out.record, data.heights);
  if (st.code == Error::no_data) {  // every vertex a hole (a root whose even vertices are all holes)
    out.record.height_offset = out.record.min_height = out.record.max_height = 0;
    out.record.flags = kNodeFlagHasHoles;
    data.heights.fill(0);
    st = Status::success();
  }
  if (!st.ok()) {
    out.status = Status::failure(st.code, fmt::format("overview node {}/{}/{}: {}", key.level, key.x, key.y, st.message));
    return;
  }
  // Children and the error (rule 8): max over children of (child error + deviation in its quadrant).
  double error = 0;
  for (int c = 0; c < 4; ++c) {
    const NodeKey ck = child_of(key, c);
    if (!below.has(ck.x, ck.y)) continue;
    out.record.child_mask = uint8_t(out.record.child_mask | (1u << c));
    double dev = 0;
    if (level > kOverviewBase) {
      // The child's vertices in this quadrant: the level below's lattice, 0..128 from its corner.
      const int64_t fi0 = int64_t(ck.x) * kQuadsPerSide, fj0 = int64_t(ck.y) * kQuadsPerSide;
      dev = deviation_of(kQuadsPerSide / 2, [&](int i, int j, int32_t& u) {
        const int64_t fi = fi0 + i, fj = fj0 + j;
        return fi >= 0 && fj >= 0 && lat.get(fi << (shift - 1), fj << (shift - 1), u);
      });
    }  // level 6: the roots' deviation is in their bound already (their odd vertices are not in the lattice)
    error = std::max(error, below.bound[size_t(ck.y) * below.nx + ck.x] + dev);
  }
  float err = float(error);
  if (double(err) < error) err = std::nextafter(err, INFINITY);
  out.record.geometric_error_m = err;
  if (!s.heights_only) {
    heights_m.resize(kWindowCount);
    for (size_t k = 0; k < size_t(kWindowCount); ++k) heights_m[k] = hole[k] ? NAN : units_to_metres_f32(units[k]);
    SurfaceInput in;
    in.key = key;
    in.x0_m = s.world.origin_x_m + double(key.x) * node_size_m(level);
    in.y0_m = s.world.origin_y_m + double(key.y) * node_size_m(level);
    in.spacing_m = vertex_spacing_m(level);
    in.heights_m = heights_m.data();
    in.holes = hole.data();
    in.rules = s.rules;
    in.bc_quality = s.bc_quality;
    in.bc_rdo = s.bc_rdo;
    in.measure_errors = s.check_all_errors || error_check_sampled(key);
    SurfaceStats stats;
    if (Status ss = cook_surface_layers(in, data, out.record.height_offset, step, data, &stats); !ss.ok()) {
      out.status = ss;
      return;
    }
  } else {
    encode_hole_albedo(hole.data(), data.albedo_bc1);
  }
  out.status = encode_node_payload(data, s.payload, out.payload);
}

}  // namespace

Status write_overview_levels(const OverviewSettings& s, const RootSource& src, const NodeOut& out,
                             OverviewStats& stats) {
  const int k = int(s.world.overview_step_log2.size());
  if (k <= 0) return Status::success();
  LatticeFile lat;
  LevelNodes below;
  TERRAIN_TRY(build_lattice(s, src, lat, below));
  const size_t batch = size_t(8) * size_t(resolve_threads(s.threads));
  std::vector<BuiltNode> built(batch);
  Band band;
  std::vector<int32_t> row;
  for (int level = kOverviewBase; level < kOverviewBase + k; ++level) {
    LevelNodes here;
    here.nx = uint32_t(level_grid_cells(s.world.roots_x, level));
    here.ny = uint32_t(level_grid_cells(s.world.roots_y, level));
    here.exists.assign(size_t(here.nx) * here.ny, 0);
    here.bound.assign(size_t(here.nx) * here.ny, 0.0);
    for (uint32_t y = 0; y < here.ny; ++y) {
      std::vector<NodeKey> keys;  // directory order within the level: y, then x
      for (uint32_t x = 0; x < here.nx; ++x) {
        const NodeKey key{uint32_t(level), x, y};
        for (int c = 0; c < 4; ++c) {
          const NodeKey ck = child_of(key, c);
          if (below.has(ck.x, ck.y)) {
            keys.push_back(key);
            break;
          }
        }
      }
      if (keys.empty()) continue;
      TERRAIN_TRY(load_band(lat, level, y, band, row));
      for (size_t start = 0; start < keys.size(); start += batch) {
        const size_t n = std::min(batch, keys.size() - start);
        parallel_for(n, s.threads, [&](size_t i) { build_node(s, band, below, keys[start + i], built[i]); });
        for (size_t i = 0; i < n; ++i) {
          BuiltNode& b = built[i];
          if (!b.status.ok()) return b.status;
          const size_t hk = size_t(b.record.key.y) * here.nx + b.record.key.x;
          here.exists[hk] = 1;
          here.bound[hk] = double(b.record.geometric_error_m);
          stats.error_max_m = std::max(stats.error_max_m, here.bound[hk]);
          TERRAIN_TRY(out(b.record, b.payload));
          ++stats.nodes;
        }
      }
    }
    below = std::move(here);
  }
  if (below.exists.size() > kMaxTopNodes)  // the grid's cells: more than the nodes, never fewer
    for (size_t i = 0, n = 0; i < below.exists.size(); ++i)
      if (below.exists[i] && ++n > kMaxTopNodes)
        return Status::failure(Error::internal, "overview levels: more than 16 top nodes");
  return Status::success();
}

}  // namespace terrain::cook
