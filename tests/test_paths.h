#pragma once
// Paths the tests need, fixed at configure time, and small helpers shared by test files.

#include <filesystem>
#include <initializer_list>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace octshape::test {

// The octshape executable under test.
inline std::string exe() { return OCTSHAPE_EXE; }
inline std::filesystem::path source_dir() { return OCTSHAPE_SOURCE_DIR; }
// The folder of third-party test files (real scans, hostile files, meshes; tests/README.md):
// $OCTSHAPE_SHARED_DIR when it is set and not empty, else the folder fixed at configure time
// (the CMake cache variable of the same name, ../shared beside the clone by default).
[[nodiscard]] std::filesystem::path shared_dir();
inline std::filesystem::path realdata(const std::string& name) {
    return shared_dir() / "realdata" / name;
}
// "" when every one of `relative` (paths under shared_dir(), e.g. "realdata/x.vol") exists;
// otherwise one line naming the first one absent and its public source (tests/README.md).
[[nodiscard]] std::string shared_absent(std::initializer_list<const char*> relative);

}  // namespace octshape::test

// At the start of a test that reads third-party files: skips the test (one line naming the
// file and where it comes from) when one is absent, so that a plain clone passes and ctest's
// summary counts what it skipped.
#define SKIP_UNLESS_SHARED(...)                                                          \
    do {                                                                                 \
        const std::string octshape_absent_ = ::octshape::test::shared_absent({__VA_ARGS__}); \
        if (!octshape_absent_.empty()) GTEST_SKIP() << octshape_absent_;                 \
    } while (0)

namespace octshape::test {

// A fresh empty directory under the system temp dir, removed by the destructor.
class TempDir {
public:
    TempDir();
    ~TempDir();
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    [[nodiscard]] const std::filesystem::path& path() const { return path_; }
    [[nodiscard]] std::filesystem::path operator/(const std::string& name) const {
        return path_ / name;
    }

private:
    std::filesystem::path path_;
};

// The whole content of a file ("" when it cannot be read: the caller's assertions then fail).
[[nodiscard]] std::string slurp(const std::filesystem::path& p);
// Writes `text` to a file (replacing it).
void spit(const std::filesystem::path& p, const std::string& text);
// The fields of one CSV line (RFC 4180 quoting: quoted commas stay inside a field; the quotes
// themselves are dropped, which is all the tests need of the tables they read).
[[nodiscard]] std::vector<std::string> split_csv_line(const std::string& line);
// Every line of a CSV file, split into fields.
[[nodiscard]] std::vector<std::vector<std::string>> read_csv(const std::filesystem::path& p);

// Result of running a command line through the shell.
struct RunResult {
    int exit_code = -1;
    std::string out;  // stdout
    std::string err;  // stderr
};
// Runs `octshape ARGS` (args are passed through the shell verbatim: quote them yourself).
RunResult run_octshape(const std::string& args);
// The same, killed (SIGKILL) after `seconds`; a run ended by a signal has exit code 128 + the
// signal (a run killed at the limit: 137), as a shell reports it.
RunResult run_octshape_limited(const std::string& args, int seconds);
// A campaign's verdict on an exit code that is never acceptable: "hang" (killed at the limit),
// "crash" (another signal), "internal error" (70); "" for any other code.
[[nodiscard]] std::string failure_kind(int exit_code);

}  // namespace octshape::test
