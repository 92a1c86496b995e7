// `octshape macula` on the real Iowa segmentation of a real Spectralis volume
// (../shared/realdata/T566581_Surfaces_Iowa.xml): alone, through our .vol writer, and laid over
// an export with --segmentation; `info` on it; the refusals.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "fixtures/etdrs_json.h"
#include "fixtures/iowa_xml.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/io/vol.h"
#include "octshape/retina/phantom_macula.h"
#include "test_paths.h"

namespace octshape {
namespace {

using nlohmann::json;
using test::slurp;

const std::string kIowa = "T566581_Surfaces_Iowa.xml";

json macula_json(const std::string& input, const std::string& extra, test::TempDir& dir,
                 const std::string& stem) {
    const auto out = dir / (stem + ".json");
    const auto r = test::run_octshape("macula '" + input + "' -o '" + out.string() + "' --csv '" +
                                      (dir / (stem + ".csv")).string() + "' " + extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return json::parse(slurp(out));
}

TEST(IowaCli, RealSegmentationGivesAnatomicallyPlausibleParameters) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    test::TempDir dir;
    const std::string xml = test::realdata(kIowa).string();
    const json j = macula_json(xml, "--qc '" + (dir / "qc").string() + "'", dir, "eye");
    const json& v = j["parameters"];
    std::printf("Iowa real volume: CFT %.1f um, rim height %.1f um, pit depth %.1f um, rim "
                "diameter %.3f mm, max slope %.2f deg, rim volume %.4f mm3, RMSE %.2f um, noise "
                "%.2f um\n",
                1e3 * v["cft_mm"].get<double>(), 1e3 * v["rim_height_mm"].get<double>(),
                1e3 * v["pit_depth_mm"].get<double>(), v["rim_diameter_mm"].get<double>(),
                v["max_pit_slope_deg"].get<double>(), v["rim_volume_mm3"].get<double>(),
                v["rmse_um"].get<double>(), j["noise"]["thickness_noise_sd_um"].get<double>());
    // Normal eyes on Spectralis (docs/algorithms/cube.md "Real eyes"): CFT 227 +- 23 um and pit
    // depth 120 +- 25 um (means +- 3 SD below), the rim (parafoveal maximum) 0.29-0.39 mm and
    // rim diameter 1.9-2.8 mm (thesis Table 7.3), maximum pit slope 5-20 deg.
    EXPECT_GE(v["cft_mm"].get<double>(), 0.227 - 3 * 0.023);
    EXPECT_LE(v["cft_mm"].get<double>(), 0.227 + 3 * 0.023);
    EXPECT_GE(v["pit_depth_mm"].get<double>(), 0.120 - 3 * 0.025);
    EXPECT_LE(v["pit_depth_mm"].get<double>(), 0.120 + 3 * 0.025);
    EXPECT_GE(v["rim_height_mm"].get<double>(), 0.29);
    EXPECT_LE(v["rim_height_mm"].get<double>(), 0.39);
    EXPECT_GE(v["max_pit_slope_deg"].get<double>(), 5.0);
    EXPECT_LE(v["max_pit_slope_deg"].get<double>(), 20.0);
    // A fit RMSE of a few um: the thesis measured 1.0-7.1 um on real scans.
    EXPECT_LT(v["rmse_um"].get<double>(), 7.1);
    EXPECT_EQ(j["scan"]["eye"], "OD");
    EXPECT_EQ(j["input"]["sha256"], io::sha256_file(xml));
    EXPECT_EQ(j["scan"]["format"], "Iowa surfaces XML");
    // The orientation is the documented default, and says so.
    bool assumed = false;
    for (const auto& f : j["qc_flags"]) assumed = assumed || f.get<std::string>().find("orientation assumed") != std::string::npos;
    EXPECT_TRUE(assumed);
    // The ETDRS grid at the fovea: the 6 mm ring reaches beyond the 4.5 mm tall field, so the
    // superior and inferior outer sectors are not reported; the rest are.
    const json& e = j["etdrs"]["at_fovea_centre"]["sectors"];
    EXPECT_FALSE(e["central"]["thickness_mm"].is_null());
    EXPECT_FALSE(e["inner_nasal"]["thickness_mm"].is_null());
    EXPECT_TRUE(e["outer_superior"]["thickness_mm"].is_null());
    EXPECT_LT(e["outer_superior"]["coverage"].get<double>(), 0.9);
    for (const char* pic : {"eye_thickness.png", "eye_profiles.png", "eye_bscan.png"}) {
        EXPECT_TRUE(std::filesystem::exists(dir / "qc" / pic)) << pic;
    }
    // Nothing names the input.
    EXPECT_EQ(slurp(dir / "eye.json").find("T566581"), std::string::npos);
    EXPECT_EQ(slurp(dir / "eye.csv").find("T566581"), std::string::npos);
}

TEST(IowaCli, ResultEqualsTheVolRoundTrip) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    // Written as a .vol with our writer and read back, the same eye must give the same numbers:
    // the .vol stores the rows as float (exact for integers) and the scales as doubles.
    test::TempDir dir;
    const std::string xml = test::realdata(kIowa).string();
    const auto vol = (dir / "iowa.vol").string();
    io::write_vol_file(io::read_scan(xml), vol);
    const json a = macula_json(xml, "", dir, "xml");
    const json b = macula_json(vol, "", dir, "vol");
    // Every parameter, ETDRS value and half-line fit, to the last bit as JSON prints them.
    EXPECT_EQ(a["parameters"].dump(), b["parameters"].dump());
    EXPECT_EQ(a["etdrs"].dump(), b["etdrs"].dump());
    EXPECT_EQ(a["half_lines"].dump(), b["half_lines"].dump());
    EXPECT_EQ(a["centre"].dump(), b["centre"].dump());
    EXPECT_EQ(a["qc_flags"].dump(), b["qc_flags"].dump());
}

TEST(IowaCli, SegmentationOverAnExportReplacesItsLines) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    // An export of the same geometry (a phantom of 19 B-scans x 512 A-scans at the file's
    // voxel size) with the real segmentation laid over it: the result is the real eye's, and
    // the JSON records the segmentation by its SHA-256 only.
    test::TempDir dir;
    retina::MaculaPhantomParams p;
    p.num_bscans = 19;
    p.size_x = 512;
    p.scale_x_mm = 0.011680;
    p.distance_mm = 0.249175;
    p.scale_z_mm = 0.003872;
    p.pixels = false;
    const auto vol = (dir / "export.vol").string();
    io::write_vol_file(retina::make_macula_phantom(p).scan, vol);
    const std::string xml = test::realdata(kIowa).string();
    const json alone = macula_json(xml, "", dir, "alone");
    const json over = macula_json(vol, "--segmentation '" + xml + "'", dir, "over");
    EXPECT_EQ(over["input"]["segmentation"]["sha256"], io::sha256_file(xml));
    EXPECT_EQ(over["input"]["segmentation"]["bm_surface"], "ob_rpe");
    EXPECT_NE(over["input"]["segmentation"]["source"].get<std::string>().find("OCTLayerSeg 3.8.0"),
              std::string::npos);
    EXPECT_FALSE(over["input"]["segmentation"].contains("path"));
    EXPECT_EQ(slurp(dir / "over.json").find("T566581"), std::string::npos);
    // Same lines, same grid: the same thickness map; the centre search starts elsewhere (the
    // export's grid centre) but finds the same pit.
    EXPECT_NEAR(over["parameters"]["cft_mm"].get<double>(),
                alone["parameters"]["cft_mm"].get<double>(), 1e-9);
    EXPECT_NEAR(over["parameters"]["rim_height_mm"].get<double>(),
                alone["parameters"]["rim_height_mm"].get<double>(), 1e-9);
    // The inner RPE boundary as BM thins the retina by the RPE's thickness.
    const json inner = macula_json(vol, "--segmentation '" + xml + "' --bm-surface ib_rpe", dir,
                                   "inner");
    const double d = over["parameters"]["cft_mm"].get<double>() -
                     inner["parameters"]["cft_mm"].get<double>();
    EXPECT_GT(d, 0.005);
    EXPECT_LT(d, 0.040);
    EXPECT_NE(over["cohort"]["fingerprint"], inner["cohort"]["fingerprint"]);
}

