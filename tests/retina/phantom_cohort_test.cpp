// The cohort phantom (phantom_cohort.h) and the per-eye shape variation it relies on
// (MaculaPhantomParams::thickness_offset_mm, pit_depth_scale).

#include "octshape/retina/phantom_cohort.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "octshape/error.h"
#include "octshape/retina/phantom_macula.h"

namespace octshape::retina {
namespace {

constexpr double kRef = kShapeReferenceMm;

MaculaPhantomParams small(double offset, double scale) {
    MaculaPhantomParams p;
    p.num_bscans = 25;
    p.size_x = 128;
    p.size_z = 160;
    p.wall_radius_mm = 0.0;
    p.tilt_x = 0.005;
    p.tilt_y = -0.005;
    p.pixels = false;
    p.thickness_offset_mm = offset;
    p.pit_depth_scale = scale;
    return p;
}

TEST(MaculaShapeVariation, TruthFollowsTheAffineHeightMap) {
    // y' = y + d + (s - 1)(y - ref): CFT and rim height map like any height, pit depth scales
    // by s, the tangent of each half-line's maximum slope by s, rim radii do not move; an
    // offset alone (s = 1) leaves depth, slopes, the pit-flat radius and the rim diameter (a
    // 3-D distance: the heights of opposite rim points differ, so a scale changes it) exactly
    // unchanged.
    const double d = 0.03;
    const double s = 1.2;
    const MaculaTruth base = macula_truth(small(0.0, 1.0));
    const MaculaTruth m = macula_truth(small(d, s));
    const auto map = [&](double y) { return y + d + (s - 1.0) * (y - kRef); };
    EXPECT_NEAR(m.cft_mm, map(base.cft_mm), 1e-14);
    EXPECT_NEAR(m.rim_height_mm, map(base.rim_height_mm), 1e-14);
    EXPECT_NEAR(m.pit_depth_mm, s * base.pit_depth_mm, 1e-14);
    ASSERT_EQ(m.half_lines.size(), base.half_lines.size());
    for (std::size_t i = 0; i < m.half_lines.size(); ++i) {
        const auto& a = base.half_lines[i];
        const auto& b = m.half_lines[i];
        EXPECT_EQ(b.rim_radius_mm, a.rim_radius_mm);
        const double deg = 180.0 / std::acos(-1.0);
        EXPECT_NEAR(std::tan(b.max_slope_deg / deg), s * std::tan(a.max_slope_deg / deg), 1e-12);
    }
    const MaculaTruth shifted = macula_truth(small(d, 1.0));
    EXPECT_NEAR(shifted.cft_mm, base.cft_mm + d, 1e-15);
    EXPECT_NEAR(shifted.pit_depth_mm, base.pit_depth_mm, 1e-14);
    EXPECT_NEAR(shifted.max_pit_slope_deg, base.max_pit_slope_deg, 1e-12);
    EXPECT_NEAR(shifted.pit_flat_diameter_mm, base.pit_flat_diameter_mm, 1e-12);
    EXPECT_NEAR(shifted.rim.diameter_mm, base.rim.diameter_mm, 1e-12);
    EXPECT_GT(shifted.rim_volume_mm3, base.rim_volume_mm3);
}

TEST(MaculaShapeVariation, ScanThicknessIsTheMappedSurface) {
    // Same seed, no noise: every node's thickness ILM - BM of the varied scan is the affine
    // image of the base scan's (segmentation depths are floats: ~1e-5 px rounding, ~1e-7 mm).
    const double d = -0.02;
    const double s = 0.85;
    const MaculaPhantom a = make_macula_phantom(small(0.0, 1.0));
    const MaculaPhantom b = make_macula_phantom(small(d, s));
    const double sz = a.scan.meta.scale_z_mm;
    int checked = 0;
    for (int k = 0; k < a.scan.num_bscans(); k += 3) {
        for (int x = 0; x < a.scan.meta.size_x; x += 5) {
            const double ta = (a.scan.depth_px(1, k, x) - a.scan.depth_px(0, k, x)) * sz;
            const double tb = (b.scan.depth_px(1, k, x) - b.scan.depth_px(0, k, x)) * sz;
            if (!std::isfinite(ta)) continue;
            EXPECT_NEAR(tb, ta + d + (s - 1.0) * (ta - kRef), 1e-6) << k << " " << x;
            ++checked;
        }
    }
    EXPECT_GT(checked, 200);
}

TEST(MaculaShapeVariation, ValidateNamesTheField) {
    auto p = small(0.2, 1.0);
    try {
        p.validate();
        FAIL() << "offset 0.2 mm accepted";
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("thickness_offset_mm"), std::string::npos);
    }
    p = small(0.0, 1.6);
    EXPECT_THROW(p.validate(), UsageError);
}

TEST(CohortPlan, DesignAsDocumented) {
    CohortPhantomParams cp;
    cp.subjects = 9;
    cp.retest_subjects = 3;
    const CohortPlan plan = plan_macula_cohort(cp);
    // 9 subjects x 2 eyes + 3 subjects x 2 eyes re-scanned.
    ASSERT_EQ(plan.scans.size(), 9U * 2 + 3U * 2);
    std::set<std::string> files;
    std::map<std::pair<int, int>, std::set<double>> scale_by_pair_eye;
    std::map<std::string, int> scans_per_eye;
    for (const auto& s : plan.scans) {
        EXPECT_TRUE(files.insert(s.file_name).second) << s.file_name;
        EXPECT_EQ(s.patient_id.rfind("FAKE-", 0), 0U);
        EXPECT_LE(s.patient_id.size(), 16U);  // the .vol ID field
        const int idx = std::stoi(s.subject_id.substr(1)) - 1;
        EXPECT_EQ(s.group, idx % 2 == 0 ? "control" : "case");
        EXPECT_EQ(s.pair, idx / 2);
        EXPECT_EQ(s.visit_date.size(), 10U);
        const int eye = s.params.eye == io::Laterality::kOD ? 0 : 1;
        scale_by_pair_eye[{s.pair, eye}].insert(s.params.pit_depth_scale);
        ++scans_per_eye[s.subject_id + (eye == 0 ? "OD" : "OS")];
        EXPECT_NO_THROW(s.params.validate());
    }
    // Matched pairs share each eye's pit depth scale (pair 4 has one subject).
    for (const auto& [key, scales] : scale_by_pair_eye) EXPECT_EQ(scales.size(), 1U);
    EXPECT_EQ(scans_per_eye["S001OD"], 2);
    EXPECT_EQ(scans_per_eye["S003OS"], 2);
    EXPECT_EQ(scans_per_eye["S004OD"], 1);
    // Deterministic for a seed; another seed changes the draws.
    const CohortPlan again = plan_macula_cohort(cp);
    EXPECT_EQ(again.manifest.dump(), plan.manifest.dump());
    cp.seed = 2;
    EXPECT_NE(plan_macula_cohort(cp).manifest.dump(), plan.manifest.dump());
    EXPECT_EQ(plan.manifest["nulls"].size(), 2U);
    EXPECT_TRUE(plan.manifest["effects"].contains("cft_mm"));
}

TEST(CohortPlan, GroupEffectOnTheOffsetOnly) {
    // 2000 subjects: the case-minus-control mean offset estimates effect_mm with SE
    // sqrt(12^2 + 4^2/2) um * sqrt(2/1000) = 0.55 um; 2.5 um is 4.5 SE. The pit depth scale has
    // no group difference at all (pairs share it): the means are equal to rounding.
    CohortPhantomParams cp;
    cp.subjects = 2000;
    cp.retest_subjects = 0;
    const CohortPlan plan = plan_macula_cohort(cp);
    double off[2] = {0, 0};
    double scale[2] = {0, 0};
    int n[2] = {0, 0};
    for (const auto& s : plan.scans) {
        const int g = s.group == "case" ? 1 : 0;
        off[g] += s.params.thickness_offset_mm;
        scale[g] += s.params.pit_depth_scale;
        ++n[g];
    }
    EXPECT_NEAR(off[1] / n[1] - off[0] / n[0], cp.effect_mm, 0.0025);
    EXPECT_NEAR(scale[1] / n[1] - scale[0] / n[0], 0.0, 1e-12);
}

TEST(CohortPlan, ValidateNamesTheField) {
    CohortPhantomParams cp;
    cp.subjects = 1;
    EXPECT_THROW((void)plan_macula_cohort(cp), UsageError);
    cp.subjects = 4;
    cp.retest_subjects = 5;
    try {
        (void)plan_macula_cohort(cp);
        FAIL();
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("retest_subjects"), std::string::npos);
    }
}

}  // namespace
}  // namespace octshape::retina
