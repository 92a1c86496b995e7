#include "test_paths.h"

#include <sys/wait.h>

#include <atomic>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

namespace octshape::test {

std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

void spit(const std::filesystem::path& p, const std::string& text) {
    std::ofstream out(p, std::ios::binary);
    out << text;
}

std::vector<std::string> split_csv_line(const std::string& line) {
    std::vector<std::string> out;
    std::string cur;
    bool quoted = false;
    for (const char c : line) {
        if (c == '"') {
            quoted = !quoted;
        } else if (c == ',' && !quoted) {
            out.push_back(cur);
            cur.clear();
        } else {
            cur += c;
        }
    }
    out.push_back(cur);
    return out;
}

std::vector<std::vector<std::string>> read_csv(const std::filesystem::path& p) {
    std::istringstream in(slurp(p));
    std::vector<std::vector<std::string>> rows;
    std::string line;
    while (std::getline(in, line)) rows.push_back(split_csv_line(line));
    return rows;
}

TempDir::TempDir() {
    static std::atomic<int> counter{0};
    std::random_device rd;
    const auto base = std::filesystem::temp_directory_path();
    for (int attempt = 0; attempt < 100; ++attempt) {
        auto candidate = base / ("octshape-test-" + std::to_string(rd()) + "-" +
                                 std::to_string(counter++));
        if (std::filesystem::create_directory(candidate)) {
            path_ = candidate;
            return;
        }
    }
    throw std::runtime_error("cannot create a temporary directory");
}

TempDir::~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
}

namespace {

RunResult run_through_shell(const std::string& prefix, const std::string& args, bool signals) {
    TempDir tmp;
    const auto out = tmp / "stdout";
    const auto err = tmp / "stderr";
    const std::string cmd = prefix + "'" + exe() + "' " + args + " >'" + out.string() + "' 2>'" +
                            err.string() + "' </dev/null";
    const int status = std::system(cmd.c_str());
    RunResult r;
    if (WIFEXITED(status)) {
        r.exit_code = WEXITSTATUS(status);
    } else {
        r.exit_code = signals ? 128 + WTERMSIG(status) : -1;
    }
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
}

}  // namespace

RunResult run_octshape(const std::string& args) { return run_through_shell("", args, false); }

std::string failure_kind(int exit_code) {
    if (exit_code == 137) return "hang";
    if (exit_code >= 128) return "crash";
    if (exit_code == 70) return "internal error";
    return "";
}

RunResult run_octshape_limited(const std::string& args, int seconds) {
    return run_through_shell("timeout -s KILL " + std::to_string(seconds) + " ", args, true);
}

}  // namespace octshape::test
