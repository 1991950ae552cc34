// Modules the command-line tools load on first use instead of linking: a library such as
// OpenImageIO maps some 150 shared libraries into a process, whose start-up a tool would pay on
// every run even when it never reads or writes an image (cooker/README.md, "Figures behind the code"). A module sits next to the
// executable in the build tree and in <libdir>/terrain once installed.
#pragma once
#include <string>

namespace terrain {

// dlopen()s `file_name` (RTLD_NOW | RTLD_LOCAL) from the executable's folder, else from the
// installed module folder; null with what was tried in `error`.
void* open_tool_module(const char* file_name, std::string& error);

}  // namespace terrain
