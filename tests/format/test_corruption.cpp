// Corruption: >= 1000 random truncations, bit flips and overwritten ranges per archive (a
// synthetic one, always; one built from the real Kilauea DEM when the data is present). Each
// damaged file must give a clean error naming a known code, or -- where no checksum can see the
// change, i.e. the bytes did not change -- exactly the original data. Never a crash, hang or
// sanitizer report (ASan/UBSan run in CI).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <set>

#include "archive_fixture.h"
#include "real_dem.h"
#include "test_data.h"

namespace terrain {
namespace {

std::vector<uint8_t> slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

struct Outcome {
  int trials = 0, rejected_at_open = 0, rejected_at_decode = 0, unchanged_ok = 0;
  std::map<std::string, int> codes;
};

// Decodes every node of `reader` (all sections) into `out` (one NodeData per node).
std::vector<std::unique_ptr<NodeData>> decode_all(const ArchiveReader& reader) {
  std::vector<std::unique_ptr<NodeData>> out;
  for (size_t i = 0; i < reader.nodes().size(); ++i) {
    out.push_back(std::make_unique<NodeData>());
    EXPECT_TRUE(reader.decode_node(i, *out.back()).ok());
  }
  return out;
}

bool same(const NodeData& a, const NodeData& b) {
  return a.heights == b.heights && a.normals_bc3 == b.normals_bc3 && a.albedo_bc1 == b.albedo_bc1 && a.splat == b.splat &&
         a.cones_bc3 == b.cones_bc3;
}

void attack(const std::vector<uint8_t>& original, int trials, uint32_t seed, Outcome& o) {
  ArchiveReader good;
  ASSERT_TRUE(good.open_memory(original).ok());
  const auto reference = decode_all(good);
  std::mt19937_64 rng(seed);
  auto pick_offset = [&]() -> size_t {
    // Half uniform over the file, half aimed at the small structures (header, directory, metadata).
    const uint64_t r = rng() % 4;
    if (r == 0) return size_t(rng() % std::min<size_t>(128, original.size()));
    if (r == 1) {
      const size_t tail = std::min<size_t>(original.size(), 48 * good.nodes().size() + 2048);
      return original.size() - 1 - size_t(rng() % tail);
    }
    return size_t(rng() % original.size());
  };
  const std::set<Error> open_errors = {Error::bad_magic,         Error::unsupported_version, Error::truncated,
                                       Error::header_checksum,   Error::header_invalid,      Error::section_out_of_bounds,
                                       Error::metadata_checksum, Error::metadata_invalid,    Error::directory_checksum,
                                       Error::directory_invalid, Error::payload_out_of_bounds};
  const std::set<Error> decode_errors = {Error::payload_checksum, Error::payload_invalid, Error::decompress_failed};
  auto out = std::make_unique<NodeData>();
  for (int t = 0; t < trials; ++t) {
    std::vector<uint8_t> bytes = original;
    size_t lo = 0, hi = 0;  // damaged range
    switch (t % 3) {
      case 0: {  // truncation
        const size_t n = size_t(rng() % original.size());
        bytes.resize(n);
        lo = n;
        hi = original.size();
        break;
      }
      case 1: {  // 1..4 bit flips near each other
        const size_t at = pick_offset();
        const int flips = 1 + int(rng() % 4);
        lo = hi = at;
        for (int f = 0; f < flips; ++f) {
          const size_t p = std::min(bytes.size() - 1, at + size_t(rng() % 16));
          bytes[p] ^= uint8_t(1u << (rng() % 8));
          hi = std::max(hi, p + 1);
        }
        break;
      }
      default: {  // overwrite a range with random bytes, zeros or 0xFF
        const size_t at = pick_offset();
        const size_t len = std::min(bytes.size() - at, size_t(1 + rng() % 64));
        const int kind = int(rng() % 3);
        for (size_t p = at; p < at + len; ++p) bytes[p] = kind == 0 ? uint8_t(rng()) : kind == 1 ? 0 : 0xFF;
        lo = at;
        hi = at + len;
        break;
      }
    }
    ++o.trials;
    const bool changed = bytes != original;
    // A fresh, exact-size allocation per trial so ASan catches any over-read.
    std::unique_ptr<uint8_t[]> exact(new uint8_t[bytes.size() ? bytes.size() : 1]);
    std::copy(bytes.begin(), bytes.end(), exact.get());
    ArchiveReader reader;
    const Status s = reader.open_memory({exact.get(), bytes.size()});
    if (!s.ok()) {
      ASSERT_TRUE(open_errors.count(s.code)) << "trial " << t << ": unexpected code " << s.to_string();
      ASSERT_FALSE(s.message.empty());
      ASSERT_TRUE(changed) << "an unchanged archive was rejected: " << s.to_string();
      ++o.rejected_at_open;
      ++o.codes[error_name(s.code)];
      continue;
    }
    // Opened: header, metadata and directory are intact. Decode the nodes whose payload the
    // damage touched; all others must still decode to the reference.
    ASSERT_EQ(reader.nodes().size(), good.nodes().size());
    bool node_rejected = false;
    const size_t spot_a = size_t(rng() % reader.nodes().size()), spot_b = size_t(rng() % reader.nodes().size());
    for (size_t i = 0; i < reader.nodes().size(); ++i) {
      const NodeRecord& r = reader.nodes()[i];
      const bool touched = r.payload_offset < hi && lo < r.payload_offset + r.payload_size;
      if (!touched && i != spot_a && i != spot_b) continue;  // untouched bytes: spot-check two nodes per trial
      const Status d = reader.decode_node(i, *out);
      if (!d.ok()) {
        ASSERT_TRUE(touched) << "untouched node " << i << " failed: " << d.to_string();
        ASSERT_TRUE(decode_errors.count(d.code)) << "unexpected code " << d.to_string();
        ASSERT_NE(d.message.find("node "), std::string::npos) << "error does not name the node: " << d.to_string();
        node_rejected = true;
        ++o.codes[error_name(d.code)];
      } else {
        ASSERT_TRUE(same(*out, *reference[i])) << "trial " << t << ": node " << i << " decoded to different data";
      }
    }
    if (node_rejected) {
      ++o.rejected_at_decode;
      if (o.rejected_at_decode % 25 == 1) {
        EXPECT_FALSE(reader.verify().ok());  // full verification sees it too
      }
    } else {
      ASSERT_FALSE(changed) << "trial " << t << ": a change at [" << lo << ", " << hi << ") went unnoticed";
      ++o.unchanged_ok;
    }
  }
}

void report(const char* name, const Outcome& o) {
  std::string codes;
  for (const auto& [k, v] : o.codes) codes += " " + k + "=" + std::to_string(v);
  std::printf("%s: %d trials, %d rejected at open, %d rejected at decode, %d unchanged and valid;%s\n", name, o.trials,
              o.rejected_at_open, o.rejected_at_decode, o.unchanged_ok, codes.c_str());
}

// `trials` damaged copies (seeded) of the archive at `path`, the outcome printed under `name`.
Outcome attack_archive(const char* name, const std::string& path, int trials, uint32_t seed) {
  Outcome o;
  attack(slurp(path), trials, seed, o);
  report(name, o);
  return o;
}

TEST(Corruption, SyntheticArchiveNeverCrashesAndNeverLies) {
  const auto dir = test::scratch_dir("corruption-synthetic");
  const auto path = (dir / "a.terrain").string();
  WorldInfo w = test::make_world();
  // Compressible surface layers keep the file small, so many trials stay fast under ASan.
  ASSERT_TRUE(test::write_archive_of(path, w, test::sparse_keys(), PayloadOptions{},
                                     [&](const NodeKey& k) { return test::make_seed_node(w, k); })
                  .ok());
  const Outcome o = attack_archive("synthetic", path, 1500, 42);
  EXPECT_EQ(o.trials, 1500);
  EXPECT_GT(o.rejected_at_open, 300);
  EXPECT_GT(o.rejected_at_decode, 100);
  std::filesystem::remove_all(dir);
}

// The same on an archive with a proj frame (format/SPEC.md section 17): its extension record
// is inside the metadata CRC, so any damage to it is caught at open.
TEST(Corruption, SyntheticProjFrameArchiveNeverCrashesAndNeverLies) {
  const auto dir = test::scratch_dir("corruption-v2");
  const auto path = (dir / "a.terrain").string();
  WorldInfo w = test::make_world();
  w.crs.kind = ProjectionKind::proj;
  w.crs.lat0_deg = w.crs.lon0_deg = w.crs.false_easting_m = 0;
  w.crs.scale_k0 = 1;
  w.crs.definition = "PROJCRS[\"custom LCC\",BASEGEOGCRS[\"WGS 84\",DATUM[\"World Geodetic System 1984\",ELLIPSOID[\"WGS 84\","
                     "6378137,298.257223563]]],CONVERSION[\"lcc\",METHOD[\"Lambert Conic Conformal (2SP)\"]],"
                     "CS[Cartesian,2],AXIS[\"E\",east],AXIS[\"N\",north],LENGTHUNIT[\"metre\",1]]";
  ASSERT_TRUE(test::write_archive_of(path, w, test::sparse_keys(), PayloadOptions{},
                                     [&](const NodeKey& k) { return test::make_seed_node(w, k); })
                  .ok());
  ASSERT_EQ(slurp(path)[8], 3);
  const Outcome o = attack_archive("synthetic v2", path, 1500, 43);
  EXPECT_EQ(o.trials, 1500);
  EXPECT_GT(o.rejected_at_open, 300);
  EXPECT_GT(o.rejected_at_decode, 100);
  std::filesystem::remove_all(dir);
}

TEST(Corruption, RealKilaueaArchiveNeverCrashesAndNeverLies) {
  const auto dem_path = test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem_path);
  test::Dem dem;
  ASSERT_TRUE(test::read_dem(dem_path.string(), -32768.0f, dem));
  const auto dir = test::scratch_dir("corruption-kilauea");
  const auto path = (dir / "kilauea.terrain").string();
  WorldInfo w;
  ASSERT_TRUE(test::write_dem_archive(path, dem, w).ok());
  const Outcome o = attack_archive("kilauea", path, 1200, 7);
  EXPECT_EQ(o.trials, 1200);
  EXPECT_GT(o.rejected_at_decode, 100);
  std::filesystem::remove_all(dir);
}

TEST(Corruption, NamedFieldDamageGivesTheNamedError) {
  const auto dir = test::scratch_dir("corruption-named");
  const auto path = (dir / "a.terrain").string();
  ASSERT_TRUE(test::write_seed_archive(path, true).ok());
  const auto good = slurp(path);
  auto open_with = [&](auto&& mutate) {
    std::vector<uint8_t> b = good;
    mutate(b);
    ArchiveReader r;
    return r.open_memory(b).code;
  };
  EXPECT_EQ(open_with([](auto& b) { b[0] = 'X'; }), Error::bad_magic);
  EXPECT_EQ(open_with([](auto& b) { b[8] = 4; }), Error::unsupported_version);  // readers open 1, 2 and 3
  EXPECT_EQ(open_with([](auto& b) { b.resize(100); }), Error::truncated);
  EXPECT_EQ(open_with([](auto& b) { b.resize(b.size() - 1); }), Error::truncated);
  EXPECT_EQ(open_with([](auto& b) { b.push_back(0); }), Error::header_invalid);
  EXPECT_EQ(open_with([](auto& b) { b[30] ^= 1; }), Error::header_checksum);
  auto u64_at = [&](size_t at) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; --i) v = (v << 8) | good[at + size_t(i)];
    return size_t(v);
  };
  const size_t directory_offset = u64_at(48), metadata_offset = u64_at(64);
  EXPECT_EQ(open_with([&](auto& b) { b[metadata_offset + 10] ^= 0x20; }), Error::metadata_checksum);
  EXPECT_EQ(open_with([&](auto& b) { b[directory_offset + 5] ^= 0x01; }), Error::directory_checksum);  // a page
  EXPECT_EQ(open_with([&](auto& b) { b[metadata_offset - 3] ^= 0x01; }), Error::directory_checksum);    // the page table
  ArchiveReader r;
  ASSERT_TRUE(r.open_memory(good).ok());
  std::vector<uint8_t> b = good;
  b[r.nodes()[2].payload_offset + 70] ^= 0x40;
  ASSERT_TRUE(r.open_memory(b).ok());
  NodeData d;
  const Status s = r.decode_node(2, d);
  EXPECT_EQ(s.code, Error::payload_checksum);
  EXPECT_NE(s.message.find("node 2/"), std::string::npos) << s.message;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace terrain
