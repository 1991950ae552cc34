// Archives read over HTTP range requests (format/remote, terrain/remote_source.h) from a real nginx
// started by the test (tests/common/nginx_server.h): the bytes by URL are the file's, every fault
// is a Status naming the URL (never a crash), transient ones are retried, and a file replaced on
// the server fails its reads instead of mixing two archives.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <utime.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "nginx_server.h"
#include "synthetic_archive.h"
#include "terrain/archive_reader.h"
#include "terrain/remote_source.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;
namespace fs = std::filesystem;

namespace {

// Moves the file's modification time `seconds` ahead (nginx's ETag is mtime + size).
void touch_ahead(const fs::path& p, int seconds) {
  struct stat st {};
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  utimbuf t{st.st_atime, st.st_mtime + seconds};
  ASSERT_EQ(::utime(p.c_str(), &t), 0);
}

class HttpArchive : public NginxTest {
 protected:
  void SetUp() override {
    NginxTest::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ASSERT_FALSE(archive_.empty()) << "SetUpTestSuite wrote no archive";
    local_ = (server_.root() / "a.terrain").string();
    fs::copy_file(archive_, local_);
  }
  // The analytic surface (a valid archive: verify() passes), 2 x 2 roots down to level 3: 84 nodes.
  static void SetUpTestSuite() {
    const fs::path dir = scratch_dir("http_archive_source");
    synthetic::Spec spec = synthetic::analytic_surface();
    spec.keep = [](const NodeKey& k) { return k.level >= 3; };
    if (synthetic::write_archive((dir / "a.terrain").string(), spec).ok()) archive_ = (dir / "a.terrain").string();
  }
  static inline std::string archive_;
  HttpOptions quick() const {
    HttpOptions o;
    o.timeout_ms = 2000;
    o.retries = 2;
    o.backoff_ms = 10;
    return o;
  }
  std::string local_;
};

// Every payload by URL is byte-identical to the file's; the reader's full verification passes over
// HTTP; the counters add up (one request per payload read at least, bytes at least the payloads').
TEST_F(HttpArchive, PayloadsByUrlAreTheFileBytes) {
  ArchiveReader file, web;
  ASSERT_TRUE(file.open(local_).ok());
  const Status st = open_archive(web, server_.url("a.terrain"), quick());
  ASSERT_TRUE(st.ok()) << st.to_string();
  ASSERT_EQ(web.file_size(), file.file_size());
  ASSERT_EQ(web.nodes().size(), file.nodes().size());
  ASSERT_GT(file.nodes().size(), size_t(16));
  // Opening is two requests: the header (which also gives the size and the validator), then the
  // directory and metadata together; the header's bytes are not fetched again.
  HttpStats before;
  ASSERT_TRUE(http_stats(*web.source(), before));
  EXPECT_EQ(before.requests, uint64_t(2));
  uint64_t payloads_end = 0;
  for (const NodeRecord& r : file.nodes()) payloads_end = std::max<uint64_t>(payloads_end, r.payload_offset + r.payload_size);
  EXPECT_EQ(before.bytes, 128 + (file.file_size() - payloads_end)) << "the header, directory and metadata: nothing else";
  std::vector<uint8_t> header(128);
  ASSERT_TRUE(web.source()->read(0, header).ok());
  HttpStats same;
  ASSERT_TRUE(http_stats(*web.source(), same));
  EXPECT_EQ(same.requests, before.requests);
  uint64_t payload_bytes = 0;
  std::vector<uint8_t> a, b;
  for (size_t i = 0; i < file.nodes().size(); ++i) {
    ASSERT_EQ(file.nodes()[i].key.level, web.nodes()[i].key.level);
    ASSERT_TRUE(file.read_payload(i, a).ok());
    const Status r = web.read_payload(i, b);
    ASSERT_TRUE(r.ok()) << r.to_string();
    ASSERT_EQ(a, b) << "node " << i;
    payload_bytes += b.size();
  }
  HttpStats after;
  ASSERT_TRUE(http_stats(*web.source(), after));
  EXPECT_GE(after.requests - before.requests, uint64_t(file.nodes().size()));
  EXPECT_GE(after.bytes - before.bytes, payload_bytes);
  EXPECT_EQ(after.retries, uint64_t(0));
  EXPECT_EQ(after.failures, uint64_t(0));
  const Status v = web.verify();
  EXPECT_TRUE(v.ok()) << v.to_string();
  HttpStats none;
  EXPECT_FALSE(http_stats(*file.source(), none));  // a file is no HTTP source
}

// Opened by page (SPEC 20), an archive costs two requests, the header and then the page table with
// the metadata, and no directory entry; a node then costs one request for its page, once.
TEST_F(HttpArchive, OpeningByPageCostsTwoRequestsAndAPageOneMore) {
  ArchiveReader file, web;
  ASSERT_TRUE(file.open(local_).ok());
  const Status st = open_archive(web, server_.url("a.terrain"), quick(), DirectoryLoad::by_page);
  ASSERT_TRUE(st.ok()) << st.to_string();
  HttpStats open;
  ASSERT_TRUE(http_stats(*web.source(), open));
  EXPECT_EQ(open.requests, 2u);
  uint64_t payloads_end = 0;
  for (const NodeRecord& r : file.nodes()) payloads_end = std::max<uint64_t>(payloads_end, r.payload_offset + r.payload_size);
  const uint64_t entries = file.nodes().size() * 48;  // the directory starts where the payloads end
  EXPECT_EQ(open.bytes, 128 + file.file_size() - (payloads_end + entries))
      << "the header, page table and metadata: no entry";
  const NodeRecord& last = file.nodes().back();
  int64_t index = -1;
  ASSERT_TRUE(web.lookup(last.key, index).ok());
  EXPECT_EQ(index, int64_t(file.nodes().size() - 1));
  std::vector<uint8_t> a, b;
  ASSERT_TRUE(web.read_payload(size_t(index), b).ok());
  ASSERT_TRUE(file.read_payload(size_t(index), a).ok());
  EXPECT_EQ(a, b);
  HttpStats after;
  ASSERT_TRUE(http_stats(*web.source(), after));
  EXPECT_EQ(after.requests, 4u) << "its page, then its payload";
  EXPECT_EQ(web.find(file.nodes().front().key), 0);  // the same (only) page: no request
  ASSERT_TRUE(http_stats(*web.source(), after));
  EXPECT_EQ(after.requests, 4u);
}

// A missing file fails open with io_open, naming the URL and the status.
TEST_F(HttpArchive, AMissingFileIsANamedError) {
  ArchiveReader web;
  const std::string url = server_.url("none.terrain");
  const Status st = open_archive(web, url, quick());
  EXPECT_EQ(st.code, Error::io_open);
  EXPECT_NE(st.message.find(url), std::string::npos) << st.message;
  EXPECT_NE(st.message.find("404"), std::string::npos) << st.message;
}

// An archive replaced on the server after open (another ETag) fails its reads with io_changed, and
// so does one truncated there; neither is read as the old archive's bytes.
TEST_F(HttpArchive, AFileChangedOnTheServerFailsItsReads) {
  ArchiveReader web;
  ASSERT_TRUE(open_archive(web, server_.url("a.terrain"), quick()).ok());
  std::vector<uint8_t> payload;
  ASSERT_TRUE(web.read_payload(0, payload).ok());
  synthetic::Spec other;  // another archive (a sparse tree of 2 x 2 roots)
  other.roots_x = other.roots_y = 2;
  ASSERT_TRUE(synthetic::write_archive(local_, other).ok());
  ASSERT_NO_FATAL_FAILURE(touch_ahead(local_, 100));
  Status st = web.read_payload(1, payload);
  EXPECT_EQ(st.code, Error::io_changed) << st.to_string();
  EXPECT_NE(st.message.find("changed on the server"), std::string::npos) << st.message;

  ArchiveReader again;
  ASSERT_TRUE(open_archive(again, server_.url("a.terrain"), quick()).ok());
  fs::resize_file(local_, again.file_size() / 2);
  ASSERT_NO_FATAL_FAILURE(touch_ahead(local_, 200));
  st = again.read_payload(again.nodes().size() - 1, payload);
  EXPECT_EQ(st.code, Error::io_changed) << st.to_string();
  HttpStats s;
  ASSERT_TRUE(http_stats(*again.source(), s));
  EXPECT_EQ(s.retries, uint64_t(0));  // a changed file is no transient fault
  EXPECT_EQ(s.failures, uint64_t(1));
}

// A server that goes away: the read is retried `retries` times with backoff, then fails io_read.
TEST_F(HttpArchive, AServerGoneIsRetriedThenFails) {
  ArchiveReader web;
  ASSERT_TRUE(open_archive(web, server_.url("a.terrain"), quick()).ok());
  server_.stop();
  std::vector<uint8_t> payload;
  const auto t0 = std::chrono::steady_clock::now();
  const Status st = web.read_payload(0, payload);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(st.code, Error::io_read) << st.to_string();
  EXPECT_NE(st.message.find("after 2 retries"), std::string::npos) << st.message;
  HttpStats stats;
  ASSERT_TRUE(http_stats(*web.source(), stats));
  EXPECT_EQ(stats.retries, uint64_t(2));
  EXPECT_EQ(stats.failures, uint64_t(1));
  EXPECT_GE(s, 0.030);  // backoff 10 ms + 20 ms
  EXPECT_LT(s, 5.0);
}

// A server slower than the timeout: the read fails (io_read, "timed out") after its retries, within
// (retries + 1) x timeout + backoff, not when the transfer would end (64 KB at 2 KB/s: 32 s).
TEST_F(HttpArchive, AServerSlowerThanTheTimeoutFails) {
  fs::copy_file(local_, server_.root() / "slow" / "a.terrain");
  HttpOptions o = quick();
  o.timeout_ms = 400;
  o.retries = 1;
  std::unique_ptr<ByteSource> src;
  const Status open = open_location(server_.url("slow/a.terrain"), src, o);
  ASSERT_TRUE(open.ok()) << open.to_string();
  ASSERT_GT(src->size(), uint64_t(65536));
  std::vector<uint8_t> bytes(65536);
  const auto t0 = std::chrono::steady_clock::now();
  const Status st = src->read(0, bytes);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(st.code, Error::io_read) << st.to_string();
  EXPECT_NE(st.message.find("imed out"), std::string::npos) << st.message;
  EXPECT_LT(s, 3.0);
}

// 5xx answers are transient: retried, then a failure naming the status.
TEST_F(HttpArchive, ServerErrorsAreRetriedThenNamed) {
  std::unique_ptr<ByteSource> src;
  const Status st = open_location(server_.url("broken/a.terrain"), src, quick());
  EXPECT_EQ(st.code, Error::io_open);
  EXPECT_NE(st.message.find("HTTP 503"), std::string::npos) << st.message;
}

// https with a certificate the test makes: trusted through HttpOptions::ca_file, the same bytes;
// without it the certificate is refused by name.
TEST(HttpsArchive, TheTestsCertificateIsTrustedOnlyWhenGiven) {
  if (nginx_binary().empty()) GTEST_SKIP() << "nginx is not installed (scripts/setup.sh installs nginx-light)";
  const fs::path dir = scratch_dir("https_archive");
  std::string error;
  ASSERT_TRUE(make_test_certificate(dir / "tls", error)) << error;
  NginxServer server;
  ASSERT_TRUE(server.start(dir / "nginx", error, dir / "tls")) << error;
  synthetic::Spec spec;
  spec.roots_x = spec.roots_y = 2;
  const std::string local = (server.root() / "b.terrain").string();
  ASSERT_TRUE(synthetic::write_archive(local, spec).ok());
  HttpOptions o;
  o.ca_file = (dir / "tls" / "cert.pem").string();
  ArchiveReader file, web;
  ASSERT_TRUE(file.open(local).ok());
  const Status st = open_archive(web, server.https_url("b.terrain"), o);
  ASSERT_TRUE(st.ok()) << st.to_string();
  std::vector<uint8_t> a, b;
  for (size_t i = 0; i < file.nodes().size(); ++i) {
    ASSERT_TRUE(file.read_payload(i, a).ok());
    ASSERT_TRUE(web.read_payload(i, b).ok());
    ASSERT_EQ(a, b);
  }
  ArchiveReader untrusted;
  const Status refused = open_archive(untrusted, server.https_url("b.terrain"), HttpOptions{.retries = 0});
  EXPECT_EQ(refused.code, Error::io_open);
  EXPECT_NE(refused.message.find("certificate"), std::string::npos) << refused.message;
}

// terrain-inspect takes a URL wherever it takes a file: the same JSON summary but for "file".
TEST_F(HttpArchive, InspectTakesAUrl) {
  auto run = [&](const std::string& where, std::string& out) {
    const std::string cmd = (bin_dir() / "terrain-inspect").string() + " --json '" + where + "' 2>&1";
    FILE* p = ::popen(cmd.c_str(), "r");
    ASSERT_NE(p, nullptr);
    char buf[4096];
    size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof(buf), p)) > 0) out.append(buf, n);
    ASSERT_EQ(::pclose(p), 0) << out;
  };
  std::string by_file, by_url;
  ASSERT_NO_FATAL_FAILURE(run(local_, by_file));
  ASSERT_NO_FATAL_FAILURE(run(server_.url("a.terrain"), by_url));
  const auto without_file = [](std::string s) {
    const size_t a = s.find("\"file\"");
    if (a != std::string::npos) s.erase(a, s.find('\n', a) - a);
    return s;
  };
  EXPECT_NE(by_url.find(server_.url("a.terrain")), std::string::npos) << by_url;
  EXPECT_EQ(without_file(by_file), without_file(by_url));
}

