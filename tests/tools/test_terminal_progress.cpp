// The tools' progress bar (tools/common/terminal_progress.h): silent where stderr is not a terminal.
#include <gtest/gtest.h>

#include "terminal_progress.h"

namespace terrain {
namespace {

TEST(Progress, TerminalBarIsSilentWhenStderrIsNotATerminal) {
  if (stderr_is_terminal()) GTEST_SKIP() << "stderr is a terminal here";
  TerminalProgress bar(true);
  EXPECT_FALSE(bar.active());
  EXPECT_TRUE(bar.update(0.5, "stage"));
  EXPECT_TRUE(bar.callback()(1.0, "stage"));
  TerminalProgress off(false);
  EXPECT_FALSE(off.active());
}

}  // namespace
}  // namespace terrain
