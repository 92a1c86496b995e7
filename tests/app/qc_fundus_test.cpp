// The en-face pictures in the fundus frame (octshape/qc/fundus.h): one eye scanned with
// horizontal and with vertical B-scans gives the same thickness map, superior up, up to the
// sampling of each scan.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>

#include "octshape/qc/fundus.h"
#include "octshape/qc/macula.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_macula.h"

namespace octshape {
namespace {

// One right eye, a 6 x 6 mm field about the fovea: 121 A-scans 50 um apart along each B-scan,
// 61 B-scans 100 um apart; no pixels (the map needs the device lines only).
retina::MaculaPhantomParams eye(bool vertical) {
    retina::MaculaPhantomParams p;
    p.eye = io::Laterality::kOD;
    p.vertical = vertical;
    p.size_x = 121;
    p.scale_x_mm = 0.05;
    p.num_bscans = 61;
    p.distance_mm = 0.1;
    p.pixels = false;
    return p;
}

TEST(QcFundusFrame, GridCellsLandWhereTheirCentresAreOnTheFundus) {
    // The ONH en-face picture moves whole cells (fundus_cell): each cell must land on the
    // fundus cell that holds its centre, for both directions of B-scans. A grid of 6 x 4 cells
    // of 0.5 x 1 mm: its fundus cells are 0.5 x 1 mm (horizontal) or 1 x 0.5 mm (vertical).
    for (const bool vertical : {false, true}) {
        const io::Scan scan = retina::make_macula_phantom(eye(vertical)).scan;
        const int cols = 6;
        const int rows = 4;
        const qc::FundusFrame f = qc::fundus_frame(scan, cols * 0.5, rows * 1.0);
        const double fdx = f.keeps_axes() ? 0.5 : 1.0;
        const double fdy = f.keeps_axes() ? 1.0 : 0.5;
        for (int b = 0; b < rows; ++b) {
            for (int a = 0; a < cols; ++a) {
                const Eigen::Vector2d c = f.to_fundus({(a + 0.5) * 0.5, (b + 0.5) * 1.0});
                const auto [fa, fb] = f.fundus_cell(a, b, cols, rows);
                EXPECT_EQ(fa, static_cast<int>(std::floor(c.x() / fdx))) << vertical << a << b;
                EXPECT_EQ(fb, static_cast<int>(std::floor(c.y() / fdy))) << vertical << a << b;
            }
        }
    }
}

TEST(QcFundusFrame, VerticalScanOfAnEyeGivesItsHorizontalScansMap) {
    const retina::MaculaPhantomParams ph = eye(false);
    const retina::MaculaPhantomParams pv = eye(true);
    const io::Scan h = retina::make_macula_phantom(ph).scan;
    const io::Scan v = retina::make_macula_phantom(pv).scan;
    const retina::ThicknessMap mh = retina::thickness_map(h);
    const retina::ThicknessMap mv = retina::thickness_map(v);

    // The frames: horizontal = the grid itself; vertical = grid x (A-scans, SLO downwards)
    // turned to point down, grid y (first B-scan leftmost) to the right. Both 6 x 6 mm.
    const qc::FundusFrame fh = qc::fundus_frame(h, 6.0, 6.0);
    const qc::FundusFrame fv = qc::fundus_frame(v, 6.0, 6.0);
    EXPECT_TRUE(fh.keeps_axes());
    EXPECT_EQ(fh.sx, 1.0);
    EXPECT_EQ(fh.sy, 1.0);
    EXPECT_FALSE(fv.keeps_axes());
    EXPECT_EQ(fv.sx, 1.0);   // fundus x = grid y
    EXPECT_EQ(fv.sy, -1.0);  // fundus y = 6 mm - grid x
    EXPECT_EQ(fv.to_fundus({0.0, 0.0}), Eigen::Vector2d(0.0, 6.0));  // first A-scan: top left

    const int w = 240;  // 25 um per pixel: finer than either scan's nodes
    const cv::Mat rh = qc::fundus_thickness_raster(mh, h, w);
    const cv::Mat rv = qc::fundus_thickness_raster(mv, v, w);
    ASSERT_EQ(rh.size(), rv.size());

    // Tolerance from the sampling: each raster is the bilinear interpolation of the true
    // thickness T at its nodes (exact there: ILM = BM + T on every A-scan, the depths stored
    // as float32, < 1e-4 um), so its error is at most (hx^2 max|T_xx| + hy^2 max|T_yy|) / 8
    // with (hx, hy) = (50, 100) um horizontally and (100, 50) um vertically on the fundus. The
    // two maps differ by at most the sum, with max|T''| measured on the generating surface
    // (central differences at 5 um steps over the field).
    const Eigen::Vector2d c = retina::macula_centre_mm(ph);
    auto truth = [&](double x, double y) {
        const Eigen::Vector2d d(x - c.x(), y - c.y());  // OD, horizontal: x nasal, y superior
        double th = std::atan2(d.y(), d.x()) * 180.0 / 3.14159265358979323846;
        if (th < 0.0) th += 360.0;
        return retina::macula_thickness_mm(ph, d.norm(), th);
    };
    const double s = 0.005;
    double txx = 0.0;
    double tyy = 0.0;
    for (double x = s; x <= 6.0 - s; x += 0.01) {
        for (double y = s; y <= 6.0 - s; y += 0.01) {
            const double t0 = truth(x, y);
            txx = std::max(txx, std::fabs(truth(x + s, y) - 2.0 * t0 + truth(x - s, y)) / (s * s));
            tyy = std::max(tyy, std::fabs(truth(x, y + s) - 2.0 * t0 + truth(x, y - s)) / (s * s));
        }
    }
    const double bound_h = (0.05 * 0.05 * txx + 0.1 * 0.1 * tyy) / 8.0;
    const double bound_v = (0.1 * 0.1 * txx + 0.05 * 0.05 * tyy) / 8.0;
    const double tol = bound_h + bound_v;

    double max_diff = 0.0;
    double sum2 = 0.0;
    int n = 0;
    for (int y = 0; y < rh.rows; ++y) {
        for (int x = 0; x < rh.cols; ++x) {
            const double a = rh.at<double>(y, x);
            const double b = rv.at<double>(y, x);
            if (std::isnan(a) || std::isnan(b)) continue;
            max_diff = std::max(max_diff, std::fabs(a - b));
            sum2 += (a - b) * (a - b);
            ++n;
        }
    }
    // Both cover the same field: every pixel but the last row and column has a value in both.
    EXPECT_GE(n, (rh.rows - 1) * (rh.cols - 1));
    EXPECT_LE(max_diff, tol) << "max |T''| " << txx << ", " << tyy << " /mm";
    // Turned by a quarter turn (the old scan-coordinate drawing of a vertical volume), the
    // maps differ by far more than the sampling: the test tells the two apart.
    cv::Mat turned;
    cv::rotate(rv, turned, cv::ROTATE_90_CLOCKWISE);
    double turned_max = 0.0;
    for (int y = 0; y < rh.rows; ++y) {
        for (int x = 0; x < rh.cols; ++x) {
            const double a = rh.at<double>(y, x);
            const double b = turned.at<double>(y, x);
            if (!std::isnan(a) && !std::isnan(b)) turned_max = std::max(turned_max, std::fabs(a - b));
        }
    }
    EXPECT_GT(turned_max, 5.0 * tol);
    RecordProperty("max_diff_um", std::to_string(max_diff * 1e3));
    RecordProperty("rms_diff_um", std::to_string(std::sqrt(sum2 / std::max(1, n)) * 1e3));
    RecordProperty("tolerance_um", std::to_string(tol * 1e3));
    RecordProperty("turned_max_diff_um", std::to_string(turned_max * 1e3));
    std::printf("horizontal vs vertical: max %.3f um, rms %.3f um, tolerance %.3f um "
                "(max|T_xx| %.3f, max|T_yy| %.3f /mm); turned a quarter: max %.1f um\n",
                max_diff * 1e3, std::sqrt(sum2 / std::max(1, n)) * 1e3, tol * 1e3, txx, tyy,
                turned_max * 1e3);
}

}  // namespace
}  // namespace octshape
