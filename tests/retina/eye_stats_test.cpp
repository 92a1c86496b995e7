// eyes.csv statistics (eye_stats.h) on small hand-made tables whose answers are computed here.

#include "octshape/retina/eye_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

EyeTable parse(const std::string& s) {
    std::istringstream in(s);
    return read_eye_table(in, "test.csv");
}

// Two groups; subject S1 has its OD scanned twice at one visit and once more a week later.
const char* kTable =
    "subject_id,eye,visit_date,scan_type,eye_key,sha256,group,cft_mm,note,qc_flags\n"
    "S1,OD,2024-03-14,macula,/a/s1_od_2.vol,x,ctl,0.230,\"a, b\",\n"
    "S1,OD,2024-03-14,macula,/a/s1_od_1.vol,x,ctl,0.220,,\n"
    "S1,OD,2024-03-21,macula,/a/s1_od_3.vol,x,ctl,0.260,,\n"
    "S1,OS,2024-03-14,macula,/a/s1_os_1.vol,x,ctl,0.240,,\"fit RMSE high\"\n"
    "S2,OD,2024-03-15,macula,/a/s2_od_1.vol,x,case,0.250,,\n"
    "S2,OD,2024-03-15,macula,/a/s2_od_2.vol,x,case,0.254,,\n"
    "S2,OS,2024-03-15,macula,/a/s2_os_1.vol,x,case,NA,,\n"
    "S3,OD,2024-03-16,macula,/a/s3_od_1.vol,x,case,0.270,\"q\"\"uote\",\n"
    "S3,OS,2024-03-16,macula,/a/s3_os_1.vol,x,NA,0.280,,\n";

TEST(EyeTable, ParsesQuotesAndMissing) {
    const EyeTable t = parse(kTable);
    ASSERT_EQ(t.header.size(), 10U);
    ASSERT_EQ(t.rows.size(), 9U);
    EXPECT_EQ(t.rows[0][8], "a, b");
    EXPECT_EQ(t.rows[7][8], "q\"uote");
    EXPECT_EQ(t.rows[3][9], "fit RMSE high");
    EXPECT_EQ(t.column("cft_mm"), 7);
    EXPECT_EQ(t.column("nope"), -1);
    EXPECT_TRUE(is_missing_field("NA"));
    EXPECT_TRUE(is_missing_field(""));
    EXPECT_FALSE(is_missing_field("0"));
    // Only cft_mm is numeric: note and qc_flags hold text, the identifiers never count.
    EXPECT_EQ(numeric_columns(t, "group"), std::vector<std::string>{"cft_mm"});
}

TEST(EyeTable, CrlfAndQuotedNewline) {
    const EyeTable t = parse("a,b\r\n1,\"x\ny\"\r\n2,z\r\n");
    ASSERT_EQ(t.rows.size(), 2U);
    EXPECT_EQ(t.rows[0][1], "x\ny");
    EXPECT_EQ(t.rows[1][0], "2");
}

TEST(EyeTable, RejectsMalformed) {
    EXPECT_THROW((void)parse(""), InputError);
    EXPECT_THROW((void)parse("a,b\n1,2,3\n"), InputError);   // ragged row
    EXPECT_THROW((void)parse("a,b\n1,\"2\n"), InputError);   // unterminated quote
    EXPECT_THROW((void)parse("a,a\n1,2\n"), InputError);     // duplicate column
    EXPECT_THROW((void)parse("a,,b\n1,2,3\n"), InputError);  // empty column name
    EXPECT_THROW((void)read_eye_table_file("/nonexistent/eyes.csv"), InputError);
}

TEST(GroupStats, FirstScanPerEye) {
    const GroupStats g = group_stats(parse(kTable), {});
    // Groups sorted by name: "(none)" (S3 OS), case, ctl.
    ASSERT_EQ(g.groups.size(), 3U);
    EXPECT_EQ(g.groups[0].name, "(none)");
    EXPECT_EQ(g.groups[1].name, "case");
    EXPECT_EQ(g.groups[2].name, "ctl");
    EXPECT_EQ(g.groups[1].eyes, 3U);  // S2 OD, S2 OS, S3 OD
    EXPECT_EQ(g.groups[1].subjects, 2U);
    EXPECT_EQ(g.groups[2].rows, 2U);  // S1 OD (first scan only), S1 OS
    ASSERT_EQ(g.parameters.size(), 1U);
    const auto& p = g.parameters[0].per_group;
    // ctl: S1 OD's first scan by visit then eye key is s1_od_1 (0.220), S1 OS 0.240.
    EXPECT_EQ(p[2].n, 2U);
    EXPECT_NEAR(p[2].mean, 0.230, 1e-15);
    EXPECT_NEAR(p[2].sd, std::sqrt(2 * 0.01 * 0.01), 1e-15);
    EXPECT_EQ(p[2].min, 0.220);
    EXPECT_EQ(p[2].max, 0.240);
    // case: 0.250 and 0.270 (S2 OS is NA).
    EXPECT_EQ(p[1].n, 2U);
    EXPECT_NEAR(p[1].mean, 0.260, 1e-15);
    EXPECT_EQ(p[0].n, 1U);
    EXPECT_EQ(p[0].mean, 0.280);
}

