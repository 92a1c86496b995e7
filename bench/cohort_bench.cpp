// Cohort throughput (issue 6 item 7): N full-size macula exports (hard links to a handful of
// distinct 61 x 768 x 496 phantoms with pixels, ~96 MB each, so the page cache holds them all)
// analysed by `octshape cohort --jobs J`, against the time that merely reading and hashing the
// same bytes takes with J threads (the I/O limit: every eye's SHA-256 must be computed), and the
// resume cost (re-run on the finished cohort). Goals: cohort <= 1.3 x read+hash, resume <= 2 s.
// Usage: cohort_bench [N=1000] [DISTINCT=4] [JOBS=2]

#include <sys/resource.h>
#include <sys/wait.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "octshape/io/sha256.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Concatenation by append (GCC 12 -O3 emits a false -Wrestrict on chained operator+).
template <class... Parts>
std::string cat(const Parts&... parts) {
    std::string s;
    (s.append(std::string_view(parts)), ...);
    return s;
}

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

// CPU seconds (user + system) of this process or of its waited-for children.
double cpu_seconds(int who) {
    rusage u{};
    ::getrusage(who, &u);
    return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

int sh(const std::string& cmd) {
    const int s = std::system(cmd.c_str());
    return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
}

// Reads and hashes every file with `jobs` threads (what the cohort cannot avoid doing).
double read_and_hash(const std::vector<std::string>& files, int jobs) {
    std::atomic<std::size_t> next{0};
    const auto t0 = Clock::now();
    std::vector<std::thread> pool;
    for (int j = 0; j < jobs; ++j) {
        pool.emplace_back([&] {
            for (std::size_t i = next++; i < files.size(); i = next++) {
                if (octshape::io::sha256_file(files[i]).empty()) std::abort();
            }
        });
    }
    for (auto& t : pool) t.join();
    return seconds_since(t0);
}

}  // namespace

int main(int argc, char** argv) {
    const int n = argc > 1 ? std::atoi(argv[1]) : 1000;
    const int distinct = argc > 2 ? std::atoi(argv[2]) : 4;
    const int jobs = argc > 3 ? std::atoi(argv[3]) : 2;
    const std::string exe = OCTSHAPE_EXE;
    const fs::path work =
        fs::temp_directory_path() / cat("octshape-cohort-bench-", std::to_string(::getpid()));
    fs::create_directories(work / "src");
    std::printf("cohort_bench: %d exports (hard links to %d distinct full-size phantoms), "
                "--jobs %d, in %s\n", n, distinct, jobs, work.c_str());

    const char* families[] = {"bezier", "scheibe"};
    const char* eyes[] = {"OD", "OS"};
    for (int d = 0; d < distinct; ++d) {
        const fs::path p = work / "src" / cat("p", std::to_string(d), ".vol");
        const std::string cmd = cat("'", exe, "' -q phantom macula --family ", families[d % 2],
                                    " --eye ", eyes[(d / 2) % 2], " --noise-um 2 --seed ",
                                    std::to_string(d + 1), " -o '", p.string(), "'");
        if (sh(cmd) != 0) {
            std::fprintf(stderr, "phantom failed: %s\n", cmd.c_str());
            return 1;
        }
    }
    std::vector<std::string> files;
    for (int i = 0; i < n; ++i) {
        const fs::path dir = work / "in" / cat("site", std::to_string(i % 10));
        fs::create_directories(dir);
        const fs::path link = dir / cat("eye", std::to_string(10000 + i), ".vol");
        fs::create_hard_link(work / "src" / cat("p", std::to_string(i % distinct), ".vol"), link);
        files.push_back(link.string());
    }
    const auto bytes = static_cast<double>(fs::file_size(files[0]));
    fs::path key = work / "key";
    std::ofstream(key) << "bench\n";

    std::vector<std::string> sources;  // warm the page cache: the few distinct inodes
    for (int d = 0; d < distinct; ++d) {
        sources.push_back((work / "src" / cat("p", std::to_string(d), ".vol")).string());
    }
    (void)read_and_hash(sources, jobs);
    const double c_hash0 = cpu_seconds(RUSAGE_SELF);
    const double t_hash = read_and_hash(files, jobs);
    const double c_hash = cpu_seconds(RUSAGE_SELF) - c_hash0;

    const auto t_start = Clock::now();
    (void)sh(cat("'", exe, "' --version >/dev/null"));
    const double t_exec = seconds_since(t_start);

    const std::string cohort =
        cat("'", exe, "' -q cohort '", (work / "in").string(), "' -o '", (work / "out").string(),
            "' --jobs ", std::to_string(jobs), " --subject-key-file '", key.string(), "'");
    double c0 = cpu_seconds(RUSAGE_CHILDREN);
    auto t0 = Clock::now();
    const int rc = sh(cohort);
    const double t_cohort = seconds_since(t0);
    const double c_cohort = cpu_seconds(RUSAGE_CHILDREN) - c0;
    c0 = cpu_seconds(RUSAGE_CHILDREN);
    t0 = Clock::now();
    const int rc2 = sh(cohort);
    const double t_resume = seconds_since(t0);
    const double c_resume = cpu_seconds(RUSAGE_CHILDREN) - c0;
    if (rc != 0 || rc2 != 0) std::fprintf(stderr, "cohort exit codes %d, %d\n", rc, rc2);

    std::printf("\n%-36s %6s %9s %10s %9s %9s %9s\n", "case", "eyes", "wall_s", "eyes_per_s",
                "ratio", "cpu_s", "cpu_ratio");
    std::printf("%-36s %6d %9.2f %10.1f %9.2f %9.2f %9.2f\n", "read+hash (SHA-256), reference", n,
                t_hash, n / t_hash, 1.0, c_hash, 1.0);
    std::printf("%-36s %6d %9.2f %10.1f %9.2f %9.2f %9.2f\n", "octshape cohort (fresh)", n,
                t_cohort, n / t_cohort, t_cohort / t_hash, c_cohort, c_cohort / c_hash);
    std::printf("%-36s %6d %9.2f %10.1f %9s %9.2f %9s\n", "octshape cohort (resume, finished)",
                n, t_resume, n / t_resume, "-", c_resume, "-");
    std::printf("%-36s %6s %9.3f %10s %9s %9s %9s\n", "process start (octshape --version)", "-",
                t_exec, "-", "-", "-", "-");
    std::printf("\ncpu_s: user+system CPU seconds (independent of other load on the machine). "
                "file size %.1f MB; read+hash %.2f GB/s on %d threads.\nGoals: cohort <= 1.3 x "
                "read+hash wall time (%s), resume <= 2 s (%s)\n",
                bytes / 1e6, n * bytes / t_hash / 1e9, jobs,
                t_cohort <= 1.3 * t_hash ? "met" : "NOT met", t_resume <= 2.0 ? "met" : "NOT met");
    std::error_code ec;
    fs::remove_all(work, ec);
    return 0;
}
