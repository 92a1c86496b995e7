// What `--help` says about patterns, pictures and defaults is what the commands do: the QC
// pictures each command's help names are the files it writes, the defaults it prints are the
// parameter structs' defaults, and the scan patterns it names are accepted.

#include <gtest/gtest.h>

#include <cctype>
#include <filesystem>
#include <iomanip>
#include <set>
#include <sstream>
#include <string>

#include "octshape/retina/cube.h"
#include "octshape/retina/onh.h"
#include "test_paths.h"

namespace octshape {
namespace {

namespace fs = std::filesystem;

std::string help_of(const std::string& command) {
    const test::RunResult r = test::run_octshape(command + " --help");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.out;
}

// KIND of every "STEM_KIND.png" the --qc option's help names.
std::set<std::string> pictures_named(const std::string& help) {
    const std::size_t at = help.find("--qc");
    const std::size_t end = help.find('\n', at);
    const std::string line = help.substr(at, end - at);
    std::set<std::string> kinds;
    // By hand, not std::regex: GCC 12 warns (-Wmaybe-uninitialized) inside <regex> at -O1
    // under the sanitizers, which -Werror turns into a failed build.
    const std::string stem = "STEM_";
    for (std::size_t p = line.find(stem); p != std::string::npos; p = line.find(stem, p + 1)) {
        std::size_t e = p + stem.size();
        while (e < line.size() && line[e] >= 'a' && line[e] <= 'z') ++e;
        if (e > p + stem.size() && line.compare(e, 4, ".png") == 0) {
            kinds.insert(line.substr(p + stem.size(), e - p - stem.size()));
        }
    }
    return kinds;
}

// KIND of every DIR/eye_KIND.png.
std::set<std::string> pictures_written(const fs::path& dir) {
    std::set<std::string> kinds;
    for (const auto& e : fs::directory_iterator(dir)) {
        const std::string n = e.path().filename().string();
        if (n.starts_with("eye_") && n.ends_with(".png")) kinds.insert(n.substr(4, n.size() - 8));
    }
    return kinds;
}

// The default the help prints for `option` ("--half-lines INT=24" -> "24"), "" if none.
std::string default_of(const std::string& help, const std::string& option) {
    // "OPTION TYPE=VALUE" or "OPTION TYPE:{choices}=VALUE", TYPE in capitals; by hand (above).
    const std::string key = option + " ";
    for (std::size_t p = help.find(key); p != std::string::npos; p = help.find(key, p + 1)) {
        std::size_t e = p + key.size();
        const std::size_t type_start = e;
        while (e < help.size() && help[e] >= 'A' && help[e] <= 'Z') ++e;
        if (e == type_start) continue;
        if (help.compare(e, 2, ":{") == 0) {
            const std::size_t close = help.find('}', e);
            if (close == std::string::npos) continue;
            e = close + 1;
        }
        if (e >= help.size() || help[e] != '=') continue;
        const std::size_t v = ++e;
        while (e < help.size() && !std::isspace(static_cast<unsigned char>(help[e]))) ++e;
        if (e > v) return help.substr(v, e - v);
    }
    return "";
}

// A number as CLI11 prints a default (std::to_string, trailing zeros dropped).
std::string printed(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

TEST(HelpClaims, QcPicturesNamedAreThePicturesWritten) {
    // One run per command and pattern family whose pictures differ: a macula volume and line
    // (the bundled samples), an ONH radial scan (the bundled sample, device ILM: fast).
    const fs::path s = test::source_dir() / "sample_scans";
    const std::set<std::string> macula = pictures_named(help_of("macula"));
    const std::set<std::string> onh = pictures_named(help_of("onh"));
    EXPECT_EQ(macula.size(), 3u);
    EXPECT_EQ(onh.size(), 3u);
    for (const auto& [cmd, input, named] :
         {std::tuple{std::string("macula"), s / "macula_bezier_od.vol", macula},
          std::tuple{std::string("macula"), s / "macula_line_od.vol", macula},
          std::tuple{std::string("onh --ilm device"), s / "onh_radial_cupped_os.vol", onh}}) {
        test::TempDir dir;
        const auto r = test::run_octshape(cmd + " " + input.string() + " -o " +
                                          (dir / "eye.json").string() + " --qc " +
                                          dir.path().string());
        ASSERT_EQ(r.exit_code, 0) << cmd << " " << input << ": " << r.err;
        EXPECT_EQ(pictures_written(dir.path()), named) << cmd << " " << input;
    }
}

TEST(HelpClaims, DefaultsPrintedAreTheParameterStructsDefaults) {
    const retina::CubeParams cube;
    for (const std::string cmd : {"macula", "cohort"}) {
        const std::string h = help_of(cmd);
        EXPECT_EQ(default_of(h, "--half-lines"), std::to_string(cube.num_half_lines)) << cmd;
        EXPECT_EQ(default_of(h, "--radius-mm"), printed(cube.radius_mm)) << cmd;
        EXPECT_EQ(default_of(h, "--spacing-mm"), printed(cube.sample_spacing_mm)) << cmd;
        EXPECT_EQ(default_of(h, "--tau-um"), printed(cube.tau_mm * 1e3)) << cmd;
        EXPECT_EQ(default_of(h, "--inner-radius-mm"), printed(cube.inner_radius_mm)) << cmd;
        EXPECT_EQ(default_of(h, "--search-radius-mm"), printed(cube.search_radius_mm)) << cmd;
        EXPECT_EQ(default_of(h, "--rim"), std::string(retina::to_string(cube.rim_point))) << cmd;
    }
    const retina::OnhParams onh;
    for (const std::string cmd : {"onh", "cohort"}) {
        const std::string h = help_of(cmd);
        EXPECT_EQ(default_of(h, "--bmo-points"), std::to_string(onh.bmo_points)) << cmd;
        EXPECT_EQ(default_of(h, "--disc-radius-mm"), printed(onh.disc_radius_mm)) << cmd;
        EXPECT_EQ(default_of(h, "--min-gap-area-mm2"), printed(onh.detection.min_gap_area_mm2))
            << cmd;
        EXPECT_EQ(default_of(h, "--ilm"), retina::to_string(retina::IlmSource::kLevelSet)) << cmd;
    }
}

TEST(HelpClaims, PatternsNamedAsAcceptedAreAccepted) {
    // macula: "A volume scan ..., a radial scan ..., a line through the fovea ..."; onh: "a
    // volume scan or a radial scan". Each pattern named is analysed (exit 0).
    const std::string mh = help_of("macula");
    const std::string oh = help_of("onh");
    for (const char* word : {"volume scan", "radial scan", "line through the fovea"}) {
        EXPECT_NE(mh.find(word), std::string::npos) << word;
    }
    for (const char* word : {"volume scan", "radial scan"}) {
        EXPECT_NE(oh.find(word), std::string::npos) << word;
    }
    test::TempDir dir;
    const fs::path radial = dir / "radial.vol";
    ASSERT_EQ(test::run_octshape("phantom macula --pattern radial --lines 6 --ascans 128 "
                                 "--no-pixels -o " + radial.string())
                  .exit_code,
              0);
    const fs::path onh_volume = dir / "onh.vol";
    ASSERT_EQ(test::run_octshape("phantom onh --bscans 25 --ascans 96 -o " + onh_volume.string())
                  .exit_code,
              0);
    const fs::path s = test::source_dir() / "sample_scans";
    for (const auto& [cmd, input] :
         {std::pair{std::string("macula"), s / "macula_bezier_od.vol"},
          std::pair{std::string("macula"), radial},
          std::pair{std::string("macula"), s / "macula_line_od.vol"},
          std::pair{std::string("onh --ilm device"), onh_volume},
          std::pair{std::string("onh --ilm device"), s / "onh_radial_cupped_os.vol"}}) {
        const auto r = test::run_octshape(cmd + " " + input.string());
        EXPECT_EQ(r.exit_code, 0) << cmd << " " << input << ": " << r.err;
    }
}

}  // namespace
}  // namespace octshape
