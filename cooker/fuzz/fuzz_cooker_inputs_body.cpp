#include "fuzz_cooker_inputs_body.h"

#include <zip.h>
#include <zlib.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "inputs/inputs.h"
#include "base/memory_budget.h"
#include "terrain/cook.h"

namespace terrain::fuzz {
namespace {

struct Format {
  const char* name;
  bool needs_georef;  // images, raw and npz without extent: --spacing and --crs local
};
constexpr Format kFormats[] = {{"N10E010.hgt", false}, {"N10E010.hgt.zip", false}, {"N10E010.hgt.gz", false},
                               {"in.npz", true},       {"in.r16", true},           {"in.r32", true},
                               {"in.png", true}};
constexpr size_t kFormatCount = sizeof kFormats / sizeof kFormats[0];
constexpr uint64_t kBudget = uint64_t(256) << 20;

void require(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz_cooker_inputs: broken invariant: %s\n", what);
    std::abort();
  }
}

void write_file(const std::string& path, const uint8_t* data, size_t size) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
}

std::vector<uint8_t> slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

std::vector<uint8_t> with_header(uint8_t format, uint8_t w, uint8_t h, const std::vector<uint8_t>& body) {
  std::vector<uint8_t> out;
  out.reserve(3 + body.size());
  for (uint8_t b : {format, w, h}) out.push_back(b);
  for (uint8_t b : body) out.push_back(b);
  return out;
}

// A zip of (name, bytes) entries, written by libzip.
std::vector<uint8_t> make_zip(const std::string& path, const std::vector<std::pair<std::string, std::vector<uint8_t>>>& entries) {
  std::filesystem::remove(path);
  int err = 0;
  zip_t* z = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  require(z != nullptr, "seed zip opens");
  for (const auto& [name, bytes] : entries) {
    zip_source_t* src = zip_source_buffer(z, bytes.data(), bytes.size(), 0);
    require(src && zip_file_add(z, name.c_str(), src, ZIP_FL_OVERWRITE) >= 0, "seed zip entry");
  }
  require(zip_close(z) == 0, "seed zip closes");
  return slurp(path);
}

std::vector<uint8_t> npy(const std::string& descr, const std::string& shape, const std::vector<uint8_t>& data) {
  std::string h = "{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape + ", }";
  while ((10 + h.size() + 1) % 64) h += ' ';
  h += '\n';
  std::vector<uint8_t> out;
  out.reserve(10 + h.size() + data.size());
  for (uint8_t b : {uint8_t(0x93), uint8_t('N'), uint8_t('U'), uint8_t('M'), uint8_t('P'), uint8_t('Y'), uint8_t(1),
                    uint8_t(0), uint8_t(h.size() & 0xff), uint8_t(h.size() >> 8)})
    out.push_back(b);
  for (char c : h) out.push_back(uint8_t(c));
  for (uint8_t b : data) out.push_back(b);
  return out;
}

std::vector<uint8_t> f8(double v) {
  std::vector<uint8_t> b(8);
  std::memcpy(b.data(), &v, 8);
  return b;
}

// A 16-bit greyscale PNG written by hand (signature, IHDR, one zlib IDAT, IEND).
std::vector<uint8_t> png16(int w, int h) {
  std::vector<uint8_t> out;
  for (int b : {0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a}) out.push_back(uint8_t(b));  // \x89PNG\r\n\x1a\n
  auto chunk = [&](const char* type, const std::vector<uint8_t>& d) {
    const uint32_t n = uint32_t(d.size());
    for (int s = 24; s >= 0; s -= 8) out.push_back(uint8_t(n >> s));
    std::vector<uint8_t> td;
    for (int i = 0; i < 4; ++i) td.push_back(uint8_t(type[i]));
    for (uint8_t b : d) td.push_back(b);
    for (uint8_t b : td) out.push_back(b);
    const uint32_t crc = uint32_t(crc32(0, td.data(), uInt(td.size())));
    for (int s = 24; s >= 0; s -= 8) out.push_back(uint8_t(crc >> s));
  };
  chunk("IHDR", {0, 0, 0, uint8_t(w), 0, 0, 0, uint8_t(h), 16, 0, 0, 0, 0});
  std::vector<uint8_t> raw;
  for (int y = 0; y < h; ++y) {
    raw.push_back(0);  // filter: none
    for (int x = 0; x < w; ++x) {
      const int v = 1000 + 37 * x + 11 * y;
      raw.push_back(uint8_t(v >> 8));
      raw.push_back(uint8_t(v));
    }
  }
  uLongf len = compressBound(uLong(raw.size()));
  std::vector<uint8_t> z(len);
  require(compress(z.data(), &len, raw.data(), uLong(raw.size())) == Z_OK, "seed png deflate");
  z.resize(len);
  chunk("IDAT", z);
  chunk("IEND", {});
  return out;
}

}  // namespace