// ---- The local cache folder (HttpOptions::cache_dir) ----

// Reads every payload of `reader` and compares it with the file's.
void expect_payloads_equal(const ArchiveReader& reader, const ArchiveReader& file) {
  ASSERT_EQ(reader.nodes().size(), file.nodes().size());
  std::vector<uint8_t> a, b;
  for (size_t i = 0; i < file.nodes().size(); ++i) {
    ASSERT_TRUE(file.read_payload(i, a).ok());
    const Status st = reader.read_payload(i, b);
    ASSERT_TRUE(st.ok()) << st.to_string();
    ASSERT_EQ(a, b) << "node " << i;
  }
}

HttpStats stats_of(const ArchiveReader& reader) {
  HttpStats s;
  EXPECT_TRUE(http_stats(*reader.source(), s));
  return s;
}

// The file, a cache folder and a first run that read every payload through it.
class HttpCache : public HttpArchive {
 protected:
  void SetUp() override {
    HttpArchive::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    ASSERT_TRUE(file_.open(local_).ok());
    options_ = quick();
    options_.cache_dir = (dir_ / "cache").string();
    url_ = server_.url("a.terrain");
    ArchiveReader first;
    ASSERT_TRUE(open_archive(first, url_, options_).ok());
    ASSERT_NO_FATAL_FAILURE(expect_payloads_equal(first, file_));
    first_ = stats_of(first);
  }
  ArchiveReader file_;
  HttpOptions options_;
  std::string url_;
  HttpStats first_;
};

