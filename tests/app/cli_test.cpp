// The executable's own contract: version, help with exit codes, usage errors.

#include <gtest/gtest.h>

#include <algorithm>

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
    // The revision once (it was printed twice: `git describe` without a tag is the revision).
    const auto at = r.out.find("(revision ");
    ASSERT_NE(at, std::string::npos) << r.out;
    const std::string rev = r.out.substr(at + 10, r.out.find_first_of(",;)", at) - at - 10);
    ASSERT_FALSE(rev.empty()) << r.out;
    EXPECT_EQ(r.out.find(rev, at + 10 + rev.size()), std::string::npos) << r.out;
}

TEST(Cli, HelpShowsChoicesAndNoInternalDefaultsOfFlags) {
    // `--no-type-check{false}` (CLI11's default of a negated flag) is gone; --type lists its
    // choices.
    const RunResult macula = run_octshape("macula --help");
    EXPECT_EQ(macula.out.find("{false}"), std::string::npos) << macula.out;
    EXPECT_NE(macula.out.find("--no-type-check"), std::string::npos) << macula.out;
    for (const char* c : {"cohort", "cohort-eye", "cohort-tables"}) {
        const RunResult r = run_octshape(std::string(c) + " --help");
        EXPECT_NE(r.out.find("--type TEXT:{auto,macula,onh}=auto"), std::string::npos) << r.out;
        EXPECT_EQ(r.out.find("{false}"), std::string::npos) << r.out;
    }
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

TEST(Cli, EveryCommandLineMistakeIsOneLineWithDidYouMean) {
    // CLI11's texts ("The following arguments were not expected: qc --qc-dir", "A subcommand
    // is required", each with a second line "Run with --help ...") become one line
    // `octshape: error: ...`, exit 64, with the nearest command or option for a near miss.
    const std::string scan = std::string(OCTSHAPE_SOURCE_DIR) + "/sample_scans/macula_line_od.vol";
    const std::vector<std::pair<std::string, std::string>> cases{
        {"maculla", "unknown command 'maculla' (did you mean macula?)"},
        {"phantom macul", "phantom: unknown command 'macul' (did you mean macula?)"},
        {"macula " + scan + " --qc-dir qc", "macula: unknown option --qc-dir (did you mean --qc?)"},
        {"cohort " + scan + " -o o --typ onh", "cohort: unknown option --typ (did you mean --type?)"},
        {"macula --bogus", "macula: unknown option --bogus (octshape macula --help)"},
        {"frobnicate", "unknown command 'frobnicate' (octshape --help)"},
        {"", "a command is required: denoise, "},
        {"macula", "macula: file is required"},
        {"macula " + scan + " extra", "macula: unexpected argument 'extra'"},
        {"cohort " + scan + " -o o --jobs 0", "cohort: --jobs: must be a count of 1 or more"},
        {"phantom onh --eye XX", "phantom onh: --eye: XX not in {OD,OS}"}};
    for (const auto& [args, want] : cases) {
        const RunResult r = run_octshape(args);
        EXPECT_EQ(r.exit_code, 64) << args;
        EXPECT_EQ(r.err.rfind("octshape: error: ", 0), 0U) << args << ": " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << ": " << r.err;
        EXPECT_NE(r.err.find(want), std::string::npos) << args << ": " << r.err;
    }
    // Far from every name: no guess.
    EXPECT_EQ(run_octshape("frobnicate").err.find("did you mean"), std::string::npos);
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
