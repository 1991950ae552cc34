// The streamer on an archive served over HTTP (issue 52's first step: Streamer::open takes a URL) by
// a real nginx the test starts (tests/common/nginx_server.h): the same resident set as from the
// file with every invariant checked each frame, the key markers of every delivered payload intact;
// an archive replaced on the server after open fails the nodes read from then on, once each, with
// io_changed, while their parents keep covering them.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <utime.h>

#include <filesystem>

#include "nginx_server.h"
#include "stream_check.h"
#include "terrain/archive_reader.h"
#include "terrain/streamer.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

class StreamerHttp : public ::testing::Test {
 protected:
  void SetUp() override {
    if (nginx_binary().empty()) GTEST_SKIP() << "nginx is not installed (scripts/setup.sh installs nginx-light)";
    dir_ = scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::string error;
    ASSERT_TRUE(server_.start(dir_ / "nginx", error)) << error;
    local_ = (server_.root() / "deep.terrain").string();
    copy_file(synthetic_archive(deep_sparse_spec()), local_);
  }
  std::filesystem::path dir_;
  NginxServer server_;
  std::string local_;
};

TEST_F(StreamerHttp, ByUrlSettlesToTheSameNodesAsTheFile) {
  const synthetic::Spec s = deep_sparse_spec();
  const double cx = s.origin_x_m + 3000, cy = s.origin_y_m + 4100;
  const View here = view_at(cx, cy, synthetic::surface_height_m(s, cx, cy) + 15);
  const View away = view_at(s.origin_x_m + 9000, s.origin_y_m + 500, 900);
  Streamer file, web;
  ASSERT_TRUE(file.open(local_, with_workers(2)).ok());
  const Status st = web.open(server_.url("deep.terrain"), with_workers(2));
  ASSERT_TRUE(st.ok()) << st.to_string();
  StreamChecker file_check(file, true), web_check(web, true);
  for (const View& v : {here, away, here}) {
    ASSERT_EQ(settle_and_compare(file, file_check, {&v, 1}), "");
    ASSERT_EQ(settle_and_compare(web, web_check, {&v, 1}), "");
    EXPECT_EQ(web_check.resident_set(), file_check.resident_set());
  }
  EXPECT_GT(web_check.deliveries(), uint64_t(100));
  EXPECT_TRUE(web_check.failures().empty());
}

TEST_F(StreamerHttp, AnArchiveReplacedOnTheServerFailsItsNodesAsChanged) {
  const synthetic::Spec s = deep_sparse_spec();
  const double cx = s.origin_x_m + 3000, cy = s.origin_y_m + 4100;
  const View here = view_at(cx, cy, synthetic::surface_height_m(s, cx, cy) + 15);
  Streamer web;
  ASSERT_TRUE(web.open(server_.url("deep.terrain"), with_workers(2)).ok());
  // Replaced (another mtime: another ETag) before any node below the top is read.
  struct stat st {};
  ASSERT_EQ(::stat(local_.c_str(), &st), 0);
  utimbuf t{st.st_atime, st.st_mtime + 100};
  ASSERT_EQ(::utime(local_.c_str(), &t), 0);
  StreamChecker checker(web, true);
  ASSERT_EQ(settle(web, checker, {&here, 1}), "");
  ASSERT_FALSE(checker.failures().empty());
  for (const auto& [k, n] : checker.failures()) {
    EXPECT_EQ(n, 1) << key_name(k);
    EXPECT_EQ(web.node_state(node_key(k)), NodeState::failed) << key_name(k);
  }
  for (const NodeFailure& f : checker.failure_statuses())
    EXPECT_EQ(f.status.code, Error::io_changed) << f.status.to_string();
  // Only the top nodes, read at open, are resident: they still cover everything.
  for (const NodeKey& k : web.resident_nodes()) EXPECT_EQ(k.level, uint32_t(kRootLevel));
}

}  // namespace
