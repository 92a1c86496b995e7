#include "octshape/retina/scan_geometry.h"

#include <gtest/gtest.h>

namespace octshape::retina {
namespace {

// A horizontal volume laid out as Spectralis does: A-scans left to right on the SLO, B-scan 0
// lowest (largest SLO y), spacing `gap` mm.
io::Scan volume(io::Laterality eye, int n, double gap, bool first_inferior = true) {
    io::Scan s;
    s.meta.laterality = eye;
    s.meta.pattern = io::ScanPattern::kVolume;
    s.meta.size_x = 768;
    s.meta.scale_x_mm = 0.0117;
    s.meta.scale_z_mm = 0.0038717;
    s.meta.distance_mm = gap;
    for (int b = 0; b < n; ++b) {
        io::BScan bs;
        const double y = first_inferior ? 7.0 - b * gap : 1.0 + b * gap;
        bs.start_x_mm = 1.0;
        bs.end_x_mm = 1.0 + 767 * 0.0117;
        bs.start_y_mm = bs.end_y_mm = y;
        s.bscans.push_back(bs);
    }
    return s;
}

TEST(ScanGeometry, HeightIsMinusDepth) {
    const ScanGeometry g(volume(io::Laterality::kOD, 3, 0.125));
    EXPECT_DOUBLE_EQ(g.z_mm(100.0), -100.0 * 0.0038717);
    EXPECT_DOUBLE_EQ(g.x_mm(10.0), 10.0 * 0.0117);
    EXPECT_DOUBLE_EQ(g.y_mm(2.0), 0.25);
}

TEST(ScanGeometry, RightEyeXIsNasalYIsSuperior) {
    const ScanGeometry g(volume(io::Laterality::kOD, 61, 0.125));
    EXPECT_TRUE(g.oriented_from_positions());
    EXPECT_TRUE(g.x_is_nasal());
    EXPECT_TRUE(g.y_is_superior());
    EXPECT_NEAR(g.anatomical_angle_deg(1, 0), 0.0, 1e-9);
    EXPECT_NEAR(g.anatomical_angle_deg(0, 1), 90.0, 1e-9);
    EXPECT_NEAR(g.anatomical_angle_deg(-1, 0), 180.0, 1e-9);
    EXPECT_NEAR(g.anatomical_angle_deg(0, -1), 270.0, 1e-9);
}

TEST(ScanGeometry, LeftEyeIsMirrored) {
    const ScanGeometry g(volume(io::Laterality::kOS, 61, 0.125));
    EXPECT_FALSE(g.x_is_nasal());  // OS: first A-scan nasal, so +x is temporal
    EXPECT_TRUE(g.y_is_superior());
    EXPECT_NEAR(g.anatomical_angle_deg(-1, 0), 0.0, 1e-9);
    EXPECT_NEAR(g.anatomical_angle_deg(1, 1), 135.0, 1e-9);
}

TEST(ScanGeometry, FirstBscanSuperiorFlipsY) {
    const ScanGeometry g(volume(io::Laterality::kOD, 61, 0.125, /*first_inferior=*/false));
    EXPECT_FALSE(g.y_is_superior());
    EXPECT_NEAR(g.anatomical_angle_deg(0, 1), 270.0, 1e-9);
}

TEST(ScanGeometry, SloRoundTrip) {
    const ScanGeometry g(volume(io::Laterality::kOD, 61, 0.125));
    const Eigen::Vector2d p(2.5, 3.0);
    const Eigen::Vector2d back = g.slo_to_grid(g.grid_to_slo(p));
    EXPECT_NEAR(back.x(), p.x(), 1e-12);
    EXPECT_NEAR(back.y(), p.y(), 1e-12);
    // Grid (0, 3 mm) is 3 mm above the first B-scan on the SLO.
    EXPECT_NEAR(g.grid_to_slo(Eigen::Vector2d(0, 3)).y(), 7.0 - 3.0, 1e-12);
}

TEST(ScanGeometry, UniformSpacingAccepted) {
    const ScanGeometry g(volume(io::Laterality::kOD, 61, 0.125));
    const auto& s = g.spacing();
    EXPECT_TRUE(s.positions_known);
    EXPECT_EQ(s.num_gaps, 60);
    EXPECT_NEAR(s.mean_mm, 0.125, 1e-12);
    EXPECT_TRUE(s.uniform);
    EXPECT_TRUE(s.matches_header);
}

TEST(ScanGeometry, MissingBscanIsReportedAsNonUniform) {
    io::Scan s = volume(io::Laterality::kOD, 61, 0.125);
    s.bscans.erase(s.bscans.begin() + 30);  // a dropped B-scan doubles one gap
    const ScanGeometry g(s);
    EXPECT_FALSE(g.spacing().uniform);
    EXPECT_NEAR(g.spacing().max_mm, 0.25, 1e-12);
}

TEST(ScanGeometry, HeaderDistanceDisagreeingWithPositionsIsReported) {
    io::Scan s = volume(io::Laterality::kOD, 61, 0.125);
    s.meta.distance_mm = 0.25;
    const ScanGeometry g(s);
    EXPECT_TRUE(g.spacing().uniform);
    EXPECT_FALSE(g.spacing().matches_header);
}

TEST(ScanGeometry, NoPositionsFallsBackToDocumentedDefault) {
    io::Scan s = volume(io::Laterality::kOD, 5, 0.125);
    for (auto& b : s.bscans) b.start_x_mm = b.start_y_mm = b.end_x_mm = b.end_y_mm = 0.0;
    const ScanGeometry g(s);
    EXPECT_FALSE(g.oriented_from_positions());
    EXPECT_FALSE(g.spacing().positions_known);
    EXPECT_TRUE(g.x_is_nasal());
    EXPECT_TRUE(g.y_is_superior());
}

TEST(ScanGeometry, IdenticalBscanPositionsDoNotOrientAVolume) {
    // Every B-scan at the first one's place: the lines' direction is known, the volume's is not
    // (a copy-pasted header, a broken export): the orientation is assumed, and says so.
    io::Scan s = volume(io::Laterality::kOD, 5, 0.125);
    for (auto& b : s.bscans) b = s.bscans.front();
    const ScanGeometry g(s);
    EXPECT_FALSE(g.oriented_from_positions());
    EXPECT_FALSE(g.spacing().positions_known);
    EXPECT_TRUE(g.x_is_nasal());
    EXPECT_TRUE(g.y_is_superior());
    // One B-scan (a line scan) at its position is oriented by it.
    s.bscans.resize(1);
    s.meta.pattern = io::ScanPattern::kLine;
    EXPECT_TRUE(ScanGeometry(s).oriented_from_positions());
}

}  // namespace
}  // namespace octshape::retina
