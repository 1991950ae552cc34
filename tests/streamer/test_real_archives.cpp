// Real cooked archives (from the cook_test_archives fixture, <build>/test-archives/*.terrain, and
// the folder in $TERRAIN_TEST_ARCHIVES): random and teleporting paths with every invariant checked each
// frame, and the settled resident set equal to the reference wanted set.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <random>

#include "stream_check.h"
#include "test_data.h"

namespace terrain::test {
namespace {

std::filesystem::path archives_dir() { return test_archives_dir(); }

std::vector<std::string> real_archives() {
  std::vector<std::string> out;
  if (std::filesystem::is_directory(archives_dir()))
    for (const auto& e : std::filesystem::directory_iterator(archives_dir()))
      if (e.path().extension() == ".terrain") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(StreamerRealArchives, PathsKeepInvariantsAndSettleToTheReference) {
  const auto archives = real_archives();
  if (archives.empty())
    GTEST_SKIP() << "no cooked archives in " << archives_dir()
                 << " (the cooking fixture makes them; or set TERRAIN_TEST_ARCHIVES)";
  for (const std::string& path : archives) {
    SCOPED_TRACE(path);
    Streamer streamer;
    StreamerConfig config;
    config.worker_threads = 2;
    ASSERT_TRUE(streamer.open(path, config).ok()) << streamer.open(path, config).to_string();
    StreamChecker checker(streamer, false);
    const WorldInfo& w = streamer.world();
    const ArchiveReader& reader = streamer.archive();
    std::mt19937_64 rng(17);
    auto random_view = [&] {
      // Inside a random root's footprint, above its highest point.
      std::vector<const NodeRecord*> roots;
      for (const NodeRecord& r : reader.nodes())
        if (r.key.level == uint32_t(kRootLevel)) roots.push_back(&r);
      const NodeRecord& r = *roots[rng() % roots.size()];
      std::uniform_real_distribution<double> u(0, node_size_m(kRootLevel)), alt(2, 300);
      return view_at(w.origin_x_m + r.key.x * node_size_m(kRootLevel) + u(rng),
                     w.origin_y_m + r.key.y * node_size_m(kRootLevel) + u(rng), units_to_metres(r.max_height) + alt(rng));
    };
    View v = random_view();
    double heading = 0;
    for (int frame = 1; frame <= 240; ++frame) {
      if (frame % 60 == 0) v = random_view();  // teleport
      if (frame % 20 == 1) heading = std::uniform_real_distribution<double>(0, 6.283)(rng);
      v.x += std::cos(heading) * 50.0 / 60.0;
      v.y += std::sin(heading) * 50.0 / 60.0;
      ASSERT_EQ(checker.check(streamer.update({&v, 1})), "") << "frame " << frame;
      if (frame % 80 == 0) {
        ASSERT_EQ(settle_and_compare(streamer, checker, {&v, 1}), "") << "frame " << frame;
      }
    }
    EXPECT_EQ(streamer.stats().failed, 0u);
  }
}

}  // namespace
}  // namespace terrain::test
