// terrain-cook: picks the program that serves the command and execs it with the same arguments
// (same process, its exit code is the command's). `merge` goes to terrain-cook-merge, linked
// without GDAL and PROJ: mapping their shared libraries costs ~0.08 s of CPU before main, more
// than the merge of an 8 km lidar square. Everything else goes to the full cooker, terrain-cook-full.
// Both sit beside this program (build tree) or in TERRAIN_COOK_LIBEXEC relative to it (installed).
// Plain libc only, so that this step itself costs about a millisecond.
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>

#ifndef TERRAIN_COOK_LIBEXEC
#define TERRAIN_COOK_LIBEXEC "."
#endif

int main(int argc, char** argv) {
  const char* program = argc > 1 && std::strcmp(argv[1], "merge") == 0 ? "terrain-cook-merge" : "terrain-cook-full";
  char self[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof self - 1);
  if (n <= 0) {
    std::fprintf(stderr, "terrain-cook: cannot find its own folder (/proc/self/exe): %s\n", std::strerror(errno));
    return 1;
  }
  self[n] = 0;
  if (char* slash = std::strrchr(self, '/')) *slash = 0;
  char tried[2 * PATH_MAX + 256] = "";
  const char* const subdirs[] = {"", "/" TERRAIN_COOK_LIBEXEC};
  for (const char* sub : subdirs) {
    char path[PATH_MAX];
    if (std::snprintf(path, sizeof path, "%s%s/%s", self, sub, program) >= int(sizeof path)) continue;
    ::execv(path, argv);
    const size_t used = std::strlen(tried);
    std::snprintf(tried + used, sizeof tried - used, "; %s: %s", path, std::strerror(errno));
  }
  std::fprintf(stderr, "terrain-cook: cannot start %s%s\n", program, tried);
  return 1;
}
