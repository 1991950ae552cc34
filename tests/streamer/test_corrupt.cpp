// Corrupt payloads: reported once, marked failed, the parent keeps covering, the streamer goes on.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>

#include "stream_check.h"
#include "test_data.h"

namespace terrain::test {
namespace {

synthetic::Spec spec() { return deep_sparse_spec(); }

// Flips one byte in the middle of each node's payload.
void corrupt(const std::string& path, const ArchiveReader& reader, const std::vector<NodeKey>& keys) {
  std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
  for (const NodeKey& k : keys) {
    const NodeRecord& r = reader.nodes()[size_t(reader.find(k))];
    const auto at = std::streamoff(r.payload_offset + r.payload_size / 2);
    char c = 0;
    f.seekg(at);
    f.read(&c, 1);
    c = char(c ^ 0x5A);
    f.seekp(at);
    f.write(&c, 1);
  }
}

// A scratch copy of the test archive for a test to corrupt, and a reader of the pristine archive.
struct ArchiveCopy {
  std::filesystem::path dir;
  std::string path;
  ArchiveReader reader;
  NodeKey root;  // the last root in directory order
};
void copy_to_corrupt(const std::string& test_name, ArchiveCopy& out) {
  const std::string pristine = synthetic_archive(spec());
  out.dir = scratch_dir(test_name);
  out.path = (out.dir / "corrupt.terrain").string();
  copy_file(pristine, out.path);
  ASSERT_TRUE(out.reader.open(pristine).ok());
  out.root = out.reader.nodes()[out.reader.nodes().size() - 1].key;
  ASSERT_EQ(out.root.level, uint32_t(kRootLevel));
}

bool is_ancestor(NodeKey a, NodeKey b) {  // a strictly above b
  while (b.level < a.level) b = parent_of(b);
  return b == a && !(a == b && false);
}

TEST(StreamerCorrupt, CorruptPayloadIsReportedOnceAndTheParentCovers) {
  ArchiveCopy copy;
  ASSERT_NO_FATAL_FAILURE(copy_to_corrupt("streamer-corrupt", copy));
  const auto& [dir, path, reader, root] = copy;
  const synthetic::Spec s = spec();
  const double cx = s.origin_x_m + 3000, cy = s.origin_y_m + 4100;
  View here = view_at(cx, cy, synthetic::surface_height_m(s, cx, cy) + 15);
  View away = view_at(s.origin_x_m + 9000, s.origin_y_m + 500, 900);

  // Pick wanted non-root nodes on levels 4..1 near the camera, none above another.
  const StreamerConfig config = with_workers(2);
  const auto wanted = reference_wanted(reader, config, {&here, 1}, {});
  std::vector<NodeKey> victims;
  for (uint32_t level = 4; level >= 1 && victims.size() < 6; --level) {
    int on_level = 0;
    for (const Key& k : wanted) {
      const NodeKey nk = node_key(k);
      if (nk.level != level || on_level >= 2) continue;
      bool related = false;
      for (const NodeKey& v : victims) related = related || is_ancestor(v, nk);
      if (related) continue;
      victims.push_back(nk);
      ++on_level;
    }
  }
  ASSERT_GE(victims.size(), 4u);
  corrupt(path, reader, victims);

  Streamer streamer;
  ASSERT_TRUE(streamer.open(path, config).ok());
  StreamChecker checker(streamer, true);
  ASSERT_EQ(settle_and_compare(streamer, checker, {&here, 1}), "");
  std::set<Key> expected_failed;
  for (const NodeKey& v : victims) expected_failed.insert(key_of(v));
  EXPECT_EQ(checker.failed_set(), expected_failed);
  EXPECT_EQ(streamer.stats().failed, victims.size());
  for (const NodeKey& v : victims) {
    EXPECT_EQ(streamer.node_state(v), NodeState::failed) << key_name(key_of(v));
    EXPECT_EQ(streamer.node_state(parent_of(v)), NodeState::resident) << "parent of " << key_name(key_of(v));
    EXPECT_EQ(streamer.residency().slot_of(v), kIndexNoNode);
  }
  // Each failure names the node and the problem.
  // Away and back: never retried, never reported again (the checker fails on a second report).
  ASSERT_EQ(settle_and_compare(streamer, checker, {&away, 1}), "");
  ASSERT_EQ(settle_and_compare(streamer, checker, {&here, 1}), "");
  EXPECT_EQ(checker.failed_set(), expected_failed);
  for (const auto& [k, n] : checker.failures()) EXPECT_EQ(n, 1) << key_name(k);
  std::filesystem::remove_all(dir);
}

TEST(StreamerCorrupt, FailureStatusNamesTheNode) {
  ArchiveCopy copy;
  ASSERT_NO_FATAL_FAILURE(copy_to_corrupt("streamer-corrupt-status", copy));
  const auto& [dir, path, reader, root] = copy;
  // Every level-4 child of the root.
  std::vector<NodeKey> victims;
  for (int c = 0; c < 4; ++c)
    if (reader.find(child_of(root, c)) >= 0) victims.push_back(child_of(root, c));
  ASSERT_FALSE(victims.empty());
  corrupt(path, reader, victims);
  Streamer streamer;
  ASSERT_TRUE(streamer.open(path).ok());
  StreamChecker checker(streamer, true);
  const double size = node_size_m(kRootLevel);
  View v = view_at(reader.world().origin_x_m + (root.x + 0.5) * size, reader.world().origin_y_m + (root.y + 0.5) * size,
                   units_to_metres(reader.nodes()[size_t(reader.find(root))].max_height) + 50);
  std::vector<NodeFailure> seen;
  for (int frame = 0; frame < 5000 && seen.size() < victims.size(); ++frame) {
    const FrameUpdate& u = streamer.update({&v, 1});
    ASSERT_EQ(checker.check(u), "");
    for (const NodeFailure& f : u.failed) seen.push_back(f);
  }
  ASSERT_EQ(seen.size(), victims.size());
  for (const NodeFailure& f : seen) {
    EXPECT_EQ(f.status.code, Error::payload_checksum) << f.status.to_string();
    EXPECT_NE(f.status.message.find(key_name(key_of(f.key))), std::string::npos) << f.status.to_string();
  }
  // The root covers the whole area alone, and stays resident.
  EXPECT_EQ(streamer.node_state(root), NodeState::resident);
  std::filesystem::remove_all(dir);
}

// Issue 48: the archive cut short after open() (a file replaced in place, a download still
// running). The workers' reads of payloads past the new end fail as `truncated` naming the node;
// those nodes are reported once and marked failed, every other node still loads. Before, the mapped
// reader raised SIGBUS in a worker and killed the process. Payloads lie finest level first, so the
// cut goes through the middle of the level-4 payloads the view wants: some of them are lost, the
// others and everything under them are intact.
TEST(StreamerCorrupt, ArchiveTruncatedAfterOpenFailsTheLostNodesByName) {
  ArchiveCopy copy;
  ASSERT_NO_FATAL_FAILURE(copy_to_corrupt("streamer-truncated", copy));
  const auto& [dir, path, reader, root] = copy;
  const synthetic::Spec s = spec();
  const double cx = s.origin_x_m + 3000, cy = s.origin_y_m + 4100;
  const View here = view_at(cx, cy, synthetic::surface_height_m(s, cx, cy) + 15);
  const View away = view_at(s.origin_x_m + 9000, s.origin_y_m + 500, 900);
  const StreamerConfig config = with_workers(2);
  std::vector<uint64_t> level4;
  for (const Key& k : reference_wanted(reader, config, {&here, 1}, {}))
    if (node_key(k).level == 4) level4.push_back(reader.nodes()[size_t(reader.find(node_key(k)))].payload_offset);
  ASSERT_GE(level4.size(), 2u);
  std::sort(level4.begin(), level4.end());
  const uint64_t half = level4[level4.size() / 2];  // the new end of the file
  Streamer streamer;
  ASSERT_TRUE(streamer.open(path, config).ok());
  std::filesystem::resize_file(path, half);
  StreamChecker checker(streamer, true);
  ASSERT_EQ(settle(streamer, checker, {&here, 1}), "");
  ASSERT_EQ(settle(streamer, checker, {&away, 1}), "");
  size_t lost = 0;
  for (const auto& [k, n] : checker.failures()) {
    const NodeRecord& r = reader.nodes()[size_t(reader.find(node_key(k)))];
    EXPECT_GT(r.payload_offset + r.payload_size, half) << key_name(k) << " failed but its payload is intact";
    EXPECT_EQ(n, 1) << key_name(k);
    EXPECT_EQ(streamer.node_state(node_key(k)), NodeState::failed) << key_name(k);
    ++lost;
  }
  EXPECT_GT(lost, 0u) << "the two views loaded no node past the cut: the test checked nothing";
  EXPECT_EQ(streamer.stats().failed, lost);
  for (const NodeFailure& f : checker.failure_statuses()) {
    EXPECT_EQ(f.status.code, Error::truncated) << f.status.to_string();
    EXPECT_NE(f.status.message.find("node " + key_name(key_of(f.key))), std::string::npos) << f.status.message;
    EXPECT_NE(f.status.message.find("short read"), std::string::npos) << f.status.message;
  }
  // Nodes whose payload lies before the cut still load: some non-top nodes are resident.
  size_t intact_resident = 0;
  for (const NodeKey& k : streamer.resident_nodes()) {
    const NodeRecord& r = reader.nodes()[size_t(reader.find(k))];
    intact_resident += k.level < uint32_t(reader.top_level()) && r.payload_offset + r.payload_size <= half;
  }
  EXPECT_GT(intact_resident, 0u);
  std::filesystem::remove_all(dir);
}

TEST(StreamerCorrupt, CorruptRootFailsOpenNamingTheRoot) {
  ArchiveCopy copy;
  ASSERT_NO_FATAL_FAILURE(copy_to_corrupt("streamer-corrupt-root", copy));
  const auto& [dir, path, reader, root] = copy;
  corrupt(path, reader, {root});
  Streamer streamer;
  const Status s = streamer.open(path);
  EXPECT_EQ(s.code, Error::payload_checksum) << s.to_string();
  EXPECT_NE(s.message.find("root node " + key_name(key_of(root))), std::string::npos) << s.message;
  EXPECT_FALSE(streamer.is_open());
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace terrain::test
