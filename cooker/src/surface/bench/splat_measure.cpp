// Splat coherence figures of an archive (see splat_measure.h).
#include "splat_measure.h"

#include <algorithm>
#include <map>

#include "terrain/bc_decode.h"
#include "terrain/format.h"

namespace terrain::cook::bench {
namespace {

constexpr int kN = kSplatSamples;  // 65

struct Map {
  std::array<uint8_t, kSplatCount> id{};
  std::array<uint8_t, kSplatCount> data{};  // 1 = the sample's vertex has data
};

Status load_map(const ArchiveReader& a, size_t index, Map& m) {
  static thread_local NodeData d;
  if (Status s = a.decode_node(index, d, kSectionAlbedo | kSectionSplat); !s.ok()) return s;
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4);
  decode_bc1_image(d.albedo_bc1.data(), kTexelBlocks, kTexelBlocks, rgba.data());
  for (int j = 0; j < kN; ++j)
    for (int i = 0; i < kN; ++i) {
      // Sample (i, j) is vertex (2i, 2j), whose hole flag is albedo texel (2i + 2, 2j + 2).
      const size_t t = size_t((2 * j + kApron) * kTexels + 2 * i + kApron);
      m.id[size_t(j * kN + i)] = d.splat[size_t(j * kN + i)];
      m.data[size_t(j * kN + i)] = rgba[t * 4 + 3] != 0;
    }
  return Status::success();
}

}  // namespace

Status measure_splat(const ArchiveReader& a, SplatMeasure& out) {
  out = SplatMeasure{};
  const auto nodes = a.nodes();
  uint32_t finest = ~0u;
  for (const NodeRecord& r : nodes) finest = std::min(finest, r.key.level);
  out.finest_level = finest;
  Map m, c;
  for (size_t n = 0; n < nodes.size(); ++n) {
    if (Status s = load_map(a, n, m); !s.ok()) return s;
    const bool fine = nodes[n].key.level == finest;
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) {
        const size_t e = size_t(j * kN + i);
        if (!m.data[e]) continue;
        ++out.samples;
        ++out.count[m.id[e]];
        if (i + 1 < kN && m.data[e + 1]) {
          const bool d = m.id[e] != m.id[e + 1];
          out.changes += d, ++out.pairs;
          if (fine) out.fine_changes += d, ++out.fine_pairs;
        }
        if (j + 1 < kN && m.data[e + kN]) {
          const bool d = m.id[e] != m.id[e + kN];
          out.changes += d, ++out.pairs;
          if (fine) out.fine_changes += d, ++out.fine_pairs;
        }
        if (i > 0 && j > 0 && i + 1 < kN && j + 1 < kN && m.data[e - 1] && m.data[e + 1] && m.data[e - kN] &&
            m.data[e + kN]) {
          const uint8_t v = m.id[e];
          const bool alone = v != m.id[e - 1] && v != m.id[e + 1] && v != m.id[e - kN] && v != m.id[e + kN];
          out.isolated += alone, ++out.isolated_tested;
          if (fine) out.fine_isolated += alone, ++out.fine_isolated_tested;
        }
      }
    const NodeKey k = nodes[n].key;
    // Shared edges with the east and north neighbours.
    for (int dir = 0; dir < 2; ++dir) {
      const int64_t ni = a.find(NodeKey{k.level, k.x + (dir == 0), k.y + (dir == 1)});
      if (ni < 0) continue;
      if (Status s = load_map(a, size_t(ni), c); !s.ok()) return s;
      for (int t = 0; t < kN; ++t) {
        const size_t mine = dir == 0 ? size_t(t * kN + kN - 1) : size_t((kN - 1) * kN + t);
        const size_t theirs = dir == 0 ? size_t(t * kN) : size_t(t);
        ++out.seam_samples;
        out.seam_mismatches += m.id[mine] != c.id[theirs];
      }
    }
    // Level agreement against the 4 children.
    if (k.level == 0) continue;
    for (uint32_t cy = 0; cy < 2; ++cy)
      for (uint32_t cx = 0; cx < 2; ++cx) {
        const int64_t ci = a.find(NodeKey{k.level - 1, 2 * k.x + cx, 2 * k.y + cy});
        if (ci < 0) continue;
        if (Status s = load_map(a, size_t(ci), c); !s.ok()) return s;
        for (int j = 0; j < kN; ++j)
          for (int i = 0; i < kN; ++i) {
            const int a0 = 2 * i - 64 * int(cx), b0 = 2 * j - 64 * int(cy);
            if (a0 < 0 || a0 > 64 || b0 < 0 || b0 > 64) continue;
            const size_t e = size_t(j * kN + i);
            if (!m.data[e]) continue;
            std::map<uint8_t, int> votes;
            bool all = true;
            for (int b = b0; b <= std::min(b0 + 1, 64); ++b)
              for (int q = a0; q <= std::min(a0 + 1, 64); ++q) {
                const size_t f = size_t(b * kN + q);
                all = all && c.data[f];
                ++votes[c.id[f]];
              }
            if (!all) continue;
            int top = 0;
            for (const auto& [id, v] : votes) top = std::max(top, v);
            ++out.lod_tested;
            out.lod_agree += votes.count(m.id[e]) && votes[m.id[e]] == top;
          }
      }
  }
  return Status::success();
}

Status measure_splat_file(const std::string& path, SplatMeasure& out) {
  ArchiveReader a;
  if (Status s = a.open(path); !s.ok()) return s;
  return measure_splat(a, out);
}

}  // namespace terrain::cook::bench
