// The manual page octshape(1) that the build writes from the --help text (octshape --man-page,
// installed as share/man/man1/octshape.1): every command's help as `--help` prints it, and
// every exit code of the footer.
#include <gtest/gtest.h>

#include <cctype>
#include <sstream>
#include <string>
#include <vector>

#include "test_paths.h"

namespace octshape::test {
namespace {

// roff's escapes undone for the characters the generator escapes.
std::string unroff(std::string s) {
    for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
             {"\\-", "-"}, {"\\e", "\\"}, {"\\&", ""}}) {
        for (auto at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) {
            s.replace(at, from.size(), to);
        }
    }
    return s;
}

// The command names listed under "Subcommands:" in a help text.
std::vector<std::string> subcommands(const std::string& help) {
    std::vector<std::string> names;
    std::istringstream in(help);
    std::string line;
    bool in_list = false;
    while (std::getline(in, line)) {
        if (line == "Subcommands:") {
            in_list = true;
        } else if (in_list && line.rfind("  ", 0) == 0) {
            names.push_back(line.substr(2, line.find(' ', 2) - 2));
        } else if (in_list) {
            in_list = false;
        }
    }
    return names;
}

TEST(ManPage, HoldsEveryCommandsHelpAndEveryExitCode) {
    const std::string page = slurp(OCTSHAPE_MAN_PAGE);
    ASSERT_FALSE(page.empty()) << "no manual page at " << OCTSHAPE_MAN_PAGE;
    EXPECT_EQ(page.rfind(".\\\"", 0), 0u);
    EXPECT_NE(page.find(".TH OCTSHAPE 1"), std::string::npos);
    const std::string text = unroff(page);

    const RunResult top = run_octshape("--help");
    ASSERT_EQ(top.exit_code, 0);
    std::vector<std::string> commands;
    for (const auto& c : subcommands(top.out)) {
        commands.push_back(c);
        const RunResult sub = run_octshape(c + " --help");
        for (const auto& s : subcommands(sub.out)) commands.push_back(c + " " + s);
    }
    ASSERT_GE(commands.size(), 18u);  // 15 commands, 3 of them under `phantom`
    for (const auto& c : commands) {
        SCOPED_TRACE(c);
        EXPECT_NE(page.find(".SS \"octshape " + c + "\""), std::string::npos);
        // Every line of `octshape C --help` but the usage line (it names the executable as
        // it was called) and the footer (the EXIT STATUS section, once).
        const RunResult help = run_octshape(c + " --help");
        ASSERT_EQ(help.exit_code, 0);
        std::istringstream in(help.out.substr(0, help.out.find("Exit codes:")));
        std::string line;
        while (std::getline(in, line)) {
            if (line.rfind("Usage:", 0) == 0 || line.empty()) continue;
            EXPECT_NE(text.find(line), std::string::npos) << "missing: " << line;
        }
    }
    // Every exit code of the footer, each an entry of EXIT STATUS.
    const auto exit_status = text.find(".SH \"EXIT STATUS\"");
    ASSERT_NE(exit_status, std::string::npos);
    std::istringstream footer(top.out.substr(top.out.find("Exit codes:")));
    std::string line;
    int codes = 0;
    while (std::getline(footer, line)) {
        // "  CODE  meaning" (read independently of the page's writer).
        if (line.rfind("  ", 0) != 0 || line.size() < 3 || !std::isdigit(static_cast<unsigned char>(line[2])))
            continue;
        const std::size_t end = line.find(' ', 2);
        if (end == std::string::npos) continue;
        const std::string code = line.substr(2, end - 2);
        const std::string meaning = line.substr(line.find_first_not_of(' ', end));
        ++codes;
        EXPECT_NE(text.find(".TP\n.B " + code + "\n" + meaning + "\n", exit_status),
                  std::string::npos)
            << "exit code " << code;
    }
    EXPECT_EQ(codes, 8);  // 0 1 64 65 66 69 70 73
}

}  // namespace
}  // namespace octshape::test
