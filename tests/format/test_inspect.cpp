// terrain-inspect's library: geographic conversion against GeographicLib's UTM, argument parsing,
// point files, and the export files read back with OpenImageIO (separate executable: OIIO).
#include <GeographicLib/UTMUPS.hpp>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "archive_fixture.h"
#include "inspect.h"
#include "scratch_archive_test.h"
#include "synthetic_archive.h"
#include "terrain/archive_writer.h"
#include "test_data.h"

namespace terrain {
namespace {

using Inspect = test::ScratchArchiveTest;

TEST_F(Inspect, TransverseMercatorMatchesUtmZone5) {
  FrameCrs c = test::make_world().crs;  // UTM 5N as explicit parameters
  for (auto [lon, lat] : {std::pair{-155.28, 19.41}, {-153.0, 0.5}, {-156.9, 22.1}}) {
    double x = 0, y = 0;
    ASSERT_TRUE(inspect::lonlat_to_frame(c, lon, lat, x, y).ok());
    int zone = 0;
    bool north = false;
    double ux = 0, uy = 0;
    GeographicLib::UTMUPS::Forward(lat, lon, zone, north, ux, uy, 5);
    EXPECT_NEAR(x, ux, 1e-3) << lon << "," << lat;
    EXPECT_NEAR(y, uy, 1e-3) << lon << "," << lat;
  }
  // A non-zero latitude of origin shifts northings by the meridian arc to it.
  c.lat0_deg = 10;
  double x = 0, y = 0;
  ASSERT_TRUE(inspect::lonlat_to_frame(c, -153, 10, x, y).ok());
  EXPECT_NEAR(x, 500000, 1e-6);
  EXPECT_NEAR(y, 0, 1e-6);
}

TEST_F(Inspect, LonLatIsRefusedForALocalFrame) {
  double x = 0, y = 0;
  const Status s = inspect::lonlat_to_frame(FrameCrs{}, 1, 2, x, y);
  EXPECT_EQ(s.code, Error::invalid_argument);
  EXPECT_NE(s.message.find("local"), std::string::npos);
}

TEST_F(Inspect, ParsesPairsKeysAndPointFiles) {
  double a = 0, b = 0;
  EXPECT_TRUE(inspect::parse_pair("12.5,-3", a, b));
  EXPECT_EQ(a, 12.5);
  EXPECT_EQ(b, -3);
  EXPECT_FALSE(inspect::parse_pair("1", a, b));
  EXPECT_FALSE(inspect::parse_pair("1,2,3", a, b));
  EXPECT_FALSE(inspect::parse_pair("x,2", a, b));
  NodeKey k;
  EXPECT_TRUE(inspect::parse_key("2/10/7", k));
  EXPECT_EQ(k, (NodeKey{2, 10, 7}));
  EXPECT_FALSE(inspect::parse_key("6/0/0", k));
  EXPECT_FALSE(inspect::parse_key("1/2", k));
  {
    std::ofstream f(dir_ / "p.txt");
    f << "# x y\n1 2\n\n3.5, 4  # comment\n";
  }
  std::vector<inspect::SamplePoint> pts;
  ASSERT_TRUE(inspect::read_point_file((dir_ / "p.txt").string(), false, pts).ok());
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_EQ(pts[1].x, 3.5);
  {
    std::ofstream f(dir_ / "bad.txt");
    f << "1 2\noops\n";
  }
  pts.clear();
  const Status s = inspect::read_point_file((dir_ / "bad.txt").string(), false, pts);
  EXPECT_EQ(s.code, Error::invalid_argument);
  EXPECT_NE(s.message.find(":2:"), std::string::npos) << s.message;
}

TEST_F(Inspect, ExportWritesEveryLayerNorthUp) {
  ASSERT_NO_FATAL_FAILURE(open_seed_chain());
  std::vector<std::string> written;
  ASSERT_TRUE(inspect::export_node(reader_, {0, 4, 3}, (dir_ / "out").string(), written).ok());
  EXPECT_EQ(written.size(), 8u);
  for (const auto& f : written) EXPECT_TRUE(std::filesystem::exists(f)) << f;
  NodeData d;
  ASSERT_TRUE(reader_.decode_node(size_t(reader_.find({0, 4, 3})), d).ok());
  auto in = OIIO::ImageInput::open((dir_ / "out/heights.png").string());
  ASSERT_TRUE(in);
  ASSERT_EQ(in->spec().width, kHeightSamples);
  std::vector<uint16_t> png(static_cast<size_t>(kHeightCount));
  ASSERT_TRUE(in->read_image(0, 0, 0, 1, OIIO::TypeDesc::UINT16, png.data()));
  // Image row 0 is north = grid row 128.
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i)
      ASSERT_EQ(png[size_t((kHeightSamples - 1 - j) * kHeightSamples + i)], d.heights[size_t(j * kHeightSamples + i)]);
  auto exr = OIIO::ImageInput::open((dir_ / "out/heights.exr").string());
  ASSERT_TRUE(exr);
  std::vector<float> m(static_cast<size_t>(kHeightCount));
  ASSERT_TRUE(exr->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, m.data()));
  // Vertex (0, 0) of node 0/4/3 (x 256, y 192) is the plane (2x + 4y)/32 = 40 m, at image row 128.
  EXPECT_FLOAT_EQ(m[size_t(128 * kHeightSamples)], 40.0f);
  // The hole centre (300, 200) = vertex (88, 16) is NaN.
  EXPECT_TRUE(std::isnan(m[size_t((128 - 16) * kHeightSamples + 88)]));
  std::vector<std::string> none;
  EXPECT_EQ(inspect::export_node(reader_, {0, 9, 9}, (dir_ / "x").string(), none).code, Error::node_not_found);
}

