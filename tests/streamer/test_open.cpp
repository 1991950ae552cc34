// open(): configuration checks, budget against roots, bad and truncated archives, first frame.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "stream_check.h"
#include "test_data.h"

namespace terrain::test {
namespace {

synthetic::Spec many_roots_spec() {
  synthetic::Spec s;
  s.roots_x = 6;
  s.roots_y = 6;
  s.root_fill = 1.0;  // all 36 roots
  s.child_probability = 0.5;
  s.min_level = 3;
  s.seed = 7;
  return s;
}

TEST(StreamerOpen, BudgetSmallerThanRootsIsAClearError) {
  const std::string path = synthetic_archive(many_roots_spec());
  Streamer streamer;
  StreamerConfig config;
  config.budget_nodes = 35;
  const Status s = streamer.open(path, config);
  EXPECT_EQ(s.code, Error::invalid_argument);
  EXPECT_NE(s.message.find("36 roots"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("at least 36"), std::string::npos) << s.message;
  EXPECT_FALSE(streamer.is_open());

  config.budget_nodes = 36;  // exactly the roots: valid, and nothing but roots can ever be resident
  ASSERT_TRUE(streamer.open(path, config).ok());
  StreamChecker checker(streamer, true);
  View v = view_at(500000.0 + 100, 4000000.0 + 100, 350);
  for (int i = 0; i < 20; ++i) {
    ASSERT_EQ(checker.check(streamer.update({&v, 1})), "");
    EXPECT_EQ(streamer.stats().resident, 36u);
    EXPECT_EQ(streamer.stats().wanted, 36u);
  }
}

TEST(StreamerOpen, RejectsBadConfigurations) {
  const std::string path = synthetic_archive(many_roots_spec());
  auto try_config = [&](auto edit) {
    StreamerConfig c;
    edit(c);
    Streamer s;
    return s.open(path, c).code;
  };
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.fence_frames = 0; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.max_deliveries_per_frame = 0; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.prefetch_ratio = 0; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.prefetch_ratio = 1.5; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.error_target_px = 0; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.error_target_px = std::nan(""); }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.slot_count = 100; }), Error::invalid_argument);  // < budget 512
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.budget_nodes = 70000; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.sections = 0; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.sections = 0x40; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.outside_frustum_error_scale = 2; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.max_fetches = 257; }), Error::invalid_argument);
  EXPECT_EQ(try_config([](StreamerConfig& c) { c.max_fetches = 256; }), Error::ok);
  EXPECT_EQ(try_config([](StreamerConfig&) {}), Error::ok);
}

// A caller who opened the archive hands the reader over; the streamer opens nothing again.
TEST(StreamerOpen, TakesAReaderTheCallerOpened) {
  const std::string path = synthetic_archive(many_roots_spec());
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path).ok());
  const size_t nodes = reader.nodes().size();
  Streamer streamer;
  const Status st = streamer.open(std::move(reader), with_workers(2));
  ASSERT_TRUE(st.ok()) << st.to_string();
  EXPECT_EQ(streamer.archive().nodes().size(), nodes);
  EXPECT_EQ(streamer.config().max_fetches, 2u);
  const FrameUpdate& u = streamer.update(std::vector<View>{view_at(0, 0, 500)});
  EXPECT_FALSE(u.delivered.empty());
  ArchiveReader closed;
  Streamer other;
  EXPECT_EQ(other.open(std::move(closed)).code, Error::invalid_argument);
  EXPECT_FALSE(other.is_open());
}

TEST(StreamerOpen, MissingFileIsAnError) {
  Streamer streamer;
  const Status s = streamer.open("/nonexistent/dir/world.terrain");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code, Error::io_open) << s.to_string();
  EXPECT_FALSE(streamer.is_open());
}

TEST(StreamerOpen, TruncatedArchiveIsAnErrorAtEveryLength) {
  const std::string path = synthetic_archive(many_roots_spec());
  const auto size = std::filesystem::file_size(path);
  const auto dir = scratch_dir("streamer-truncated");
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes(size);
  in.read(bytes.data(), std::streamsize(size));
  // Empty, inside the header, inside the payloads, inside directory/metadata, one byte short.
  std::vector<uint64_t> lengths = {0, 1, 7, 63, 64, 200, size / 3, size / 2, size - 4096, size - 100, size - 1};
  for (uint64_t cut = 997; cut < size; cut += size / 23) lengths.push_back(cut);
  for (uint64_t length : lengths) {
    const std::string p = (dir / "cut.terrain").string();
    {
      std::ofstream out(p, std::ios::binary | std::ios::trunc);
      out.write(bytes.data(), std::streamsize(length));
    }
    Streamer streamer;
    const Status s = streamer.open(p);
    EXPECT_FALSE(s.ok()) << "length " << length << " of " << size << " opened";
    EXPECT_FALSE(s.message.empty()) << "length " << length;
    EXPECT_FALSE(streamer.is_open());
  }
  std::filesystem::remove_all(dir);
}

