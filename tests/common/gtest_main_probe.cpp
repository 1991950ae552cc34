// Cases for tests/gtest_main_exit_codes.cmake: the exit code of common/gtest_main.cpp for a run
// that passes, one that also skips, and one that also fails.
#include <gtest/gtest.h>

TEST(Probe, Passes) { EXPECT_EQ(1 + 1, 2); }
TEST(Probe, Skips) { GTEST_SKIP() << "skipped on purpose"; }
TEST(Probe, Fails) { FAIL() << "fails on purpose"; }