TEST(IowaCli, SegmentationOfAnotherScanIsRefused) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    test::TempDir dir;
    const auto vol = (test::source_dir() / "sample_scans/macula_bezier_od.vol").string();
    const std::string xml = test::realdata(kIowa).string();
    const auto r = test::run_octshape("macula '" + vol + "' --segmentation '" + xml + "' -o '" +
                                      (dir / "x.json").string() + "'");
    EXPECT_EQ(r.exit_code, 64) << r.err;
    EXPECT_NE(r.err.find(xml), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("not a segmentation of"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "x.json"));
    // A .vol given as the segmentation.
    const auto r2 = test::run_octshape("macula '" + vol + "' --segmentation '" + vol + "' -o '" +
                                       (dir / "x.json").string() + "'");
    EXPECT_EQ(r2.exit_code, 64) << r2.err;
    EXPECT_NE(r2.err.find("Iowa surfaces XML"), std::string::npos) << r2.err;
}

TEST(IowaCli, OnhOverItsOwnLinesWrittenAsIowaEqualsTheExport) {
    // An ONH phantom's own ILM and BM written as an Iowa document and laid over it: with the
    // device ILM the analysis sees the very same lines (9 significant digits read back bit for
    // bit; missing A-scans undefined), so every parameter must be identical.
    test::TempDir dir;
    const auto vol = dir / "onh.vol";
    const auto made = test::run_octshape("phantom onh --shape cupped --bscans 49 --ascans 192 -o '" +
                                         vol.string() + "'");
    ASSERT_EQ(made.exit_code, 0) << made.err;
    const auto xml = (dir / "onh_Surfaces_Iowa.xml").string();
    io::Scan scan = io::read_scan(vol.string(), {.pixels = true});
    std::ofstream(xml) << test::iowa_xml_of(scan);
    // An Iowa file marks an A-scan undefined in every surface: where the export's BM ends (the
    // disc) its ILM is undefined too. The export the result is compared with is the same scan
    // with its ILM removed there as well, so that both analyses see the same lines.
    for (auto& b : scan.bscans) {
        for (std::size_t a = 0; a < b.seg[0].size(); ++a) {
            if (std::isnan(b.seg[1][a])) b.seg[0][a] = std::numeric_limits<float>::quiet_NaN();
        }
    }
    const auto same_lines = dir / "onh_same_lines.vol";
    io::write_vol_file(scan, same_lines.string());
    auto onh = [&](const std::filesystem::path& input, const std::string& extra,
                   const std::string& stem) {
        const auto out = dir / (stem + ".json");
        const auto r = test::run_octshape("onh '" + input.string() + "' --ilm device -o '" +
                                          out.string() + "' " + extra);
        EXPECT_EQ(r.exit_code, 0) << r.err;
        return json::parse(slurp(out));
    };
    const json own = onh(same_lines, "", "own");
    const json over = onh(vol, "--segmentation '" + xml + "'", "over");
    EXPECT_EQ(own["parameters"].dump(), over["parameters"].dump());
    EXPECT_EQ(over["input"]["segmentation"]["sha256"], io::sha256_file(xml));
    EXPECT_NE(own["cohort"]["fingerprint"], over["cohort"]["fingerprint"]);
}