TEST_F(Inspect, SummaryJsonCarriesTheFacts) {
  ASSERT_NO_FATAL_FAILURE(open_seed_chain());
  std::string text;
  ASSERT_TRUE(inspect::summary_json(reader_, path_, text).ok());
  EXPECT_NE(text.find("\"epsg\": 32605"), std::string::npos);
  EXPECT_NE(text.find("\"nodes\": 6"), std::string::npos);
  EXPECT_NE(text.find("\"tool\": \"test\""), std::string::npos);
}

// Bytes per source sample (issue 17): the cooker records its valid source samples in the cook info;
// inspect divides each level's stored bytes (as the reader counts them) and the file by them, as
// the cook report does. Without the record the column says so and the JSON has no such key.
TEST_F(Inspect, BytesPerSourceSampleFollowTheCookInfo) {
  using namespace test;
  WorldInfo w = make_world(1, 1);
  w.cook_info_json = R"({"tool":"test","source_valid_samples":1000})";
  const std::vector<NodeKey> keys = close_tree({{0, 4, 3}});
  ArchiveWriter writer;
  ASSERT_TRUE(writer.open(path_).ok());
  std::vector<uint8_t> payload;
  for (const NodeKey& k : keys) {
    BuiltNode n = make_seed_node(w, k);
    n.record.child_mask = child_mask_of(keys, k);
    ASSERT_TRUE(encode_node_payload(*n.data, PayloadOptions{}, payload).ok());
    ASSERT_TRUE(writer.add_node(n.record, payload).ok());
  }
  ASSERT_TRUE(writer.finish(w).ok());
  ASSERT_TRUE(reader_.open(path_).ok());
  // The cook report's archive_bytes: the whole file once finished (it was the payloads' end).
  EXPECT_EQ(writer.bytes_written(), std::filesystem::file_size(path_));
  SectionBytes sb;
  ASSERT_TRUE(reader_.section_bytes(sb).ok());
  std::string text;
  ASSERT_TRUE(inspect::summary_json(reader_, path_, text).ok());
  const auto j = nlohmann::json::parse(text);
  EXPECT_EQ(j["source_valid_samples"].get<uint64_t>(), 1000u);
  EXPECT_DOUBLE_EQ(j["bytes_per_source_sample"].get<double>(), double(std::filesystem::file_size(path_)) / 1000.0);
  for (int l = 0; l < kLevelCount; ++l) {
    uint64_t stored = 0;
    for (int k = 0; k < 5; ++k) stored += sb.stored_by_level[l][k];
    EXPECT_GT(stored, 0u) << "level " << l;  // the chain has one node on every level
    EXPECT_DOUBLE_EQ(j["levels"][size_t(l)]["bytes_per_source_sample"].get<double>(), double(stored) / 1000.0) << "level " << l;
  }
  ASSERT_TRUE(inspect::summary_text(reader_, path_, text).ok());
  EXPECT_NE(text.find("bytes_per_sample: stored bytes per valid source sample (1000 samples)"), std::string::npos) << text;

  reader_ = ArchiveReader();
  ASSERT_NO_FATAL_FAILURE(open_seed_chain());
  ASSERT_TRUE(inspect::summary_json(reader_, path_, text).ok());
  const auto k = nlohmann::json::parse(text);
  EXPECT_FALSE(k.contains("bytes_per_source_sample"));
  EXPECT_FALSE(k["levels"][0].contains("bytes_per_source_sample"));
  ASSERT_TRUE(inspect::summary_text(reader_, path_, text).ok());
  EXPECT_NE(text.find("(not recorded by the writer)"), std::string::npos) << text;
}

TEST_F(Inspect, SummaryShowsOverviewLevels) {
  synthetic::Spec spec;  // 6 x 6 roots: 36 > 16, one overview level of 3 x 3
  spec.min_level = 5;
  spec.overview_levels = -1;
  ASSERT_TRUE(synthetic::write_archive(path_, spec).ok());
  ASSERT_TRUE(reader_.open(path_).ok());
  std::string text;
  ASSERT_TRUE(inspect::summary_text(reader_, path_, text).ok());
  EXPECT_NE(text.find("overview   1 levels above the roots (6..6), top level 6 holds 9 nodes"), std::string::npos) << text;
  EXPECT_NE(text.find("4096"), std::string::npos) << text;
  ASSERT_TRUE(inspect::summary_json(reader_, path_, text).ok());
  EXPECT_NE(text.find("\"overview_levels\": 1"), std::string::npos) << text;
  EXPECT_NE(text.find("\"top_level\": 6"), std::string::npos) << text;
}

}  // namespace
}  // namespace terrain
