// Window mode: GLFW window (works under Xvfb), swapchain, fly camera. The terrain renders into the
// session's offscreen target, which is blitted to the swapchain image.
#pragma once
#include "app.h"

namespace terrain::view {

int run_window(const ViewerOptions& options);

}  // namespace terrain::view
