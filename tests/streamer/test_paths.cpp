// Camera paths over synthetic archives (deep sparse trees, many roots): every invariant checked
// after every update(), and once loads settle the resident set equals an independently computed
// wanted set.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "stream_check.h"

namespace terrain::test {
namespace {

double world_size_m(const synthetic::Spec& s) { return s.roots_x * node_size_m(kRootLevel); }

View random_view(std::mt19937_64& rng, const synthetic::Spec& s) {
  std::uniform_real_distribution<double> pos(0, world_size_m(s)), alt(2, 400);
  const double x = s.origin_x_m + pos(rng), y = s.origin_y_m + pos(rng);
  return view_at(x, y, synthetic::surface_height_m(s, x, y) + alt(rng));
}

// 90-degree perspective looking along +x from the view position.
void look_east(View& v) {
  v.has_frustum = true;
  v.frustum = {FrustumPlane{1, -1, 0, 0}, FrustumPlane{1, 1, 0, 0}, FrustumPlane{1, 0, -1, 0},
               FrustumPlane{1, 0, 1, 0},  FrustumPlane{1, 0, 0, -0.1}, FrustumPlane{-1, 0, 0, 30000}};
}

TEST(StreamerPaths, RandomFlightsKeepInvariantsAndSettleToTheReference) {
  const synthetic::Spec spec = deep_sparse_spec();
  Streamer streamer;
  ASSERT_TRUE(streamer.open(synthetic_archive(spec), with_workers(2)).ok());
  StreamChecker checker(streamer, true);
  std::mt19937_64 rng(11);
  View v = random_view(rng, spec);
  double heading = 0, speed = 50;
  const double speeds[] = {2.0, 50.0, 300.0};
  int compared = 0;
  for (int frame = 1; frame <= 480; ++frame) {
    if (frame % 40 == 1) {
      heading = std::uniform_real_distribution<double>(0, 2 * M_PI)(rng);
      speed = speeds[rng() % 3];
    }
    v.x += std::cos(heading) * speed / 60.0;
    v.y += std::sin(heading) * speed / 60.0;
    v.z = synthetic::surface_height_m(spec, v.x, v.y) + 20 + 10 * std::sin(frame * 0.05);
    ASSERT_EQ(checker.check(streamer.update({&v, 1})), "") << "flight frame " << frame;
    if (frame % 120 == 0) {
      ASSERT_EQ(settle_and_compare(streamer, checker, {&v, 1}), "") << "after flight frame " << frame;
      ++compared;
      EXPECT_EQ(streamer.stats().resident, streamer.stats().wanted);
    }
  }
  EXPECT_EQ(compared, 4);
  // The budget binds over this archive (the unconstrained wanted set is larger), so the budget
  // truncation rule is exercised.
  StreamerConfig unlimited = streamer.config();
  unlimited.budget_nodes = 100000;
  EXPECT_GT(reference_wanted(streamer.archive(), unlimited, {&v, 1}, {}).size(), 512u) << "the budget should bind here";
  EXPECT_GT(streamer.stats().wanted, 400u);
  EXPECT_GT(checker.evictions(), 20u);  // the flight churns the resident set (exact count depends on timing)
  EXPECT_GT(checker.slot_reuses(), 0u);
  // Memory: decode buffers never exceed (budget + max_in_flight) nodes.
  EXPECT_LE(streamer.stats().buffer_bytes, uint64_t(512 + streamer.config().max_in_flight) * sizeof(NodeData));
  EXPECT_GE(streamer.stats().buffer_bytes, uint64_t(streamer.stats().resident) * sizeof(NodeData));
}

TEST(StreamerPaths, TeleportDropsTheOldQueueAndSettlesToTheReference) {
  const synthetic::Spec spec = deep_sparse_spec();
  Streamer streamer;
  ASSERT_TRUE(streamer.open(synthetic_archive(spec), with_workers(1)).ok());  // a long queue at the old position
  StreamChecker checker(streamer, true);
  std::mt19937_64 rng(5);
  for (int jump = 0; jump < 5; ++jump) {
    View a = random_view(rng, spec);
    View b = random_view(rng, spec);
    ASSERT_EQ(checker.check(streamer.update({&a, 1})), "");
    ASSERT_EQ(checker.check(streamer.update({&b, 1})), "");  // teleport right after the first frame at A
    const StreamerStats at_jump = streamer.stats();
    ASSERT_EQ(settle_and_compare(streamer, checker, {&b, 1}), "") << "teleport " << jump;
    const StreamerStats after = streamer.stats();
    // Once B's list is published, every load a worker starts is one of B's wanted nodes.
    EXPECT_LE(after.loads_started - at_jump.loads_started, uint64_t(at_jump.wanted)) << "teleport " << jump;
    // A's loads that workers had already taken finish and are discarded, the rest of A's queue
    // is dropped unstarted.
    EXPECT_EQ(after.loads_started, after.loads_delivered + after.loads_discarded + after.in_flight) << "teleport " << jump;
  }
  EXPECT_GT(streamer.stats().requests_dropped, 0u);
  // Decode accounting (the benchmark's work-per-teleport figures): every decode takes CPU time, and
  // a thread's CPU time never exceeds its wall time (0.1 ms slack per load for the clocks' granularity).
  const StreamerStats s = streamer.stats();
  EXPECT_GT(s.decode_cpu_seconds, 0.0);
  EXPECT_LE(s.decode_cpu_seconds, s.decode_seconds + 1e-4 * double(s.loads_started));
}

TEST(StreamerPaths, TightBudgetAndSlotsRespectTheFence) {
  const synthetic::Spec spec = deep_sparse_spec();
  const std::string path = synthetic_archive(spec);
  Streamer streamer;
  StreamerConfig config = with_workers(2);
  config.budget_nodes = 60;  // 20 roots + 40
  config.slot_count = 60;    // no spare slots: every reuse waits for its fence
  config.fence_frames = 4;
  config.max_deliveries_per_frame = 6;
  ASSERT_TRUE(streamer.open(path, config).ok());
  StreamChecker checker(streamer, true);
  std::mt19937_64 rng(9);
  View v = random_view(rng, spec);
  for (int frame = 1; frame <= 300; ++frame) {
    if (frame % 15 == 0) v = random_view(rng, spec);
    ASSERT_EQ(checker.check(streamer.update({&v, 1})), "") << "frame " << frame;
    EXPECT_LE(streamer.stats().resident, 60u);
    if (frame % 100 == 0) {
      ASSERT_EQ(settle_and_compare(streamer, checker, {&v, 1}), "");
    }
  }
  EXPECT_GT(checker.slot_reuses(), 50u);
  EXPECT_LE(streamer.stats().buffer_bytes, uint64_t(60 + streamer.config().max_in_flight) * sizeof(NodeData));
}

TEST(StreamerPaths, SeveralViewsAndAFrustum) {
  const synthetic::Spec spec = deep_sparse_spec();
  Streamer streamer;
  StreamerConfig config = with_workers(2);
  config.prefetch_ratio = 1.0;
  ASSERT_TRUE(streamer.open(synthetic_archive(spec), config).ok());
  StreamChecker checker(streamer, true);
  std::mt19937_64 rng(21);
  for (int round = 0; round < 3; ++round) {
    View views[2] = {random_view(rng, spec), random_view(rng, spec)};
    views[1].pixels_per_radian = 400;
    look_east(views[0]);
    ASSERT_EQ(settle_and_compare(streamer, checker, views), "") << "round " << round;
    // The frustum matters: without it the reference wants a different set.
    View plain[2] = {views[0], views[1]};
    plain[0].has_frustum = false;
    const auto with = reference_wanted(streamer.archive(), streamer.config(), views, checker.failed_set());
    const auto without = reference_wanted(streamer.archive(), streamer.config(), plain, checker.failed_set());
    EXPECT_NE(with, without);
    // Each view alone wants a subset of nothing more than the union (when the budget does not bind).
  }
}

TEST(StreamerPaths, DeliveredDataEqualsADirectDecode) {
  const synthetic::Spec spec = deep_sparse_spec();
  const std::string path = synthetic_archive(spec);
  Streamer streamer;
  ASSERT_TRUE(streamer.open(path).ok());
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path).ok());
  std::mt19937_64 rng(2);
  View v = random_view(rng, spec);
  auto expected = std::make_unique<NodeData>();
  int compared = 0;
  for (int frame = 0; frame < 2000 && compared < 60; ++frame) {
    const FrameUpdate& u = streamer.update({&v, 1});
    for (const NodeDelivery& d : u.delivered) {
      ASSERT_TRUE(reader.decode_node(size_t(reader.find(d.key)), *expected).ok());
      EXPECT_EQ(std::memcmp(expected.get(), d.data, sizeof(NodeData)), 0) << "node " << key_name(key_of(d.key));
      ++compared;
    }
  }
  EXPECT_GE(compared, 60);
}