// A second run reads what the first read from the cache folder: its open costs the one request
// that learns the size and validator, and its payloads none. A second process (here: a second
// source) on the same version meanwhile reads without the cache.
TEST_F(HttpCache, TheNextRunReadsWithoutRequests) {
  EXPECT_TRUE(first_.cached);
  EXPECT_EQ(first_.cache_hits, 0u);
  EXPECT_EQ(first_.requests, 2 + file_.nodes().size());
  ArchiveReader second;
  ASSERT_TRUE(open_archive(second, url_, options_).ok());
  EXPECT_EQ(stats_of(second).requests, 1u) << "the directory and metadata come from the cache";
  ASSERT_NO_FATAL_FAILURE(expect_payloads_equal(second, file_));
  const HttpStats s = stats_of(second);
  EXPECT_EQ(s.requests, 1u);
  EXPECT_EQ(s.cache_hits, 1 + file_.nodes().size());
  EXPECT_TRUE(second.verify().ok());

  ArchiveReader meanwhile;  // the version is held by `second`
  ASSERT_TRUE(open_archive(meanwhile, url_, options_).ok());
  EXPECT_FALSE(stats_of(meanwhile).cached);
  ASSERT_NO_FATAL_FAILURE(expect_payloads_equal(meanwhile, file_));
}

