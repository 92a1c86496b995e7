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

// ACCURACY_TEST(Suite, Name) is a SLOW_TEST (label "slow") that is one more member of a family
// of accuracy tests (another shape, eye or line count through the same code), labelled
// "accuracy" besides: run in Release only. Under the sanitizers each family keeps a member
// that runs the same code paths (the comment beside each ACCURACY_TEST names it): the
// sanitizers look for memory and undefined-behaviour errors on a path, and a second phantom
// through the same path finds none the first does not, at 5-10x the Release time.
#define ACCURACY_TEST(suite, name) TEST(suite, name)
