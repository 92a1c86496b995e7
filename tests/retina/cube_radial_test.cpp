// Radial scans: the lines' geometry (retina/radial_geometry.h) on hand-made positions, the
// radial macula phantom against its generating surface, and the CuBe radial path against the
// phantoms' truth (phantom_macula.h), which never sees the analysis code.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <numbers>
#include <sstream>

#include "octshape/error.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/cube_report.h"
#include "octshape/retina/phantom_macula.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/scan_summary.h"

namespace octshape::retina {
namespace {

using V2 = Eigen::Vector2d;
constexpr double kPi = std::numbers::pi;

// n lines of length len through the SLO point c, line k at k * 180 / n deg from SLO +x towards
// up (SLO -y), each shifted across itself by shift[k] mm.
io::Scan star(int n, double len, V2 c, io::Laterality eye, std::vector<double> shift = {}) {
    io::Scan s;
    s.meta.pattern = io::ScanPattern::kRadial;
    s.meta.size_x = 768;
    s.meta.scale_x_mm = len / 767;
    s.meta.laterality = eye;
    for (int k = 0; k < n; ++k) {
        const double phi = kPi * k / n;
        const V2 u(std::cos(phi), -std::sin(phi));  // SLO y is down
        const V2 across(-u.y(), u.x());
        const double d = shift.empty() ? 0.0 : shift[static_cast<std::size_t>(k)];
        io::BScan b;
        const V2 a = c - 0.5 * len * u + d * across;
        const V2 e = c + 0.5 * len * u + d * across;
        b.start_x_mm = a.x();
        b.start_y_mm = a.y();
        b.end_x_mm = e.x();
        b.end_y_mm = e.y();
        s.bscans.push_back(b);
    }
    return s;
}

TEST(RadialGeometry, CrossingAnglesAndStepsOfARegularStar) {
    const V2 c(4.1, 3.7);
    for (const auto eye : {io::Laterality::kOD, io::Laterality::kOS}) {
        const RadialGeometry g = radial_geometry(star(12, 6.0, c, eye));
        ASSERT_EQ(g.lines.size(), 12U);
        EXPECT_NEAR((g.crossing_slo_mm - c).norm(), 0.0, 1e-12);
        EXPECT_NEAR(g.max_miss_mm, 0.0, 1e-12);
        EXPECT_TRUE(g.lines_cross);
        EXPECT_TRUE(g.regular);
        EXPECT_NEAR(g.nominal_step_deg, 15.0, 1e-12);
        EXPECT_NEAR(g.min_step_deg, 15.0, 1e-9);
        EXPECT_NEAR(g.max_step_deg, 15.0, 1e-9);
        EXPECT_NEAR(g.mean_length_mm, 6.0, 1e-12);
        // Line 0 runs SLO left -> right: nasal (0 deg) for OD, temporal (180 deg) for OS. Line 3
        // (45 deg towards up on the SLO) points superonasal for OD (45 deg), superotemporal for
        // OS (135 deg): up on the fundus is superior for both eyes.
        const bool od = eye == io::Laterality::kOD;
        EXPECT_NEAR(g.lines[0].angle_deg, od ? 0.0 : 180.0, 1e-9);
        EXPECT_NEAR(g.lines[3].angle_deg, od ? 45.0 : 135.0, 1e-9);
        EXPECT_NEAR(g.lines[6].angle_deg, od ? 90.0 : 90.0, 1e-9);
        // The A-scan in the middle of every line is the crossing (radial frame origin).
        for (int k = 0; k < 12; ++k) EXPECT_NEAR(g.ascan_mm(k, 383.5, 768).norm(), 0.0, 1e-12);
    }
}

TEST(RadialGeometry, MissesAndIrregularStepsAreMeasured) {
    // Line 5 shifted 40 um across itself: least squares puts the crossing where the sum of
    // squared misses is least; with 12 lines 15 deg apart the shift spreads so that line 5
    // misses by most and the rest by less, every miss below 40 um, and all misses sum to a
    // projection of the 40 um (checked: the largest miss is line 5's).
    std::vector<double> shift(12, 0.0);
    shift[5] = 0.040;
    const RadialGeometry g = radial_geometry(star(12, 6.0, V2(4, 4), io::Laterality::kOD, shift));
    EXPECT_GT(g.max_miss_mm, 0.02);
    EXPECT_LT(g.max_miss_mm, 0.040);
    for (const auto& l : g.lines) EXPECT_LE(l.miss_mm, g.lines[5].miss_mm + 1e-12);
    EXPECT_FALSE(g.lines_cross);  // 40 um > one A-scan (7.8 um)
    // A missing line (11 of 12): one step of 30 deg, named.
    io::Scan s = star(12, 6.0, V2(4, 4), io::Laterality::kOD);
    s.bscans.erase(s.bscans.begin() + 4);
    const RadialGeometry h = radial_geometry(s);
    EXPECT_FALSE(h.regular);
    EXPECT_NEAR(h.max_step_deg, 30.0, 1e-9);
    ASSERT_EQ(h.irregular_steps.size(), 11U);  // nominal 180/11: every step is off by > 2 %
    // Parallel lines cross nowhere; one line cannot cross.
    io::Scan par = star(2, 6.0, V2(4, 4), io::Laterality::kOD);
    par.bscans[1] = par.bscans[0];
    par.bscans[1].start_y_mm += 0.1;
    par.bscans[1].end_y_mm += 0.1;
    EXPECT_THROW((void)radial_geometry(par), AnalysisError);
    io::Scan one = star(1, 6.0, V2(4, 4), io::Laterality::kOD);
    EXPECT_THROW((void)radial_geometry(one), AnalysisError);

    // The lines' QC (the same for the macula and the ONH analyses): a stable flag each, the
    // numbers in the notes.
    const auto has = [](const std::vector<std::string>& v, const std::string& text) {
        return std::any_of(v.begin(), v.end(),
                           [&](const std::string& x) { return x.find(text) != std::string::npos; });
    };
    const RadialGeometryQc ok = radial_geometry_qc(radial_geometry(star(12, 6.0, V2(4, 4),
                                                                        io::Laterality::kOD)));
    EXPECT_TRUE(ok.flags.empty());
    EXPECT_TRUE(ok.notes.empty());
    const RadialGeometryQc missed = radial_geometry_qc(g);
    ASSERT_EQ(missed.flags.size(), 1U);
    EXPECT_EQ(missed.flags[0], "radial lines miss their crossing");
    std::ostringstream miss;
    miss.setf(std::ios::fixed);
    miss.precision(1);
    miss << 1e3 * g.max_miss_mm << " um";
    EXPECT_TRUE(has(missed.notes, miss.str())) << miss.str();
    const RadialGeometryQc uneven = radial_geometry_qc(h);
    ASSERT_EQ(uneven.flags.size(), 1U);
    EXPECT_EQ(uneven.flags[0], "radial angular steps irregular");
    EXPECT_TRUE(has(uneven.notes, "to 30.00 deg (nominal 16.36)"));
    EXPECT_EQ(uneven.notes.size(), 1U + h.irregular_steps.size());
    io::Scan with_fields = star(12, 6.0, V2(4, 4), io::Laterality::kOD);
    with_fields.bscans[2].bmo = io::BmoFields{};
    EXPECT_TRUE(has(radial_geometry_qc(radial_geometry(with_fields)).notes,
                    "BMO fields present in 1 B-scans: not used"));
}

TEST(RadialGeometry, SummaryDescribesTheStarNotParallelLines) {
    const nlohmann::json j = scan_summary(star(24, 6.0, V2(4, 4), io::Laterality::kOS));
    ASSERT_TRUE(j.contains("radial"));
    EXPECT_FALSE(j.contains("bscan_spacing"));
    EXPECT_FALSE(j.contains("volume_height_mm"));
    EXPECT_EQ(j["radial"]["num_lines"], 24);
    EXPECT_NEAR(j["radial"]["angular_step_deg"].get<double>(), 7.5, 1e-9);
    EXPECT_TRUE(j["radial"]["regular"].get<bool>());
    EXPECT_FALSE(j["radial"]["bmo_fields"]["used"].get<bool>());
}

// ---- the radial phantom ---------------------------------------------------------------------

MaculaPhantomParams radial_params(MaculaFamily f, int lines, double off_um, double off_deg,
                                  io::Laterality eye = io::Laterality::kOD) {
    MaculaPhantomParams p;
    p.family = f;
    p.radial = true;
    p.radial_lines = lines;
    p.eye = eye;
    p.pixels = false;
    const double th = off_deg * kPi / 180.0;
    const double nasal_x = eye == io::Laterality::kOS ? -1.0 : 1.0;
    p.fovea_dx_mm = 1e-3 * off_um * std::cos(th) * nasal_x;
    p.fovea_dy_mm = 1e-3 * off_um * std::sin(th);
    return p;
}

TEST(RadialPhantom, LinesCrossAtTheFieldCentreAndSampleTheSameEye) {
    const MaculaPhantomParams p = radial_params(MaculaFamily::kBezier, 12, 50.0, 30.0);
    const MaculaPhantom ph = make_macula_phantom(p);
    EXPECT_EQ(ph.scan.meta.pattern, io::ScanPattern::kRadial);
    ASSERT_EQ(ph.scan.num_bscans(), 12);
    const RadialGeometry g = radial_geometry(ph.scan);
    // The crossing on the SLO is the truth frame's centre (L/2, L/2).
    EXPECT_NEAR((g.crossing_slo_mm - ph.frame.to_slo(V2(3.0, 3.0))).norm(), 0.0, 1e-9);
    EXPECT_LT(g.max_miss_mm, 1e-9);
    EXPECT_TRUE(g.regular);
    // Thickness ILM - BM at every A-scan is the generating surface at that A-scan's point, the
    // point the volume phantom's code evaluates too (macula_sample_points): f32 depths at
    // 3.87 um per pixel round to < 1e-4 px, i.e. < 1 nm; 2e-6 mm allows for both lines.
    const std::vector<V2> pts = macula_sample_points(p);
    const double sz = ph.scan.meta.scale_z_mm;
    for (int b = 0; b < 12; ++b) {
        for (int a = 0; a < 768; a += 37) {
            const V2 q = pts[static_cast<std::size_t>(b) * 768 + static_cast<std::size_t>(a)];
            // The point lies on its B-scan's line, at its A-scan.
            const V2 on = g.ascan_mm(b, a, 768) + V2(3.0, 3.0);
            EXPECT_NEAR((on - q).norm(), 0.0, 1e-9);
            const V2 d = q - ph.centre_mm;
            const double th = ph.frame.anatomical_angle_deg(d.x(), d.y());
            const auto& bs = ph.scan.bscans[static_cast<std::size_t>(b)];
            const double m = (bs.seg[1][static_cast<std::size_t>(a)] -
                              bs.seg[0][static_cast<std::size_t>(a)]) * sz;
            EXPECT_NEAR(m, macula_thickness_mm(p, d.norm(), th), 2e-6);
        }
    }
    // Truth: one half-line per line direction, 360 / (2 x 12) deg apart.
    EXPECT_EQ(ph.truth.half_lines.size(), 24U);
}

// ---- CuBe on radial scans -----------------------------------------------------------------

struct RadialErrors {
    double centre = 0, cft = 0, rim_height = 0, rim_diameter = 0, rim_area_rel = 0,
           slope_diameter = 0, slope_deg = 0, flat_diameter = 0, vr_rel = 0, vir_rel = 0,
           vp_rel = 0;
};

RadialErrors radial_errors(const CubeResult& r, const MaculaPhantom& ph) {
    const MaculaTruth& t = ph.truth;
    RadialErrors e;
    // The analysis reports the centre in the radial frame (mm from the crossing); the truth
    // frame's crossing is the field centre (L/2, L/2) = (3, 3) mm.
    e.centre = (r.centre_mm + V2(3.0, 3.0) - ph.centre_mm).norm();
    e.cft = std::fabs(r.cft_mm - t.cft_mm);
    e.rim_height = std::fabs(r.rim_height_mm - t.rim_height_mm);
    e.rim_diameter = std::fabs(r.rim.diameter_mm - t.rim.diameter_mm);
    e.rim_area_rel = std::fabs(r.rim.area_mm2 / t.rim.area_mm2 - 1.0);
    e.slope_diameter = std::fabs(r.slope.diameter_mm - t.slope.diameter_mm);
    e.slope_deg = std::fabs(r.max_pit_slope_deg - t.max_pit_slope_deg);
    e.flat_diameter = std::fabs(r.pit_flat_diameter_mm - t.pit_flat_diameter_mm);
    e.vr_rel = std::fabs(r.rim_volume_mm3 / t.rim_volume_mm3 - 1.0);
    e.vir_rel = std::fabs(r.inner_rim_volume_mm3 / t.inner_rim_volume_mm3 - 1.0);
    e.vp_rel = std::fabs(r.pit_volume_mm3 / t.pit_volume_mm3 - 1.0);
    return e;
}

// The volume analysis's accuracy targets (tests/retina/cube_test.cpp
// CubePhantom.ScheibeWithinOnePercentAt193): 1 % of each value, lengths at least 2 um (where
// 1 % is below the 2 um a ScaleX of 7.8-11.7 um can resolve with sub-sample fits), the slope
// 0.2 deg. A radial scan samples each half-line at the A-scans (7.8 um at 768 over 6 mm), finer
// than a 193-B-scan volume's bilinear samples (39 um across), so the same targets apply. The
// Scheibe pit-flat diameter is the model's limit (a cubic cannot follow Scheibe's pit floor:
// 1-17 %, docs/algorithms/cube.md), as for volumes.
void expect_within_volume_targets(const RadialErrors& e, const MaculaTruth& t, bool scheibe) {
    auto tol = [](double v) { return std::max(0.01 * std::fabs(v), 0.002); };
    EXPECT_LE(e.cft, tol(t.cft_mm));
    EXPECT_LE(e.rim_height, tol(t.rim_height_mm));
    EXPECT_LE(e.rim_diameter, tol(t.rim.diameter_mm));
    EXPECT_LE(e.rim_area_rel, 0.01);
    EXPECT_LE(e.slope_diameter, tol(t.slope.diameter_mm));
    EXPECT_LE(e.slope_deg, 0.2);
    EXPECT_LE(e.vr_rel, 0.01);
    EXPECT_LE(e.vir_rel, 0.01);
    EXPECT_LE(e.vp_rel, 0.01);
    EXPECT_LE(e.flat_diameter, scheibe ? 0.17 * t.pit_flat_diameter_mm : tol(t.pit_flat_diameter_mm));
}

std::string row(const std::string& tag, const RadialErrors& e) {
    std::ostringstream s;
    s << std::fixed << std::setprecision(2) << std::setw(24) << std::left << tag << std::right
      << " centre " << std::setw(6) << e.centre * 1e3 << " um  cft " << std::setw(5)
      << e.cft * 1e3 << " um  rim_h " << std::setw(5) << e.rim_height * 1e3 << " um  rim_d "
      << std::setw(5) << e.rim_diameter * 1e3 << " um  slope " << std::setw(5) << e.slope_deg
      << " deg  flat_d " << std::setw(6) << e.flat_diameter * 1e3 << " um  Vr "
      << std::setw(5) << e.vr_rel * 100 << " %  Vir " << std::setw(5) << e.vir_rel * 100
      << " %  Vp " << std::setw(5) << e.vp_rel * 100 << " %";
    return s.str();
}

TEST(CubeRadial, TwelveAndTwentyFourLinesWithinTheVolumeTargets) {
    // The crossing on the fovea (every line through it; the centre is still searched), and
    // 20 um from it in an oblique direction so that no line passes through the fovea: within
    // the QC limit, where every parameter meets the volume targets.
    for (const auto f : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        for (const int lines : {12, 24}) {
            for (const auto eye : {io::Laterality::kOD, io::Laterality::kOS})
            for (const double off : {0.0, 20.0}) {
                const MaculaPhantom ph = make_macula_phantom(radial_params(f, lines, off, 37.0, eye));
                const CubeResult r = analyse_macula(ph.scan);
                const std::string tag = to_string(f) + " " + std::to_string(lines) + " lines " +
                                        (eye == io::Laterality::kOS ? "OS " : "OD ") +
                                        std::to_string(static_cast<int>(off)) + " um";
                SCOPED_TRACE(tag);
                EXPECT_TRUE(r.radial_scan);
                ASSERT_EQ(r.half_lines.size(), static_cast<std::size_t>(2 * lines));
                for (std::size_t i = 0; i < r.half_lines.size(); ++i) {
                    EXPECT_NEAR(r.half_lines[i].angle_deg, ph.truth.half_lines[i].angle_deg, 1e-6);
                }
                const RadialErrors e = radial_errors(r, ph);
                std::cout << row(tag, e) << '\n';
                expect_within_volume_targets(e, ph.truth, f == MaculaFamily::kScheibe);
                EXPECT_TRUE(r.qc_flags.empty()) << r.qc_flags.front();
            }
        }
    }
}

TEST(CubeRadial, CrossingOffsetTableAndItsQcFlag) {
    // The parameters' error against the crossing offset (fovea minus crossing, 0-150 um, in
    // the direction where it hurts most among 0/45/90 deg: the largest error of the three is
    // printed). The QC limit radial_offset_limit_mm() is the largest offset at which every
    // parameter stays within the volume targets (docs/algorithms/cube.md "Radial scans").
    std::cout << "crossing offset table (Bezier and Scheibe, 12 lines, OD; worst of 0/45/90 deg)\n";
    for (const auto f : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        for (const double off : {0.0, 25.0, 50.0, 75.0, 100.0, 125.0, 150.0}) {
            RadialErrors worst;
            bool flagged = false;
            double limit = 0.0;
            for (const double dir : {0.0, 45.0, 90.0}) {
                const MaculaPhantom ph = make_macula_phantom(radial_params(f, 12, off, dir));
                const CubeResult r = analyse_macula(ph.scan);
                limit = r.radial.centre_offset_limit_mm;
                const RadialErrors e = radial_errors(r, ph);
                for (auto m : {&RadialErrors::centre, &RadialErrors::cft, &RadialErrors::rim_height,
                               &RadialErrors::rim_diameter, &RadialErrors::rim_area_rel,
                               &RadialErrors::slope_diameter, &RadialErrors::slope_deg,
                               &RadialErrors::flat_diameter, &RadialErrors::vr_rel,
                               &RadialErrors::vir_rel, &RadialErrors::vp_rel}) {
                    worst.*m = std::max(worst.*m, e.*m);
                }
                const bool has = std::find(r.qc_flags.begin(), r.qc_flags.end(),
                                           "centre off the line crossing") != r.qc_flags.end();
                flagged = flagged || has;
                // The flag follows the measured offset: raised exactly beyond the limit.
                EXPECT_EQ(has, r.radial.centre_offset_distance_mm > limit);
            }
            std::cout << row(to_string(f) + " " + std::to_string(static_cast<int>(off)) + " um",
                             worst)
                      << (flagged ? "  [flagged]" : "") << '\n';
            // Up to the limit every parameter meets the volume targets (in every direction:
            // `worst`).
            if (off * 1e-3 <= limit + 1e-12) {
                const MaculaPhantom ph = make_macula_phantom(radial_params(f, 12, off, 0.0));
                SCOPED_TRACE(off);
                expect_within_volume_targets(worst, ph.truth, f == MaculaFamily::kScheibe);
            }
        }
    }
}

TEST(CubeRadial, ReportCarriesTheCrossingOffsetAndItsFlag) {
    // 60 um from the crossing towards superior: beyond the 25 um limit, flagged; the JSON
    // reports the offset the analysis measured (within the centre's error, < 15 um at 60 um in
    // the table) and the CSV names the analysis.
    const MaculaPhantom ph = make_macula_phantom(radial_params(MaculaFamily::kBezier, 12, 60.0, 90.0));
    const CubeParams cp;
    const CubeResult r = analyse_macula(ph.scan, cp);
    EXPECT_NE(std::find(r.qc_flags.begin(), r.qc_flags.end(), "centre off the line crossing"),
              r.qc_flags.end());
    const auto j = cube_json(r, cp, nlohmann::ordered_json::object());
    EXPECT_EQ(j["radial"]["num_lines"], 12);
    EXPECT_NEAR(j["radial"]["centre_offset_distance_mm"].get<double>(), 0.060, 0.015);
    EXPECT_EQ(j["radial"]["centre_offset_limit_mm"].get<double>(), 0.025);
    EXPECT_FALSE(j["radial"]["bmo_fields"]["used"].get<bool>());
    EXPECT_EQ(j["sampling"]["half_lines"], 24);
    EXPECT_EQ(j["radial"]["half_line_feet_mm"].size(), 24U);
    EXPECT_EQ(cube_csv_values(r).front(), "radial");
}

TEST(CubeRadial, LinesShorterThanTwoHalfLinesAreRefused) {
    MaculaPhantomParams p = radial_params(MaculaFamily::kBezier, 6, 0.0, 0.0);
    p.line_length_mm = 4.0;
    const MaculaPhantom ph = make_macula_phantom(p);
    CubeParams cp;
    cp.radius_mm = 2.5;  // 2 x 2.5 mm > 4 mm lines
    EXPECT_THROW((void)analyse_macula(ph.scan, cp), AnalysisError);
}

}  // namespace
}  // namespace octshape::retina