// Bytes changed in the cache, or a journal cut in the middle of a record, are never served: the
// range is fetched again and kept again.
TEST_F(HttpCache, ARangeThatFailsItsCheckIsFetchedAgain) {
  std::vector<fs::path> versions;
  for (const auto& e : fs::directory_iterator(dir_ / "cache")) versions.push_back(e.path());
  ASSERT_EQ(versions.size(), 1u);
  const NodeRecord& victim = file_.nodes()[3];
  {
    std::fstream data(versions[0] / "data", std::ios::binary | std::ios::in | std::ios::out);
    data.seekg(std::streamoff(victim.payload_offset + victim.payload_size / 2));
    char c = 0;
    data.read(&c, 1);
    c = char(c ^ 0x21);
    data.seekp(std::streamoff(victim.payload_offset + victim.payload_size / 2));
    data.write(&c, 1);
    std::ofstream journal(versions[0] / "ranges", std::ios::binary | std::ios::app);
    journal.write("half a record", 13);
  }
  {
    ArchiveReader second;
    ASSERT_TRUE(open_archive(second, url_, options_).ok());
    EXPECT_EQ(fs::file_size(versions[0] / "ranges") % 24, 0u) << "the cut record is dropped";
    ASSERT_NO_FATAL_FAILURE(expect_payloads_equal(second, file_));
    EXPECT_EQ(stats_of(second).requests, 2u) << "the open's, and the changed payload's again";
  }
  ArchiveReader third;
  ASSERT_TRUE(open_archive(third, url_, options_).ok());
  ASSERT_NO_FATAL_FAILURE(expect_payloads_equal(third, file_));
  EXPECT_EQ(stats_of(third).requests, 1u) << "the payload fetched again was kept again";
}

