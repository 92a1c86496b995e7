// The executable's own contract: version, help with exit codes, usage errors.

#include <gtest/gtest.h>

#include <string>
#include <vector>

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
    EXPECT_EQ(r.exit_code, 64);
}

TEST(Cli, UnknownCommandIsAUsageError) {
    const RunResult r = run_octshape("frobnicate");
    EXPECT_EQ(r.exit_code, 64);
}

TEST(Cli, EveryBadOptionValueIsTheSameUsageError) {
    // One rule whoever finds the mistake: CLI11's validators (a value outside a set: its own
    // code 105; a number that does not parse: 106; an unknown option: 109) and octshape's own
    // checks (UsageError) all exit 64 with a message naming the option.
    const std::string scan = std::string(OCTSHAPE_SOURCE_DIR) + "/sample_scans/macula_line_od.vol";
    for (const std::string& args : std::vector<std::string>{
             "denoise in.ply -o out.ply --method nonsense", "denoise in.ply -o out.ply -p abc",
             "denoise in.ply -o out.ply --no-such-option", "macula " + scan + " --rim nowhere",
             "macula " + scan + " --half-lines 5", "cohort " + scan + " -o out --jobs 0",
             "cohort " + scan + " -o out --jobs -2", "macula " + scan + " --bm-surface rpe",
             "macula " + scan + " --etdrs-layers ILM"}) {
        const RunResult r = run_octshape(args);
        EXPECT_EQ(r.exit_code, 64) << args << "\n" << r.err;
        EXPECT_FALSE(r.err.empty()) << args;
    }
}

TEST(Cli, QuietAndVerboseWorkAfterTheSubcommandToo) {
    // `octshape macula FILE -q` as well as `octshape -q macula FILE`: the info lines go, the
    // result stays; -v after the subcommand is accepted (it was an unknown option, exit 64).
    const std::string scan = std::string(OCTSHAPE_SOURCE_DIR) + "/sample_scans/macula_line_od.vol";
    TempDir dir;
    const std::string out = " -o " + (dir / "eye.json").string();
    const RunResult normal = run_octshape("macula " + scan + out);
    const RunResult before = run_octshape("-q macula " + scan + out);
    const RunResult after = run_octshape("macula " + scan + out + " -q");
    const RunResult verbose = run_octshape("macula " + scan + out + " -vv");
    for (const RunResult* r : {&normal, &before, &after, &verbose}) EXPECT_EQ(r->exit_code, 0) << r->err;
    EXPECT_NE(normal.err.find("info:"), std::string::npos) << normal.err;
    EXPECT_EQ(before.err.find("info:"), std::string::npos) << before.err;
    EXPECT_EQ(after.err.find("info:"), std::string::npos) << after.err;
    EXPECT_NE(verbose.err.find("info:"), std::string::npos) << verbose.err;
}

}  // namespace
}  // namespace octshape::test