// One read takes queued requests whose payloads follow each other in the file along; what they
// deliver is byte for byte a direct decode, and every invariant holds meanwhile.
TEST(StreamerPaths, ReadsTakeAdjacentPayloadsAlongAndDeliverTheSameBytes) {
  const synthetic::Spec spec = deep_sparse_spec();
  const std::string path = synthetic_archive(spec);
  Streamer streamer;
  StreamerConfig config = with_workers(2);
  config.max_fetches = 1;  // one reader: requests queue up behind it, so neighbours are there to take
  ASSERT_TRUE(streamer.open(path, config).ok());
  EXPECT_EQ(streamer.config().max_fetches, 1u);
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path).ok());
  StreamChecker checker(streamer, /*check_markers=*/true);
  std::mt19937_64 rng(6);
  for (int jump = 0; jump < 3; ++jump) {
    View v = random_view(rng, spec);
    ASSERT_EQ(settle(streamer, checker, {&v, 1}), "");
  }
  const StreamerStats st = streamer.stats();
  EXPECT_GT(st.loads_started, 100u);
  EXPECT_LT(st.fetches, st.loads_started) << "no read took a neighbour along";
  EXPECT_GT(st.fetch_seconds, 0.0);
  auto expected = std::make_unique<NodeData>();
  for (const NodeKey& k : streamer.resident_nodes()) {
    ASSERT_TRUE(reader.decode_node(size_t(reader.find(k)), *expected).ok());
    EXPECT_EQ(std::memcmp(expected.get(), streamer.resident_data(k), sizeof(NodeData)), 0) << "node " << node_name(k);
  }
  // Automatic: the worker count for a file.
  Streamer automatic;
  ASSERT_TRUE(automatic.open(path, with_workers(3)).ok());
  EXPECT_EQ(automatic.config().max_fetches, 3u);
}

