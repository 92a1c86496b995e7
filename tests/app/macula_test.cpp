// `octshape macula` end to end: the bundled phantoms against their truth, the JSON and CSV
// outputs, and the refusals (exit 69).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "fixtures/lateral_shifts.h"
#include "octshape/io/sha256.h"
#include "octshape/io/vol.h"
#include "octshape/retina/phantom_macula.h"
#include "octshape/version.h"
#include "retina/macula_bounds.h"
#include "test_paths.h"

namespace octshape {
namespace {

using test::read_csv;
using test::slurp;
using test::spit;
using test::split_csv_line;

using nlohmann::json;



TEST(MaculaCli, BezierSampleMatchesItsTruth) {
    const auto vol = test::source_dir() / "sample_scans/macula_bezier_od.vol";
    const json truth =
        json::parse(slurp(test::source_dir() / "sample_scans/macula_bezier_od.truth.json"));
    test::TempDir dir;
    const auto r =
        test::run_octshape("macula " + vol.string() + " -o " + (dir / "eye.json").string() +
                           " --csv " + (dir / "eye.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json j = json::parse(slurp(dir / "eye.json"));
    EXPECT_EQ(j["input"]["sha256"], io::sha256_file(vol.string()));
    EXPECT_EQ(j["provenance"]["version"], kVersion);
    EXPECT_EQ(j["provenance"]["inputs"][0]["sha256"], io::sha256_file(vol.string()));
    EXPECT_EQ(slurp(dir / "eye.json").find("FAKE-PHANTOM"), std::string::npos);  // no identifiers
    EXPECT_NE(j["orientation"].get<std::string>().find("0 deg nasal"), std::string::npos);
    EXPECT_EQ(j["centre"]["source"], "device thickness grid");
    // A still eye: the lateral registration estimates and moves nothing (the scan as read).
    EXPECT_EQ(j["lateral_registration"]["estimable"], true);
    EXPECT_EQ(j["lateral_registration"]["applied"], false);
    ASSERT_EQ(j["half_lines"].size(), 24U);
    EXPECT_EQ(j["half_lines"][0]["interior_control_points_mm"].size(), 4U);
    // One list of options (issue 33): the JSON's are the provenance's, under the command
    // line's names (--half-lines, --tau-um), but for what the run adds (subjects, pictures,
    // paths); what the scan resolved is apart, in "sampling" (the spacing: the scan's ScaleX).
    json from_provenance = j["provenance"]["options"];
    for (const char* run : {"subjects", "qc_pictures", "record_paths"}) from_provenance.erase(run);
    EXPECT_EQ(j["options"], from_provenance);
    EXPECT_EQ(j["options"]["half_lines"], 24);
    EXPECT_EQ(j["options"]["tau_um"], 5);
    EXPECT_EQ(j["options"]["spacing_mm"], 0);
    EXPECT_EQ(j["sampling"]["half_lines"], 24);
    EXPECT_DOUBLE_EQ(j["sampling"]["spacing_mm"].get<double>(),
                     truth["generator"]["scale_x_mm"].get<double>());

    // This sample is coarse: 128 A-scans (ScaleX 70.6 um) x 61 B-scans (125 um). The bounds
    // follow from that grid (tests/retina/macula_bounds.h): centre within e, CFT within the
    // node rise + bilinear error, rim height within eps + the angular shift of the crest, rim
    // points within e + s/2 + sqrt(4 eps / |T''_rim|) (s = ScaleX is the radial step).
    retina::MaculaPhantomParams p;  // the sample's surface: Bezier, not flat, fovea centred
    const double dx = truth["generator"]["scale_x_mm"].get<double>();
    const double dy = truth["generator"]["distance_mm"].get<double>();
    const auto sb = retina::sampling_bounds(p, dx, dy, 0.0005);
    const json& v = j["parameters"];
    const json& t = truth["parameters"];
    const double ec = std::hypot(v["centre_x_mm"].get<double>() - t["centre_x_mm"].get<double>(),
                                 v["centre_y_mm"].get<double>() - t["centre_y_mm"].get<double>());
    EXPECT_LE(ec, sb.centre_mm);
    EXPECT_NEAR(v["cft_mm"].get<double>(), t["cft_mm"].get<double>(),
                sb.node_rise_mm + 0.0005 + sb.bilinear_mm);
    EXPECT_NEAR(v["rim_height_mm"].get<double>(), t["rim_height_mm"].get<double>(),
                sb.bilinear_mm +
                    sb.rim_theta_slope * sb.centre_mm / (sb.min_rim_radius - sb.centre_mm) +
                    dx * dx / 4);
    const double rim_pos = sb.centre_mm + dx / 2 + std::sqrt(4 * sb.bilinear_mm / sb.rim_curv);
    EXPECT_NEAR(v["rim_diameter_mm"].get<double>(), t["rim_diameter_mm"].get<double>(),
                2 * rim_pos);
    EXPECT_NEAR(v["rim_volume_mm3"].get<double>(), t["rim_volume_mm3"].get<double>(),
                2 * rim_pos / sb.min_rim_radius * t["rim_volume_mm3"].get<double>());

    // CSV: one header, one row, same width, the JSON's values.
    std::istringstream csv(slurp(dir / "eye.csv"));
    std::string h;
    std::string row;
    std::string extra;
    ASSERT_TRUE(std::getline(csv, h));
    ASSERT_TRUE(std::getline(csv, row));
    EXPECT_FALSE(std::getline(csv, extra));
    const auto hv = split_csv_line(h);
    const auto rv = split_csv_line(row);
    ASSERT_EQ(hv.size(), rv.size());
    // Columns are only ever appended: the noise estimate after qc_flags, then the ETDRS ones,
    // the grid at the scan centre last.
    EXPECT_EQ(hv.back(), "etdrs_at_scan_centre_total_volume_mm3");
    for (std::size_t i = 0; i < hv.size(); ++i) {
        if (hv[i] == "cft_mm") {
            EXPECT_NEAR(std::stod(rv[i]), v["cft_mm"].get<double>(), 1e-9);
        }
        if (hv[i] == "eye") {
            EXPECT_EQ(rv[i], "OD");
        }
        if (hv[i] == "thickness_noise_sd_um") {  // appended after qc_flags: the JSON's noise
            ASSERT_GT(i, 0U);
            EXPECT_EQ(hv[i - 1], "qc_flags");
            EXPECT_NEAR(std::stod(rv[i]), j["noise"]["thickness_noise_sd_um"].get<double>(),
                        1e-9);
        }
        if (hv[i] == "etdrs_central_mm") {
            EXPECT_NEAR(std::stod(rv[i]),
                        j["etdrs"]["at_fovea_centre"]["sectors"]["central"]["thickness_mm"]
                            .get<double>(),
                        1e-9);
        }
        if (hv[i] == "etdrs_at_scan_centre_central_mm") {
            EXPECT_NEAR(std::stod(rv[i]),
                        j["etdrs"]["at_scan_centre"]["sectors"]["central"]["thickness_mm"]
                            .get<double>(),
                        1e-9);
        }
        if (hv[i].ends_with("_mm") || hv[i].ends_with("_mm2") || hv[i].ends_with("_mm3")) {
            EXPECT_NE(rv[i], "NA") << hv[i];
        }
    }
}

// Lateral registration of a macular volume (docs/algorithms/cube.md, step 1): on by default,
// recorded in the options and the provenance; off, the shifts are still estimated and reported
// and the large-motion flag says they were not removed. The JSON's shifts follow the truth
// file's: 49 B-scans over 7.5 mm leave the 20 smoothest cosines to the eye, so for white jitter
// an exact estimate of the rest correlates sqrt(29 / 49) = 0.77 with the truth; a floor of 0.7
// (the estimate's own error, ~1 um against 30 um, costs < 0.01). The RMS of that part,
// 30 x 0.77 = 23 um, is above the 15 um flag.
TEST(MaculaCli, LateralRegistrationIsOnByDefaultAndRecorded) {
    test::TempDir dir;
    const auto vol = dir / "jitter.vol";
    ASSERT_EQ(test::run_octshape("phantom macula --bscans 49 --ascans 256 --jitter-um 30 -o " +
                                 vol.string())
                  .exit_code,
              0);
    const json truth = json::parse(slurp(dir / "jitter.truth.json"));
    const auto on = test::run_octshape("macula " + vol.string() + " -o " + (dir / "on.json").string());
    ASSERT_EQ(on.exit_code, 0) << on.err;
    const auto off = test::run_octshape("macula " + vol.string() + " --no-lateral-registration -o " +
                                        (dir / "off.json").string());
    ASSERT_EQ(off.exit_code, 0) << off.err;
    const json a = json::parse(slurp(dir / "on.json"));
    const json b = json::parse(slurp(dir / "off.json"));
    EXPECT_EQ(a["options"]["lateral_registration"], true);
    EXPECT_EQ(b["options"]["lateral_registration"], false);
    EXPECT_EQ(a["provenance"]["options"]["lateral_registration"], true);
    EXPECT_EQ(a["options"]["lateral_registration_wavelength_mm"], 0.75);
    EXPECT_EQ(a["options"]["lateral_registration_line_smoothing_ascans"], 4);
    EXPECT_EQ(a["options"]["lateral_registration_wavelength_bscans"], 8);
    EXPECT_EQ(a["options"]["lateral_registration_whole_ascans"], true);
    EXPECT_EQ(a["options"]["lateral_registration_step_ascans"], 0.01);
    EXPECT_EQ(a["lateral_registration"]["applied"], true);
    EXPECT_EQ(a["lateral_registration"]["smooth_modes"], 20);
    EXPECT_EQ(b["lateral_registration"]["applied"], false);
    const auto& t = truth["acquisition"]["lateral_shift_um"];
    const auto& e = a["lateral_registration"]["shift_um"];
    ASSERT_EQ(e.size(), t.size());
    EXPECT_EQ(b["lateral_registration"]["shift_um"], e);  // estimated either way
    EXPECT_GT(test::correlation(e.get<std::vector<double>>(), t.get<std::vector<double>>()), 0.7);
    EXPECT_TRUE(test::has_qc_flag(a, "large lateral motion between B-scans (registered)"));
    EXPECT_TRUE(test::has_qc_flag(b, "large lateral motion between B-scans (not registered)"));
}

TEST(MaculaCli, LineScanOmitsTheThreeDimensionalParameters) {
    const auto vol = test::source_dir() / "sample_scans/macula_line_od.vol";
    test::TempDir dir;
    const auto r =
        test::run_octshape("macula " + vol.string() + " --csv " + (dir / "eye.csv").string() +
                           " -o " + (dir / "eye.json").string() + " --qc " + (dir / "qc").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json j = json::parse(slurp(dir / "eye.json"));
    EXPECT_FALSE(j["parameters"].contains("rim_volume_mm3"));
    EXPECT_EQ(j["half_lines"].size(), 2U);
    EXPECT_FALSE(j["notes"].empty());
    const std::string csv = slurp(dir / "eye.csv");
    EXPECT_NE(csv.find(",NA,"), std::string::npos);  // R reads NA as missing
    // QC pictures: three PNG files named after the -o file (never after the input).
    for (const char* name : {"eye_thickness.png", "eye_profiles.png", "eye_bscan.png"}) {
        const std::string png = slurp(dir / "qc" / name);
        ASSERT_GT(png.size(), 1000U) << name;
        EXPECT_EQ(png.substr(1, 3), "PNG") << name;
    }
}

TEST(MaculaCli, CircleScanAndMissingBmExit69WithoutOutput) {
    retina::MaculaPhantomParams p;
    p.line = true;
    p.pixels = false;
    p.size_x = 256;
    retina::MaculaPhantom ph = retina::make_macula_phantom(p);
    test::TempDir dir;
    io::Scan circle = ph.scan;
    circle.meta.pattern = io::ScanPattern::kCircle;
    circle.meta.scan_pattern_code = 2;
    io::write_vol_file(circle, (dir / "circle.vol").string());
    auto r = test::run_octshape("macula " + (dir / "circle.vol").string() + " -o " +
                                (dir / "c.json").string());
    EXPECT_EQ(r.exit_code, 69) << r.err;
    EXPECT_NE(r.err.find("circle"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "c.json"));

    io::Scan no_bm = ph.scan;
    for (auto& b : no_bm.bscans) {
        std::fill(b.seg[1].begin(), b.seg[1].end(), std::numeric_limits<float>::quiet_NaN());
    }
    io::write_vol_file(no_bm, (dir / "nobm.vol").string());
    r = test::run_octshape("macula " + (dir / "nobm.vol").string() + " -o " +
                           (dir / "n.json").string());
    EXPECT_EQ(r.exit_code, 69) << r.err;
    EXPECT_NE(r.err.find("BM"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "n.json"));
}

TEST(MaculaCli, BadOptionIsAUsageError) {
    const auto vol = test::source_dir() / "sample_scans/macula_line_od.vol";
    const auto r = test::run_octshape("macula " + vol.string() + " --half-lines 23");
    EXPECT_EQ(r.exit_code, 64) << r.err;
    EXPECT_NE(r.err.find("num_half_lines"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace octshape

namespace octshape {
namespace {

// Every refusal of an analysis is one line that names the file (issue: messages that do not
// say which of a thousand files failed are useless in a batch log).
TEST(AnalysisCli, EveryRefusalNamesTheFile) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_716_2.vol");
    test::TempDir dir;
    const std::string circle = test::realdata("onh_circle_716_2.vol").string();
    const std::string macula = (test::source_dir() / "sample_scans/macula_bezier_od.vol").string();
    const std::string line = (test::source_dir() / "sample_scans/macula_line_od.vol").string();
    struct Case {
        std::string args;
        std::string file;
    };
    const std::vector<Case> cases = {
        {"macula '" + circle + "'", circle},                       // wrong pattern
        {"onh '" + circle + "' --ilm device", circle},             // wrong pattern
        {"onh '" + macula + "' --ilm device", macula},             // no BMO in a macula volume
        {"onh '" + line + "' --ilm device", line},                 // a line is not a volume
        {"macula '" + macula + "' --etdrs-layers ILM,NOSUCH", macula},  // a line the scan lacks
    };
    for (const Case& c : cases) {
        const auto r = test::run_octshape(c.args + " -o '" + (dir / "x.json").string() + "'");
        EXPECT_EQ(r.exit_code, 69) << c.args << "\n" << r.err;
        EXPECT_NE(r.err.find(c.file + ": "), std::string::npos) << c.args << "\n" << r.err;
        EXPECT_FALSE(std::filesystem::exists(dir / "x.json")) << c.args;
    }
}

}  // namespace
}  // namespace octshape
