// BMO: automatic detection from the BM gap, the user CSV, the direct ellipse fit and its
// resampling (docs/algorithms/onh.md "BMO").

#include "octshape/retina/bmo.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "octshape/error.h"
#include "test_paths.h"

namespace octshape::retina {
namespace {

constexpr double kPi = std::numbers::pi;

std::vector<BmoPoint> ellipse_points(
    Eigen::Vector2d c, double a, double b, double deg, int n, double phase = 0.3) {
    std::vector<BmoPoint> pts;
    const double th = deg * kPi / 180.0;
    for (int i = 0; i < n; ++i) {
        const double t = phase + 2.0 * kPi * i / n;
        const double u = a * std::cos(t);
        const double v = b * std::sin(t);
        BmoPoint p;
        p.mm = Eigen::Vector3d(c.x() + std::cos(th) * u - std::sin(th) * v,
                               c.y() + std::sin(th) * u + std::cos(th) * v, -1.0 - 0.01 * i);
        pts.push_back(p);
    }
    return pts;
}

TEST(BmoEllipse, RecoversAKnownEllipseInEveryOrientation) {
    for (const double deg : {0.0, 20.0, 80.0, 100.0, 135.0, 170.0}) {
        const auto pts = ellipse_points({2.2, 2.1}, 0.92, 0.76, deg, 40);
        const BmoEllipse e = fit_bmo_ellipse(pts, 360);
        // Points on an exact ellipse. OpenCV 4.6's fitEllipseDirect (float points, a float
        // RotatedRect) does not return them exactly: measured on this ellipse, the axes come
        // out 1e-5 (major) and 5.5e-5 mm (minor) long, in every orientation and at any scale
        // of the input (its normalisation and singularity threshold, opencv/opencv#28627).
        // 1e-4 mm (relative 1.3e-4, 0.03 % of the BMO area) bounds that; a wrong axis, centre
        // or angle convention errs by 0.1 mm or 10 deg and more.
        EXPECT_NEAR(e.centre_mm.x(), 2.2, 1e-5) << deg;
        EXPECT_NEAR(e.centre_mm.y(), 2.1, 1e-5) << deg;
        EXPECT_NEAR(e.semi_major_mm, 0.92, 1e-4) << deg;
        EXPECT_NEAR(e.semi_minor_mm, 0.76, 1e-4) << deg;
        EXPECT_NEAR(e.orientation_deg, deg, 1e-3) << deg;
        EXPECT_NEAR(e.area_mm2, kPi * 0.92 * 0.76, 3e-4) << deg;
        EXPECT_LT(e.rms_residual_mm, 1e-4);
        ASSERT_EQ(e.points_mm.size(), 360U);
        // Resampled points lie on the ellipse, t = 0 on the major axis (+ direction of theta).
        for (const auto& p : e.points_mm) {
            EXPECT_NEAR(e.normalised_radius(p.x(), p.y()), 1.0, 1e-12);
        }
        const double th = e.orientation_deg * kPi / 180.0;
        EXPECT_NEAR(e.points_mm[0].x(), e.centre_mm.x() + e.semi_major_mm * std::cos(th), 1e-12);
        EXPECT_NEAR(e.points_mm[0].y(), e.centre_mm.y() + e.semi_major_mm * std::sin(th), 1e-12);
        EXPECT_TRUE(e.inside(2.2, 2.1));
        EXPECT_FALSE(e.inside(2.2 + 1.0, 2.1));
    }
}

TEST(BmoEllipse, ResampledHeightsAreLinearInAngleBetweenTheMeasuredPoints) {
    // A circle of 8 measured points (45 deg apart) with distinct heights; every resampled point
    // takes the height linear in polar angle between the two measured points that bracket it,
    // across +-180 deg too. (It took the nearest point's height: a step between neighbouring
    // resampled points of up to the two ends' difference; docs/algorithms/onh.md "3-D MRW per
    // point".)
    auto pts = ellipse_points({1.0, 1.0}, 0.5, 0.5 - 1e-9, 0.0, 8, 0.0);
    for (std::size_t k = 0; k < pts.size(); ++k) pts[k].mm.z() = -1.0 + 0.01 * static_cast<double>(k * k);
    const BmoEllipse e = fit_bmo_ellipse(pts, 64);
    std::vector<std::pair<double, double>> sorted;
    for (const auto& m : pts) sorted.emplace_back(std::atan2(m.mm.y() - 1.0, m.mm.x() - 1.0), m.mm.z());
    std::sort(sorted.begin(), sorted.end());
    double largest_step = 0.0;
    for (std::size_t i = 0; i < e.points_mm.size(); ++i) {
        const auto& p = e.points_mm[i];
        const double ang = std::atan2(p.y() - 1.0, p.x() - 1.0);
        // The bracketing pair, by brute force over the sorted angles (periodic).
        std::size_t j = 0;
        while (j < sorted.size() && sorted[j].first <= ang) ++j;
        const auto& after = sorted[j % sorted.size()];
        const auto& before = sorted[(j + sorted.size() - 1) % sorted.size()];
        double span = after.first - before.first;
        double from = ang - before.first;
        if (span <= 0.0) span += 2 * kPi;
        if (from < 0.0) from += 2 * kPi;
        const double w = from / span;
        EXPECT_NEAR(p.z(), (1.0 - w) * before.second + w * after.second, 1e-12) << i;
        largest_step = std::max(largest_step,
                                std::fabs(e.points_mm[(i + 1) % e.points_mm.size()].z() - p.z()));
    }
    // 64 points over 8 ends: a step is 1/8 of the two bracketing ends' difference (at most
    // 0.49, between the last and the first), never the whole of it.
    EXPECT_LE(largest_step, 0.49 / 8.0 + 1e-9);
}

TEST(BmoEllipse, RefusesTooFewPoints) {
    EXPECT_THROW((void)fit_bmo_ellipse(ellipse_points({1, 1}, 0.5, 0.4, 0, 5), 360), AnalysisError);
}

// A BM height field (plane z = -1 + 0.05 x) on an anisotropic grid with an elliptical gap and a
// small spurious gap elsewhere.
GridSurface bm_with_gap(double cx, double cy, double a, double b) {
    GridSurface s;
    s.cols = 200;
    s.rows = 80;
    s.dx_mm = 0.0113;
    s.dy_mm = 0.0302;
    for (int r = 0; r < s.rows; ++r) {
        for (int c = 0; c < s.cols; ++c) {
            const double x = c * s.dx_mm;
            const double y = r * s.dy_mm;
            const double u = (x - cx) / a;
            const double v = (y - cy) / b;
            const bool gap = u * u + v * v < 1.0;
            const bool spurious = c >= 10 && c < 14 && r >= 5 && r < 8;
            s.z.push_back(gap || spurious ? std::numeric_limits<double>::quiet_NaN()
                                          : -1.0 + 0.05 * x);
        }
    }
    s.filled.assign(s.z.size(), 0);
    return s;
}

TEST(BmoDetection, EndsOfTheLargestGapPerBScanIgnoringSmallGaps) {
    const GridSurface s = bm_with_gap(1.2, 1.2, 0.6, 0.5);
    const BmoDetection d = detect_bmo_points(s);
    EXPECT_EQ(d.other_gaps, 1);
    EXPECT_EQ(d.other_gap_nodes, 12);
    EXPECT_NEAR(d.gap_area_mm2, kPi * 0.6 * 0.5, 0.02);  // pixelated ellipse
    int rows_with_gap = 0;
    for (int r = 0; r < s.rows; ++r) {
        const double v = (r * s.dy_mm - 1.2) / 0.5;
        if (v * v < 1.0) ++rows_with_gap;
    }
    EXPECT_EQ(d.points.size(), static_cast<std::size_t>(2 * rows_with_gap));
    for (const auto& p : d.points) {
        // Half-way between the last present and the first missing A-scan: within half an
        // A-scan of the true boundary.
        const double half = std::sqrt(1.0 - std::pow((p.mm.y() - 1.2) / 0.5, 2));
        const double xb = 1.2 + p.side * 0.6 * half;
        EXPECT_LE(std::fabs(p.mm.x() - xb), 0.5 * s.dx_mm + 1e-12);
        // z extrapolated half an A-scan: exact for the plane.
        EXPECT_NEAR(p.mm.z(), -1.0 + 0.05 * p.mm.x(), 1e-12);
        EXPECT_EQ(d.points_per_bscan[static_cast<std::size_t>(p.bscan)], 2);
    }
    const BmoEllipse e = fit_bmo_ellipse(d.points, 360);
    // Quantisation of +-dx/2 (uniform, zero mean) over ~66 points: centre and axes within a
    // few um; 10 um is > 5 sigma.
    EXPECT_NEAR(e.centre_mm.x(), 1.2, 0.01);
    EXPECT_NEAR(e.centre_mm.y(), 1.2, 0.01);
    EXPECT_NEAR(e.semi_major_mm, 0.6, 0.01);
    EXPECT_NEAR(e.semi_minor_mm, 0.5, 0.01);
}

TEST(BmoDetection, AGapReachingTheEdgeGivesOnePointPerBScan) {
    const GridSurface s = bm_with_gap(0.2, 1.2, 0.6, 0.5);  // cut by the x = 0 edge
    const BmoDetection d = detect_bmo_points(s);
    // Where the gap reaches A-scan 0 its start has no present neighbour: only the end counts.
    int cut = 0;
    for (int r = 0; r < s.rows; ++r) {
        if (!std::isnan(s.z[static_cast<std::size_t>(r * s.cols)])) continue;
        ++cut;
        EXPECT_EQ(d.points_per_bscan[static_cast<std::size_t>(r)], 1) << r;
        for (const auto& p : d.points) {
            if (p.bscan == r) {
                EXPECT_EQ(p.side, +1) << r;
            }
        }
    }
    EXPECT_GT(cut, 20);
}

TEST(BmoDetection, RefusesWithoutADiscSizedGap) {
    GridSurface s = bm_with_gap(1.2, 1.2, 0.6, 0.5);
    for (auto& v : s.z) {
        if (std::isnan(v)) v = -1.0;
    }
    EXPECT_THROW((void)detect_bmo_points(s), AnalysisError);  // no gap at all
    GridSurface small = bm_with_gap(1.2, 1.2, 0.2, 0.2);      // 0.126 mm2 < 0.2 mm2
    EXPECT_THROW((void)detect_bmo_points(small), AnalysisError);
    BmoDetectionParams p;
    p.min_gap_area_mm2 = 0.05;
    EXPECT_NO_THROW((void)detect_bmo_points(small, p));
    p.min_gap_area_mm2 = -1.0;
    EXPECT_THROW(p.validate(), UsageError);
}

io::ScanMeta meta() {
    io::ScanMeta m;
    m.size_x = 384;
    m.scale_x_mm = 0.0113;
    m.distance_mm = 0.0302;
    m.scale_z_mm = 0.0039;
    return m;
}

TEST(BmoCsv, ReadsMillimetresAndPixelIndices) {
    test::TempDir dir;
    {
        std::ofstream f(dir / "mm.csv");
        f << "# BMO of a test eye\nx_mm,y_mm,z_mm\n";
        for (int i = 0; i < 6; ++i) f << 1.0 + 0.1 * i << ", 2.0, -1.25\n";
    }
    const auto mm = read_bmo_csv((dir / "mm.csv").string(), meta(), 145);
    ASSERT_EQ(mm.size(), 6U);
    EXPECT_DOUBLE_EQ(mm[2].mm.x(), 1.2);
    EXPECT_DOUBLE_EQ(mm[2].mm.z(), -1.25);
    EXPECT_EQ(mm[2].bscan, -1);
    {
        std::ofstream f(dir / "px.csv");
        f << "ascan,bscan,depth_px\n";
        for (int i = 0; i < 6; ++i) f << 100 + i << "," << 70 << ",300.5\n";
    }
    const auto px = read_bmo_csv((dir / "px.csv").string(), meta(), 145);
    ASSERT_EQ(px.size(), 6U);
    EXPECT_DOUBLE_EQ(px[1].mm.x(), 101 * 0.0113);
    EXPECT_DOUBLE_EQ(px[1].mm.y(), 70 * 0.0302);
    EXPECT_DOUBLE_EQ(px[1].mm.z(), -300.5 * 0.0039);
}

TEST(BmoCsv, BadFilesGiveInputErrors) {
    test::TempDir dir;
    auto write = [&](const std::string& name, const std::string& text) {
        std::ofstream(dir / name) << text;
        return (dir / name).string();
    };
    const std::string six = "1,1,-1\n1.1,1,-1\n1.2,1,-1\n1.3,1,-1\n1.4,1,-1\n1.5,1,-1\n";
    EXPECT_THROW((void)read_bmo_csv((dir / "none.csv").string(), meta(), 145), InputError);
    EXPECT_THROW((void)read_bmo_csv(write("h.csv", "x,y,z\n" + six), meta(), 145), InputError);
    EXPECT_THROW((void)read_bmo_csv(write("n.csv", "x_mm,y_mm,z_mm\n1,abc,2\n" + six), meta(), 145),
                 InputError);
    EXPECT_THROW((void)read_bmo_csv(write("c.csv", "x_mm,y_mm,z_mm\n1,1\n" + six), meta(), 145),
                 InputError);
    EXPECT_THROW((void)read_bmo_csv(write("f.csv", "x_mm,y_mm,z_mm\n1,1,-1\n"), meta(), 145),
                 InputError);
    EXPECT_THROW((void)read_bmo_csv(write("o.csv", "x_mm,y_mm,z_mm\n9,1,-1\n" + six), meta(), 145),
                 InputError);  // x beyond the 4.33 mm grid
    EXPECT_NO_THROW((void)read_bmo_csv(write("ok.csv", "x_mm,y_mm,z_mm\n" + six), meta(), 145));
}

}  // namespace
}  // namespace octshape::retina