// A new version on the server is a new cache entry: none of the old one's bytes are served. The
// limit evicts the old version once both do not fit, and the folder stays within it.
TEST_F(HttpCache, ANewVersionIsCachedApartAndTheLimitEvictsTheOld) {
  const uint64_t old_size = fs::file_size(local_);
  synthetic::Spec other;  // another archive in its place
  other.roots_x = other.roots_y = 2;
  ASSERT_TRUE(synthetic::write_archive(local_, other).ok());
  ASSERT_NO_FATAL_FAILURE(touch_ahead(local_, 100));
  const uint64_t new_size = fs::file_size(local_);
  options_.cache_limit_bytes = new_size + 64 * 1024 + old_size / 2;  // room for the new version, not both
  ArchiveReader file, second;
  ASSERT_TRUE(file.open(local_).ok());
  ASSERT_TRUE(open_archive(second, url_, options_).ok());
  ASSERT_NO_FATAL_FAILURE(expect_payloads_equal(second, file));
  const HttpStats s = stats_of(second);
  EXPECT_EQ(s.cache_hits, 0u);
  EXPECT_EQ(s.cache_refused, 0u);
  uint64_t disk = 0;
  int versions = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "cache")) {
    ++versions;
    struct stat st {};
    ASSERT_EQ(::stat((e.path() / "data").c_str(), &st), 0);
    disk += uint64_t(st.st_blocks) * 512;
  }
  EXPECT_EQ(versions, 1) << "the old version was evicted";
  EXPECT_LE(disk, options_.cache_limit_bytes);

  // A limit below one range keeps nothing, and says so.
  options_.cache_dir = (dir_ / "tiny").string();
  options_.cache_limit_bytes = 1024;
  ArchiveReader tiny;
  ASSERT_TRUE(open_archive(tiny, url_, options_).ok());
  ASSERT_NO_FATAL_FAILURE(expect_payloads_equal(tiny, file));
  EXPECT_GT(stats_of(tiny).cache_refused, 0u);
}

// A cache folder that cannot be made fails the open, naming it.
TEST_F(HttpArchive, AnUnusableCacheFolderIsANamedError) {
  HttpOptions options = quick();
  fs::create_directories(dir_);
  std::ofstream(dir_ / "plain-file") << "x";
  options.cache_dir = (dir_ / "plain-file" / "cache").string();
  ArchiveReader web;
  const Status st = open_archive(web, server_.url("a.terrain"), options);
  EXPECT_EQ(st.code, Error::io_open);
  EXPECT_NE(st.message.find("cache folder " + options.cache_dir), std::string::npos) << st.message;
}

}  // namespace
