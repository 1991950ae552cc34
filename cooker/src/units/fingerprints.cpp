#include "units/fingerprints.h"

#include <sys/stat.h>

#include <fstream>
#include <vector>
#include <fmt/format.h>

#include "terrain/detail/bytes.h"

namespace terrain::cook {

uint64_t fnv1a(std::string_view s, uint64_t h) { return detail::fnv1a(s, h); }
std::string hex64(uint64_t v) { return fmt::format("{:016x}", v); }

bool file_fnv1a(const std::string& path, uint64_t& h) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  h = fnv1a({});
  std::vector<char> chunk(1 << 16);
  while (f) {
    f.read(chunk.data(), std::streamsize(chunk.size()));
    h = fnv1a(std::string_view(chunk.data(), size_t(f.gcount())), h);
  }
  return !f.bad();
}


bool stat_file(InputFile& f) {
  struct stat st {};
  if (::stat(f.path.c_str(), &st) != 0) return false;
  f.size = uint64_t(st.st_size);
  f.mtime_ns = int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
  f.inode = uint64_t(st.st_ino);
  f.ctime_ns = int64_t(st.st_ctim.tv_sec) * 1000000000 + st.st_ctim.tv_nsec;
  return true;
}
std::string file_fingerprint(const InputFile& f) {
  return hex64(fnv1a(fmt::format("{}\n{}\n{}\n{}\n{}", f.path, f.size, f.mtime_ns, f.inode, f.ctime_ns)));
}
std::string file_change(const InputFile& was, const InputFile& now) {
  std::string what;
  auto differ = [&](const char* name, auto a, auto b) {
    if (a != b) what += fmt::format("{}{} {} -> {}", what.empty() ? "" : ", ", name, a, b);
  };
  differ("size", was.size, now.size);
  differ("mtime", was.mtime_ns, now.mtime_ns);
  differ("inode", was.inode, now.inode);
  differ("ctime", was.ctime_ns, now.ctime_ns);
  if (was.ctime_ns != now.ctime_ns && was.size == now.size && was.mtime_ns == now.mtime_ns)
    what += ": rewritten or replaced keeping size and mtime (cp -p, rsync -t, tar), or its metadata changed";
  return what.empty() ? "its fingerprint" : what;
}

}  // namespace terrain::cook
