// Progress reporting of long calls (cook(), the engine exports): a callback that gets a fraction in
// [0, 1] and the current stage name and returns false to cancel. The tools' terminal bar that such
// a callback may drive lives with the tools (tools/common/terminal_progress.h).
#pragma once
#include <functional>
#include <string_view>

namespace terrain {

// Return false to ask the caller to stop (it then returns Error::cancelled).
using ProgressFn = std::function<bool(double fraction, std::string_view stage)>;

// Maps a sub-step's [0, 1] into [lo, hi] of `parent` (parent may be empty: the result then
// always returns true).
ProgressFn scaled_progress(ProgressFn parent, double lo, double hi);

}  // namespace terrain
