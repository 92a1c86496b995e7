#include "test_paths.h"

#include <sys/wait.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

namespace octshape::test {

std::filesystem::path shared_dir() {
    const char* env = std::getenv("OCTSHAPE_SHARED_DIR");
    if (env != nullptr && *env != '\0') return env;
    return OCTSHAPE_SHARED_DIR;
}

namespace {

// Where each third-party file comes from (the shared folder's READMEs; tests/README.md).
struct Source {
    const char* prefix;  // a path under shared_dir(), or the folder that holds it
    const char* origin;
};
constexpr std::array kSources{
    Source{"realdata/fovea_line_716_0.vol",
           "halirutan/spectralis-raw-data test-data/Willis_B_716_0.vol, MIT"},
    Source{"realdata/onh_circle_716_2.vol",
           "halirutan/spectralis-raw-data test-data/Willis_B_716_2.vol, MIT"},
    Source{"realdata/onh_circle_716_4.vol",
           "halirutan/spectralis-raw-data test-data/Willis_B_716_4.vol, MIT"},
    Source{"realdata/onh_circle_valid.vol", "halirutan/HeyexImport Tests/valid.vol, MIT"},
    Source{"realdata/not_spectralis_eyepy_written.vol",
           "MedVisBonn/eyepy tests/data/filetypes/heyex_vol/test_volume.vol, MIT"},
    Source{"realdata/T566581_Surfaces_Iowa.xml",
           "barefootbiology/heyexr inst/extdata/TEST_T_566581_Surfaces_Iowa.xml, MIT"},
    Source{"realdata/heyex_xml_dummy",
           "MedVisBonn/eyepy tests/data/filetypes/heyex_xml/test_volume/, MIT"},
    Source{"realdata/topcon_ukb_example_min.fda",
           "DIAGNijmegen/rse-panimg tests/resources/oct/fda_minimized.fda, Apache-2.0"},
    Source{"realdata/cirrus_macular_cube_512x128_os_Surfaces_Iowa.xml",
           "made from scitran/ophthalmology iowa/zeissimg/"
           "P73304206_MacularCube512x128_OS_Surfaces_Retina-JEI-Final.mat, MIT"},
    Source{"meshes/", "bldeng/GuidedDenoising models/, LGPL-3.0"},
};

std::string origin_of(const std::string& relative) {
    for (const Source& s : kSources) {
        if (relative.starts_with(s.prefix)) return s.origin;
    }
    return "see tests/README.md";
}

}  // namespace

std::string shared_absent(std::initializer_list<const char*> relative) {
    for (const char* r : relative) {
        const auto p = shared_dir() / r;
        std::error_code ec;
        if (!std::filesystem::exists(p, ec)) {
            return "third-party file absent: " + p.string() + " (from " + origin_of(r) +
                   "; tests/README.md)";
        }
    }
    return "";
}

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