int cooker_inputs_one_input(const uint8_t* data, size_t size, const std::string& dir) {
  if (size < 3) return 0;
  const Format& f = kFormats[data[0] % kFormatCount];
  const std::string path = dir + "/" + f.name;
  write_file(path, data + 3, size - 3);
  cook::InputOptions o;
  o.inputs = {path};
  o.memory_limit_bytes = kBudget;
  o.raw_size = {std::max<int>(data[1], 1), std::max<int>(data[2], 1)};
  if (f.needs_georef) {
    o.spacing = std::array<double, 2>{1.0, 1.0};
    o.crs = "local";
  }
  std::vector<cook::Raster> rasters;
  const Status st = cook::load_inputs(o, rasters);
  std::filesystem::remove(path);
  if (!st.ok()) {
    require(!st.message.empty(), "a failure has a message");
    return 0;
  }
  require(rasters.size() == 1, "one raster per input");
  const cook::Raster& r = rasters[0];
  require(r.width >= 2 && r.height >= 2, "at least 2x2 samples");
  require(r.values.size() == size_t(r.width) * size_t(r.height), "values match the size");
  require(uint64_t(r.values.size()) * cook::kCookBytesPerSample <= kBudget, "within the budget");
  require(r.geo.valid, "positioned");
  for (float v : r.values) require(std::isnan(v) || (v >= o.valid_range_m[0] && v <= o.valid_range_m[1]), "plausible");
  int c0 = 0, r0 = 0, c1 = 0, r1 = 0;
  uint64_t valid = 0;
  if (cook::valid_bounds(r, c0, r0, c1, r1, valid))
    require(c0 <= c1 && r0 <= r1 && c1 < r.width && r1 < r.height && valid > 0, "valid bounds inside");
  return 1;
}

std::vector<std::vector<uint8_t>> cooker_inputs_seeds(const std::string& dir) {
  std::vector<std::vector<uint8_t>> seeds;
  // A 3" HGT tile with a little relief and a void (mostly constant: it zips to a few KB).
  std::vector<uint8_t> hgt(size_t(1201) * 1201 * 2, 0);
  for (size_t i = 0; i < hgt.size() / 2; ++i) {
    const int v = i % 1201 < 8 ? int(i % 1201) * 10 : 250;
    hgt[2 * i] = uint8_t(v >> 8);
    hgt[2 * i + 1] = uint8_t(v);
  }
  hgt[2 * 5000] = 0x80;  // -32768: a void
  hgt[2 * 5000 + 1] = 0;
  seeds.push_back(with_header(1, 0, 0, make_zip(dir + "/seed.zip", {{"N10E010.hgt", hgt}})));
  {
    const std::string gz = dir + "/seed.gz";
    gzFile g = gzopen(gz.c_str(), "wb9");
    require(g != nullptr && gzwrite(g, hgt.data(), unsigned(hgt.size())) == int(hgt.size()) && gzclose(g) == Z_OK,
            "seed gzip");
    seeds.push_back(with_header(2, 0, 0, slurp(gz)));
  }
  // .npz: 3x4 Int16 elevations with edges, and one without an extent.
  std::vector<uint8_t> elev;
  for (int i = 0; i < 12; ++i) {
    elev.push_back(uint8_t(100 + i));
    elev.push_back(0);
  }
  seeds.push_back(with_header(3, 0, 0,
                              make_zip(dir + "/seed.npz", {{"elevation.npy", npy("<i2", "(3, 4)", elev)},
                                                           {"xmin.npy", npy("<f8", "()", f8(10.0))},
                                                           {"xmax.npy", npy("<f8", "()", f8(14.0))},
                                                           {"ymin.npy", npy("<f8", "()", f8(23.0))},
                                                           {"ymax.npy", npy("<f8", "()", f8(20.0))}})));
  seeds.push_back(with_header(3, 0, 0, make_zip(dir + "/seed2.npz", {{"elevation.npy", npy(">f4", "(2, 2)", std::vector<uint8_t>(16, 0x42))}})));
  // Raw: 4x3 u16 and 3x3 f32 (one NaN).
  std::vector<uint8_t> r16;
  for (int i = 0; i < 12; ++i) {
    r16.push_back(uint8_t(i * 7));
    r16.push_back(1);
  }
  seeds.push_back(with_header(4, 4, 3, r16));
  std::vector<uint8_t> r32;
  for (int i = 0; i < 9; ++i) {
    const float v = i == 4 ? NAN : 100.0f + float(i);
    uint8_t b[4];
    std::memcpy(b, &v, 4);
    r32.insert(r32.end(), b, b + 4);
  }
  seeds.push_back(with_header(5, 3, 3, r32));
  seeds.push_back(with_header(6, 0, 0, png16(8, 6)));
  for (const char* name : {"seed.zip", "seed.gz", "seed.npz", "seed2.npz"}) std::filesystem::remove(dir + "/" + name);
  return seeds;
}

}  // namespace terrain::fuzz
