// `octshape info` and `octshape macula` on the real Topcon 3D OCT-1000 Mk II file of the UK
// Biobank example (../shared/realdata/topcon_ukb_example_min.fda), its privacy, and the
// `phantom macula --format fda` round trip against the same phantom through .vol.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "fixtures/etdrs_json.h"
#include "octshape/io/sha256.h"
#include "test_paths.h"

namespace octshape {
namespace {

using nlohmann::json;
using test::slurp;

const std::string kTopcon = "topcon_ukb_example_min.fda";
// The exam time in @CAPTURE_INFO_02 (2010-07-09 09:23:36): private, shown only with
// --show-identifiers. (Its date is the `visit_date` of the JSON's `cohort` block, as for every
// export: docs/cohort.md.)
const std::string kExamDate = "2010-07-09";
const std::string kExamTime = "09:23:36";

TEST(TopconCli, InfoOnTheRealFile) {
    SKIP_UNLESS_SHARED("realdata/topcon_ukb_example_min.fda");
    const std::string fda = test::realdata(kTopcon).string();
    const auto r = test::run_octshape("info --json '" + fda + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json j = json::parse(r.out);
    EXPECT_EQ(j["format"], "Topcon .fda/.fds");
    EXPECT_EQ(j["eye"], "OS");
    ASSERT_EQ(j["layers"].size(), 4U);
    EXPECT_EQ(j["layers"][0]["name"], "ILM");
    EXPECT_EQ(j["layers"][1]["name"], "BM");
    const auto text = test::run_octshape("info '" + fda + "'");
    ASSERT_EQ(text.exit_code, 0) << text.err;
    std::printf("%s", text.out.c_str());
    for (const std::string& s : {r.out, r.err, text.out, text.err}) {
        EXPECT_EQ(s.find(kExamDate), std::string::npos) << s;
    }
    for (const std::string& s : {r.out, r.err}) {
        EXPECT_EQ(s.find("topcon_ukb"), std::string::npos) << s;
    }
}

json macula_json(const std::string& input,
                 const std::string& extra,
                 test::TempDir& dir,
                 const std::string& stem,
                 std::string* streams = nullptr) {
    const auto out = dir / (stem + ".json");
    const auto r = test::run_octshape("macula '" + input + "' -o '" + out.string() + "' --csv '" +
                                      (dir / (stem + ".csv")).string() + "' " + extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    if (streams != nullptr) *streams = r.out + r.err + slurp(out) + slurp(dir / (stem + ".csv"));
    return json::parse(slurp(out));
}

void expect_finite_and_oriented(const json& j) {
    for (const auto& [k, x] : j["parameters"].items()) {
        if (x.is_number()) {
            EXPECT_TRUE(std::isfinite(x.get<double>())) << k;
        }
    }
    EXPECT_EQ(j["scan"]["eye"], "OS");
    EXPECT_EQ(j["scan"]["format"], "Topcon .fda/.fds");
    for (const auto& f : j["qc_flags"]) {
        EXPECT_EQ(f.get<std::string>().find("orientation assumed"), std::string::npos) << f;
    }
}

double central_subfield(const json& j) {
    return j["etdrs"]["at_fovea_centre"]["sectors"]["central"]["thickness_mm"].get<double>();
}

void print_row(const char* what, const json& j) {
    const json& v = j["parameters"];
    std::printf(
        "Topcon real volume, %s: CFT %.1f um, pit depth %.1f um, rim height %.1f um, "
        "central subfield %.1f um, RMSE %.2f um\n",
        what, 1e3 * v["cft_mm"].get<double>(), 1e3 * v["pit_depth_mm"].get<double>(),
        1e3 * v["rim_height_mm"].get<double>(), 1e3 * central_subfield(j),
        v["rmse_um"].get<double>());
}

// BM = RETINA_4, the outer RPE boundary (Bruch's membrane): the eye against the ILM-BM ranges
// of normal eyes every octshape number is measured to (docs/algorithms/cube.md "Real eyes":
// CFT 227 +- 23 um, pit depth 120 +- 25 um, means +- 3 SD; rim height 0.29-0.39 mm).
TEST(TopconCli, MaculaOnTheRealFileToBruchsMembraneWithinIlmBmRanges) {
    SKIP_UNLESS_SHARED("realdata/topcon_ukb_example_min.fda");
    test::TempDir dir;
    const std::string fda = test::realdata(kTopcon).string();
    std::string streams;
    const json j = macula_json(fda, "", dir, "eye", &streams);
    print_row("BM = RETINA_4", j);
    expect_finite_and_oriented(j);
    const json& v = j["parameters"];
    EXPECT_GE(v["cft_mm"].get<double>(), 0.227 - 3 * 0.023);
    EXPECT_LE(v["cft_mm"].get<double>(), 0.227 + 3 * 0.023);
    EXPECT_GE(v["pit_depth_mm"].get<double>(), 0.120 - 3 * 0.025);
    EXPECT_LE(v["pit_depth_mm"].get<double>(), 0.120 + 3 * 0.025);
    EXPECT_GE(v["rim_height_mm"].get<double>(), 0.29);
    EXPECT_LE(v["rim_height_mm"].get<double>(), 0.39);
    EXPECT_LT(v["rmse_um"].get<double>(), 7.1);  // thesis: 1.0-7.1 um on real scans
    EXPECT_EQ(j["input"]["sha256"], io::sha256_file(fda));
    EXPECT_EQ(j["provenance"]["options"]["bm_surface"], "ob_rpe");
    EXPECT_EQ(streams.find(kExamTime), std::string::npos);
    EXPECT_EQ(streams.find("topcon_ukb"), std::string::npos);
    EXPECT_EQ(j["cohort"]["visit_date"], kExamDate);
}

// BM = RETINA_3 (--bm-surface ib_rpe), the inner RPE boundary: the central subfield against the
// Topcon 3D OCT-1000 normal eyes. 6 x 6 mm raster, 248 eyes: mean foveal (central 1 mm ETDRS
// circle) thickness 222 +- 19 um (Ooto S et al., Invest Ophthalmol Vis Sci 2010;51:465-473;
// the numbers were checked against the abstract, the instrument and the boundary Topcon's
// thickness uses were not: docs/formats.md). Mean +- 3 SD. To RETINA_4 this eye's central
// subfield is 3.4 SD above that mean, one reason for the docs' reading of the boundaries.
TEST(TopconCli, MaculaOnTheRealFileToTheInnerRpeWithinTopconNormativeRange) {
    SKIP_UNLESS_SHARED("realdata/topcon_ukb_example_min.fda");
    test::TempDir dir;
    const json j =
        macula_json(test::realdata(kTopcon).string(), "--bm-surface ib_rpe", dir, "inner");
    print_row("BM = RETINA_3", j);
    expect_finite_and_oriented(j);
    const json& v = j["parameters"];
    const double central = central_subfield(j);
    test::expect_whole_grid_at_scan_centre(j, "Topcon real volume");
    EXPECT_GE(central, 0.222 - 3 * 0.019);
    EXPECT_LE(central, 0.222 + 3 * 0.019);
    // CFT (the thickness at the pit's bottom): no published Topcon range for this point value
    // was verified; it is at most the central subfield's mean.
    EXPECT_GT(v["cft_mm"].get<double>(), 0.0);
    EXPECT_LE(v["cft_mm"].get<double>(), central + 1e-9);
    // Pit depth is a difference of two thicknesses to the same boundary: the boundary's offset
    // cancels, so the ILM-BM range applies.
    EXPECT_GE(v["pit_depth_mm"].get<double>(), 0.120 - 3 * 0.025);
    EXPECT_LE(v["pit_depth_mm"].get<double>(), 0.120 + 3 * 0.025);
    EXPECT_EQ(j["provenance"]["options"]["bm_surface"], "ib_rpe");
}

// The same phantom written as .vol and as .fda gives the same parameters, to the .fda's whole
// pixel depths: rounding moves every depth by at most half a pixel (1.9 um at 3.87 um per px),
// so a thickness moves by at most one pixel and a fitted parameter by much less.
TEST(TopconCli, PhantomThroughFdaEqualsThroughVol) {
    test::TempDir dir;
    const std::string common = " --bscans 49 --ascans 256 --seed 3 ";
    for (const std::string family : {"bezier", "scheibe"}) {
        for (const std::string fmt : {"vol", "fda"}) {
            const std::string scan = (dir / (family + "." + fmt)).string();
            const auto made = test::run_octshape("phantom macula --family " + family +
                                                 " --format " + fmt + common + "-o '" + scan + "'" +
                                                 (fmt == "vol" ? " --no-pixels" : ""));
            ASSERT_EQ(made.exit_code, 0) << made.err;
            const auto r = test::run_octshape("macula '" + scan + "' -o '" +
                                              (dir / (family + fmt + ".json")).string() + "'");
            ASSERT_EQ(r.exit_code, 0) << r.err;
        }
        const json a = json::parse(slurp(dir / (family + "vol.json")))["parameters"];
        const json b = json::parse(slurp(dir / (family + "fda.json")))["parameters"];
        const double px_mm = 0.0038717;  // the phantom's pixel height
        std::printf(
            "phantom %s (vol | fda): CFT %.2f | %.2f um, pit depth %.2f | %.2f um, rim "
            "height %.2f | %.2f um, rim diameter %.4f | %.4f mm, RMSE %.2f | %.2f um\n",
            family.c_str(), 1e3 * a["cft_mm"].get<double>(), 1e3 * b["cft_mm"].get<double>(),
            1e3 * a["pit_depth_mm"].get<double>(), 1e3 * b["pit_depth_mm"].get<double>(),
            1e3 * a["rim_height_mm"].get<double>(), 1e3 * b["rim_height_mm"].get<double>(),
            a["rim_diameter_mm"].get<double>(), b["rim_diameter_mm"].get<double>(),
            a["rmse_um"].get<double>(), b["rmse_um"].get<double>());
        // Each surface is rounded to whole pixels independently: a sampled thickness moves by at
        // most one pixel, and a fitted thickness (an average over many samples) by no more.
        for (const char* k : {"cft_mm", "pit_depth_mm", "rim_height_mm"}) {
            EXPECT_NEAR(a[k].get<double>(), b[k].get<double>(), px_mm) << family << " " << k;
        }
        // The rim's radius is where the fitted profile peaks: a one-pixel change of a flat
        // crest can move it along the profile, bounded here by one A-scan spacing (8.97 mm /
        // 255) on each side of the diameter.
        EXPECT_NEAR(a["rim_diameter_mm"].get<double>(), b["rim_diameter_mm"].get<double>(),
                    2 * 8.97 / 255)
            << family;
    }
}

// `cohort` takes Topcon files by content: a phantom written as .fda is analysed as a macula
// eye, and a .fds of unknown content is a failure (65), as a damaged .vol would be.
TEST(TopconCli, CohortClassifiesFdaFiles) {
    test::TempDir dir;
    const auto in = dir / "in";
    std::filesystem::create_directories(in);
    const auto made =
        test::run_octshape("phantom macula --format fda --bscans 25 --ascans 128 -o '" +
                           (in / "a.fda").string() + "'");
    ASSERT_EQ(made.exit_code, 0) << made.err;
    std::filesystem::remove(in / "a.truth.json");
    std::ofstream(in / "junk.fds") << "not a Topcon file";
    const auto out = dir / "out";
    const auto r = test::run_octshape("cohort '" + in.string() + "' -o '" + out.string() + "'");
    const auto eyes = test::read_csv(out / "eyes.csv");
    ASSERT_EQ(eyes.size(), 2U) << r.err;  // header + the .fda
    EXPECT_NE(slurp(out / "eyes.csv").find("macula"), std::string::npos);
    const auto failures = test::read_csv(out / "failures.csv");
    ASSERT_EQ(failures.size(), 2U) << r.err;  // header + junk.fds
    EXPECT_NE(slurp(out / "failures.csv").find("65"), std::string::npos);
}

// `onh` on the (macular) Topcon file: a clean refusal, exit 69, one line naming the file and
// no output file: the level-set ILM needs pixels this reader does not decode, and the device
// ILM needs a BM opening a macular cube does not have.
TEST(TopconCli, OnhRefusesClearly) {
    SKIP_UNLESS_SHARED("realdata/topcon_ukb_example_min.fda");
    test::TempDir dir;
    const std::string fda = test::realdata(kTopcon).string();
    for (const std::string ilm : {"levelset", "device"}) {
        const auto out = dir / (ilm + ".json");
        const auto r =
            test::run_octshape("onh '" + fda + "' --ilm " + ilm + " -o '" + out.string() + "'");
        EXPECT_EQ(r.exit_code, 69) << r.err;
        EXPECT_NE(r.err.find(fda + ": "), std::string::npos) << r.err;
        EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
        EXPECT_FALSE(std::filesystem::exists(out));
    }
}

}  // namespace
}  // namespace octshape