TEST(StreamerPaths, OnlyTheConfiguredSectionsAreDecoded) {
  const synthetic::Spec spec = deep_sparse_spec();
  const std::string path = synthetic_archive(spec);
  Streamer streamer;
  StreamerConfig config;
  config.sections = kSectionHeights;
  ASSERT_TRUE(streamer.open(path, config).ok());
  StreamChecker checker(streamer, /*check_markers=*/false);  // the marker lives in the splat section
  std::mt19937_64 rng(4);
  View v = random_view(rng, spec);
  ASSERT_EQ(settle(streamer, checker, {&v, 1}), "");
  int checked = 0;
  for (const NodeKey& k : streamer.resident_nodes()) {
    const NodeData* d = streamer.resident_data(k);
    ASSERT_NE(d, nullptr);
    EXPECT_FALSE(synthetic::key_marker_matches(*d, k));
    bool any_height = false;
    for (uint16_t h : d->heights) any_height = any_height || h != 0;
    EXPECT_TRUE(any_height);
    ++checked;
  }
  EXPECT_GT(checked, 20);
  EXPECT_EQ(streamer.stats().bytes_decoded % sizeof(NodeData::heights), 0u);
  EXPECT_GE(streamer.stats().bytes_decoded, streamer.stats().loads_delivered * sizeof(NodeData::heights));
}

}  // namespace
}  // namespace terrain::test
