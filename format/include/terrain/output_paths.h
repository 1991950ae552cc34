// The command-line tools' one rule for the files they read and write (terrain-cook, terrain-inspect
// --export, terrain-view --out/--stats): an input must be a regular file; an output may only name
// a regular file or nothing, never an input, another output, a device, a FIFO, a socket or a
// directory, and its directory must exist and be writable. Checked before any work, so a refused
// command leaves every file as it was (as root, a rename over /dev/null replaces the device).
#pragma once
#include <string>
#include <vector>

#include "terrain/status.h"

namespace terrain {

// "regular file", "directory", "FIFO", "character device", "block device", "socket", "symbolic link".
const char* file_kind_name(unsigned st_mode);

// io_open "<what> <path>: no such file" or "...: not a regular file (FIFO)" unless `path` is a
// regular file (symbolic links followed). Never opens the file, so a FIFO cannot block.
Status check_input_file(const std::string& what, const std::string& path);

struct NamedPath {
  std::string flag;  // how the user gave it: "-o", "--report", "input"
  std::string path;
};

// invalid_argument when an output names an input or another output (same device and inode, or
// the same resolved path for outputs that do not exist yet), an existing non-regular file, or a
// directory that does not exist; io_write when its directory is not writable. Inputs that do not
// exist are skipped (their reader names them).
Status check_output_paths(const std::vector<NamedPath>& inputs, const std::vector<NamedPath>& outputs);

// Staged writes: a file written atomically (an archive, a plan, a work unit) or spooled on the way
// to one is first `<target>.<kind>-<host>-<pid>` (kind "tmp" or "spool"), renamed over or removed
// at the end. Host and pid name the writer, so writers on machines sharing a directory never meet.
std::string staging_path(const std::string& target, const char* kind = "tmp");

// Removes the staged files of `target` (any kind, any extension after the pid) that a process of
// this host left and that no longer runs: what a SIGKILLed cook leaves, cleared by the next write of
// the same target. Files of other hosts and of live processes (or a reused pid) are left alone.
// Returns how many were removed.
size_t remove_stale_staging(const std::string& target);

// The same for every target in `dir`: one listing for a directory of many staged outputs (a work
// dir's units), where one remove_stale_staging per target would list it once per target.
size_t remove_stale_staging_in(const std::string& dir);

}  // namespace terrain
