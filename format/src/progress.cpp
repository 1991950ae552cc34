#include "terrain/progress.h"

#include <algorithm>

namespace terrain {

ProgressFn scaled_progress(ProgressFn parent, double lo, double hi) {
  return [parent = std::move(parent), lo, hi](double fraction, std::string_view stage) {
    if (!parent) return true;
    return parent(lo + (hi - lo) * std::clamp(fraction, 0.0, 1.0), stage);
  };
}

}  // namespace terrain
