// `octshape info` end to end on the real files in ../shared/realdata and on hostile input.
// Expected values were read from the files with an independent Python script (struct.unpack of
// the header fields and a count of segmentation values < 1e30), not from octshape.

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "test_paths.h"

namespace octshape::test {
namespace {

using nlohmann::json;

json info_json(const std::string& file, const std::string& extra = "") {
    const RunResult r = run_octshape("info --json " + extra + " '" + file + "'");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return json::parse(r.out);
}

double valid_percent(const json& j, const std::string& layer) {
    for (const json& l : j["layers"]) {
        if (l["name"] == layer) return l["valid_percent"].get<double>();
    }
    ADD_FAILURE() << "no layer " << layer;
    return -1;
}

TEST(InfoRealFiles, FovealLineScan) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol");
    const json j = info_json(realdata("fovea_line_716_0.vol").string());
    EXPECT_EQ(j["format_version"], "HSF-OCT-103");
    EXPECT_EQ(j["eye"], "OD");
    EXPECT_EQ(j["scan_pattern"], "line");
    EXPECT_EQ(j["num_bscans"], 1);
    EXPECT_EQ(j["ascans_per_bscan"], 768);
    EXPECT_EQ(j["pixels_per_ascan"], 496);
    EXPECT_NEAR(j["scale_x_mm"].get<double>(), 0.011821, 1e-6);
    EXPECT_NEAR(j["scale_z_mm"].get<double>(), 0.0038717, 1e-7);
    // ILM valid at A-scans 5..763 (759 of 768), BM at 9..641 (633: the disc edge ends BM).
    EXPECT_NEAR(valid_percent(j, "ILM"), 100.0 * 759 / 768, 1e-6);
    EXPECT_NEAR(valid_percent(j, "BM"), 100.0 * 633 / 768, 1e-6);
    EXPECT_NEAR(valid_percent(j, "RNFL"), 0.0, 1e-12);
    EXPECT_EQ(j["orientation"]["grid_x_points"], "nasal");
    // An ETDRS grid trails the last B-scan although GridType is 0.
    ASSERT_EQ(j["thickness_grids"].size(), 1U);
    EXPECT_FALSE(j["thickness_grids"][0]["from_header"].get<bool>());
    EXPECT_EQ(j["sha256"].get<std::string>().size(), 64U);
    EXPECT_FALSE(j.contains("identifiers"));
}

TEST(InfoRealFiles, CircleScans) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_valid.vol", "realdata/onh_circle_716_2.vol", "realdata/onh_circle_716_4.vol");
    for (const char* name : {"onh_circle_716_2.vol", "onh_circle_716_4.vol"}) {
        const json j = info_json(realdata(name).string());
        EXPECT_EQ(j["eye"], "OD") << name;
        EXPECT_EQ(j["scan_pattern"], "circle") << name;
        EXPECT_EQ(j["ascans_per_bscan"], 768) << name;
        // Radius 1.80 mm both from ScaleX * SizeX / 2 pi and from Start-to-centre distance.
        EXPECT_NEAR(j["circle_radius_mm"].get<double>(), 1.80, 0.005) << name;
        EXPECT_NEAR(j["circle_radius_from_positions_mm"].get<double>(), 1.80, 0.005) << name;
        EXPECT_NEAR(valid_percent(j, "ILM"), 100.0, 1e-9) << name;
    }
    const json v = info_json(realdata("onh_circle_valid.vol").string());
    EXPECT_EQ(v["scan_pattern"], "circle");
    EXPECT_NEAR(valid_percent(v, "ILM"), 100.0 * 581 / 768, 1e-6);  // ILM invalid in places
    EXPECT_NEAR(valid_percent(v, "BM"), 100.0, 1e-9);
}

TEST(InfoRealFiles, XmlExport) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy");
    const json j = info_json(realdata("heyex_xml_dummy/test_dummy.xml").string());
    EXPECT_EQ(j["format"], "Heidelberg XML");
    EXPECT_EQ(j["num_bscans"], 10);
    EXPECT_EQ(j["scan_pattern"], "volume");
    EXPECT_TRUE(j["bscan_spacing"]["uniform"].get<bool>());
    EXPECT_EQ(j["orientation"]["grid_y_points"], "superior");
}

