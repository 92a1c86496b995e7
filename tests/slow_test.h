#pragma once
// SLOW_TEST(Suite, Name) is TEST(Suite, Name) for a test that takes seconds (minutes under the
// sanitizers). tests/CMakeLists.txt finds every SLOW_TEST( at the start of a line in the test
// sources and gives that test the ctest label "slow" (`ctest -LE slow` skips them; CI runs
// them all). The mark sits on the test itself, so renaming a test keeps its label.

#include <gtest/gtest.h>

#define SLOW_TEST(suite, name) TEST(suite, name)

// EXTERNAL_TEST(Suite, Name) is TEST(Suite, Name) for a test that drives a program we do not
// build (headless Chromium): label "external", run in Release only (the sanitizer preset
// excludes the label: the sanitizers see nothing of the other program).
#define EXTERNAL_TEST(suite, name) TEST(suite, name)
