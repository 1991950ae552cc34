// terrain-splat-measure ARCHIVE...: splat coherence per archive (issue 18): isolated samples and
// neighbour id changes (all levels, and the finest level), agreement of each node with its
// children, and the share of every palette material.
#include <cstdio>
#include <string>

#include "splat_measure.h"

using namespace terrain;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s ARCHIVE...\n", argv[0]);
    return 2;
  }
  std::printf("%-36s %8s %8s %8s %8s %8s  shares %% (id:share)\n", "archive", "isol%", "chg%", "isolF%",
              "chgF%", "lod%");
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
    std::printf("%-36s %8.2f %8.2f %8.2f %8.2f %8.2f ", name.c_str(), m.isolated_pct(), m.changes_pct(),
                m.fine_isolated_pct(), m.fine_changes_pct(), m.lod_agree_pct());
    const auto& pal = reader.world().palette;
    for (int id = 0; id < 256; ++id)
      if (m.count[size_t(id)])
        std::printf(" %s:%.1f", id < int(pal.size()) ? pal[size_t(id)].name.c_str() : "?", m.share_pct(id));
    std::printf("\n");
  }
  return rc;
}
