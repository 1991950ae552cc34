// Nothing on the caller's thread decompresses: the zstd entry point the format library decodes
// with is interposed here and counts calls per thread while open() and update() run.
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <zstd.h>

#include <atomic>
#include <random>
#include <thread>

#include "stream_check.h"

namespace {
std::atomic<bool> g_watching{false};
std::thread::id g_caller;  // written before g_watching is set
std::atomic<int> g_on_caller{0}, g_elsewhere{0};

void note_decompression() {
  if (!g_watching.load()) return;
  if (std::this_thread::get_id() == g_caller)
    ++g_on_caller;
  else
    ++g_elsewhere;
}
}  // namespace

// Interposes libzstd's function for every caller linked into this executable (the format library
// is static), then forwards to the real one.
extern "C" size_t ZSTD_decompressDCtx(ZSTD_DCtx* dctx, void* dst, size_t dst_capacity, const void* src, size_t src_size) {
  using Fn = size_t (*)(ZSTD_DCtx*, void*, size_t, const void*, size_t);
  static const Fn real = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "ZSTD_decompressDCtx"));
  note_decompression();
  return real(dctx, dst, dst_capacity, src, src_size);
}

namespace terrain::test {
namespace {

TEST(StreamerThreads, TheCallersThreadNeverDecompresses) {
  const synthetic::Spec spec = deep_sparse_spec();
  const std::string path = synthetic_archive(spec);
  g_caller = std::this_thread::get_id();
  g_watching = true;
  Streamer streamer;
  ASSERT_TRUE(streamer.open(path, with_workers(2)).ok());
  StreamChecker checker(streamer, true);
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> pos(0, 5 * node_size_m(kRootLevel));
  View v = view_at(spec.origin_x_m + pos(rng), spec.origin_y_m + pos(rng), 400);
  for (int frame = 1; frame <= 300; ++frame) {
    if (frame % 50 == 0) v = view_at(spec.origin_x_m + pos(rng), spec.origin_y_m + pos(rng), 400);
    v.x += 5;
    v.z = synthetic::surface_height_m(spec, v.x, v.y) + 10;
    ASSERT_EQ(checker.check(streamer.update({&v, 1})), "");
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  g_watching = false;
  ASSERT_GT(streamer.stats().loads_delivered, 100u);
  EXPECT_GE(g_elsewhere.load(), int(streamer.stats().loads_delivered))
      << "the interposed ZSTD_decompressDCtx saw too few calls: has the format library changed its zstd entry point?";
  EXPECT_EQ(g_on_caller.load(), 0) << "payloads were decompressed on the caller's thread";
}

}  // namespace
}  // namespace terrain::test
