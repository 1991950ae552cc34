// Format versions 2 and 3 (format/SPEC.md sections 17, 20): the extension records of version 2 (a
// proj frame with its WKT2 definition) read back from what writers write today (version 3), every
// damaged field named; files of versions 1 and 2 still open, with the same nodes in the same order.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>

#include "archive_fixture.h"
#include "archive_bytes.h"
#include "terrain/archive_layout.h"
#include "test_data.h"

namespace terrain {
namespace {

// A Lambert conformal conic frame as PROJ writes it (the format library only stores the text).
constexpr const char* kLccWkt =
    "PROJCRS[\"RGF93 v1 / Lambert-93\",BASEGEOGCRS[\"RGF93 v1\",DATUM[\"Reseau Geodesique Francais 1993 v1\","
    "ELLIPSOID[\"GRS 1980\",6378137,298.257222101]]],CONVERSION[\"Lambert-93\",METHOD[\"Lambert Conic Conformal "
    "(2SP)\"],PARAMETER[\"Latitude of false origin\",46.5],PARAMETER[\"Longitude of false origin\",3],"
    "PARAMETER[\"Latitude of 1st standard parallel\",49],PARAMETER[\"Latitude of 2nd standard parallel\",44],"
    "PARAMETER[\"Easting at false origin\",700000],PARAMETER[\"Northing at false origin\",6600000]],"
    "CS[Cartesian,2],AXIS[\"easting (X)\",east],AXIS[\"northing (Y)\",north],LENGTHUNIT[\"metre\",1],"
    "ID[\"EPSG\",2154]]";  // 589 bytes: its record ends with 3 bytes of padding

WorldInfo lcc_world() {
  WorldInfo w = test::make_world();  // 2 x 1 roots, as sparse_keys() needs
  w.crs = FrameCrs{};
  w.crs.kind = ProjectionKind::proj;
  w.crs.epsg = 2154;
  w.crs.semi_major_m = 6378137.0;
  w.crs.inverse_flattening = 298.257222101;
  w.crs.name = "RGF93 v1 / Lambert-93";
  w.crs.definition = kLccWkt;
  w.origin_x_m = 800000;
  w.origin_y_m = 6400000;
  w.extent_min_x_m = w.origin_x_m + 1;
  w.extent_min_y_m = w.origin_y_m + 1;
  w.extent_max_x_m = w.origin_x_m + 4000;
  w.extent_max_y_m = w.origin_y_m + 2000;
  return w;
}

using namespace test;  // archive_bytes.h: slurp, get/put_u32/u64, crc, reseal

class FormatV2 : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::scratch_dir("format-v2");
    const auto path = (dir_ / "lcc.terrain").string();
    const WorldInfo w = lcc_world();
    ASSERT_TRUE(test::write_synthetic_archive(path, w, test::sparse_keys()).ok());
    good_ = slurp(path);
    meta_ = size_t(get_u64(good_, layout::header::metadata_offset));
    ext_ = good_.size() - get_u32(good_, meta_ + layout::metadata::extension_size);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  // Opens good_ (or its version-`legacy` bytes, legacy_bytes()) changed by `mutate`, re-sealed.
  Error open_with(const std::function<void(std::vector<uint8_t>&)>& mutate, std::string* message = nullptr,
                  uint32_t legacy = 0) {
    std::vector<uint8_t> b = legacy ? legacy_bytes(good_, legacy) : good_;
    mutate(b);
    reseal(b);
    ArchiveReader r;
    const Status s = r.open_memory(b);
    if (message) *message = s.message;
    return s.code;
  }
  std::filesystem::path dir_;
  std::vector<uint8_t> good_;
  size_t meta_ = 0, ext_ = 0;  // metadata offset, first extension record
};

TEST_F(FormatV2, TmFrameIsVersionThreeAndItsVersionOneBytesReadTheSame) {
  const auto path = (dir_ / "tm.terrain").string();
  ASSERT_TRUE(test::write_synthetic_archive(path, test::make_world(), test::sparse_keys()).ok());
  const auto b = slurp(path);
  EXPECT_EQ(get_u32(b, layout::header::format_version), 3u);
  EXPECT_EQ(get_u32(b, size_t(get_u64(b, layout::header::metadata_offset)) + layout::metadata::reserved3), 0u);
  ArchiveReader r;
  ASSERT_TRUE(r.open(path).ok());
  EXPECT_EQ(r.format_version(), 3u);
  EXPECT_TRUE(r.world().crs.definition.empty());
  // The same archive as a version-1 writer made it: row order on disk, directory order in the reader.
  ArchiveReader v1;
  ASSERT_TRUE(v1.open_memory(legacy_bytes(b, 1)).ok());
  EXPECT_EQ(v1.format_version(), 1u);
  ASSERT_EQ(v1.nodes().size(), r.nodes().size());
  for (size_t i = 0; i < r.nodes().size(); ++i) {
    EXPECT_EQ(v1.nodes()[i].key, r.nodes()[i].key) << i;
    EXPECT_EQ(v1.nodes()[i].payload_offset, r.nodes()[i].payload_offset) << i;
    EXPECT_EQ(v1.find(r.nodes()[i].key), int64_t(i));
  }
  EXPECT_TRUE(v1.verify().ok());
}

TEST_F(FormatV2, ProjFrameRoundTripsInVersionThreeAndTwo) {
  EXPECT_EQ(get_u32(good_, layout::header::format_version), 3u);
  const size_t def_size = std::strlen(kLccWkt);
  ASSERT_EQ(def_size % 4, 1u);  // the padding test below needs padding
  // One record: tag 1, size, the text, padding to 4.
  EXPECT_EQ(get_u32(good_, meta_ + layout::metadata::extension_size), 8 + ((def_size + 3) & ~size_t(3)));
  EXPECT_EQ(get_u32(good_, ext_), layout::kExtensionFrameDefinition);
  EXPECT_EQ(get_u32(good_, ext_ + 4), def_size);
  ArchiveReader r;
  ASSERT_TRUE(r.open_memory(good_).ok());
  EXPECT_EQ(r.format_version(), 3u);
  EXPECT_EQ(r.world().crs.kind, ProjectionKind::proj);
  EXPECT_EQ(r.world().crs.definition, kLccWkt);
  EXPECT_EQ(r.world().crs.epsg, 2154);
  EXPECT_TRUE(r.verify().ok());
  ArchiveReader v2;
  ASSERT_TRUE(v2.open_memory(legacy_bytes(good_, 2)).ok());
  EXPECT_EQ(v2.format_version(), 2u);
  EXPECT_EQ(v2.world().crs.definition, kLccWkt);
  EXPECT_TRUE(v2.verify().ok());
}

TEST_F(FormatV2, DamagedVersionTwoFieldsAreNamed) {
  namespace m = layout::metadata;
  std::string msg;
  EXPECT_EQ(open_with([](auto& b) { put_u32(b, layout::header::format_version, 4); }), Error::unsupported_version);
  // A proj frame in a version-1 file: offset 164 is then reserved.
  EXPECT_EQ(open_with([](auto& b) { put_u32(b, layout::header::format_version, 1); }, &msg, 2), Error::metadata_invalid);
  EXPECT_NE(msg.find("reserved"), std::string::npos) << msg;
  EXPECT_EQ(open_with([&](auto& b) {
              put_u32(b, layout::header::format_version, 1);
              put_u32(b, b.size() - (good_.size() - meta_) + m::extension_size, 0);
              b.resize(b.size() - (good_.size() - ext_));
            }, &msg, 2),
            Error::metadata_invalid);
  EXPECT_NE(msg.find("version 1"), std::string::npos) << msg;
  // Without its definition record.
  EXPECT_EQ(open_with([&](auto& b) {
              put_u32(b, meta_ + m::extension_size, 0);
              b.resize(ext_);
            }, &msg),
            Error::metadata_invalid);
  EXPECT_NE(msg.find("frame_definition"), std::string::npos) << msg;
  // A definition with a TM frame.
  EXPECT_EQ(open_with([&](auto& b) { b[meta_ + m::projection_kind] = 1; }, &msg), Error::metadata_invalid);
  EXPECT_EQ(open_with([&](auto& b) { b[meta_ + m::projection_kind] = 3; }, &msg), Error::metadata_invalid);
  EXPECT_EQ(open_with([&](auto& b) { put_u32(b, meta_ + m::extension_size, get_u32(b, meta_ + m::extension_size) + 2); }, &msg),
            Error::metadata_invalid);
  EXPECT_EQ(open_with([&](auto& b) { put_u32(b, ext_ + 4, get_u32(b, ext_ + 4) + 8); }, &msg), Error::metadata_invalid);
  EXPECT_NE(msg.find("past extension_size"), std::string::npos) << msg;
  EXPECT_EQ(open_with([&](auto& b) { put_u32(b, ext_ + 4, 0); }, &msg), Error::metadata_invalid);
  EXPECT_EQ(open_with([&](auto& b) { b.back() = 7; }, &msg), Error::metadata_invalid);  // padding
  EXPECT_NE(msg.find("padding"), std::string::npos) << msg;
  EXPECT_EQ(open_with([&](auto& b) { b[ext_ + 8 + 20] = 0; }, &msg), Error::metadata_invalid);  // NUL in the text
  EXPECT_EQ(open_with([&](auto& b) { put_u32(b, ext_, 0); }, &msg), Error::metadata_invalid);
  // A required tag this reader does not know, after the definition.
  auto append = [&](auto& b, uint32_t tag) {
    for (uint32_t v : {tag, 4u, 0x01020304u}) b.insert(b.end(), {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)});
    put_u32(b, meta_ + m::extension_size, get_u32(b, meta_ + m::extension_size) + 12);
  };
  EXPECT_EQ(open_with([&](auto& b) { append(b, 7); }, &msg), Error::metadata_invalid);
  EXPECT_NE(msg.find("unknown required tag 7"), std::string::npos) << msg;
  EXPECT_EQ(open_with([&](auto& b) { append(b, 1); }, &msg), Error::metadata_invalid);  // tag repeated
  // An optional tag is skipped.
  EXPECT_EQ(open_with([&](auto& b) { append(b, layout::kExtensionOptional | 5u); }), Error::ok);
}

}  // namespace
}  // namespace terrain