TEST(StreamerOpen, FirstUpdateDeliversEveryRootAndTheWholeIndex) {
  const std::string path = synthetic_archive(many_roots_spec());
  Streamer streamer;
  StreamerConfig config = with_workers(2);
  config.max_deliveries_per_frame = 4;  // fewer than the roots: the first frame still brings all 36
  ASSERT_TRUE(streamer.open(path, config).ok());
  EXPECT_EQ(streamer.slot_count(), 512u + 3u * 4u);  // automatic: budget + fence * deliveries
  EXPECT_EQ(streamer.config().max_in_flight, 16u);   // automatic: max(2 * workers, budget / 32)
  EXPECT_TRUE(streamer.resident_nodes().empty());    // nothing before the first update
  StreamChecker checker(streamer, true);
  View v = view_at(500000.0 + 5000, 4000000.0 + 5000, 3000);
  const FrameUpdate& u = streamer.update({&v, 1});
  EXPECT_EQ(u.frame, 1u);
  EXPECT_EQ(u.delivered.size(), 36u);
  for (const NodeDelivery& d : u.delivered) EXPECT_EQ(d.key.level, uint32_t(kRootLevel));
  // The first update marks the whole residency index dirty: every root cell, the start list and
  // every slot's child words.
  const ResidencyIndex& index = streamer.residency();
  EXPECT_EQ(index.root_grid().size(), 36u);
  EXPECT_EQ(index.tree().size(), index_tree_words(streamer.slot_count()));
  EXPECT_EQ(u.dirty_roots.x0, 0u);
  EXPECT_EQ(u.dirty_roots.y0, 0u);
  EXPECT_EQ(u.dirty_roots.x1, 6u);
  EXPECT_EQ(u.dirty_roots.y1, 6u);
  EXPECT_TRUE(u.dirty_starts);
  ASSERT_EQ(u.dirty_children.size(), size_t(streamer.slot_count()));
  for (size_t s = 0; s < u.dirty_children.size(); ++s) EXPECT_EQ(u.dirty_children[s], s);
  EXPECT_EQ(index.start_slots().size(), 36u);  // no overview levels: the roots are the top
  ASSERT_EQ(checker.check(u), "");
  EXPECT_EQ(streamer.stats().resident, 36u);
}

TEST(StreamerOpen, AClosedStreamerAnswersWithEmptyState) {
  Streamer streamer;
  EXPECT_FALSE(streamer.open("/nonexistent/world.terrain").ok());
  View v = view_at(0, 0, 0);
  const FrameUpdate& u = streamer.update({&v, 1});
  EXPECT_EQ(u.frame, 0u);
  EXPECT_TRUE(u.delivered.empty());
  EXPECT_EQ(streamer.slot_count(), 0u);
  EXPECT_TRUE(streamer.residency().root_grid().empty());
  EXPECT_TRUE(streamer.residency().tree().empty());
  EXPECT_TRUE(streamer.slots().empty());
  EXPECT_TRUE(streamer.resident_nodes().empty());
  EXPECT_EQ(streamer.node_state({5, 0, 0}), NodeState::absent);
  EXPECT_EQ(streamer.slot_of({5, 0, 0}), -1);
  EXPECT_EQ(streamer.stats().resident, 0u);

  // Open, then close: back to the same empty answers.
  ASSERT_TRUE(streamer.open(synthetic_archive(many_roots_spec())).ok());
  EXPECT_EQ(streamer.update({&v, 1}).frame, 1u);
  streamer.close();
  EXPECT_FALSE(streamer.is_open());
  EXPECT_EQ(streamer.update({&v, 1}).frame, 0u);
}

TEST(StreamerOpen, PixelsPerRadianOfAPerspective) {
  EXPECT_NEAR(pixels_per_radian(1080, 1.5707963267948966), 540.0, 1e-9);
  EXPECT_NEAR(pixels_per_radian(720, 1.0471975511965976), 360.0 / std::tan(0.5235987755982988), 1e-9);
}

}  // namespace
}  // namespace terrain::test