TEST(GroupStats, AllScansAndNoGroupColumn) {
    GroupStatsParams gp;
    gp.all_scans = true;
    gp.group_column = "cohort_arm";  // absent: one group "all"
    const GroupStats g = group_stats(parse(kTable), gp);
    ASSERT_EQ(g.groups.size(), 1U);
    EXPECT_EQ(g.groups[0].name, "all");
    EXPECT_EQ(g.groups[0].rows, 9U);
    EXPECT_EQ(g.groups[0].eyes, 6U);
    EXPECT_EQ(g.groups[0].subjects, 3U);
    EXPECT_EQ(g.parameters[0].per_group[0].n, 8U);  // one NA
}

TEST(RetestStats, AnyVisitUsesTheFewestScansOfARepeatedEye) {
    // Repeated eyes: S1 OD (3 scans) and S2 OD (2): k = 2, S1 OD's first two scans by
    // visit then eye key are 0.220 (s1_od_1) and 0.230 (s1_od_2). Matrix [[0.22, 0.23],
    // [0.25, 0.254]]: hand-computed ANOVA below.
    const RetestStats r = retest_stats(parse(kTable), {}, "group");
    EXPECT_EQ(r.k, 2);
    EXPECT_EQ(r.repeated_eyes, 2U);
    EXPECT_EQ(r.eyes_used, 2U);
    ASSERT_EQ(r.parameters.size(), 1U);
    const IccResult& i = r.parameters[0].icc;
    EXPECT_EQ(i.n, 2);
    // Row means 0.225, 0.252; column means 0.235, 0.242; grand 0.2385.
    // BMS = 2 * ((0.225-0.2385)^2 + (0.252-0.2385)^2) = 7.29e-4; JMS = 2 * 2 * 0.0035^2 =
    // 4.9e-5; residuals +-0.0015 -> SSE = 4 * 0.0015^2 = 9e-6 = EMS.
    EXPECT_NEAR(i.ms_rows, 7.29e-4, 1e-15);
    EXPECT_NEAR(i.ms_cols, 4.9e-5, 1e-15);
    EXPECT_NEAR(i.ms_error, 9e-6, 1e-15);
    EXPECT_NEAR(i.icc, (7.29e-4 - 9e-6) / (7.29e-4 + 9e-6 + 2 * (4.9e-5 - 9e-6) / 2), 1e-12);
}

TEST(RetestStats, SameVisitAndExplicitSessions) {
    RetestParams p;
    p.same_visit = true;  // S1 OD's third scan is another visit: not a repeat of the first two
    const RetestStats r = retest_stats(parse(kTable), p, "group");
    EXPECT_EQ(r.repeated_eyes, 2U);
    EXPECT_EQ(r.k, 2);
    RetestParams three;
    three.sessions = 3;  // only S1 OD has 3 scans: one eye, no ICC
    const RetestStats r3 = retest_stats(parse(kTable), three, "group");
    EXPECT_EQ(r3.eyes_used, 1U);
    EXPECT_TRUE(std::isnan(r3.parameters[0].icc.icc));
    RetestParams bad;
    bad.sessions = 1;
    EXPECT_THROW((void)retest_stats(parse(kTable), bad, "group"), UsageError);
}

TEST(RetestStats, NoRepeatsIsAnAnalysisError) {
    EXPECT_THROW((void)retest_stats(parse("subject_id,eye,visit_date,eye_key,x\nS1,OD,d,f,1\n"
                                          "S1,OS,d,g,2\n"),
                                    {}, "group"),
                 AnalysisError);
    EXPECT_THROW((void)group_stats(parse("eye,x\nOD,1\n"), {}), InputError);
}

}  // namespace
}  // namespace octshape::retina