TEST(InfoRealFiles, IdentifiersOnlyWhenAsked) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol");
    const std::string file = realdata("fovea_line_716_0.vol").string();
    const json with = info_json(file, "--show-identifiers");
    ASSERT_TRUE(with.contains("identifiers"));
    const std::string dob = with["identifiers"]["date_of_birth"].is_null()
                                ? std::string("no-dob")
                                : with["identifiers"]["date_of_birth"].get<std::string>();
    const std::string pid = with["identifiers"]["patient_id"].get<std::string>();
    for (const std::string args : {"info ", "info --json ", "-v info "}) {
        const RunResult r = run_octshape(args + "'" + file + "'");
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_EQ(r.out.find(dob), std::string::npos) << args;
        EXPECT_EQ(r.err.find(dob), std::string::npos) << args;
        if (!pid.empty()) {
            EXPECT_EQ(r.out.find(pid), std::string::npos) << args;
        }
    }
}

TEST(InfoTextOutput, ReadableSummary) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol");
    const RunResult r = run_octshape("info '" + realdata("fovea_line_716_0.vol").string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("eye:"), std::string::npos);
    EXPECT_NE(r.out.find("OD"), std::string::npos);
    EXPECT_NE(r.out.find("ILM 98.8%"), std::string::npos) << r.out;
}

// One line on stderr that names the file, and the documented exit code.
void expect_refused(const std::string& file, int code, const std::string& needle) {
    const RunResult r = run_octshape("info '" + file + "'");
    EXPECT_EQ(r.exit_code, code) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_NE(r.err.find(file), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(InfoBadInput, EyepyWrittenFileIsRefused) {
    SKIP_UNLESS_SHARED("realdata/not_spectralis_eyepy_written.vol");
    expect_refused(realdata("not_spectralis_eyepy_written.vol").string(), 65, "ep-v0.6.8");
}

TEST(InfoBadInput, MissingDirectoryEmptyAndUnknown) {
    TempDir dir;
    expect_refused((dir / "nope.vol").string(), 66, "no such file");
    expect_refused(dir.path().string(), 66, "not a regular file");
    std::ofstream(dir / "empty.vol").flush();
    expect_refused((dir / "empty.vol").string(), 65, "empty");
    std::ofstream(dir / "text.vol") << "hello, not a scan\n";
    expect_refused((dir / "text.vol").string(), 65, "not a Spectralis .vol, Heidelberg XML export, Iowa surfaces XML or Topcon .fda/.fds");
}

TEST(InfoRadial, DescribesTheStarAsItIs) {
    // A 12-line radial phantom: info must describe lines, length, crossing and angular step,
    // never a parallel spacing or a volume extent (which would read "extent 6 mm x 0 mm").
    TempDir dir;
    const std::string vol = (dir / "radial.vol").string();
    const RunResult g = run_octshape("phantom macula --pattern radial --lines 12 --no-pixels -o '" +
                                     vol + "'");
    ASSERT_EQ(g.exit_code, 0) << g.err;
    const json j = info_json(vol);
    ASSERT_TRUE(j.contains("radial"));
    EXPECT_FALSE(j.contains("bscan_spacing"));
    EXPECT_EQ(j["radial"]["num_lines"], 12);
    EXPECT_NEAR(j["radial"]["line_length_mm"].get<double>(), 6.0, 1e-9);
    EXPECT_NEAR(j["radial"]["angular_step_deg"].get<double>(), 15.0, 1e-9);
    EXPECT_LT(j["radial"]["max_miss_mm"].get<double>(), 1e-9);
    const RunResult t = run_octshape("info '" + vol + "'");
    ASSERT_EQ(t.exit_code, 0) << t.err;
    EXPECT_NE(t.out.find("12 lines of 6 mm"), std::string::npos) << t.out;
    EXPECT_NE(t.out.find("step 15 deg"), std::string::npos) << t.out;
    EXPECT_EQ(t.out.find("extent"), std::string::npos) << t.out;
    EXPECT_EQ(t.out.find("differs from the header"), std::string::npos) << t.out;
}

}  // namespace
}  // namespace octshape::test
