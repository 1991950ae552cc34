// terrain-splat-measure ARCHIVE...: splat coherence per archive (issue 18): isolated samples and
// neighbour id changes (all levels, and the finest level), agreement of each node with its
// children, and the share of every palette material.
// terrain-splat-measure --same-geometry A B: exit 0 when both archives hold the same nodes with
// byte-identical heights, normals and cones (the sections a splat change must leave alone).
#include <cstdio>
#include <string>

#include "splat_measure.h"
#include "terrain/format.h"

using namespace terrain;

namespace {

int same_geometry(const char* pa, const char* pb) {
  ArchiveReader a, b;
  Status s = a.open(pa);
  if (s.ok()) s = b.open(pb);
  if (!s.ok()) {
    std::fprintf(stderr, "%s\n", s.to_string().c_str());
    return 1;
  }
  const auto na = a.nodes(), nb = b.nodes();
  if (na.size() != nb.size()) {
    std::printf("node counts differ: %zu vs %zu\n", na.size(), nb.size());
    return 1;
  }
  size_t differ[4] = {};  // heights, normals, cones, splat
  static NodeData da, db;
  for (size_t i = 0; i < na.size(); ++i) {
    const int64_t j = b.find(na[i].key);
    if (j < 0) {
      std::printf("node %u/%u/%u missing\n", na[i].key.level, na[i].key.x, na[i].key.y);
      return 1;
    }
    if (Status e = a.decode_node(i, da); !e.ok()) return 1;
    if (Status e = b.decode_node(size_t(j), db); !e.ok()) return 1;
    differ[0] += da.heights != db.heights;
    differ[1] += da.normals_bc3 != db.normals_bc3;
    differ[2] += da.cones_bc3 != db.cones_bc3;
    differ[3] += da.splat != db.splat;
  }
  std::printf("%zu nodes; differing: heights %zu, normals %zu, cones %zu (splat %zu)\n", na.size(), differ[0],
              differ[1], differ[2], differ[3]);
  return differ[0] + differ[1] + differ[2] ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 4 && std::string(argv[1]) == "--same-geometry") return same_geometry(argv[2], argv[3]);
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s ARCHIVE...\n", argv[0]);
    return 2;
  }
  std::printf("%-36s %8s %8s %8s %8s %8s %8s  shares %% (id:share)\n", "archive", "isol%", "chg%", "isolF%",
              "chgF%", "lod%", "seamErr");
  int rc = 0;
  for (int a = 1; a < argc; ++a) {
    ArchiveReader reader;
    cook::bench::SplatMeasure m;
    Status s = reader.open(argv[a]);
    if (s.ok()) s = cook::bench::measure_splat(reader, m);
    if (!s.ok()) {
      std::fprintf(stderr, "%s: %s\n", argv[a], s.to_string().c_str());
      rc = 1;
      continue;
    }
    std::string name = argv[a];
    if (const size_t p = name.rfind('/'); p != std::string::npos) name = name.substr(p + 1);
    std::printf("%-36s %8.2f %8.2f %8.2f %8.2f %8.2f %8llu ", name.c_str(), m.isolated_pct(), m.changes_pct(),
                m.fine_isolated_pct(), m.fine_changes_pct(), m.lod_agree_pct(),
                static_cast<unsigned long long>(m.seam_mismatches));
    if (m.seam_mismatches) rc = 1;
    const auto& pal = reader.world().palette;
    for (int id = 0; id < 256; ++id)
      if (m.count[size_t(id)])
        std::printf(" %s:%.1f", id < int(pal.size()) ? pal[size_t(id)].name.c_str() : "?", m.share_pct(id));
    std::printf("\n");
  }
  return rc;
}
