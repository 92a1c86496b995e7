// `octshape onh` end to end on a reduced ONH phantom: JSON and CSV outputs, QC pictures, mesh
// output, a user BMO file, and the refusals (exit codes documented in README.md).

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "fixtures/lateral_shifts.h"
#include "octshape/io/mesh_io.h"
#include "octshape/io/sha256.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/vol.h"
#include "octshape/retina/phantom_onh.h"
#include "test_paths.h"

namespace octshape {
namespace {

using test::read_csv;
using test::slurp;
using test::spit;
using test::split_csv_line;

using nlohmann::json;



// A reduced cupped phantom (49 B-scans x 192 A-scans) written with its truth file.
std::filesystem::path make_phantom(const test::TempDir& dir) {
    const auto vol = dir / "onh.vol";
    const auto r = test::run_octshape("phantom onh --shape cupped --bscans 49 --ascans 192 -o " +
                                      vol.string());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return vol;
}

// Axial registration end to end: on by default and recorded; off on request (the estimate is
// still reported, the large-motion flag says it was not removed); the truth file's shifts are
// what the JSON reports up to the cubic across the B-scans that a volume cannot tell from the
// eye's wall (docs/algorithms/onh.md): fourth differences remove any cubic exactly, and the
// estimate is exact to < 0.01 um on these lines (tests/retina/axial_registration_test.cpp),
// which a fourth difference amplifies at most 16-fold: 0.2 um.
TEST(OnhCli, AxialRegistrationIsOnByDefaultAndRecorded) {
    test::TempDir dir;
    const auto vol = dir / "moving.vol";
    ASSERT_EQ(test::run_octshape("phantom onh --bscans 25 --ascans 64 --motion-um 60 "
                                 "--vessel-shadows -o " + vol.string())
                  .exit_code,
              0);
    const json truth = json::parse(slurp(dir / "moving.truth.json"));
    const auto on = test::run_octshape("onh " + vol.string() + " --ilm device -o " +
                                       (dir / "on.json").string());
    ASSERT_EQ(on.exit_code, 0) << on.err;
    const auto off = test::run_octshape("onh " + vol.string() + " --ilm device " +
                                        "--no-axial-registration -o " + (dir / "off.json").string());
    ASSERT_EQ(off.exit_code, 0) << off.err;
    const json a = json::parse(slurp(dir / "on.json"));
    const json b = json::parse(slurp(dir / "off.json"));
    // The JSON's options are the provenance's (one list): true on, false off.
    EXPECT_EQ(a["options"]["axial_registration"], true);
    EXPECT_EQ(b["options"]["axial_registration"], false);
    EXPECT_EQ(a["axial_registration"]["applied"], true);
    EXPECT_EQ(b["axial_registration"]["applied"], false);
    EXPECT_EQ(a["provenance"]["options"]["axial_registration"], true);
    EXPECT_EQ(b["provenance"]["options"]["axial_registration"], false);
    const auto& t = truth["acquisition"]["axial_shift_um"];
    const auto& e = a["axial_registration"]["shift_um"];
    ASSERT_EQ(e.size(), t.size());
    auto fourth = [](const json& v, std::size_t k) {
        return v[k].get<double>() - 4 * v[k + 1].get<double>() + 6 * v[k + 2].get<double>() -
               4 * v[k + 3].get<double>() + v[k + 4].get<double>();
    };
    for (std::size_t k = 0; k + 4 < t.size(); ++k) EXPECT_NEAR(fourth(e, k), fourth(t, k), 0.2) << k;
    auto has = [](const json& j, const std::string& flag) {
        for (const auto& f : j["qc_flags"]) {
            if (f.get<std::string>() == flag) return true;
        }
        return false;
    };
    EXPECT_TRUE(has(a, "large axial motion between B-scans (registered)"));
    EXPECT_TRUE(has(b, "large axial motion between B-scans (not registered)"));
}

// Lateral registration of a volume (docs/algorithms/onh.md "Lateral registration"): on by
// default, recorded in the options and the provenance; off, the shifts are still estimated and
// reported and the large-motion flag says they were not removed. The JSON's shifts follow the
// truth file's: they hold its part outside the 12 smoothest of 49 cosines across the B-scans
// (which the registration leaves to the eye), for white jitter a correlation of
// sqrt(37 / 49) = 0.87 if that part is exact (measured 0.947 on this draw); a floor of 0.8.
TEST(OnhCli, LateralRegistrationIsOnByDefaultAndRecorded) {
    test::TempDir dir;
    const auto vol = dir / "jitter.vol";
    ASSERT_EQ(test::run_octshape("phantom onh --bscans 49 --ascans 128 --jitter-um 30 "
                                 "--vessel-shadows -o " + vol.string())
                  .exit_code,
              0);
    const json truth = json::parse(slurp(dir / "jitter.truth.json"));
    const auto on = test::run_octshape("onh " + vol.string() + " --ilm device -o " +
                                       (dir / "on.json").string());
    ASSERT_EQ(on.exit_code, 0) << on.err;
    const auto off = test::run_octshape("onh " + vol.string() + " --ilm device " +
                                        "--no-lateral-registration -o " + (dir / "off.json").string());
    ASSERT_EQ(off.exit_code, 0) << off.err;
    const json a = json::parse(slurp(dir / "on.json"));
    const json b = json::parse(slurp(dir / "off.json"));
    EXPECT_EQ(a["options"]["lateral_registration"], true);
    EXPECT_EQ(b["options"]["lateral_registration"], false);
    EXPECT_EQ(a["provenance"]["options"]["lateral_registration"], true);
    EXPECT_EQ(a["options"]["lateral_registration_wavelength_mm"], 0.75);
    EXPECT_EQ(a["options"]["lateral_registration_wavelength_bscans"], 25);
    EXPECT_EQ(a["options"]["axial_registration_isotropic_curvature"], true);
    EXPECT_TRUE(a["axial_registration"]["curvature_to_motion_um"].is_number());
    EXPECT_TRUE(a["axial_registration"]["curvature_mrw_effect_um"].is_number());
    EXPECT_EQ(a["lateral_registration"]["applied"], true);
    EXPECT_EQ(b["lateral_registration"]["applied"], false);
    const auto& t = truth["acquisition"]["lateral_shift_um"];
    const auto& e = a["lateral_registration"]["shift_um"];
    ASSERT_EQ(e.size(), t.size());
    EXPECT_EQ(b["lateral_registration"]["shift_um"], e);  // estimated either way
    EXPECT_GT(test::correlation(e.get<std::vector<double>>(), t.get<std::vector<double>>()), 0.8);
    EXPECT_TRUE(test::has_qc_flag(a, "large lateral motion between B-scans (registered)"));
    EXPECT_TRUE(test::has_qc_flag(b, "large lateral motion between B-scans (not registered)"));
}

TEST(OnhCli, JsonCsvQcAndMeshesOfAPhantom) {
    test::TempDir dir;
    const auto vol = make_phantom(dir);
    const json truth = json::parse(slurp(dir / "onh.truth.json"));
    const auto r =
        test::run_octshape("onh " + vol.string() + " -o " + (dir / "eye.json").string() +
                           " --csv " + (dir / "eye.csv").string() + " --qc " +
                           (dir / "qc").string() + " --mesh-out " + (dir / "mesh").string() +
                           " --ilm device");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json j = json::parse(slurp(dir / "eye.json"));
    EXPECT_EQ(j["command"], "onh");
    EXPECT_EQ(j["input"]["sha256"], io::sha256_file(vol.string()));
    EXPECT_EQ(slurp(dir / "eye.json").find("FAKE-PHANTOM"), std::string::npos);  // no identifiers
    EXPECT_EQ(j["sources"]["ilm_source"], "device");
    EXPECT_EQ(j["sources"]["bmo_source"], "automatic");
    // One list of options: the JSON's are the provenance's but for what the run adds.
    json from_provenance = j["provenance"]["options"];
    for (const char* run : {"subjects", "qc_pictures", "record_paths"}) from_provenance.erase(run);
    EXPECT_EQ(j["options"], from_provenance);
    EXPECT_EQ(j["options"]["ilm"], "device");
    EXPECT_NE(j["orientation"].get<std::string>().find("0 deg nasal"), std::string::npos);
    const json& v = j["parameters"];
    const json& t = truth["truth"];
    // The reduced grid (dx 22.7 um, dy 90.6 um) keeps the BMO area well within 1 % (the fit
    // averages the +-dx/2 quantisation of ~40 end points).
    EXPECT_NEAR(v["bmo_area_mm2"].get<double>(), t["bmo_area_mm2"].get<double>(),
                0.01 * t["bmo_area_mm2"].get<double>());
    EXPECT_TRUE(v["has_cup"].get<bool>());
    EXPECT_EQ(j["bmo_points"].size(), 360U);
    EXPECT_EQ(v["mrw_sector_mm"].size(), 12U);
    EXPECT_EQ(j["bmo"]["points_per_bscan"].size(), 49U);
    EXPECT_GT(j["bmo"]["measured"].size(), 20U);
    EXPECT_GT(j["qc"]["rpe_fill_area_mm2"].get<double>(), 2.0);  // the BMO, ~2.2 mm2

    // CSV: one header line, one row, same width; values match the JSON.
    std::istringstream csv(slurp(dir / "eye.csv"));
    std::string header;
    std::string row;
    std::string extra;
    ASSERT_TRUE(std::getline(csv, header));
    ASSERT_TRUE(std::getline(csv, row));
    EXPECT_FALSE(std::getline(csv, extra));
    const auto hv = split_csv_line(header);
    const auto rv = split_csv_line(row);
    ASSERT_EQ(hv.size(), rv.size());
    EXPECT_EQ(hv.front(), "eye_key");  // no file name by default (--record-paths adds it)
    // A volume has no in-plane MRW (radial scans only): null in the JSON, NA in its columns.
    EXPECT_TRUE(v["mrw_inplane_mean_mm"].is_null());
    EXPECT_FALSE(j.contains("radial"));
    ASSERT_GE(hv.size(), 2U);
    EXPECT_EQ(hv[hv.size() - 2], "mrw_inplane_sector_330_mm");
    EXPECT_EQ(rv[rv.size() - 2], "NA");
    // Appended last: which analysis read the scan.
    EXPECT_EQ(hv.back(), "analysis");
    EXPECT_EQ(rv.back(), "volume");
    int checked = 0;
    for (std::size_t i = 0; i < hv.size(); ++i) {
        for (const char* key : {"cup_volume_mm3", "conht_mm", "mrw_mean_mm", "bmo_area_mm2"}) {
            if (hv[i] == key) {
                EXPECT_NEAR(std::stod(rv[i]), v[key].get<double>(), 1e-8) << key;
                ++checked;
            }
        }
        if (hv[i] == "mrw_sector_090_mm") {
            EXPECT_NEAR(std::stod(rv[i]), v["mrw_sector_mm"]["90"].get<double>(), 1e-8);
            ++checked;
        }
    }
    EXPECT_EQ(checked, 5);

    for (const char* name : {"eye_enface.png", "eye_bscans.png", "eye_mrw.png"}) {
        const std::string png = slurp(dir / "qc" / name);
        ASSERT_GT(png.size(), 1000U) << name;
        EXPECT_EQ(png.substr(1, 3), "PNG") << name;
    }
    const io::MeshData ilm = io::read_mesh(dir / "mesh" / "eye_ilm.vtp");
    EXPECT_EQ(ilm.F.rows(), 2 * 48 * 191);
    const auto provenance = nlohmann::json::parse(ilm.provenance);
    EXPECT_EQ(provenance.at("command"), "onh");
    EXPECT_EQ(provenance.at("inputs")[0].at("sha256"), io::sha256_file(vol.string()));
    EXPECT_EQ(ilm.V.rows(), 49 * 192);
    const io::MeshData rpe = io::read_mesh(dir / "mesh" / "eye_rpe.vtp");
    EXPECT_EQ(rpe.V.rows(), 49 * 192);
    const std::string vtp = slurp(dir / "mesh" / "eye_ilm.vtp");
    for (const char* scalar : {"height_above_rpe_mm", "region", "envt_strength"}) {
        EXPECT_NE(vtp.find(scalar), std::string::npos) << scalar;
    }
}

TEST(OnhCli, UserBmoFileReplacesTheDetection) {
    test::TempDir dir;
    const auto vol = make_phantom(dir);
    const json truth = json::parse(slurp(dir / "onh.truth.json"));
    {
        std::ofstream f(dir / "bmo.csv");
        f << "# the phantom's true BMO points\nx_mm,y_mm,z_mm\n";
        f.precision(17);
        for (const auto& p : truth["bmo_points"]) {
            const auto& q = p["bmo_mm"];
            f << q[0].get<double>() << ',' << q[1].get<double>() << ',' << q[2].get<double>()
              << '\n';
        }
    }
    const auto r =
        test::run_octshape("onh " + vol.string() + " --bmo " + (dir / "bmo.csv").string() + " -o " +
                           (dir / "eye.json").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json j = json::parse(slurp(dir / "eye.json"));
    EXPECT_EQ(j["sources"]["bmo_source"], "file");
    EXPECT_EQ(j["bmo"]["measured_points"], truth["bmo_points"].size());
    // Exact ellipse points: only cv::fitEllipseDirect's own error on exact points remains
    // (<= 1e-4 mm on the axes, tests/retina/bmo_test.cpp): <= 3e-4 mm2.
    EXPECT_NEAR(j["parameters"]["bmo_area_mm2"].get<double>(),
                truth["truth"]["bmo_area_mm2"].get<double>(), 3e-4);
}

TEST(OnhCli, RefusalsHaveTheirExitCodesAndWriteNothing) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_716_2.vol", "realdata/onh_circle_valid.vol");
    test::TempDir dir;
    for (const char* name : {"onh_circle_716_2.vol", "onh_circle_valid.vol"}) {
        const auto r = test::run_octshape("onh " + test::realdata(name).string() + " -o " +
                                          (dir / "c.json").string());
        EXPECT_EQ(r.exit_code, 69) << r.err;
        EXPECT_NE(r.err.find("a volume or radial scan is needed"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find(name), std::string::npos) << r.err;  // names the file
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(std::filesystem::exists(dir / "c.json"));
    }
    const auto missing = test::run_octshape("onh " + (dir / "nope.vol").string());
    EXPECT_EQ(missing.exit_code, 66) << missing.err;
    const auto vol = make_phantom(dir);
    const auto bad_ilm = test::run_octshape("onh " + vol.string() + " --ilm graph");
    EXPECT_EQ(bad_ilm.exit_code, 64) << bad_ilm.err;
    std::ofstream(dir / "bad.csv") << "x,y\n1,2\n";
    const auto bad_bmo =
        test::run_octshape("onh " + vol.string() + " --bmo " + (dir / "bad.csv").string() + " -o " +
                           (dir / "b.json").string());
    EXPECT_EQ(bad_bmo.exit_code, 65) << bad_bmo.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "b.json"));
}


// ---- Radial scans -------------------------------------------------------------------------

const char* const kRadialSampleCommand =
    "phantom onh --pattern radial --lines 12 --ascans 128 --eye OS --crossing-offset-um 50 "
    "--seed 4";

std::string file_bytes(const std::filesystem::path& path) {
    std::string text(std::filesystem::file_size(path), '\0');
    std::ifstream in(path, std::ios::binary);
    in.read(text.data(), static_cast<std::streamsize>(text.size()));
    return text;
}

// sample_scans/README.md promises that its command reproduces the sample bit for bit.
TEST(OnhCli, RadialSampleIsReproducedBitForBit) {
    const test::TempDir dir;
    const auto vol = dir / "r.vol";
    const auto r = test::run_octshape(std::string(kRadialSampleCommand) + " -o " + vol.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto sample = test::source_dir() / "sample_scans";
    EXPECT_TRUE(file_bytes(vol) == file_bytes(sample / "onh_radial_cupped_os.vol"));
    EXPECT_EQ(file_bytes(dir / "r.truth.json"),
              file_bytes(sample / "onh_radial_cupped_os.truth.json"));
}

TEST(OnhCli, RadialSampleJsonCsvAgainstItsTruth) {
    const test::TempDir dir;
    const auto sample = test::source_dir() / "sample_scans" / "onh_radial_cupped_os.vol";
    const json truth =
        json::parse(slurp(test::source_dir() / "sample_scans" / "onh_radial_cupped_os.truth.json"));
    const auto r = test::run_octshape("onh " + sample.string() + " --ilm device -o " +
                                      (dir / "eye.json").string() + " --csv " +
                                      (dir / "eye.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string text = slurp(dir / "eye.json");
    EXPECT_EQ(text.find("onh_radial_cupped_os"), std::string::npos);  // no file name
    const json j = json::parse(text);
    const json& v = j["parameters"];
    const json& t = truth["truth"];
    // The sample is coarse (12 lines, 128 A-scans: ds = 34 um) but deterministic: measured
    // BMO area +0.03 %, volumes within 0.9 %, CONHT 0.2 um, MRWs 0.6 um. The targets
    // (1 %, 2 %, 5 um) are asserted.
    auto rel = [&](const char* k) { return v[k].get<double>() / t[k].get<double>() - 1.0; };
    EXPECT_LT(std::fabs(rel("bmo_area_mm2")), 0.01);
    for (const char* k : {"cup_volume_mm3", "bmo_volume_mm3", "total_volume_mm3",
                          "annular_volume_mm3"}) {
        EXPECT_LT(std::fabs(rel(k)), 0.02) << k;
    }
    for (const char* k : {"conht_mm", "mrw_mean_mm", "mrw_inplane_mean_mm"}) {
        EXPECT_NEAR(v[k].get<double>(), t[k].get<double>(), 0.005) << k;
    }
    const json& rad = j["radial"];
    EXPECT_EQ(rad["lines"], 12);
    EXPECT_EQ(rad["mrw_inplane_points"].size(), 24U);
    EXPECT_EQ(j["bmo"]["measured_points"], 24);
    EXPECT_TRUE(j["qc_flags"].empty()) << j["qc_flags"];
    // The CSV: the in-plane columns appended after the volume's, filled.
    const auto rows = read_csv(dir / "eye.csv");
    ASSERT_EQ(rows.size(), 2U);
    const auto& h = rows[0];
    ASSERT_GE(h.size(), 14U);
    EXPECT_EQ(h[h.size() - 14], "mrw_inplane_mean_mm");
    EXPECT_EQ(h[h.size() - 2], "mrw_inplane_sector_330_mm");
    EXPECT_NE(rows[1][h.size() - 14], "NA");
    EXPECT_NEAR(std::stod(rows[1][h.size() - 14]), v["mrw_inplane_mean_mm"].get<double>(), 1e-6);
    EXPECT_EQ(h.back(), "analysis");  // appended after the in-plane columns
    EXPECT_EQ(rows[1].back(), "radial");
}

// A BMO file for a radial scan: ascan,bscan,depth_px (the automatic detection's own points,
// written back as pixel indices, give the same ellipse); x_mm,y_mm,z_mm is refused (65).
TEST(OnhCli, RadialBmoFileGivesThePointsOnTheirBscans) {
    const test::TempDir dir;
    const auto sample = test::source_dir() / "sample_scans" / "onh_radial_cupped_os.vol";
    const auto a = test::run_octshape("onh " + sample.string() + " --ilm device -o " +
                                      (dir / "a.json").string());
    ASSERT_EQ(a.exit_code, 0) << a.err;
    const json ja = json::parse(slurp(dir / "a.json"));
    // The radial grid mm back to A-scan indices: along each line from its Start (A-scan 0).
    const io::Scan scan = io::read_scan(sample.string(), {});
    std::ostringstream csv;
    csv << "ascan,bscan,depth_px\n";
    csv.precision(17);
    const json& pts = ja["bmo"]["measured"];
    const double ds = scan.meta.scale_x_mm;
    const json& ip = ja["radial"]["mrw_inplane_points"];
    ASSERT_EQ(ip.size(), pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
        const int b = pts[i]["bscan"].get<int>();
        const io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        // The line's direction in the grid frame (x = SLO +x, y = SLO -y); the point's distance
        // along it from the crossing, plus the crossing's A-scan (the lines are centred on it).
        const double len = std::hypot(bs.end_x_mm - bs.start_x_mm, bs.end_y_mm - bs.start_y_mm);
        const double ux = (bs.end_x_mm - bs.start_x_mm) / len;
        const double uy = -(bs.end_y_mm - bs.start_y_mm) / len;
        const double cx = ja["radial"]["crossing_mm"][0].get<double>();
        const double cy = ja["radial"]["crossing_mm"][1].get<double>();
        const double along = (pts[i]["x_mm"].get<double>() - cx) * ux +
                             (pts[i]["y_mm"].get<double>() - cy) * uy;
        const double foot_ascan = 0.5 * (scan.meta.size_x - 1);
        csv << foot_ascan + along / ds << ',' << b << ','
            << -pts[i]["z_mm"].get<double>() / scan.meta.scale_z_mm << '\n';
    }
    spit(dir / "bmo.csv", csv.str());
    const auto f = test::run_octshape("onh " + sample.string() + " --ilm device --bmo " +
                                      (dir / "bmo.csv").string() + " -o " +
                                      (dir / "f.json").string());
    ASSERT_EQ(f.exit_code, 0) << f.err;
    const json jf = json::parse(slurp(dir / "f.json"));
    EXPECT_EQ(jf["sources"]["bmo_source"], "file");
    EXPECT_NEAR(jf["parameters"]["bmo_area_mm2"].get<double>(),
                ja["parameters"]["bmo_area_mm2"].get<double>(), 1e-6);
    EXPECT_NEAR(jf["parameters"]["mrw_inplane_mean_mm"].get<double>(),
                ja["parameters"]["mrw_inplane_mean_mm"].get<double>(), 1e-6);
    EXPECT_EQ(jf["radial"]["mrw_inplane_points"].size(), pts.size());
    spit(dir / "mm.csv", "x_mm,y_mm,z_mm\n1,1,-1\n1,2,-1\n2,1,-1\n2,2,-1\n1.5,1,-1\n1,1.5,-1\n");
    const auto mm = test::run_octshape("onh " + sample.string() + " --ilm device --bmo " +
                                       (dir / "mm.csv").string() + " -o " +
                                       (dir / "m.json").string());
    EXPECT_EQ(mm.exit_code, 65) << mm.err;
    EXPECT_NE(mm.err.find("ascan,bscan,depth_px"), std::string::npos) << mm.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "m.json"));
}

// The default ILM (the level set) on the radial sample: a 2-D level set per B-scan,
// interpolated between the lines (docs/algorithms/onh.md "Radial scans"). The sample is coarse
// (12 lines, 128 A-scans: ds = 34 um, the crossing 50 um off the BMO centre); measured BMO area
// +0.03 %, volumes within 1.4 %, CONHT +2.2 um, MRWs within 2.6 um, MRW area +0.1 %. The
// issue's targets (1 %, 2 %, 5 um, 2 %) are asserted; the level set sits 1-3 um above the
// device line's exact ILM (levelset.md), which the 5 um and 2 % hold with a margin.
TEST(OnhCli, RadialDefaultIsTheLevelSet) {
    const test::TempDir dir;
    const auto sample = test::source_dir() / "sample_scans" / "onh_radial_cupped_os.vol";
    const json truth =
        json::parse(slurp(test::source_dir() / "sample_scans" / "onh_radial_cupped_os.truth.json"));
    const auto r = test::run_octshape("onh " + sample.string() + " -o " +
                                      (dir / "eye.json").string() + " --csv " +
                                      (dir / "eye.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json j = json::parse(slurp(dir / "eye.json"));
    EXPECT_EQ(j["sources"]["ilm_source"], "levelset");
    const json& v = j["parameters"];
    const json& t = truth["truth"];
    auto rel = [&](const char* k) { return v[k].get<double>() / t[k].get<double>() - 1.0; };
    EXPECT_LT(std::fabs(rel("bmo_area_mm2")), 0.01);
    for (const char* k : {"cup_volume_mm3", "bmo_volume_mm3", "total_volume_mm3",
                          "annular_volume_mm3", "mrw_area_mm2"}) {
        EXPECT_LT(std::fabs(rel(k)), 0.02) << k;
    }
    for (const char* k : {"conht_mm", "mrw_mean_mm", "mrw_inplane_mean_mm"}) {
        EXPECT_NEAR(v[k].get<double>(), t[k].get<double>(), 0.005) << k;
    }
    EXPECT_EQ(j["radial"]["mrw_inplane_points"].size(), 24U);
    EXPECT_TRUE(j["qc_flags"].empty()) << j["qc_flags"];
    bool noted = false;
    for (const auto& n : j["notes"]) {
        noted = noted || n.get<std::string>().find("2-D level set per B-scan (12 B-scans") !=
                             std::string::npos;
    }
    EXPECT_TRUE(noted) << j["notes"];
    // The CSV keeps its columns: the same header as the device ILM's.
    const auto d = test::run_octshape("onh " + sample.string() + " --ilm device -o " +
                                      (dir / "dev.json").string() + " --csv " +
                                      (dir / "dev.csv").string());
    ASSERT_EQ(d.exit_code, 0) << d.err;
    EXPECT_EQ(read_csv(dir / "eye.csv")[0], read_csv(dir / "dev.csv")[0]);
}

// A radial scan whose B-scan holds no image (all pixels equal) is refused by the level set
// (exit 69, one line naming the file and the B-scan, nothing written); --ilm device analyses it.
TEST(OnhCli, RadialLevelSetRefusesABlankBscan) {
    const test::TempDir dir;
    const auto sample = test::source_dir() / "sample_scans" / "onh_radial_cupped_os.vol";
    io::ReadOptions with_pixels;
    with_pixels.pixels = true;
    io::Scan scan = io::read_scan(sample.string(), with_pixels);
    std::fill(scan.bscans[5].pixels.begin(), scan.bscans[5].pixels.end(), 0.0F);
    const auto blank = dir / "blank.vol";
    io::write_vol_file(scan, blank.string());
    const auto out = (dir / "x.json").string();
    const auto r = test::run_octshape("onh " + blank.string() + " -o " + out + " --csv " +
                                      (dir / "x.csv").string());
    EXPECT_EQ(r.exit_code, 69) << r.err;
    EXPECT_NE(r.err.find("blank.vol"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("radial B-scan 5"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));
    EXPECT_FALSE(std::filesystem::exists(dir / "x.csv"));
    const auto d = test::run_octshape("onh " + blank.string() + " --ilm device -o " + out);
    EXPECT_EQ(d.exit_code, 0) << d.err;
}

TEST(OnhCli, RadialDefaultsRunWithPicturesAndImpossibleGeometryWritesNothing) {
    const test::TempDir dir;
    const auto sample = test::source_dir() / "sample_scans" / "onh_radial_cupped_os.vol";
    const auto out = (dir / "x.json").string();
    // The defaults on a radial scan (level-set ILM) with the QC pictures: nothing refused any
    // more; the three pictures of the eye's stem and the JSON are written.
    {
        const auto r = test::run_octshape("onh " + sample.string() + " --qc " +
                                          (dir / "qc").string() + " -o " + out);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        const json j = json::parse(slurp(out));
        EXPECT_EQ(j["sources"]["ilm_source"], "levelset");
        int pictures = 0;
        for (const auto& e : std::filesystem::directory_iterator(dir / "qc")) {
            EXPECT_EQ(e.path().extension(), ".png") << e.path();
            ++pictures;
        }
        EXPECT_EQ(pictures, 3);
        std::filesystem::remove_all(dir / "qc");
        std::filesystem::remove(out);
    }
    // Impossible geometry: one line with Start = End on the SLO (69, one line naming the file).
    io::ReadOptions with_pixels;
    with_pixels.pixels = true;
    io::Scan scan = io::read_scan(sample.string(), with_pixels);
    scan.bscans[3].end_x_mm = scan.bscans[3].start_x_mm;
    scan.bscans[3].end_y_mm = scan.bscans[3].start_y_mm;
    const auto broken = dir / "broken.vol";
    io::write_vol_file(scan, broken.string());
    const auto r = test::run_octshape("onh " + broken.string() + " --ilm device -o " + out +
                                      " --csv " + (dir / "x.csv").string() + " --qc " +
                                      (dir / "qc").string());
    EXPECT_EQ(r.exit_code, 69) << r.err;
    EXPECT_NE(r.err.find("broken.vol"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("Start = End"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));
    EXPECT_FALSE(std::filesystem::exists(dir / "x.csv"));
    EXPECT_FALSE(std::filesystem::exists(dir / "qc"));  // no picture of a failed analysis
}

}  // namespace
}  // namespace octshape
