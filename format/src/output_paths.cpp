#include "terrain/output_paths.h"

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

namespace terrain {
namespace {

struct Identity {
  bool exists = false;
  dev_t dev = 0;
  ino_t ino = 0;
  mode_t mode = 0;
  std::string resolved;  // realpath of the directory + file name (outputs that do not exist yet)
};

std::string directory_of(const std::string& path) {
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return dir.empty() ? "." : dir;
}

// `resolve`: also the resolved name (needed only to compare files that do not exist yet).
Identity identify(const std::string& path, bool resolve = true) {
  Identity id;
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    id.exists = true;
    id.dev = st.st_dev;
    id.ino = st.st_ino;
    id.mode = st.st_mode;
  }
  char buf[PATH_MAX];
  if (resolve && ::realpath(directory_of(path).c_str(), buf))
    id.resolved = std::string(buf) + "/" + std::filesystem::path(path).filename().string();
  return id;
}

bool same_file(const Identity& a, const Identity& b) {
  if (a.exists && b.exists) return a.dev == b.dev && a.ino == b.ino;
  return !a.exists && !b.exists && !a.resolved.empty() && a.resolved == b.resolved;
}

std::string named(const NamedPath& p) { return p.flag + " " + p.path; }

}  // namespace

const char* file_kind_name(unsigned m) {
  if (S_ISREG(m)) return "regular file";
  if (S_ISDIR(m)) return "directory";
  if (S_ISFIFO(m)) return "FIFO";
  if (S_ISCHR(m)) return "character device";
  if (S_ISBLK(m)) return "block device";
  if (S_ISSOCK(m)) return "socket";
  if (S_ISLNK(m)) return "symbolic link";
  return "special file";
}

Status check_input_file(const std::string& what, const std::string& path) {
  struct stat st {};
  const std::string name = what.empty() ? path : what + " " + path;
  if (::stat(path.c_str(), &st) != 0)
    return Status::failure(Error::io_open, name + (errno == ENOENT ? ": no such file" : ": cannot stat: " + std::string(std::strerror(errno))));
  if (!S_ISREG(st.st_mode))
    return Status::failure(Error::io_open, name + ": not a regular file (" + file_kind_name(st.st_mode) + ")");
  return Status::success();
}

Status check_output_paths(const std::vector<NamedPath>& inputs, const std::vector<NamedPath>& outputs) {
  // The inputs are identified (one stat each, no realpath: an input that exists is compared by
  // device and inode) only once an output exists: a merge of a national mosaic lists 10^5..10^6.
  std::vector<Identity> in_ids, out_ids;
  for (size_t i = 0; i < outputs.size(); ++i) {
    const NamedPath& out = outputs[i];
    if (out.path.empty()) return Status::failure(Error::invalid_argument, out.flag + ": empty path");
    const Identity id = identify(out.path);
    if (id.exists && !S_ISREG(id.mode))
      return Status::failure(Error::invalid_argument, named(out) + ": is a " + std::string(file_kind_name(id.mode)) +
                                                          ", not a regular file; refusing to replace it");
    if (id.exists && in_ids.empty())
      for (const NamedPath& p : inputs) in_ids.push_back(identify(p.path, /*resolve=*/false));
    for (size_t k = 0; k < in_ids.size(); ++k)
      if (in_ids[k].exists && id.exists && same_file(id, in_ids[k]))
        return Status::failure(Error::invalid_argument,
                               named(out) + ": is the same file as " + named(inputs[k]) + "; refusing to overwrite an input");
    for (size_t k = 0; k < i; ++k)
      if (same_file(id, out_ids[k]))
        return Status::failure(Error::invalid_argument, named(out) + ": is the same file as " + named(outputs[k]));
    out_ids.push_back(id);
    const std::string dir = directory_of(out.path);
    struct stat ds {};
    if (::stat(dir.c_str(), &ds) != 0 || !S_ISDIR(ds.st_mode))
      return Status::failure(Error::invalid_argument, named(out) + ": directory " + dir + " does not exist");
    if (::access(dir.c_str(), W_OK | X_OK) != 0)
      return Status::failure(Error::io_write, named(out) + ": directory " + dir + " is not writable: " + std::strerror(errno));
  }
  return Status::success();
}

namespace {

std::string host_name() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0 || host[0] == 0) return "host";
  return host;
}

}  // namespace

std::string staging_path(const std::string& target, const char* kind) {
  return target + "." + kind + "-" + host_name() + "-" + std::to_string(::getpid());
}

namespace {

// The pid of a staged name's writer when `name` is `<base>.<kind>-<host>-<pid>[.<ext>]` with this
// host, scanning from `from`; 0 otherwise. The pid ends the name or an extension follows it
// ("...-<pid>.payloads"); anything else is another host's name that merely starts with ours
// ("<host>-5-<pid>").
pid_t staged_pid(const std::string& name, size_t at, const std::string& host, const char* kind) {
  const std::string marker = std::string(".") + kind + "-" + host + "-";
  if (name.compare(at, marker.size(), marker) != 0) return 0;
  const size_t digits = at + marker.size();
  size_t end_digits = digits;
  while (end_digits < name.size() && name[end_digits] >= '0' && name[end_digits] <= '9') ++end_digits;
  if (end_digits == digits || end_digits - digits > 9) return 0;
  if (end_digits < name.size() && name[end_digits] != '.') return 0;
  return pid_t(std::stol(name.substr(digits, end_digits - digits)));
}

bool writer_is_gone(pid_t pid) { return pid > 0 && pid != ::getpid() && ::kill(pid, 0) != 0 && errno == ESRCH; }

template <class Match>
size_t remove_in(const std::string& dir, Match&& stale) {
  std::error_code ec;
  size_t removed = 0;
  std::vector<std::filesystem::path> doomed;  // collected first: no removal under the iterator
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (stale(it->path().filename().string())) doomed.push_back(it->path());
  for (const auto& p : doomed) {
    std::error_code rm;
    if (std::filesystem::remove(p, rm)) ++removed;
  }
  return removed;
}

}  // namespace

size_t remove_stale_staging(const std::string& target) {
  const std::string base = std::filesystem::path(target).filename().string(), host = host_name();
  return remove_in(directory_of(target), [&](const std::string& name) {
    if (name.size() <= base.size() || name.compare(0, base.size(), base) != 0) return false;
    for (const char* kind : {"tmp", "spool"})
      if (writer_is_gone(staged_pid(name, base.size(), host, kind))) return true;
    return false;
  });
}

size_t remove_stale_staging_in(const std::string& dir) {
  const std::string host = host_name();
  return remove_in(dir, [&](const std::string& name) {
    for (size_t at = name.find('.'); at != std::string::npos; at = name.find('.', at + 1))
      for (const char* kind : {"tmp", "spool"})
        if (writer_is_gone(staged_pid(name, at, host, kind))) return true;
    return false;
  });
}

}  // namespace terrain
