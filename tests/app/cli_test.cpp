// The executable's own contract: version, help with exit codes, usage errors.

#include <gtest/gtest.h>

#include "octshape/version.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

TEST(Cli, VersionPrintsTheVersion) {
    const RunResult r = run_octshape("--version");
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_NE(r.out.find(kVersion), std::string::npos) << r.out;
}

TEST(Cli, HelpListsExitCodes) {
    const RunResult r = run_octshape("--help");
    EXPECT_EQ(r.exit_code, 0);
    for (const char* code : {"64", "65", "66", "69", "70", "73"}) {
        EXPECT_NE(r.out.find(std::string("  ") + code + "  "), std::string::npos) << code;
    }
}

TEST(Cli, NoCommandIsAUsageError) {
    const RunResult r = run_octshape("");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_GE(r.exit_code, 100);  // CLI11 parse errors are 100..127
}

TEST(Cli, UnknownCommandIsAUsageError) {
    const RunResult r = run_octshape("frobnicate");
    EXPECT_GE(r.exit_code, 100);
}

}  // namespace
}  // namespace octshape::test
