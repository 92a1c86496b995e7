// `octshape stats` and `octshape phantom cohort` from the command line.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "octshape/io/scan_reader.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

namespace fs = std::filesystem;



// Group "a": eyes 1.0 and 3.0 (S1 OD scanned twice: 1.0 then 1.5); group "b": 4.0, 6.0, 8.0.
// Retest: S1 OD [1.0, 1.5], S3 OD [6.0, 6.25].
const char* kEyes =
    "subject_id,eye,visit_date,scan_type,eye_key,sha256,group,x_mm\n"
    "S1,OD,2024-01-01,macula,0000000000000001,h,a,1.0\n"
    "S1,OD,2024-01-01,macula,0000000000000002,h,a,1.5\n"
    "S1,OS,2024-01-01,macula,0000000000000003,h,a,3.0\n"
    "S2,OD,2024-01-02,macula,0000000000000004,h,b,4.0\n"
    "S3,OD,2024-01-03,macula,0000000000000005,h,b,6.0\n"
    "S3,OD,2024-01-03,macula,0000000000000006,h,b,6.25\n"
    "S3,OS,2024-01-03,macula,0000000000000007,h,b,8.0\n";

TEST(StatsCli, JsonGroupTableAndRetest) {
    TempDir dir;
    spit(dir / "eyes.csv", kEyes);
    const RunResult r = run_octshape("stats " + (dir / "eyes.csv").string() +
                                     " --retest --json -o " + (dir / "table.csv").string() +
                                     " --retest-output " + (dir / "icc.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j["parameters"].size(), 1U);
    const auto& a = j["parameters"][0]["groups"]["a"];
    const auto& b = j["parameters"][0]["groups"]["b"];
    EXPECT_EQ(a["n"], 2);
    EXPECT_NEAR(a["mean"].get<double>(), 2.0, 1e-12);
    EXPECT_NEAR(a["sd"].get<double>(), std::sqrt(2.0), 1e-12);
    EXPECT_EQ(b["n"], 3);
    EXPECT_NEAR(b["mean"].get<double>(), 6.0, 1e-12);
    EXPECT_NEAR(b["sd"].get<double>(), 2.0, 1e-12);
    EXPECT_EQ(b["min"], 4.0);
    EXPECT_EQ(b["max"], 8.0);
    // Retest matrix [[1, 1.5], [6, 6.25]]: row means 1.25, 6.125; column means 3.5, 3.875;
    // grand 3.6875. BMS = 2 * 2 * 2.4375^2 = 23.765625, JMS = 2 * 2 * 0.1875^2 = 0.140625,
    // residuals +-0.0625: EMS = 4 * 0.0625^2 = 0.015625.
    const auto& t = j["retest"]["parameters"][0];
    const double bms = 23.765625;
    const double jms = 0.140625;
    const double ems = 0.015625;
    EXPECT_EQ(t["n_eyes"], 2);
    EXPECT_EQ(t["k"], 2);
    EXPECT_NEAR(t["icc"].get<double>(), (bms - ems) / (bms + ems + (jms - ems)), 1e-12);
    EXPECT_NEAR(t["f"].get<double>(), bms / ems, 1e-9);
    const std::string table = slurp(dir / "table.csv");
    EXPECT_EQ(table.substr(0, table.find('\n')), "parameter,group,n,mean,sd,min,max");
    EXPECT_NE(table.find("\nx_mm,b,3,6,2,4,8\n"), std::string::npos) << table;
    EXPECT_EQ(slurp(dir / "icc.csv").rfind("parameter,n_eyes,k,icc,lower_95,upper_95", 0), 0U);
}

TEST(StatsCli, TextTableHasTheThesisLayout) {
    TempDir dir;
    spit(dir / "eyes.csv", kEyes);
    const RunResult r = run_octshape("stats " + (dir / "eyes.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("a mean (SD)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("6 (2)"), std::string::npos) << r.out;  // group b: mean (SD)
    EXPECT_NE(r.out.find("4 to 8"), std::string::npos) << r.out;  // min to max
}

TEST(StatsCli, NegativeRangesReadAsRanges) {
    TempDir dir;
    spit(dir / "eyes.csv",
         "subject_id,eye,visit_date,scan_type,eye_key,sha256,group,tilt_deg\n"
         "S1,OD,2024-01-01,macula,0000000000000001,h,a,-0.2594\n"
         "S2,OD,2024-01-01,macula,0000000000000002,h,a,-0.125\n");
    const RunResult r = run_octshape("stats " + (dir / "eyes.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("-0.2594 to -0.125"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("--"), std::string::npos) << r.out;
}

TEST(StatsCli, AnIccOverTwoEyesIsFlagged) {
    // kEyes has two re-scanned eyes: the interval rests on F(1, v) quantiles.
    TempDir dir;
    spit(dir / "eyes.csv", kEyes);
    RunResult r = run_octshape("stats --retest " + (dir / "eyes.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find(" *\n"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("* fewer than 10 eyes"), std::string::npos) << r.out;
    EXPECT_NE(r.err.find("only 2 eyes"), std::string::npos) << r.err;
    r = run_octshape("stats --retest --json " + (dir / "eyes.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    const auto& t = j["retest"]["parameters"][0];
    EXPECT_EQ(t["n_eyes"], 2);
    EXPECT_NE(t["warning"].get<std::string>().find("only 2 eyes"), std::string::npos);
}

TEST(StatsCli, LineAndVolumeRowsAreNeverPooled) {
    TempDir dir;
    spit(dir / "eyes.csv",
         "subject_id,eye,visit_date,scan_type,eye_key,sha256,group,analysis,cft_mm\n"
         "S1,OD,2024-01-01,macula,0000000000000001,h,NA,volume,0.2\n"
         "S2,OD,2024-01-01,macula,0000000000000002,h,NA,volume,0.4\n"
         "S3,OD,2024-01-01,macula,0000000000000003,h,NA,line,5.0\n"
         "S4,OD,2024-01-01,macula,0000000000000004,h,NA,radial,0.7\n");
    RunResult r = run_octshape("stats --json " + (dir / "eyes.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["analysis"], "volume");
    // Every group missing: one group "all" (as the help says), not "(none)".
    const auto& all = j["parameters"][0]["groups"]["all"];
    EXPECT_EQ(all["n"], 2);
    EXPECT_NEAR(all["mean"].get<double>(), 0.3, 1e-12);
    EXPECT_NE(r.err.find("1 rows of analysis 'line' left out"), std::string::npos) << r.err;
    // Radial macula rows (the cohort writes `radial`): left out, with the option that takes them.
    EXPECT_NE(r.err.find("1 rows of analysis 'radial' left out (one analysis a table: give "
                         "--analysis radial)"),
              std::string::npos)
        << r.err;
    r = run_octshape("stats --json --analysis radial " + (dir / "eyes.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["analysis"], "radial");
    EXPECT_EQ(j["parameters"][0]["groups"]["all"]["n"], 1);
    EXPECT_EQ(j["parameters"][0]["groups"]["all"]["mean"], 0.7);
    r = run_octshape("stats --json --analysis line " + (dir / "eyes.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["parameters"][0]["groups"]["all"]["n"], 1);
    EXPECT_EQ(j["parameters"][0]["groups"]["all"]["mean"], 5.0);
}

TEST(StatsCli, FailuresTableIsNamedAsSuch) {
    TempDir dir;
    const auto f = (dir / "failures.csv").string();
    spit(f, "file,reason,exit_code\n/x/a.vol,no such file,66\n");
    const RunResult r = run_octshape("stats " + f);
    EXPECT_EQ(r.exit_code, 65);
    EXPECT_EQ(r.err.rfind("octshape: error: " + f + ": corrupt: this is a failures table", 0), 0U)
        << r.err;
    // Another table without the identifiers: the error names the file given.
    const auto o = (dir / "other.csv").string();
    spit(o, "a,b\n1,2\n");
    const RunResult q = run_octshape("stats " + o);
    EXPECT_EQ(q.exit_code, 65);
    EXPECT_EQ(q.err.rfind("octshape: error: " + o + ": ", 0), 0U) << q.err;
}

TEST(StatsCli, ExitCodes) {
    TempDir dir;
    EXPECT_EQ(run_octshape("stats " + (dir / "none.csv").string()).exit_code, 66);
    spit(dir / "bad.csv", "subject_id,eye\nS1\n");
    EXPECT_EQ(run_octshape("stats " + (dir / "bad.csv").string()).exit_code, 65);
    spit(dir / "one.csv",
          "subject_id,eye,visit_date,eye_key,x\nS1,OD,2024-01-01,/a,1\nS2,OD,2024-01-01,/b,2\n");
    EXPECT_EQ(run_octshape("stats " + (dir / "one.csv").string()).exit_code, 0);
    EXPECT_EQ(run_octshape("stats --retest " + (dir / "one.csv").string()).exit_code, 69);
    spit(dir / "eyes.csv", kEyes);
    EXPECT_EQ(run_octshape("stats --retest --sessions 1 " + (dir / "eyes.csv").string()).exit_code,
              64);
}

TEST(PhantomCohortCli, WritesScansMapsAndManifest) {
    TempDir dir;
    const RunResult r = run_octshape("phantom cohort -o " + (dir / "c").string() +
                                     " --subjects 3 --retest-subjects 1 --bscans 13 --ascans 96");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // 3 subjects x 2 eyes + 1 subject's 2 re-scans.
    int vols = 0;
    for (const auto& e : fs::directory_iterator(dir / "c" / "scans")) {
        EXPECT_EQ(e.path().extension(), ".vol");
        EXPECT_TRUE(fs::exists(dir / "c" / "truth" / (e.path().stem().string() + ".truth.json")));
        ++vols;
    }
    EXPECT_EQ(vols, 8);
    EXPECT_EQ(slurp(dir / "c" / "groups.csv"),
              "subject_id,group\nS001,control\nS002,case\nS003,control\n");
    EXPECT_EQ(slurp(dir / "c" / "subjects.csv"),
              "patient_id,subject_id\nFAKE-COHORT-0001,S001\nFAKE-COHORT-0002,S002\n"
              "FAKE-COHORT-0003,S003\n");
    const io::Scan s = io::read_scan((dir / "c" / "scans" / "S002_OS_1.vol").string());
    EXPECT_EQ(s.meta.ids.patient_id, "FAKE-COHORT-0002");
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOS);
    ASSERT_TRUE(s.meta.visit_date_ole.has_value());
    EXPECT_EQ(io::ole_date_to_iso_date(*s.meta.visit_date_ole), "2024-03-21");  // + 7 days
    EXPECT_EQ(s.num_bscans(), 13);
    const auto m = nlohmann::json::parse(slurp(dir / "c" / "manifest.json"));
    EXPECT_EQ(m["subjects"].size(), 3U);
    EXPECT_EQ(m["subjects"][0]["eyes"][0]["files"].size(), 2U);  // S001 OD re-scanned
    EXPECT_EQ(run_octshape("phantom cohort -o " + (dir / "d").string() + " --subjects 1").exit_code,
              64);
}

}  // namespace
}  // namespace octshape::test