TEST(IowaCli, CohortIgnoresSegmentationFilesBesideTheirExports) {
    // OCTExplorer writes T_Surfaces_Iowa.xml beside T.vol: a cohort over the folder must count
    // the eye once (the export), not twice.
    test::TempDir dir;
    const auto in = dir / "in";
    std::filesystem::create_directories(in);
    std::filesystem::copy_file(test::source_dir() / "sample_scans/macula_bezier_od.vol",
                               in / "T1.vol");
    std::ofstream(in / "T1_Surfaces_Iowa.xml") << test::iowa_xml(test::IowaDoc{});
    const auto out = dir / "out";
    const auto r = test::run_octshape("cohort '" + in.string() + "' -o '" + out.string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto eyes = test::read_csv(out / "eyes.csv");
    EXPECT_EQ(eyes.size(), 2U);  // header + the export
    EXPECT_NE(r.err.find("1 Iowa surfaces file(s) ignored"), std::string::npos) << r.err;
    EXPECT_EQ(test::read_csv(out / "failures.csv").size(), 1U);  // header only
}

TEST(IowaCli, InfoListsTheSurfaces) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    const auto r = test::run_octshape("info --json '" + test::realdata(kIowa).string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json j = json::parse(r.out);
    EXPECT_EQ(j["format"], "Iowa surfaces XML");
    EXPECT_NE(j["format_version"].get<std::string>().find("OCTLayerSeg 3.8.0"), std::string::npos);
    ASSERT_EQ(j["layers"].size(), 11U);
    EXPECT_EQ(j["layers"][0]["name"], "ILM");
    EXPECT_EQ(j["layers"][1]["name"], "BM");
    EXPECT_EQ(j["layers"][2]["name"], "RNFL-GCL");
    EXPECT_EQ(j["layers"][10]["name"], "IB_RPE");
    // 84 of 9728 A-scans undefined.
    EXPECT_NEAR(j["layers"][0]["valid_percent"].get<double>(), 100.0 * (9728 - 84) / 9728, 0.01);
    const auto text = test::run_octshape("info '" + test::realdata(kIowa).string() + "'");
    EXPECT_NE(text.out.find("RNFL-GCL"), std::string::npos) << text.out;
}

// The real Zeiss Cirrus 512 x 128 macular cube segmented by OCTExplorer: the file names the
// manufacturer and the cube is a known Cirrus protocol, so the orientation is the protocol's
// (not flagged as assumed), and the eye's thickness pattern agrees with it.
TEST(IowaCli, RealCirrusCubeInTheProtocolsOrientationWithinCirrusNormativeRanges) {
    SKIP_UNLESS_SHARED("realdata/cirrus_macular_cube_512x128_os_Surfaces_Iowa.xml");
    test::TempDir dir;
    const std::string xml =
        test::realdata("cirrus_macular_cube_512x128_os_Surfaces_Iowa.xml").string();
    const json j = macula_json(xml, "", dir, "cirrus");
    const json& v = j["parameters"];
    for (const auto& [k, x] : v.items()) {
        if (x.is_number()) {
            EXPECT_TRUE(std::isfinite(x.get<double>())) << k;
        }
    }
    const json& e = j["etdrs"]["at_fovea_centre"]["sectors"];
    const double central = e["central"]["thickness_mm"].get<double>();
    std::printf("Cirrus real cube: CFT %.1f um, pit depth %.1f um, central subfield %.1f um, "
                "outer nasal %.1f um, outer temporal %.1f um, RMSE %.2f um\n",
                1e3 * v["cft_mm"].get<double>(), 1e3 * v["pit_depth_mm"].get<double>(),
                1e3 * central, 1e3 * e["outer_nasal"]["thickness_mm"].get<double>(),
                1e3 * e["outer_temporal"]["thickness_mm"].get<double>(),
                v["rmse_um"].get<double>());
    test::expect_whole_grid_at_scan_centre(j, "Cirrus real cube");
    for (const auto& f : j["qc_flags"]) {
        EXPECT_EQ(f.get<std::string>().find("orientation assumed"), std::string::npos) << f;
    }
    EXPECT_EQ(j["scan"]["eye"], "OS");
    // Orientation: in normal eyes the outer nasal subfield is the thicker of the two horizontal
    // outer ones (by ~20-30 um on Cirrus; Hu et al. below); swapped nasal/temporal would invert
    // this.
    EXPECT_GT(e["outer_nasal"]["thickness_mm"].get<double>(),
              e["outer_temporal"]["thickness_mm"].get<double>() + 0.010);
    // Cirrus HD-OCT normal eyes, 192 eyes: central subfield thickness 262.4 +- 22.8 um, proposed
    // normal range 216.8-308 um (Hu AY, Liu T, Kaines A, et al. Normative data for macular
    // thickness and volume measurements using Cirrus HD-OCT. Invest Ophthalmol Vis Sci
    // 2010;51:ARVO E-Abstract 338; checked against the abstract). The BM here is OCTExplorer's
    // outer RPE boundary, not Cirrus's own RPE line.
    EXPECT_GE(central, 0.2168);
    EXPECT_LE(central, 0.308);
    // CFT (the thickness at the pit's bottom): no published Cirrus range for this point value
    // was verified; it is at most the central subfield's mean.
    EXPECT_GT(v["cft_mm"].get<double>(), 0.0);
    EXPECT_LE(v["cft_mm"].get<double>(), central + 1e-9);
    // Pit depth: the device-independent range of docs/algorithms/cube.md, 120 +- 3 x 25 um.
    EXPECT_GE(v["pit_depth_mm"].get<double>(), 0.120 - 3 * 0.025);
    EXPECT_LE(v["pit_depth_mm"].get<double>(), 0.120 + 3 * 0.025);
    EXPECT_LT(v["rmse_um"].get<double>(), 7.1);
}

}  // namespace
}  // namespace octshape
