#include "voids/void_plan.h"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <fmt/format.h>
#include <memory>
#include <mutex>
#include <thread>
#include <tuple>

#include "base/memory_budget.h"

namespace terrain::cook {
namespace {

// What the plan knows of one void (or of a part of it until the parts are joined).
struct VoidRecord {
  int64_t parent = 0;  // union-find; a root is its own parent
  int64_t samples = 0;
  SampleRect bbox;
  bool touches_border = false;
  float rim_lo = INFINITY, rim_hi = -INFINITY;  // the valid samples next to it (NaN-free)
};

// Reads the first pass's chunks (a run of tiles of one row of tiles) on a second thread, one
// chunk ahead of the pass: decoding a compressed source is about half of the pass, and it then
// overlaps the labelling. One thread, chunks read in the order the pass asks for them and each
// sample once, so the source sees what it sees without it (implausible-height counts included)
// and nothing in the plan changes. A persistent thread: per-thread state of the readers (GDAL,
// PROJ contexts) is made once.
class ReadAhead {
 public:
  explicit ReadAhead(const ReadSamples& read) : read_(read), thread_([this] { run(); }) {}
  ReadAhead(const ReadAhead&) = delete;
  ReadAhead& operator=(const ReadAhead&) = delete;
  ~ReadAhead() {
    {
      std::lock_guard<std::mutex> lock(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  // Queues samples [c0, c0 + w) x [r0, r0 + h), read into `buffer` (recycled storage).
  void request(const SampleRect& r, std::vector<float>&& buffer) {
    {
      std::lock_guard<std::mutex> lock(m_);
      jobs_.push_back({r, std::move(buffer), Status::success(), false});
    }
    cv_.notify_all();
  }
  // Waits for the oldest queued read; its samples are moved into `out`.
  Status take(std::vector<float>& out) {
    std::unique_lock<std::mutex> lock(m_);
    cv_.wait(lock, [&] { return !jobs_.empty() && jobs_.front().done; });
    Job& j = jobs_.front();
    out = std::move(j.data);
    const Status st = j.status;
    jobs_.pop_front();
    --started_;
    return st;
  }

 private:
  struct Job {
    SampleRect rect;  // c0, r0, c1 = width, r1 = height
    std::vector<float> data;
    Status status;
    bool done = false;
  };
  void run() {
    std::unique_lock<std::mutex> lock(m_);
    for (;;) {
      cv_.wait(lock, [&] { return stop_ || started_ < jobs_.size(); });
      if (stop_) return;
      Job& j = jobs_[started_++];  // deque: references survive push_back, and j is not popped until done
      const SampleRect r = j.rect;
      std::vector<float> data = std::move(j.data);
      lock.unlock();
      Status st = Status::success();
      try {  // what would have reached the caller of a read on its own thread
        data.resize(size_t(r.c1) * size_t(r.r1));
        st = read_(r.c0, r.r0, r.c1, r.r1, data.data());
      } catch (const std::exception& e) {
        st = Status::failure(Error::internal, fmt::format("reading samples: {}", e.what()));
      }
      lock.lock();
      j.data = std::move(data);
      j.status = std::move(st);
      j.done = true;
      cv_.notify_all();
    }
  }
  const ReadSamples& read_;
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<Job> jobs_;
  size_t started_ = 0;  // jobs_[0, started_) taken by the thread
  bool stop_ = false;
  std::thread thread_;
};

void take(float v, float& lo, float& hi) {
  if (v < lo) lo = v;
  if (v > hi) hi = v;
}

// fill_voids()'s rule (void_fill.cpp): the whole raster as one void is never filled.
bool will_fill(const VoidPlan& plan, int64_t samples, bool touches_border) {
  const bool fill = plan.policy == NodataPolicy::fill ||
                    (plan.policy == NodataPolicy::automatic && !touches_border && samples <= plan.max_fill_samples);
  return fill && uint64_t(samples) < uint64_t(plan.width) * uint64_t(plan.height);
}

// A whole void is known: count it, and keep its box when it is filled across tiles; the summary
// hears of every void that will be filled.
void finish_void(VoidPlan& plan, RangeSummary* summary, int64_t samples, const SampleRect& bbox, bool touches_border,
                 float rim_lo, float rim_hi) {
  if (will_fill(plan, samples, touches_border)) {
    if (summary) summary->add_filled_void(bbox, rim_lo, rim_hi);
    plan.stats.filled_samples += uint64_t(samples);
    plan.stats.filled_regions += 1;
    const int t = plan.tile;
    if (bbox.c0 / t != bbox.c1 / t || bbox.r0 / t != bbox.r1 / t) plan.spanning_fills.push_back(bbox);
  } else {
    plan.stats.hole_samples += uint64_t(samples);
    plan.stats.hole_regions += 1;
  }
}

// The voids that reach a tile edge inside the raster, joined across edges as tiles are read.
struct OpenVoids {
  std::vector<VoidRecord> records;

  int64_t find(int64_t i) {
    while (records[size_t(i)].parent != i) {
      records[size_t(i)].parent = records[size_t(records[size_t(i)].parent)].parent;  // path halving
      i = records[size_t(i)].parent;
    }
    return i;
  }
  void join(int64_t a, int64_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return;
    if (records[size_t(a)].samples < records[size_t(b)].samples) std::swap(a, b);
    VoidRecord& ra = records[size_t(a)];
    const VoidRecord& rb = records[size_t(b)];
    ra.samples += rb.samples;
    ra.bbox = unite(ra.bbox, rb.bbox);
    ra.touches_border = ra.touches_border || rb.touches_border;
    take(rb.rim_lo, ra.rim_lo, ra.rim_hi);
    take(rb.rim_hi, ra.rim_lo, ra.rim_hi);
    records[size_t(b)].parent = a;
  }
  // After a row of tiles: finishes every void no label in `above` refers to (it cannot grow any
  // more) and keeps only the others, renumbering `above`.
  void close_unreferenced(VoidPlan& plan, RangeSummary* summary, std::vector<int64_t>& above) {
    std::vector<int64_t> renumber(records.size(), -1);
    for (int64_t& a : above)
      if (a >= 0) a = find(a);
    std::vector<VoidRecord> kept;
    for (int64_t a : above)
      if (a >= 0 && renumber[size_t(a)] < 0) {
        renumber[size_t(a)] = int64_t(kept.size());
        kept.push_back(records[size_t(a)]);
        kept.back().parent = renumber[size_t(a)];
      }
    for (size_t i = 0; i < records.size(); ++i)
      if (records[i].parent == int64_t(i) && renumber[i] < 0)
        finish_void(plan, summary, records[i].samples, records[i].bbox, records[i].touches_border, records[i].rim_lo,
                    records[i].rim_hi);
    for (int64_t& a : above)
      if (a >= 0) a = renumber[size_t(a)];
    records = std::move(kept);
  }
};

}  // namespace

Status plan_voids(int width, int height, const ReadSamples& read, NodataPolicy policy, int64_t max_fill_samples,
                  int tile, VoidPlan& out, const ProgressFn& progress, RangeSummary* summary, bool read_ahead) {
  out = VoidPlan{};
  if (width < 0 || height < 0 || tile <= 0 || int64_t(tile) * tile > INT32_MAX)  // tile indices are 32-bit
    return Status::failure(Error::invalid_argument,
                           fmt::format("plan_voids: raster {} x {}, tile {}", width, height, tile));
  out.width = width;
  out.height = height;
  out.tile = tile;
  out.policy = policy;
  out.max_fill_samples = max_fill_samples;

  OpenVoids open;
  // Record (or -1) of the last sample read in each column (the bottom row of the tiles read last
  // there), and of the right column of the tile read last in this row of tiles.
  std::vector<int64_t> above(size_t(width), -1), left;
  // The samples beside them (NaN = nodata): rims across tile edges.
  std::vector<float> above_z(size_t(width), NAN), left_z;
  std::vector<float> z;
  std::vector<int32_t> label;        // per tile sample: its void in the tile, -1 valid
  std::vector<int64_t> record_of;    // per void of the tile: its record, -1 when it reaches no inner edge
  std::vector<int32_t> stack;
  std::vector<uint8_t> filled_scratch;
  struct TileVoid { int64_t samples; SampleRect bbox; bool border, inner_edge; float rim_lo, rim_hi; };
  std::vector<TileVoid> tile_voids;

  // With read-ahead: chunks of kReadAheadTiles tiles of one row of tiles, the next one read while
  // this one is labelled (chunk: its samples, cw x ch, from column chunk_x0 to chunk_x1).
  std::unique_ptr<ReadAhead> ahead;
  std::vector<float> chunk, spare;
  int chunk_x0 = 0, chunk_x1 = 0;
  const int64_t chunk_w = int64_t(tile) * kReadAheadTiles;
  int next_x = 0, next_y = 0;  // the next chunk to ask for
  auto request_next = [&] {
    if (next_y >= height) return;
    const int w = int(std::min<int64_t>(chunk_w, width - next_x)), h = std::min(tile, height - next_y);
    ahead->request(SampleRect{next_x, next_y, w, h}, std::move(spare));
    next_x += w;
    if (next_x >= width) next_x = 0, next_y += tile;
  };
  if (read_ahead && width > 0 && height > 0) {
    ahead = std::make_unique<ReadAhead>(read);
    request_next();
  }
  for (int ty = 0; ty < height; ty += tile) {
    const int th = std::min(tile, height - ty);
    left.assign(size_t(th), -1);
    left_z.assign(size_t(th), NAN);
    for (int tx = 0; tx < width; tx += tile) {
      const int tw = std::min(tile, width - tx);
      z.resize(size_t(tw) * size_t(th));
      if (ahead) {
        if (tx >= chunk_x1 || tx == 0) {
          spare = std::move(chunk);
          TERRAIN_TRY(ahead->take(chunk));
          chunk_x0 = tx;
          chunk_x1 = int(std::min<int64_t>(int64_t(tx) + chunk_w, width));
          request_next();
        }
        const size_t cw = size_t(chunk_x1 - chunk_x0);
        for (int y = 0; y < th; ++y)
          std::memcpy(&z[size_t(y) * size_t(tw)], &chunk[size_t(y) * cw + size_t(tx - chunk_x0)],
                      size_t(tw) * sizeof(float));
      } else if (Status st = read(tx, ty, tw, th, z.data()); !st.ok()) {
        return st;
      }
      // Valid samples.
      for (int y = 0; y < th; ++y) {
        int first = -1, last = -1;
        for (int x = 0; x < tw; ++x)
          if (!std::isnan(z[size_t(y) * size_t(tw) + size_t(x)])) {
            if (first < 0) first = x;
            last = x;
            ++out.valid_samples;
          }
        if (first >= 0) out.valid_bounds = unite(out.valid_bounds, SampleRect{tx + first, ty + y, tx + last, ty + y});
      }
      // The tile's voids (any labelling order: only sizes, boxes and edges matter here).
      label.assign(z.size(), -1);
      tile_voids.clear();
      for (size_t s = 0; s < z.size(); ++s) {
        if (!std::isnan(z[s]) || label[s] >= 0) continue;
        const int32_t id = int32_t(tile_voids.size());
        TileVoid v{0, {}, false, false, INFINITY, -INFINITY};
        stack.assign(1, int32_t(s));
        label[s] = id;
        while (!stack.empty()) {
          const int32_t i = stack.back();
          stack.pop_back();
          const int x = i % tw, y = i / tw, gx = tx + x, gy = ty + y;
          ++v.samples;
          v.bbox = unite(v.bbox, SampleRect{gx, gy, gx, gy});
          if (gx == 0 || gy == 0 || gx == width - 1 || gy == height - 1) v.border = true;
          if ((x == 0 && gx > 0) || (y == 0 && gy > 0) || (x == tw - 1 && gx < width - 1) ||
              (y == th - 1 && gy < height - 1))
            v.inner_edge = true;
          const int32_t cand[4] = {x > 0 ? i - 1 : -1, x + 1 < tw ? i + 1 : -1, y > 0 ? i - tw : -1,
                                   y + 1 < th ? i + tw : -1};
          for (int32_t c : cand)
            if (c >= 0 && !std::isnan(z[size_t(c)])) take(z[size_t(c)], v.rim_lo, v.rim_hi);
          for (int32_t c : cand)
            if (c >= 0 && label[size_t(c)] < 0 && std::isnan(z[size_t(c)])) {
              label[size_t(c)] = id;
              stack.push_back(c);
            }
        }
        tile_voids.push_back(v);
      }
      // Voids inside the tile are finished; those reaching an inner edge become records.
      // (The summary gets those voids filled, in the tile, below.)
      record_of.assign(tile_voids.size(), -1);
      bool fill_here = false;
      for (size_t v = 0; v < tile_voids.size(); ++v) {
        const TileVoid& tv = tile_voids[v];
        if (!tv.inner_edge) {
          fill_here = fill_here || will_fill(out, tv.samples, tv.border);
          finish_void(out, nullptr, tv.samples, tv.bbox, tv.border, tv.rim_lo, tv.rim_hi);
          continue;
        }
        record_of[v] = int64_t(open.records.size());
        open.records.push_back({record_of[v], tv.samples, tv.bbox, tv.border, tv.rim_lo, tv.rim_hi});
      }
      auto record_at = [&](int x, int y) -> int64_t {
        const int32_t l = label[size_t(y) * size_t(tw) + size_t(x)];
        return l >= 0 ? record_of[size_t(l)] : -1;
      };
      // Rims across the top and left edges: a void on one side, a valid sample on the other.
      auto rim = [&](int64_t r, float v) {
        VoidRecord& rec = open.records[size_t(open.find(r))];
        take(v, rec.rim_lo, rec.rim_hi);
      };
      for (int x = 0; x < tw && ty > 0; ++x) {
        const float a = above_z[size_t(tx + x)], b = z[size_t(x)];
        if (std::isnan(b) && !std::isnan(a)) rim(record_at(x, 0), a);
        else if (!std::isnan(b) && std::isnan(a) && above[size_t(tx + x)] >= 0) rim(above[size_t(tx + x)], b);
      }
      for (int y = 0; y < th && tx > 0; ++y) {
        const float a = left_z[size_t(y)], b = z[size_t(y) * size_t(tw)];
        if (std::isnan(b) && !std::isnan(a)) rim(record_at(0, y), a);
        else if (!std::isnan(b) && std::isnan(a) && left[size_t(y)] >= 0) rim(left[size_t(y)], b);
      }
      // Join across the top and left edges.
      for (int x = 0; x < tw; ++x)
        if (const int64_t r = record_at(x, 0); r >= 0 && above[size_t(tx + x)] >= 0) open.join(r, above[size_t(tx + x)]);
      for (int y = 0; y < th; ++y)
        if (const int64_t r = record_at(0, y); r >= 0 && left[size_t(y)] >= 0) open.join(r, left[size_t(y)]);
      // What the next tiles join to (nothing beyond the raster's last row and column).
      const bool last_row = ty + th == height, last_col = tx + tw == width;
      for (int x = 0; x < tw; ++x) above[size_t(tx + x)] = last_row ? -1 : record_at(x, th - 1);
      for (int y = 0; y < th; ++y) left[size_t(y)] = last_col ? -1 : record_at(tw - 1, y);
      for (int x = 0; x < tw; ++x) above_z[size_t(tx + x)] = z[size_t(th - 1) * size_t(tw) + size_t(x)];
      for (int y = 0; y < th; ++y) left_z[size_t(y)] = z[size_t(y) * size_t(tw) + size_t(tw - 1)];
      if (summary) {
        // The voids inside the tile filled as the cook fills them (the same bits: void_plan.h),
        // so the summary holds their values, not only their rims'.
        if (fill_here) {
          filled_scratch.resize(z.size());
          VoidStats unused;
          const FillWindow fw{width, height, tx, ty, tw, th};
          if (Status st = fill_complete_voids(fw, z.data(), filled_scratch.data(), policy, max_fill_samples, 0,
                                              "source", unused, UINT64_MAX);
              !st.ok())
            return st;
        }
        summary->add_tile(tx, ty, tw, th, z.data());
      }
    }
    open.close_unreferenced(out, summary, above);
    if (progress && !progress(double(ty + th) / double(std::max(height, 1)), "voids"))
      return Status::failure(Error::cancelled, "cancelled");
  }
  std::sort(out.spanning_fills.begin(), out.spanning_fills.end(), [](const SampleRect& a, const SampleRect& b) {
    return std::tie(a.r0, a.c0, a.r1, a.c1) < std::tie(b.r0, b.c0, b.r1, b.c1);
  });
  return Status::success();
}

SampleRect fill_read_rect(const VoidPlan& plan, const SampleRect& need) {
  const SampleRect raster{0, 0, plan.width - 1, plan.height - 1};
  const SampleRect n = intersect(need, raster);
  if (n.empty() || plan.tile <= 0) return SampleRect{};
  const int t = plan.tile;
  // Whole tiles (so every void inside one tile that meets `need` is here), and a ring around them
  // (so such a void touching its tile's edge is not cut by the window's).
  SampleRect rect{(n.c0 / t) * t - 1, (n.r0 / t) * t - 1, (n.c1 / t + 1) * t, (n.r1 / t + 1) * t};
  for (const SampleRect& f : plan.spanning_fills)
    if (!intersect(f, n).empty()) rect = unite(rect, SampleRect{f.c0 - 1, f.r0 - 1, f.c1 + 1, f.r1 + 1});
  return intersect(rect, raster);
}

Status fill_voids_window(const VoidPlan& plan, const SampleRect& window, float* values, uint8_t* filled,
                         double& max_residual_m, uint64_t memory_limit_bytes) {
  max_residual_m = 0;
  if (window.empty() || window.c0 < 0 || window.r0 < 0 || window.c1 >= plan.width || window.r1 >= plan.height)
    return Status::failure(Error::invalid_argument,
                           fmt::format("fill_voids_window: window [{}, {}] x [{}, {}] outside the {} x {} raster",
                                       window.c0, window.c1, window.r0, window.r1, plan.width, plan.height));
  std::fill(filled, filled + window.samples(), uint8_t(0));
  const FillWindow w{plan.width, plan.height, window.c0, window.r0, window.width(), window.height()};
  VoidStats stats;
  const Status st = fill_complete_voids(w, values, filled, plan.policy, plan.max_fill_samples,
                                        window.samples() * kWindowBytesPerSample,
                                        plan.source_name.empty() ? std::string("source") : plan.source_name, stats,
                                        memory_limit_bytes);
  max_residual_m = stats.max_residual_m;
  return st;
}

}  // namespace terrain::cook
